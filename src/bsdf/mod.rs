//! Fibre scattering models, in the thesis' §4.1 hair frame. Directions `wo` (towards the viewer) and `wi`
//! (towards the light) both point away from the fibre; `tangent` runs root → tip.
//!
//! # Frame and conventions (all models)
//!
//! Every [`Bsdf`] method takes directions in the **local hair frame** of [`frame::HairFrame`]: component
//! `x` along u (the tangent, root → tip), `y` along v and `z` along w (v, w span the normal plane; u × v = w).
//! So sin θ = ω.x (θ ∈ [−π/2, π/2], the longitudinal angle from the normal plane) and φ = atan2(ω.z, ω.y)
//! (φ ∈ [−π, π], 0 along v, π/2 along w). Directions are unit vectors with finite components.
//!
//! f is returned in the **fibre convention**: L_o(ωo) = ∫_S² f(ωo, ωi) L_i(ωi) cos θi dωi with cos θi the
//! cosine of the *longitudinal* angle (|ωi × u|), and dω = cos θ dθ dφ. Each model file states the convention of
//! its paper and converts at its edge. pdfs are densities per unit solid angle (sr⁻¹), so a sample's weight is
//! f · cos θi / pdf.
//!
//! # Models
//!
//! - [`kajiya_kay`]: Kajiya & Kay 1989 diffuse + specular cone (also the diffuse term of the other two).
//! - [`marschner`]: the R lobe of Marschner et al. 2003 as importance sampled by Hery & Ramamoorthi 2012
//!   (thesis §4.2), two R-type lobes (primary and secondary highlight, thesis §5.3.1).
//! - [`ishair`]: Sadeghi et al. 2010's four lobes as importance sampled by Ou et al. 2012 (thesis §4.3).
//! - [`chiang`]: Chiang et al. 2016's energy-conserving near/far-field model (d'Eon et al. 2011's M_p), the one
//!   production renderers ship; [`chiang::Chiang::at`] gives it at an offset h across the fibre.
//!
//! Shared pieces sit in their own files: [`frame`] (hair frame, θ/φ conversions), [`gaussian`] (Gaussians, erf,
//! truncated Gaussian sampling), [`cauchy`] (truncated Cauchy sampling), [`fresnel`] (dielectric Fresnel, for
//! [`Balance::Fresnel`]), [`lobe_curves`] (f per lobe along θi or φ) and [`histogram`] (sampled directions against
//! the pdf); the last two are plain data, which `cuticle plot-bsdf` draws in `crate::plot::bsdf`. Tools that are not
//! physics sit below, in [`crate::util`]: uniform sphere sampling ([`crate::util::sampling`]), luminance
//! ([`crate::util::color`]), the chi-square test ([`crate::util::stats`]); tests and plots draw their random numbers
//! from `rand_pcg`'s PCG32.

pub mod cauchy;
pub mod chiang;
pub mod dual;
pub mod frame;
pub mod fresnel;
pub mod gaussian;
pub mod histogram;
pub mod ishair;
pub mod kajiya_kay;
pub mod lanes;
pub mod lobe_curves;
pub mod marschner;
pub mod material;
#[cfg(test)]
mod testing;

use crate::util::real::Real;
use glam::{Vec3, Vec3A};

pub use material::{HitBsdf, Material, PreparedBsdf, PreparedLanes, Scattering};

/// A fibre scattering model in the local hair frame (see the module docs for axes and conventions).
///
/// Every method returns finite values for every unit `wo`, `wi` (including θ = ±π/2 and φ = ±π).
pub trait Bsdf {
    /// f(ωo, ωi) per lobe, RGB, for AOVs. [`Bsdf::eval`] is their sum.
    fn eval_lobes(&self, wo: Vec3, wi: Vec3) -> LobeValues;

    /// f(ωo, ωi), RGB, in the fibre convention (L_o = ∫ f L_i cos θi dωi).
    fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.eval_lobes(wo, wi).sum()
    }

    /// Draws ωi given ωo from three uniform numbers in [0, 1). `None` when the model has no sample to give
    /// (every model here always returns one; the integrator must still handle `None`).
    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample>;

    /// The density, per unit solid angle, with which [`Bsdf::sample`] draws `wi` given `wo`. For
    /// [`Sampling::ClampAndFlip`] this is the density *claimed* by Hery & Ramamoorthi 2012 (thesis eq. 13), which
    /// is not the one their sampler draws from.
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32;
}

/// One sampled direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BsdfSample {
    /// The sampled incident direction, local hair frame, unit length.
    pub wi: Vec3,
    /// f(ωo, ωi) of the whole model (all lobes).
    pub f: Vec3,
    /// [`Bsdf::pdf`] of `wi` (the whole mixture, not only the lobe drawn), sr⁻¹, > 0.
    pub pdf: f32,
    /// f · cos θi / pdf: the Monte Carlo weight of this sample.
    pub weight: Vec3,
    /// The lobe whose sampler drew `wi`; `None` for [`Sampling::Uniform`].
    pub lobe: Option<Lobe>,
}

