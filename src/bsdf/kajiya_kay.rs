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
mod tests {
    use super::super::gaussian::TruncatedGaussian;
    use super::super::lanes::{directions, InLanes, LANES};
    use super::super::testing;
    use super::*;
    use glam::Vec3A;
    use rand::Rng;
    use rand_pcg::Pcg32;
    use wide::f32x8;

    /// Runs `check` on both forms of `m`: its scalar [`Bsdf`] (the generic code at f32) and its eight-lane form
    /// ([`InLanes`]: the f32x8 code with the query in one lane).
    fn both_forms(m: &KajiyaKay, mut check: impl FnMut(&str, &dyn Bsdf)) {
        check("scalar", m);
        check("lanes", &InLanes { model: m, h: 0.3 });
    }

    /// Deterministic stratified estimate of the albedo ∫ f cos θi dωi over the sphere.
    fn albedo(m: &KajiyaKay, wo: Vec3) -> (Vec3, f32) {
        const N: usize = 400; // 400² cells: the Riemann sum of a smooth integrand converges to < 0.1%.
        let (mut d, mut s) = (Vec3::ZERO, 0.0);
        let t = Vec3::X;
        for i in 0..N {
            for j in 0..N {
                let z = -1.0 + 2.0 * (i as f32 + 0.5) / N as f32; // uniform in z = sin θ about the tangent
                let phi = std::f32::consts::TAU * (j as f32 + 0.5) / N as f32;
                let r = (1.0 - z * z).sqrt();
                let wi = Vec3::new(z, r * phi.cos(), r * phi.sin());
                let (fd, fs) = m.eval(t, wo, wi);
                let w = cos_theta(t, wi) * 4.0 * std::f32::consts::PI / (N * N) as f32;
                d += fd * w;
                s += fs * w;
            }
        }
        (d, s)
    }

    #[test]
    fn diffuse_albedo_is_k_d() {
        let m = KajiyaKay::new(Vec3::new(0.2, 0.5, 0.9), 0.0, 10.0);
        let (d, _) = albedo(&m, Vec3::new(0.3, 0.95, 0.0).normalize());
        assert!((d - m.k_d).abs().max_element() < 2e-3, "{d}");
    }

    #[test]
    fn specular_albedo_near_k_s_at_normal_incidence() {
        // Laplace approximation error for p = 60 is O(1/p): allow 5%.
        let m = KajiyaKay::new(Vec3::ZERO, 0.3, 60.0);
        let (_, s) = albedo(&m, Vec3::Y);
        assert!((s / 0.3 - 1.0).abs() < 0.05, "specular albedo {s}");
    }

    fn model(k_d: f32, k_s: f32, p: f32, balance: Balance, sampling: Sampling) -> KajiyaKay {
        KajiyaKay::from_params(KajiyaKayParams {
            k_d: Vec3::splat(k_d),
            k_s,
            p,
            balance,
            sampling,
        })
        .unwrap()
    }

    /// θo of the furnace and chi-square grids, degrees.
    const THETA_O_DEG: [f32; 5] = [-80.0, -40.0, 0.0, 30.0, 75.0];

    #[test]
    fn white_furnace_diffuse_is_exactly_one() {
        // The diffuse term claims albedo k_d for every θo: k_d = 1 must give 1 within quadrature error.
        let m = model(1.0, 0.0, 60.0, Balance::Sum, Sampling::ExactPdf);
        both_forms(&m, |form, b| {
            for t in THETA_O_DEG {
                let a = testing::albedo(b, testing::wo_at(t)).diffuse;
                assert!(
                    (a - Vec3A::ONE).abs().max_element() < 1e-3,
                    "{form} θo {t}°: diffuse albedo {a}"
                );
            }
        });
    }

