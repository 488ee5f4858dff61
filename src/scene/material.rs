//! `[material]`: which fibre model shades the hair, with its parameters as a user writes them (angles in degrees,
//! colours linear RGB), and how they become a [`Material`].
//!
//! ```toml
//! [material]
//! model = "marschner"        # or "ishair", "kajiya-kay", "chiang"
//! color = [0.4, 0.25, 0.12]  # diffuse colour; absent ⇒ each strand's colour from the hair file
//! beta_1 = 7.5               # degrees; every width must be > 0
//! sampling = "importance"    # or "published" (marschner only), "uniform"
//! balance = "user"           # or "fresnel" (with `eta`), "sum"
//! specular = 0.5             # the specular share for balance = "user"
//! ```
//!
//! Defaults are the model files' defaults ([`MarschnerParams::default`], [`IsHairParams::default`]), which cite the
//! papers they come from; this file only converts units, so there is one source of truth for each number.
//!
//! `model = "chiang"` (Chiang et al. 2016, [`crate::bsdf::chiang`]) takes `sigma_a` (RGB, per unit fibre
//! *radius*), **or** `eumelanin` / `pheomelanin` (concentrations), **or** `color` (the target colour of a volume of
//! hair, inverted to σa with the paper's eq. 9 at `beta_n`), at most one of the three ways; with none, pbrt-v4's
//! default σa (eumelanin 1.3). Then `beta_m`, `beta_n` (0.3, 0.3; in [0.001, 1]), `alpha` (2 degrees; |α| ≤ 22.5)
//! and `eta` (1.55; in (1, 10]), and `sampling` (`importance` or `uniform`). Its `color` is not a diffuse colour:
//! the strand colours of the file are unused.
//!
//! **Strand colour.** Without `color`, the renderer multiplies the *diffuse* lobe by the strand's colour from the
//! hair file (the other lobes keep their explicit colours: the cuticle's reflection R is not pigmented, and TT/TRT
//! colours are parameters of the models).

use glam::Vec3;
use serde::Deserialize;

use crate::bsdf::chiang::{self, Chiang, ChiangParams};
use crate::bsdf::ishair::{IsHair, IsHairParams, LobeSelection};
use crate::bsdf::kajiya_kay::{KajiyaKay, KajiyaKayParams};
use crate::bsdf::marschner::{Marschner, MarschnerParams};
use crate::bsdf::{Balance, BsdfError, Material, Sampling, Scattering};

/// `[material]`, tagged by `model`.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "model", rename_all = "kebab-case")]
pub enum MaterialConfig {
    /// Kajiya & Kay 1989: a diffuse cylinder plus a specular cone (the foundation's shading).
    KajiyaKay(KajiyaKayConfig),
    /// Hery & Ramamoorthi 2012's importance-sampled Marschner R lobe, two highlights (thesis §4.2, §5.3.1).
    Marschner(MarschnerConfig),
    /// Ou et al. 2012's ISHair: Sadeghi et al. 2010's R, TT, TRT − g and glint lobes (thesis §4.3, §5.3.2).
    Ishair(IsHairConfig),
    /// Chiang et al. 2016's energy-conserving near/far-field model.
    Chiang(ChiangConfig),
}

impl Default for MaterialConfig {
    fn default() -> Self {
        MaterialConfig::KajiyaKay(KajiyaKayConfig::default())
    }
}

impl MaterialConfig {
    /// The model called `name` in a scene (`"kajiya-kay"`, `"marschner"`, `"ishair"`) with its paper's defaults,
    /// as `model = "name"` alone would give.
    pub fn named(name: &str) -> Option<MaterialConfig> {
        Some(match name {
            "kajiya-kay" => MaterialConfig::KajiyaKay(KajiyaKayConfig::default()),
            "marschner" => MaterialConfig::Marschner(MarschnerConfig::default()),
            "ishair" => MaterialConfig::Ishair(IsHairConfig::default()),
            "chiang" => MaterialConfig::Chiang(ChiangConfig::default()),
            _ => return None,
        })
    }
}

