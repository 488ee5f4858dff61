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

use serde::Deserialize;

use crate::accel::{Backend, CurveKind};
use crate::hair::procedural::Procedural;
use crate::hair::{HairSource, HairSpec};
use crate::quality::{QualityConfig, QualityMode};
use crate::render::{FrameSpec, RenderSettings};

pub use crate::render::camera::CameraConfig;
pub use crate::render::settings::{
    FilmConfig, IntegratorConfig, LightSelection, MultipleScattering, Reconstruction, Shading,
    ShadowConfig, ShadowMode, Strategy, TransmittanceMode,
};

pub mod fuzz;
pub mod lights;
pub mod material;
mod usd;
pub use lights::{EnvironmentConfig, LightConfig, ShapeConfig};
pub use material::MaterialConfig;

/// The default scene, compiled in so `cuticle render` works from any directory with no downloaded data.
pub const DEFAULT_SCENE: &str = include_str!("../../scenes/default.toml");

/// Largest scene file read: 16 MiB. The shipped scenes are under 4 KiB; a scene is a few tables of settings, and
/// anything larger is a wrong file (an image, `/dev/zero`) that would otherwise be read without bound.
pub const MAX_SCENE_BYTES: u64 = 16 << 20;

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
    /// Fixed settings, or `mode = "auto"` for an error target ([`crate::quality`]).
    #[serde(default)]
    pub quality: QualityConfig,
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
    /// A `.hair`, `.tfx` or USD (`.usda`, `.usdc`, `.usdz`, `.usd`) file, relative to the scene file.
    pub file: Option<PathBuf>,
    /// USD only: the prim whose subtree's `BasisCurves` are the hair (default: every curve of the stage).
    pub prim: Option<String>,
    /// A procedural model, e.g. `{ kind = "fur-ball", strands = 12000 }`.
    pub procedural: Option<Procedural>,
    /// Round tubes or flat ribbons.
    #[serde(default)]
    pub curves: CurveKind,
    /// Which implementation traces the strands: `"embree"` (default) or `"bvh"` (the pure-Rust BVH).
    #[serde(default)]
    pub backend: Backend,
    /// Per-strand opacity for shadow rays, overriding the file's transparency (0 = invisible to shadows).
    pub opacity: Option<f32>,
    /// Multiplies every strand radius (a thickness control for models whose files are too thick or thin).
    #[serde(default = "one")]
    pub radius_scale: f32,
}

fn one() -> f32 {
    1.0
}

/// Whether `path` names a USD file by its extension (`.usda`, `.usdc`, `.usdz`, `.usd`, any case).
pub fn is_usd(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .is_some_and(|e| matches!(e.as_str(), "usda" | "usdc" | "usdz" | "usd"))
}

/// Checks a prim path key: absolute (`/World/Groom`), and no longer than a path needs to be.
pub(crate) fn check_prim_path(key: &str, prim: &str) -> Result<(), String> {
    if !prim.starts_with('/') || prim.len() > 4096 || prim.chars().any(char::is_control) {
        return Err(format!(
            "{key} must be an absolute prim path such as \"/World/Groom\" (at most 4096 characters), got {:?}",
            crate::util::report::capped(prim)
        ));
    }
    Ok(())
}

