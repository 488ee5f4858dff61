//! e^x of four lanes at once in `wide`'s SIMD vectors (AVX2 on the x86-64-v3 build: one instruction per step for
//! four f64 or four f32), for the shading code's small fixed-size batches — Chiang's four M_p lobes and three
//! N_p lobes per evaluation. libm's `exp` is scalar and branchy; on the fur ball's peer frame it and `expf` were a
//! tenth of cuticle's own instructions.
//!
//! The method is the textbook one (Cody & Waite 1980's reduction, as in Cephes and musl): x = k ln 2 + r with
//! k = round(x / ln 2), |r| ≤ ln 2 / 2, ln 2 split in a high part with trailing zero bits and a low part so k ln 2
//! is exact enough; e^r by its Taylor polynomial (degree 13 for f64: the first omitted term is (ln 2/2)¹⁴/14! ≈
//! 4e-18 < 2⁻⁵³/20; degree 7 for f32: 5e-9 < 2⁻²⁴/3) by Estrin's scheme; 2^k put straight into the exponent bits. k
//! is rounded by adding and subtracting 1.5·2⁵² (1.5·2²³), which also leaves k in the low mantissa bits of the sum.
//! Arguments whose result is below 2⁻¹⁰²¹ (f32: 2⁻¹²⁵) give 0 (no subnormals: every caller multiplies the result
//! into an f32 radiance, where they are 0 anyway), above the largest finite one +∞, NaN gives NaN. Accuracy: within
//! 2 ulp of libm's result over the whole range (tested).

use bytemuck::cast;
use wide::{f32x4, f64x4, u32x4, u64x4, CmpGt, CmpLt};

/// ln 2 in two parts (fdlibm's): the high part has 20 trailing zero bits, so k · `LN2_HI` is exact for |k| < 2²⁰.
const LN2_HI_F64: f64 = f64::from_bits(0x3fe62e42fee00000);
const LN2_LO_F64: f64 = f64::from_bits(0x3dea39ef35793c76);
/// Round-to-integer shift for f64: 1.5 · 2⁵².
const SHIFT_F64: f64 = 6_755_399_441_055_744.0;
/// Below this (ln 2⁻¹⁰²¹) the result is 0: 2^k must stay a normal number (a result in [2⁻¹⁰²², 2⁻¹⁰²¹) is lost).
const MIN_ARG_F64: f64 = -707.7032713517042;
/// e^x overflows above this (ln(2¹⁰²⁴ (1 − 2⁻⁵³))).
const MAX_ARG_F64: f64 = 709.782_712_893_383_9;

/// ln 2 in two parts for f32 (the high part 0.693145751953125 has trailing zero bits, so k · it is exact).
const LN2_HI_F32: f32 = f32::from_bits(0x3f317200);
const LN2_LO_F32: f32 = f32::from_bits(0x35bfbe8e);
/// 1.5 · 2²³.
const SHIFT_F32: f32 = 12_582_912.0;
/// ln 2⁻¹²⁵ (as for f64).
const MIN_ARG_F32: f32 = -86.643_4;
/// ln(2¹²⁸ (1 − 2⁻²⁴)).
const MAX_ARG_F32: f32 = 88.722_83;

/// 1/k! for k = 0..=13 (by successive division: each within a few ulp, which the 2-ulp test covers).
const INV_FACTORIAL: [f64; 14] = {
    let mut c = [1.0; 14];
    let mut k = 1;
    while k < 14 {
        c[k] = c[k - 1] / k as f64;
        k += 1;
    }
    c
};

/// e^x per lane of an f64×4 vector (module docs).
#[inline(always)]
pub fn exp_f64x4(x: f64x4) -> f64x4 {
    let xc = x
        .max(f64x4::splat(MIN_ARG_F64))
        .min(f64x4::splat(MAX_ARG_F64));
    let shifted = xc.mul_add(
        f64x4::splat(std::f64::consts::LOG2_E),
        f64x4::splat(SHIFT_F64),
    );
    let k = shifted - f64x4::splat(SHIFT_F64);
    let r = k.mul_neg_add(
        f64x4::splat(LN2_LO_F64),
        k.mul_neg_add(f64x4::splat(LN2_HI_F64), xc),
    );
    let c = INV_FACTORIAL.map(f64x4::splat);
    let r2 = r * r;
    let r4 = r2 * r2;
    let r8 = r4 * r4;
    let p = |i: usize| c[i + 1].mul_add(r, c[i]);
    let q0 = p(2).mul_add(r2, p(0));
    let q1 = p(6).mul_add(r2, p(4));
    let q2 = p(10).mul_add(r2, p(8));
    let lo = q1.mul_add(r4, q0);
    let hi = p(12).mul_add(r4, q2);
    let poly = hi.mul_add(r8, lo);
    // k sits in the low mantissa bits of `shifted` (2⁵¹ + k); (k + 1022) << 52 is 2^(k−1), the 2⁵¹ and the
    // exponent shifted out. Scaling by 2^(k−1) and then 2 keeps the largest argument (k = 1024) finite.
    let bits: u64x4 = cast(shifted);
    let half_scale: f64x4 = cast((bits + u64x4::splat(1022)) << 52);
    let y = poly * half_scale * f64x4::splat(2.0);
    let y = x.cmp_lt(f64x4::splat(MIN_ARG_F64)).blend(f64x4::ZERO, y);
    let y = x
        .cmp_gt(f64x4::splat(MAX_ARG_F64))
        .blend(f64x4::splat(f64::INFINITY), y);
    x.is_nan().blend(x, y)
}

