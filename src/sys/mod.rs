//! The only module with `unsafe` code: the Embree bindings, the OpenImageIO shim, Open Image Denoise, a cache
//! prefetch hint and the process's CPU clock, each wrapped in a safe API.
//! Everything above this module is safe Rust (`#![deny(unsafe_code)]` at the crate root).
//!
//! From the crate, `sys` imports only `crate::ray` (the plain ray the Embree queries take and validate). Decisions
//! that belong to the layers above are passed down, never called up: the stochastic queries take the caller's
//! strand-presence test as a closure.

pub mod clock;
pub mod embree;
pub mod oidn;
pub mod oiio;
pub mod prefetch;

/// The symbol `name` (NUL-terminated) of a library loaded at run time, copied out as `T`; the loader's message when it
/// is missing.
///
/// # Safety
/// `T` is the declared type of the symbol `name`, and the value is used only while `library` stays loaded.
unsafe fn symbol<T: Copy>(library: &libloading::Library, name: &[u8]) -> Result<T, String> {
    // SAFETY: the caller guarantees `T` is the symbol's declared type and keeps the library loaded.
    unsafe { library.get::<T>(name) }
        .map(|symbol| *symbol)
        .map_err(|e| e.to_string())
}