    #[test]
    fn white_furnace_specular_measured() {
        // Kajiya-Kay's cone is normalised for θo = 0 and large p only. Over p ∈ {4 .. 400} and θo ∈ ±80° the
        // measured albedo (k_s = 1) spans [0.032, 0.997]; at large p it is cos²θo (checked at p = 400).
        let models = [4.0, 20.0, 60.0, 400.0]
            .map(|p| (p, model(0.0, 1.0, p, Balance::Sum, Sampling::ExactPdf)));
        for form in ["scalar", "lanes"] {
            let (mut lo, mut hi) = (f32::MAX, f32::MIN);
            for (p, m) in &models {
                let lanes = InLanes { model: m, h: 0.3 };
                let b: &dyn Bsdf = if form == "scalar" { m } else { &lanes };
                for t in THETA_O_DEG {
                    let a = testing::albedo(b, testing::wo_at(t)).r.x;
                    lo = lo.min(a);
                    hi = hi.max(a);
                    if *p == 400.0 {
                        let want = t.to_radians().cos().powi(2);
                        assert!(
                            (a - want).abs() < 0.01,
                            "{form} p {p} θo {t}°: albedo {a}, cos²θo = {want}"
                        );
                    }
                    if t == 0.0 && *p >= 60.0 {
                        // Laplace's approximation is O(1/p) low: 0.98 at p = 60.
                        assert!(
                            (a - 1.0).abs() < 0.025,
                            "{form} p {p}: albedo at θo = 0 is {a}"
                        );
                    }
                }
            }
            assert!(
                lo > 0.025 && lo < 0.04 && hi > 0.99 && hi <= 1.0,
                "{form}: range [{lo}, {hi}]"
            );
        }
    }

    #[test]
    fn sampler_matches_pdf_chi_square() {
        for sampling in [Sampling::ExactPdf, Sampling::Uniform] {
            let m = model(0.5, 0.5, 30.0, Balance::Fresnel { eta: 1.55 }, sampling);
            both_forms(&m, |form, b| {
                testing::chi_square_battery(
                    &format!("kajiya-kay {} {form}", sampling.name()),
                    b,
                    &THETA_O_DEG[1..],
                );
            });
        }
    }

    #[test]
    fn pdf_integrates_to_one_and_sampled_furnace_matches() {
        for sampling in [Sampling::ExactPdf, Sampling::Uniform] {
            let m = model(0.6, 0.4, 20.0, Balance::User { specular: 0.5 }, sampling);
            both_forms(&m, |form, b| {
                for t in [-60.0, 0.0, 45.0] {
                    let wo = testing::wo_at(t);
                    let integral = testing::pdf_integral(b, wo);
                    assert!(
                        (integral - 1.0).abs() < 2e-3,
                        "{form} {sampling:?} θo {t}°: ∫ pdf = {integral}"
                    );
                    testing::assert_sampled_furnace_matches(
                        &format!("kajiya-kay {form} {sampling:?} θo {t}°"),
                        b,
                        wo,
                        0.01,
                    );
                }
            });
        }
    }

    #[test]
    fn reciprocity_except_fresnel_balance() {
        let user = model(
            0.6,
            0.4,
            20.0,
            Balance::User { specular: 0.3 },
            Sampling::ExactPdf,
        );
        both_forms(&user, |_, b| testing::assert_reciprocal(b, true));
        // Fresnel balance weighs by θo only: not reciprocal, and the test must see it.
        let fresnel = model(
            0.6,
            0.4,
            20.0,
            Balance::Fresnel { eta: 1.55 },
            Sampling::ExactPdf,
        );
        both_forms(&fresnel, |_, b| testing::assert_reciprocal(b, false));
    }

    #[test]
    fn finite_everywhere() {
        for p in [1.0, 60.0, 1e4] {
            for sampling in [Sampling::ExactPdf, Sampling::Uniform] {
                let m = model(0.5, 0.5, p, Balance::Fresnel { eta: 1.55 }, sampling);
                both_forms(&m, |form, b| {
                    testing::assert_finite_sweep(
                        &format!("kajiya-kay {form} p {p} {sampling:?}"),
                        b,
                    );
                });
            }
        }
    }

