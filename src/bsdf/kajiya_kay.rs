//! Kajiya & Kay 1989, "Rendering fur with three dimensional textures": the classic hair shading model, used by the
//! thesis as the diffuse term of both shaders (§5.3).
//!
//! In the fibre convention the reflected radiance is L_o = ∫ f(ωo, ωi) L_i(ωi) cos θi dωi, where θ is the
//! longitudinal angle of §4.1 (sin θ = u·ω) so cos θi = |ωi × u|. (Kajiya & Kay write their terms as radiance
//! per unit irradiance from a light at angle θi; dividing by cos θi gives the f here.)
//!
//! - **Diffuse** ([`Lobe::Diffuse`]): f_d = k_d / π². Since ∫_sphere cos θ dω = π², the albedo is exactly k_d for
//!   every ωo.
//! - **Specular** ([`Lobe::R`]): the light reflects into the cone of directions mirror to ωi about the normal
//!   plane; cos of the angle between ωo and that cone is cos(θi + θo) = cos θi cos θo − sin θi sin θo, and
//!   f_s = k_s · N_p · max(0, cos(θi + θo))^p with N_p = √(p / 2π) / 2π, which makes the albedo ≈ k_s at θo = 0
//!   for large p (Laplace approximation of ∫ cos^p). It is not energy conserving at grazing θo: the tests measure
//!   its albedo (≈ k_s cos²θo at large p: the cone's mirror direction has cos θi = cos θo, and the cone's solid
//!   angle shrinks by another cos θo).
//! - **Balance** ([`Balance`]): f = w_d f_d + w_s f_s, with the weights in the colours ([`Balance::Sum`], what
//!   [`KajiyaKay::new`] does), a user factor (thesis §5.3) or the Fresnel reflectance at θo (thesis §8.2).
//! - **Sampling**: [`Sampling::ExactPdf`] draws the diffuse term proportionally to cos θ (sin θ is the abscissa of
//!   a uniform point in the unit disk, the semicircle law) and the cone from a Gaussian of σ = 1/√p in θi + θo
//!   (cos^p t ≈ e^{−p t²/2}) truncated to θi ∈ [−π/2, π/2], φi uniform; the lobe is chosen in proportion to
//!   w_d·lum(k_d) and w_s·k_s. [`Sampling::Uniform`]: the sphere. [`Sampling::ClampAndFlip`] is refused.
//!
//! Reciprocal (f(ωo, ωi) = f(ωi, ωo)) except with [`Balance::Fresnel`].
//!
//! Parameters: `k_d` (RGB) and `k_s` ≥ 0 (the scene checks k_d + k_s ≤ 1 for [`KajiyaKay::new`]), exponent
//! `p` ≥ 1. Defaults ([`KajiyaKayParams::default`]) are the scene's: k_d = 0.7, k_s = 0.3, p = 60.
//!
//! # One implementation, one lane or eight
//!
//! The model is written once over the number type ([`Real`]) as a [`Fibre`]: [`Fibre::view`] takes what ωo
//! decides ([`KajiyaKayView`]: sin/cos θo, the balance weights in f, θo, the lobe-selection probability and the
//! cone sampler's normalisation), [`Fibre::eval_view`] and [`Fibre::sample_view`] the rest. Its [`Bsdf`] is that
//! code at `R = f32` ([`At`]); at `R = f32x8` it shades eight points at once ([`super::lanes`]). The offset h is
//! not read. Everything is f32 arithmetic: the cone c^p is e^{p ln c}, the sampler's truncated Gaussian
//! (`ConeSampler`) uses f32 error functions and Wichura's single-precision Φ⁻¹; each place states its precision.

use super::frame::{from_spherical_of, sin_cos_theta_of, theta_of, COS_THETA_MIN};
use super::gaussian::{normal_quantile_of, upper_tail_of, INV_SQRT_TAU};
use super::lanes::{At, EvalOf, Fibre, LobesOf, SampleOf};
use super::{check, check_color, Balance, Bsdf, BsdfError, BsdfSample, Lobe, LobeValues, Sampling};
use crate::util::color::luminance;
use crate::util::real::{Real, RealMask};
use crate::util::sampling::{uniform_sphere_of, UNIFORM_SPHERE_PDF};
use glam::Vec3;
use std::f32::consts::{FRAC_1_PI, FRAC_PI_2, PI, TAU};

