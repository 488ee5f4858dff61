//! The R lobe of Marschner et al. 2003 as importance sampled by Hery & Ramamoorthi 2012, "Importance sampling of
//! reflection from hair fibers" (JCGT), thesis §4.2 (eq. 5–14); two R-type lobes as in the thesis'
//! `plausibleMarschner` (§5.3.1), plus the Kajiya-Kay diffuse term.
//!
//! # Model (fibre convention, see [`super`])
//!
//! Each lobe k ∈ {1, 2} is
//!
//! f_k = k_s,k · M_k(θh) · N(φ) / (8 cos²θd),  M_k = g(β_k, θh − α_k) (eq. 5),  N = cos(φ/2) (eq. 6),
//!
//! with g the *normalised* Gaussian ([`gaussian`]). The 1/8 is not printed in the thesis; it is fixed by Hery &
//! Ramamoorthi's own estimator: with their pdf (eq. 13) p = M N / (8 cos θi), the weight f cos θi / p equals their
//! eq. 14, k_s cos²θi / cos²θd, only for this f. It is Marschner's S = M N / cos²θd with N normalised over φ
//! (∫ cos(φ/2) dφ = 4) and M over θi (dθi = 2 dθh). So each lobe's albedo is ≈ k_s but **not exactly**: where
//! the Gaussian is cut by θi ∈ [−π/2, π/2] it loses energy, and the factor cos²θi/cos²θd (1 only at the mirror
//! direction with α = 0) moves it far at oblique θo once α ≠ 0. Measured over θo ∈ ±80° and β ∈ [0.5°, 30°]:
//! α = 0 gives [0.56, 1.03] (within 5% of 1 for β ≤ 5° and |θo| ≤ 40°); α = −7.5° gives [0.007, 1.97].
//!
//! [`gaussian`]: super::gaussian::gaussian
//!
//! The lobes: k = 1 is the primary highlight ([`Lobe::R`]), k = 2 the secondary highlight, which the thesis
//! (after Hery & Ramamoorthi) also models with the R term but which is physically TRT, so it is reported as
//! [`Lobe::Trt`]. Their colours are normalised so that k_s,1 + k_s,2 ≤ 1 per channel (each is divided by
//! max(1, max channel of k_s,1 + k_s,2)): the thesis' "normalised" sample budget over two lobes. f = w_d f_diffuse
//! + w_s (f_1 + f_2) with [`Balance`] weights.
//!
//! # Sampling
//!
//! A lobe is chosen with probability ∝ w_d lum(k_d) (Kajiya-Kay diffuse, [`super::kajiya_kay::sample_diffuse`])
//! and w_s lum(k_s,k) (the sample budget split between the two R lobes); then for an R lobe:
//!
//! - [`Sampling::ClampAndFlip`] — as published: Z = √(−2 ln ξ1) cos 2πξ2 (eq. 7), θs = β Z clamped to
//!   ±θs,max (eq. 8, with θs,max = π/2 here; the thesis gives no value), θi = 2(θs + α) − θr (eq. 9), θi flipped
//!   about ±π/2 into range (θi → ±π − θi), φ = 2 asin(2ξ − 1) (eq. 12), and the pdf **claimed** by eq. 13,
//!   M N / (8 cos θi). The claim ignores the Gaussian mass cut off by the range and the flipped samples (Ou et al.
//!   2012, appendices A–B), so sample() does not draw from pdf(): estimates are biased. The tests measure it.
//! - [`Sampling::ExactPdf`] — θh from N(α, β²) truncated to the valid range [θr/2 − π/4, θr/2 + π/4] by inverse
//!   CDF ([`TruncatedGaussianOf`]), θi = 2θh − θr, φ by eq. 12. pdf = p_θh(θh) · ½ (dθi = 2 dθh) · cos(φ/2)/4
//!   (eq. 10) / cos θi (solid angle: dω = cos θi dθi dφ). Exactly the density drawn.
//! - [`Sampling::Uniform`] — the sphere.
//!
//! Reciprocal (θh, cos²θd and |φ| are symmetric in i ↔ r) except with [`Balance::Fresnel`].
//!
//! # Parameters ([`MarschnerParams`]; angles in radians)
//!
//! | name | meaning | range | default |
//! |---|---|---|---|
//! | `alpha_1`, `beta_1` | primary shift α_R and width β_R | \|α\| ≤ π/4; β ∈ [1e-4, π/2] | −7.5°, 7.5° (midpoints of Marschner et al. 2003 Table 1: α_R −10°…−5°, β_R 5°…10°) |
//! | `alpha_2`, `beta_2` | secondary shift and width | same | 11.25° = −3α_R/2, 15° = 2β_R (Marschner's TRT relations) |
//! | `k_s1`, `k_s2` | lobe colours, RGB ≥ 0 | normalised as above | 1 (white cuticle reflection); (0.5, 0.35, 0.2) (chosen here: a brown, TRT passes through pigment) |
//! | `k_d` | Kajiya-Kay diffuse colour | RGB ≥ 0 | (0.5, 0.35, 0.2) (chosen here) |
//! | `balance` | diffuse/specular weights | [`Balance`] | user, s = 0.5 |
//! | `sampling` | [`Sampling`] | all three | exact |
//!
//! Curve type: any (round or flat); the model depends on φr − φi only, so the frame's choice of v is immaterial.
//!
//! # One implementation, two forms
//!
//! The model is written once, generic over the number type ([`Real`]), as a [`Fibre`]: [`Fibre::view`] takes what
//! depends on ωo alone (θo, the balance weights, the exact sampler's two truncated Gaussians), then
//! [`Fibre::eval_view`] and [`Fibre::sample_view`] the rest. At `R = f32` it is the scalar [`Bsdf`]
//! ([`Marschner`]'s impl runs it as [`super::lanes::At`] does); at `R = f32x8` it shades eight directions at once
//! ([`super::lanes::InLanes`] runs every test on that form too). Branches are selects, and work no lane needs is
//! skipped (at `f32` the skip is a branch). Precision, where it differs from an all-f64 reading of the
//! equations, is stated beside each equation: the standardised θh of eq. 5 and the exact sampler's ends are
//! formed in f32 (the subtractions that cancel are exact there), the exact sampler's inverse CDF is f32 (its
//! levels are tails formed with relative accuracy), and only the truncated Gaussian's sampler in its tail case,
//! which needs f64, runs lane by lane ([`TruncatedGaussianOf`]).

