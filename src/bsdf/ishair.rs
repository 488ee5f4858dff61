//! ISHair: Sadeghi et al. 2010, "An artist friendly hair shading system", as importance sampled by Ou et al. 2012,
//! "ISHair: importance sampling for hair scattering" (thesis §4.3, eq. 15–21), plus the Kajiya-Kay diffuse term
//! (thesis §5.3: `plausibleIsHair` = the four specular lobes + `kajiyaKayDiffuse`).
//!
//! # Model (fibre convention, see [`super`])
//!
//! f = w_s (f_R + f_TT + f_TRT + f_g) + w_d k_d/π², with f_X = C_X M_X(θh) N_X(φ) / cos²θd, the Marschner form
//! S = M N / cos²θd that thesis eq. 4 abbreviates as M N (Sadeghi et al. keep Marschner's 1/cos²θd):
//!
//! - M_X = g(β_X², α_X, θh) = e^{−(θh − α_X)²/2β_X²} (eq. 15–16): a **unit-height** Gaussian, not a pdf (its
//!   integral is β√(2π), so a lobe's albedo scales with its width: ≈ 20 β_R C_R for R).
//! - N_R = cos(φ/2); N_TT = g(γ_TT², π − φ); N_TRT−g = cos(φ/2); N_g = g(γ_g², |φ| − φ_g) (eq. 17). Ou et al.
//!   take φ ∈ [0, 2π) for TT; here φ ∈ [−π, π], so π − φ is read as the distance to π, π − |φ|.
//! - Colours: C_R (Sadeghi's R is uncoloured: white × intensity), C_TT, C_TRT; the glint is C_TRT × I_g.
//!
//! The lobes are **not** energy conserving and not meant to be (Sadeghi et al. trade that for artist control):
//! the white-furnace tests report the albedo of each lobe and assert the measured ranges.
//!
//! Reciprocal (θh, cos²θd and |φ| are symmetric in i ↔ r) except with [`Balance::Fresnel`].
//!
//! # Sampling ([`Sampling::ExactPdf`], Ou et al. 2012)
//!
//! Choose diffuse or specular in proportion to w_d lum(k_d) and w_s ΣE_X; then one of the four specular lobes,
//! [`LobeSelection::Uniform`] (1/4 each, as the thesis did, §5.3.2) or [`LobeSelection::ByEnergy`] (∝ E_X, Ou et
//! al.'s suggestion, thesis §8.2), with E_X the lobe's albedo estimated at θo = 0 from its integrals
//! (2∫M dθh over the valid range × ∫N dφ × lum(C_X) × cos²θi/cos²θd at the lobe's peak). Then:
//!
//! - θ (eq. 18–20): θh from a Cauchy centred at α_X with scale β_X truncated to [θr/2 − π/4, θr/2 + π/4]
//!   ([`TruncatedCauchyOf`]), θi = 2θh − θr, so p(θi) = p(θh)/2, and per solid angle p/cos θi, which is eq. 20,
//!   1/(2 cos θi (A − B)) · β/((θh − α)² + β²).
//! - φ: R and TRT−g: φ = 2 asin(2ξ − 1) (eq. 21a, 21c), density cos(φ/2)/4; TT: φ = π + γ_TT tan(C_TT(ξ − ½))
//!   (eq. 21b), a Cauchy about π truncated to one turn; glint: |φ| = φ_g + γ_g tan(ξ(C_g − D_g) + D_g) (eq. 21d),
//!   a Cauchy about φ_g truncated to [0, π/2], with a random sign (the thesis leaves the sign implicit; the
//!   two glints are symmetric), so density ½ p(|φ|) for |φ| ≤ π/2 and 0 beyond.
//!
//! pdf() is the whole mixture: Σ selection probability × lobe pdf, exactly what sample() draws (chi-square
//! tested). Cauchy tails are heavier than the Gaussian lobes', so weights stay bounded. [`Sampling::Uniform`]:
//! the sphere. [`Sampling::ClampAndFlip`] is refused.
//!
//! # One shading point or eight ([`Fibre`])
//!
//! The model is written once, over the number type [`Real`]: [`IsHair`]'s [`Fibre`] implementation. Its view
//! ([`IsHairView`]) holds what eval and sample share for one ωo: θo with its sine and cosine, the balance
//! weights and p_s, and the three θh distributions with their normalisations A − B. The scalar [`Bsdf`] is that
//! code at `R = f32` ([`At`]); at `R = f32x8` it shades eight points at once, each lane choosing its own lobe
//! (comparisons give masks, branches are selects, and work no lane needs is skipped). Terms that another file
//! implements as a scalar function (the Fresnel balance, Kajiya-Kay's diffuse sampler, eq. 12's azimuth, the
//! uniform sphere) are computed lane by lane ([`Real::from_fn`]), so each stays one implementation.
//!
//! Precision: all arithmetic is f32. The θh ranges' standardised ends, which reach 1.5e4 for β = 1e-4, are kept
//! exact by compensated sums ([`theta_h_distribution`]), so A − B is within 1e-6 of its f64 value; the Cauchy
//! samplers draw the exact inverse CDF at a level within ~1e-6 of ξ ([`TruncatedCauchyOf::sample`]); the lobe
//! exponentials are 0 below e^{−87.3} ([`exp_lobe_of`]). One lane and eight differ only in their exponential,
//! sine and cosine (libm's against `wide`'s polynomials, a few ulp), tested lane by lane.
//!
//! # Parameters ([`IsHairParams`]; angles in radians)
//!
//! | name | meaning | range | default |
//! |---|---|---|---|
//! | `alpha_r`, `beta_r` | R shift, width | \|α\| ≤ π/4; β ∈ [1e-4, π/2] | −7.5°, 7.5° (midpoints of Marschner et al. 2003 Table 1: −10°…−5°, 5°…10°) |
//! | `alpha_tt`, `beta_tt` | TT | same | −α_R/2 = 3.75°, β_R/2 = 3.75° (Marschner's relations, kept by Sadeghi et al.) |
//! | `alpha_trt`, `beta_trt` | TRT and glint | same | −3α_R/2 = 11.25°, 2β_R = 15° |
//! | `gamma_tt` | TT azimuthal width | [1e-4, 1e6] | 10° (chosen here) |
//! | `gamma_g` | glint azimuthal width | [1e-4, 1e6] | 15° (in Marschner's caustic-width range, 10°…25°) |
//! | `phi_g` | glint half separation | [0, π/2] | 35° (chosen here, inside the 30°…45° commonly used) |
//! | `color_r`, `color_tt`, `color_trt` | lobe colours × intensities, RGB ≥ 0 | | 0.1 white; (1, 0.7, 0.4); (0.1, 0.07, 0.04) (chosen here: each lobe's albedo at θo = 0 of order 0.1–0.3) |
//! | `glint` | I_g, glint gain relative to TRT | ≥ 0 | 2 (chosen here) |
//! | `k_d` | Kajiya-Kay diffuse colour | RGB ≥ 0 | (0.5, 0.35, 0.2) |
//! | `balance`, `sampling`, `selection` | see [`Balance`], [`Sampling`], [`LobeSelection`] | | user 0.5, exact, uniform |
//!
//! The papers leave intensities to the artist; the defaults marked "chosen here" are not from them.

