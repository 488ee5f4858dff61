//! The energy-conserving near/far-field fibre model of Chiang, Bitterli, Tappan & Burley 2016, "A practical and
//! controllable hair and fur model for production path tracing", with the longitudinal term of d'Eon, Francois,
//! Hill, Letteri & Aubry 2011, "An energy-conserving hair reflectance model" (thesis §8.2's planned model).
//! The model Cycles' Principled Hair, pbrt-v4's `HairBxDF` and Mitsuba 3's `hair` implement.
//!
//! # Model (fibre convention, see [`super`])
//!
//! f(ωo, ωi) = Σ_{p=0}^{3} M_p(θi, θo′_p) A_p(θo, h) N_p(φ, h) / cos θi, so that ∫ f cos θi dωi = Σ A_p: with
//! σa = 0 the A_p sum to 1 and the model is exactly energy conserving (white furnace = 1, tested). The 1/cos θi
//! converts the paper's L_o = ∫ S L_i dωi (pbrt-v4 divides by |cos θ| for the same reason) to this crate's
//! convention.
//!
//! - **M_p** (d'Eon et al. 2011): M_p = csch(1/v)/(2v) · exp(−sin θi sin θo′/v) · I₀(cos θi cos θo′/v), the
//!   θ-marginal of a von Mises–Fisher lobe of concentration 1/v about the mirror direction of θo′, normalised so
//!   that ∫ M_p cos θi dθi = 1 for every θo′. Evaluated here in log space for **every** v (the paper asks it for
//!   v < 0.1) with the exponentially scaled Bessel function: M_p = exp(ln c(v) + (cos(θi + θo′) − 1)/v) · I₀ₑ(a),
//!   a = cos θi cos θo′/v, I₀ₑ(x) = e^{−x} I₀(x), ln c(v) = −ln v − ln(1 − e^{−2/v}). Nothing overflows for any
//!   v ≥ 1e-7, and [`i0e`] is accurate to ~4e-12 relative over [0, ∞) (the power series to 32 terms below 12, the
//!   asymptotic expansion to its smallest term above; tested against an independent quadrature to 1e-9). The
//!   peers' 10-term series misses ~2 % of I₀(12) (the terms k ≥ 10 sum to ~385 of 18948), which is where their
//!   M_p loses energy near βm ≈ 0.1.
//! - **Variances**: v₀ = (0.726 βm + 0.812 βm² + 3.7 βm²⁰)² (the paper's fit), v₁ = v₀/4, v₂ = v₃ = 4 v₀.
//! - **Tilt α** of the cuticle scales: θo′ = θo − 2α for R, θo + α for TT, θo + 4α for TRT, θo for p ≥ 3, so the
//!   peaks sit at θi = −θo + 2α, −θo − α, −θo − 4α (as the paper and pbrt-v4: R shifted by 2α, TT by −α, TRT by
//!   −4α). α > 0 moves R towards +u (the tip, θ > 0). |cos θo′| is used where the tilt passes the pole (pbrt-v4).
//! - **A_p** (attenuation): F = dielectric Fresnel ([`super::fresnel::dielectric`]) at cos = cos θo cos γo and
//!   the fibre's IOR η; A₀ = F, A₁ = (1 − F)² T, A₂ = A₁ F T, A₃ = A₂ F T/(1 − F T) (every p ≥ 3 summed), with
//!   T = exp(−σa · 2 cos γt / cos θt) the transmittance of one chord of the refracted path, γt from
//!   sin γt = h/η′, η′ = √(η² − sin²θo)/cos θo (Bravais' index) and sin θt = sin θo/η.
//! - **N_p** (azimuth): the logistic of scale s trimmed to [−π, π], about Φ(p, h) = 2p γt − 2γo + pπ, in
//!   φ = φi − φo wrapped to [−π, π] (**note**: the paper's and pbrt-v4's sign, the opposite of the relative azimuth
//!   φr − φi of [`super::frame::Angles`]). s = √(π/8) (0.265 βn + 1.194 βn² + 5.372 βn²²) (the paper's fit).
//!   N₃ = 1/2π.
//!
//! Lobes: R (p = 0) → [`LobeValues::r`], TT (p = 1) → `tt`, TRT (p = 2) **and** the residual p ≥ 3 → `trt`;
//! `glint` and `diffuse` are zero.
//!
//! # Units and conventions
//!
//! - **σa is per unit fibre radius**: T = exp(−σa · ℓ) with ℓ = 2 cos γt / cos θt the path length of one chord
//!   measured in radii (a cylinder of radius 1). This is pbrt-v4's `HairBxDF` (and pbrt-v3's, which Cycles'
//!   Principled Hair ports), so their σa values carry over unchanged. A σa per unit *diameter* σ_d is σ_d/2 here;
//!   an absorption per unit world length σ is σ · r here, r the fibre radius in world units.
//! - **Melanin** ([`sigma_a_from_melanin`]): σa = c_eu (0.419, 0.697, 1.37) + c_pheo (0.187, 0.4, 1.05), the
//!   absorption coefficients pbrt-v4 (`SigmaAFromConcentration`) and Mitsuba 3 use. Cycles uses another pair
//!   (0.506, 0.841, 1.653) / (0.343, 0.733, 1.924) and maps its "melanin" and "redness" to concentrations
//!   first; pass its σa directly to reproduce it.
//! - **Colour** ([`sigma_a_from_color`]): Chiang et al.'s eq. 9, σa = (ln C / (5.969 − 0.215 βn + 2.532 βn² −
//!   10.73 βn³ + 5.574 βn⁴ + 0.245 βn⁵))², per channel, C ∈ (0, 1] (the colour of a whole volume of such hair
//!   after multiple scattering, not of one fibre).
//! - **h** = sin γo ∈ [−1, 1], the signed offset of the hit across the fibre in radii. In the local hair frame,
//!   γo is the angle, in the normal plane and counter-clockwise about u (from v towards w), from the outward
//!   normal n at the hit to ωo's projection ω̂o⊥: the normal's azimuth is φn = φo − γo. Equivalently
//!   h = u · (n × ω̂o⊥) = ((p − c)/r) · (ω̂o⊥ × u), with p − c the hit's offset from the fibre axis. So h > 0 puts
//!   the R peak at φ = φi − φo = −2γo < 0 (tested against a mirror reflection on the cylinder). Round curves: from
//!   the hit's outward normal and the ray (the first formula). Flat ribbons: p − c = (2v − 1) r b with v ∈ [0, 1]
//!   Embree's coordinate across the ribbon and b the unit vector of increasing v, so h = (2v − 1) b · (ω̂o⊥ × u);
//!   pbrt-v4 takes h = 2v − 1 and leaves the sign to the ribbon's orientation. [`h_from_normal`] and
//!   [`h_from_ribbon`] compute both (tested against a ray–cylinder intersection). Not reciprocal because of h:
//!   swapping ωo and ωi keeps the view's h.
//!
//! # Sampling
//!
//! p is chosen with probability lum(A_p)/Σ lum(A_p) (Rec. 709 luminance), θi is drawn from M_p exactly (d'Eon
//! et al.'s von Mises–Fisher construction: cos of the angle to the mirror direction by inverting
//! ∝ e^{cos/v}, a uniform azimuth about it, then its θ), φ from the trimmed logistic about Φ(p) by inverting its
//! CDF (uniform for p = 3). [`Bsdf::pdf`] is the whole mixture Σ_p P(p) M_p N_p (per solid angle), exactly what
//! `sample` draws (χ² tested), so with σa = 0 every sample's weight f cos θi/pdf is 1.
//!
//! [`Sampling::Uniform`] (`sampling = "uniform"`): directions uniform over the sphere and pdf 1/4π, the baseline
//! importance sampling is measured against (`cuticle study sampling`), as the other models have it.
//! [`Sampling::ClampAndFlip`] is Marschner's alone and refused.
//!
//! # Reciprocity
//!
//! **Not reciprocal**, as published: A_p depends on θo (Fresnel at cos θo cos γo, the chord length through cos θt)
//! and on the view's offset h, and the tilt shifts θo only. M_p(θi, θo) = M_p(θo, θi) and, at h = 0,
//! N_p(φ) = N_p(−φ) hold term by term (tested); the whole f does not (tested).
//!
//! # Parameters ([`ChiangParams`]; angles in radians)
//!
//! | name | meaning | range | default |
//! |---|---|---|---|
//! | `sigma_a` | absorption per unit fibre radius, RGB | ≥ 0, finite | eumelanin 1.3 (pbrt-v4's default): (0.5447, 0.9061, 1.781) |
//! | `beta_m` | longitudinal roughness | [1e-3, 1] | 0.3 (pbrt-v4, Mitsuba 3) |
//! | `beta_n` | azimuthal roughness | [1e-3, 1] | 0.3 |
//! | `alpha` | cuticle scale tilt | \|α\| ≤ π/8 | 2° (pbrt-v4, Mitsuba 3) |
//! | `eta` | index of refraction of the fibre | (1, 10] | 1.55 (keratin, Marschner et al. 2003) |
//! | `sampling` | how directions are sampled | exact pdf or uniform | exact pdf |
//!
//! The roughness fits were made for βm, βn ∈ [0, 1]; below 1e-3 the lobes are narrower than f32 directions
//! resolve.

