//! `cuticle merge`'s tile reader on arbitrary bytes (split into up to four tile files): no panic, no hang, no
//! allocation past the target's bound.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    cuticle::scene::fuzz::merge(data);
});