use super::cauchy::{TruncatedCauchy, TruncatedCauchyOf};
use super::frame::{atan2_of as atan2, sin_cos_from_of as sin_cos_from, COS_THETA_MIN};
use super::gaussian::{exp_lobe_of, gaussian_exponent_of, gaussian_unit_integral};
use super::kajiya_kay::{diffuse_f, diffuse_pdf, sample_diffuse_of, selection_probability};
use super::lanes::{At, EvalOf, Fibre, LobesOf, SampleOf};
use super::marschner::phi_eq12_parts;
use super::{
    check, check_color, check_width, make_sample, Balance, Bsdf, BsdfError, BsdfSample, Lobe,
    LobeValues, Sampling,
};
use crate::util::color::luminance;
use crate::util::real::{Real, RealMask};
use crate::util::sampling::{uniform_sphere_of, UNIFORM_SPHERE_PDF};
use glam::{Vec3, Vec3A};
use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};

/// How the sample budget is split between the four specular lobes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LobeSelection {
    /// 1/4 each, as the thesis' shader did (§5.3.2).
    #[default]
    Uniform,
    /// In proportion to each lobe's estimated albedo (Ou et al. 2012's suggestion, thesis §8.2).
    ByEnergy,
}

/// The parameters of [`IsHair::new`] (radians; see the module docs' table).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IsHairParams {
    /// Kajiya-Kay diffuse colour.
    pub k_d: Vec3,
    /// C_R, R colour × intensity.
    pub color_r: Vec3,
    /// C_TT.
    pub color_tt: Vec3,
    /// C_TRT (TRT − g and, times `glint`, the glints).
    pub color_trt: Vec3,
    /// I_g, the glints' gain relative to TRT.
    pub glint: f32,
    /// α_R.
    pub alpha_r: f32,
    /// β_R.
    pub beta_r: f32,
    /// α_TT.
    pub alpha_tt: f32,
    /// β_TT.
    pub beta_tt: f32,
    /// α_TRT (also the glints').
    pub alpha_trt: f32,
    /// β_TRT (also the glints').
    pub beta_trt: f32,
    /// γ_TT, azimuthal width of TT.
    pub gamma_tt: f32,
    /// γ_g, azimuthal width of each glint.
    pub gamma_g: f32,
    /// φ_g, the azimuth of the glints (half the angle between them).
    pub phi_g: f32,
    /// Diffuse/specular weights.
    pub balance: Balance,
    /// Sampling mode.
    pub sampling: Sampling,
    /// Lobe selection.
    pub selection: LobeSelection,
}

impl Default for IsHairParams {
    fn default() -> Self {
        let d = |x: f32| x.to_radians();
        IsHairParams {
            k_d: Vec3::new(0.5, 0.35, 0.2),
            color_r: Vec3::splat(0.1),
            color_tt: Vec3::new(1.0, 0.7, 0.4),
            color_trt: Vec3::new(0.1, 0.07, 0.04),
            glint: 2.0,
            alpha_r: d(-7.5),
            beta_r: d(7.5),
            alpha_tt: d(3.75),
            beta_tt: d(3.75),
            alpha_trt: d(11.25),
            beta_trt: d(15.0),
            gamma_tt: d(10.0),
            gamma_g: d(15.0),
            phi_g: d(35.0),
            balance: Balance::default(),
            sampling: Sampling::ExactPdf,
            selection: LobeSelection::Uniform,
        }
    }
}

/// Sadeghi et al.'s four-lobe model with Ou et al.'s sampling, plus Kajiya-Kay diffuse.
#[derive(Debug, Clone, Copy)]
pub struct IsHair {
    params: IsHairParams,
    /// α of the longitudinal terms R, TT, TRT (the glint shares TRT's).
    alpha: [f32; 3],
    /// β of R, TT, TRT.
    beta: [f32; 3],
    /// 1/β of R, TT, TRT (multiplications per call, not divisions).
    inv_beta: [f32; 3],
    /// 1/γ_TT and 1/γ_g.
    inv_gamma_tt: f32,
    inv_gamma_g: f32,
    /// Selection probabilities of R, TT, TRT − g, g among the specular lobes.
    probs: [f32; 4],
    /// Their running sums q_R, q_R + q_TT, q_R + q_TT + q_TRT: the thresholds of the lobe choice.
    cum: [f32; 3],
    /// q_R + q_TT + q_TRT + q_g/2: below it a glint sample takes the positive azimuth.
    glint_split: f32,
    /// Σ E_X, the estimated specular albedo (diffuse vs specular split).
    e_spec: f32,
    /// Estimated albedo E_X of each lobe at θo = 0.
    energies: [f32; 4],
    /// lum(k_d), the diffuse term's share of the split.
    lum_kd: f32,
    /// The diffuse f, k_d/π² ([`diffuse_f`]), per channel.
    diffuse: [f32; 3],
    /// (w_d, w_s, p_s) when the balance does not depend on ωo (every [`Balance`] but Fresnel).
    fixed_balance: Option<[f32; 3]>,
    /// The TT azimuth distribution (eq. 21b), which depends on the parameters only.
    tt: TruncatedCauchyOf<f32>,
    /// The glint azimuth distribution (eq. 21d).
    glint: TruncatedCauchyOf<f32>,
}

