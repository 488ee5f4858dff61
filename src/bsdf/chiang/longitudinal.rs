//! M_p, the longitudinal term of d'Eon et al. 2011 (a von Mises–Fisher lobe's θ-marginal): its per-variance
//! constants, its evaluation and its exact sampler, written once over the number type ([`Real`]).
//!
//! M_p = exp(ln c − (1 − cos(θi + θo′))/v − a) I₀(a) for a = cos θi cos θo′/v ≤ [`M_P_SWITCH`] and
//! exp(ln c − (1 − cos(θi + θo′))/v) I₀ₑ(a) above, each expansion cut to 16 terms (enough for f32,
//! [`M_P_SWITCH`]). The exponent is a difference of terms ~1/v: written as cos θi cos θo′ − sin θi sin θo′ − 1 it
//! would lose its digits to cancellation in f32 (a pair off unit length by ε ~ 6e-8 scales M_p by e^{ε/v}: 0.7 % at
//! βm = 0.01). So 1 − cos(θi + θo′) is formed as sin²(θi + θo′)/(1 + cos(θi + θo′)) (or 1 − cos where the cosine
//! is negative), which no rounding of nearly equal terms enters, and f32 keeps M_p's relative precision also for
//! the narrowest lobes (tested against the f64 formula with the full Bessel function).

use super::bessel::{estrin16, I0_ASYMPTOTIC, I0_SERIES, M_P_SWITCH};
use crate::util::real::{Real, RealMask};
use std::f32::consts::TAU;

/// One longitudinal lobe of variance v, its constants computed once in f64 and kept in f32.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Longitudinal {
    /// v.
    pub(super) v: f32,
    /// 1/v.
    pub(super) inv_v: f32,
    /// ln c(v) + 1/v = −ln v − ln(1 − e^{−2/v}), with c(v) = csch(1/v)/(2v) M_p's normalisation.
    pub(super) log_norm: f32,
    /// 1 − e^{−2/v}, for the sampler.
    pub(super) one_minus_e: f32,
}

impl Longitudinal {
    pub(super) fn new(v: f64) -> Longitudinal {
        let one_minus_e = -(-2.0 / v).exp_m1();
        Longitudinal {
            v: v as f32,
            inv_v: (1.0 / v) as f32,
            // csch(1/v)/(2v) = e^{−1/v} / (v (1 − e^{−2/v})); the e^{−1/v} goes into the exponent of M_p.
            log_norm: (-v.ln() - one_minus_e.ln()) as f32,
            one_minus_e: one_minus_e as f32,
        }
    }
}

/// M_p(θi, θo′) of a lobe of 1/v = `inv_v` and ln c(v) + 1/v = `log_norm` ([`Longitudinal`]; per lane, so that
/// one shading point's lobes can run side by side) from (sin θi, cos θi) and (sin θo′, cos θo′ ≥ 0), each pair of
/// unit length (module docs: the form and its precision). A lane skips an expansion only when no lane needs it.
#[inline(always)]
pub(super) fn m_p_of<R: Real>(inv_v: R, log_norm: R, [sin_i, cos_i, sin_o, cos_o]: [R; 4]) -> R {
    let one = R::splat(1.0);
    let zero = R::splat(0.0);
    let switch = R::splat(M_P_SWITCH as f32);
    let a = cos_i * cos_o * inv_v;
    // 1 − cos(θi + θo′) without cancellation.
    let sin_sum = sin_i.mul_add(cos_o, cos_i * sin_o);
    let cos_sum = cos_i.mul_sub(cos_o, sin_i * sin_o);
    let one_minus_cos = R::select(
        cos_sum.gt(zero),
        sin_sum * sin_sum / (one + cos_sum),
        one - cos_sum,
    );
    let series = a.le(switch);
    let exponent = log_norm - one_minus_cos * inv_v - R::select(series, a, zero);
    // Each expansion only where a lane needs it (TRT's and the residual's wide lobes never reach the asymptotic
    // one at the usual roughness, TT's narrow one seldom stays in the series).
    let small = if series.any() {
        let a = a.min(switch);
        let y = R::splat(0.25) * a * a;
        y.mul_add(estrin16(&I0_SERIES, y), one)
    } else {
        zero
    };
    let large = if series.all() {
        zero
    } else {
        let inv_a = one / a.max(switch);
        estrin16(&I0_ASYMPTOTIC, inv_a) * (inv_a * R::splat(1.0 / TAU)).sqrt()
    };
    exponent.exp() * R::select(series, small, large)
}

/// M_p(θi, θo) for variance `v` (d'Eon et al. 2011), from the sines and cosines (cos ≥ 0, any length: each pair is
/// scaled to unit length); normalised so that ∫ M_p cos θi dθi = 1 over [−π/2, π/2].
pub fn m_p(v: f64, sin_theta_i: f32, cos_theta_i: f32, sin_theta_o: f32, cos_theta_o: f32) -> f32 {
    let unit = |s: f32, c: f32| {
        let inv = 1.0 / (s as f64).hypot(c as f64);
        ((s as f64 * inv) as f32, (c as f64 * inv) as f32)
    };
    let (si, ci) = unit(sin_theta_i, cos_theta_i);
    let (so, co) = unit(sin_theta_o, cos_theta_o);
    let l = Longitudinal::new(v);
    m_p_of(l.inv_v, l.log_norm, [si, ci, so, co])
}

/// sin θi of a direction drawn from M_p(·, θo′) (d'Eon et al. 2011's sampling) with the constants of the lobe
/// (`v`, `one_minus_e` = 1 − e^{−2/v}) per lane: the cosine of the angle t to the lobe's centre (θ = −θo′) from
/// the density ∝ e^{cos t/v} on [−1, 1] by its inverse CDF, then a uniform azimuth 2π `u_phi` about the centre;
/// sin θi = −cos t sin θo′ + sin t cos(2π u_phi) cos θo′.
#[inline(always)]
pub(super) fn sample_sin_theta<R: Real>(
    v: R,
    one_minus_e: R,
    u_t: R,
    u_phi: R,
    (sin_o, cos_o): (R, R),
) -> R {
    let one = R::splat(1.0);
    // w = cos t − 1 = v ln(ξ + (1 − ξ) e^{−2/v}) ∈ [−2, 0] with ξ = 1 − u_t, i.e. v ln(1 + x),
    // x = −u_t (1 − e^{−2/v}), by Kahan's ln(1 + x) = ln(y) x / (y − 1), y = 1 + x rounded: a wide lobe's
    // argument near 1 keeps its digits in f32.
    let x = -u_t * one_minus_e;
    let y = one + x;
    let ln1p = R::select((y - one).eq(R::splat(0.0)), x, y.ln() * (x / (y - one)));
    let w = (v * ln1p).max(R::splat(-2.0));
    // sin t = √(−w (2 + w)) keeps its precision for narrow lobes.
    let (cos_t, sin_t) = (
        one + w,
        (-w * (R::splat(2.0) + w)).max(R::splat(0.0)).sqrt(),
    );
    let cos_phi = (R::splat(TAU) * u_phi).cos();
    (sin_t * cos_phi)
        .mul_sub(cos_o, cos_t * sin_o)
        .clamp_to(-1.0, 1.0)
}
