//! The only module with `unsafe` code: the Embree bindings and the OpenImageIO shim, each wrapped in a safe API.
//! Everything above this module is safe Rust (`#![deny(unsafe_code)]` at the crate root).

pub mod embree;
pub mod oiio;
