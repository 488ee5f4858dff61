//! Scene parsing and validation on arbitrary bytes: no panic, no hang.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    cuticle::scene::fuzz::scene(data);
});