    #[test]
    fn balance_weights_and_validation() {
        let user = model(
            1.0,
            1.0,
            20.0,
            Balance::User { specular: 0.25 },
            Sampling::ExactPdf,
        );
        let sum = model(1.0, 1.0, 20.0, Balance::Sum, Sampling::ExactPdf);
        let fresnel = model(
            1.0,
            1.0,
            20.0,
            Balance::Fresnel { eta: 1.55 },
            Sampling::ExactPdf,
        );
        for form in ["scalar", "lanes"] {
            let eval = |m: &KajiyaKay, wo: Vec3, wi: Vec3| {
                if form == "scalar" {
                    m.eval_lobes(wo, wi)
                } else {
                    InLanes { model: m, h: 0.3 }.eval_lobes(wo, wi)
                }
            };
            let (wo, wi) = (testing::wo_at(10.0), testing::wo_at(-5.0));
            let l = eval(&user, wo, wi);
            let plain = eval(&sum, wo, wi);
            assert!(
                (l.diffuse - plain.diffuse * 0.75).length() < 1e-6
                    && (l.r - plain.r * 0.25).length() < 1e-6,
                "{form}"
            );
            // Fresnel: at normal view incidence w_s = F(1.55, 1) = 0.0465.
            let f = eval(&fresnel, Vec3::Y, wi);
            let plain = eval(&sum, Vec3::Y, wi);
            assert!(
                (f.r.x / plain.r.x - 0.0465).abs() < 1e-3,
                "{form}: {}",
                f.r.x / plain.r.x
            );
        }
        let bad = KajiyaKayParams {
            p: 0.5,
            ..Default::default()
        };
        assert_eq!(
            KajiyaKay::from_params(bad).unwrap_err().to_string(),
            "kajiya-kay: p must be >= 1 and finite, got 0.5"
        );
        let bad = KajiyaKayParams {
            sampling: Sampling::ClampAndFlip,
            ..Default::default()
        };
        assert!(KajiyaKay::from_params(bad)
            .unwrap_err()
            .to_string()
            .contains("published"));
        let bad = KajiyaKayParams {
            balance: Balance::User { specular: 1.5 },
            ..Default::default()
        };
        assert!(KajiyaKay::from_params(bad)
            .unwrap_err()
            .to_string()
            .contains("specular must be in [0, 1]"));
    }

    #[test]
    fn legacy_eval_matches_trait_eval() {
        // The renderer's world-space eval and the trait's local eval agree (same frame: tangent = x), in both
        // forms.
        let m = KajiyaKay::new(Vec3::new(0.3, 0.2, 0.1), 0.3, 60.0);
        let (wo, wi) = (
            testing::wo_at(20.0),
            super::super::frame::from_spherical(-0.3, 2.0),
        );
        let (d, s) = m.eval(Vec3::X, wo, wi);
        both_forms(&m, |form, b| {
            let l = b.eval_lobes(wo, wi);
            assert!(
                (l.diffuse - Vec3A::from(d)).length() < 1e-7
                    && (l.r.x - s).abs() < 1e-6 * s.max(1.0),
                "{form}: {l:?} against ({d}, {s})"
            );
        });
    }

    #[test]
    fn lobe_indices_follow_lobe_all() {
        for lobe in [Lobe::R, Lobe::Diffuse] {
            assert_eq!(Lobe::ALL[lobe_index(lobe) as usize], lobe);
        }
    }

    /// f32's machine epsilon, for the tolerances below.
    const EPS: f64 = f32::EPSILON as f64;

    /// `got` within `rel` of `want`, relative to the larger (or both below 1e-30).
    fn close(got: f32, want: f32, rel: f64) -> bool {
        let (g, w) = (got as f64, want as f64);
        (g - w).abs() <= rel * g.abs().max(w.abs()) || g.abs().max(w.abs()) < 1e-30
    }

    /// Random unit directions, a quarter of them within 1e-3 rad of a pole (where the cone and its pdf are
    /// steepest in θ).
    fn direction(rng: &mut Pcg32) -> Vec3 {
        let w = crate::util::sampling::uniform_sphere(rng.random(), rng.random());
        if rng.random::<f32>() < 0.25 {
            let s = if rng.random::<bool>() { 1.0 } else { -1.0 };
            super::super::frame::from_spherical(
                s * (FRAC_PI_2 - 1e-3 * rng.random::<f32>()),
                rng.random_range(-PI..PI),
            )
        } else {
            w
        }
    }