/// Sampling mode names of the scene file (`sampling = ...`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SamplingName {
    /// [`Sampling::ExactPdf`].
    #[default]
    Importance,
    /// [`Sampling::ClampAndFlip`], Hery & Ramamoorthi as published (marschner only; biased, kept for comparison).
    Published,
    /// [`Sampling::Uniform`].
    Uniform,
}

impl From<SamplingName> for Sampling {
    fn from(s: SamplingName) -> Sampling {
        match s {
            SamplingName::Importance => Sampling::ExactPdf,
            SamplingName::Published => Sampling::ClampAndFlip,
            SamplingName::Uniform => Sampling::Uniform,
        }
    }
}

/// Diffuse/specular balance names (`balance = ...`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BalanceName {
    /// [`Balance::User`] with `specular` as the specular share (thesis §5.3).
    #[default]
    User,
    /// [`Balance::Fresnel`] with `eta` (thesis §8.2; not reciprocal).
    Fresnel,
    /// [`Balance::Sum`]: both terms at full weight; the colours carry the balance.
    Sum,
}

fn balance(name: BalanceName, specular: f32, eta: f32) -> Balance {
    match name {
        BalanceName::User => Balance::User { specular },
        BalanceName::Fresnel => Balance::Fresnel { eta },
        BalanceName::Sum => Balance::Sum,
    }
}

/// Lobe selection names for ISHair (`selection = ...`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SelectionName {
    /// 1/4 per lobe, as in the thesis.
    #[default]
    Uniform,
    /// In proportion to each lobe's estimated energy (thesis §8.2).
    ByEnergy,
}

/// `model = "kajiya-kay"`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct KajiyaKayConfig {
    /// Diffuse colour; absent ⇒ the strand colour.
    #[serde(default, deserialize_with = "crate::util::exact_array::option_array")]
    pub color: Option<[f32; 3]>,
    /// Weight of the diffuse term.
    pub diffuse: f32,
    /// Weight of the specular cone.
    pub specular: f32,
    /// Cone exponent p (larger = sharper).
    pub exponent: f32,
    /// Sampling mode (`importance` or `uniform`).
    pub sampling: SamplingName,
}

impl Default for KajiyaKayConfig {
    fn default() -> Self {
        let p = KajiyaKayParams::default();
        KajiyaKayConfig {
            color: None,
            diffuse: p.k_d.x,
            specular: p.k_s,
            exponent: p.p,
            sampling: SamplingName::Importance,
        }
    }
}

/// `model = "marschner"`: fields named as in thesis eq. 5–14 (index 1 = primary, 2 = secondary highlight).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MarschnerConfig {
    /// Diffuse colour k_d; absent ⇒ the strand colour.
    #[serde(default, deserialize_with = "crate::util::exact_array::option_array")]
    pub color: Option<[f32; 3]>,
    /// Primary highlight colour k_s,1.
    #[serde(deserialize_with = "crate::util::exact_array::array")]
    pub k_s1: [f32; 3],
    /// Primary shift α_1, degrees.
    pub alpha_1: f32,
    /// Primary width β_1, degrees, > 0.
    pub beta_1: f32,
    /// Secondary highlight colour k_s,2.
    #[serde(deserialize_with = "crate::util::exact_array::array")]
    pub k_s2: [f32; 3],
    /// Secondary shift α_2, degrees.
    pub alpha_2: f32,
    /// Secondary width β_2, degrees, > 0.
    pub beta_2: f32,
    /// Diffuse/specular balance.
    pub balance: BalanceName,
    /// Specular share for `balance = "user"`.
    pub specular: f32,
    /// Cuticle index of refraction for `balance = "fresnel"`.
    pub eta: f32,
    /// Sampling mode.
    pub sampling: SamplingName,
}