mod azimuthal;
mod bessel;
mod lanes;
mod longitudinal;
#[cfg(test)]
mod tests;

pub use azimuthal::{a_p, phi_p, sample_trimmed_logistic, trimmed_logistic};
pub use bessel::{i0, i0e, log_i0};
pub use lanes::{directions, EvalLanes, ViewLanes, LANES};
pub use longitudinal::m_p;

use azimuthal::Azimuthal;
use bessel::{I0_ASYMPTOTIC, I0_SERIES, M_P_SWITCH};
use longitudinal::{m_p_lanes, sin_cos_theta_f64, Longitudinal};

use super::frame::{atan2, phi as azimuth, wrap_phi, COS_THETA_MIN};
use super::{check, check_color, Bsdf, BsdfError, BsdfSample, Lobe, LobeValues, Sampling};
use crate::util::color::luminance;
use crate::util::lanes::exp_f32x4;
use crate::util::sampling::{uniform_sphere, UNIFORM_SPHERE_PDF};
use glam::{Vec3, Vec3A};
use std::f32::consts::{FRAC_PI_8, PI, TAU};
use wide::{f32x4, f64x4};

/// The highest scattering order with its own lobe; [`P_MAX`] itself stands for every p ≥ 3.
pub const P_MAX: usize = 3;