    #[test]
    fn eight_lanes_match_the_scalar_form_lane_by_lane() {
        // The f32x8 code against the f32 code, lane by lane, over random (ωo, ωi, u) for every sampling mode,
        // balance and a range of p. Both forms do the same arithmetic; only the transcendental functions differ
        // (`wide`'s polynomials against libm, each within a few ulp), so each value agrees to a few ulp times the
        // condition number of what it went through: the cone e^{p ln c} by 1 + |p ln c|; the pdf's Gaussian
        // e^{−p t²/2} of t = θi + θo (arctangents a few ulp apart in each angle) by 1 + p |t| (|θi| + |θo|).
        // Samples: the same lobe and ωi within 1e-5.
        let mut rng = Pcg32::new(41, 3);
        let (mut worst_r, mut worst_pdf, mut worst_wi, mut draws) = (0.0f64, 0.0f64, 0.0f32, 0);
        for sampling in [Sampling::ExactPdf, Sampling::Uniform] {
            for balance in [
                Balance::Sum,
                Balance::User { specular: 0.3 },
                Balance::Fresnel { eta: 1.55 },
            ] {
                for p in [1.0, 7.0, 60.0, 1e4] {
                    let m = KajiyaKay::from_params(KajiyaKayParams {
                        k_d: Vec3::new(0.2, 0.5, 0.7),
                        k_s: 0.4,
                        p,
                        balance,
                        sampling,
                    })
                    .unwrap();
                    for _ in 0..200 {
                        let wo: [Vec3; LANES] = std::array::from_fn(|_| direction(&mut rng));
                        let wi: [Vec3; LANES] = std::array::from_fn(|_| direction(&mut rng));
                        let u: [[f32; 3]; LANES] = std::array::from_fn(|_| rng.random());
                        let h = f32x8::new(std::array::from_fn(|_| rng.random_range(-1.0..1.0)));
                        let view = m.view(h, directions(&wo));
                        let eval = m.eval_view(&view, directions(&wi));
                        let u8 = std::array::from_fn(|c| f32x8::new(u.map(|u| u[c])));
                        let sample = m.sample_view(&view, u8);
                        for k in 0..LANES {
                            let name = format!(
                                "{sampling:?} {balance:?} p {p} lane {k}: wo {} wi {} u {:?}",
                                wo[k], wi[k], u[k]
                            );
                            let view1 = m.view(0.0, wo[k].to_array());
                            let eval1 = m.eval_view(&view1, wi[k].to_array());
                            let (lobes, pdf) = eval.lane(k);
                            let (lobes1, pdf1) = eval1.lane(0);
                            assert_eq!(lobes.diffuse, lobes1.diffuse, "{name}");
                            assert_eq!(lobes.tt + lobes.trt + lobes.glint, Vec3A::ZERO);
                            let (so, co) = super::super::frame::sin_cos_theta(wo[k]);
                            let (si, ci) = super::super::frame::sin_cos_theta(wi[k]);
                            let c = (ci as f64 * co as f64 - si as f64 * so as f64).max(1e-300);
                            let r_cond = 1.0 + (p as f64 * c.ln()).abs();
                            for ch in 0..3 {
                                assert!(
                                    close(lobes.r[ch], lobes1.r[ch], 4.0 * EPS * r_cond),
                                    "{name}: R {} against {}",
                                    lobes.r,
                                    lobes1.r
                                );
                            }
                            if lobes1.r.x > 1e-30 {
                                let e = (lobes.r.x as f64 / lobes1.r.x as f64 - 1.0).abs();
                                worst_r = worst_r.max(e / (EPS * r_cond));
                            }
                            let (to, ti) =
                                ((so as f64).atan2(co as f64), (si as f64).atan2(ci as f64));
                            let pdf_cond = 1.0 + p as f64 * (to + ti).abs() * (to.abs() + ti.abs());
                            assert!(
                                close(pdf, pdf1, 4.0 * EPS * pdf_cond),
                                "{name}: pdf {pdf} against {pdf1}"
                            );
                            worst_pdf = worst_pdf
                                .max((pdf as f64 / pdf1 as f64 - 1.0).abs() / (EPS * pdf_cond));
                            // The sample: same lobe, same direction.
                            let sample1 = m.sample_view(&view1, u[k]);
                            assert_eq!(
                                sample.lobe.lane(k),
                                sample1.lobe,
                                "{name}: lobe {} against {}",
                                sample.lobe.lane(k),
                                sample1.lobe
                            );
                            let d = (sample.wi(k) - sample1.wi(0)).abs().max_element();
                            worst_wi = worst_wi.max(d);
                            assert!(
                                d < 1e-5,
                                "{name}: sampled wi {} against {}",
                                sample.wi(k),
                                sample1.wi(0)
                            );
                            assert_eq!(
                                sample.to_sample(k).is_some(),
                                sample1.to_sample(0).is_some(),
                                "{name}"
                            );
                            draws += 1;
                        }
                    }
                }
            }
        }
        eprintln!(
            "{draws} lanes: worst R {worst_r:.2} ulp × (1 + |p ln c|), pdf {worst_pdf:.2} ulp × (1 + p|t|(|θi| + \
             |θo|)), sampled wi {worst_wi:e}"
        );
    }