/// The exponent of M_X = e^{−(θh − α)²/2β²} (thesis eq. 15–16), given 1/β.
#[inline(always)]
fn m_exponent<R: Real>(inv_beta: R, alpha: R, theta_h: R) -> R {
    gaussian_exponent_of(inv_beta, theta_h - alpha)
}

/// The exponent of N_TT = e^{−(π − |φ|)²/2γ²} (eq. 17, π − φ as the distance to π), given 1/γ and |φ|.
#[inline(always)]
fn n_tt_exponent<R: Real>(inv_gamma_tt: R, abs_phi: R) -> R {
    gaussian_exponent_of(inv_gamma_tt, R::splat(PI) - abs_phi)
}

/// The exponent of N_g = e^{−(|φ| − φ_g)²/2γ_g²} (eq. 17), given 1/γ_g and |φ|.
#[inline(always)]
fn n_g_exponent<R: Real>(inv_gamma_g: R, phi_g: R, abs_phi: R) -> R {
    gaussian_exponent_of(inv_gamma_g, abs_phi - phi_g)
}

/// M_X = e^{−(θh − α)²/2β²} (thesis eq. 15–16), unit height.
#[inline]
pub fn m_x<R: Real>(beta: R, alpha: R, theta_h: R) -> R {
    exp_lobe_of(m_exponent(R::splat(1.0) / beta, alpha, theta_h))
}

/// N_R = N_TRT−g = cos(φ/2) (eq. 17).
#[inline]
pub fn n_r<R: Real>(phi: R) -> R {
    (R::splat(0.5) * phi).cos().max(R::splat(0.0))
}

/// N_TT = e^{−(π − |φ|)²/2γ²} (eq. 17, π − φ as the distance to π).
#[inline]
pub fn n_tt<R: Real>(gamma_tt: R, phi: R) -> R {
    exp_lobe_of(n_tt_exponent(R::splat(1.0) / gamma_tt, phi.abs()))
}

/// N_g = e^{−(|φ| − φ_g)²/2γ_g²} (eq. 17): two glints at ±φ_g.
#[inline]
pub fn n_g<R: Real>(gamma_g: R, phi_g: R, phi: R) -> R {
    exp_lobe_of(n_g_exponent(R::splat(1.0) / gamma_g, phi_g, phi.abs()))
}

/// The TT azimuth distribution (eq. 21b) in δ = φ − π wrapped: Cauchy(0, γ_TT) on [−π, π].
#[inline]
fn tt_distribution(gamma_tt: f32) -> TruncatedCauchy {
    TruncatedCauchy::new(
        0.0,
        gamma_tt as f64,
        -std::f64::consts::PI,
        std::f64::consts::PI,
    )
}

/// The glint azimuth distribution (eq. 21d) in |φ|: Cauchy(φ_g, γ_g) on [0, π/2].
#[inline]
fn glint_distribution(gamma_g: f32, phi_g: f32) -> TruncatedCauchy {
    TruncatedCauchy::new(
        phi_g as f64,
        gamma_g as f64,
        0.0,
        std::f64::consts::FRAC_PI_2,
    )
}

/// The index in [`Lobe::ALL`] of a lobe, as [`SampleOf::lobe`] carries it.
const fn lobe_index(lobe: Lobe) -> f32 {
    match lobe {
        Lobe::R => 0.0,
        Lobe::Tt => 1.0,
        Lobe::Trt => 2.0,
        Lobe::Glint => 3.0,
        Lobe::Diffuse => 4.0,
    }
}

/// π/4 as the sum of two f32s, [`FRAC_PI_4`] (rounded) and the rest, for the θh range's ends (see
/// [`theta_h_range`]).
const FRAC_PI_4_LO: f32 = (std::f64::consts::FRAC_PI_4 - FRAC_PI_4 as f64) as f32;

/// The θh range [θo/2 − π/4, θo/2 + π/4] of a view at θo (θi = 2θh − θo ∈ [−π/2, π/2]), each end as its f32 value
/// and the rest, (lo, lo′) and (hi, hi′) with lo + lo′ = θo/2 − π/4 to ~1e-15: the ends the θh distributions are
/// truncated to, and what [`theta_h_distribution`] needs to standardise them exactly. θo/2 ± [`FRAC_PI_4`] is
/// rounded with its error kept (Dekker's fast two-sum, exact since |θo/2| ≤ π/4 in f32), and π/4's own rest
/// [`FRAC_PI_4_LO`] is added to it.
#[inline(always)]
fn theta_h_range<R: Real>(theta_o: R) -> ([R; 2], [R; 2]) {
    let half = R::splat(0.5) * theta_o;
    let end = |q: f32| {
        let s = R::splat(q) + half;
        // The error of that sum, exact for |q| ≥ |θo/2| (θo from `atan2` lies within ±FRAC_PI_2 as f32).
        let rest = half - (s - R::splat(q));
        [s, rest + R::splat(q.signum() * FRAC_PI_4_LO)]
    };
    (end(-FRAC_PI_4), end(FRAC_PI_4))
}