impl Default for MarschnerConfig {
    fn default() -> Self {
        let p = MarschnerParams::default();
        MarschnerConfig {
            color: None,
            k_s1: p.k_s1.into(),
            alpha_1: p.alpha_1.to_degrees(),
            beta_1: p.beta_1.to_degrees(),
            k_s2: p.k_s2.into(),
            alpha_2: p.alpha_2.to_degrees(),
            beta_2: p.beta_2.to_degrees(),
            balance: BalanceName::User,
            specular: 0.5,
            eta: 1.55,
            sampling: SamplingName::Importance,
        }
    }
}

/// `model = "ishair"`: fields named as in thesis eq. 15–21.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct IsHairConfig {
    /// Diffuse colour k_d; absent ⇒ the strand colour.
    #[serde(default, deserialize_with = "crate::util::exact_array::option_array")]
    pub color: Option<[f32; 3]>,
    /// C_R.
    #[serde(deserialize_with = "crate::util::exact_array::array")]
    pub color_r: [f32; 3],
    /// C_TT.
    #[serde(deserialize_with = "crate::util::exact_array::array")]
    pub color_tt: [f32; 3],
    /// C_TRT.
    #[serde(deserialize_with = "crate::util::exact_array::array")]
    pub color_trt: [f32; 3],
    /// I_g, the glints' gain.
    pub glint: f32,
    /// α_R, degrees.
    pub alpha_r: f32,
    /// β_R, degrees, > 0.
    pub beta_r: f32,
    /// α_TT, degrees.
    pub alpha_tt: f32,
    /// β_TT, degrees, > 0.
    pub beta_tt: f32,
    /// α_TRT, degrees.
    pub alpha_trt: f32,
    /// β_TRT, degrees, > 0.
    pub beta_trt: f32,
    /// γ_TT, degrees, > 0.
    pub gamma_tt: f32,
    /// γ_g, degrees, > 0.
    pub gamma_g: f32,
    /// φ_g, degrees.
    pub phi_g: f32,
    /// Diffuse/specular balance.
    pub balance: BalanceName,
    /// Specular share for `balance = "user"`.
    pub specular: f32,
    /// Cuticle index of refraction for `balance = "fresnel"`.
    pub eta: f32,
    /// Sampling mode.
    pub sampling: SamplingName,
    /// How samples are split between the lobes.
    pub selection: SelectionName,
}

impl Default for IsHairConfig {
    fn default() -> Self {
        let p = IsHairParams::default();
        IsHairConfig {
            color: None,
            color_r: p.color_r.into(),
            color_tt: p.color_tt.into(),
            color_trt: p.color_trt.into(),
            glint: p.glint,
            alpha_r: p.alpha_r.to_degrees(),
            beta_r: p.beta_r.to_degrees(),
            alpha_tt: p.alpha_tt.to_degrees(),
            beta_tt: p.beta_tt.to_degrees(),
            alpha_trt: p.alpha_trt.to_degrees(),
            beta_trt: p.beta_trt.to_degrees(),
            gamma_tt: p.gamma_tt.to_degrees(),
            gamma_g: p.gamma_g.to_degrees(),
            phi_g: p.phi_g.to_degrees(),
            balance: BalanceName::User,
            specular: 0.5,
            eta: 1.55,
            sampling: SamplingName::Importance,
            selection: SelectionName::Uniform,
        }
    }
}

/// `model = "chiang"`: the paper's names; colour given one of three ways (none ⇒ the model's default σa).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ChiangConfig {
    /// σa, absorption per unit fibre radius, RGB.
    #[serde(default, deserialize_with = "crate::util::exact_array::option_array")]
    pub sigma_a: Option<[f32; 3]>,
    /// Eumelanin concentration (with `pheomelanin`; an absent one is 0).
    pub eumelanin: Option<f32>,
    /// Pheomelanin concentration.
    pub pheomelanin: Option<f32>,
    /// Target colour of a volume of such hair, per channel in (0, 1] (Chiang et al. eq. 9).
    #[serde(default, deserialize_with = "crate::util::exact_array::option_array")]
    pub color: Option<[f32; 3]>,
    /// βm, longitudinal roughness, in [0.001, 1].
    pub beta_m: f32,
    /// βn, azimuthal roughness, in [0.001, 1].
    pub beta_n: f32,
    /// α, cuticle scale tilt, degrees (> 0 moves R towards the tip).
    pub alpha: f32,
    /// η, the fibre's index of refraction.
    pub eta: f32,
    /// Sampling mode (`importance` or `uniform`).
    pub sampling: SamplingName,
}

