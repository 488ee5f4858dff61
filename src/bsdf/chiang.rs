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
//! Lobes: R (p = 0) → [`LobeValues::r`](super::LobeValues::r), TT (p = 1) → `tt`, TRT (p = 2) **and** the residual p ≥ 3 → `trt`;
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
//!   pbrt-v4 takes h = 2v − 1 and leaves the sign to the ribbon's orientation. [`super::frame::h_from_normal`] and
//!   [`super::frame::h_from_ribbon`] compute both (tested against a ray–cylinder intersection). Not reciprocal because of h:
//!   swapping ωo and ωi keeps the view's h.
//!
//! # Sampling
//!
//! p is chosen with probability lum(A_p)/Σ lum(A_p) (Rec. 709 luminance), θi is drawn from M_p exactly (d'Eon
//! et al.'s von Mises–Fisher construction: cos of the angle to the mirror direction by inverting
//! ∝ e^{cos/v}, a uniform azimuth about it, then its θ), φ from the trimmed logistic about Φ(p) by inverting its
//! CDF (uniform for p = 3). [`Bsdf::pdf`](super::Bsdf::pdf) is the whole mixture Σ_p P(p) M_p N_p (per solid angle), exactly what
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
mod longitudinal;
#[cfg(test)]
mod tests;

pub use azimuthal::{a_p, phi_p, sample_trimmed_logistic, trimmed_logistic};
pub use bessel::{i0, i0e, log_i0};
pub use longitudinal::m_p;

use azimuthal::{luminance, wrap, Azimuthal};
use longitudinal::{m_p_of, sample_sin_theta, Longitudinal};

use super::frame::COS_THETA_MIN;
use super::lanes::{At, EvalOf, Fibre, LobesOf, SampleOf};
use super::{check, check_coefficient, BsdfError, Sampling};
use crate::util::real::{Kernel, Real};
use crate::util::sampling::UNIFORM_SPHERE_PDF;
use glam::Vec3;
use std::f32::consts::{FRAC_PI_8, PI, TAU};

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

/// Chiang et al. 2016's fibre model with its constants: a [`Fibre`] (one implementation for one shading point and
/// for eight); [`Chiang::at`] gives the scalar [`super::Bsdf`] at an offset h.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Chiang {
    params: ChiangParams,
    /// M_p of p = 0, 1, 2 (variances v₀, v₀/4, 4v₀); the residual p = 3 shares p = 2's (4v₀), so it is stored
    /// once ([`Chiang::longitudinal`]).
    longitudinal: [Longitudinal; P_MAX],
    /// N_p's trimmed logistic.
    azimuthal: Azimuthal,
    /// (sin 2^k α, cos 2^k α) for k = 0, 1, 2.
    tilt: [(f32, f32); 3],
}

impl Chiang {
    /// A checked model (ranges in the module docs' table).
    pub fn new(params: ChiangParams) -> Result<Chiang, BsdfError> {
        let p = params;
        check_coefficient(MODEL, "sigma_a", p.sigma_a)?;
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
        let tilt = [1.0f64, 2.0, 4.0].map(|k| {
            let (s, c) = (k * p.alpha as f64).sin_cos();
            (s as f32, c as f32)
        });
        Ok(Chiang {
            params,
            longitudinal,
            azimuthal: Azimuthal::new(logistic_scale(p.beta_n)),
            tilt,
        })
    }

    /// M_p's terms for order `p` (0 ..= [`P_MAX`]; the residual shares p = 2's variance).
    #[inline(always)]
    fn longitudinal(&self, p: usize) -> &Longitudinal {
        &self.longitudinal[p.min(P_MAX - 1)]
    }

    /// The parameters the model was built with.
    pub fn params(&self) -> &ChiangParams {
        &self.params
    }

    /// The variances v of M_p for p = 0, 1, 2 and the residual.
    pub fn variances(&self) -> [f32; P_MAX + 1] {
        [0, 1, 2, 3].map(|p| self.longitudinal(p).v)
    }

    /// The logistic scale s of N_p.
    pub fn logistic_scale(&self) -> f32 {
        self.azimuthal.s
    }