/// The θh distribution of a longitudinal term (α, β) for a view whose θh range is `lo`, `hi` ([`theta_h_range`];
/// eq. 18–19): Cauchy(α, β) on [lo, hi], with its normalisation A − B (eq. 20).
///
/// Precision: the standardised ends x = (lo − α)/β, (hi − α)/β reach ±1.5e4 for β = 1e-4, where the f32 rounding
/// of lo (~1e-7 rad) would move x by ~1e-3 and A − B by up to 1e-3 relative when an end sits near the peak. So lo
/// − α is formed from the rounded end and its rest: lo − α rounds exactly where it cancels (Sterbenz), and adding
/// the rest leaves ~1 ulp of the difference itself (relative error ~1e-7, as the f64 ends of
/// [`TruncatedCauchy::new`] rounded to f32). A − B is then one arctangent of (x_hi − x_lo, 1 + x_lo x_hi) (the
/// tangent of a difference, the product fused), as there. Within 1e-6 (relative) of the f64 width over the
/// parameter grid (tested); the sampler and the pdf share this one value, so they agree exactly whatever its error.
#[inline(always)]
fn theta_h_distribution<R: Real>(
    alpha: f32,
    beta: f32,
    inv_beta: f32,
    [lo, lo_rest]: [R; 2],
    [hi, hi_rest]: [R; 2],
) -> TruncatedCauchyOf<R> {
    let alpha_r = R::splat(alpha);
    let inv_beta = R::splat(inv_beta);
    let x_lo = ((lo - alpha_r) + lo_rest) * inv_beta;
    let x_hi = ((hi - alpha_r) + hi_rest) * inv_beta;
    let width = atan2(x_hi - x_lo, x_lo.mul_add(x_hi, R::splat(1.0)));
    TruncatedCauchyOf::new(alpha_r, R::splat(beta), inv_beta, lo, hi, x_lo, width)
}

/// √(y² + z²), the length of a direction's normal-plane projection.
#[inline(always)]
fn rho<R: Real>(y: R, z: R) -> R {
    (y * y + z * z).sqrt()
}

/// cos θd ≥ 0 as half the length of (cos θo + cos θi, sin θo + sin θi) (accurate also near θd = ±π/2).
#[inline(always)]
fn cos_theta_d<R: Real>(sin_o: R, cos_o: R, sin_i: R, cos_i: R) -> R {
    let (c, s) = (cos_o + cos_i, sin_o + sin_i);
    (R::splat(0.5) * (c * c + s * s).sqrt()).min(R::splat(1.0))
}

/// `$a` in the lanes where the mask `$m` is set and `$b` elsewhere, merged by `$blend(mask, a, b)`; a side no lane
/// needs is not computed (for one lane, `f32`, that is a branch, as a scalar sampler takes). A macro, not a function
/// of closures: closures this large are called out of line, and their results pass through memory.
macro_rules! branch {
    ($m:expr, $a:expr, $b:expr, $blend:expr $(,)?) => {{
        let m = $m;
        if RealMask::all(m) {
            $a
        } else if RealMask::all(!m) {
            $b
        } else {
            ($blend)(m, $a, $b)
        }
    }};
}

/// Per lane: `a` where `m` is set, else `b`, element by element.
#[inline(always)]
fn blend<R: Real, const N: usize>(m: R::Mask, a: [R; N], b: [R; N]) -> [R; N] {
    let mut out = a;
    for (o, (&x, &y)) in out.iter_mut().zip(a.iter().zip(&b)) {
        *o = R::select(m, x, y);
    }
    out
}

/// What eval and sample share for one ωo ([`Fibre::view`]), in number type `R`.
#[derive(Debug, Clone, Copy)]
pub struct IsHairView<R> {
    /// ωo as given (x, y, z).
    wo: [R; 3],
    /// ρo = √(y² + z²) of ωo.
    rho_o: R,
    /// (cos φr, sin φr): ωo's normal-plane projection made unit; (1, 0) along ±u (φr = 0 there).
    cos_r: R,
    sin_r: R,
    /// sin θo, cos θo ≥ 0, θo.
    sin_o: R,
    cos_o: R,
    theta_o: R,
    /// The diffuse and specular weights (w_d, w_s) and the probability p_s of sampling the specular lobes.
    w_d: R,
    w_s: R,
    p_s: R,
    /// The θh range [θo/2 − π/4, θo/2 + π/4].
    theta_h_lo: R,
    theta_h_hi: R,
    /// The θh distributions of R, TT and TRT (eq. 18–19), which the pdf and the sampler share.
    theta_h: [TruncatedCauchyOf<R>; 3],
}

/// The angles of a pair (ωo, ωi) the lobes and the pdf read (thesis Table 1; θo's are in the view). Taken from the
/// two directions ([`Pair::of_directions`]), or, for a sampled ωi, from what the sampler drew
/// ([`Pair::of_sampled`]): that needs no arctangent, and f and the pdf are then those of the direction drawn.
#[derive(Debug, Clone, Copy)]
struct Pair<R> {
    /// sin θi, cos θi ≥ 0.
    sin_i: R,
    cos_i: R,
    /// θh = (θo + θi)/2.
    theta_h: R,
    /// cos θd ≥ 0.
    cos_theta_d: R,
    /// cos(φ/2) ≥ 0 for φ ∈ [−π, π] (N_R, and the density of eq. 21a, 21c).
    cos_half_phi: R,
    /// |φ| ∈ [0, π], all the lobes need of the relative azimuth φ = φr − φi.
    abs_phi: R,
}