impl Scene {
    /// Reads and checks a scene file.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let text = crate::util::input_file::read_text_bounded(path, MAX_SCENE_BYTES).map_err(
            |source| SceneError::Io {
                path: path.into(),
                source,
            },
        )?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Scene::parse(&text, path, &base)
    }

    /// Parses the bytes of a scene file as [`Scene::load`] does after reading it: at most [`MAX_SCENE_BYTES`],
    /// UTF-8, then [`Scene::parse`].
    pub fn parse_bytes(bytes: &[u8], source: &Path, base_dir: &Path) -> Result<Scene, SceneError> {
        let invalid = |message: String| SceneError::Invalid {
            path: source.into(),
            message,
        };
        if bytes.len() as u64 > MAX_SCENE_BYTES {
            return Err(invalid(format!(
                "{} bytes, more than the {MAX_SCENE_BYTES} bytes a scene file may have",
                bytes.len()
            )));
        }
        let text = std::str::from_utf8(bytes).map_err(|e| {
            invalid(format!(
                "not UTF-8 text (invalid byte at offset {})",
                e.valid_up_to()
            ))
        })?;
        Scene::parse(text, source, base_dir)
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
        // toml's messages carry the line, column and key ("unknown field `fov2`, expected one of ...") and quote
        // the offending line, which may be megabytes long: cut to its head and tail.
        let mut scene: Scene = toml::from_str(text)
            .map_err(|e| invalid(crate::util::report::capped(e.to_string().trim_end())))?;
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
        if let Some(prim) = &h.prim {
            if !h.file.as_deref().is_some_and(is_usd) {
                return Err(format!(
                    "hair.prim = {prim:?} names a prim of a USD stage, but hair.file is not a USD file (.usda, \
                     .usdc, .usdz or .usd)"
                ));
            }
            check_prim_path("hair.prim", prim)?;
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
        self.camera.validate()?;
        self.film.validate()?;
        // Building a model is how its parameters are checked (each model validates its own); it takes microseconds
        // and is dropped here. The material a frame renders with is built once, by `resolve`.
        self.material.build()?;
        self.integrator.validate()?;
        if self.integrator.dual() && !matches!(self.material, MaterialConfig::Chiang(_)) {
            return Err(format!(
                "integrator.multiple_scattering = \"dual\" is built for material model \"chiang\" (an \
                 energy-conserving fibre), not \"{}\"",
                self.material.name()
            ));
        }
        self.shadows.deep_opacity.validate()?;
        self.quality.validate()?;
        lights::validate(self)?;
        Ok(())
    }

    /// The files the scene reads: the scene file itself (unless built in), the hair file, the environment map.
    pub fn input_files(&self) -> Vec<PathBuf> {
        let mut files = Vec::new();
        if self.source.is_file() {
            files.push(self.source.clone());
        }
        if let HairSource::File(path) | HairSource::Usd { path, .. } = self.hair_source() {
            files.push(path);
        }
        for shape in &self.shapes {
            if let ShapeConfig::Usd { file, .. } = shape {
                files.push(self.base_dir.join(file));
            }
        }
        if let Some(file) = &self.camera.usd {
            files.push(self.base_dir.join(file));
        }
        if let Some(map) = &self.environment.map {
            files.push(self.base_dir.join(map));
        }
        files
    }

    /// The hair source with file paths resolved against the scene directory.
    pub fn hair_source(&self) -> HairSource {
        match (&self.hair.file, &self.hair.procedural) {
            (Some(file), _) if is_usd(file) => HairSource::Usd {
                path: self.base_dir.join(file),
                prim: self.hair.prim.clone(),
            },
            (Some(file), _) => HairSource::File(self.base_dir.join(file)),
            (None, Some(p)) => HairSource::Procedural(p.clone()),
            (None, None) => unreachable!("validate() requires a hair source"),
        }
    }

    /// The hair source with the scene's radius scale and opacity override.
    pub fn hair_spec(&self) -> HairSpec {
        HairSpec {
            source: self.hair_source(),
            radius_scale: self.hair.radius_scale,
            opacity: self.hair.opacity,
        }
    }

    /// The settings a render of this scene runs with.
    pub fn render_settings(&self) -> RenderSettings {
        RenderSettings {
            camera: self.camera.clone(),
            film: self.film.clone(),
            integrator: self.integrator.clone(),
            shadows: self.shadows.clone(),
            adaptive: None,
            background_visible: self.environment.visible,
        }
    }

    /// Everything a frame of this scene is made of: the material, lights and shapes built (the environment map
    /// read), the hair not yet loaded. Errors name the scene and, for a map, the file.
    pub fn resolve(&self) -> Result<FrameSpec, SceneError> {
        let material = self
            .material
            .build()
            .map_err(|message| SceneError::Invalid {
                path: self.source.clone(),
                message,
            })?;
        let mut settings = self.render_settings();
        if let Some(file) = &self.camera.usd {
            settings.camera = self.usd_camera(file)?;
        }
        Ok(FrameSpec {
            hair: self.hair_spec(),
            curves: self.hair.curves,
            backend: self.hair.backend,
            material,
            lights: self.build_lights()?,
            shapes: self.build_shapes()?,
            settings,
        })
    }

    /// The scene's camera placed as the first `Camera` prim of the USD stage `file` places it (position, view
    /// direction, up, vertical field of view); the scene's other camera keys (margin, orbit) stay.
    fn usd_camera(&self, file: &Path) -> Result<CameraConfig, SceneError> {
        let path = self.base_dir.join(file);
        let stage = crate::usd::read_parts(
            &path,
            None,
            crate::usd::DEFAULT_RADIUS,
            crate::usd::Parts::NONE,
        )
        .map_err(|e| SceneError::Invalid {
            path: self.source.clone(),
            message: format!("camera.usd: {e}"),
        })?;
        let Some(cam) = stage.camera else {
            return Err(SceneError::Invalid {
                path: self.source.clone(),
                message: format!("camera.usd: {} has no Camera prim", path.display()),
            });
        };
        let mut camera = self.camera.clone();
        camera.usd = None;
        camera.position = Some(cam.position.to_array());
        camera.look_at = Some((cam.position + cam.forward).to_array());
        camera.up = cam.up.to_array();
        camera.fov = cam.vertical_fov_degrees;
        camera.validate().map_err(|message| SceneError::Invalid {
            path: self.source.clone(),
            message: format!(
                "camera.usd: {} places the camera so that {message}",
                path.display()
            ),
        })?;
        Ok(camera)
    }

    /// Applies command-line overrides and checks the result like a scene file (a bad value is reported like a bad
    /// scene key).
    pub fn apply(mut self, o: &Overrides) -> Result<Scene, SceneError> {
        if let Some(spp) = o.spp {
            self.film.spp = spp;
        }
        if let Some(res) = o.resolution {
            self.film.resolution = res;
        }
        if let Some(seed) = o.seed {
            self.film.seed = seed;
        }
        if let Some(aovs) = &o.aovs {
            self.film.aovs.clone_from(aovs);
        }
        if let Some(r) = o.reconstruction {
            self.film.reconstruction = r;
        }
        if let Some(curves) = o.curves {
            self.hair.curves = curves;
        }
        if let Some(backend) = o.backend {
            self.hair.backend = backend;
        }
        if let Some(mode) = o.shadows {
            self.shadows.mode = mode;
        }
        if let Some(t) = o.transmittance {
            self.shadows.transmittance = t;
        }
        if let Some(n) = o.light_samples {
            self.integrator.light_samples = n;
        }
        if let Some(n) = o.material_samples {
            self.integrator.material_samples = n;
        }
        if let Some(n) = o.path_length {
            self.integrator.path_length = n;
        }
        if let Some(l) = o.lights {
            self.integrator.lights = l;
        }
        if let Some(s) = o.shading {
            self.integrator.shading = s;
        }
        if let Some(m) = o.multiple_scattering {
            self.integrator.multiple_scattering = m;
        }
        if let Some(m) = o.quality {
            self.quality.mode = m;
        }
        if let Some(t) = o.target {
            self.quality.target = t;
        }
        self.revalidate()
    }
}