/// The lobes the AOVs separate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Lobe {
    /// Surface reflection (Kajiya-Kay's specular cone; Marschner's primary highlight).
    R,
    /// Transmission through the fibre (forward scattering).
    Tt,
    /// Internal reflection without the glint (Marschner's secondary highlight, ISHair's TRT − g).
    Trt,
    /// The two caustic glints of TRT (ISHair's N_g).
    Glint,
    /// Kajiya-Kay diffuse.
    Diffuse,
}

impl Lobe {
    /// Every lobe, in AOV order.
    pub const ALL: [Lobe; 5] = [Lobe::R, Lobe::Tt, Lobe::Trt, Lobe::Glint, Lobe::Diffuse];

    /// A short lower-case name for AOV channels and plots.
    pub fn name(self) -> &'static str {
        match self {
            Lobe::R => "r",
            Lobe::Tt => "tt",
            Lobe::Trt => "trt",
            Lobe::Glint => "glint",
            Lobe::Diffuse => "diffuse",
        }
    }
}

/// f of each lobe, RGB (zero for the lobes a model does not have).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LobeValues {
    /// [`Lobe::R`].
    pub r: Vec3A,
    /// [`Lobe::Tt`].
    pub tt: Vec3A,
    /// [`Lobe::Trt`].
    pub trt: Vec3A,
    /// [`Lobe::Glint`].
    pub glint: Vec3A,
    /// [`Lobe::Diffuse`].
    pub diffuse: Vec3A,
}

impl LobeValues {
    /// The sum of all lobes: the model's f.
    #[inline]
    pub fn sum(&self) -> Vec3 {
        Vec3::from(self.r + self.tt + self.trt + self.glint + self.diffuse)
    }

    /// The value of one lobe.
    pub fn get(&self, lobe: Lobe) -> Vec3A {
        match lobe {
            Lobe::R => self.r,
            Lobe::Tt => self.tt,
            Lobe::Trt => self.trt,
            Lobe::Glint => self.glint,
            Lobe::Diffuse => self.diffuse,
        }
    }

    /// A mutable reference to one lobe's value.
    pub fn get_mut(&mut self, lobe: Lobe) -> &mut Vec3A {
        match lobe {
            Lobe::R => &mut self.r,
            Lobe::Tt => &mut self.tt,
            Lobe::Trt => &mut self.trt,
            Lobe::Glint => &mut self.glint,
            Lobe::Diffuse => &mut self.diffuse,
        }
    }

    /// Every lobe scaled by `s`.
    pub fn scaled(&self, s: f32) -> LobeValues {
        LobeValues {
            r: self.r * s,
            tt: self.tt * s,
            trt: self.trt * s,
            glint: self.glint * s,
            diffuse: self.diffuse * s,
        }
    }
}

/// How [`Bsdf::sample`] draws directions. Variants are never mixed silently: a model that cannot honour one
/// refuses it in its constructor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Sampling {
    /// Importance sampling whose [`Bsdf::pdf`] is exactly the density the sampler draws from (Ou et al.'s
    /// Cauchy sampling for ISHair; a truncated Gaussian by inverse CDF for Marschner and the Kajiya-Kay cone).
    #[default]
    ExactPdf,
    /// Hery & Ramamoorthi 2012 as published (thesis eq. 7–13): Box-Muller, θs clamped, θi flipped. Biased: the
    /// claimed pdf (eq. 13) is not the sampled density. Only [`marschner::Marschner`] accepts it.
    ClampAndFlip,
    /// Uniform over the sphere (pdf 1/4π), the baseline the thesis asks importance sampling be compared with
    /// (§7, §8.2).
    Uniform,
}

impl Sampling {
    /// The name used in scene files and messages.
    pub fn name(self) -> &'static str {
        match self {
            Sampling::ExactPdf => "importance",
            Sampling::ClampAndFlip => "published",
            Sampling::Uniform => "uniform",
        }
    }
}

/// How the specular lobes and the Kajiya-Kay diffuse term are weighted against each other:
/// f = w_d · f_diffuse + w_s · f_specular.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Balance {
    /// w_d = w_s = 1: the colours already carry the balance (what [`kajiya_kay::KajiyaKay::new`] does; the scene
    /// checks `diffuse + specular ≤ 1`).
    Sum,
    /// Thesis §5.3: a user factor s ∈ [0, 1] interpolates linearly, w_s = s, w_d = 1 − s.
    User {
        /// s, the specular share.
        specular: f32,
    },
    /// Thesis §8.2 (further work; RenderMan's plausible shaders): w_s = F(η, θo), w_d = 1 − F, with F the
    /// unpolarised dielectric Fresnel reflectance of the view direction on the fibre's centre line (h = 0, so the
    /// angle of incidence is θo). Depends on ωo only, so a model balanced this way is **not reciprocal**.
    Fresnel {
        /// Relative index of refraction of the cuticle, > 1 (hair keratin: 1.55, Marschner et al. 2003).
        eta: f32,
    },
}

impl Default for Balance {
    /// An even split, w_s = w_d = 1/2 (chosen here; the thesis leaves the factor to the user).
    fn default() -> Self {
        Balance::User { specular: 0.5 }
    }
}