/// Absorption coefficients of eumelanin per unit concentration and unit fibre radius, RGB (pbrt-v4
/// `HairBxDF::SigmaAFromConcentration`, Mitsuba 3 `hair`).
pub const EUMELANIN_SIGMA_A: Vec3 = Vec3::new(0.419, 0.697, 1.37);

/// Absorption coefficients of pheomelanin, as [`EUMELANIN_SIGMA_A`].
pub const PHEOMELANIN_SIGMA_A: Vec3 = Vec3::new(0.187, 0.4, 1.05);

/// The smallest roughness βm, βn accepted.
pub const BETA_MIN: f32 = 1e-3;

/// The model's name in error messages.
const MODEL: &str = "chiang";

/// The parameters of [`Chiang::new`] (see the module docs' table).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChiangParams {
    /// σa, absorption per unit fibre radius, RGB.
    pub sigma_a: Vec3,
    /// βm, longitudinal roughness.
    pub beta_m: f32,
    /// βn, azimuthal roughness.
    pub beta_n: f32,
    /// α, cuticle scale tilt, radians.
    pub alpha: f32,
    /// η, the fibre's index of refraction.
    pub eta: f32,
    /// How directions are sampled: [`Sampling::ExactPdf`] or [`Sampling::Uniform`].
    pub sampling: Sampling,
}

impl Default for ChiangParams {
    fn default() -> Self {
        ChiangParams {
            sigma_a: EUMELANIN_SIGMA_A * 1.3,
            beta_m: 0.3,
            beta_n: 0.3,
            alpha: 2f32.to_radians(),
            eta: 1.55,
            sampling: Sampling::ExactPdf,
        }
    }
}