/// Kajiya-Kay diffuse + specular, with RGB diffuse colour.
#[derive(Debug, Clone, Copy)]
pub struct KajiyaKay {
    /// Diffuse albedo k_d per channel (weight × colour).
    pub k_d: Vec3,
    /// Specular weight k_s (uncoloured: the cuticle reflects white light).
    pub k_s: f32,
    /// Cone exponent p.
    pub p: f32,
    /// N_p, precomputed.
    n_p: f32,
    /// √p = 1/σ of the cone sampler's Gaussian, precomputed.
    sqrt_p: f32,
    /// How the diffuse and specular terms are weighted ([`Balance::Sum`] for [`KajiyaKay::new`]).
    pub balance: Balance,
    /// How [`Bsdf::sample`] draws directions.
    pub sampling: Sampling,
}

/// The parameters of [`KajiyaKay::from_params`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KajiyaKayParams {
    /// Diffuse colour k_d, linear RGB, ≥ 0.
    pub k_d: Vec3,
    /// Specular weight k_s ≥ 0.
    pub k_s: f32,
    /// Cone exponent p ≥ 1.
    pub p: f32,
    /// Diffuse/specular balance.
    pub balance: Balance,
    /// Sampling mode ([`Sampling::ExactPdf`] or [`Sampling::Uniform`]).
    pub sampling: Sampling,
}

impl Default for KajiyaKayParams {
    /// The scene's Kajiya-Kay defaults: k_d = 0.7 (grey; the renderer multiplies by the strand colour),
    /// k_s = 0.3, p = 60, weights in the colours, importance sampling.
    fn default() -> Self {
        KajiyaKayParams {
            k_d: Vec3::splat(0.7),
            k_s: 0.3,
            p: 60.0,
            balance: Balance::Sum,
            sampling: Sampling::ExactPdf,
        }
    }
}

impl KajiyaKay {
    /// A model with diffuse albedo `k_d`, specular weight `k_s` and exponent `p` ([`Balance::Sum`], importance
    /// sampling). Unchecked: the scene validates these.
    pub fn new(k_d: Vec3, k_s: f32, p: f32) -> Self {
        let n_p = (p / TAU).sqrt() / TAU;
        KajiyaKay {
            k_d,
            k_s,
            p,
            n_p,
            sqrt_p: p.sqrt(),
            balance: Balance::Sum,
            sampling: Sampling::ExactPdf,
        }
    }

    /// A checked model: every parameter in range, or an error naming it.
    pub fn from_params(params: KajiyaKayParams) -> Result<Self, BsdfError> {
        const M: &str = "kajiya-kay";
        check_color(M, "k_d", params.k_d)?;
        check(
            M,
            "k_s",
            params.k_s,
            ">= 0 and finite",
            params.k_s >= 0.0 && params.k_s.is_finite(),
        )?;
        check(
            M,
            "p",
            params.p,
            ">= 1 and finite",
            params.p >= 1.0 && params.p.is_finite(),
        )?;
        params.balance.validate(M)?;
        if params.sampling == Sampling::ClampAndFlip {
            return Err(BsdfError::Sampling {
                model: M,
                sampling: params.sampling.name(),
            });
        }
        Ok(KajiyaKay {
            balance: params.balance,
            sampling: params.sampling,
            ..Self::new(params.k_d, params.k_s, params.p)
        })
    }

    /// f(ωo, ωi) for unit `tangent`, `wo`, `wi` in world space. Returns (diffuse, specular) separately for AOVs,
    /// each already multiplied by its [`Balance`] weight. The generic lobes ([`Fibre::eval_view`]'s) at `f32`.
    #[inline]
    pub fn eval(&self, tangent: Vec3, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let (sin_theta_i, cos_theta_i) = world_sin_cos_theta(tangent, wi);
        let (sin_theta_o, cos_theta_o) = world_sin_cos_theta(tangent, wo);
        let terms = self.lobe_terms(sin_theta_o, cos_theta_o);
        let l = self.lobes_at(&terms, sin_theta_i, cos_theta_i);
        (Vec3::from_array(l.diffuse), l.r[0])
    }