    /// The model at offset `h` = sin γo across the fibre (module docs: sign and where it comes from), as a scalar
    /// [`super::Bsdf`]. Values a rounding outside [−1, 1] are clamped.
    pub fn at(&self, h: f32) -> At<'_, Chiang> {
        debug_assert!(h.is_finite() && h.abs() <= 1.0 + 1e-3, "h = {h}");
        At { model: self, h }
    }

    /// Whether directions are sampled uniformly ([`Sampling::Uniform`]).
    #[inline(always)]
    fn uniform(&self) -> bool {
        self.params.sampling == Sampling::Uniform
    }

    /// A_p per order and channel and Φ(p) for p = 0, 1, 2 at offset `h` (clamped to [−1, 1]) seen from an ωo of
    /// inclination (`sin_o`, `cos_o` ≥ 0): the terms of N_p and A_p that depend on the hit (module docs).
    #[inline(always)]
    pub fn azimuthal_terms<R: Real>(
        &self,
        h: R,
        sin_o: R,
        cos_o: R,
    ) -> ([[R; 3]; P_MAX + 1], [R; P_MAX]) {
        let one = R::splat(1.0);
        let zero = R::splat(0.0);
        let eta = self.params.eta;
        let h = h.clamp_to(-1.0, 1.0);
        let gamma_o = h.asin();
        let cos_gamma_o = (one - h * h).max(zero).sqrt();
        // Refraction into the fibre: θt (sin θt = sin θo/η) and, in the normal plane, γt with Bravais' index η′.
        let sin_t = sin_o / R::splat(eta);
        let cos_t = (one - sin_t * sin_t).max(zero).sqrt();
        let eta_p = (R::splat(eta * eta) - sin_o * sin_o).max(zero).sqrt()
            / cos_o.max(R::splat(COS_THETA_MIN));
        let sin_gt = (h / eta_p).clamp_to(-1.0, 1.0);
        let gamma_t = sin_gt.asin();
        let cos_gt = (one - sin_gt * sin_gt).max(zero).sqrt();
        // One chord of length 2 cos γt / cos θt radii; cos θt ≥ √(1 − 1/η²) > 0.
        let chord = R::splat(2.0) * cos_gt / cos_t;
        let sigma = self.params.sigma_a;
        let t: [R; 3] = std::array::from_fn(|c| (-R::splat(sigma[c]) * chord).exp());
        let ap = a_p(cos_o, cos_gamma_o, eta, t);
        let phis = std::array::from_fn(|p| phi_p(p, gamma_o, gamma_t));
        (ap, phis)
    }

    /// (sin θo′, |cos θo′|) per order p = 0 ..= [`P_MAX`] for an ωo of inclination (`sin_o`, `cos_o`): the tilted
    /// angles M_p is evaluated at, θo − 2α (R), θo + α (TT), θo + 4α (TRT), θo (residual).
    #[inline(always)]
    pub fn tilted<R: Real>(&self, sin_o: R, cos_o: R) -> [(R, R); P_MAX + 1] {
        let rot = |(s, c): (f32, f32), sign: f32| {
            let (s, c) = (R::splat(sign * s), R::splat(c));
            (
                sin_o.mul_add(c, cos_o * s),
                cos_o.mul_sub(c, sin_o * s).abs(),
            )
        };
        [
            rot(self.tilt[1], -1.0),
            rot(self.tilt[0], 1.0),
            rot(self.tilt[2], 1.0),
            (sin_o, cos_o),
        ]
    }
}

/// What Chiang's eval and sample share for one hit (its h and ωo), per lane: computed once per shading point
/// ([`Fibre::view`]) and reused by its light samples, its material sample and their pdfs.
#[derive(Debug, Clone, Copy)]
pub struct ChiangView<R> {
    /// ωo's components in the normal plane (y, z): φ is measured from it.
    wo_y: R,
    wo_z: R,
    /// A_p per p and colour channel.
    ap: [[R; 3]; P_MAX + 1],
    /// P(p) = lum(A_p)/Σ lum(A_p).
    ap_pdf: [R; P_MAX + 1],
    /// Φ(p) for p = 0, 1, 2.
    phis: [R; P_MAX],
    /// (sin θo′, |cos θo′|) per p.
    tilted_sin: [R; P_MAX + 1],
    tilted_cos: [R; P_MAX + 1],
}