impl<R: Real> Pair<R> {
    /// The angles of `wi` (any non-zero length) seen from the view's ωo, as [`super::frame::Angles::new`] takes
    /// them: θh from the sine and cosine of θo + θi (one arctangent), cos θd and cos(φ/2) as half-lengths of sums
    /// of unit vectors (accurate where they vanish), |φ| from the sine and cosine of φr − φi (one arctangent).
    #[inline(always)]
    fn of_directions(v: &IsHairView<R>, wi: [R; 3]) -> Pair<R> {
        let c = R::splat;
        let zero = c(0.0);
        let wo = v.wo;
        let rho_i = rho(wi[1], wi[2]);
        // θo + θi ∈ [−π, π] from its sine and cosine (angle-sum formulas, scaled by |ωo||ωi| > 0). Exactly at a pole
        // the sine may be a zero of either sign; θo + θi = ±π then takes the sign of the poles.
        let sin_sum = wo[0] * rho_i + v.rho_o * wi[0];
        let cos_sum = v.rho_o * rho_i - wo[0] * wi[0];
        let at_poles = sin_sum.eq(zero) & cos_sum.lt(zero);
        let pole = R::select((wo[0] + wi[0]).lt(zero), c(-FRAC_PI_2), c(FRAC_PI_2));
        let theta_h = R::select(at_poles, pole, c(0.5) * atan2(sin_sum, cos_sum));
        let (sin_i, cos_i) = sin_cos_from(wi[0], rho_i);
        // cos(φ/2): half the length of the sum of the unit normal-plane projections; 1 when either direction lies
        // along ±u (φ = 0 there).
        let inv_i = c(1.0) / rho_i;
        let (y, z) = (v.cos_r + wi[1] * inv_i, v.sin_r + wi[2] * inv_i);
        let projected = v.rho_o.gt(zero) & rho_i.gt(zero);
        let cos_half_phi = R::select(
            projected,
            (c(0.5) * (y * y + z * z).sqrt()).min(c(1.0)),
            c(1.0),
        );
        // sin(φr − φi) ρo ρi and cos(φr − φi) ρo ρi.
        let phi_sin = wo[2] * wi[1] - wo[1] * wi[2];
        let phi_cos = wo[1] * wi[1] + wo[2] * wi[2];
        Pair {
            sin_i,
            cos_i,
            theta_h,
            cos_theta_d: cos_theta_d(v.sin_o, v.cos_o, sin_i, cos_i),
            cos_half_phi,
            abs_phi: atan2(phi_sin.abs(), phi_cos),
        }
    }

    /// The angles of a pair the sampler has just drawn, from θi (in [−π/2, π/2]) with its sine and cosine, and
    /// the relative azimuth by cos(φ/2) and |φ| (as [`super::frame::Angles::from_sampled`]). These are the angles
    /// of the direction drawn; the direction returned is that one rounded to f32 (see
    /// `testing::assert_sample_consistent`, which bounds the difference).
    #[inline(always)]
    fn of_sampled(
        v: &IsHairView<R>,
        theta_i: R,
        (sin_i, cos_i): (R, R),
        cos_half_phi: R,
        abs_phi: R,
    ) -> Pair<R> {
        let cos_i = cos_i.max(R::splat(0.0));
        Pair {
            sin_i,
            cos_i,
            theta_h: R::splat(0.5) * (v.theta_o + theta_i),
            cos_theta_d: cos_theta_d(v.sin_o, v.cos_o, sin_i, cos_i),
            cos_half_phi,
            abs_phi,
        }
    }

    /// Per lane: `a` where `m` is set, else `b`.
    #[inline(always)]
    fn blend(m: R::Mask, a: Pair<R>, b: Pair<R>) -> Pair<R> {
        let s = |x: R, y: R| R::select(m, x, y);
        Pair {
            sin_i: s(a.sin_i, b.sin_i),
            cos_i: s(a.cos_i, b.cos_i),
            theta_h: s(a.theta_h, b.theta_h),
            cos_theta_d: s(a.cos_theta_d, b.cos_theta_d),
            cos_half_phi: s(a.cos_half_phi, b.cos_half_phi),
            abs_phi: s(a.abs_phi, b.abs_phi),
        }
    }
}

/// The unit direction with longitudinal angle θi (by its sine and cosine) whose azimuth is φi = φr − φ, φ given by
/// its cosine and sine: (cos φi, sin φi) is the view's (cos φr, sin φr) turned by −φ (the angle-difference
/// formulas), so no angle is formed (as [`super::frame::from_sin_cos_theta_and_relative_azimuth`]).
#[inline(always)]
fn direction<R: Real>(v: &IsHairView<R>, (sin_t, cos_t): (R, R), cos_phi: R, sin_phi: R) -> [R; 3] {
    let cos_i = v.cos_r * cos_phi + v.sin_r * sin_phi;
    let sin_i = v.sin_r * cos_phi - v.cos_r * sin_phi;
    let cos_t = cos_t.max(R::splat(0.0));
    [sin_t, cos_t * cos_i, cos_t * sin_i]
}