use super::frame::{
    atan2_of, half_length_of, sin_cos_from_of, theta_h_of, turned_by_relative_azimuth_of,
    unit_azimuth_of, COS_THETA_MIN,
};
use super::gaussian::{exp_lobe_of, TruncatedGaussianOf, INV_SQRT_TAU};
use super::kajiya_kay::{diffuse_f, diffuse_pdf, sample_diffuse_of, selection_probability};
use super::lanes::{EvalOf, Fibre, LobesOf, SampleOf, LANES};
use super::{
    check, check_color, check_width, make_sample, Balance, Bsdf, BsdfError, BsdfSample, Lobe,
    LobeValues, Sampling,
};
use crate::util::color::luminance;
use crate::util::real::{Real, RealMask};
use crate::util::sampling::{uniform_sphere_of, UNIFORM_SPHERE_PDF};
use glam::Vec3;
use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI, TAU};

/// The clamp of θs in the published sampler (eq. 8's θs,max): the thesis gives no value; π/2 keeps one flip
/// enough to bring θi back into range for |α| ≤ π/4 up to a final clamp.
pub const THETA_S_MAX: f32 = FRAC_PI_2;

/// The parameters of [`Marschner::new`] (radians; see the module docs' table).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarschnerParams {
    /// Kajiya-Kay diffuse colour.
    pub k_d: Vec3,
    /// Primary highlight colour k_s,1.
    pub k_s1: Vec3,
    /// Primary longitudinal shift α_1 (negative: towards the root).
    pub alpha_1: f32,
    /// Primary longitudinal width β_1 (standard deviation of M in θh).
    pub beta_1: f32,
    /// Secondary highlight colour k_s,2.
    pub k_s2: Vec3,
    /// Secondary shift α_2.
    pub alpha_2: f32,
    /// Secondary width β_2.
    pub beta_2: f32,
    /// Diffuse/specular weights.
    pub balance: Balance,
    /// Sampling mode.
    pub sampling: Sampling,
}

impl Default for MarschnerParams {
    fn default() -> Self {
        let brown = Vec3::new(0.5, 0.35, 0.2);
        MarschnerParams {
            k_d: brown,
            k_s1: Vec3::ONE,
            alpha_1: (-7.5f32).to_radians(),
            beta_1: 7.5f32.to_radians(),
            k_s2: brown,
            alpha_2: 11.25f32.to_radians(),
            beta_2: 15f32.to_radians(),
            balance: Balance::default(),
            sampling: Sampling::ExactPdf,
        }
    }
}