/// M_p N_p of one order ([`Kernel`]): arguments 1/v, ln c(v) + 1/v, sin θi, cos θi, sin θo′, cos θo′, φ − Φ(p) and
/// 1 for the residual p ≥ 3 (whose N_p is uniform, 1/2π) or 0.
struct LobeTerm<'a>(&'a Azimuthal);

impl Kernel<8> for LobeTerm<'_> {
    #[inline(always)]
    fn run<R: Real>(&self, [inv_v, log_norm, si, ci, so, co, dphi, residual]: [R; 8]) -> R {
        let m = m_p_of(inv_v, log_norm, [si, ci, so, co]);
        let n = R::select(
            residual.gt(R::splat(0.0)),
            R::splat(0.5 / PI),
            self.0.eval(wrap(dphi)),
        );
        m * n
    }
}

/// (sin θ, cos θ ≥ 0) of a local direction (x along the fibre), scaled to unit length.
#[inline(always)]
fn sin_cos_theta<R: Real>([x, y, z]: [R; 3]) -> (R, R) {
    let rho = y.mul_add(y, z * z).sqrt();
    let inv_len = R::splat(1.0) / x.mul_add(x, rho * rho).sqrt();
    (x * inv_len, rho * inv_len)
}

/// Per lane, `values[p]` for the order `p_of` (0 ..= [`P_MAX`], as a number).
#[inline(always)]
fn pick<R: Real>(p_of: R, values: [R; P_MAX + 1]) -> R {
    (1..=P_MAX).fold(values[0], |acc, p| {
        R::select(p_of.eq(R::splat(p as f32)), values[p], acc)
    })
}

impl Fibre for Chiang {
    type View<R: Real> = ChiangView<R>;

    fn uses_offset(&self) -> bool {
        true
    }

    #[inline(always)]
    fn view<R: Real>(&self, h: R, wo: [R; 3]) -> ChiangView<R> {
        let (sin_o, cos_o) = sin_cos_theta(wo);
        let (ap, phis) = self.azimuthal_terms(h, sin_o, cos_o);
        let lum = ap.map(|a| luminance(&a));
        // A₀ = F ≥ ((η − 1)/(η + 1))² > 0, so the total is positive.
        let total = lum[0] + lum[1] + lum[2] + lum[3];
        let ap_pdf = lum.map(|l| l / total);
        let tilted = self.tilted(sin_o, cos_o);
        ChiangView {
            wo_y: wo[1],
            wo_z: wo[2],
            ap,
            ap_pdf,
            phis,
            tilted_sin: tilted.map(|t| t.0),
            tilted_cos: tilted.map(|t| t.1),
        }
    }

    #[inline(always)]
    fn eval_view<R: Real>(&self, view: &ChiangView<R>, wi: [R; 3]) -> EvalOf<R> {
        let (sin_i, cos_i) = sin_cos_theta(wi);
        let [_, y, z] = wi;
        // φ = φi − φo.
        let phi = view
            .wo_y
            .mul_sub(z, view.wo_z * y)
            .atan2(view.wo_y.mul_add(y, view.wo_z * z));
        // M_p N_p of the four orders, side by side in lanes for one shading point ([`Real::four`]).
        let lobe = |p: usize| {
            let l = self.longitudinal(p);
            let (dphi, residual) = if p < P_MAX {
                (phi - view.phis[p], 0.0)
            } else {
                (R::splat(0.0), 1.0)
            };
            [
                R::splat(l.inv_v),
                R::splat(l.log_norm),
                sin_i,
                cos_i,
                view.tilted_sin[p],
                view.tilted_cos[p],
                dphi,
                R::splat(residual),
            ]
        };
        let mn = R::four(
            &LobeTerm(&self.azimuthal),
            [lobe(0), lobe(1), lobe(2), lobe(3)],
        );
        let inv_cos = R::splat(1.0) / cos_i.max(R::splat(COS_THETA_MIN));
        let f = |p: usize| -> [R; 3] { std::array::from_fn(|c| view.ap[p][c] * mn[p] * inv_cos) };
        let (f2, f3) = (f(2), f(3));
        let pdf = if self.uniform() {
            R::splat(UNIFORM_SPHERE_PDF)
        } else {
            (0..=P_MAX).fold(R::splat(0.0), |s, p| view.ap_pdf[p].mul_add(mn[p], s))
        };
        EvalOf {
            lobes: LobesOf {
                r: f(0),
                tt: f(1),
                trt: std::array::from_fn(|c| f2[c] + f3[c]),
                ..LobesOf::zero()
            },
            pdf,
        }
    }