impl IsHair {
    /// A checked model.
    pub fn new(params: IsHairParams) -> Result<IsHair, BsdfError> {
        const M: &str = "ishair";
        let p = params;
        check_color(M, "k_d", p.k_d)?;
        check_color(M, "color_r", p.color_r)?;
        check_color(M, "color_tt", p.color_tt)?;
        check_color(M, "color_trt", p.color_trt)?;
        check(
            M,
            "glint",
            p.glint,
            ">= 0 and finite",
            p.glint >= 0.0 && p.glint.is_finite(),
        )?;
        for (key, a) in [
            ("alpha_r", p.alpha_r),
            ("alpha_tt", p.alpha_tt),
            ("alpha_trt", p.alpha_trt),
        ] {
            check(M, key, a, "in [-pi/4, pi/4] radians", a.abs() <= FRAC_PI_4)?;
        }
        for (key, b) in [
            ("beta_r", p.beta_r),
            ("beta_tt", p.beta_tt),
            ("beta_trt", p.beta_trt),
        ] {
            check_width(M, key, b, FRAC_PI_2, "in [1e-4, pi/2] radians")?;
        }
        check_width(M, "gamma_tt", p.gamma_tt, 1e6, "in [1e-4, 1e6] radians")?;
        check_width(M, "gamma_g", p.gamma_g, 1e6, "in [1e-4, 1e6] radians")?;
        check(
            M,
            "phi_g",
            p.phi_g,
            "in [0, pi/2] radians",
            (0.0..=FRAC_PI_2).contains(&p.phi_g),
        )?;
        p.balance.validate(M)?;
        if p.sampling == Sampling::ClampAndFlip {
            return Err(BsdfError::Sampling {
                model: M,
                sampling: p.sampling.name(),
            });
        }
        let longitudinal = [
            (p.alpha_r, p.beta_r),
            (p.alpha_tt, p.beta_tt),
            (p.alpha_trt, p.beta_trt),
        ];
        // Estimated albedos at θo = 0: 2∫M dθh over [−π/4, π/4] (dθi = 2dθh) × ∫N dφ × lum(C), times
        // cos²θi/cos²θd at the lobe's peak (θi = 2α, θd = −α), which the furnace integrand carries.
        let m_int = |(alpha, beta): (f32, f32)| {
            let tilt = ((2.0 * alpha).cos() / alpha.cos()).powi(2);
            2.0 * gaussian_unit_integral(beta, -FRAC_PI_4 - alpha, FRAC_PI_4 - alpha) * tilt
        };
        let n_tt_int = gaussian_unit_integral(p.gamma_tt, -PI, PI);
        let n_g_int = 2.0 * gaussian_unit_integral(p.gamma_g, -p.phi_g, PI - p.phi_g);
        let energies = [
            luminance(p.color_r) * m_int(longitudinal[0]) * 4.0,
            luminance(p.color_tt) * m_int(longitudinal[1]) * n_tt_int,
            luminance(p.color_trt) * m_int(longitudinal[2]) * 4.0,
            luminance(p.color_trt) * p.glint * m_int(longitudinal[2]) * n_g_int,
        ];
        let e_spec: f32 = energies.iter().sum();
        let probs = match p.selection {
            LobeSelection::Uniform => [0.25; 4],
            LobeSelection::ByEnergy if e_spec > 0.0 => energies.map(|e| e / e_spec),
            LobeSelection::ByEnergy => [0.25; 4],
        };
        let cum = [
            probs[0],
            probs[0] + probs[1],
            probs[0] + probs[1] + probs[2],
        ];
        let lum_kd = luminance(p.k_d);
        let fixed_balance = match p.balance {
            Balance::Fresnel { .. } => None,
            b => {
                let (w_d, w_s) = b.weights(1.0);
                Some([w_d, w_s, selection_probability(w_s * e_spec, w_d * lum_kd)])
            }
        };
        Ok(IsHair {
            params,
            alpha: longitudinal.map(|(alpha, _)| alpha),
            beta: longitudinal.map(|(_, beta)| beta),
            inv_beta: longitudinal.map(|(_, beta)| 1.0 / beta),
            inv_gamma_tt: 1.0 / p.gamma_tt,
            inv_gamma_g: 1.0 / p.gamma_g,
            probs,
            cum,
            glint_split: cum[2] + 0.5 * probs[3],
            e_spec,
            energies,
            lum_kd,
            diffuse: diffuse_f(p.k_d).to_array(),
            fixed_balance,
            tt: tt_distribution(p.gamma_tt).to_f32(),
            glint: glint_distribution(p.gamma_g, p.phi_g).to_f32(),
        })
    }

    /// The parameters the model was built with.
    pub fn params(&self) -> &IsHairParams {
        &self.params
    }

    /// The estimated albedo of R, TT, TRT − g and g at θo = 0 that [`LobeSelection::ByEnergy`] uses.
    pub fn estimated_energies(&self) -> [f32; 4] {
        self.energies
    }

    /// The selection probabilities of R, TT, TRT − g and g among the specular lobes.
    pub fn lobe_probabilities(&self) -> [f32; 4] {
        self.probs
    }

    /// (w_d, w_s, p_s) for a view with longitudinal cosine `cos_theta_o`: the diffuse and specular weights, and the
    /// probability of sampling the specular lobes, w_s ΣE_X against w_d lum(k_d).
    #[inline(always)]
    fn balance<R: Real>(&self, cos_theta_o: R) -> [R; 3] {
        match self.fixed_balance {
            Some([w_d, w_s, p_s]) => [R::splat(w_d), R::splat(w_s), R::splat(p_s)],
            // The Fresnel balance depends on θo: `Balance::weights` (`fresnel::dielectric`) and
            // `selection_probability`, the one implementation of each, which every model shares; once per view.
            None => {
                let (w_d, w_s) = self.params.balance.weights(cos_theta_o);
                let p_s =
                    selection_probability(w_s * R::splat(self.e_spec), w_d * R::splat(self.lum_kd));
                [w_d, w_s, p_s]
            }
        }
    }

