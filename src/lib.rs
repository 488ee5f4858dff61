//! cuticle: a physically based hair renderer.
//!
//! Layers, top first; each module imports only its own layer and those below (`docs/architecture.md` lists every
//! file, draws one frame's data flow, and `tests/architecture.rs` checks both):
//!
//! - measurement: [`study`] (error-against-time studies) and [`mod@bench`] (benchmarks), drawing with [`plot`]
//!   (plotters charts) and measuring with [`measure`] (timings, memory, image error);
//! - [`job`]: one render job as `cuticle render` runs it (scene → frame → auto's plan → maps → frames → outputs);
//! - configuration: [`scene`] reads and checks the TOML and resolves it into the settings each layer owns;
//! - [`quality`]: `--quality auto`, the renderer choosing its methods for an error target;
//! - [`farm`]: tiles, animation frames, interrupted renders and `merge`;
//! - [`render`]: one frame set up ([`render::Frame`]), camera, sampler, film, integrator, adaptive sampling;
//! - physics: [`shadow`] (deep opacity maps), then [`light`], [`bsdf`] (fibre models), [`shape`] (Lambert shapes);
//! - [`accel`] (the [`accel::Tracer`] trait, Embree and the pure-Rust BVH) and [`geometry`] (ray–primitive hits);
//! - [`hair`] (files → B-spline strands), [`mesh`] (triangle meshes as plain data), [`usd`] (USD stages → strands,
//!   meshes, camera, lights) and [`image`] (OpenImageIO);
//! - [`sys`]: FFI only; all `unsafe` code lives there;
//! - [`ray`] (validated rays) and [`util`] (hashing, colour, sampling, statistics, atomic file writes).
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
pub mod mesh;
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
pub mod usd;
pub mod util;