/// σa (per unit fibre radius) of a mix of eumelanin and pheomelanin concentrations (≥ 0):
/// c_eu [`EUMELANIN_SIGMA_A`] + c_pheo [`PHEOMELANIN_SIGMA_A`].
pub fn sigma_a_from_melanin(eumelanin: f32, pheomelanin: f32) -> Result<Vec3, BsdfError> {
    for (key, c) in [("eumelanin", eumelanin), ("pheomelanin", pheomelanin)] {
        check(MODEL, key, c, ">= 0 and finite", c >= 0.0 && c.is_finite())?;
    }
    Ok(eumelanin * EUMELANIN_SIGMA_A + pheomelanin * PHEOMELANIN_SIGMA_A)
}

/// The denominator of Chiang et al.'s eq. 9, a polynomial fit in βn.
#[inline]
fn eq9_denominator(beta_n: f32) -> f32 {
    let b = beta_n;
    5.969 - 0.215 * b + 2.532 * b * b - 10.73 * b.powi(3) + 5.574 * b.powi(4) + 0.245 * b.powi(5)
}

/// σa (per unit fibre radius) that gives a volume of hair the colour `color` (each channel in (0, 1]) at azimuthal
/// roughness `beta_n` (Chiang et al. eq. 9): σa = (ln C / D(βn))².
pub fn sigma_a_from_color(color: Vec3, beta_n: f32) -> Result<Vec3, BsdfError> {
    let ok = color.is_finite() && color.min_element() > 0.0 && color.max_element() <= 1.0;
    check(
        MODEL,
        "color",
        if ok {
            color.min_element()
        } else if color.is_finite() {
            if color.min_element() <= 0.0 {
                color.min_element()
            } else {
                color.max_element()
            }
        } else {
            f32::NAN
        },
        "in (0, 1] per channel",
        ok,
    )?;
    check_beta("beta_n", beta_n)?;
    let d = eq9_denominator(beta_n);
    Ok(color.to_array().map(|c| (c.ln() / d).powi(2)).into())
}

/// The colour eq. 9 assigns to `sigma_a` at `beta_n`: C = exp(−√σa · D(βn)) (the inverse of
/// [`sigma_a_from_color`]).
pub fn color_from_sigma_a(sigma_a: Vec3, beta_n: f32) -> Vec3 {
    let d = eq9_denominator(beta_n);
    sigma_a.to_array().map(|s| (-s.sqrt() * d).exp()).into()
}

fn check_beta(key: &'static str, beta: f32) -> Result<(), BsdfError> {
    check(
        MODEL,
        key,
        beta,
        "in [1e-3, 1]",
        (BETA_MIN..=1.0).contains(&beta),
    )
}

/// v₀, the variance of the R lobe's M_p, from βm (the paper's fit): (0.726 βm + 0.812 βm² + 3.7 βm²⁰)².
#[inline]
pub fn longitudinal_variance(beta_m: f32) -> f32 {
    let b = beta_m;
    (0.726 * b + 0.812 * b * b + 3.7 * b.powi(20)).powi(2)
}

/// s, the logistic scale of N_p, from βn (the paper's fit): √(π/8) (0.265 βn + 1.194 βn² + 5.372 βn²²).
#[inline]
pub fn logistic_scale(beta_n: f32) -> f32 {
    let b = beta_n;
    const SQRT_PI_OVER_8: f32 = 0.626_657;
    SQRT_PI_OVER_8 * (0.265 * b + 1.194 * b * b + 5.372 * b.powi(22))
}

// ---------------------------------------------------------------------------------------------------------------
// The model.

/// Chiang et al. 2016's fibre model with its constants; [`Chiang::at`] gives the [`Bsdf`] at an offset h.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Chiang {
    params: ChiangParams,
    /// M_p of p = 0, 1, 2 (variances v₀, v₀/4, 4v₀); the residual p = 3 shares p = 2's (4v₀), so it is stored
    /// once ([`Chiang::longitudinal`]; this keeps [`super::Scattering`] within clippy's variant-size bound).
    longitudinal: [Longitudinal; P_MAX],
    /// N_p's trimmed logistic.
    azimuthal: Azimuthal,
    /// (sin 2^k α, cos 2^k α) for k = 0, 1, 2.
    tilt: [(f64, f64); 3],
}

