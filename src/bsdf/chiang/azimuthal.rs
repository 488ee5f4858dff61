//! A_p and N_p, the azimuthal terms: the attenuation of each scattering order (Fresnel and one chord's
//! transmittance) and the trimmed logistic about the order's exit azimuth Φ(p), with its inverse-CDF sampler.

use super::P_MAX;
use crate::bsdf::fresnel::dielectric;
use crate::util::lanes::exp_f32x4;
use glam::Vec3;
use std::f32::consts::PI;
use wide::f32x4;

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
pub(super) struct Azimuthal {
    /// s.
    pub(super) s: f32,
    /// 1/s.
    pub(super) inv_s: f32,
    /// 1/(s tanh(π/2s)).
    pub(super) norm: f32,
    /// F(−π) = 1/(1 + e^{π/s}) and tanh(π/2s) in f64, for [`Azimuthal::sample`].
    pub(super) cdf_lo: f64,
    pub(super) tanh_half: f64,
}

impl Azimuthal {
    pub(super) fn new(s: f32) -> Azimuthal {
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
    pub(super) fn sample(&self, u: f32) -> f32 {
        let u = u as f64;
        let (q, q_c) = (
            self.cdf_lo + u * self.tanh_half,
            self.cdf_lo + (1.0 - u) * self.tanh_half,
        );
        ((self.s as f64 * (q / q_c).ln()) as f32).clamp(-PI, PI)
    }

    /// The density at x ∈ [−π, π] ([`trimmed_logistic`]).
    #[inline]
    pub(super) fn eval(&self, x: f32) -> f32 {
        self.eval_lanes([x; 4])[0]
    }

    /// [`Azimuthal::eval`] at four points at once (Chiang's three lobes in one f32 vector).
    #[inline(always)]
    pub(super) fn eval_lanes(&self, x: [f32; 4]) -> [f32; 4] {
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
