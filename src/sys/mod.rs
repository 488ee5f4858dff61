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