/// Hery & Ramamoorthi's two-lobe Marschner R model plus Kajiya-Kay diffuse.
#[derive(Debug, Clone, Copy)]
pub struct Marschner {
    params: MarschnerParams,
    /// k_s,1 and k_s,2 after normalisation, channel by channel.
    c: [[f32; 3]; 2],
    /// (α_k, β_k).
    lobes: [(f32, f32); 2],
    /// 1/β_k: eq. 5's standardisation as a multiplication.
    inv_beta: [f32; 2],
    /// 1/(β_k √(2π)): eq. 5's normalisation without a division.
    norm: [f32; 2],
    /// The probability of each R lobe among the two.
    probs: [f32; 2],
    /// Estimated specular albedo, lum(c_1) + lum(c_2) (each lobe's albedo is ≈ its colour).
    e_spec: f32,
    /// The diffuse f at unit weight, k_d/π² ([`diffuse_f`]), channel by channel.
    diffuse: [f32; 3],
    /// (w_d, w_s, the probability of the specular lobes) when the balance does not depend on ωo.
    fixed: Option<(f32, f32, f32)>,
}

/// The index in [`Lobe::ALL`] of `lobe`, as the [`SampleOf::lobe`] number.
#[inline(always)]
const fn lobe_index(lobe: Lobe) -> f32 {
    // `Lobe::ALL` lists the lobes in declaration order (tested).
    lobe as u8 as f32
}

/// M = g(β, θh − α), the normalised Gaussian (thesis eq. 5).
#[inline]
pub fn m_r<R: Real>(beta: R, alpha: R, theta_h: R) -> R {
    let inv_beta = R::splat(1.0) / beta;
    m_r_scaled(alpha, inv_beta, inv_beta * R::splat(INV_SQRT_TAU), theta_h)
}

/// M = g(β, θh − α) (eq. 5) given 1/β and the normalisation `norm` = 1/(β√(2π)), which a model takes once.
///
/// Precision: x = (θh − α)/β in f32. Where θh − α cancels (a narrow lobe near its peak) the subtraction is exact
/// (Sterbenz), elsewhere it rounds once (6e-8 relative), and so does the product: the exponent −x²/2 carries a
/// relative error ≈ 2.4e-7, < 5e-6 in M wherever M is within e^{−20} of its peak, below what θh's own error
/// (an arctangent's 6e-7 rad, i.e. 6e-7/β in x) makes of it.
#[inline(always)]
pub fn m_r_scaled<R: Real>(alpha: R, inv_beta: R, norm: R, theta_h: R) -> R {
    let x = (theta_h - alpha) * inv_beta;
    norm * exp_lobe_of(R::splat(-0.5) * (x * x))
}

/// N = cos(φ/2) (thesis eq. 6), φ the relative azimuth ∈ [−π, π] (≥ 0 there).
#[inline]
pub fn n_r<R: Real>(phi: R) -> R {
    (R::splat(0.5) * phi).cos().max(R::splat(0.0))
}

/// One lobe's f per unit colour: M N / (8 cos²θd) (see the module docs for the 1/8).
#[inline]
pub fn f_lobe<R: Real>(m: R, n: R, cos_theta_d: R) -> R {
    m * n_over_8_cos2_d(n, cos_theta_d)
}

/// N / (8 cos²θd): [`f_lobe`] without M, which both lobes share (one division for the two).
#[inline(always)]
pub fn n_over_8_cos2_d<R: Real>(n: R, cos_theta_d: R) -> R {
    // Guard: cos θd → 0 only for θr = −θi = ±π/2.
    let c = cos_theta_d.max(R::splat(COS_THETA_MIN));
    n / (R::splat(8.0) * c * c)
}

/// The pdf Hery & Ramamoorthi claim for their sampler (thesis eq. 13): M N / (8 cos θi).
#[inline(always)]
pub fn pdf_eq13<R: Real>(m: R, n: R, cos_theta_i: R) -> R {
    m * n / (R::splat(8.0) * cos_theta_i.max(R::splat(COS_THETA_MIN)))
}

/// The sample weight of eq. 14 per unit k_s: cos²θi / cos²θd, which Hery & Ramamoorthi approximate by 1 for sharp
/// lobes.
#[inline]
pub fn weight_eq14<R: Real>(cos_theta_i: R, cos_theta_d: R) -> R {
    let c = cos_theta_d.max(R::splat(COS_THETA_MIN));
    cos_theta_i * cos_theta_i / (c * c)
}

