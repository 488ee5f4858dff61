//! cuticle: a physically based hair renderer.
//!
//! Module tree, following the data flow of DESIGN.md:
//! [`hair`] (files → B-spline strands) → [`accel`] (Embree curves behind the [`accel::Tracer`] trait) →
//! [`render`] (camera, sampler, shading, film) → [`image`] (OpenImageIO output). [`scene`] reads the TOML that ties
//! them together. All `unsafe` code lives in [`sys`]. Above the renderer, [`study`] and [`bench`] measure it and
//! [`plot`] draws the charts (plotters); below everything, [`atomic_file`] writes files whole or not at all.
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod accel;
pub mod atomic_file;
pub mod bench;
pub mod bsdf;
pub mod geometry;
pub mod hair;
pub mod image;
pub mod light;
pub mod measure;
pub mod plot;
pub mod ray;
pub mod render;
pub mod scene;
pub mod shadow;
pub mod shape;
pub mod study;
#[allow(unsafe_code)]
pub mod sys;
pub mod util;