/// e^x per lane of an f32×4 vector (module docs).
#[inline(always)]
pub fn exp_f32x4(x: f32x4) -> f32x4 {
    let xc = x
        .max(f32x4::splat(MIN_ARG_F32))
        .min(f32x4::splat(MAX_ARG_F32));
    let shifted = xc.mul_add(
        f32x4::splat(std::f32::consts::LOG2_E),
        f32x4::splat(SHIFT_F32),
    );
    let k = shifted - f32x4::splat(SHIFT_F32);
    let r = k.mul_neg_add(
        f32x4::splat(LN2_LO_F32),
        k.mul_neg_add(f32x4::splat(LN2_HI_F32), xc),
    );
    let c = INV_FACTORIAL.map(|v| f32x4::splat(v as f32));
    let r2 = r * r;
    let r4 = r2 * r2;
    let p = |i: usize| c[i + 1].mul_add(r, c[i]);
    let poly = p(6).mul_add(r2, p(4)).mul_add(r4, p(2).mul_add(r2, p(0)));
    let bits: u32x4 = cast(shifted);
    let half_scale: f32x4 = cast((bits + u32x4::splat(126)) << 23);
    let y = poly * half_scale * f32x4::splat(2.0);
    let y = x.cmp_lt(f32x4::splat(MIN_ARG_F32)).blend(f32x4::ZERO, y);
    let y = x
        .cmp_gt(f32x4::splat(MAX_ARG_F32))
        .blend(f32x4::splat(f32::INFINITY), y);
    x.is_nan().blend(x, y)
}

/// [`exp_f64x4`] of one value (same result as its lane).
pub fn exp_f64(x: f64) -> f64 {
    exp_f64x4(f64x4::splat(x)).to_array()[0]
}

/// [`exp_f32x4`] of one value (same result as its lane).
pub fn exp_f32(x: f32) -> f32 {
    exp_f32x4(f32x4::splat(x)).to_array()[0]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The largest `ulps(x)` over x dense in [lo, hi] (400 001 points), and at those points times 1e-3 and 1e-6
    /// (the small arguments the shading code mostly sees), with the x where it is.
    fn worst(lo: f64, hi: f64, ulps: impl Fn(f64) -> u64) -> (u64, f64) {
        let n = 400_000;
        let mut worst = (0, 0.0);
        for i in 0..=n {
            let x = lo + (hi - lo) * i as f64 / n as f64;
            for x in [x, x * 1e-3, x * 1e-6] {
                let d = ulps(x);
                if d > worst.0 {
                    worst = (d, x);
                }
            }
        }
        worst
    }

    #[test]
    fn f64_within_two_ulp_of_libm_over_the_whole_range() {
        let (d, x) = worst(MIN_ARG_F64, MAX_ARG_F64, |x| {
            exp_f64(x).to_bits().abs_diff(x.exp().to_bits())
        });
        assert!(d <= 2, "{d} ulp at x = {x}");
    }

    #[test]
    fn f32_within_two_ulp_of_libm_over_the_whole_range() {
        let (lo, hi) = (f64::from(MIN_ARG_F32), f64::from(MAX_ARG_F32));
        let (d, x) = worst(lo, hi, |x| {
            let x = (x as f32).clamp(MIN_ARG_F32, MAX_ARG_F32);
            u64::from(exp_f32(x).to_bits().abs_diff(x.exp().to_bits()))
        });
        assert!(d <= 2, "{d} ulp at x = {x}");
    }

    #[test]
    fn edges_underflow_to_zero_overflow_to_infinity_and_keep_nan() {
        let [a, b, c, d] = exp_f64x4(f64x4::new([-1e6, 1e6, f64::NAN, 0.0])).to_array();
        assert_eq!((a, b, d), (0.0, f64::INFINITY, 1.0));
        assert!(c.is_nan());
        assert_eq!(exp_f64(f64::NEG_INFINITY), 0.0);
        assert_eq!(exp_f64(f64::INFINITY), f64::INFINITY);
        let [a, b, c, d] = exp_f32x4(f32x4::new([-1e6, 1e6, f32::NAN, 0.0])).to_array();
        assert_eq!((a, b, d), (0.0, f32::INFINITY, 1.0));
        assert!(c.is_nan());
        // The largest finite results, where k rounds to the top exponent, and the smallest.
        assert!(exp_f64(MAX_ARG_F64).is_finite());
        assert!(exp_f32(MAX_ARG_F32).is_finite());
        assert!(exp_f64(MIN_ARG_F64) >= f64::MIN_POSITIVE);
        assert!(exp_f32(MIN_ARG_F32) >= f32::MIN_POSITIVE);
    }

    #[test]
    fn lanes_are_independent() {
        let x = [-3.5, 0.25, 11.0, -700.0];
        let v = exp_f64x4(f64x4::new(x)).to_array();
        for k in 0..4 {
            assert_eq!(v[k], exp_f64(x[k]));
        }
        let x = [-3.5f32, 0.25, 11.0, -80.0];
        let v = exp_f32x4(f32x4::new(x)).to_array();
        for k in 0..4 {
            assert_eq!(v[k], exp_f32(x[k]));
        }
    }
}
