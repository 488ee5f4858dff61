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

use super::frame::{from_spherical, sin_cos_theta, theta, COS_THETA_MIN};
use super::gaussian::TruncatedGaussian;
use super::{check, check_color, Balance, Bsdf, BsdfError, BsdfSample, Lobe, LobeValues, Sampling};
use crate::util::color::luminance;
use crate::util::sampling::{uniform_sphere, UNIFORM_SPHERE_PDF};
use glam::{Vec3, Vec3A};
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
    /// each already multiplied by its [`Balance`] weight.
    #[inline]
    pub fn eval(&self, tangent: Vec3, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let sin_theta_i = tangent.dot(wi).clamp(-1.0, 1.0);
        let sin_theta_o = tangent.dot(wo).clamp(-1.0, 1.0);
        let cos_theta_i = (1.0 - sin_theta_i * sin_theta_i).max(0.0).sqrt();
        let cos_theta_o = (1.0 - sin_theta_o * sin_theta_o).max(0.0).sqrt();
        self.terms(sin_theta_i, cos_theta_i, sin_theta_o, cos_theta_o)
    }

    /// (w_d f_d, w_s f_s) from the longitudinal sines and cosines.
    #[inline]
    fn terms(
        &self,
        sin_theta_i: f32,
        cos_theta_i: f32,
        sin_theta_o: f32,
        cos_theta_o: f32,
    ) -> (Vec3, f32) {
        let (w_d, w_s) = self.balance.weights(cos_theta_o);
        let diffuse = diffuse_f(self.k_d) * w_d;
        let specular = w_s
            * self.k_s
            * self.n_p
            * cone(sin_theta_i, cos_theta_i, sin_theta_o, cos_theta_o, self.p);
        (diffuse, specular)
    }

    /// The probability of drawing the specular cone rather than the diffuse term, for the balance weights.
    #[inline]
    fn specular_probability(&self, w_d: f32, w_s: f32) -> f32 {
        selection_probability(w_s * self.k_s, w_d * luminance(self.k_d))
    }

    /// The distribution of t = θi + θo the cone sampler draws from.
    #[inline]
    fn cone_distribution(&self, theta_o: f32) -> TruncatedGaussian {
        let (lo, hi) = cone_range(theta_o);
        TruncatedGaussian::new(0.0, 1.0 / (self.p as f64).sqrt(), lo as f64, hi as f64)
    }
}

/// The range of t = θi + θo for θi ∈ [−π/2, π/2], in f32 so that [`KajiyaKay::pdf`] can clamp t to exactly it.
#[inline]
fn cone_range(theta_o: f32) -> (f32, f32) {
    (theta_o - FRAC_PI_2, theta_o + FRAC_PI_2)
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
    let sin_theta = (a.sqrt() * (TAU * b).cos()).clamp(-1.0, 1.0);
    let cos_theta = (1.0 - sin_theta * sin_theta).max(0.0).sqrt();
    let (s, co) = (TAU * c - PI).sin_cos();
    Vec3::new(sin_theta, cos_theta * co, cos_theta * s)
}

/// The density of [`sample_diffuse`] at a direction with longitudinal cosine `cos_theta_i`: cos θi / π².
#[inline]
pub fn diffuse_pdf(cos_theta_i: f32) -> f32 {
    cos_theta_i * (FRAC_1_PI * FRAC_1_PI)
}

/// max(0, cos(θi + θo))^p, the Kajiya-Kay specular cone.
#[inline]
pub fn cone(sin_theta_i: f32, cos_theta_i: f32, sin_theta_o: f32, cos_theta_o: f32, p: f32) -> f32 {
    // cos(θi + θo): how close ωo is to the mirror cone of ωi.
    let c = cos_theta_i * cos_theta_o - sin_theta_i * sin_theta_o;
    if c > 0.0 {
        c.powf(p)
    } else {
        0.0
    }
}

/// cos θ of the fibre convention: |ω × u| for unit vectors.
#[inline]
pub fn cos_theta(tangent: Vec3, w: Vec3) -> f32 {
    let s = tangent.dot(w).clamp(-1.0, 1.0);
    (1.0 - s * s).max(0.0).sqrt()
}

/// The probability of choosing lobe group A with estimated energy `a` over group B with `b` (both ≥ 0): a/(a + b),
/// or 1/2 when both are zero (any choice is then as good, and both stay sampled).
#[inline]
pub(crate) fn selection_probability(a: f32, b: f32) -> f32 {
    let s = a + b;
    if s > 0.0 && s.is_finite() {
        a / s
    } else {
        0.5
    }
}