    /// Every lobe's f at the angles of a pair, before its colour: the factors of C_R, C_TT, C_TRT (TRT − g), C_TRT
    /// (the glint) and k_d/π² (the diffuse term).
    #[inline(always)]
    fn lobe_factors<R: Real>(&self, v: &IsHairView<R>, a: &Pair<R>) -> [R; 5] {
        let c = R::splat;
        let p = &self.params;
        // Guard: cos θd → 0 only for θr = −θi = ±π/2.
        let cos_d = a.cos_theta_d.max(c(COS_THETA_MIN));
        let s = v.w_s / (cos_d * cos_d);
        // Exponents of the unit-height Gaussians: M_X (eq. 15–16) in θh, N_TT and N_g (eq. 17) in |φ|. The products
        // M_TT N_TT and M_TRT N_g are each one exponential of the summed exponents (what `m_x`, `n_tt` and `n_g`
        // multiply out to), so f costs four exponentials, not five.
        let e = |k: usize| m_exponent(c(self.inv_beta[k]), c(self.alpha[k]), a.theta_h);
        let (e_r, e_tt, e_trt) = (e(0), e(1), e(2));
        let e_n_tt = n_tt_exponent(c(self.inv_gamma_tt), a.abs_phi);
        let e_n_g = n_g_exponent(c(self.inv_gamma_g), c(p.phi_g), a.abs_phi);
        // N_R = N_TRT−g = cos(φ/2), from the half-angle vector (see `Pair`).
        let n_r = a.cos_half_phi;
        [
            s * exp_lobe_of(e_r) * n_r,
            s * exp_lobe_of(e_tt + e_n_tt),
            s * exp_lobe_of(e_trt) * n_r,
            s * c(p.glint) * exp_lobe_of(e_trt + e_n_g),
            v.w_d,
        ]
    }

    /// Every lobe's f at the angles of a pair, channel by channel.
    #[inline(always)]
    fn lobes_at<R: Real>(&self, v: &IsHairView<R>, a: &Pair<R>) -> LobesOf<R> {
        let c = R::splat;
        let p = &self.params;
        let [r, tt, trt, glint, w_d] = self.lobe_factors(v, a);
        let coloured = |colour: Vec3, x: R| [c(colour.x) * x, c(colour.y) * x, c(colour.z) * x];
        LobesOf {
            r: coloured(p.color_r, r),
            tt: coloured(p.color_tt, tt),
            trt: coloured(p.color_trt, trt),
            glint: coloured(p.color_trt, glint),
            diffuse: [
                c(self.diffuse[0]) * w_d,
                c(self.diffuse[1]) * w_d,
                c(self.diffuse[2]) * w_d,
            ],
        }
    }

    /// f at one pair in f32, summed over the lobes with their colours as vectors: the scalar eval and sample's f,
    /// the same products and the same order of sums as [`IsHair::lobes_at`] and [`LobeValues::sum`] (so equal to
    /// that sum bit for bit), five vector multiplications instead of fifteen scalar ones.
    #[inline(always)]
    fn f_at(&self, v: &IsHairView<f32>, a: &Pair<f32>) -> Vec3 {
        let p = &self.params;
        let [r, tt, trt, glint, w_d] = self.lobe_factors(v, a);
        let colour = |c: Vec3| Vec3A::from(c);
        Vec3::from(
            colour(p.color_r) * r
                + colour(p.color_tt) * tt
                + colour(p.color_trt) * trt
                + colour(p.color_trt) * glint
                + Vec3A::from_array(self.diffuse) * w_d,
        )
    }

    /// The pdf with which [`Fibre::sample_view`] draws a pair: the whole mixture, Σ selection probability × lobe
    /// pdf.
    #[inline(always)]
    fn pdf_at<R: Real>(&self, v: &IsHairView<R>, a: &Pair<R>) -> R {
        let c = R::splat;
        if self.params.sampling == Sampling::Uniform {
            return c(UNIFORM_SPHERE_PDF);
        }
        // θh is in range by construction; clamp away the rounding at θi = ±π/2.
        let theta_h = a.theta_h.max(v.theta_h_lo).min(v.theta_h_hi);
        // p(θh) of each longitudinal term (eq. 18–19), β/((A − B)((θh − α)² + β²)); p(θi) = p(θh)/2, and eq. 20's
        // 1/cos θi is applied once below.
        let [p_theta_r, p_theta_tt, p_theta_trt] = [
            v.theta_h[0].pdf(theta_h),
            v.theta_h[1].pdf(theta_h),
            v.theta_h[2].pdf(theta_h),
        ];
        // φ: eq. 21a and 21c's density cos(φ/2)/4; eq. 21b's in δ = φ − π wrapped to [−π, π], a Cauchy centred on
        // 0 there, so even: its value at |δ| = π − |φ|; eq. 21d's halved between ±φ_g.
        let p_r = c(0.25) * a.cos_half_phi;
        let p_tt = self.tt.splat::<R>().pdf(c(PI) - a.abs_phi);
        let p_g = c(0.5) * self.glint.splat::<R>().pdf(a.abs_phi);
        let q = [
            c(self.probs[0]),
            c(self.probs[1]),
            c(self.probs[2]),
            c(self.probs[3]),
        ];
        let spec = c(0.5)
            * (q[0] * p_theta_r * p_r
                + q[1] * p_theta_tt * p_tt
                + p_theta_trt * (q[2] * p_r + q[3] * p_g));
        // The diffuse pdf, cos θi/π² ([`diffuse_pdf`], linear in cos θi: its value at 1 is the factor).
        v.p_s * spec / a.cos_i.max(c(COS_THETA_MIN))
            + (c(1.0) - v.p_s) * (c(diffuse_pdf(1.0)) * a.cos_i)
    }

    /// A diffuse sample in every lane: Kajiya-Kay's exact sampler ([`sample_diffuse_of`], in lanes: the one
    /// implementation), with u0 rescaled over the diffuse share [p_s, 1).
    #[inline(always)]
    fn sample_diffuse_lanes<R: Real>(&self, v: &IsHairView<R>, u: [R; 3]) -> ([R; 3], Pair<R>, R) {
        let c = ((u[0] - v.p_s) / (R::splat(1.0) - v.p_s)).min(R::splat(1.0));
        let wi = sample_diffuse_of(u[1], u[2], c);
        (
            wi,
            Pair::of_directions(v, wi),
            R::splat(lobe_index(Lobe::Diffuse)),
        )
    }

