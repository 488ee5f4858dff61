//! Cem Yuksel's `.hair` reader on arbitrary bytes: no panic, no allocation beyond the input's size.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    cuticle::scene::fuzz::hair(data);
});