    /// What f needs of a view at (sin θo, cos θo): the balance weights folded into each lobe's factor.
    #[inline(always)]
    fn lobe_terms<R: Real>(&self, sin_o: R, cos_o: R) -> LobeTerms<R> {
        let (w_d, w_s) = self.balance.weights(cos_o);
        let k_d = diffuse_f(self.k_d);
        LobeTerms {
            sin_o,
            cos_o,
            w_d,
            w_s,
            diffuse: std::array::from_fn(|c| R::splat(k_d[c]) * w_d),
            specular: w_s * R::splat(self.k_s) * R::splat(self.n_p),
        }
    }

    /// f per lobe towards a direction at (sin θi, cos θi): w_d f_d in [`LobesOf::diffuse`], w_s f_s in
    /// [`LobesOf::r`].
    #[inline(always)]
    fn lobes_at<R: Real>(&self, terms: &LobeTerms<R>, sin_i: R, cos_i: R) -> LobesOf<R> {
        let s = terms.specular * cone(sin_i, cos_i, terms.sin_o, terms.cos_o, self.p);
        LobesOf {
            r: [s; 3],
            diffuse: terms.diffuse,
            ..LobesOf::zero()
        }
    }

    /// The density with which [`Fibre::sample_view`] draws `wi` (longitudinal cosine `cos_i`), per unit solid
    /// angle.
    #[inline(always)]
    fn pdf_at<R: Real>(&self, view: &KajiyaKayView<R>, wi: &[R; 3], cos_i: R) -> R {
        if self.sampling == Sampling::Uniform {
            return R::splat(UNIFORM_SPHERE_PDF);
        }
        // t = θi + θo is in the cone sampler's range by construction; the clamp takes away the rounding at
        // θi = ±π/2.
        let theta_i = theta_of(wi);
        let cone = &view.cone;
        let t = (theta_i + view.theta_o).max(cone.lo).min(cone.hi);
        // Cone: density p_t(θi + θo) in θi, 1/2π in φi; per solid angle ÷ cos θi.
        let p_cone = cone.pdf(t) / (R::splat(TAU) * cos_i.max(R::splat(COS_THETA_MIN)));
        view.p_s * p_cone + (R::splat(1.0) - view.p_s) * diffuse_pdf(cos_i)
    }
}

/// (sin θ, cos θ) of a world-space unit direction about a unit tangent.
#[inline]
fn world_sin_cos_theta(tangent: Vec3, w: Vec3) -> (f32, f32) {
    let s = tangent.dot(w).clamp(-1.0, 1.0);
    (s, (1.0 - s * s).max(0.0).sqrt())
}

/// What f needs of ωo, per lane.
#[derive(Debug, Clone, Copy)]
struct LobeTerms<R> {
    /// sin θo, cos θo.
    sin_o: R,
    cos_o: R,
    /// The balance weights (w_d, w_s) at θo.
    w_d: R,
    w_s: R,
    /// w_d f_d = w_d k_d / π² per channel: the diffuse f, the same towards every ωi.
    diffuse: [R; 3],
    /// w_s k_s N_p: the specular f over the cone max(0, cos(θi + θo))^p.
    specular: R,
}

/// What [`KajiyaKay`]'s eval and sample share for one ωo, per lane ([`Fibre::View`]).
#[derive(Debug, Clone, Copy)]
pub struct KajiyaKayView<R> {
    /// The terms of f.
    lobes: LobeTerms<R>,
    /// θo ∈ [−π/2, π/2] ([`Sampling::ExactPdf`] only, else 0).
    theta_o: R,
    /// The probability of drawing the cone rather than the diffuse term ([`Sampling::ExactPdf`] only).
    p_s: R,
    /// The cone's distribution of θi + θo ([`Sampling::ExactPdf`] only).
    cone: ConeSampler<R>,
}

