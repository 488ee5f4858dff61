//! The settings one render runs with, owned by the renderer: film, sample counts, light transport, self-shadowing.
//!
//! These are the types a scene's `[film]`, `[integrator]` and `[shadows]` tables deserialize into
//! ([`crate::scene`] reads the TOML and calls each type's `validate`); a program that renders without a scene file
//! (a test, a benchmark variant) fills them in directly. Every check names the scene key it is about, so a bad
//! command-line override reads like a bad scene key.

use serde::Deserialize;

use crate::shadow::DeepOpacityConfig;

use super::camera::CameraConfig;
use super::integrator::{Settings, MAX_PATH_LENGTH, MAX_TAIL_LENGTH};
use crate::bsdf::dual::DualForm;

/// `[film]`: image size and sampling.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FilmConfig {
    /// Width and height in pixels.
    #[serde(deserialize_with = "crate::util::exact_array::array")]
    pub resolution: [u32; 2],
    /// Camera samples per pixel.
    pub spp: u32,
    /// Seed of the sample streams: same scene + seed ⇒ same image.
    pub seed: u32,
    /// Width of the Gaussian pixel filter in pixels (thesis §5.5 used a 3×3 Gaussian).
    pub filter_width: f32,
    /// How the pixel filter is applied ([`Reconstruction`]).
    pub reconstruction: Reconstruction,
    /// The AOV layers an EXR holds beside the beauty R, G, B, A (always written): `["all"]` (the default), `[]` for
    /// the beauty alone, or names from [`super::film::aov_layers`], e.g. `["depth", "albedo"]`. Production
    /// renderers write the AOVs a compositor asks for, not every pass: 38 float channels at 512² cost about a
    /// second of zlib per frame, and `depth`, `tangent` and `strand` one more camera ray per pixel (traced only
    /// when one of them is kept).
    pub aovs: Vec<String>,
}

impl Default for FilmConfig {
    fn default() -> Self {
        FilmConfig {
            resolution: [640, 480],
            spp: 16,
            seed: 0,
            filter_width: 3.0,
            reconstruction: Reconstruction::default(),
            aovs: vec![ALL_AOVS.to_owned()],
        }
    }
}

/// `film.reconstruction`: how camera samples become pixels through the pixel filter. Both converge to the same
/// image, the radiance convolved with the filter (they differ only on the frame's outermost pixels, where a splat
/// has no samples beyond the edge to weigh); they differ in noise.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Reconstruction {
    /// Each sample lands uniformly in its pixel and is splatted onto every pixel whose filter reaches it, with the
    /// filter's weight; a pixel is the weighted mean of the samples that reach it (Mitsuba 3's film, RenderMan's).
    /// A sample counts in up to (2⌈r − ½⌉ + 1)² pixels, so the noise is lower at the same spp. Adaptive sampling
    /// (`--quality auto`) splats too: its stop reads each pixel's own samples and scales them by the pixel's share
    /// of the splatted image's noise ([`crate::render::splat::SplatFilter::noise_shares`]). `--denoise` uses
    /// [`Reconstruction::Importance`]: Open Image Denoise cannot remove noise shared by neighbouring pixels.
    #[default]
    Splat,
    /// Filter importance sampling: each sample's offset is drawn from the filter and counts in its own pixel alone
    /// with weight 1 (pbrt-v4's film).
    Importance,
}

impl Reconstruction {
    /// The name the scene file uses.
    pub fn name(self) -> &'static str {
        match self {
            Reconstruction::Splat => "splat",
            Reconstruction::Importance => "importance",
        }
    }
}

/// The `film.aovs` entry that keeps every AOV layer.
pub const ALL_AOVS: &str = "all";

impl FilmConfig {
    /// Range checks; messages name the `film.*` key.
    pub fn validate(&self) -> Result<(), String> {
        let [w, h] = self.resolution;
        if w == 0 || h == 0 || w > 32768 || h > 32768 {
            return Err(format!(
                "film.resolution must be in [1, 32768]², got {:?}",
                self.resolution
            ));
        }
        if self.spp == 0 || self.spp > 65536 {
            return Err(format!("film.spp must be in [1, 65536], got {}", self.spp));
        }
        let fw = self.filter_width;
        if !(fw.is_finite() && fw > 0.0 && fw <= 16.0) {
            return Err(format!(
                "film.filter_width must be in (0, 16] pixels, got {fw}"
            ));
        }
        let layers = super::film::aov_layers();
        for name in &self.aovs {
            if name == ALL_AOVS {
                if self.aovs.len() > 1 {
                    return Err(format!(
                        "film.aovs: \"{ALL_AOVS}\" keeps every layer and cannot be listed with others, got {:?}",
                        self.aovs
                    ));
                }
            } else if !layers.contains(&name.as_str()) {
                return Err(format!(
                    "film.aovs: no AOV layer {name:?}; the layers are {} (or \"{ALL_AOVS}\"; the beauty is always \
                     written)",
                    layers.join(", ")
                ));
            }
        }
        Ok(())
    }