impl Default for ChiangConfig {
    fn default() -> Self {
        let p = ChiangParams::default();
        ChiangConfig {
            sigma_a: None,
            eumelanin: None,
            pheomelanin: None,
            color: None,
            beta_m: p.beta_m,
            beta_n: p.beta_n,
            alpha: p.alpha.to_degrees(),
            eta: p.eta,
            sampling: SamplingName::Importance,
        }
    }
}

/// A model's parameter error as the user wrote the key: `material.beta_m must be in [1e-3, 1], got 0`.
fn keyed(e: BsdfError) -> String {
    match e {
        BsdfError::Parameter {
            key,
            requirement,
            value,
            ..
        } => format!("material.{key} must be {requirement}, got {value}"),
        other => format!("material: {other}"),
    }
}

impl ChiangConfig {
    /// The checked parameters: at most one colour way, α in degrees, then the model's own ranges.
    fn params(&self) -> Result<ChiangParams, String> {
        let ways: Vec<&str> = [
            self.sigma_a.map(|_| "sigma_a"),
            (self.eumelanin.is_some() || self.pheomelanin.is_some())
                .then_some("eumelanin/pheomelanin"),
            self.color.map(|_| "color"),
        ]
        .into_iter()
        .flatten()
        .collect();
        if ways.len() > 1 {
            return Err(format!(
                "material: give the chiang colour one way (material.sigma_a, material.eumelanin/pheomelanin or \
                 material.color), got {}",
                ways.join(" and ")
            ));
        }
        if !(self.alpha.is_finite() && self.alpha.abs() <= 22.5) {
            return Err(format!(
                "material.alpha must be in [-22.5, 22.5] degrees, got {}",
                self.alpha
            ));
        }
        let defaults = ChiangParams::default();
        let sigma_a = if let Some(s) = self.sigma_a {
            Vec3::from(s)
        } else if let Some(c) = self.color {
            chiang::sigma_a_from_color(Vec3::from(c), self.beta_n).map_err(keyed)?
        } else if self.eumelanin.is_some() || self.pheomelanin.is_some() {
            chiang::sigma_a_from_melanin(
                self.eumelanin.unwrap_or(0.0),
                self.pheomelanin.unwrap_or(0.0),
            )
            .map_err(keyed)?
        } else {
            defaults.sigma_a
        };
        Ok(ChiangParams {
            sigma_a,
            beta_m: self.beta_m,
            beta_n: self.beta_n,
            alpha: rad(self.alpha),
            eta: self.eta,
            sampling: self.sampling.into(),
        })
    }
}

/// Checks that the widths in degrees are positive and finite, naming the key (`material.beta_1 must be > 0
/// degrees, got 0`): the models' own checks speak radians, which is not what the user wrote.
fn check_widths(widths: &[(&str, f32)]) -> Result<(), String> {
    for &(key, value) in widths {
        if !(value.is_finite() && value > 0.0) {
            return Err(format!("material.{key} must be > 0 degrees, got {value}"));
        }
    }
    Ok(())
}

/// Checks albedo-like colours (each entry: key, value) are in [0, 1] per channel: a fibre cannot scatter more light
/// than reaches it, and a colour of 2 doubled the image's energy per bounce while 3e38 put infinities in the film.
fn check_colors(colors: &[(&str, Option<[f32; 3]>)]) -> Result<(), String> {
    for &(key, value) in colors {
        if let Some(c) = value {
            if !c.iter().all(|v| (0.0..=1.0).contains(v)) {
                return Err(format!(
                    "material.{key} must be in [0, 1] per channel (a fibre reflects at most the light that reaches \
                     it), got {c:?}"
                ));
            }
        }
    }
    Ok(())
}

