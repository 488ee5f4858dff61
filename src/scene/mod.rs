//! Scenes: the TOML file a user writes, checked strictly (an unknown key or a wrong type is an error naming the key
//! and line), and resolved into what the renderer needs.
//!
//! ```toml
//! [hair]                       # exactly one of `file` or `procedural`
//! file = "../shared/data/hair/furball.hair"   # relative to the scene file
//! curves = "round"             # or "flat"
//! opacity = 0.6                # optional: overrides the file's transparency for shadow rays
//!
//! [camera]                     # position/look_at absent: auto-framed from the model's bounds
//! fov = 40.0                   # vertical, degrees
//!
//! [film]
//! resolution = [640, 480]
//! spp = 16
//!
//! [[light]]
//! kind = "distant"
//! direction = [1.0, -1.0, 1.0] # the direction light travels
//! irradiance = 3.0
//! ```

use std::path::{Path, PathBuf};

use glam::Vec3;
use serde::Deserialize;

use crate::accel::CurveKind;
use crate::hair::procedural::Procedural;

pub mod lights;
pub mod material;
pub use lights::{EnvironmentConfig, LightConfig, ShapeConfig};
pub use material::{Material, MaterialConfig};

/// The default scene, compiled in so `cuticle render` works from any directory with no downloaded data.
pub const DEFAULT_SCENE: &str = include_str!("../../scenes/default.toml");

/// A scene could not be read or is invalid. Messages name the file and, where known, the key and line.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The scene file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// TOML syntax, an unknown key, a wrong type, or a value out of range.
    #[error("{path}: {message}")]
    Invalid {
        /// The scene file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

/// The whole scene file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// The hair model and how it is intersected.
    pub hair: HairConfig,
    /// The camera.
    #[serde(default)]
    pub camera: CameraConfig,
    /// Resolution, samples, seed.
    #[serde(default)]
    pub film: FilmConfig,
    /// The fibre material.
    #[serde(default)]
    pub material: MaterialConfig,
    /// Light sources, `[[light]]` tables.
    #[serde(default, rename = "light")]
    pub lights: Vec<LightConfig>,
    /// Light arriving from every direction not blocked by hair.
    #[serde(default)]
    pub environment: EnvironmentConfig,
    /// Self-shadowing.
    #[serde(default)]
    pub shadows: ShadowConfig,
    /// Light transport: sample counts and path length.
    #[serde(default)]
    pub integrator: IntegratorConfig,
    /// Non-hair geometry, `[[shape]]` tables (a ground plane, a Cornell box).
    #[serde(default, rename = "shape")]
    pub shapes: Vec<ShapeConfig>,
    /// Directory of the scene file: relative paths in the scene resolve against it.
    #[serde(skip)]
    pub base_dir: PathBuf,
    /// Where the scene came from (a path, or `<default scene>`), for messages.
    #[serde(skip)]
    pub source: PathBuf,
}

/// `[hair]`: the model and its intersection.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HairConfig {
    /// A `.hair` or `.tfx` file, relative to the scene file.
    pub file: Option<PathBuf>,
    /// A procedural model, e.g. `{ kind = "fur-ball", strands = 12000 }`.
    pub procedural: Option<Procedural>,
    /// Round tubes or flat ribbons.
    #[serde(default)]
    pub curves: CurveKind,
    /// Per-strand opacity for shadow rays, overriding the file's transparency (0 = invisible to shadows).
    pub opacity: Option<f32>,
    /// Multiplies every strand radius (a thickness control for models whose files are too thick or thin).
    #[serde(default = "one")]
    pub radius_scale: f32,
}

fn one() -> f32 {
    1.0
}

/// Where the hair comes from, after checking `[hair]`.
#[derive(Debug, Clone)]
pub enum HairSource {
    /// A file path, already resolved against the scene directory.
    File(PathBuf),
    /// A generated model.
    Procedural(Procedural),
}

/// `[camera]`: a pinhole camera. Without `position` the camera is placed automatically so the model's bounding
/// sphere fills the frame, looking along `view` at the model's centre.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraConfig {
    /// Vertical field of view, degrees, in (0, 180).
    pub fov: f32,
    /// Eye position, world space.
    pub position: Option<[f32; 3]>,
    /// Point looked at (default: the model's bounding-box centre).
    pub look_at: Option<[f32; 3]>,
    /// Up vector.
    pub up: [f32; 3],
    /// Viewing direction used by auto-framing (from the eye towards the model).
    pub view: [f32; 3],
    /// Auto-framing margin: 1 fits the bounding sphere exactly, larger zooms out.
    pub margin: f32,
}

