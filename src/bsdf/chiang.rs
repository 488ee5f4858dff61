//! The energy-conserving near/far-field fibre model of Chiang, Bitterli, Tappan & Burley 2016, "A practical and
//! controllable hair and fur model for production path tracing", with the longitudinal term of d'Eon, Francois,
//! Hill, Letteri & Aubry 2011, "An energy-conserving hair reflectance model" (thesis §8.2's planned model; issue
//! 14). The model Cycles' Principled Hair, pbrt-v4's `HairBxDF` and Mitsuba 3's `hair` implement.
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
//!   M_p loses energy near βm ≈ 0.1 (issue 14).
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

mod lanes;

pub use lanes::{directions, EvalLanes, ViewLanes, LANES};

use super::frame::{atan2, phi as azimuth, wrap_phi, COS_THETA_MIN};
use super::fresnel::dielectric;
use super::{check, check_color, Bsdf, BsdfError, BsdfSample, Lobe, LobeValues, Sampling};
use crate::util::color::luminance;
use crate::util::lanes::{exp_f32x4, exp_f64x4};
use crate::util::sampling::{uniform_sphere, UNIFORM_SPHERE_PDF};
use glam::{Vec3, Vec3A};
use std::f32::consts::{FRAC_PI_8, PI, TAU};
use wide::{f32x4, f64x4, CmpLe};

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
// The modified Bessel function of the first kind, order 0.

/// Below this the power series, above it the asymptotic expansion (whose smallest term there is ~1e-11 relative).
const I0_SWITCH: f64 = 12.0;

/// [`m_p_lanes`]' switch between the two expansions, each cut to its first 16 terms: M_p is returned as f32, and at
/// a switch of 10 both stay within 2.2e-9 relative of I₀ (series 1.8e-9 at x = 10, asymptotic 2.2e-9 there; against
/// mpmath's `besseli`, 40 digits), 0.04 of an f32 ulp, where the full 32-term pair at 12 spent twice the
/// multiply-adds on digits the f32 drops (`estrin16_x4`; tested against [`i0e`]).
const M_P_SWITCH: f64 = 10.0;

/// I₀(x) − 1 = y Σ_j y^j/((j + 1)!)², y = x²/4, for |x| ≤ [`I0_SWITCH`]: all terms positive, no cancellation, and
/// relative accuracy also as x → 0 (for [`log_i0`]).
#[inline]
fn i0_series_minus_one(x: f64) -> f64 {
    let y = 0.25 * x * x;
    y * estrin32(&I0_SERIES, y)
}

/// e^{−x} I₀(x) √(2πx) for x > [`I0_SWITCH`] by the asymptotic expansion Σ_k Π_{j≤k} (2j − 1)² / (k! (8x)^k)
/// (Abramowitz & Stegun 9.7.1), to its smallest term at x = 12.
#[inline]
fn i0e_asymptotic_scaled(x: f64) -> f64 {
    estrin32(&I0_ASYMPTOTIC, 1.0 / x)
}

/// Σ_k c_k x^k by Estrin's scheme: pairs, then pairs of pairs with x², x⁴, …, a dependency chain of five
/// multiply-adds where Horner's has 31. Hand-written because M_p's Bessel function is most of an eval (perf: the
/// term-by-term loop it replaced was half of `eval`).
#[inline(always)]
fn estrin32(c: &[f64; 32], x: f64) -> f64 {
    let x2 = x * x;
    let x4 = x2 * x2;
    let x8 = x4 * x4;
    let a: [f64; 16] = std::array::from_fn(|i| c[2 * i] + c[2 * i + 1] * x);
    let b: [f64; 8] = std::array::from_fn(|i| a[2 * i] + a[2 * i + 1] * x2);
    let d: [f64; 4] = std::array::from_fn(|i| b[2 * i] + b[2 * i + 1] * x4);
    let e = [d[0] + d[1] * x8, d[2] + d[3] * x8];
    e[0] + e[1] * (x8 * x8)
}

/// 1/(k!)² for k = 1..32: I₀(x) − 1 = y D(y), y = x²/4, D(y) = Σ_{j<32} y^j/((j + 1)!)². For x ≤ [`I0_SWITCH`]
/// (y ≤ 36) the first omitted term is 36³²/(33!)² ≈ 1e-24 of the sum.
const I0_SERIES: [f64; 32] = [
    1.0,
    0.25,
    0.027777777777777776,
    0.001736111111111111,
    6.944444444444444e-05,
    1.9290123456790124e-06,
    3.936759889140842e-08,
    6.151187326782565e-10,
    7.594058428126624e-12,
    7.594058428126623e-14,
    6.276081345559193e-16,
    4.358389823304995e-18,
    2.5789288895295828e-20,
    1.3157800456783586e-22,
    5.8479113141260385e-25,
    2.2843403570804838e-27,
    7.904291893012054e-30,
    2.4395962632753253e-32,
    6.757884385804225e-35,
    1.6894710964510564e-37,
    3.8310002187098785e-40,
    7.915289708078262e-43,
    1.4962740468957016e-45,
    2.5976979980828152e-48,
    4.156316796932504e-51,
    6.14839762859838e-54,
    8.434015951438106e-57,
    1.0757673407446564e-59,
    1.2791526049282477e-62,
    1.4212806721424974e-65,
    1.4789601166935458e-68,
    1.4442969889585408e-71,
];