/// θi by the published sampler: Box-Muller (eq. 7), θs clamped (eq. 8), θi (eq. 9), flipped into [−π/2, π/2].
#[inline(always)]
pub fn theta_i_clamp_and_flip<R: Real>(alpha: R, beta: R, theta_r: R, xi1: R, xi2: R) -> R {
    let c = R::splat;
    // Guard: ξ1 = 0 would give ln 0.
    let z1 = (c(-2.0) * xi1.max(c(f32::MIN_POSITIVE)).ln()).sqrt() * (c(TAU) * xi2).cos();
    let theta_s = (beta * z1).clamp_to(-THETA_S_MAX, THETA_S_MAX);
    let theta_i = c(2.0) * (theta_s + alpha) - theta_r;
    // Flip about ±π/2 (Hery & Ramamoorthi: "flip θi about the u vector"), then clamp what one flip cannot fix.
    let theta_i = R::select(
        theta_i.gt(c(FRAC_PI_2)),
        c(PI) - theta_i,
        R::select(theta_i.lt(c(-FRAC_PI_2)), c(-PI) - theta_i, theta_i),
    );
    theta_i.clamp_to(-FRAC_PI_2, FRAC_PI_2)
}

/// (cos(φ/2), cos φ, sin φ) of [`phi_eq12`]'s φ = 2 asin(s), s = 2ξ − 1, without the arcsine or a sine and
/// cosine: by the double-angle formulas with sin(φ/2) = s and cos(φ/2) = √((1 − s)(1 + s)) ≥ 0 (factored: no
/// cancellation near s = ±1), cos φ = 1 − 2s², sin φ = 2s cos(φ/2). cos(φ/2) is N (eq. 6) at the sample.
#[inline(always)]
pub fn phi_eq12_parts<R: Real>(xi: R) -> (R, R, R) {
    let one = R::splat(1.0);
    let s = (R::splat(2.0) * xi - one).clamp_to(-1.0, 1.0);
    let c = ((one - s) * (one + s)).sqrt();
    (c, one - R::splat(2.0) * s * s, R::splat(2.0) * s * c)
}

/// The relative azimuth by inverting eq. 11's CDF (thesis eq. 12): φ = 2 asin(2ξ − 1), density cos(φ/2)/4.
#[inline]
pub fn phi_eq12<R: Real>(xi: R) -> R {
    R::splat(2.0)
        * (R::splat(2.0) * xi - R::splat(1.0))
            .clamp_to(-1.0, 1.0)
            .asin()
}

/// What [`Marschner`]'s eval and sample share for one ωo ([`Fibre::View`]), one per lane.
#[derive(Clone, Copy)]
pub struct MarschnerView<R: Real> {
    /// ωo's tangent component and normal-plane length, for θh's angle sum ([`theta_h_of`]).
    x_o: R,
    rho_o: R,
    /// sin θo, cos θo ≥ 0 and θo.
    sin_o: R,
    cos_o: R,
    theta_o: R,
    /// ωo's unit normal-plane direction (cos φr, sin φr) ((1, 0) along ±u), and whether it has one.
    cos_r: R,
    sin_r: R,
    has_azimuth: R::Mask,
    /// The balance weights (w_d, w_s) and the probability of sampling the specular lobes.
    w_d: R,
    w_s: R,
    p_s: R,
    /// The θh range [θr/2 − π/4, θr/2 + π/4] (θi ∈ [−π/2, π/2]), in f32.
    lo: R,
    hi: R,
    /// Both lobes' exact θh distributions ([`Sampling::ExactPdf`] only): the drawn one samples, both normalise
    /// the pdf.
    dists: Option<[TruncatedGaussianOf<R>; 2]>,
}

/// The angles of one (ωo, ωi) pair that f and the pdf read, beside the view's.
#[derive(Clone, Copy)]
struct Pair<R> {
    /// cos θi ≥ 0.
    cos_i: R,
    /// θh = (θr + θi)/2.
    theta_h: R,
    /// cos θd ≥ 0.
    cos_d: R,
    /// cos(φ/2) ≥ 0: N (eq. 6).
    cos_half_phi: R,
}

impl<R: Real> Pair<R> {
    /// Per lane: `x` where `m` is set, else `y`.
    #[inline(always)]
    fn pick(m: R::Mask, x: &Self, y: &Self) -> Self {
        Pair {
            cos_i: R::select(m, x.cos_i, y.cos_i),
            theta_h: R::select(m, x.theta_h, y.theta_h),
            cos_d: R::select(m, x.cos_d, y.cos_d),
            cos_half_phi: R::select(m, x.cos_half_phi, y.cos_half_phi),
        }
    }
}

