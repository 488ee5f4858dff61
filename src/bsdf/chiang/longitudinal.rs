//! M_p, the longitudinal term of d'Eon et al. 2011 (a von Mises–Fisher lobe's θ-marginal): its per-variance
//! constants, the scalar and four-lane evaluations and the exact sampler, apart from the model that combines the
//! three terms.

use super::bessel::{estrin16_x4, I0_ASYMPTOTIC, I0_SERIES, M_P_SWITCH};
use crate::util::lanes::exp_f64x4;
use glam::Vec3;
use std::f32::consts::TAU;
use wide::{f64x4, CmpLe};

/// One longitudinal lobe of variance v, its constants taken once.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Longitudinal {
    /// v.
    pub(super) v: f64,
    /// 1/v.
    pub(super) inv_v: f64,
    /// ln c(v) + 1/v = −ln v − ln(1 − e^{−2/v}), with c(v) = csch(1/v)/(2v) M_p's normalisation.
    pub(super) log_norm: f64,
    /// e^{−2/v}, for the sampler.
    pub(super) exp_m2_over_v: f64,
}

impl Longitudinal {
    pub(super) fn new(v: f64) -> Longitudinal {
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
    pub(super) fn eval(&self, sc_i: (f64, f64), sc_o: (f64, f64)) -> f64 {
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
    pub(super) fn sample_sin_theta(&self, u_t: f32, u_phi: f32, (sin_o, cos_o): (f64, f64)) -> f64 {
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
pub(super) fn m_p_lanes(
    inv_v: f64x4,
    log_norm: f64x4,
    (si, ci): (f64, f64),
    sc_o: [(f64, f64); 4],
) -> f64x4 {
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
pub(super) fn unit_pair(x: f64, rho: f64) -> (f64, f64) {
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
pub(super) fn sin_cos_theta_f64(w: Vec3) -> (f64, f64) {
    let (y, z) = (w.y as f64, w.z as f64);
    unit_pair(w.x as f64, (y * y + z * z).sqrt())
}
