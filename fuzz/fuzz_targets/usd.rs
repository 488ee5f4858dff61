//! The USD reader on arbitrary bytes, named `.usda`, `.usdc` or `.usdz` by the first byte: no panic, no hang, no
//! allocation past the target's bound.
//!
//! openusd 0.6 panics on some malformed files (e.g. a `.usdc` token table whose declared size overflows a `Vec`);
//! `usd::read` catches those at its one boundary and reports the file as malformed, which is what a user sees.
//! libFuzzer's panic hook would abort on them first, so this target's hook lets a panic unwind when openusd is on
//! its stack (to that boundary) and aborts on every other panic, which is then cuticle's own.
#![no_main]

use std::sync::Once;

static HOOK: Once = Once::new();

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    HOOK.call_once(|| {
        let abort = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let stack = std::backtrace::Backtrace::force_capture().to_string();
            if !stack.contains("openusd::") {
                abort(info);
            }
        }));
    });
    cuticle::scene::fuzz::usd(data);
});