    /// Whether the EXR holds AOV layer `layer` (a name from [`super::film::aov_layers`]).
    pub fn keeps_aov(&self, layer: &str) -> bool {
        self.aovs.iter().any(|a| a == ALL_AOVS || a == layer)
    }

    /// Whether a pixel traces the unfiltered ray through its centre that fills the `depth`, `tangent` and `strand`
    /// layers (one camera ray per pixel beyond its samples).
    pub fn traces_centre_ray(&self) -> bool {
        super::film::CENTRE_LAYERS
            .iter()
            .any(|layer| self.keeps_aov(layer))
    }
}

/// How strands shadow each other.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
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

impl ShadowMode {
    /// The name the scene file and the command line use.
    pub fn name(self) -> &'static str {
        match self {
            ShadowMode::Raytraced => "raytraced",
            ShadowMode::DeepOpacity => "deep-opacity",
            ShadowMode::None => "none",
        }
    }
}

/// How light samples' shadow rays account for semi-transparent strands (see [`super::integrator`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TransmittanceMode {
    /// Each strand present with probability = opacity: one any-hit query per shadow ray, visibility 0 or 1.
    #[default]
    Stochastic,
    /// ∏ (1 − opacity) over every strand crossed: smooth, but a full traversal per shadow ray.
    Exact,
}

/// `[shadows]`.
#[derive(Debug, Clone, PartialEq, Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
pub struct ShadowConfig {
    /// Ray traced, deep opacity maps, or none.
    pub mode: ShadowMode,
    /// Stochastic or exact transparency for light samples (ray-traced mode).
    pub transmittance: TransmittanceMode,
    /// The maps of the deep-opacity mode.
    pub deep_opacity: DeepOpacityConfig,
}

/// Which strategies estimate direct light (MIS, or one alone for comparisons and tests).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
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
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
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

/// Which integrator shades: the wavefront (eight paths of a pixel in flight, every vertex shaded in f32×8 lanes) or
/// the scalar path tracer (one path at a time). Both run the same model code and give the same image bit for bit
/// (tested); the scalar path is the reference the tests compare against.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Shading {
    /// The wavefront ([`crate::render::wavefront`]): every model, shadow mode and light, fixed or adaptive
    /// sampling, `--quality auto`'s pilots.
    #[default]
    Lanes,
    /// Every shading point one at a time.
    Scalar,
}

/// How light scattered between fibres more than once is found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MultipleScattering {
    /// Path tracing: `path_length` bounces through the hair.
    #[default]
    Path,
    /// Dual scattering (after Zinke et al. 2008, [`crate::bsdf::dual`]) in its layered form: each light sample at
    /// the first vertex counts the strands towards the light and behind the point and adds the light forward-
    /// and back-scattered between them, every order summed; paths end at the first vertex (`path_length` and
    /// `tail` do not apply). Chiang's model only; ray-traced shadows; shaded one path at a time (the scalar
    /// integrator).
    Dual,
    /// Dual scattering as Zinke et al. published it (product of forward attenuations, back-scattering to three
    /// events, density factors 0.7): kept to measure against; otherwise as `dual`.
    DualPublished,
}

/// `[integrator]`: the thesis' sample counts (§6, table 3) and the path length.
#[derive(Debug, Clone, PartialEq, Deserialize)]
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
    /// Light-sample Russian roulette: a light sample whose unshadowed contribution (largest channel of
    /// L_e f cos θi w / p, the path's throughput not included) is below this value traces its shadow ray only with
    /// probability contribution / threshold and is divided by that probability if it does, so the estimate stays
    /// unbiased and dim light samples cost fewer rays (more noise where they are dim). Cycles' "Light Threshold"
    /// (`light_sampling_threshold`, 0.01 by default there, same test); 0 = off (cuticle's default, every light
    /// sample traced).
    pub light_threshold: f32,
    /// In lanes or one at a time ([`Shading`]); the same image either way.
    pub shading: Shading,
    /// Past `path_length` bounces, the probability that a path goes on (times Russian roulette's own), its
    /// throughput divided by it, up to [`MAX_TAIL_LENGTH`] bounces (Russian roulette ends them long before):
    /// the bounces past `path_length` are then estimated
    /// without bias, at the cost of their noise, instead of left out. 0 = off (the default: paths end at
    /// `path_length`); needs `path_length` ≥ 1.
    pub tail: f32,
    /// Path tracing or dual scattering for the light scattered between fibres ([`MultipleScattering`]).
    pub multiple_scattering: MultipleScattering,
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
            light_threshold: 0.0,
            shading: Shading::Lanes,
            tail: 0.0,
            multiple_scattering: MultipleScattering::Path,
        }
    }
}