    #[test]
    fn cone_sampler_is_the_truncated_gaussian() {
        // The f32 cone distribution against the f64 TruncatedGaussian it replaces (N(0, 1/p) on [θo − π/2,
        // θo + π/2]), in both forms, for p from 1 to 10⁴ and θo across [−π/2, π/2] (ends included): the pdf within
        // 2e-6 relative plus the f32 rounding of its exponent (6e-8 per unit, 1e-7 allowed) where the density is
        // within e^{−20} of its peak, and the sampler's value at each CDF level within 2e-6 in CDF level
        // (|t32 − t64| · pdf).
        let (mut worst_pdf, mut worst_level) = (0.0f64, 0.0f64);
        for p in [1.0f32, 4.0, 60.0, 1e3, 1e4] {
            let sqrt_p = p.sqrt();
            let thetas: Vec<f32> = (0..=40)
                .map(|i| (-FRAC_PI_2 + i as f32 * PI / 40.0).clamp(-FRAC_PI_2, FRAC_PI_2))
                .collect();
            for chunk in thetas.chunks(LANES) {
                let theta8 = f32x8::new(std::array::from_fn(|k| chunk[k.min(chunk.len() - 1)]));
                let cone8 = ConeSampler::new(theta8, sqrt_p);
                for (k, &theta_o) in chunk.iter().enumerate() {
                    let cone1 = ConeSampler::new(theta_o, sqrt_p);
                    let (lo, hi) = (theta_o - FRAC_PI_2, theta_o + FRAC_PI_2);
                    let tg =
                        TruncatedGaussian::new(0.0, 1.0 / (p as f64).sqrt(), lo as f64, hi as f64);
                    let peak = tg.pdf(0.0);
                    for j in 0..=200 {
                        let t = lo + (hi - lo) * j as f32 / 200.0;
                        let exact = tg.pdf(t as f64);
                        if exact == 0.0 || (peak / exact).ln() > 20.0 {
                            continue;
                        }
                        let e = 0.5 * p as f64 * (t as f64).powi(2);
                        for got in [cone1.pdf(t), cone8.pdf(f32x8::splat(t)).lane(k)] {
                            let err = (got as f64 / exact - 1.0).abs();
                            worst_pdf = worst_pdf.max(err);
                            assert!(
                                err < 2e-6 + 1e-7 * e,
                                "p {p} θo {theta_o} t {t}: pdf {got} against {exact}"
                            );
                        }
                    }
                    for j in 0..=100 {
                        let u = (j as f32 / 100.0).min(1.0 - f32::EPSILON / 2.0);
                        let t64 = tg.sample(u as f64);
                        for t32 in [cone1.sample(u), cone8.sample(f32x8::splat(u)).lane(k)] {
                            assert!((lo..=hi).contains(&t32), "p {p} θo {theta_o}: {t32}");
                            let level = (t32 as f64 - t64).abs() * tg.pdf(0.5 * (t32 as f64 + t64));
                            worst_level = worst_level.max(level);
                            assert!(
                                level < 2e-6,
                                "p {p} θo {theta_o} u {u}: sample {t32} against {t64}"
                            );
                        }
                    }
                }
            }
        }
        eprintln!("worst pdf {worst_pdf:e}, worst CDF level {worst_level:e}");
    }
}
