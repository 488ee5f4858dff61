//! A number type for shading code written once and run on one value or on eight at a time, as Mitsuba 3's plugins
//! are templated over `Float`: [`Real`] is implemented for `f32` (one shading point) and `wide`'s `f32x8` (eight
//! shading points in AVX2 lanes, a batch of paths). A model's lobes are written as generic functions over
//! `R: Real`; the scalar BSDF instantiates them with `f32`, the batched shading with `f32x8`, so no physics is
//! written twice.
//!
//! Branches become selects: a comparison gives a [`Real::Mask`] (`bool` for `f32`, an all-ones/all-zeros lane
//! mask for `f32x8`) and [`Real::select`] picks per lane; code that skips work no lane needs asks
//! [`RealMask::any`] or [`RealMask::all`] (for `f32` the comparison itself, so the scalar form keeps its branch).
//! The transcendental functions (exp, ln, arcsine, arctangent, sine and cosine) of `f32` are `f32x8`'s, `wide`'s
//! branch-free polynomials, on one lane: so one shading point and lane k of eight give bit for bit the same value,
//! and the batched integrator reproduces the scalar one exactly instead of to a few ulp (where a sampler's choice
//! could flip). They are within a few ulp of libm's (tested below); arithmetic, square roots and fused
//! multiply-adds are IEEE's in both.

use std::ops::{Add, AddAssign, BitAnd, BitOr, Div, Mul, Neg, Not, Sub, SubAssign};
use wide::{f32x8, CmpEq, CmpGt, CmpLe, CmpLt};

/// A lane mask: the result of comparing two [`Real`]s.
pub trait RealMask:
    Copy + BitAnd<Output = Self> + BitOr<Output = Self> + Not<Output = Self>
{
    /// Whether any lane is set.
    fn any(self) -> bool;
    /// Whether every lane is set.
    fn all(self) -> bool;
}

impl RealMask for bool {
    #[inline(always)]
    fn any(self) -> bool {
        self
    }
    #[inline(always)]
    fn all(self) -> bool {
        self
    }
}

impl RealMask for f32x8 {
    #[inline(always)]
    fn any(self) -> bool {
        f32x8::any(self)
    }
    #[inline(always)]
    fn all(self) -> bool {
        f32x8::all(self)
    }
}

/// A function of `N` numbers written once over the number type, which [`Real::four`] runs on four argument sets at
/// once: a model's per-lobe term (Chiang's M_p N_p over its four orders).
pub trait Kernel<const N: usize> {
    /// The function.
    fn run<R: Real>(&self, x: [R; N]) -> R;
}

/// One f32 or a vector of f32 lanes, with the arithmetic and functions the fibre models use.
pub trait Real:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
{
    /// The result of a comparison.
    type Mask: RealMask;
    /// Values per number: 1 or 8.
    const LANES: usize;
    /// `x` in every lane.
    fn splat(x: f32) -> Self;
    /// Lane `k`.
    fn lane(self, k: usize) -> f32;
    /// Lane k = `f(k)`: a term no vector form serves (e.g. one that needs f64) computed lane by lane, still written
    /// once.
    fn from_fn(f: impl FnMut(usize) -> f32) -> Self;
    /// `self · a + b`, fused.
    fn mul_add(self, a: Self, b: Self) -> Self;
    /// `self · a − b`, fused.
    fn mul_sub(self, a: Self, b: Self) -> Self;
    /// √x.
    fn sqrt(self) -> Self;
    /// eˣ.
    fn exp(self) -> Self;
    /// ln x.
    fn ln(self) -> Self;
    /// |x|.
    fn abs(self) -> Self;
    /// arcsin x.
    fn asin(self) -> Self;
    /// The angle of (x, self), in [−π, π].
    fn atan2(self, x: Self) -> Self;
    /// (sin x, cos x).
    fn sin_cos(self) -> (Self, Self);
    /// cos x.
    fn cos(self) -> Self;
    /// To the nearest integer, ties to even.
    fn round(self) -> Self;
    /// The smaller.
    fn min(self, o: Self) -> Self;
    /// The larger.
    fn max(self, o: Self) -> Self;
    /// x < o.
    fn lt(self, o: Self) -> Self::Mask;
    /// x ≤ o.
    fn le(self, o: Self) -> Self::Mask;
    /// x > o.
    fn gt(self, o: Self) -> Self::Mask;
    /// x = o.
    fn eq(self, o: Self) -> Self::Mask;
    /// Per lane: `a` where `m` is set, else `b`.
    fn select(m: Self::Mask, a: Self, b: Self) -> Self;