/// The most light or material samples per shading point: the thesis' table 3 goes to 2048.
pub const MAX_SAMPLES_PER_POINT: u32 = 2048;

impl IntegratorConfig {
    /// Whether multiple scattering is dual scattering (either form).
    pub fn dual(&self) -> bool {
        self.dual_form().is_some()
    }

    /// The form of dual scattering, if multiple scattering is dual scattering.
    pub fn dual_form(&self) -> Option<DualForm> {
        match self.multiple_scattering {
            MultipleScattering::Path => None,
            MultipleScattering::Dual => Some(DualForm::Layered),
            MultipleScattering::DualPublished => Some(DualForm::Published),
        }
    }

    /// Whether the wavefront shades (`shading = "lanes"`, and path tracing: dual scattering is written for the
    /// scalar integrator).
    pub fn lanes(&self) -> bool {
        self.shading == Shading::Lanes && !self.dual()
    }

    /// Range checks; messages name the `integrator.*` key.
    pub fn validate(&self) -> Result<(), String> {
        for (key, n) in [
            ("light_samples", self.light_samples),
            ("material_samples", self.material_samples),
        ] {
            if !(1..=MAX_SAMPLES_PER_POINT).contains(&n) {
                return Err(format!(
                    "integrator.{key} must be in [1, {MAX_SAMPLES_PER_POINT}], got {n}"
                ));
            }
        }
        if self.path_length > MAX_PATH_LENGTH {
            return Err(format!(
                "integrator.path_length must be in [0, {MAX_PATH_LENGTH}], got {}",
                self.path_length
            ));
        }
        for (key, v) in [
            ("clamp", self.clamp),
            ("light_threshold", self.light_threshold),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!("integrator.{key} must be >= 0 (0 = off), got {v}"));
            }
        }
        if !(0.0..=1.0).contains(&self.tail) {
            return Err(format!(
                "integrator.tail must be in [0, 1] (0 = off), got {}",
                self.tail
            ));
        }
        if self.tail > 0.0 && self.path_length == 0 {
            return Err("integrator.tail needs integrator.path_length >= 1".into());
        }
        if self.dual() {
            if self.tail > 0.0 {
                return Err("integrator.tail continues paths, which integrator.multiple_scattering = \"dual\" \
                            ends at the first vertex: set one of them"
                    .into());
            }
            if self.strategy == Strategy::Material {
                return Err("integrator.multiple_scattering = \"dual\" adds its light to the light samples: \
                            integrator.strategy must be \"mis\" or \"light\""
                    .into());
            }
        }
        Ok(())
    }
}

/// Everything one render of a prepared [`super::Frame`] can vary without reloading the hair: a benchmark or a
/// study renders one frame under several of these.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderSettings {
    /// The camera (auto-framed from the hair's bounds unless placed).
    pub camera: CameraConfig,
    /// Resolution, samples, seed, pixel filter.
    pub film: FilmConfig,
    /// Sample counts, path length, strategy.
    pub integrator: IntegratorConfig,
    /// Self-shadowing.
    pub shadows: ShadowConfig,
    /// Per-pixel adaptive sampling ([`super::adaptive`]) instead of `film.spp` samples everywhere (`--quality
    /// auto` sets it; scenes do not).
    pub adaptive: Option<super::adaptive::Schedule>,
    /// Whether camera rays that escape see the infinite lights.
    pub background_visible: bool,
}

impl RenderSettings {
    /// Whether the frame splats its samples ([`Reconstruction::Splat`]): asked for, with a filter wider than a
    /// pixel (narrower, a sample would count in its own pixel alone, with weight 0 wherever the filter misses it).
    pub fn splats(&self) -> bool {
        self.film.reconstruction == Reconstruction::Splat
            && super::splat::SplatFilter::new(self.film.filter_width).reach() > 0
    }