impl Bsdf for KajiyaKay {
    fn eval_lobes(&self, wo: Vec3, wi: Vec3) -> LobeValues {
        let (sin_o, cos_o) = sin_cos_theta(wo);
        let (sin_i, cos_i) = sin_cos_theta(wi);
        let (d, s) = self.terms(sin_i, cos_i, sin_o, cos_o);
        LobeValues {
            r: Vec3A::splat(s),
            diffuse: d.into(),
            ..LobeValues::default()
        }
    }

    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        if self.sampling == Sampling::Uniform {
            return super::finish_sample(self, wo, uniform_sphere(u[0], u[1]), None);
        }
        let (sin_o, cos_o) = sin_cos_theta(wo);
        let theta_o = theta(wo);
        // Built once for the sample and for the pdf of the result.
        let cone = self.cone_distribution(theta_o);
        let (w_d, w_s) = self.balance.weights(cos_o);
        let p_s = self.specular_probability(w_d, w_s);
        let (wi, lobe) = if u[0] < p_s {
            // Cone: t = θi + θo from the truncated Gaussian, φi uniform.
            let t = cone.sample(u[1] as f64) as f32;
            let theta_i = (t - theta_o).clamp(-FRAC_PI_2, FRAC_PI_2);
            (from_spherical(theta_i, TAU * u[2] - PI), Lobe::R)
        } else {
            let c = ((u[0] - p_s) / (1.0 - p_s)).min(1.0);
            (sample_diffuse(u[1], u[2], c), Lobe::Diffuse)
        };
        let (sin_i, cos_i) = sin_cos_theta(wi);
        let (d, s) = self.terms(sin_i, cos_i, sin_o, cos_o);
        let pdf = Self::mixture_pdf(p_s, &cone, theta_o, theta(wi), cos_i);
        super::make_sample(wi, d + Vec3::splat(s), pdf, cos_i, Some(lobe))
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if self.sampling == Sampling::Uniform {
            return UNIFORM_SPHERE_PDF;
        }
        let (w_d, w_s) = self.balance.weights(sin_cos_theta(wo).1);
        let theta_o = theta(wo);
        let cone = self.cone_distribution(theta_o);
        let p_s = self.specular_probability(w_d, w_s);
        Self::mixture_pdf(p_s, &cone, theta_o, theta(wi), sin_cos_theta(wi).1)
    }
}

impl KajiyaKay {
    /// The pdf of the cone/diffuse mixture at a direction θi (longitudinal cosine `cos_i`) for a view at θo.
    #[inline]
    fn mixture_pdf(
        p_s: f32,
        cone: &TruncatedGaussian,
        theta_o: f32,
        theta_i: f32,
        cos_i: f32,
    ) -> f32 {
        // t is in range by construction; clamp away the rounding at θi = ±π/2.
        let (lo, hi) = cone_range(theta_o);
        let t = (theta_i + theta_o).clamp(lo, hi);
        // Cone: density p_t(θi + θo) in θi, 1/2π in φi; per solid angle ÷ cos θi.
        let p_cone = cone.pdf(t as f64) as f32 / (TAU * cos_i.max(COS_THETA_MIN));
        p_s * p_cone + (1.0 - p_s) * diffuse_pdf(cos_i)
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing;
    use super::*;

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
        for t in THETA_O_DEG {
            let a = testing::albedo(&m, testing::wo_at(t)).diffuse;
            assert!(
                (a - Vec3A::ONE).abs().max_element() < 1e-3,
                "θo {t}°: diffuse albedo {a}"
            );
        }
    }

    #[test]
    fn white_furnace_specular_measured() {
        // Kajiya-Kay's cone is normalised for θo = 0 and large p only. Over p ∈ {4 .. 400} and θo ∈ ±80° the
        // measured albedo (k_s = 1) spans [0.032, 0.997]; at large p it is cos²θo (checked at p = 400).
        let (mut lo, mut hi) = (f32::MAX, f32::MIN);
        for p in [4.0, 20.0, 60.0, 400.0] {
            let m = model(0.0, 1.0, p, Balance::Sum, Sampling::ExactPdf);
            for t in THETA_O_DEG {
                let a = testing::albedo(&m, testing::wo_at(t)).r.x;
                lo = lo.min(a);
                hi = hi.max(a);
                if p == 400.0 {
                    let want = t.to_radians().cos().powi(2);
                    assert!(
                        (a - want).abs() < 0.01,
                        "p {p} θo {t}°: albedo {a}, cos²θo = {want}"
                    );
                }
                if t == 0.0 && p >= 60.0 {
                    // Laplace's approximation is O(1/p) low: 0.98 at p = 60.
                    assert!((a - 1.0).abs() < 0.025, "p {p}: albedo at θo = 0 is {a}");
                }
            }
        }
        assert!(
            lo > 0.025 && lo < 0.04 && hi > 0.99 && hi <= 1.0,
            "range [{lo}, {hi}]"
        );
    }