    /// p by P(p) (the remainder of u₀, rescaled, turns the longitudinal lobe's azimuth), sin θi by d'Eon et al.'s
    /// inverse CDF, φi by the trimmed logistic about Φ(p) (uniform for the residual), then f and the pdf at the
    /// sampled ωi, as eval sees it: at βm, βn ~ 1e-3 (lobes 0.02° wide) the rounding of ωi and of its azimuth move
    /// f by more than values at the drawn angles could be trusted to match. Lanes whose A_p all vanish take the
    /// last p with P(p) > 0, remainder ½.
    #[inline(always)]
    fn sample_view<R: Real>(&self, view: &ChiangView<R>, u: [R; 3]) -> SampleOf<R> {
        let one = R::splat(1.0);
        let zero = R::splat(0.0);
        if self.uniform() {
            let sin_i = (one - R::splat(2.0) * u[0]).clamp_to(-1.0, 1.0);
            let cos_i = (one - sin_i * sin_i).max(zero).sqrt();
            let (s, c) = (R::splat(TAU) * u[1]).sin_cos();
            let wi = [sin_i, cos_i * c, cos_i * s];
            return SampleOf {
                wi,
                eval: self.eval_view(view, wi),
                lobe: R::splat(-1.0),
            };
        }
        // p by P(p): r < q_p picks p, else r −= q_p; rounding can leave r past the sum.
        let mut r = u[0];
        let mut chosen = zero.lt(zero); // no lane yet
        let mut p_of = R::splat(-1.0);
        let mut remainder = R::splat(0.5);
        for p in 0..=P_MAX {
            let q = view.ap_pdf[p];
            let take = r.lt(q) & !chosen;
            p_of = R::select(take, R::splat(p as f32), p_of);
            remainder = R::select(take, (r / q).min(one), remainder);
            chosen = chosen | take;
            r -= q;
        }
        let mut last = zero;
        for p in 0..=P_MAX {
            last = R::select(view.ap_pdf[p].gt(zero), R::splat(p as f32), last);
        }
        let p_of = R::select(chosen, p_of, last);
        let tilted = (pick(p_of, view.tilted_sin), pick(p_of, view.tilted_cos));
        let per_p = |f: &dyn Fn(&Longitudinal) -> f32| {
            pick(
                p_of,
                std::array::from_fn(|p| R::splat(f(self.longitudinal(p)))),
            )
        };
        let sin_i = sample_sin_theta(
            per_p(&|l| l.v),
            per_p(&|l| l.one_minus_e),
            u[1],
            remainder,
            tilted,
        );
        let cos_i = (one - sin_i * sin_i).max(zero).sqrt();
        // φi − φo: Φ(p) plus the trimmed logistic's draw, uniform for the residual.
        let phis = pick(p_of, [view.phis[0], view.phis[1], view.phis[2], zero]);
        let residual = p_of.eq(R::splat(P_MAX as f32));
        let dphi = R::select(
            residual,
            R::splat(TAU) * u[2],
            phis + self.azimuthal.sample(u[2]),
        );
        let phi_i = view.wo_z.atan2(view.wo_y) + dphi;
        let (s, c) = phi_i.sin_cos();
        let wi = [sin_i, cos_i * c, cos_i * s];
        SampleOf {
            wi,
            eval: self.eval_view(view, wi),
            // R, TT, TRT (the residual is reported as TRT, the lobe it is added to).
            lobe: p_of.min(R::splat(2.0)),
        }
    }
}