    /// The share of a pixel's variance of the mean that reaches the image inside the frame: the splatting film's
    /// ([`super::splat::SplatFilter::noise_shares`], 0.32 for the 3-pixel Gaussian) or 1 when each pixel is the
    /// mean of its own samples. What auto's pilots, which measure each pixel's own noise, scale their prediction
    /// of the frame's noise by.
    pub fn noise_share(&self) -> f64 {
        if !self.splats() {
            return 1.0;
        }
        let filter = super::splat::SplatFilter::new(self.film.filter_width);
        // Far enough from the frame's edges in both axes to read the inside's share.
        let side = 4 * filter.reach() + 1;
        filter
            .noise_shares([side, side])
            .at(2 * filter.reach(), 2 * filter.reach())
    }

    /// The light-transport settings of the integrator.
    pub fn transport(&self) -> Settings {
        let i = &self.integrator;
        // A tail: paths go on to the longest length, thinned once at `path_length` (the integrator's roulette).
        let tail = (i.tail > 0.0 && i.path_length >= 1 && i.path_length < MAX_TAIL_LENGTH)
            .then_some((i.path_length, i.tail))
            .filter(|_| !i.dual());
        Settings {
            light_samples: i.light_samples,
            material_samples: i.material_samples,
            path_length: if i.dual() {
                0
            } else if tail.is_some() {
                MAX_TAIL_LENGTH
            } else {
                i.path_length
            },
            tail,
            clamp: i.clamp,
            shadows: self.shadows.mode,
            transmittance: self.shadows.transmittance,
            // In deep-opacity mode a material sample's light is also seen through the maps
            // (`Integrator::mapped_light`), so both strategies estimate the same integral and MIS applies as in
            // ray-traced mode.
            strategy: i.strategy,
            light_selection: i.lights,
            light_threshold: i.light_threshold,
            dual: i.dual_form(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tail_outside_zero_to_one_or_without_a_bounce_is_refused_by_name_and_runs_to_the_longest_path(
    ) {
        for (tail, path_length, ok) in [
            (0.0, 0, true),
            (0.5, 1, true),
            (1.0, 3, true),
            (-0.1, 1, false),
            (1.5, 1, false),
            (f32::NAN, 1, false),
            (0.5, 0, false),
        ] {
            let c = IntegratorConfig {
                tail,
                path_length,
                ..IntegratorConfig::default()
            };
            let r = c.validate();
            assert_eq!(r.is_ok(), ok, "tail {tail}, path {path_length}: {r:?}");
            if let Err(m) = r {
                assert!(m.contains("integrator.tail"), "{m}");
            }
        }
        let mut s = RenderSettings {
            camera: CameraConfig::default(),
            film: FilmConfig::default(),
            integrator: IntegratorConfig {
                tail: 0.5,
                path_length: 2,
                ..IntegratorConfig::default()
            },
            shadows: ShadowConfig::default(),
            adaptive: None,
            background_visible: true,
        };
        let t = s.transport();
        assert_eq!((t.path_length, t.tail), (MAX_TAIL_LENGTH, Some((2, 0.5))));
        s.integrator.tail = 0.0;
        let t = s.transport();
        assert_eq!((t.path_length, t.tail), (2, None));
    }

    #[test]
    fn a_negative_or_nan_light_threshold_is_refused_by_name() {
        for (t, ok) in [(0.0, true), (0.01, true), (-0.01, false), (f32::NAN, false)] {
            let c = IntegratorConfig {
                light_threshold: t,
                ..IntegratorConfig::default()
            };
            match c.validate() {
                Ok(()) => assert!(ok, "{t} accepted"),
                Err(e) => {
                    assert!(!ok, "{t} refused: {e}");
                    assert!(e.contains("integrator.light_threshold must be >= 0"), "{e}");
                }
            }
        }
    }

    #[test]
    fn samples_per_point_go_to_2048_and_no_further() {
        for (n, ok) in [(0, false), (1, true), (2048, true), (2049, false)] {
            let c = IntegratorConfig {
                light_samples: n,
                material_samples: n,
                ..IntegratorConfig::default()
            };
            let r = c.validate();
            assert_eq!(r.is_ok(), ok, "{n}: {r:?}");
            if let Err(e) = r {
                assert!(
                    e.contains("integrator.light_samples must be in [1, 2048]"),
                    "{e}"
                );
            }
        }
    }
}
