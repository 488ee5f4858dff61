//! The USD reader on arbitrary bytes, named `.usda`, `.usdc` or `.usdz` by the first byte: no panic, no hang, no
//! allocation past the target's bound.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    cuticle::scene::fuzz::usd(data);
});