/// Checks degree-valued keys against the models' own ranges, converted to degrees, so a bad value is reported
/// in the unit the user wrote (the models' checks speak radians): each entry is (key, value, low, high).
fn check_degrees(keys: &[(&str, f32, f32, f32)]) -> Result<(), String> {
    for &(key, value, lo, hi) in keys {
        if !(lo..=hi).contains(&value) {
            return Err(format!(
                "material.{key} must be in [{lo}, {hi}] degrees, got {value}"
            ));
        }
    }
    Ok(())
}

/// The narrowest lobe width the models accept ([`crate::bsdf::WIDTH_MIN`]), degrees (rounded up).
const WIDTH_MIN_DEG: f32 = 0.0058;

/// Largest Kajiya-Kay exponent p: cos^p θ at p = 10⁴ is a lobe under 1° wide, narrower than any hair highlight
/// (the R lobe is 5–10° wide, Marschner et al. 2003), and its normalisation (p + 2)/2π and sampled pdf stay far
/// from f32 overflow (p = 10³⁰ made them infinite, and the pixels NaN).
pub const MAX_KK_EXPONENT: f32 = 1e4;

/// Largest glint gain I_g: 100 lets glints outshine the TRT lobe they sit on by two orders of magnitude (Ou et
/// al. 2012 use gains of a few units); larger values are a typo, and 10³⁰ overflowed the film to infinity.
pub const MAX_GLINT: f32 = 100.0;

fn rad(deg: f32) -> f32 {
    deg.to_radians()
}