impl Default for CameraConfig {
    fn default() -> Self {
        CameraConfig {
            fov: 40.0,
            position: None,
            look_at: None,
            up: [0.0, 1.0, 0.0],
            view: [0.0, 0.0, -1.0],
            margin: 1.05,
        }
    }
}

/// `[film]`: image size and sampling.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FilmConfig {
    /// Width and height in pixels.
    pub resolution: [u32; 2],
    /// Camera samples per pixel.
    pub spp: u32,
    /// Seed of the sample streams: same scene + seed ⇒ same image.
    pub seed: u32,
    /// Width of the Gaussian pixel filter in pixels (thesis §5.5 used a 3×3 Gaussian).
    pub filter_width: f32,
}

impl Default for FilmConfig {
    fn default() -> Self {
        FilmConfig {
            resolution: [640, 480],
            spp: 16,
            seed: 0,
            filter_width: 3.0,
        }
    }
}

/// How strands shadow each other.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum ShadowMode {
    /// Shadow rays through semi-transparent strands (transmittance query).
    #[default]
    Raytraced,
    /// Deep opacity maps (Yuksel & Keyser 2008), built per light before rendering ([`crate::shadow`]).
    DeepOpacity,
    /// No self-shadowing.
    None,
}

/// How light samples' shadow rays account for semi-transparent strands (see [`crate::render::integrator`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum TransmittanceMode {
    /// Each strand present with probability = opacity: one any-hit query per shadow ray, visibility 0 or 1.
    #[default]
    Stochastic,
    /// ∏ (1 − opacity) over every strand crossed: smooth, but a full traversal per shadow ray.
    Exact,
}

/// `[shadows]`.
#[derive(Debug, Clone, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct ShadowConfig {
    /// Ray traced, deep opacity maps, or none.
    pub mode: ShadowMode,
    /// Stochastic or exact transparency for light samples (ray-traced mode).
    pub transmittance: TransmittanceMode,
    /// The maps of the deep-opacity mode.
    pub deep_opacity: crate::shadow::DeepOpacityConfig,
}

/// Which strategies estimate direct light (MIS, or one alone for comparisons and tests).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Strategy {
    /// Light and material samples combined by the power heuristic.
    #[default]
    Mis,
    /// Light samples only (material samples still continue paths).
    Light,
    /// Material samples only (delta lights, which no material sample can hit, are still light-sampled).
    Material,
}

/// Which lights the first shading point's light samples go to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum LightSelection {
    /// Every light gets `light_samples` samples (delta lights one): RenderMan's and the thesis' semantics. Costs
    /// one shadow ray per light per sample.
    #[default]
    All,
    /// Each of the `light_samples` samples first picks one light in proportion to its power (pbrt-v4's and
    /// Cycles' way): one shadow ray per sample however many lights there are, more variance per sample.
    One,
}

/// `[integrator]`: the thesis' sample counts (§6, table 3) and the path length.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct IntegratorConfig {
    /// Light samples per light at the first shading point (RenderMan's light samples).
    pub light_samples: u32,
    /// Material (BSDF) samples at the first shading point.
    pub material_samples: u32,
    /// Indirect bounces: 0 = direct light only.
    pub path_length: u32,
    /// Clamp each indirect contribution to this value per channel; 0 = off (the default; clamping is biased).
    pub clamp: f32,
    /// Direct-light strategy.
    pub strategy: Strategy,
    /// Which lights the first vertex's light samples go to.
    pub lights: LightSelection,
}

impl Default for IntegratorConfig {
    fn default() -> Self {
        IntegratorConfig {
            light_samples: 1,
            material_samples: 1,
            path_length: 1,
            clamp: 0.0,
            strategy: Strategy::Mis,
            lights: LightSelection::All,
        }
    }
}

