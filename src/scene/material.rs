//! `[material]`: which fibre model shades the hair, with its parameters as a user writes them (angles in degrees,
//! colours linear RGB), and how they become a [`Bsdf`].
//!
//! ```toml
//! [material]
//! model = "marschner"        # or "ishair", "kajiya-kay"
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
//! **Strand colour.** Without `color`, the renderer multiplies the *diffuse* lobe by the strand's colour from the
//! hair file (the other lobes keep their explicit colours: the cuticle's reflection R is not pigmented, and TT/TRT
//! colours are parameters of the models).

use glam::Vec3;
use serde::Deserialize;

use crate::bsdf::ishair::{IsHair, IsHairParams, LobeSelection};
use crate::bsdf::kajiya_kay::{KajiyaKay, KajiyaKayParams};
use crate::bsdf::marschner::{Marschner, MarschnerParams};
use crate::bsdf::{Balance, Bsdf, Material, Sampling};

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
    pub color: Option<[f32; 3]>,
    /// Primary highlight colour k_s,1.
    pub k_s1: [f32; 3],
    /// Primary shift α_1, degrees.
    pub alpha_1: f32,
    /// Primary width β_1, degrees, > 0.
    pub beta_1: f32,
    /// Secondary highlight colour k_s,2.
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
    pub color: Option<[f32; 3]>,
    /// C_R.
    pub color_r: [f32; 3],
    /// C_TT.
    pub color_tt: [f32; 3],
    /// C_TRT.
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
        }
    }

    /// Builds the model, or a message naming the offending `material.key`.
    pub fn build(&self) -> Result<Material, String> {
        // The models name their own parameters; prefix with the table so the user finds the key.
        let named = |e: crate::bsdf::BsdfError| format!("material: {e}");
        let white = |c: Option<[f32; 3]>| c.map_or(Vec3::ONE, Vec3::from);
        let (bsdf, color): (Box<dyn Bsdf + Send + Sync>, _) = match self {
            MaterialConfig::KajiyaKay(c) => {
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
                (Box::new(model), c.color)
            }
            MaterialConfig::Marschner(c) => {
                check_widths(&[("beta_1", c.beta_1), ("beta_2", c.beta_2)])?;
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
                (Box::new(model), c.color)
            }
            MaterialConfig::Ishair(c) => {
                check_widths(&[
                    ("beta_r", c.beta_r),
                    ("beta_tt", c.beta_tt),
                    ("beta_trt", c.beta_trt),
                    ("gamma_tt", c.gamma_tt),
                    ("gamma_g", c.gamma_g),
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
                (Box::new(model), c.color)
            }
        };
        Ok(Material {
            bsdf,
            tint_diffuse_by_strand: color.is_none(),
            name: self.name(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn named_defaults_are_what_the_model_key_alone_gives() {
        for name in ["kajiya-kay", "marschner", "ishair"] {
            let parsed: MaterialConfig = toml::from_str(&format!("model = \"{name}\"")).unwrap();
            let named = MaterialConfig::named(name).unwrap();
            assert_eq!(format!("{named:?}"), format!("{parsed:?}"));
            assert_eq!(named.name(), name);
        }
        assert!(MaterialConfig::named("chiang").is_none());
    }

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
        for model in ["kajiya-kay", "marschner", "ishair"] {
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