/// The distribution of t = θi + θo from which [`Sampling::ExactPdf`] draws the cone, per lane: N(0, σ² = 1/p)
/// (cos^p t ≈ e^{−p t²/2}) truncated to [θo − π/2, θo + π/2] (θi ∈ [−π/2, π/2]) and renormalised, sampled by
/// inverse CDF. It is [`super::gaussian::TruncatedGaussian`] for an interval that always contains the mean (θo ∈
/// [−π/2, π/2]), written for lanes in f32 arithmetic:
///
/// - The standardised ends are a = (θo − π/2)√p ≤ 0 ≤ b = (θo + π/2)√p; the tails Φ(a) and 1 − Φ(b) are each
///   ½ erfc(|·|/√2) ([`upper_tail_of`], relative accuracy ~1e-7, 0 beyond 6σ as in the f64 type), and the mass
///   Z = 1 − Φ(a) − (1 − Φ(b)) ≥ 0.499 (p ≥ 1, the interval π wide) does not cancel in f32.
/// - pdf(t) = √p e^{−p t²/2} / (√(2π) Z): the exponent is rounded in f32, relative error ≲ (p t²/2)·6e-8 (5e-6 at
///   the largest exponent not flushed to 0, [`exp_neg`]).
/// - The sampler inverts the same CDF: Φ⁻¹ of the lower-tail level Φ(a) + uZ below the median, −Φ⁻¹ of the
///   upper-tail level (1 − Φ(b)) + (1 − u)Z above it (no 1 − Φ cancels), with [`normal_quantile_of`] (relative
///   accuracy 3e-7): so it draws the density `pdf` returns, to that accuracy (tested against the f64 type: the
///   values at each CDF level agree within 2e-7 in level).
#[derive(Debug, Clone, Copy)]
struct ConeSampler<R> {
    /// The range of t, θo ∓ π/2.
    lo: R,
    hi: R,
    /// Φ(a), the mass below the range.
    below: R,
    /// 1 − Φ(b), the mass above it.
    above: R,
    /// Z, the mass inside it.
    mass: R,
    /// √p / (√(2π) Z), the density's normalisation.
    norm: R,
    /// √p = 1/σ.
    sqrt_p: f32,
}

impl<R: Real> ConeSampler<R> {
    /// The distribution for views at `theta_o` ∈ [−π/2, π/2] and exponent p = `sqrt_p`².
    #[inline(always)]
    fn new(theta_o: R, sqrt_p: f32) -> ConeSampler<R> {
        let lo = theta_o - R::splat(FRAC_PI_2);
        let hi = theta_o + R::splat(FRAC_PI_2);
        let s = R::splat(sqrt_p);
        // Φ(a) = Φ(−|a|) with −a = (π/2 − θo)√p ≥ 0; 1 − Φ(b) = Φ(−b).
        let below = upper_tail_of(-lo * s);
        let above = upper_tail_of(hi * s);
        let mass = R::splat(1.0) - below - above;
        ConeSampler {
            lo,
            hi,
            below,
            above,
            mass,
            norm: R::splat(INV_SQRT_TAU * sqrt_p) / mass,
            sqrt_p,
        }
    }

    /// A placeholder for views that never use it ([`Sampling::Uniform`]).
    #[inline(always)]
    fn unused() -> ConeSampler<R> {
        let z = R::splat(0.0);
        ConeSampler {
            lo: z,
            hi: z,
            below: z,
            above: z,
            mass: z,
            norm: z,
            sqrt_p: 0.0,
        }
    }

    /// The density at `t` ∈ [lo, hi].
    #[inline(always)]
    fn pdf(&self, t: R) -> R {
        let x = t * R::splat(self.sqrt_p);
        self.norm * exp_neg(R::splat(-0.5) * x * x)
    }

    /// The t at CDF level `u` ∈ [0, 1).
    #[inline(always)]
    fn sample(&self, u: R) -> R {
        let one = R::splat(1.0);
        let lower = self.below + u * self.mass;
        let from_below = lower.le(R::splat(0.5));
        // Above the median, the upper tail (1 − Φ(b)) + (1 − u)Z, which keeps its relative precision.
        let level = R::select(from_below, lower, self.above + (one - u) * self.mass);
        let x = normal_quantile_of(level);
        let x = R::select(from_below, x, -x);
        (x * R::splat(1.0 / self.sqrt_p)).max(self.lo).min(self.hi)
    }
}