impl Chiang {
    /// A checked model (ranges in the module docs' table).
    pub fn new(params: ChiangParams) -> Result<Chiang, BsdfError> {
        let p = params;
        check_color(MODEL, "sigma_a", p.sigma_a)?;
        check_beta("beta_m", p.beta_m)?;
        check_beta("beta_n", p.beta_n)?;
        check(
            MODEL,
            "alpha",
            p.alpha,
            "in [-pi/8, pi/8] radians",
            p.alpha.abs() <= FRAC_PI_8,
        )?;
        check(
            MODEL,
            "eta",
            p.eta,
            "in (1, 10]",
            p.eta > 1.0 && p.eta <= 10.0,
        )?;
        if p.sampling == Sampling::ClampAndFlip {
            return Err(BsdfError::Sampling {
                model: MODEL,
                sampling: p.sampling.name(),
            });
        }
        let v0 = longitudinal_variance(p.beta_m) as f64;
        let longitudinal = [v0, 0.25 * v0, 4.0 * v0].map(Longitudinal::new);
        let tilt = [1.0f64, 2.0, 4.0].map(|k| (k * p.alpha as f64).sin_cos());
        Ok(Chiang {
            params,
            longitudinal,
            azimuthal: Azimuthal::new(logistic_scale(p.beta_n)),
            tilt,
        })
    }

    /// M_p's terms for order `p` (0 ..= [`P_MAX`]; the residual shares p = 2's variance).
    #[inline]
    fn longitudinal(&self, p: usize) -> &Longitudinal {
        &self.longitudinal[p.min(P_MAX - 1)]
    }

    /// The parameters the model was built with.
    pub fn params(&self) -> &ChiangParams {
        &self.params
    }

    /// The variances v of M_p for p = 0, 1, 2 and the residual.
    pub fn variances(&self) -> [f64; P_MAX + 1] {
        [0, 1, 2, 3].map(|p| self.longitudinal(p).v)
    }

    /// The logistic scale s of N_p.
    pub fn logistic_scale(&self) -> f32 {
        self.azimuthal.s
    }

    /// The model at offset `h` = sin γo across the fibre (module docs: sign and where it comes from). Values a
    /// rounding outside [−1, 1] are clamped.
    pub fn at(&self, h: f32) -> ChiangFibre<'_> {
        debug_assert!(h.is_finite() && h.abs() <= 1.0 + 1e-3, "h = {h}");
        let h = h.clamp(-1.0, 1.0);
        ChiangFibre {
            model: self,
            h,
            gamma_o: h.asin(),
            cos_gamma_o: (1.0 - h * h).max(0.0).sqrt(),
        }
    }
}

/// h = sin γo for a hit on a **round** fibre: u · (n × ω̂o⊥), with `tangent` u, `normal` n the outward surface
/// normal at the hit and ω̂o⊥ the unit projection of `wo` (towards the viewer) on the normal plane. Any frame
/// (world or local): a triple product. Neither n nor u need be unit or exactly orthogonal (they are projected);
/// 0 if `wo` runs along u or n along u. Clamped to [−1, 1].
pub fn h_from_normal(tangent: Vec3, normal: Vec3, wo: Vec3) -> f32 {
    let u = tangent.normalize_or_zero();
    let n = normal.reject_from_normalized(u).normalize_or_zero();
    let w = wo.reject_from_normalized(u).normalize_or_zero();
    u.dot(n.cross(w)).clamp(-1.0, 1.0)
}

