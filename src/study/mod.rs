//! Studies: measured comparisons that render a scene many ways and write what they measured into a directory
//! (CSV tables, charts, image crops), for the documents in `docs/`. Offline tooling, not part of a render.
//!
//! - [`framework`]: the one study framework (variants × seeds against cached references, every
//!   measure, CSVs, charts with equal-time and equal-error read-outs, crop mosaics, image differences between
//!   series); [`kinds`]: `samples`, `sampling`, `lobes`, `hery`, `models`, `curves`, `backends` (Embree against
//!   the pure-Rust BVH) and `shadows` (deep opacity maps against ray tracing) as data for it;
//!   [`report`]: `all`, one Markdown report.
//! - [`stress`]: `cuticle study stress SCENE` — adversarial cases per method (NaN/Inf, fireflies, error), on the
//!   framework.
//! - [`auto`]: `cuticle study auto SCENE...` — `--quality auto` against every fixed configuration, per error target.
//! - [`cache`]: a stable hash (FNV-1a) naming cached reference renders, and atomic text-file writes.
//! - [`figures`]: the error-against-time chart (through [`crate::plot`]) and the mosaic of crops.
//!
//! Image error measures (RMSE, relMSE, shadowed pixels, the crop window) are [`crate::measure::metrics`], shared
//! with the benchmarks.

pub mod auto;
pub mod cache;
pub mod figures;
pub mod framework;
pub mod kinds;
pub mod report;
pub mod stress;

use std::path::{Path, PathBuf};

use crate::image::{self, Image};
use crate::scene::Scene;

/// Reads and validates the scene file at `path`, with the film resolution replaced by `resolution` if given.
/// Returns the file's text (for cache keys) and the scene.
pub fn load_scene(
    path: &Path,
    resolution: Option<[u32; 2]>,
) -> Result<(String, Scene), StudyError> {
    let text = std::fs::read_to_string(path).map_err(|source| StudyError::SceneFile {
        path: path.to_path_buf(),
        source,
    })?;
    let base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut scene = Scene::parse(&text, path, &base_dir)?;
    if let Some(res) = resolution {
        scene.film.resolution = res;
    }
    Ok((text, scene.revalidate()?))
}

/// Creates `dir` and its parents.
pub fn create_dir(dir: &Path) -> Result<(), StudyError> {
    std::fs::create_dir_all(dir).map_err(|source| StudyError::Io {
        path: dir.to_path_buf(),
        context: "cannot create the directory",
        source,
    })
}

/// A converged reference: read from `path` if it is there (checked to be `width × height`), else rendered by
/// `render` (returning the image and its render seconds) and written there. Returns the image, whether it was
/// cached, and the render time if it was rendered now.
pub fn cached_reference(
    path: &Path,
    [width, height]: [u32; 2],
    render: impl FnOnce() -> (Image, f64),
) -> Result<(Image, bool, Option<f64>), StudyError> {
    if path.is_file() {
        let image = image::read(path)?;
        if (image.width, image.height) != (width as usize, height as usize) {
            return Err(StudyError::Config(format!(
                "{}: cached reference is {}x{}, expected {width}x{height}; delete it",
                path.display(),
                image.width,
                image.height
            )));
        }
        return Ok((image, true, None));
    }
    let (image, seconds) = render();
    image::write(path, &image)?;
    Ok((image, false, Some(seconds)))
}

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