    /// `k` on four argument sets: for `f32` the four go into lanes 0–3 of one `f32x8` run (one shading point's
    /// lobes side by side, each lane bit for bit what one `f32` run gives); for `f32x8` four runs, one per set.
    fn four<K: Kernel<N>, const N: usize>(k: &K, x: [[Self; N]; 4]) -> [Self; 4];

    /// Clamped to [lo, hi] (NaN stays NaN in `f32`, becomes a bound in `f32x8`).
    #[inline(always)]
    fn clamp_to(self, lo: f32, hi: f32) -> Self {
        self.max(Self::splat(lo)).min(Self::splat(hi))
    }
}

impl Real for f32 {
    type Mask = bool;
    const LANES: usize = 1;
    #[inline(always)]
    fn splat(x: f32) -> Self {
        x
    }
    #[inline(always)]
    fn lane(self, _k: usize) -> f32 {
        self
    }
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> f32) -> Self {
        f(0)
    }
    #[inline(always)]
    fn mul_add(self, a: Self, b: Self) -> Self {
        f32::mul_add(self, a, b)
    }
    #[inline(always)]
    fn mul_sub(self, a: Self, b: Self) -> Self {
        f32::mul_add(self, a, -b)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f32::sqrt(self)
    }
    #[inline(always)]
    fn exp(self) -> Self {
        f32x8::splat(self).exp().lane(0)
    }
    #[inline(always)]
    fn ln(self) -> Self {
        f32x8::splat(self).ln().lane(0)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32::abs(self)
    }
    #[inline(always)]
    fn asin(self) -> Self {
        f32x8::splat(self).asin().lane(0)
    }
    #[inline(always)]
    fn atan2(self, x: Self) -> Self {
        f32x8::splat(self).atan2(f32x8::splat(x)).lane(0)
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        let (s, c) = f32x8::splat(self).sin_cos();
        (s.lane(0), c.lane(0))
    }
    #[inline(always)]
    fn cos(self) -> Self {
        f32x8::splat(self).cos().lane(0)
    }
    #[inline(always)]
    fn round(self) -> Self {
        f32::round_ties_even(self)
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        f32::min(self, o)
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        f32::max(self, o)
    }
    #[inline(always)]
    fn lt(self, o: Self) -> bool {
        self < o
    }
    #[inline(always)]
    fn le(self, o: Self) -> bool {
        self <= o
    }
    #[inline(always)]
    fn gt(self, o: Self) -> bool {
        self > o
    }
    #[inline(always)]
    fn eq(self, o: Self) -> bool {
        self == o
    }
    #[inline(always)]
    fn select(m: bool, a: Self, b: Self) -> Self {
        if m {
            a
        } else {
            b
        }
    }
    #[inline(always)]
    fn four<K: Kernel<N>, const N: usize>(k: &K, x: [[f32; N]; 4]) -> [f32; 4] {
        // Lanes 4–7 repeat set 3: valid arguments, so they change no lane's value nor any `any`/`all` choice.
        let args = std::array::from_fn(|n| {
            let l = x[3][n];
            f32x8::new([x[0][n], x[1][n], x[2][n], l, l, l, l, l])
        });
        let r = k.run::<f32x8>(args);
        let r = r.as_array_ref();
        [r[0], r[1], r[2], r[3]]
    }
}