/// h = sin γo for a hit on a **flat ribbon** standing for a fibre: (2v − 1) b · (ω̂o⊥ × u), with `v` ∈ [0, 1]
/// the hit's coordinate across the ribbon, `across` the direction b in which v grows, u the `tangent`. For a
/// ribbon facing the viewer b · (ω̂o⊥ × u) = ±1, so |h| = |2v − 1| and the sign says which side of the fibre the
/// hit stands for (the same h a round fibre of the ribbon's width gives at the same offset; tested).
pub fn h_from_ribbon(v: f32, across: Vec3, tangent: Vec3, wo: Vec3) -> f32 {
    let u = tangent.normalize_or_zero();
    let w = wo.reject_from_normalized(u).normalize_or_zero();
    let b = across.normalize_or_zero();
    ((2.0 * v - 1.0) * b.dot(w.cross(u))).clamp(-1.0, 1.0)
}

/// [`Chiang`] at one offset h across the fibre: the [`Bsdf`].
#[derive(Debug, Clone, Copy)]
pub struct ChiangFibre<'a> {
    model: &'a Chiang,
    h: f32,
    gamma_o: f32,
    cos_gamma_o: f32,
}

/// What depends on ωo (and h) only.
#[derive(Debug, Clone, Copy)]
struct View {
    /// A_p (four lanes each: f per lobe is one product).
    ap: [Vec3A; P_MAX + 1],
    /// P(p) = lum(A_p)/Σ lum(A_p).
    ap_pdf: [f32; P_MAX + 1],
    /// Φ(p) for p = 0, 1, 2.
    phis: [f32; P_MAX],
    /// (sin θo′, |cos θo′|) per p, unit pairs in f64.
    tilted: [(f64, f64); P_MAX + 1],
}

/// Everything [`ChiangFibre`]'s eval, pdf and sample share for one ωo (and h): computed once per shading point
/// ([`ChiangFibre::viewed`]) and reused by its light samples, its material sample and their pdfs through
/// [`Chiang::eval_viewed`] and [`Chiang::sample_viewed`], which give bit for bit what the [`Bsdf`] methods give.
/// A plain value (no borrow), so that a shading point can keep it.
#[derive(Debug, Clone, Copy)]
pub struct ChiangView {
    wo: Vec3,
    h: f32,
    gamma_o: f32,
    cos_gamma_o: f32,
    view: View,
}

impl Chiang {
    /// The fibre of a [`ChiangView`] (no `asin`: γo was kept).
    #[inline]
    fn fibre_of(&self, v: &ChiangView) -> ChiangFibre<'_> {
        ChiangFibre {
            model: self,
            h: v.h,
            gamma_o: v.gamma_o,
            cos_gamma_o: v.cos_gamma_o,
        }
    }

    /// (f per lobe, pdf) at the view's ωo and `wi` (local frame): [`Bsdf::eval_lobes`] and [`Bsdf::pdf`] of the
    /// fibre the view was taken at, in one evaluation.
    #[inline]
    pub fn eval_viewed(&self, v: &ChiangView, wi: Vec3) -> (LobeValues, f32) {
        let (sc_i, phi) = ChiangFibre::angles(v.wo, wi);
        self.fibre_of(v).eval_at(&v.view, sc_i, phi)
    }

    /// [`Bsdf::sample`] of the fibre the view was taken at, with f per lobe at the sampled direction (what
    /// [`Bsdf::eval_lobes`] would give there).
    #[inline]
    pub fn sample_viewed(&self, v: &ChiangView, u: [f32; 3]) -> Option<(BsdfSample, LobeValues)> {
        self.fibre_of(v).sample_with(&v.view, v.wo, u)
    }
}

impl<'a> ChiangFibre<'a> {
    /// The model this fibre belongs to.
    pub fn model(&self) -> &'a Chiang {
        self.model
    }
}