/// Π_{j≤k} (2j − 1)²/(8j) for k = 0..23 (then zeros, for [`estrin32`]): e^{−x} I₀(x) √(2πx) = Σ_k A_k x^{−k} (Abramowitz & Stegun 9.7.1). At
/// x = [`I0_SWITCH`] the terms shrink up to k ≈ 24, the last kept ~1e-11 of the sum (the expansion's own limit
/// there); past it they shrink faster.
const I0_ASYMPTOTIC: [f64; 32] = [
    1.0,
    0.125,
    0.0703125,
    0.0732421875,
    0.112152099609375,
    0.22710800170898438,
    0.5725014209747314,
    1.7277275025844574,
    6.074042001273483,
    24.380529699556064,
    110.01714026924674,
    551.3358961220206,
    3038.090510922384,
    18257.755474293175,
    118838.42625678325,
    832859.3040162893,
    6252951.493434797,
    50069589.531988926,
    425939216.5047669,
    3836255180.2304335,
    36468400807.06556,
    364901081884.98334,
    3833534661393.9443,
    42189715702840.97,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
];

/// I₀ₑ(x) = e^{−|x|} I₀(x), the exponentially scaled modified Bessel function of order 0: within 4e-12 relative of
/// an independent quadrature over [1e-3, 2e4] (tested), for every finite x by construction.
#[inline]
pub fn i0e(x: f64) -> f64 {
    let x = x.abs();
    if x <= I0_SWITCH {
        (1.0 + i0_series_minus_one(x)) * (-x).exp()
    } else {
        i0e_asymptotic_scaled(x) / (std::f64::consts::TAU * x).sqrt()
    }
}

/// I₀(x) (overflows to +∞ past x ≈ 713; use [`i0e`] or [`log_i0`] there).
pub fn i0(x: f64) -> f64 {
    let x = x.abs();
    if x <= I0_SWITCH {
        1.0 + i0_series_minus_one(x)
    } else {
        i0e_asymptotic_scaled(x) * x.exp() / (std::f64::consts::TAU * x).sqrt()
    }
}

/// ln I₀(x), accurate in relative terms also where it vanishes (x → 0: ln I₀ ≈ x²/4, by ln(1 + (I₀ − 1))).
pub fn log_i0(x: f64) -> f64 {
    let x = x.abs();
    if x <= I0_SWITCH {
        i0_series_minus_one(x).ln_1p()
    } else {
        x + i0e_asymptotic_scaled(x).ln() - 0.5 * (std::f64::consts::TAU * x).ln()
    }
}

// ---------------------------------------------------------------------------------------------------------------
// The three terms.

/// One longitudinal lobe of variance v, its constants taken once.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Longitudinal {
    /// v.
    v: f64,
    /// 1/v.
    inv_v: f64,
    /// ln c(v) + 1/v = −ln v − ln(1 − e^{−2/v}), with c(v) = csch(1/v)/(2v) M_p's normalisation.
    log_norm: f64,
    /// e^{−2/v}, for the sampler.
    exp_m2_over_v: f64,
}

impl Longitudinal {
    fn new(v: f64) -> Longitudinal {
        Longitudinal {
            v,
            inv_v: 1.0 / v,
            // csch(1/v)/(2v) = e^{−1/v} / (v (1 − e^{−2/v})); the e^{−1/v} goes into the exponent of `eval`.
            log_norm: -v.ln() - (-(-2.0 / v).exp_m1()).ln(),
            exp_m2_over_v: (-2.0 / v).exp(),
        }
    }

    /// M_p(θi, θo′) (d'Eon et al. 2011) from the sines and cosines (cos θo′ ≥ 0), each pair of unit length in
    /// f64 ([`unit_pair`]): [`m_p_lanes`] with one lane.
    #[inline]
    fn eval(&self, sc_i: (f64, f64), sc_o: (f64, f64)) -> f64 {
        m_p_lanes(
            f64x4::splat(self.inv_v),
            f64x4::splat(self.log_norm),
            sc_i,
            [sc_o; 4],
        )
        .to_array()[0]
    }

    /// sin θi of a direction drawn from M_p(·, θo′) (d'Eon et al. 2011's sampling): the cosine of the angle t to
    /// the lobe's centre (θ = −θo′) from the density ∝ e^{cos t/v} on [−1, 1] by its inverse CDF,
    /// cos t = 1 + v ln(ξ + (1 − ξ) e^{−2/v}) with ξ = 1 − `u_t` ∈ (0, 1], then a uniform azimuth 2π `u_phi`
    /// about the centre; sin θi = −cos t sin θo′ + sin t cos(2π u_phi) cos θo′.
    #[inline]
    fn sample_sin_theta(&self, u_t: f32, u_phi: f32, (sin_o, cos_o): (f64, f64)) -> f64 {
        let xi = 1.0 - u_t as f64;
        // w = cos t − 1 ∈ [−2, 0]; sin t = √(−w (2 + w)) keeps its precision for narrow lobes.
        let w = (self.v * (xi + (1.0 - xi) * self.exp_m2_over_v).ln()).max(-2.0);
        let (cos_t, sin_t) = (1.0 + w, (-w * (2.0 + w)).max(0.0).sqrt());
        // The azimuth about the centre in f32 (libm's f64 cos was a tenth of the sampler): it multiplies sin t, so
        // its rounding moves the direction by ~1e-7 of the lobe's width; f and pdf are taken at the result.
        let cos_phi = (TAU * u_phi).cos() as f64;
        (-cos_t * sin_o + sin_t * cos_phi * cos_o).clamp(-1.0, 1.0)
    }
}