impl Balance {
    /// (w_d, w_s) for a view direction with longitudinal cosine `cos_theta_o`, in any number type ([`Real`]): one
    /// view per lane.
    #[inline]
    pub fn weights<R: Real>(&self, cos_theta_o: R) -> (R, R) {
        match *self {
            Balance::Sum => (R::splat(1.0), R::splat(1.0)),
            Balance::User { specular } => (R::splat(1.0 - specular), R::splat(specular)),
            Balance::Fresnel { eta } => {
                let f = fresnel::dielectric(cos_theta_o, eta);
                (R::splat(1.0) - f, f)
            }
        }
    }

    /// Checks the parameters, naming the offending key for `model`.
    pub fn validate(&self, model: &'static str) -> Result<(), BsdfError> {
        match *self {
            Balance::Sum => Ok(()),
            Balance::User { specular } => check(
                model,
                "specular",
                specular,
                "in [0, 1]",
                (0.0..=1.0).contains(&specular),
            ),
            Balance::Fresnel { eta } => check(
                model,
                "eta",
                eta,
                "> 1 and finite",
                eta > 1.0 && eta.is_finite(),
            ),
        }
    }
}

/// A [`BsdfSample`] from its parts, with the weight f · cos θi / pdf; `None` unless the pdf is positive.
#[inline]
pub(crate) fn make_sample(
    wi: Vec3,
    f: Vec3,
    pdf: f32,
    cos_theta_i: f32,
    lobe: Option<Lobe>,
) -> Option<BsdfSample> {
    if !(pdf > 0.0 && pdf.is_finite()) {
        return None;
    }
    // One division for the three channels; but for a subnormal pdf (a sample far in a lobe's tail, where f is as
    // tiny) cos θi / pdf alone would overflow, so f cos θi comes first there.
    let weight = if pdf >= f32::MIN_POSITIVE {
        f * (cos_theta_i / pdf)
    } else {
        (f * cos_theta_i) / pdf
    };
    debug_assert!(
        weight.is_finite(),
        "weight {weight} for wi {wi}, f {f}, pdf {pdf}"
    );
    Some(BsdfSample {
        wi,
        f,
        pdf,
        weight,
        lobe,
    })
}

/// A parameter a model refuses, with what it should have been.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BsdfError {
    /// A numeric parameter out of its range.
    #[error("{model}: {key} must be {requirement}, got {value}")]
    Parameter {
        /// The model (`"marschner"`, `"ishair"`, `"kajiya-kay"`).
        model: &'static str,
        /// The parameter's name, as in the model's parameter struct.
        key: &'static str,
        /// What was expected, e.g. "> 0 radians".
        requirement: &'static str,
        /// What was given (for colours: the smallest channel).
        value: f32,
    },
    /// A sampling mode the model does not implement.
    #[error("{model}: sampling = \"{sampling}\" is not available for this model (only marschner has \"published\")")]
    Sampling {
        /// The model.
        model: &'static str,
        /// The refused mode's name.
        sampling: &'static str,
    },
}

/// `Ok` if `ok`, else a [`BsdfError::Parameter`].
pub(crate) fn check(
    model: &'static str,
    key: &'static str,
    value: f32,
    requirement: &'static str,
    ok: bool,
) -> Result<(), BsdfError> {
    if ok {
        Ok(())
    } else {
        Err(BsdfError::Parameter {
            model,
            key,
            requirement,
            value,
        })
    }
}

/// Checks an albedo-like RGB colour is in [0, 1] per channel (a fibre scatters at most the light that reaches it);
/// the value reported is the channel out of range.
pub(crate) fn check_color(
    model: &'static str,
    key: &'static str,
    c: Vec3,
) -> Result<(), BsdfError> {
    let bad = c.to_array().into_iter().find(|v| !(0.0..=1.0).contains(v));
    check(
        model,
        key,
        bad.unwrap_or(0.0),
        "in [0, 1] per channel",
        bad.is_none(),
    )
}

/// Checks an RGB coefficient (an absorption σa) is finite and ≥ 0 per channel.
pub(crate) fn check_coefficient(
    model: &'static str,
    key: &'static str,
    c: Vec3,
) -> Result<(), BsdfError> {
    let ok = c.is_finite() && c.min_element() >= 0.0;
    check(
        model,
        key,
        if c.is_finite() {
            c.min_element()
        } else {
            f32::NAN
        },
        ">= 0 and finite per channel",
        ok,
    )
}

/// Checks an angular width (β, γ) is in [`WIDTH_MIN`], `max`] radians.
pub(crate) fn check_width(
    model: &'static str,
    key: &'static str,
    value: f32,
    max: f32,
    requirement: &'static str,
) -> Result<(), BsdfError> {
    check(
        model,
        key,
        value,
        requirement,
        value >= WIDTH_MIN && value <= max,
    )
}

/// The smallest lobe width accepted, radians (0.0057°): far below any paper's range (≥ 0.5°), far above where
/// f32 Gaussians and Cauchy pdfs would overflow.
pub const WIDTH_MIN: f32 = 1e-4;