impl ChiangFibre<'_> {
    /// The offset h = sin γo.
    pub fn h(&self) -> f32 {
        self.h
    }

    /// What eval, pdf and sample share for `wo` (local frame), to be reused ([`ChiangView`]).
    pub fn viewed(&self, wo: Vec3) -> ChiangView {
        ChiangView {
            wo,
            h: self.h,
            gamma_o: self.gamma_o,
            cos_gamma_o: self.cos_gamma_o,
            view: self.view(wo),
        }
    }

    fn view(&self, wo: Vec3) -> View {
        let m = self.model;
        let eta = m.params.eta;
        let (sin_o64, cos_o64) = sin_cos_theta_f64(wo);
        let (sin_o, cos_o) = (sin_o64 as f32, cos_o64 as f32);
        // Refraction into the fibre: θt (sin θt = sin θo/η) and, in the normal plane, γt with Bravais' index η′.
        let sin_t = sin_o / eta;
        let cos_t = (1.0 - sin_t * sin_t).max(0.0).sqrt();
        let eta_p = (eta * eta - sin_o * sin_o).max(0.0).sqrt() / cos_o.max(COS_THETA_MIN);
        let sin_gt = (self.h / eta_p).clamp(-1.0, 1.0);
        let gamma_t = sin_gt.asin();
        let cos_gt = (1.0 - sin_gt * sin_gt).max(0.0).sqrt();
        // One chord of length 2 cos γt / cos θt radii; cos θt ≥ √(1 − 1/η²) > 0.
        let t = exp_f32x4(f32x4::from(
            (-m.params.sigma_a * (2.0 * cos_gt / cos_t))
                .extend(0.0)
                .to_array(),
        ))
        .to_array();
        let t = Vec3::new(t[0], t[1], t[2]);
        let ap = a_p(cos_o, self.cos_gamma_o, eta, t);
        let lum = ap.map(luminance);
        let total: f32 = lum.iter().sum();
        // A₀ = F ≥ ((η − 1)/(η + 1))² > 0, so the total is positive.
        let ap_pdf = lum.map(|l| l / total);
        let phis = [0, 1, 2].map(|p| phi_p(p, self.gamma_o, gamma_t));
        // Tilts: θo − 2α (R), θo + α (TT), θo + 4α (TRT), θo (residual).
        let rot = |(s, c): (f64, f64), sign: f64| {
            let sin = sin_o64 * c + sign * cos_o64 * s;
            let cos = cos_o64 * c - sign * sin_o64 * s;
            (sin, cos.abs())
        };
        let tilted = [
            rot(m.tilt[1], -1.0),
            rot(m.tilt[0], 1.0),
            rot(m.tilt[2], 1.0),
            (sin_o64, cos_o64),
        ];
        View {
            ap: ap.map(Vec3A::from),
            ap_pdf,
            phis,
            tilted,
        }
    }

    /// M_p N_p per p for an incident direction (sin θi, cos θi) (a unit pair) at azimuth `phi` = φi − φo.
    #[inline]
    fn mn(&self, view: &View, sc_i: (f64, f64), phi: f32) -> [f32; P_MAX + 1] {
        let m = self.model;
        // The lanes written out, not built by `map` over the lobes: the arrays' maps were ~50 of an eval's
        // instructions (callgrind, peer frame). The residual p = 3 shares p = 2's variance.
        let [l0, l1, l2] = &m.longitudinal;
        let mp = m_p_lanes(
            f64x4::new([l0.inv_v, l1.inv_v, l2.inv_v, l2.inv_v]),
            f64x4::new([l0.log_norm, l1.log_norm, l2.log_norm, l2.log_norm]),
            sc_i,
            view.tilted,
        )
        .to_array();
        // The residual's N_p is uniform; its lane of the logistic is computed and dropped (a 4-wide vector).
        let [d0, d1, d2] = view.phis.map(|x| wrap_phi(phi - x));
        let np = m.azimuthal.eval_lanes([d0, d1, d2, d2]);
        [
            mp[0] as f32 * np[0],
            mp[1] as f32 * np[1],
            mp[2] as f32 * np[2],
            mp[3] as f32 * (0.5 / PI),
        ]
    }

    /// The lobes (f per p, R/TT/TRT + residual) and the mixture pdf.
    #[inline]
    fn eval_at(&self, view: &View, sc_i: (f64, f64), phi: f32) -> (LobeValues, f32) {
        let mn = self.mn(view, sc_i, phi);
        let inv_cos = 1.0 / (sc_i.1 as f32).max(COS_THETA_MIN);
        let f = |p: usize| view.ap[p] * (mn[p] * inv_cos);
        let lobes = LobeValues {
            r: f(0),
            tt: f(1),
            trt: f(2) + f(3),
            ..Default::default()
        };
        let pdf = if m_uniform(self.model) {
            UNIFORM_SPHERE_PDF
        } else {
            (0..=P_MAX).map(|p| view.ap_pdf[p] * mn[p]).sum()
        };
        (lobes, pdf)
    }

    /// ((sin θi, cos θi), φi − φo) of a pair.
    #[inline]
    fn angles(wo: Vec3, wi: Vec3) -> ((f64, f64), f32) {
        let sc_i = sin_cos_theta_f64(wi);
        // sin and cos of φi − φo, each scaled by ρo ρi.
        let phi = atan2(wo.y * wi.z - wo.z * wi.y, wo.y * wi.y + wo.z * wi.z);
        (sc_i, phi)
    }
}

