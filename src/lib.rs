//! cuticle: a physically based hair renderer.
//!
//! Layers, each importing only those below it (`docs/architecture.md` draws one frame's data flow):
//!
//! - measurement: [`study`] (error-against-time studies) and [`mod@bench`] (benchmarks), drawing with [`plot`]
//!   (plotters charts) and measuring with [`measure`] (timings, memory, image error);
//! - configuration: [`scene`] reads and checks the TOML and resolves it into the settings each layer owns;
//! - [`render`]: one frame set up ([`render::Frame`]), camera, sampler, film, integrator;
//! - physics: [`shadow`] (deep opacity maps), [`light`], [`bsdf`] (fibre models), [`shape`] (Lambert shapes);
//! - [`accel`]: the [`accel::Tracer`] trait and the Embree backend;
//! - [`hair`] (files → B-spline strands), [`ray`], [`geometry`] (ray–primitive hits), [`image`] (OpenImageIO);
//! - [`sys`]: FFI only; all `unsafe` code lives there;
//! - [`util`]: hashing, colour, sampling, statistics, atomic file writes; imports nothing of this crate.
#![deny(unsafe_code)]
#![warn(missing_docs)]
// The crate's docs are its developers' reference (`cargo doc --document-private-items`): a public item's doc may
// name the private constant or helper that decides its behaviour, and that link is meant.
#![allow(rustdoc::private_intra_doc_links)]

pub mod accel;
pub mod bench;
pub mod bsdf;
pub mod farm;
pub mod geometry;
pub mod hair;
pub mod image;
pub mod job;
pub mod light;
pub mod measure;
pub mod plot;
pub mod quality;
pub mod ray;
pub mod render;
pub mod scene;
pub mod shadow;
pub mod shape;
pub mod study;
#[allow(unsafe_code)]
pub mod sys;
pub mod util;