/// e^x for the (non-positive, up to rounding) exponents of the cone and of its sampling density, and 0 below −87.3,
/// where e^x is below f32's smallest normal number (1.18e-38): `wide`'s exp gives 0 there, and the scalar form
/// skips libm's underflow path (narrow cones underflow for most directions).
#[inline(always)]
fn exp_neg<R: Real>(x: R) -> R {
    let limit = R::splat(-87.3);
    let under = x.lt(limit);
    if under.all() {
        return R::splat(0.0);
    }
    R::select(under, R::splat(0.0), x.max(limit).exp())
}

/// The index of a lobe in [`Lobe::ALL`], as [`SampleOf::lobe`] holds it (the enum is declared in that order).
const fn lobe_index(lobe: Lobe) -> f32 {
    lobe as u8 as f32
}

impl Fibre for KajiyaKay {
    type View<R: Real> = KajiyaKayView<R>;

    #[inline(always)]
    fn view<R: Real>(&self, _h: R, wo: [R; 3]) -> KajiyaKayView<R> {
        let (sin_o, cos_o) = sin_cos_theta_of(&wo);
        let lobes = self.lobe_terms(sin_o, cos_o);
        if self.sampling == Sampling::Uniform {
            return KajiyaKayView {
                lobes,
                theta_o: R::splat(0.0),
                p_s: R::splat(0.0),
                cone: ConeSampler::unused(),
            };
        }
        let theta_o = theta_of(&wo).clamp_to(-FRAC_PI_2, FRAC_PI_2);
        let p_s = selection_probability(
            lobes.w_s * R::splat(self.k_s),
            lobes.w_d * R::splat(luminance(self.k_d)),
        );
        KajiyaKayView {
            lobes,
            theta_o,
            p_s,
            cone: ConeSampler::new(theta_o, self.sqrt_p),
        }
    }

    #[inline(always)]
    fn eval_view<R: Real>(&self, view: &KajiyaKayView<R>, wi: [R; 3]) -> EvalOf<R> {
        let (sin_i, cos_i) = sin_cos_theta_of(&wi);
        EvalOf {
            lobes: self.lobes_at(&view.lobes, sin_i, cos_i),
            pdf: self.pdf_at(view, &wi, cos_i),
        }
    }

    #[inline(always)]
    fn sample_view<R: Real>(&self, view: &KajiyaKayView<R>, u: [R; 3]) -> SampleOf<R> {
        let (wi, lobe) = if self.sampling == Sampling::Uniform {
            (uniform_sphere_of(u[0], u[1]), R::splat(-1.0))
        } else {
            let cone = u[0].lt(view.p_s);
            let mut wi = [R::splat(0.0); 3];
            if cone.any() {
                // Cone: t = θi + θo from the truncated Gaussian, φi uniform.
                let t = view.cone.sample(u[1]);
                let theta_i = (t - view.theta_o).clamp_to(-FRAC_PI_2, FRAC_PI_2);
                wi = from_spherical_of(theta_i, R::splat(TAU) * u[2] - R::splat(PI));
            }
            if !cone.all() {
                // Diffuse, with u[0] rescaled to [0, 1) within its share.
                let one = R::splat(1.0);
                let c = ((u[0] - view.p_s) / (one - view.p_s)).min(one);
                let d = sample_diffuse_of(u[1], u[2], c);
                wi = std::array::from_fn(|k| R::select(cone, wi[k], d[k]));
            }
            let lobe = R::select(
                cone,
                R::splat(lobe_index(Lobe::R)),
                R::splat(lobe_index(Lobe::Diffuse)),
            );
            (wi, lobe)
        };
        // f and the pdf at the direction returned, as eval gives them there.
        SampleOf {
            wi,
            eval: self.eval_view(view, wi),
            lobe,
        }
    }
}

impl Bsdf for KajiyaKay {
    /// The generic lobes at `f32`, without the pdf (which eval does not return).
    #[inline]
    fn eval_lobes(&self, wo: Vec3, wi: Vec3) -> LobeValues {
        let (sin_o, cos_o) = sin_cos_theta_of(&wo.to_array());
        let (sin_i, cos_i) = sin_cos_theta_of(&wi.to_array());
        self.lobes_at(&self.lobe_terms(sin_o, cos_o), sin_i, cos_i)
            .lane(0)
    }

    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        At {
            model: self,
            h: 0.0,
        }
        .sample(wo, u)
    }

    /// The generic pdf at `f32`, without the lobes.
    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let view = self.view(0.0, wo.to_array());
        let wi = wi.to_array();
        self.pdf_at(&view, &wi, sin_cos_theta_of(&wi).1)
    }
}