/// M_p of N lobes at once, lobe k of variance 1/`inv_v[k]` (normalisation `log_norm[k]`, [`Longitudinal`]) towards
/// its own (tilted) outgoing direction `sc_o[k]`, for one incident direction `sc_i`; each pair (sin, cos) of unit
/// length in f64 ([`unit_pair`]), cos ≥ 0. In log space:
/// exp(ln c + (cos θi cos θo′ − sin θi sin θo′ − 1)/v) · I₀ₑ(cos θi cos θo′/v), in f64: the exponent is a difference
/// of terms ~1/v, and a pair off unit length by an f32 rounding (ε ~ 1e-7) would scale M_p by e^{ε/v}, 0.7 % at
/// βm = 0.01 and a factor e at βm = 1e-3.
///
/// One exponential per lane: where a = cos θi cos θo′/v ≤ [`M_P_SWITCH`] the e^{−a} of I₀ₑ(a) cancels the e^{a} of
/// the exponent, so M_p = exp(ln c − (sin θi sin θo′ + 1)/v) I₀(a) with the series; above, the asymptotic expansion
/// of I₀ₑ. Written lane by lane without branches (a lane takes its branch by a select; a polynomial no lane needs is
/// skipped): Chiang's four lobes go through AVX2 as one f64×4 vector, the exponentials by
/// [`crate::util::lanes::exp_f64x4`].
#[inline(always)]
fn m_p_lanes(inv_v: f64x4, log_norm: f64x4, (si, ci): (f64, f64), sc_o: [(f64, f64); 4]) -> f64x4 {
    let one = f64x4::splat(1.0);
    let switch = f64x4::splat(M_P_SWITCH);
    let cc = f64x4::splat(ci) * f64x4::new(sc_o.map(|s| s.1));
    let ss = f64x4::splat(si) * f64x4::new(sc_o.map(|s| s.0));
    let a = cc * inv_v;
    let series = a.cmp_le(switch);
    let e = exp_f64x4(log_norm + (series.blend(f64x4::ZERO, cc) - ss - one) * inv_v);
    let small = if series.any() {
        let a = a.min(switch);
        let y = f64x4::splat(0.25) * a * a;
        y.mul_add(estrin16_x4(&I0_SERIES, y), one)
    } else {
        f64x4::ZERO
    };
    let large = if series.all() {
        f64x4::ZERO
    } else {
        let inv_a = one / a.max(switch);
        estrin16_x4(&I0_ASYMPTOTIC, inv_a)
            * (inv_a * f64x4::splat(1.0 / std::f64::consts::TAU)).sqrt()
    };
    e * series.blend(small, large)
}

/// The first 16 terms of a [`estrin32`] table in four lanes at once: what [`m_p_lanes`] needs for an f32 result
/// with its switch at [`M_P_SWITCH`].
#[inline(always)]
fn estrin16_x4(c: &[f64; 32], x: f64x4) -> f64x4 {
    let x2 = x * x;
    let x4 = x2 * x2;
    let x8 = x4 * x4;
    let a: [f64x4; 8] =
        std::array::from_fn(|i| f64x4::splat(c[2 * i + 1]).mul_add(x, f64x4::splat(c[2 * i])));
    let b: [f64x4; 4] = std::array::from_fn(|i| a[2 * i + 1].mul_add(x2, a[2 * i]));
    let d0 = b[1].mul_add(x4, b[0]);
    let d1 = b[3].mul_add(x4, b[2]);
    d1.mul_add(x8, d0)
}

/// M_p(θi, θo) for variance `v` (d'Eon et al. 2011), from the sines and cosines (cos ≥ 0); normalised so that
/// ∫ M_p cos θi dθi = 1 over [−π/2, π/2].
pub fn m_p(v: f64, sin_theta_i: f32, cos_theta_i: f32, sin_theta_o: f32, cos_theta_o: f32) -> f64 {
    Longitudinal::new(v).eval(
        unit_pair(sin_theta_i as f64, cos_theta_i as f64),
        unit_pair(sin_theta_o as f64, cos_theta_o as f64),
    )
}

/// (sin θ, cos θ) from any (x, ρ) with ρ ≥ 0, not both zero, scaled to unit length in f64; (0, 1) for zero.
#[inline]
fn unit_pair(x: f64, rho: f64) -> (f64, f64) {
    let len2 = x * x + rho * rho;
    if len2 > 0.0 {
        let inv = 1.0 / len2.sqrt();
        (x * inv, rho * inv)
    } else {
        (0.0, 1.0)
    }
}

/// (sin θ, cos θ) of a local direction, of unit length in f64.
#[inline]
fn sin_cos_theta_f64(w: Vec3) -> (f64, f64) {
    let (y, z) = (w.y as f64, w.z as f64);
    unit_pair(w.x as f64, (y * y + z * z).sqrt())
}

/// A_p for p = 0, 1, 2 and the residual p ≥ 3 (index [`P_MAX`]): Fresnel at cos θo cos γo and IOR `eta`, `t`
/// the transmittance of one chord (module docs).
#[inline]
pub fn a_p(cos_theta_o: f32, cos_gamma_o: f32, eta: f32, t: Vec3) -> [Vec3; P_MAX + 1] {
    let f = dielectric(cos_theta_o * cos_gamma_o, eta);
    let a0 = Vec3::splat(f);
    let a1 = (1.0 - f) * (1.0 - f) * t;
    let a2 = a1 * f * t;
    // Σ_{p≥3} A₂ (F T)^{p−2}, a geometric series; zero where F T = 1 (then A₂ = 0: F = 1 leaves nothing inside).
    let ft = f * t;
    let tail = Vec3::select(ft.cmplt(Vec3::ONE), ft / (Vec3::ONE - ft), Vec3::ZERO);
    [a0, a1, a2, a2 * tail]
}

/// Φ(p, γo, γt) = 2p γt − 2γo + pπ, the azimuth (φi − φo) of the p-th order's exit (Chiang et al., from
/// Marschner et al. 2003).
#[inline]
pub fn phi_p(p: usize, gamma_o: f32, gamma_t: f32) -> f32 {
    let p = p as f32;
    2.0 * p * gamma_t - 2.0 * gamma_o + p * PI
}

/// The logistic of scale `s` trimmed to [−π, π]: e^{−|x|/s} / (s (1 + e^{−|x|/s})²) / tanh(π/2s) (the CDF's
/// difference at ±π is tanh(π/2s)).
#[inline]
pub fn trimmed_logistic(x: f32, s: f32) -> f32 {
    Azimuthal::new(s).eval(x)
}