impl Marschner {
    /// A checked model.
    pub fn new(params: MarschnerParams) -> Result<Marschner, BsdfError> {
        const M: &str = "marschner";
        check_color(M, "k_d", params.k_d)?;
        check_color(M, "k_s1", params.k_s1)?;
        check_color(M, "k_s2", params.k_s2)?;
        let alpha_ok = |a: f32| a.abs() <= FRAC_PI_4;
        check(
            M,
            "alpha_1",
            params.alpha_1,
            "in [-pi/4, pi/4] radians",
            alpha_ok(params.alpha_1),
        )?;
        check(
            M,
            "alpha_2",
            params.alpha_2,
            "in [-pi/4, pi/4] radians",
            alpha_ok(params.alpha_2),
        )?;
        check_width(
            M,
            "beta_1",
            params.beta_1,
            FRAC_PI_2,
            "in [1e-4, pi/2] radians",
        )?;
        check_width(
            M,
            "beta_2",
            params.beta_2,
            FRAC_PI_2,
            "in [1e-4, pi/2] radians",
        )?;
        params.balance.validate(M)?;
        let norm = (params.k_s1 + params.k_s2).max_element().max(1.0);
        let c = [params.k_s1 / norm, params.k_s2 / norm];
        let prob_1 = selection_probability(luminance(c[0]), luminance(c[1]));
        let betas = [params.beta_1, params.beta_2];
        let mut m = Marschner {
            params,
            c: c.map(|c| c.to_array()),
            lobes: [
                (params.alpha_1, params.beta_1),
                (params.alpha_2, params.beta_2),
            ],
            inv_beta: betas.map(|b| (1.0 / b as f64) as f32),
            norm: betas.map(|b| INV_SQRT_TAU / b),
            probs: [prob_1, 1.0 - prob_1],
            e_spec: luminance(c[0]) + luminance(c[1]),
            diffuse: diffuse_f(params.k_d).to_array(),
            fixed: None,
        };
        if !matches!(params.balance, Balance::Fresnel { .. }) {
            // Balance::Sum and Balance::User do not read cos θo.
            let (w_d, w_s) = params.balance.weights(1.0);
            m.fixed = Some((w_d, w_s, m.specular_probability(w_d, w_s)));
        }
        Ok(m)
    }

    /// The parameters the model was built with.
    pub fn params(&self) -> &MarschnerParams {
        &self.params
    }

    /// The probability of sampling the specular lobes under balance weights (`w_d`, `w_s`).
    #[inline]
    fn specular_probability(&self, w_d: f32, w_s: f32) -> f32 {
        selection_probability(w_s * self.e_spec, w_d * luminance(self.params.k_d))
    }

    /// (w_d, w_s, probability of the specular lobes) for view cosine `cos_o`. [`Balance::Fresnel`] reads θo
    /// through the scalar Fresnel equations (`Balance::weights`), taken lane by lane: once per view, not per
    /// direction, and the one implementation of that balance.
    #[inline(always)]
    fn weights<R: Real>(&self, cos_o: R) -> (R, R, R) {
        if let Some((w_d, w_s, p_s)) = self.fixed {
            return (R::splat(w_d), R::splat(w_s), R::splat(p_s));
        }
        debug_assert!(R::LANES <= LANES);
        let mut w = [[0.0f32; 3]; LANES];
        for (k, w) in w.iter_mut().enumerate().take(R::LANES) {
            let (w_d, w_s) = self.params.balance.weights(cos_o.lane(k));
            *w = [w_d, w_s, self.specular_probability(w_d, w_s)];
        }
        (
            R::from_fn(|k| w[k][0]),
            R::from_fn(|k| w[k][1]),
            R::from_fn(|k| w[k][2]),
        )
    }