impl Real for f32x8 {
    type Mask = f32x8;
    const LANES: usize = 8;
    #[inline(always)]
    fn splat(x: f32) -> Self {
        f32x8::splat(x)
    }
    #[inline(always)]
    fn lane(self, k: usize) -> f32 {
        self.as_array_ref()[k]
    }
    #[inline(always)]
    fn from_fn(f: impl FnMut(usize) -> f32) -> Self {
        f32x8::new(std::array::from_fn(f))
    }
    #[inline(always)]
    fn mul_add(self, a: Self, b: Self) -> Self {
        f32x8::mul_add(self, a, b)
    }
    #[inline(always)]
    fn mul_sub(self, a: Self, b: Self) -> Self {
        f32x8::mul_sub(self, a, b)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f32x8::sqrt(self)
    }
    #[inline(always)]
    fn exp(self) -> Self {
        f32x8::exp(self)
    }
    #[inline(always)]
    fn ln(self) -> Self {
        f32x8::ln(self)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f32x8::abs(self)
    }
    #[inline(always)]
    fn asin(self) -> Self {
        f32x8::asin(self)
    }
    #[inline(always)]
    fn atan2(self, x: Self) -> Self {
        f32x8::atan2(self, x)
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        f32x8::sin_cos(self)
    }
    #[inline(always)]
    fn cos(self) -> Self {
        f32x8::cos(self)
    }
    #[inline(always)]
    fn round(self) -> Self {
        f32x8::round(self)
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        f32x8::min(self, o)
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        f32x8::max(self, o)
    }
    #[inline(always)]
    fn lt(self, o: Self) -> f32x8 {
        self.cmp_lt(o)
    }
    #[inline(always)]
    fn le(self, o: Self) -> f32x8 {
        self.cmp_le(o)
    }
    #[inline(always)]
    fn gt(self, o: Self) -> f32x8 {
        self.cmp_gt(o)
    }
    #[inline(always)]
    fn eq(self, o: Self) -> f32x8 {
        self.cmp_eq(o)
    }
    #[inline(always)]
    fn select(m: f32x8, a: Self, b: Self) -> Self {
        m.blend(a, b)
    }
    #[inline(always)]
    fn four<K: Kernel<N>, const N: usize>(k: &K, x: [[f32x8; N]; 4]) -> [f32x8; 4] {
        x.map(|x| k.run(x))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A generic expression evaluated once per lane in f32 and once in f32x8 gives each lane's f32 result within a
    /// few ulp, and selects pick per lane.
    fn expression<R: Real>(x: R) -> R {
        let y = (x * x + R::splat(1.0)).sqrt().ln() + (-x.abs()).exp() * x.sin_cos().0;
        let z = x.atan2(R::splat(0.5)) + (x * R::splat(0.3)).asin() + x.round() + x.cos();
        R::select(x.lt(R::splat(0.0)), y, z)
    }

    #[test]
    fn functions_are_within_a_few_ulp_of_libm() {
        let ulps = |a: f32, b: f32| (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs();
        for i in 0..20_000 {
            let x = -20.0 + 40.0 * (i as f32 + 0.5) / 20_000.0;
            let u = x / 20.0;
            let close = |got: f32, want: f32, what: &str| {
                assert!(
                    ulps(got, want) <= 4
                        || (got - want).abs() <= 4.0 * f32::EPSILON * want.abs().max(1e-30)
                        || (got - want).abs() < 2e-7,
                    "{what}({x}): {got} against libm's {want}"
                );
            };
            close(Real::exp(x), x.exp(), "exp");
            close(Real::ln(x.abs() + 1e-3), (x.abs() + 1e-3).ln(), "ln");
            close(Real::asin(u), u.asin(), "asin");
            close(Real::atan2(u, 0.3), u.atan2(0.3), "atan2");
            let (s, c) = Real::sin_cos(x * 0.3);
            close(s, (x * 0.3).sin(), "sin");
            close(c, (x * 0.3).cos(), "cos");
        }
    }

    struct Expression;
    impl Kernel<2> for Expression {
        fn run<R: Real>(&self, [x, y]: [R; 2]) -> R {
            expression(x) * y
        }
    }

    #[test]
    fn four_at_once_match_one_at_a_time() {
        let sets = [[-2.7f32, 0.5], [0.25, 3.0], [1.5, -1.0], [3.2, 2.0]];
        let got = f32::four(&Expression, sets);
        for (k, [x, y]) in sets.into_iter().enumerate() {
            assert_eq!(
                got[k].to_bits(),
                Expression.run([x, y]).to_bits(),
                "set {k}"
            );
        }
    }

    #[test]
    fn eight_lanes_match_one_at_a_time() {
        let xs = [-2.7f32, -1.0, -0.25, 0.0, 0.5, 1.5, 2.5, 3.2];
        let lanes = expression(f32x8::new(xs));
        for (k, &x) in xs.iter().enumerate() {
            let one = expression(x);
            let got = lanes.lane(k);
            assert_eq!(got.to_bits(), one.to_bits(), "lane {k}: x = {x}");
        }
        assert!(f32x8::new(xs).lt(f32x8::splat(0.0)).any());
        assert!(!f32x8::new(xs).lt(f32x8::splat(-3.0)).any());
        assert!(f32x8::new(xs).lt(f32x8::splat(4.0)).all());
    }
}
