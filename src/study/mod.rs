//! Studies: measured comparisons that render a scene many ways and write what they measured into a directory
//! (CSV tables, charts, image crops), for the documents in `docs/`. Offline tooling, not part of a render.
//!
//! - [`framework`]: the one study framework (variants × seeds against cached references, every
//!   measure, CSVs, charts with equal-time and equal-error read-outs, crop mosaics, image differences between
//!   series); [`kinds`]: `samples`, `sampling`, `lobes`, `hery`, `models`, `curves`, `backends` (Embree against
//!   the pure-Rust BVH) and `shadows` (deep opacity maps against ray tracing) as data for it;
//!   [`report`]: `all`, one Markdown report.
//! - [`stress`]: `cuticle study stress [SCENE]` — adversarial cases per method (NaN/Inf, fireflies, error), on the
//!   framework.
//! - [`auto`]: `cuticle study auto [SCENE...]` — `--quality auto` against every fixed configuration, per error target.
//! - [`cache`]: a stable hash (FNV-1a) naming cached reference renders, and atomic text-file writes.
//! - [`figures`]: the error-against-time chart (through [`crate::plot`]), the crop window on the hair and the
//!   mosaic of crops.
//!
//! Every study reads its scene as a [`SceneFile`]: a scene file, or without one the built-in default scene, as
//! `cuticle render` does. Cached references go to `cache/` in the output directory unless the study is told
//! another directory. Image error measures (RMSE, relMSE, shadowed pixels) are [`crate::measure::metrics`], shared
//! with the benchmarks.

pub mod auto;
pub mod cache;
pub mod denoise;
pub mod figures;
pub mod framework;
pub mod generated;
pub mod kinds;
pub mod report;
pub mod stress;
pub mod temporal;

use std::path::{Path, PathBuf};

use crate::image::{self, Image};
use crate::scene::Scene;

/// The name the built-in default scene goes by in messages, reports and file names' places.
pub const DEFAULT_SCENE_SOURCE: &str = "<default scene>";

/// The scene a study renders, as text: variants are this text with dotted keys replaced
/// ([`framework::Overrides`]), so the studies keep the text rather than a parsed [`Scene`]. Either a scene file or,
/// without one, the built-in default scene ([`crate::scene::DEFAULT_SCENE`]), as for `cuticle render`.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneFile {
    /// The TOML text.
    pub text: String,
    /// What errors call it: the file's path, or [`DEFAULT_SCENE_SOURCE`].
    pub source: PathBuf,
    /// The directory its relative paths (hair files, maps) resolve against: the file's directory, or `.` for the
    /// default scene (which names no file).
    pub base_dir: PathBuf,
    /// The file read, `None` for the default scene.
    pub path: Option<PathBuf>,
}

impl SceneFile {
    /// The scene file at `path`, or the built-in default scene without one.
    pub fn load(path: Option<&Path>) -> Result<SceneFile, StudyError> {
        match path {
            Some(p) => SceneFile::read(p),
            None => Ok(SceneFile::default_scene()),
        }
    }

    /// Reads the scene file at `path` (not yet parsed: see [`SceneFile::scene`]).
    pub fn read(path: &Path) -> Result<SceneFile, StudyError> {
        let text = std::fs::read_to_string(path).map_err(|source| StudyError::SceneFile {
            path: path.to_path_buf(),
            source,
        })?;
        Ok(SceneFile {
            text,
            source: path.to_path_buf(),
            base_dir: path.parent().map(Path::to_path_buf).unwrap_or_default(),
            path: Some(path.to_path_buf()),
        })
    }

    /// The built-in default scene (a procedural fur ball).
    pub fn default_scene() -> SceneFile {
        SceneFile {
            text: crate::scene::DEFAULT_SCENE.to_owned(),
            source: PathBuf::from(DEFAULT_SCENE_SOURCE),
            base_dir: PathBuf::from("."),
            path: None,
        }
    }

    /// A short name for tables and file names: the file's stem, or `default`.
    pub fn name(&self) -> String {
        self.path.as_deref().and_then(Path::file_stem).map_or_else(
            || "default".to_owned(),
            |s| s.to_string_lossy().into_owned(),
        )
    }

    /// Parses and validates the text, with the film resolution replaced by `resolution` if given.
    pub fn scene(&self, resolution: Option<[u32; 2]>) -> Result<Scene, StudyError> {
        let mut scene = Scene::parse(&self.text, &self.source, &self.base_dir)?;
        if let Some(res) = resolution {
            scene.film.resolution = res;
        }
        Ok(scene.revalidate()?)
    }

    /// The text as a TOML table (to apply overrides to); errors name the file.
    pub fn table(&self) -> Result<toml::Table, StudyError> {
        toml::from_str(&self.text)
            .map_err(|e| StudyError::Config(format!("{}: {e}", self.source.display())))
    }

    /// What the cache keys ([`cache::scene_key`]) take for where the scene lives: the canonical directory of a
    /// file (its hair and maps resolve there), or [`DEFAULT_SCENE_SOURCE`] for the default scene, which needs no
    /// directory, so its references are shared by every working directory and never taken for a file's.
    pub fn key_dir(&self) -> String {
        match self.path {
            Some(_) => std::fs::canonicalize(&self.base_dir)
                .unwrap_or_else(|_| self.base_dir.clone())
                .to_string_lossy()
                .into_owned(),
            None => DEFAULT_SCENE_SOURCE.to_owned(),
        }
    }
}

impl std::fmt::Display for SceneFile {
    /// The file's path, or "the built-in default scene" (for report titles).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.path {
            Some(p) => write!(f, "{}", p.display()),
            None => write!(f, "the built-in default scene"),
        }
    }
}

/// Creates `dir` and its parents.
pub fn create_dir(dir: &Path) -> Result<(), StudyError> {
    std::fs::create_dir_all(dir).map_err(|source| StudyError::Io {
        path: dir.to_path_buf(),
        context: "cannot create the directory",
        source,
    })
}

/// A progress bar of `len` steps named `prefix`, the step's name as its message: one per scene of `study auto` and
/// one for `study denoise`.
pub fn steps_bar(len: u64, prefix: impl Into<String>) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(len);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{prefix} [{bar:30}] {pos}/{len} {msg} ({elapsed})",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar.set_prefix(prefix.into());
    bar
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