impl Scene {
    /// Reads and checks a scene file.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            path: path.into(),
            source,
        })?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Scene::parse(&text, path, &base)
    }

    /// The built-in default scene (a procedural fur ball; no downloaded data).
    pub fn default_scene() -> Scene {
        Scene::parse(DEFAULT_SCENE, Path::new("<default scene>"), Path::new("."))
            .expect("the built-in default scene is valid (tested)")
    }

    /// Parses scene text; `source` names it in errors, `base_dir` resolves relative paths.
    pub fn parse(text: &str, source: &Path, base_dir: &Path) -> Result<Scene, SceneError> {
        let invalid = |message: String| SceneError::Invalid {
            path: source.into(),
            message,
        };
        // toml's messages carry the line, column and key ("unknown field `fov2`, expected one of ...").
        let mut scene: Scene =
            toml::from_str(text).map_err(|e| invalid(e.to_string().trim_end().to_owned()))?;
        scene.base_dir = base_dir.to_path_buf();
        scene.source = source.to_path_buf();
        scene.validate().map_err(invalid)?;
        Ok(scene)
    }

    /// Checks the scene again after a program changed it (e.g. command-line overrides); errors name the source.
    pub fn revalidate(self) -> Result<Scene, SceneError> {
        self.validate().map_err(|message| SceneError::Invalid {
            path: self.source.clone(),
            message,
        })?;
        Ok(self)
    }

    /// Range checks serde cannot express. Messages name the key.
    fn validate(&self) -> Result<(), String> {
        let h = &self.hair;
        if h.file.is_some() == h.procedural.is_some() {
            return Err("[hair] needs exactly one of `file` or `procedural`".into());
        }
        if let Some(o) = h.opacity {
            if !(0.0..=1.0).contains(&o) {
                return Err(format!("hair.opacity must be in [0, 1], got {o}"));
            }
        }
        if !(h.radius_scale.is_finite() && h.radius_scale > 0.0) {
            return Err(format!(
                "hair.radius_scale must be > 0, got {}",
                h.radius_scale
            ));
        }
        let c = &self.camera;
        if !(c.fov > 0.0 && c.fov < 180.0) {
            return Err(format!(
                "camera.fov must be in (0, 180) degrees, got {}",
                c.fov
            ));
        }
        if !(c.margin.is_finite() && c.margin > 0.0) {
            return Err(format!("camera.margin must be > 0, got {}", c.margin));
        }
        for (key, v) in [("camera.up", c.up), ("camera.view", c.view)] {
            if !Vec3::from(v).is_finite() || Vec3::from(v).length_squared() == 0.0 {
                return Err(format!("{key} must be a non-zero finite vector, got {v:?}"));
            }
        }
        let f = &self.film;
        if f.resolution[0] == 0
            || f.resolution[1] == 0
            || f.resolution[0] > 32768
            || f.resolution[1] > 32768
        {
            return Err(format!(
                "film.resolution must be in [1, 32768]², got {:?}",
                f.resolution
            ));
        }
        if f.spp == 0 || f.spp > 65536 {
            return Err(format!("film.spp must be in [1, 65536], got {}", f.spp));
        }
        if !(f.filter_width.is_finite() && f.filter_width > 0.0 && f.filter_width <= 16.0) {
            return Err(format!(
                "film.filter_width must be in (0, 16] pixels, got {}",
                f.filter_width
            ));
        }
        self.material.build()?;
        let i = &self.integrator;
        if !(1..=1024).contains(&i.light_samples) {
            return Err(format!(
                "integrator.light_samples must be in [1, 1024], got {}",
                i.light_samples
            ));
        }
        if !(1..=1024).contains(&i.material_samples) {
            return Err(format!(
                "integrator.material_samples must be in [1, 1024], got {}",
                i.material_samples
            ));
        }
        let max = crate::render::integrator::MAX_PATH_LENGTH;
        if i.path_length > max {
            return Err(format!(
                "integrator.path_length must be in [0, {max}], got {}",
                i.path_length
            ));
        }
        if !(i.clamp.is_finite() && i.clamp >= 0.0) {
            return Err(format!(
                "integrator.clamp must be >= 0 (0 = off), got {}",
                i.clamp
            ));
        }
        self.shadows.deep_opacity.validate()?;
        lights::validate(self)?;
        Ok(())
    }

    /// The hair source with file paths resolved against the scene directory.
    pub fn hair_source(&self) -> HairSource {
        match (&self.hair.file, &self.hair.procedural) {
            (Some(file), _) => HairSource::File(self.base_dir.join(file)),
            (None, Some(p)) => HairSource::Procedural(p.clone()),
            (None, None) => unreachable!("validate() requires a hair source"),
        }
    }
}