/// Whether `m` samples uniformly ([`Sampling::Uniform`]).
#[inline]
fn m_uniform(m: &Chiang) -> bool {
    m.params.sampling == Sampling::Uniform
}

impl Bsdf for ChiangFibre<'_> {
    fn eval_lobes(&self, wo: Vec3, wi: Vec3) -> LobeValues {
        let (sc_i, phi) = Self::angles(wo, wi);
        self.eval_at(&self.view(wo), sc_i, phi).0
    }

    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        self.sample_with(&self.view(wo), wo, u).map(|(s, _)| s)
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let (sc_i, phi) = Self::angles(wo, wi);
        self.eval_at(&self.view(wo), sc_i, phi).1
    }
}

impl ChiangFibre<'_> {
    /// [`Bsdf::sample`] with the view of `wo` given, and f per lobe at the sampled direction.
    #[inline]
    fn sample_with(&self, view: &View, wo: Vec3, u: [f32; 3]) -> Option<(BsdfSample, LobeValues)> {
        let m = self.model;
        if m_uniform(m) {
            let wi = uniform_sphere(u[0], u[1]);
            let (sc_i, phi) = Self::angles(wo, wi);
            let (lobes, pdf) = self.eval_at(view, sc_i, phi);
            return super::make_sample(wi, lobes.sum(), pdf, sc_i.1 as f32, None)
                .map(|s| (s, lobes));
        }
        // p by P(p); the remainder of u[0], rescaled, turns the von Mises–Fisher azimuth. Rounding can leave
        // u[0] past the sum: then the last p with P(p) > 0.
        let mut r = u[0];
        let mut chosen = None;
        for (p, &q) in view.ap_pdf.iter().enumerate() {
            if r < q {
                chosen = Some((p, (r / q).min(1.0)));
                break;
            }
            r -= q;
        }
        let (p, r) = chosen.unwrap_or_else(|| {
            let p = (0..=P_MAX)
                .rev()
                .find(|&p| view.ap_pdf[p] > 0.0)
                .unwrap_or(0);
            (p, 0.5)
        });
        let sin_i = m.longitudinal(p).sample_sin_theta(u[1], r, view.tilted[p]);
        let cos_i = (1.0 - sin_i * sin_i).max(0.0).sqrt();
        let (sin_i, cos_i) = (sin_i as f32, cos_i as f32);
        let dphi = if p < P_MAX {
            view.phis[p] + m.azimuthal.sample(u[2])
        } else {
            TAU * u[2]
        };
        let phi_i = azimuth(wo) + dphi;
        let (s, c) = phi_i.sin_cos();
        let wi = Vec3::new(sin_i, cos_i * c, cos_i * s);
        // f and pdf at the returned (f32) direction, as `eval` and `pdf` see it, not at the drawn angles: at
        // βm, βn ~ 1e-3 (lobes 0.02° wide) the rounding of wi and the arctangent of its azimuth (< 6e-7 rad) move
        // f by more than the drawn angles' values could be trusted to match. The view terms are reused.
        let (sc_i, phi) = Self::angles(wo, wi);
        let (lobes, pdf) = self.eval_at(view, sc_i, phi);
        let lobe = match p {
            0 => Lobe::R,
            1 => Lobe::Tt,
            _ => Lobe::Trt,
        };
        super::make_sample(wi, lobes.sum(), pdf, sc_i.1 as f32, Some(lobe)).map(|s| (s, lobes))
    }
}