/// The trimmed logistic of one scale s, its constants taken once.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Azimuthal {
    /// s.
    s: f32,
    /// 1/s.
    inv_s: f32,
    /// 1/(s tanh(π/2s)).
    norm: f32,
    /// F(−π) = 1/(1 + e^{π/s}) and tanh(π/2s) in f64, for [`Azimuthal::sample`].
    cdf_lo: f64,
    tanh_half: f64,
}

impl Azimuthal {
    fn new(s: f32) -> Azimuthal {
        Azimuthal {
            s,
            inv_s: 1.0 / s,
            norm: 1.0 / (s * (0.5 * PI / s).tanh()),
            cdf_lo: 1.0 / (1.0 + (std::f64::consts::PI / s as f64).exp()),
            tanh_half: (0.5 * std::f64::consts::PI / s as f64).tanh(),
        }
    }

    /// A draw by the inverse CDF ([`sample_trimmed_logistic`], whose constants this keeps).
    #[inline]
    fn sample(&self, u: f32) -> f32 {
        let u = u as f64;
        let (q, q_c) = (
            self.cdf_lo + u * self.tanh_half,
            self.cdf_lo + (1.0 - u) * self.tanh_half,
        );
        ((self.s as f64 * (q / q_c).ln()) as f32).clamp(-PI, PI)
    }

    /// The density at x ∈ [−π, π] ([`trimmed_logistic`]).
    #[inline]
    fn eval(&self, x: f32) -> f32 {
        self.eval_lanes([x; 4])[0]
    }

    /// [`Azimuthal::eval`] at four points at once (Chiang's three lobes in one f32 vector).
    #[inline(always)]
    fn eval_lanes(&self, x: [f32; 4]) -> [f32; 4] {
        let e = exp_f32x4(-f32x4::new(x).abs() * f32x4::splat(self.inv_s));
        let e1 = e + f32x4::splat(1.0);
        (e * f32x4::splat(self.norm) / (e1 * e1)).to_array()
    }
}

