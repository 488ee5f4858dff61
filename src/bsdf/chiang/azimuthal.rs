//! A_p and N_p, the azimuthal terms: the attenuation of each scattering order (Fresnel and one chord's
//! transmittance) and the trimmed logistic about the order's exit azimuth Φ(p), with its inverse-CDF sampler;
//! written once over the number type ([`Real`]).

use super::P_MAX;
use crate::util::color::REC709_LUMINANCE;
use crate::util::real::Real;
use std::f32::consts::{PI, TAU};

/// The Fresnel reflectance of a dielectric of index `eta` at incidence cosine `cos_i`
/// ([`crate::bsdf::fresnel::dielectric`]; 1 past the critical angle).
#[inline(always)]
pub(super) fn dielectric<R: Real>(cos_i: R, eta: f32) -> R {
    let one = R::splat(1.0);
    let zero = R::splat(0.0);
    let eta = R::splat(eta);
    let cos_i = cos_i.max(zero).min(one);
    let sin2_t = (one - cos_i * cos_i) / (eta * eta);
    let cos_t = (one - sin2_t).max(zero).sqrt();
    let r_parl = eta.mul_sub(cos_i, cos_t) / eta.mul_add(cos_i, cos_t);
    let r_perp = (-eta).mul_add(cos_t, cos_i) / eta.mul_add(cos_t, cos_i);
    let f = R::splat(0.5) * r_parl.mul_add(r_parl, r_perp * r_perp);
    R::select(sin2_t.lt(one), f, one)
}

/// A_p per colour channel for p = 0, 1, 2 and the residual p ≥ 3 (index [`P_MAX`]): Fresnel at cos θo cos γo and
/// IOR `eta`, `t` the transmittance of one chord per channel (module docs of [`super`]).
#[inline(always)]
pub fn a_p<R: Real>(cos_theta_o: R, cos_gamma_o: R, eta: f32, t: [R; 3]) -> [[R; 3]; P_MAX + 1] {
    let one = R::splat(1.0);
    let f = dielectric(cos_theta_o * cos_gamma_o, eta);
    let a1 = t.map(|t| (one - f) * (one - f) * t);
    let a2: [R; 3] = std::array::from_fn(|c| a1[c] * f * t[c]);
    // Σ_{p≥3} A₂ (F T)^{p−2}, a geometric series; zero where F T = 1 (then A₂ = 0: F = 1 leaves nothing inside).
    let a3: [R; 3] = std::array::from_fn(|c| {
        let ft = f * t[c];
        a2[c] * R::select(ft.lt(one), ft / (one - ft), R::splat(0.0))
    });
    [[f; 3], a1, a2, a3]
}

/// Rec. 709 luminance of a colour given channel by channel.
#[inline(always)]
pub(super) fn luminance<R: Real>(c: &[R; 3]) -> R {
    let w = REC709_LUMINANCE;
    c[0] * R::splat(w.x) + c[1] * R::splat(w.y) + c[2] * R::splat(w.z)
}

/// Φ(p, γo, γt) = 2p γt − 2γo + pπ, the azimuth (φi − φo) of the p-th order's exit (Chiang et al., from
/// Marschner et al. 2003).
#[inline(always)]
pub fn phi_p<R: Real>(p: usize, gamma_o: R, gamma_t: R) -> R {
    let p = p as f32;
    R::splat(2.0 * p) * gamma_t - R::splat(2.0) * gamma_o + R::splat(p * PI)
}

/// An angle wrapped to [−π, π].
#[inline(always)]
pub(super) fn wrap<R: Real>(d: R) -> R {
    (d - R::splat(TAU) * (d * R::splat(1.0 / TAU)).round()).clamp_to(-PI, PI)
}

/// The logistic of scale `s` trimmed to [−π, π]: e^{−|x|/s} / (s (1 + e^{−|x|/s})²) / tanh(π/2s) (the CDF's
/// difference at ±π is tanh(π/2s)).
#[inline]
pub fn trimmed_logistic(x: f32, s: f32) -> f32 {
    Azimuthal::new(s).eval(x)
}

/// The trimmed logistic of one scale s, its constants taken once.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Azimuthal {
    /// s.
    pub(super) s: f32,
    /// 1/s.
    pub(super) inv_s: f32,
    /// 1/(s tanh(π/2s)).
    pub(super) norm: f32,
    /// F(−π) = 1/(1 + e^{π/s}) and tanh(π/2s), for [`Azimuthal::sample`].
    pub(super) cdf_lo: f32,
    pub(super) tanh_half: f32,
}

impl Azimuthal {
    pub(super) fn new(s: f32) -> Azimuthal {
        let s64 = s as f64;
        Azimuthal {
            s,
            inv_s: 1.0 / s,
            norm: (1.0 / (s64 * (0.5 * std::f64::consts::PI / s64).tanh())) as f32,
            cdf_lo: (1.0 / (1.0 + (std::f64::consts::PI / s64).exp())) as f32,
            tanh_half: (0.5 * std::f64::consts::PI / s64).tanh() as f32,
        }
    }

    /// A draw by the inverse CDF: q = F(−π) + u tanh(π/2s), x = s ln(q/(1 − q)), with
    /// 1 − q = F(−π) + (1 − u) tanh(π/2s) written so (no cancellation near u = 1).
    #[inline(always)]
    pub(super) fn sample<R: Real>(&self, u: R) -> R {
        let (lo, th) = (R::splat(self.cdf_lo), R::splat(self.tanh_half));
        let q = u.mul_add(th, lo);
        let q_c = (R::splat(1.0) - u).mul_add(th, lo);
        (R::splat(self.s) * (q / q_c).ln()).clamp_to(-PI, PI)
    }

    /// The density at x ∈ [−π, π] ([`trimmed_logistic`]).
    #[inline(always)]
    pub(super) fn eval<R: Real>(&self, x: R) -> R {
        let e = (-x.abs() * R::splat(self.inv_s)).exp();
        let e1 = e + R::splat(1.0);
        e * R::splat(self.norm) / (e1 * e1)
    }
}

/// A draw from [`trimmed_logistic`] by its inverse CDF ([`Azimuthal::sample`]).
#[inline]
pub fn sample_trimmed_logistic(u: f32, s: f32) -> f32 {
    Azimuthal::new(s).sample(u)
}