    /// The angles of (ωo, `wi`) beside the view's, from the direction (as [`super::frame::Angles::new`]).
    #[inline(always)]
    fn pair_of<R: Real>(&self, v: &MarschnerView<R>, wi: [R; 3]) -> Pair<R> {
        let rho_i = (wi[1] * wi[1] + wi[2] * wi[2]).sqrt();
        let theta_h = theta_h_of(v.x_o, v.rho_o, wi[0], rho_i);
        let (sin_i, cos_i) = sin_cos_from_of(wi[0], rho_i);
        let cos_d = half_length_of(v.cos_o + cos_i, v.sin_o + sin_i);
        // cos(φ/2): half the length of the sum of the two unit normal-plane projections; 1 (φ = 0) when either
        // direction lies along ±u.
        let inv = R::splat(1.0) / rho_i;
        let both = v.has_azimuth & rho_i.gt(R::splat(0.0));
        let cos_half_phi = R::select(
            both,
            half_length_of(v.cos_r + wi[1] * inv, v.sin_r + wi[2] * inv),
            R::splat(1.0),
        );
        Pair {
            cos_i,
            theta_h,
            cos_d,
            cos_half_phi,
        }
    }

    /// The angles of a direction a sampler has just drawn, from what it knows (as
    /// [`super::frame::Angles::from_sampled`]): θi ∈ [−π/2, π/2], its sine and cosine, and N = cos(φ/2).
    #[inline(always)]
    fn sampled_pair<R: Real>(
        &self,
        v: &MarschnerView<R>,
        theta_i: R,
        sin_i: R,
        cos_i: R,
        n: R,
    ) -> Pair<R> {
        let cos_i = cos_i.max(R::splat(0.0));
        Pair {
            cos_i,
            theta_h: R::splat(0.5) * (v.theta_o + theta_i),
            cos_d: half_length_of(v.cos_o + cos_i, v.sin_o + sin_i),
            cos_half_phi: n,
        }
    }

    /// Every lobe's f and the mixture pdf at a pair's angles. Each lobe's Gaussian is one exponential for both.
    #[inline(always)]
    fn eval_pair<R: Real>(&self, v: &MarschnerView<R>, p: &Pair<R>) -> EvalOf<R> {
        let (lobes, m) = self.lobes_pair(v, p);
        EvalOf {
            lobes,
            pdf: self.pdf_pair(v, p, m),
        }
    }

    /// Every lobe's f at a pair's angles, and both lobes' M (eq. 5), which the pdf shares.
    #[inline(always)]
    fn lobes_pair<R: Real>(&self, v: &MarschnerView<R>, p: &Pair<R>) -> (LobesOf<R>, [R; 2]) {
        let c = R::splat;
        // (Arrays are built element by element here and below: `array::map` over vectors compiles to copies.)
        let m_k = |k: usize| {
            m_r_scaled(
                c(self.lobes[k].0),
                c(self.inv_beta[k]),
                c(self.norm[k]),
                p.theta_h,
            )
        };
        let m = [m_k(0), m_k(1)];
        // f_k = c_k M_k N / (8 cos²θd) (`f_lobe`): the lobes share w_s N / (8 cos²θd), one division.
        let s = v.w_s * n_over_8_cos2_d(p.cos_half_phi, p.cos_d);
        let mut lobes = LobesOf::zero();
        let (s0, s1) = (s * m[0], s * m[1]);
        let [c0, c1] = self.c;
        lobes.r = [c(c0[0]) * s0, c(c0[1]) * s0, c(c0[2]) * s0];
        lobes.trt = [c(c1[0]) * s1, c(c1[1]) * s1, c(c1[2]) * s1];
        let d = self.diffuse;
        lobes.diffuse = [c(d[0]) * v.w_d, c(d[1]) * v.w_d, c(d[2]) * v.w_d];
        (lobes, m)
    }

    /// The pdf of [`Sampling::Uniform`], which reads no direction; `None` under the other modes.
    #[inline(always)]
    fn uniform_pdf<R: Real>(&self) -> Option<R> {
        (self.params.sampling == Sampling::Uniform).then(|| R::splat(UNIFORM_SPHERE_PDF))
    }

    /// The mixture pdf towards `wi` alone (f is not formed).
    #[inline(always)]
    fn pdf_view<R: Real>(&self, v: &MarschnerView<R>, wi: [R; 3]) -> R {
        if let Some(p) = self.uniform_pdf() {
            return p;
        }
        let p = self.pair_of(v, wi);
        let m = self.lobes_pair(v, &p).1;
        self.pdf_pair(v, &p, m)
    }

