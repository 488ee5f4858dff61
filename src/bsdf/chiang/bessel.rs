//! The modified Bessel function of the first kind, order 0 (I₀, I₀ₑ = e^{−x} I₀ and ln I₀) and the polynomial
//! evaluators it runs on: M_p's normalisation needs it to ~1e-12 over [0, ∞), a numerical piece of its own apart
//! from the model.

use crate::util::real::Real;

/// Below this the power series, above it the asymptotic expansion (whose smallest term there is ~1e-11 relative).
pub(super) const I0_SWITCH: f64 = 12.0;

/// M_p's ([`m_p_of`](super::longitudinal::m_p_of)) switch between the two expansions, each cut to its first 16 terms:
/// M_p is returned as f32, and at a switch of 10 both stay within 2.2e-9 relative of I₀ (series 1.8e-9 at x = 10,
/// asymptotic 2.2e-9 there; against mpmath's `besseli`, 40 digits), 0.04 of an f32 ulp, where the full 32-term pair
/// at 12 spent twice the multiply-adds on digits the f32 drops (`estrin16`; tested against [`i0e`]).
pub(super) const M_P_SWITCH: f64 = 10.0;

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
pub(super) const I0_SERIES: [f64; 32] = [
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

/// Π_{j≤k} (2j − 1)²/(8j) for k = 0..23 (then zeros, for [`estrin32`]): e^{−x} I₀(x) √(2πx) = Σ_k A_k x^{−k}
/// (Abramowitz & Stegun 9.7.1). At x = [`I0_SWITCH`] the terms shrink up to k ≈ 24, the last kept ~1e-11 of the sum
/// (the expansion's own limit there); past it they shrink faster.
pub(super) const I0_ASYMPTOTIC: [f64; 32] = [
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

/// The first 16 terms of a [`estrin32`] table in f32 (one value or eight lanes): what M_p
/// ([`m_p_of`](super::longitudinal::m_p_of)) needs for an f32 result with its switch at [`M_P_SWITCH`].
#[inline(always)]
pub(super) fn estrin16<R: Real>(c: &[f64; 32], x: R) -> R {
    let x2 = x * x;
    let x4 = x2 * x2;
    let x8 = x4 * x4;
    let k = |i: usize| R::splat(c[i] as f32);
    let a: [R; 8] = std::array::from_fn(|i| k(2 * i + 1).mul_add(x, k(2 * i)));
    let b: [R; 4] = std::array::from_fn(|i| a[2 * i + 1].mul_add(x2, a[2 * i]));
    let d0 = b[1].mul_add(x4, b[0]);
    let d1 = b[3].mul_add(x4, b[2]);
    d1.mul_add(x8, d0)
}