/// The Kajiya-Kay diffuse f: k_d / π² (albedo exactly k_d in the fibre convention).
#[inline]
pub fn diffuse_f(k_d: Vec3) -> Vec3 {
    k_d * (FRAC_1_PI * FRAC_1_PI)
}

/// A direction with density cos θ / π² per solid angle ([`diffuse_pdf`]), the diffuse term's exact sampler, from
/// three uniform numbers: sin θ = √a cos 2πb is the abscissa of a uniform point in the unit disk, whose density
/// (2/π)√(1 − x²) is the marginal of cos θ/π² in x = sin θ; φ = 2πc − π.
#[inline]
pub fn sample_diffuse(a: f32, b: f32, c: f32) -> Vec3 {
    Vec3::from_array(sample_diffuse_of(a, b, c))
}

/// [`sample_diffuse`] in any number type ([`Real`]), one direction per lane, component by component.
#[inline(always)]
pub fn sample_diffuse_of<R: Real>(a: R, b: R, c: R) -> [R; 3] {
    let one = R::splat(1.0);
    let sin_theta = (a.sqrt() * (R::splat(TAU) * b).cos()).clamp_to(-1.0, 1.0);
    let cos_theta = (one - sin_theta * sin_theta).max(R::splat(0.0)).sqrt();
    let (s, co) = (R::splat(TAU) * c - R::splat(PI)).sin_cos();
    [sin_theta, cos_theta * co, cos_theta * s]
}

/// The density of [`sample_diffuse`] at a direction with longitudinal cosine `cos_theta_i`: cos θi / π². Per lane
/// in any number type ([`Real`]).
#[inline]
pub fn diffuse_pdf<R: Real>(cos_theta_i: R) -> R {
    cos_theta_i * R::splat(FRAC_1_PI * FRAC_1_PI)
}

/// max(0, cos(θi + θo))^p, the Kajiya-Kay specular cone, per lane in any number type ([`Real`]).
///
/// c^p is taken as e^{p ln c}, in f32 in both forms: its relative error is that of the exponent, about
/// (|p ln c| + 2) f32 ulp (≤ 5e-6 where the result is not flushed to 0), where a correctly rounded powf would give
/// 1 ulp; the cos(θi + θo) it is raised from carries that much relative error times p already.
#[inline(always)]
pub fn cone<R: Real>(sin_theta_i: R, cos_theta_i: R, sin_theta_o: R, cos_theta_o: R, p: f32) -> R {
    // cos(θi + θo): how close ωo is to the mirror cone of ωi.
    let c = cos_theta_i * cos_theta_o - sin_theta_i * sin_theta_o;
    let lit = c.gt(R::splat(0.0));
    if !lit.any() {
        return R::splat(0.0);
    }
    // ln of at least the smallest normal number: `wide`'s ln is NaN below it (and +∞ at 0).
    let v = exp_neg(R::splat(p) * c.max(R::splat(f32::MIN_POSITIVE)).ln());
    R::select(lit, v, R::splat(0.0))
}

/// cos θ of the fibre convention: |ω × u| for unit vectors.
#[inline]
pub fn cos_theta(tangent: Vec3, w: Vec3) -> f32 {
    world_sin_cos_theta(tangent, w).1
}

/// The probability of choosing lobe group A with estimated energy `a` over group B with `b` (both ≥ 0): a/(a + b),
/// or 1/2 when both are zero (any choice is then as good, and both stay sampled). Per lane in any number type
/// ([`Real`]).
#[inline]
pub(crate) fn selection_probability<R: Real>(a: R, b: R) -> R {
    let s = a + b;
    let ok = s.gt(R::splat(0.0)) & s.lt(R::splat(f32::INFINITY));
    R::select(ok, a / s, R::splat(0.5))
}

#[cfg(test)]
mod tests;