    /// The mixture pdf at a pair's angles, given both lobes' M.
    #[inline(always)]
    fn pdf_pair<R: Real>(&self, v: &MarschnerView<R>, p: &Pair<R>, m: [R; 2]) -> R {
        let c = R::splat;
        if let Some(p) = self.uniform_pdf() {
            return p;
        }
        let n = p.cos_half_phi;
        let (p0, p1) = (c(self.probs[0]), c(self.probs[1]));
        let p_spec = match &v.dists {
            Some(d) => {
                // θh is in the range by construction; clamped away from the rounding at θi = ±π/2.
                let theta_h = p.theta_h.max(v.lo).min(v.hi);
                // The truncated Gaussian's density shares M's exponential (M is its untruncated density).
                let ph = p0 * d[0].pdf_given(theta_h, m[0]) + p1 * d[1].pdf_given(theta_h, m[1]);
                // p(θi) = p(θh)/2 (dθi = 2 dθh); p(φ) = cos(φ/2)/4 (eq. 10); per solid angle ÷ cos θi.
                let cos_i = p.cos_i.max(c(COS_THETA_MIN));
                ph * c(0.5) * (c(0.25) * n) / cos_i
            }
            // Eq. 13 is linear in M: the mixture's claim is eq. 13 of the mixed M.
            None => pdf_eq13(p0 * m[0] + p1 * m[1], n, p.cos_i),
        };
        v.p_s * p_spec + (c(1.0) - v.p_s) * diffuse_pdf(p.cos_i)
    }

    /// A direction from one of the R lobes (`u[0]` < the view's p_s), with its angles, and the lanes that drew
    /// lobe 1.
    #[inline(always)]
    fn sample_specular<R: Real>(
        &self,
        v: &MarschnerView<R>,
        u: [R; 3],
    ) -> ([R; 3], Pair<R>, R::Mask) {
        let c = R::splat;
        // Which R lobe, then u[0] rescaled to [0, 1) once more for the published sampler's third number.
        let w = u[0] / v.p_s;
        let first = w.lt(c(self.probs[0]));
        let w = R::select(
            first,
            w / c(self.probs[0]),
            (w - c(self.probs[0])) / c(self.probs[1]),
        )
        .min(c(1.0));
        let (theta_i, xi_phi) = match &v.dists {
            Some(d) => {
                let theta_h = TruncatedGaussianOf::pick(first, &d[0], &d[1]).sample(u[1]);
                (
                    (c(2.0) * theta_h - v.theta_o).clamp_to(-FRAC_PI_2, FRAC_PI_2),
                    u[2],
                )
            }
            None => {
                let (a, b) = (self.lobes[0], self.lobes[1]);
                let alpha = R::select(first, c(a.0), c(b.0));
                let beta = R::select(first, c(a.1), c(b.1));
                (
                    theta_i_clamp_and_flip(alpha, beta, v.theta_o, u[1], u[2]),
                    w,
                )
            }
        };
        let (sin_i, cos_i) = theta_i.sin_cos();
        // φ = φr − φi ⇒ φi = φr − φ (eq. 12's φ by cos(φ/2) = N, cos φ and sin φ).
        let (n, cos_phi, sin_phi) = phi_eq12_parts(xi_phi);
        let wi = turned_by_relative_azimuth_of(sin_i, cos_i, v.cos_r, v.sin_r, cos_phi, sin_phi);
        (wi, self.sampled_pair(v, theta_i, sin_i, cos_i, n), first)
    }

    /// The view of `wo`, with the exact sampler's θh distributions if `dists` (what f alone does not read).
    #[inline(always)]
    fn view_of<R: Real>(&self, wo: [R; 3], dists: bool) -> MarschnerView<R> {
        let rho_o = (wo[1] * wo[1] + wo[2] * wo[2]).sqrt();
        let (sin_o, cos_o) = sin_cos_from_of(wo[0], rho_o);
        let theta_o = atan2_of(wo[0], rho_o);
        let (cos_r, sin_r, has_azimuth) = unit_azimuth_of(wo[1], wo[2], rho_o);
        let (w_d, w_s, p_s) = self.weights(cos_o);
        // The θh range; θr/2 is exact, the ends round once (≤ 3e-8 rad; see `TruncatedGaussianOf`).
        let centre = R::splat(0.5) * theta_o;
        let (lo, hi) = (centre - R::splat(FRAC_PI_4), centre + R::splat(FRAC_PI_4));
        let dists = dists.then(|| {
            let dist = |k: usize| {
                let (alpha, beta) = self.lobes[k];
                TruncatedGaussianOf::new(alpha, beta, self.inv_beta[k], lo, hi)
            };
            [dist(0), dist(1)]
        });
        MarschnerView {
            x_o: wo[0],
            rho_o,
            sin_o,
            cos_o,
            theta_o,
            cos_r,
            sin_r,
            has_azimuth,
            w_d,
            w_s,
            p_s,
            lo,
            hi,
            dists,
        }
    }
}