impl MaterialConfig {
    /// The model's scene name.
    pub fn name(&self) -> &'static str {
        match self {
            MaterialConfig::KajiyaKay(_) => "kajiya-kay",
            MaterialConfig::Marschner(_) => "marschner",
            MaterialConfig::Ishair(_) => "ishair",
            MaterialConfig::Chiang(_) => "chiang",
        }
    }

    /// Builds the model, or a message naming the offending `material.key`.
    pub fn build(&self) -> Result<Material, String> {
        // One piece: one arm per model, each mapping the paper's parameters as the user writes them.
        // The models name their own parameters; prefix with the table so the user finds the key.
        let named = |e: crate::bsdf::BsdfError| format!("material: {e}");
        let white = |c: Option<[f32; 3]>| c.map_or(Vec3::ONE, Vec3::from);
        let (scattering, tint_diffuse_by_strand) = match self {
            MaterialConfig::KajiyaKay(c) => {
                if !(..=MAX_KK_EXPONENT).contains(&c.exponent) {
                    return Err(format!(
                        "material.exponent must be in [1, {MAX_KK_EXPONENT:e}], got {}",
                        c.exponent
                    ));
                }
                check_colors(&[("color", c.color)])?;
                if c.diffuse < 0.0 || c.specular < 0.0 || c.diffuse + c.specular > 1.0 {
                    return Err(format!(
                        "material.diffuse and material.specular must be >= 0 with a sum <= 1, got {} and {}",
                        c.diffuse, c.specular
                    ));
                }
                let model = KajiyaKay::from_params(KajiyaKayParams {
                    k_d: white(c.color) * c.diffuse,
                    k_s: c.specular,
                    p: c.exponent,
                    balance: Balance::Sum,
                    sampling: c.sampling.into(),
                })
                .map_err(named)?;
                (Scattering::KajiyaKay(model), c.color.is_none())
            }
            MaterialConfig::Marschner(c) => {
                check_colors(&[
                    ("color", c.color),
                    ("k_s1", Some(c.k_s1)),
                    ("k_s2", Some(c.k_s2)),
                ])?;
                check_widths(&[("beta_1", c.beta_1), ("beta_2", c.beta_2)])?;
                check_degrees(&[
                    ("alpha_1", c.alpha_1, -45.0, 45.0),
                    ("alpha_2", c.alpha_2, -45.0, 45.0),
                    ("beta_1", c.beta_1, WIDTH_MIN_DEG, 90.0),
                    ("beta_2", c.beta_2, WIDTH_MIN_DEG, 90.0),
                ])?;
                let model = Marschner::new(MarschnerParams {
                    k_d: white(c.color),
                    k_s1: c.k_s1.into(),
                    alpha_1: rad(c.alpha_1),
                    beta_1: rad(c.beta_1),
                    k_s2: c.k_s2.into(),
                    alpha_2: rad(c.alpha_2),
                    beta_2: rad(c.beta_2),
                    balance: balance(c.balance, c.specular, c.eta),
                    sampling: c.sampling.into(),
                })
                .map_err(named)?;
                (Scattering::Marschner(model), c.color.is_none())
            }
            MaterialConfig::Ishair(c) => {
                check_colors(&[
                    ("color", c.color),
                    ("color_r", Some(c.color_r)),
                    ("color_tt", Some(c.color_tt)),
                    ("color_trt", Some(c.color_trt)),
                ])?;
                if !(..=MAX_GLINT).contains(&c.glint) {
                    return Err(format!(
                        "material.glint must be in [0, {MAX_GLINT}], got {}",
                        c.glint
                    ));
                }
                check_widths(&[
                    ("beta_r", c.beta_r),
                    ("beta_tt", c.beta_tt),
                    ("beta_trt", c.beta_trt),
                    ("gamma_tt", c.gamma_tt),
                    ("gamma_g", c.gamma_g),
                ])?;
                check_degrees(&[
                    ("alpha_r", c.alpha_r, -45.0, 45.0),
                    ("alpha_tt", c.alpha_tt, -45.0, 45.0),
                    ("alpha_trt", c.alpha_trt, -45.0, 45.0),
                    ("beta_r", c.beta_r, WIDTH_MIN_DEG, 90.0),
                    ("beta_tt", c.beta_tt, WIDTH_MIN_DEG, 90.0),
                    ("beta_trt", c.beta_trt, WIDTH_MIN_DEG, 90.0),
                    ("gamma_tt", c.gamma_tt, WIDTH_MIN_DEG, 360.0),
                    ("gamma_g", c.gamma_g, WIDTH_MIN_DEG, 360.0),
                    ("phi_g", c.phi_g, 0.0, 90.0),
                ])?;
                let model = IsHair::new(IsHairParams {
                    k_d: white(c.color),
                    color_r: c.color_r.into(),
                    color_tt: c.color_tt.into(),
                    color_trt: c.color_trt.into(),
                    glint: c.glint,
                    alpha_r: rad(c.alpha_r),
                    beta_r: rad(c.beta_r),
                    alpha_tt: rad(c.alpha_tt),
                    beta_tt: rad(c.beta_tt),
                    alpha_trt: rad(c.alpha_trt),
                    beta_trt: rad(c.beta_trt),
                    gamma_tt: rad(c.gamma_tt),
                    gamma_g: rad(c.gamma_g),
                    phi_g: rad(c.phi_g),
                    balance: balance(c.balance, c.specular, c.eta),
                    sampling: c.sampling.into(),
                    selection: match c.selection {
                        SelectionName::Uniform => LobeSelection::Uniform,
                        SelectionName::ByEnergy => LobeSelection::ByEnergy,
                    },
                })
                .map_err(named)?;
                (Scattering::IsHair(model), c.color.is_none())
            }
            // No diffuse lobe: the strand colours of the file are unused.
            MaterialConfig::Chiang(c) => (
                Scattering::Chiang(Chiang::new(c.params()?).map_err(keyed)?),
                false,
            ),
        };
        Ok(Material {
            scattering,
            tint_diffuse_by_strand,
            name: self.name(),
            dual: Default::default(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn named_defaults_are_what_the_model_key_alone_gives() {
        for name in MODELS {
            let parsed: MaterialConfig = toml::from_str(&format!("model = \"{name}\"")).unwrap();
            let named = MaterialConfig::named(name).unwrap();
            assert_eq!(format!("{named:?}"), format!("{parsed:?}"));
            assert_eq!(named.name(), name);
        }
        assert!(MaterialConfig::named("phong").is_none());
    }

    /// Every model name a scene accepts.
    const MODELS: [&str; 4] = ["kajiya-kay", "marschner", "ishair", "chiang"];

    fn parse(text: &str) -> Result<MaterialConfig, String> {
        #[derive(Deserialize)]
        struct Wrapper {
            material: MaterialConfig,
        }
        toml::from_str::<Wrapper>(text)
            .map(|w| w.material)
            .map_err(|e| e.to_string())
    }

    #[test]
    fn every_model_builds_with_defaults() {
        for model in MODELS {
            let m = parse(&format!("[material]\nmodel = \"{model}\"\n")).unwrap();
            assert_eq!(m.name(), model);
            m.build().unwrap();
        }
    }

    #[test]
    fn defaults_round_trip_to_the_model_defaults() {
        // Degrees in the file, radians in the model: the conversion must give back the papers' numbers.
        let c = MarschnerConfig::default();
        let p = MarschnerParams::default();
        assert!((rad(c.beta_1) - p.beta_1).abs() < 1e-7);
        assert!((rad(c.alpha_2) - p.alpha_2).abs() < 1e-7);
        let c = IsHairConfig::default();
        let p = IsHairParams::default();
        assert!((rad(c.phi_g) - p.phi_g).abs() < 1e-7);
        assert!((rad(c.gamma_tt) - p.gamma_tt).abs() < 1e-7);
        let c = ChiangConfig::default();
        assert_eq!(c.params().unwrap(), ChiangParams::default());
    }

    fn chiang_params(keys: &str) -> Result<ChiangParams, String> {
        match parse(&format!("[material]\nmodel = \"chiang\"\n{keys}\n"))? {
            MaterialConfig::Chiang(c) => {
                let params = c.params()?;
                MaterialConfig::Chiang(c).build()?;
                Ok(params)
            }
            other => panic!("parsed {other:?}"),
        }
    }

    #[test]
    fn chiang_takes_its_colour_three_ways() {
        let p = chiang_params("sigma_a = [0.1, 0.2, 0.3]\nalpha = -3.0").unwrap();
        assert_eq!(p.sigma_a, Vec3::new(0.1, 0.2, 0.3));
        assert!((p.alpha - (-3f32).to_radians()).abs() < 1e-7);
        let p = chiang_params("eumelanin = 0.5").unwrap();
        assert_eq!(p.sigma_a, chiang::sigma_a_from_melanin(0.5, 0.0).unwrap());
        let p = chiang_params("pheomelanin = 2.0").unwrap();
        assert_eq!(p.sigma_a, chiang::sigma_a_from_melanin(0.0, 2.0).unwrap());
        // The colour is inverted at the scene's beta_n (eq. 9 depends on it), and comes back.
        let p = chiang_params("color = [0.5, 0.3, 0.1]\nbeta_n = 0.6").unwrap();
        let back = chiang::color_from_sigma_a(p.sigma_a, 0.6);
        assert!(
            (back - Vec3::new(0.5, 0.3, 0.1)).abs().max_element() < 1e-4,
            "{back}"
        );
        // No colour key: the model's default.
        assert_eq!(
            chiang_params("").unwrap().sigma_a,
            ChiangParams::default().sigma_a
        );
        // The material has no diffuse lobe for strand colours to tint.
        let m = parse("[material]\nmodel = \"chiang\"\n").unwrap();
        assert!(!m.build().unwrap().tint_diffuse_by_strand);
    }

    #[test]
    fn chiang_refuses_two_colour_ways_naming_the_keys() {
        for (keys, named) in [
            (
                "sigma_a = [0.1, 0.2, 0.3]\ncolor = [0.5, 0.5, 0.5]",
                ["sigma_a", "color"],
            ),
            (
                "sigma_a = [0.1, 0.2, 0.3]\neumelanin = 1.0",
                ["sigma_a", "eumelanin"],
            ),
            (
                "pheomelanin = 1.0\ncolor = [0.5, 0.5, 0.5]",
                ["pheomelanin", "color"],
            ),
        ] {
            let err = chiang_params(keys).unwrap_err();
            for key in named {
                assert!(err.contains(key), "{keys}: {err}");
            }
        }
    }

    #[test]
    fn chiang_bad_values_name_the_key() {
        for (keys, key) in [
            ("beta_m = 0.0", "material.beta_m"),
            ("beta_m = 1.5", "material.beta_m"),
            ("beta_n = -0.1", "material.beta_n"),
            ("alpha = 30.0", "material.alpha"),
            ("alpha = nan", "material.alpha"),
            ("eta = 1.0", "material.eta"),
            ("sigma_a = [0.1, -0.2, 0.3]", "material.sigma_a"),
            ("eumelanin = -1.0", "material.eumelanin"),
            ("pheomelanin = inf", "material.pheomelanin"),
            ("color = [0.5, 0.0, 0.5]", "material.color"),
            ("color = [0.5, 1.5, 0.5]", "material.color"),
            ("color = [0.5, 0.5, 0.5]\nbeta_n = 0.0", "material.beta_n"),
        ] {
            let err = chiang_params(keys).unwrap_err();
            assert!(err.starts_with(key), "{keys}: {err}");
        }
        // Marschner's keys are not chiang's.
        let err = chiang_params("beta_1 = 5.0").unwrap_err();
        assert!(err.contains("beta_1"), "{err}");
    }

    #[test]
    fn non_positive_width_names_the_key() {
        for (model, key) in [
            ("marschner", "beta_1"),
            ("marschner", "beta_2"),
            ("ishair", "beta_tt"),
            ("ishair", "gamma_g"),
        ] {
            for value in ["0.0", "-3.0"] {
                let m = parse(&format!(
                    "[material]\nmodel = \"{model}\"\n{key} = {value}\n"
                ))
                .unwrap();
                let err = m.build().unwrap_err();
                assert!(err.contains(&format!("material.{key}")), "{err}");
            }
        }
    }

    #[test]
    fn published_sampling_is_marschner_only() {
        let ok = parse("[material]\nmodel = \"marschner\"\nsampling = \"published\"\n").unwrap();
        ok.build().unwrap();
        let bad = parse("[material]\nmodel = \"ishair\"\nsampling = \"published\"\n").unwrap();
        let err = bad.build().unwrap_err();
        assert!(err.contains("published"), "{err}");
    }

    #[test]
    fn chiang_takes_the_uniform_sampling_key() {
        let m = parse("[material]\nmodel = \"chiang\"\nsampling = \"uniform\"\n").unwrap();
        let MaterialConfig::Chiang(c) = &m else {
            panic!("not chiang: {m:?}")
        };
        assert_eq!(c.params().unwrap().sampling, Sampling::Uniform);
        m.build().unwrap();
        let bad = parse("[material]\nmodel = \"chiang\"\nsampling = \"published\"\n").unwrap();
        let err = bad.build().unwrap_err();
        assert!(err.contains("published"), "{err}");
    }

    #[test]
    fn unknown_keys_and_models_are_refused() {
        let err = parse("[material]\nmodel = \"marschner\"\nbeta_3 = 1.0\n").unwrap_err();
        assert!(err.contains("beta_3"), "{err}");
        let err = parse("[material]\nmodel = \"phong\"\n").unwrap_err();
        assert!(err.contains("phong"), "{err}");
    }

    #[test]
    fn absent_color_tints_by_strand() {
        let m = parse("[material]\nmodel = \"kajiya-kay\"\n").unwrap();
        assert!(m.build().unwrap().tint_diffuse_by_strand);
        let m = parse("[material]\nmodel = \"ishair\"\ncolor = [0.2, 0.1, 0.05]\n").unwrap();
        assert!(!m.build().unwrap().tint_diffuse_by_strand);
        assert!(
            MaterialConfig::Marschner(MarschnerConfig::default())
                .build()
                .unwrap()
                .tint_diffuse_by_strand
        );
    }
}