    #[test]
    fn sampler_matches_pdf_chi_square() {
        for sampling in [Sampling::ExactPdf, Sampling::Uniform] {
            let m = model(0.5, 0.5, 30.0, Balance::Fresnel { eta: 1.55 }, sampling);
            testing::chi_square_battery(
                &format!("kajiya-kay {}", sampling.name()),
                &m,
                &THETA_O_DEG[1..],
            );
        }
    }

    #[test]
    fn pdf_integrates_to_one_and_sampled_furnace_matches() {
        for sampling in [Sampling::ExactPdf, Sampling::Uniform] {
            let m = model(0.6, 0.4, 20.0, Balance::User { specular: 0.5 }, sampling);
            for t in [-60.0, 0.0, 45.0] {
                let wo = testing::wo_at(t);
                let integral = testing::pdf_integral(&m, wo);
                assert!(
                    (integral - 1.0).abs() < 2e-3,
                    "{sampling:?} θo {t}°: ∫ pdf = {integral}"
                );
                testing::assert_sampled_furnace_matches(
                    &format!("kajiya-kay {sampling:?} θo {t}°"),
                    &m,
                    wo,
                    0.01,
                );
            }
        }
    }

    #[test]
    fn reciprocity_except_fresnel_balance() {
        testing::assert_reciprocal(
            &model(
                0.6,
                0.4,
                20.0,
                Balance::User { specular: 0.3 },
                Sampling::ExactPdf,
            ),
            true,
        );
        // Fresnel balance weighs by θo only: not reciprocal, and the test must see it.
        testing::assert_reciprocal(
            &model(
                0.6,
                0.4,
                20.0,
                Balance::Fresnel { eta: 1.55 },
                Sampling::ExactPdf,
            ),
            false,
        );
    }

    #[test]
    fn finite_everywhere() {
        for p in [1.0, 60.0, 1e4] {
            for sampling in [Sampling::ExactPdf, Sampling::Uniform] {
                testing::assert_finite_sweep(
                    &format!("kajiya-kay p {p} {sampling:?}"),
                    &model(0.5, 0.5, p, Balance::Fresnel { eta: 1.55 }, sampling),
                );
            }
        }
    }

    #[test]
    fn balance_weights_and_validation() {
        let m = model(
            1.0,
            1.0,
            20.0,
            Balance::User { specular: 0.25 },
            Sampling::ExactPdf,
        );
        let (wo, wi) = (testing::wo_at(10.0), testing::wo_at(-5.0));
        let l = m.eval_lobes(wo, wi);
        let plain = model(1.0, 1.0, 20.0, Balance::Sum, Sampling::ExactPdf).eval_lobes(wo, wi);
        assert!(
            (l.diffuse - plain.diffuse * 0.75).length() < 1e-6
                && (l.r - plain.r * 0.25).length() < 1e-6
        );
        // Fresnel: at normal view incidence w_s = F(1.55, 1) = 0.0465.
        let f = model(
            1.0,
            1.0,
            20.0,
            Balance::Fresnel { eta: 1.55 },
            Sampling::ExactPdf,
        )
        .eval_lobes(Vec3::Y, wi);
        let plain = model(1.0, 1.0, 20.0, Balance::Sum, Sampling::ExactPdf).eval_lobes(Vec3::Y, wi);
        assert!(
            (f.r.x / plain.r.x - 0.0465).abs() < 1e-3,
            "{}",
            f.r.x / plain.r.x
        );
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
        // The renderer's world-space eval and the trait's local eval agree (same frame: tangent = x).
        let m = KajiyaKay::new(Vec3::new(0.3, 0.2, 0.1), 0.3, 60.0);
        let (wo, wi) = (
            testing::wo_at(20.0),
            super::super::frame::from_spherical(-0.3, 2.0),
        );
        let (d, s) = m.eval(Vec3::X, wo, wi);
        let l = m.eval_lobes(wo, wi);
        assert!(
            (l.diffuse - Vec3A::from(d)).length() < 1e-7 && (l.r.x - s).abs() < 1e-6 * s.max(1.0)
        );
    }
}