impl Fibre for Marschner {
    type View<R: Real> = MarschnerView<R>;

    #[inline(always)]
    fn view<R: Real>(&self, _h: R, wo: [R; 3]) -> MarschnerView<R> {
        self.view_of(wo, self.params.sampling == Sampling::ExactPdf)
    }

    #[inline(always)]
    fn eval_view<R: Real>(&self, v: &MarschnerView<R>, wi: [R; 3]) -> EvalOf<R> {
        self.eval_pair(v, &self.pair_of(v, wi))
    }

    #[inline(always)]
    fn sample_view<R: Real>(&self, v: &MarschnerView<R>, u: [R; 3]) -> SampleOf<R> {
        let c = R::splat;
        if self.params.sampling == Sampling::Uniform {
            let wi = uniform_sphere_of(u[0], u[1]);
            return SampleOf {
                wi,
                eval: self.eval_view(v, wi),
                lobe: c(-1.0),
            };
        }
        // A lobe is chosen with probability ∝ w_d lum(k_d) and w_s lum(k_s,k); lanes of either kind go their own
        // way and meet at the angles, from which f and the pdf follow.
        let specular = u[0].lt(v.p_s);
        let mut wi = [c(0.0); 3];
        let mut pair = Pair {
            cos_i: c(0.0),
            theta_h: c(0.0),
            cos_d: c(1.0),
            cos_half_phi: c(0.0),
        };
        let mut lobe = c(lobe_index(Lobe::Diffuse));
        if !specular.all() {
            // The diffuse term's sampler, with u[0] rescaled to [0, 1) once more.
            let w = ((u[0] - v.p_s) / (c(1.0) - v.p_s)).min(c(1.0));
            wi = sample_diffuse_of(u[1], u[2], w);
            pair = self.pair_of(v, wi);
        }
        if specular.any() {
            let (ws, ps, first) = self.sample_specular(v, u);
            wi = [
                R::select(specular, ws[0], wi[0]),
                R::select(specular, ws[1], wi[1]),
                R::select(specular, ws[2], wi[2]),
            ];
            pair = Pair::pick(specular, &ps, &pair);
            let k = R::select(first, c(lobe_index(Lobe::R)), c(lobe_index(Lobe::Trt)));
            lobe = R::select(specular, k, lobe);
        }
        SampleOf {
            wi,
            eval: self.eval_pair(v, &pair),
            lobe,
        }
    }
}

/// The scalar form: the generic code at `f32`, as [`super::lanes::At`] runs it, except that eval and pdf take
/// only the parts of the view and of [`Fibre::eval_view`] that they return.
impl Bsdf for Marschner {
    #[inline]
    fn eval_lobes(&self, wo: Vec3, wi: Vec3) -> LobeValues {
        let v = self.view_of(wo.to_array(), false);
        self.lobes_pair(&v, &self.pair_of(&v, wi.to_array()))
            .0
            .lane(0)
    }

    /// The sum of [`Bsdf::eval_lobes`], with the lobes summed where they are computed.
    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        let v = self.view_of(wo.to_array(), false);
        let l = self.lobes_pair(&v, &self.pair_of(&v, wi.to_array())).0;
        Vec3::from_array(std::array::from_fn(|c| l.r[c] + l.trt[c] + l.diffuse[c]))
    }

    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        let v: MarschnerView<f32> = self.view(0.0, wo.to_array());
        let s = self.sample_view(&v, u);
        // As `SampleOf::to_sample`, with f summed from the lobes' channels directly (gathering them into vectors
        // first went through the stack, and its loads missed store-to-load forwarding).
        let l = &s.eval.lobes;
        let f = Vec3::from_array(std::array::from_fn(|c| l.r[c] + l.trt[c] + l.diffuse[c]));
        let wi = Vec3::from_array(s.wi);
        let lobe = (s.lobe >= 0.0).then(|| Lobe::ALL[s.lobe as usize]);
        make_sample(wi, f, s.eval.pdf, (wi.y * wi.y + wi.z * wi.z).sqrt(), lobe)
    }

    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        // (The view is taken only where it is read.)
        if let Some(p) = self.uniform_pdf() {
            return p;
        }
        let v: MarschnerView<f32> = self.view(0.0, wo.to_array());
        self.pdf_view(&v, wi.to_array())
    }
}

#[cfg(test)]
mod tests;