/// Values a user overrides on the command line, each replacing one scene key.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Overrides {
    /// `film.spp`.
    pub spp: Option<u32>,
    /// `film.resolution`.
    pub resolution: Option<[u32; 2]>,
    /// `film.seed`.
    pub seed: Option<u32>,
    /// `film.aovs`.
    pub aovs: Option<Vec<String>>,
    /// `film.reconstruction`.
    pub reconstruction: Option<Reconstruction>,
    /// `hair.curves`.
    pub curves: Option<CurveKind>,
    /// `hair.backend`.
    pub backend: Option<Backend>,
    /// `shadows.mode`.
    pub shadows: Option<ShadowMode>,
    /// `shadows.transmittance`.
    pub transmittance: Option<TransmittanceMode>,
    /// `integrator.light_samples`.
    pub light_samples: Option<u32>,
    /// `integrator.material_samples`.
    pub material_samples: Option<u32>,
    /// `integrator.path_length`.
    pub path_length: Option<u32>,
    /// `integrator.lights`.
    pub lights: Option<LightSelection>,
    /// `integrator.shading`.
    pub shading: Option<Shading>,
    /// `integrator.multiple_scattering`.
    pub multiple_scattering: Option<MultipleScattering>,
    /// `quality.mode`.
    pub quality: Option<QualityMode>,
    /// `quality.target`.
    pub target: Option<f32>,
}