    /// A specular sample in every lane (Ou et al. 2012): the lobe by u0/p_s against the running selection
    /// probabilities, θh from the lobe's Cauchy (eq. 18, TRT's for the glint too), φ by eq. 21a–d.
    #[inline(always)]
    fn sample_specular_lanes<R: Real>(&self, v: &IsHairView<R>, u: [R; 3]) -> ([R; 3], Pair<R>, R) {
        let c = R::splat;
        let x = u[0] / v.p_s;
        let is_r = x.lt(c(self.cum[0]));
        let is_tt = !is_r & x.lt(c(self.cum[1]));
        let is_trt = !(is_r | is_tt) & x.lt(c(self.cum[2]));
        let lobe = R::select(
            is_r,
            c(lobe_index(Lobe::R)),
            R::select(
                is_tt,
                c(lobe_index(Lobe::Tt)),
                R::select(is_trt, c(lobe_index(Lobe::Trt)), c(lobe_index(Lobe::Glint))),
            ),
        );
        // θ: eq. 18, θi = 2θh − θo.
        let theta_h = TruncatedCauchyOf::select(
            is_r,
            &v.theta_h[0],
            &TruncatedCauchyOf::select(is_tt, &v.theta_h[1], &v.theta_h[2]),
        )
        .sample(u[1]);
        let theta_i = (c(2.0) * theta_h - v.theta_o).clamp_to(-FRAC_PI_2, FRAC_PI_2);
        let sc_i = theta_i.sin_cos();
        // φ: eq. 21a–d, as cos(φ/2), cos φ, sin φ (φi = φr − φ is then turned from ωo's azimuth, no arctangent)
        // and |φ|, each from the half angle: cos(φ/2) stays accurate where it vanishes (φ → ±π).
        let [cos_half, cos_phi, sin_phi, abs_phi] = branch!(
            is_r | is_trt,
            {
                // R and TRT − g: eq. 12 by double angles (`phi_eq12_parts`, the one implementation); |φ| ∈ [0, π]
                // from its cosine and |sine|.
                let (c_half, cos_phi, sin_phi) = phi_eq12_parts(u[2]);
                [c_half, cos_phi, sin_phi, atan2(sin_phi.abs(), cos_phi)]
            },
            {
                // TT (eq. 21b, δ = φ − π) and the glint (eq. 21d, ψ = |φ|): one Cauchy draw with the lobe's
                // distribution, one half-angle sine and cosine.
                let d = TruncatedCauchyOf::select(
                    is_tt,
                    &self.tt.splat::<R>(),
                    &self.glint.splat::<R>(),
                );
                let y = d.sample(u[2]);
                let (s, co) = (c(0.5) * y).sin_cos();
                let two_sc = c(2.0) * s * co;
                // φ = π + δ: cos(φ/2) = |sin(δ/2)|, cos φ = −cos δ, sin φ = −sin δ, |φ| = π − |δ|.
                let tt = [s.abs(), c(2.0) * s * s - c(1.0), -two_sc, c(PI) - y.abs()];
                // |φ| = ψ ∈ [0, π/2], the sign by the remainder of the lobe choice (the thesis leaves it implicit).
                let sin_psi = R::select(x.lt(c(self.glint_split)), two_sc, -two_sc);
                let glint = [co, c(1.0) - c(2.0) * s * s, sin_psi, y];
                blend(is_tt, tt, glint)
            },
            blend,
        );
        (
            direction(v, sc_i, cos_phi, sin_phi),
            Pair::of_sampled(v, theta_i, sc_i, cos_half, abs_phi),
            lobe,
        )
    }
}

/// The model written once over the number type: `R = f32` is its scalar [`Bsdf`] (below, through [`At`]), `R =
/// f32x8` eight shading points at a time.
impl Fibre for IsHair {
    type View<R: Real> = IsHairView<R>;

    #[inline(always)]
    fn view<R: Real>(&self, _h: R, wo: [R; 3]) -> IsHairView<R> {
        let c = R::splat;
        let rho_o = rho(wo[1], wo[2]);
        let (sin_o, cos_o) = sin_cos_from(wo[0], rho_o);
        let theta_o = atan2(wo[0], rho_o);
        let inv = c(1.0) / rho_o;
        let projected = rho_o.gt(c(0.0));
        let [w_d, w_s, p_s] = self.balance(cos_o);
        let (lo, hi) = theta_h_range(theta_o);
        IsHairView {
            wo,
            rho_o,
            cos_r: R::select(projected, wo[1] * inv, c(1.0)),
            sin_r: R::select(projected, wo[2] * inv, c(0.0)),
            sin_o,
            cos_o,
            theta_o,
            w_d,
            w_s,
            p_s,
            theta_h_lo: lo[0],
            theta_h_hi: hi[0],
            theta_h: [
                theta_h_distribution(self.alpha[0], self.beta[0], self.inv_beta[0], lo, hi),
                theta_h_distribution(self.alpha[1], self.beta[1], self.inv_beta[1], lo, hi),
                theta_h_distribution(self.alpha[2], self.beta[2], self.inv_beta[2], lo, hi),
            ],
        }
    }

    #[inline(always)]
    fn eval_view<R: Real>(&self, v: &IsHairView<R>, wi: [R; 3]) -> EvalOf<R> {
        let a = Pair::of_directions(v, wi);
        EvalOf {
            lobes: self.lobes_at(v, &a),
            pdf: self.pdf_at(v, &a),
        }
    }

    #[inline(always)]
    fn sample_view<R: Real>(&self, v: &IsHairView<R>, u: [R; 3]) -> SampleOf<R> {
        let (wi, a, lobe) = self.draw(v, u);
        SampleOf {
            wi,
            eval: EvalOf {
                lobes: self.lobes_at(v, &a),
                pdf: self.pdf_at(v, &a),
            },
            lobe,
        }
    }
}

mod scalar;

#[cfg(test)]
mod tests;