/// A draw from [`trimmed_logistic`] by its inverse CDF, in f64: q = F(−π) + u tanh(π/2s),
/// x = s ln(q/(1 − q)), with 1 − q = F(−π) + (1 − u) tanh(π/2s) written so (no cancellation near u = 1).
#[inline]
pub fn sample_trimmed_logistic(u: f32, s: f32) -> f32 {
    Azimuthal::new(s).sample(u)
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

#[cfg(test)]
mod tests {
    use super::super::frame::{from_spherical, sin_cos_theta};
    use super::super::testing::{self, mean};
    use super::*;
    use crate::util::sampling::uniform_sphere;
    use rand::Rng;
    use rand_pcg::Pcg32;

    /// The roughnesses of the white-furnace grid (the 0.1, 0.2, …, 0.9).
    const BETAS: [f32; 9] = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9];
    /// θo of the chi-square batteries, degrees.
    const CHI2_THETA_O_DEG: [f32; 3] = [-60.0, 10.0, 70.0];

    fn model(f: impl FnOnce(&mut ChiangParams)) -> Chiang {
        let mut p = ChiangParams::default();
        f(&mut p);
        Chiang::new(p).unwrap()
    }

    fn white(beta_m: f32, beta_n: f32) -> Chiang {
        model(|p| {
            p.sigma_a = Vec3::ZERO;
            p.beta_m = beta_m;
            p.beta_n = beta_n;
        })
    }

    /// I₀ₑ(x) = (1/π) ∫₀^π e^{x (cos t − 1)} dt by the trapezoid rule: exponentially convergent for this periodic
    /// analytic integrand (error ~ I_{2N}(x)/I₀(x)), an independent reference for the series and the expansion.
    fn i0e_reference(x: f64) -> f64 {
        const N: usize = 4000;
        let h = std::f64::consts::PI / N as f64;
        let mut s = 0.5 * (1.0 + (-2.0 * x).exp());
        for k in 1..N {
            s += (x * ((k as f64 * h).cos() - 1.0)).exp();
        }
        s / N as f64
    }

    #[test]
    fn bessel_i0_accurate_over_the_whole_range() {
        let mut x = 1e-3;
        while x < 2e4 {
            for y in [x, I0_SWITCH * (1.0 - 1e-12), I0_SWITCH * (1.0 + 1e-12)] {
                let (got, want) = (i0e(y), i0e_reference(y));
                let rel = (got / want - 1.0).abs();
                assert!(rel < 1e-9, "i0e({y}) = {got}, reference {want}: {rel:e}");
                // ln I₀ = x + ln I₀ₑ where the reference has no cancellation (x ≥ 1).
                if y >= 1.0 {
                    let want_log = y + want.ln();
                    let rel_log = (log_i0(y) / want_log - 1.0).abs();
                    assert!(rel_log < 1e-9, "log_i0({y}): {rel_log:e}");
                }
            }
            x *= 1.3;
        }
        // Tabulated (Abramowitz & Stegun Table 9.8): I₀(1), I₀(2), e^{−10} I₀(10).
        for (x, want) in [
            (1.0, 1.266_065_877_752_008),
            (2.0, 2.279_585_302_336_067),
            (10.0, 2_815.716_628_466_254),
        ] {
            assert!((i0(x) / want - 1.0).abs() < 1e-12, "I0({x}) = {}", i0(x));
        }
        // Small x: ln I₀(x) = x²/4 − x⁴/64 + x⁶/576 − …, relative.
        for x in [1e-6f64, 1e-3, 0.05, 0.3] {
            let want =
                x * x / 4.0 - x.powi(4) / 64.0 + x.powi(6) / 576.0 - 11.0 * x.powi(8) / 49152.0;
            let rel = (log_i0(x) / want - 1.0).abs();
            assert!(rel < 1e-6, "log_i0({x}) = {} vs {want}: {rel:e}", log_i0(x));
        }
    }

    #[test]
    fn m_p_lanes_match_the_full_bessel_function_to_f32() {
        // The lanes cut both expansions to 16 terms at M_P_SWITCH (10); M_p from the 32-term i0e (within 1e-9 of
        // quadrature, test above) must agree within 3e-9 relative — a twentieth of an f32 ulp — for a's on both
        // sides of the switch, in every lane position, and not one f32 result may differ by more than an ulp.
        for v in [0.002f64, 0.02, 0.0846, 0.2, 0.5, 1.0] {
            let l = Longitudinal::new(v);
            for ti in -40..=40 {
                for to in -40..=40 {
                    let sc_i = ((ti as f64 * 0.039).sin(), (ti as f64 * 0.039).cos());
                    let sc_o = ((to as f64 * 0.0391).sin(), (to as f64 * 0.0391).cos().abs());
                    let got = l.eval(sc_i, sc_o);
                    let cc = sc_i.1 * sc_o.1;
                    let want = (l.log_norm + (cc - sc_i.0 * sc_o.0 - 1.0) * l.inv_v).exp()
                        * i0e(cc * l.inv_v);
                    if want > 1e-300 {
                        let rel = (got / want - 1.0).abs();
                        assert!(
                            rel < 3e-9,
                            "v {v} sc_i {sc_i:?} sc_o {sc_o:?}: {got} vs {want} ({rel:e})"
                        );
                        let (a, b) = ((got as f32).to_bits(), (want as f32).to_bits());
                        assert!(
                            a.abs_diff(b) <= 1,
                            "v {v}: f32 {} vs {}",
                            got as f32,
                            want as f32
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn m_p_is_normalised_for_every_variance() {
        // ∫ M_p cos θi dθi = 1 (midpoint rule, 40000 nodes: ≥ 10 per standard deviation of the narrowest lobe,
        // βm = 0.01 at p = 1). The peers' truncated I₀ lose up to ~2 % near v ≈ 0.1 (issue 14).
        const N: usize = 40_000;
        for beta_m in [0.01f32, 0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 0.9, 1.0] {
            let v0 = longitudinal_variance(beta_m) as f64;
            for v in [0.25 * v0, v0, 4.0 * v0] {
                for theta_o in [-80f32, -30.0, 0.0, 45.0, 89.0] {
                    let (so, co) = theta_o.to_radians().sin_cos();
                    let h = std::f64::consts::PI / N as f64;
                    let mut s = 0.0;
                    for k in 0..N {
                        let t = -std::f64::consts::FRAC_PI_2 + (k as f64 + 0.5) * h;
                        let (si, ci) = (t as f32).sin_cos();
                        s += m_p(v, si, ci, so, co) * t.cos() * h;
                    }
                    assert!(
                        (s - 1.0).abs() < 1e-5,
                        "βm {beta_m} v {v} θo {theta_o}°: ∫ M_p cos θi dθi = {s}"
                    );
                }
            }
        }
    }

    #[test]
    fn white_furnace_by_quadrature() {
        // σa = 0: ∫ f cos θi dωi = Σ A_p = 1 exactly; the quadrature of `eval` must find it within 1e-3 for every
        // (βm, βn) of the grid at two pseudo-random (θo, h) each, with the paper's 2° tilt.
        let mut rng = Pcg32::new(14, 1);
        for beta_m in BETAS {
            for beta_n in BETAS {
                let m = white(beta_m, beta_n);
                // Two pseudo-random views, and the grazing corners for the narrowest lobes.
                let mut views: Vec<(f32, f32)> = (0..2)
                    .map(|_| {
                        let theta_o = (rng.random::<f32>() - 0.5) * 170.0;
                        (theta_o, 2.0 * rng.random::<f32>() - 1.0)
                    })
                    .collect();
                if beta_m == 0.1 && beta_n == 0.1 {
                    views.extend([(85.0, 0.99), (-85.0, -0.99), (0.0, 1.0)]);
                }
                for (theta_o, h) in views {
                    let a = mean(testing::albedo(&m.at(h), testing::wo_at(theta_o)).sum());
                    assert!(
                        (0.999..=1.001).contains(&a),
                        "βm {beta_m} βn {beta_n} θo {theta_o}° h {h}: albedo {a}"
                    );
                }
            }
        }
    }

    #[test]
    fn sample_weights_are_one_without_absorption() {
        // With σa = 0 the mixture pdf is exactly f cos θi, so each weight is 1 up to rounding.
        let mut rng = Pcg32::new(3, 3);
        let mut sampled = 0usize;
        for beta_m in BETAS {
            for beta_n in BETAS {
                let m = white(beta_m, beta_n);
                for _ in 0..500 {
                    let fibre = m.at(2.0 * rng.random::<f32>() - 1.0);
                    let wo = uniform_sphere(rng.random(), rng.random());
                    let Some(s) = fibre.sample(wo, rng.random()) else {
                        continue;
                    };
                    for c in 0..3 {
                        let w = s.weight[c];
                        assert!(
                            w > 0.99 && w < 1.01,
                            "βm {beta_m} βn {beta_n} h {} wo {wo}: weight {}",
                            fibre.h(),
                            s.weight
                        );
                    }
                    sampled += 1;
                }
            }
        }
        assert!(sampled > 0, "no direction was sampled");
    }

    #[test]
    fn sampled_furnace_matches_quadrature_with_absorption() {
        let m = model(|_| ());
        for (t, h) in [(-50.0, 0.3), (20.0, -0.9)] {
            testing::assert_sampled_furnace_matches(
                &format!("chiang default θo {t}° h {h}"),
                &m.at(h),
                testing::wo_at(t),
                0.01,
            );
        }
    }

    #[test]
    fn sampler_chi_square() {
        for (beta_m, beta_n, h, alpha_deg) in [
            (0.3, 0.3, 0.0, 2.0),
            (0.1, 0.1, 0.5, 2.0),
            (0.9, 0.9, -0.8, 2.0),
            (0.2, 0.6, 0.95, -3.0),
        ] {
            let m = model(|p| {
                p.beta_m = beta_m;
                p.beta_n = beta_n;
                p.alpha = f32::to_radians(alpha_deg);
            });
            testing::chi_square_battery(
                &format!("chiang βm {beta_m} βn {beta_n} h {h} α {alpha_deg}°"),
                &m.at(h),
                &CHI2_THETA_O_DEG,
            );
        }
    }

    #[test]
    fn uniform_sampling_furnace_and_chi_square() {
        // The uniform switch: a white furnace (σa = 0) by sampling equals 1 like the quadrature's, the sampled
        // furnace with absorption matches the quadrature, the pdf is 1/4π and integrates to 1, and χ² accepts
        // the sampled directions against it.
        let uniform = |f: &dyn Fn(&mut ChiangParams)| {
            model(|p| {
                f(p);
                p.sampling = Sampling::Uniform;
            })
        };
        // βm = βn = 0.7: at the default 0.3 uniform sampling's standard error with 10⁶ samples (0.6 %) is too
        // large to test 1 %.
        let white = uniform(&|p| {
            p.sigma_a = Vec3::ZERO;
            (p.beta_m, p.beta_n) = (0.7, 0.7);
        });
        let absorbing = uniform(&|p| (p.beta_m, p.beta_n) = (0.7, 0.7));
        for (t, h) in [(-50.0, 0.3), (20.0, -0.9)] {
            let wo = testing::wo_at(t);
            let (fibre, w) = (white.at(h), testing::albedo(&white.at(h), wo));
            assert!(
                (mean(w.sum()) - 1.0).abs() < 2e-3,
                "chiang uniform white furnace θo {t}° h {h}: {}",
                mean(w.sum())
            );
            let p = testing::pdf_integral(&fibre, wo);
            assert!((p - 1.0).abs() < 1e-3, "θo {t}° h {h}: ∫ pdf = {p}");
            let wi = uniform_sphere(0.3, 0.7);
            assert_eq!(fibre.pdf(wo, wi), UNIFORM_SPHERE_PDF);
            testing::assert_sampled_furnace_matches(
                &format!("chiang uniform white θo {t}° h {h}"),
                &fibre,
                wo,
                0.01,
            );
            testing::assert_sampled_furnace_matches(
                &format!("chiang uniform default θo {t}° h {h}"),
                &absorbing.at(h),
                wo,
                0.01,
            );
        }
        testing::chi_square_battery("chiang uniform", &absorbing.at(0.4), &CHI2_THETA_O_DEG[..2]);
        // Published (clamp-and-flip) sampling is Marschner's alone.
        let published = Chiang::new(ChiangParams {
            sampling: Sampling::ClampAndFlip,
            ..ChiangParams::default()
        });
        assert!(matches!(published, Err(BsdfError::Sampling { .. })));
    }

    #[test]
    fn pdf_integrates_to_one() {
        for (beta_m, beta_n, h) in [(0.1, 0.1, 0.2), (0.5, 0.9, -0.7)] {
            let m = model(|p| {
                p.beta_m = beta_m;
                p.beta_n = beta_n;
            });
            for t in [-70.0, 0.0, 40.0] {
                let i = testing::pdf_integral(&m.at(h), testing::wo_at(t));
                assert!(
                    (i - 1.0).abs() < 1e-3,
                    "βm {beta_m} βn {beta_n} θo {t}°: ∫ pdf = {i}"
                );
            }
        }
    }

    #[test]
    fn importance_and_uniform_sampling_agree() {
        // A smooth lighting L(ωi) = 1 + 0.8 x + 0.5 y² − 0.3 y z (> 0): ∫ f L cos θi dωi by the model's sampler
        // and by uniform sphere sampling (weight f cos θi · 4π), each with 1e6 samples.
        /// Samples of each estimate: uniform sampling needs 4× more for a 0.5 % standard error at θo = 75°.
        const N: usize = 1_000_000;
        const N_UNIFORM: usize = 4 * N;
        let light = |w: Vec3| 1.0 + 0.8 * w.x + 0.5 * w.y * w.y - 0.3 * w.y * w.z;
        let m = model(|_| ());
        for (t, h) in [(-40.0, 0.1), (30.0, -0.6), (75.0, 0.9)] {
            let (fibre, wo) = (m.at(h), testing::wo_at(t));
            let mut rng = Pcg32::new(8, 8);
            let (mut si, mut si2, mut su, mut su2) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
            for _ in 0..N {
                if let Some(s) = fibre.sample(wo, rng.random()) {
                    let x = mean(s.weight) * light(s.wi) as f64;
                    (si, si2) = (si + x, si2 + x * x);
                }
            }
            for _ in 0..N_UNIFORM {
                let wi = uniform_sphere(rng.random(), rng.random());
                let x =
                    mean(fibre.eval(wo, wi)) * (sin_cos_theta(wi).1 * light(wi) * 4.0 * PI) as f64;
                (su, su2) = (su + x, su2 + x * x);
            }
            let (n, nu) = (N as f64, N_UNIFORM as f64);
            let (mi, mu) = (si / n, su / nu);
            let (ei, eu) = (
                ((si2 / n - mi * mi) / n).sqrt(),
                ((su2 / nu - mu * mu) / nu).sqrt(),
            );
            assert!(
                eu < 0.005 * mu && ei < 0.005 * mi,
                "standard errors too large to test 2 %"
            );
            assert!(
                (mi / mu - 1.0).abs() < 0.02,
                "importance {mi} vs uniform {mu}"
            );
        }
    }

    #[test]
    fn reciprocity_only_term_by_term() {
        // The whole model is not reciprocal (A_p and h belong to the view).
        testing::assert_reciprocal(&model(|_| ()).at(0.0), false);
        testing::assert_reciprocal(&model(|p| p.alpha = 0.0).at(0.0), false);
        // M_p(θi, θo) = M_p(θo, θi); N_p even in φ at h = 0.
        let mut rng = Pcg32::new(1, 2);
        for _ in 0..1000 {
            let (a, b) = (
                (rng.random::<f32>() - 0.5) * PI,
                (rng.random::<f32>() - 0.5) * PI,
            );
            let ((sa, ca), (sb, cb)) = (a.sin_cos(), b.sin_cos());
            for v in [0.001, 0.05, 0.5, 5.0] {
                let (x, y) = (m_p(v, sa, ca, sb, cb), m_p(v, sb, cb, sa, ca));
                assert!(
                    (x - y).abs() <= 1e-6 * x.max(y) + 1e-30,
                    "M_p({a}, {b}) = {x} vs {y}"
                );
            }
            let phi = (rng.random::<f32>() - 0.5) * TAU;
            for p in 0..P_MAX {
                let n = |x: f32| trimmed_logistic(wrap_phi(x - phi_p(p, 0.0, 0.0)), 0.3);
                assert!(
                    (n(phi) - n(-phi)).abs() <= 1e-5 * n(phi) + 1e-12,
                    "N_{p}({phi})"
                );
            }
        }
    }

    #[test]
    fn h_sign_matches_a_mirror_reflection_on_the_cylinder() {
        // The outward normal at offset h has azimuth φo − γo (module docs); a mirror reflection of the incoming
        // ray −ωo about it must be where R peaks (narrow lobes, no tilt).
        let m = model(|p| {
            p.beta_m = 0.1;
            p.beta_n = 0.1;
            p.alpha = 0.0;
        });
        for h in [-0.7f32, -0.2, 0.4, 0.9] {
            let (theta_o, phi_o) = (0.3f32, 0.5f32);
            let wo = from_spherical(theta_o, phi_o);
            // n from the definition h = u · (n × ω̂o⊥).
            let n = from_spherical(0.0, phi_o - h.asin());
            let w_perp = Vec3::new(0.0, wo.y, wo.z).normalize();
            assert!((Vec3::X.dot(n.cross(w_perp)) - h).abs() < 1e-5);
            let d = -wo;
            let mirror = d - 2.0 * d.dot(n) * n;
            let fibre = m.at(h);
            let best = (0..3600)
                .map(|k| from_spherical(-theta_o, -PI + k as f32 * TAU / 3600.0))
                .max_by(|a, b| {
                    fibre
                        .eval_lobes(wo, *a)
                        .r
                        .x
                        .total_cmp(&fibre.eval_lobes(wo, *b).r.x)
                })
                .unwrap();
            assert!(
                best.dot(mirror) > 0.9999,
                "h {h}: R peaks at {best}, the mirror direction is {mirror}"
            );
        }
    }

    #[test]
    fn h_from_a_ray_cylinder_hit_and_from_a_ribbon() {
        // A fibre of radius r along u through c, a ray towards it from the view direction ωo at signed offset d
        // along b = ω̂o⊥ × u: the hit's outward normal gives h = d/r (h_from_normal), and so does a ribbon facing
        // the ray across b with v = (d/r + 1)/2 (h_from_ribbon). Frames turned arbitrarily, world space.
        let mut rng = Pcg32::new(21, 4);
        for _ in 0..200 {
            let u = uniform_sphere(rng.random(), rng.random());
            let wo = uniform_sphere(rng.random(), rng.random());
            if u.dot(wo).abs() > 0.99 {
                continue;
            }
            let (c, r) = (Vec3::new(0.3, -1.0, 2.0), 0.01 + rng.random::<f32>());
            let w_perp = wo.reject_from_normalized(u).normalize();
            let b = w_perp.cross(u);
            let d = r * (2.0 * rng.random::<f32>() - 1.0) * 0.999;
            // The ray starts far along ωo, offset by d b, and travels along −ωo: in the normal plane it meets the
            // circle where its in-plane distance to c is r (in f64: the quadratic cancels in f32).
            let (u64_, c64) = (u.as_dvec3(), c.as_dvec3());
            let o = c64 + 10.0 * wo.as_dvec3() + (d * b).as_dvec3();
            let dir = -wo.as_dvec3();
            let (oc, dp) = (
                (o - c64).reject_from_normalized(u64_),
                dir.reject_from_normalized(u64_),
            );
            let r64 = r as f64;
            let (qa, qb, qc) = (dp.dot(dp), 2.0 * oc.dot(dp), oc.dot(oc) - r64 * r64);
            let t = (-qb - (qb * qb - 4.0 * qa * qc).sqrt()) / (2.0 * qa);
            let hit = o + t * dir;
            let n = ((hit - c64).reject_from_normalized(u64_) / r64).as_vec3();
            let h = h_from_normal(u, n, wo);
            assert!((h - d / r).abs() < 1e-4, "h {h} vs d/r {}", d / r);
            let v = 0.5 * (d / r + 1.0);
            let h_ribbon = h_from_ribbon(v, b, u, wo);
            assert!((h_ribbon - d / r).abs() < 1e-4, "{h_ribbon} vs {}", d / r);
            // In a local hair frame (here v along n), the outward normal's azimuth is φo − γo, γo = asin h.
            let frame = super::super::frame::HairFrame::from_round_curve(u, n);
            let (wo_l, n_l) = (frame.to_local(wo), frame.to_local(n));
            let phi_n = super::super::frame::phi(n_l);
            let gamma = wrap_phi(super::super::frame::phi(wo_l) - phi_n);
            assert!(
                (gamma.sin() - h).abs() < 2e-3,
                "sin γo {} vs h {h}",
                gamma.sin()
            );
        }
    }

    #[test]
    fn tilt_moves_each_lobe_as_documented() {
        // Narrow lobes: the θi where each lobe peaks, at h = 0 and φ at its Φ (R 0, TT π, TRT 2π ≡ 0), is
        // −θo + 2α (R), −θo − α (TT), −θo − 4α (TRT).
        let alpha = 5f32.to_radians();
        let m = model(|p| {
            p.beta_m = 0.05;
            p.beta_n = 0.3;
            p.alpha = alpha;
            p.sigma_a = Vec3::ZERO;
        });
        let fibre = m.at(0.0);
        let theta_o = 0.4f32;
        let wo = from_spherical(theta_o, 0.0);
        let peak = |phi: f32, lobe: fn(&LobeValues) -> f32| {
            (0..20_000)
                .map(|k| -1.5 + 3.0 * k as f32 / 20_000.0)
                .max_by(|a, b| {
                    let f = |t: f32| lobe(&fibre.eval_lobes(wo, from_spherical(t, phi)));
                    f(*a).total_cmp(&f(*b))
                })
                .unwrap()
        };
        let r = peak(0.0, |l| l.r.x);
        let tt = peak(PI, |l| l.tt.x);
        let trt = peak(0.0, |l| l.trt.x);
        // f = M_p A_p N_p / cos θi peaks within ~v tan θi of the lobe's centre (v₀ = 1.5e-3, v₂ = 5.9e-3 here).
        assert!((r - (-theta_o + 2.0 * alpha)).abs() < 3e-3, "R {r}");
        assert!((tt - (-theta_o - alpha)).abs() < 3e-3, "TT {tt}");
        assert!((trt - (-theta_o - 4.0 * alpha)).abs() < 1e-2, "TRT {trt}");
    }

    #[test]
    fn finite_everywhere() {
        for (beta_m, beta_n) in [
            (BETA_MIN, BETA_MIN),
            (1.0, 1.0),
            (BETA_MIN, 1.0),
            (1.0, BETA_MIN),
        ] {
            for (alpha, sigma_a) in [(FRAC_PI_8, Vec3::ZERO), (-FRAC_PI_8, Vec3::splat(1e3))] {
                let m = model(|p| {
                    p.beta_m = beta_m;
                    p.beta_n = beta_n;
                    p.alpha = alpha;
                    p.sigma_a = sigma_a;
                });
                for h in [-1.0, -0.999, 0.0, 0.5, 1.0] {
                    testing::assert_finite_sweep(
                        &format!("chiang βm {beta_m} βn {beta_n} α {alpha} σa {sigma_a} h {h}"),
                        &m.at(h),
                    );
                }
            }
        }
    }

    #[test]
    fn melanin_and_colour() {
        // pbrt-v4's default hair: eumelanin 1.3.
        let s = sigma_a_from_melanin(1.3, 0.2).unwrap();
        let want = Vec3::new(0.5821, 0.9861, 1.991);
        assert!((s - want).abs().max_element() < 1e-3, "{s}");
        assert_eq!(
            ChiangParams::default().sigma_a,
            sigma_a_from_melanin(1.3, 0.0).unwrap()
        );
        // eq. 9 by hand: βn = 0.3 gives D = 5.88841, so C = 0.5 needs σa = (ln 2 / D)² = 0.0138565.
        let s = sigma_a_from_color(Vec3::splat(0.5), 0.3).unwrap();
        assert!((s.x - 0.013_856_5).abs() < 1e-6, "{s}");
        // Round trip, and darker colours absorb more.
        for beta_n in [0.1, 0.3, 0.6, 1.0] {
            for c in [Vec3::new(0.9, 0.5, 0.2), Vec3::new(0.05, 0.3, 1.0)] {
                let s = sigma_a_from_color(c, beta_n).unwrap();
                let back = color_from_sigma_a(s, beta_n);
                assert!(
                    (back - c).abs().max_element() < 1e-5,
                    "βn {beta_n}: {c} → {s} → {back}"
                );
            }
            let dark = sigma_a_from_color(Vec3::splat(0.1), beta_n).unwrap();
            let light = sigma_a_from_color(Vec3::splat(0.8), beta_n).unwrap();
            assert!(dark.x > light.x);
        }
        // Absorption lowers the fibre's albedo, channel by channel in σa's order.
        let a = testing::albedo(&model(|_| ()).at(0.0), testing::wo_at(0.0)).sum();
        assert!(a.x > a.y && a.y > a.z && a.x < 1.0, "{a}");
    }

    #[test]
    fn validation_names_the_parameter() {
        let err = |f: fn(&mut ChiangParams)| {
            let mut p = ChiangParams::default();
            f(&mut p);
            Chiang::new(p).unwrap_err().to_string()
        };
        assert_eq!(
            err(|p| p.beta_m = 0.0),
            "chiang: beta_m must be in [1e-3, 1], got 0"
        );
        assert!(err(|p| p.beta_n = 1.5).starts_with("chiang: beta_n must be"));
        assert!(err(|p| p.eta = 1.0).starts_with("chiang: eta must be in (1, 10]"));
        assert!(err(|p| p.alpha = 1.0).starts_with("chiang: alpha must be"));
        assert!(
            err(|p| p.sigma_a = Vec3::new(0.1, -1.0, 0.1)).starts_with("chiang: sigma_a must be")
        );
        let e = sigma_a_from_color(Vec3::new(0.5, 0.0, 0.5), 0.3).unwrap_err();
        assert_eq!(
            e.to_string(),
            "chiang: color must be in (0, 1] per channel, got 0"
        );
        let e = sigma_a_from_melanin(-1.0, 0.0).unwrap_err();
        assert!(e.to_string().starts_with("chiang: eumelanin must be >= 0"));
    }
}
