//! Studies: measured comparisons that render a scene many ways and write what they measured into a directory
//! (CSV tables, charts, image crops), for the documents in `docs/`. Offline tooling, not part of a render.
//!
//! - [`shadows`]: `cuticle study shadows SCENE` — ray-traced shadows at several sample counts and deep opacity maps
//!   over layer counts and resolutions, against a converged ray-traced reference: error against time, map memory
//!   (issue 6).
//!
//! Image error measures (RMSE, relMSE, shadowed pixels, the crop window) are [`crate::measure::metrics`], shared
//! with the benchmarks.
//! - [`cache`]: a stable hash (FNV-1a) naming cached reference renders, and atomic text-file writes.
//! - [`figures`]: the error-against-time chart (through [`crate::plot`]) and the mosaic of crops.

pub mod cache;
pub mod figures;
pub mod shadows;

use std::path::PathBuf;

/// Why a study could not run. Variants name the file involved where there is one.
#[derive(Debug, thiserror::Error)]
pub enum StudyError {
    /// The scene file could not be read.
    #[error("cannot read scene file {path}: {source}")]
    SceneFile {
        /// The scene file asked for.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The scene (or a variant of it) is invalid, or its lights could not be built.
    #[error(transparent)]
    Scene(#[from] crate::scene::SceneError),
    /// The hair could not be loaded or Embree refused it.
    #[error(transparent)]
    Frame(#[from] crate::render::FrameError),
    /// An image (the cached reference, a chart, the crops) could not be read or written.
    #[error(transparent)]
    Image(#[from] crate::image::ImageError),
    /// A chart could not be drawn or written.
    #[error(transparent)]
    Plot(#[from] crate::plot::PlotError),
    /// The CSV table could not be formatted.
    #[error("cannot write the csv table: {0}")]
    Csv(#[from] csv::Error),
    /// A file or directory could not be written.
    #[error("{path}: {context}: {source}")]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// What was being done.
        context: &'static str,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The worker threads could not be started.
    #[error(transparent)]
    ThreadPool(#[from] crate::render::ThreadPoolError),
    /// The study's own settings are unusable (an empty list, 0 samples, a cached reference of the wrong size).
    #[error("{0}")]
    Config(String),
}
