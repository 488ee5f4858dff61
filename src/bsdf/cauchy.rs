//! The truncated Cauchy distribution Ou et al. 2012 sample every ISHair lobe with (thesis eq. 18–21): density
//! ∝ γ / ((x − c)² + γ²) on [lo, hi], sampled by inverting its CDF, x = c + γ tan(B + ξ(A − B)) with
//! A = atan((hi − c)/γ), B = atan((lo − c)/γ).
//!
//! [`TruncatedCauchy`] works in f64 (with narrow γ, A and B both approach ±π/2, and their difference computed as
//! atan A − atan B would lose most of its digits in f32): the reference, and the constructor of distributions that
//! depend on the parameters only. [`TruncatedCauchyOf`] is the same distribution over the number type [`Real`]
//! (one f32 or eight lanes), in f32 given its ends and A − B, which is what the models sample and evaluate per call.

use crate::util::real::Real;

/// A Cauchy density with centre `c` and scale `gamma`, truncated to [lo, hi] and renormalised.
#[derive(Debug, Clone, Copy)]
pub struct TruncatedCauchy {
    c: f64,
    gamma: f64,
    lo: f64,
    hi: f64,
    /// (lo − c)/γ, whose atan is B.
    x_lo: f64,
    /// A − B; 0 selects the uniform fallback.
    width: f64,
}

impl TruncatedCauchy {
    /// Centre `c`, scale `gamma` > 0, support [`lo`, `hi`] with `lo` < `hi`.
    #[inline]
    pub fn new(c: f64, gamma: f64, lo: f64, hi: f64) -> TruncatedCauchy {
        let x_lo = (lo - c) / gamma;
        let x_hi = (hi - c) / gamma;
        // A − B = atan2(x_hi − x_lo, 1 + x_lo x_hi) for x_lo < x_hi (tan of a difference; atan2 picks the branch in
        // (0, π)): one arctangent instead of two, and no cancellation when both ends are far in one tail.
        let width = (x_hi - x_lo).atan2(1.0 + x_lo * x_hi);
        // Guard: an interval so far out in the tail that A − B vanishes is sampled uniformly (pdf alike).
        let width = if width > 1e-300 && width.is_finite() {
            width
        } else {
            0.0
        };
        TruncatedCauchy {
            c,
            gamma,
            lo,
            hi,
            x_lo,
            width,
        }
    }

    /// A − B, the normalisation of thesis eq. 20.
    pub fn width(&self) -> f64 {
        self.width
    }

    /// The value at CDF level `u` ∈ [0, 1] (thesis eq. 18, 21b, 21d): c + γ tan(B + w), w = u(A − B), with the
    /// tangent of the sum expanded, tan(B + w) = (tan B + tan w)/(1 − tan B tan w) and tan B = (lo − c)/γ, so
    /// that B itself (an arctangent) is never formed. The denominator is cos(B + w)/(cos B cos w): it vanishes
    /// only where the sample goes to +∞ (B + w = π/2, beyond hi), and for the parameter ranges the models accept
    /// (hi − c ≤ 2π, γ ≥ 1e-4) it stays ≥ 1e-5 in size, far above its rounding (~1e-16), so its sign is exact.
    #[inline]
    pub fn sample(&self, u: f64) -> f64 {
        if self.width == 0.0 {
            return self.lo + u * (self.hi - self.lo);
        }
        let t = (u * self.width).tan();
        let x = (self.x_lo + t) / (1.0 - self.x_lo * t);
        (self.c + self.gamma * x).clamp(self.lo, self.hi)
    }

    /// The density at `x` (0 outside [lo, hi]): 1 / ((A − B) γ (1 + ((x − c)/γ)²)), written with (x − c)/γ so
    /// that neither a tiny nor a huge γ overflows.
    #[inline]
    pub fn pdf(&self, x: f64) -> f64 {
        if !(self.lo..=self.hi).contains(&x) {
            return 0.0;
        }
        if self.width == 0.0 {
            return 1.0 / (self.hi - self.lo);
        }
        let z = (x - self.c) / self.gamma;
        1.0 / (self.width * self.gamma * (1.0 + z * z))
    }
}

/// A [`TruncatedCauchy`] over the number type [`Real`] (one f32, or eight lanes each with its own distribution),
/// in f32 arithmetic throughout: what ISHair's generic code samples and evaluates (eq. 18–21). It is built from
/// its ends in standardised form, x_lo = (lo − c)/γ, and its normalisation A − B, which the caller computes with
/// the care its interval needs ([`TruncatedCauchy::to_f32`] rounds the f64 ones). A width ≤ 0 (or NaN) selects the
/// uniform fallback, with 1/γ = 0 and the density 1/(hi − lo).
#[derive(Debug, Clone, Copy)]
pub struct TruncatedCauchyOf<R> {
    c: R,
    gamma: R,
    /// 1/γ; 0 for the uniform fallback.
    inv_gamma: R,
    lo: R,
    hi: R,
    /// (lo − c)/γ = tan B.
    x_lo: R,
    /// A − B; 0 for the uniform fallback.
    width: R,
    /// (A − B) γ, the reciprocal of the density's peak (eq. 20), or hi − lo for the fallback: a product, so that
    /// building a distribution per view costs no division (the pdf takes one anyway).
    scale: R,
}

impl<R: Real> TruncatedCauchyOf<R> {
    /// Centre `c`, scale `gamma` (and its inverse `inv_gamma`: callers keep both, no division on the sampling
    /// path), support [`lo`, `hi`], x_lo = (lo − c)/γ and `width` = A − B.
    #[inline(always)]
    pub fn new(c: R, gamma: R, inv_gamma: R, lo: R, hi: R, x_lo: R, width: R) -> Self {
        let zero = R::splat(0.0);
        let ok = width.gt(zero) & width.lt(R::splat(f32::INFINITY));
        TruncatedCauchyOf {
            c,
            gamma,
            inv_gamma: R::select(ok, inv_gamma, zero),
            lo,
            hi,
            x_lo,
            width: R::select(ok, width, zero),
            scale: R::select(ok, width * gamma, hi - lo),
        }
    }

    /// A − B (0 for the uniform fallback).
    #[inline(always)]
    pub fn width(&self) -> R {
        self.width
    }

    /// tan B = (lo − c)/γ.
    #[inline(always)]
    pub fn x_lo(&self) -> R {
        self.x_lo
    }

    /// Per lane: `a` where `m` is set, else `b`.
    #[inline(always)]
    pub fn select(m: R::Mask, a: &Self, b: &Self) -> Self {
        let s = |x: R, y: R| R::select(m, x, y);
        TruncatedCauchyOf {
            c: s(a.c, b.c),
            gamma: s(a.gamma, b.gamma),
            inv_gamma: s(a.inv_gamma, b.inv_gamma),
            lo: s(a.lo, b.lo),
            hi: s(a.hi, b.hi),
            x_lo: s(a.x_lo, b.x_lo),
            width: s(a.width, b.width),
            scale: s(a.scale, b.scale),
        }
    }

    /// The value at CDF level `u` ∈ [0, 1], as [`TruncatedCauchy::sample`]: c + γ tan(B + w), w = u(A − B), with
    /// tan(B + w) = (tan B cos w + sin w)/(cos w − tan B sin w) (the tangent-sum formula times cos w), so that
    /// neither B nor a tangent's pole is formed: one sine and cosine.
    ///
    /// Precision (f32): the rounding of w, the sine and cosine's few-ulp error, and the once-rounded fused
    /// numerator and denominator (together the vector (cos, sin)(B + w)/cos B, formed with absolute errors
    /// ~1e-7 max(1, |tan B|), a fraction ~1e-7 of its length) each move the angle B + w by a few parts in 1e7. The
    /// CDF is uniform in w, so the value drawn is the exact inverse CDF at a level within ~1e-6 of `u` for the
    /// models' parameter ranges (hi − c ≤ 2π, γ ≥ 1e-4; tested against the closed-form CDF, as the f64 sampler is).
    #[inline(always)]
    pub fn sample(&self, u: R) -> R {
        let (s, c) = (u * self.width).sin_cos();
        let x = self.x_lo.mul_add(c, s) / (-self.x_lo).mul_add(s, c);
        let cauchy = self.c + self.gamma * x;
        let uniform = self.lo + u * (self.hi - self.lo);
        R::select(self.width.gt(R::splat(0.0)), cauchy, uniform)
            .max(self.lo)
            .min(self.hi)
    }

    /// The density at `x` (0 outside [lo, hi]): 1 / ((A − B) γ (1 + ((x − c)/γ)²)), with (x − c)/γ as a product
    /// by 1/γ (neither a tiny nor a huge γ overflows, and the fallback's 1/γ = 0 makes it flat).
    #[inline(always)]
    pub fn pdf(&self, x: R) -> R {
        let z = (x - self.c) * self.inv_gamma;
        let p = R::splat(1.0) / (self.scale * z.mul_add(z, R::splat(1.0)));
        let inside = !(x.lt(self.lo) | self.hi.lt(x));
        R::select(inside, p, R::splat(0.0))
    }
}

impl TruncatedCauchyOf<f32> {
    /// The same distribution in every lane of `R`.
    #[inline(always)]
    pub fn splat<R: Real>(&self) -> TruncatedCauchyOf<R> {
        TruncatedCauchyOf {
            c: R::splat(self.c),
            gamma: R::splat(self.gamma),
            inv_gamma: R::splat(self.inv_gamma),
            lo: R::splat(self.lo),
            hi: R::splat(self.hi),
            x_lo: R::splat(self.x_lo),
            width: R::splat(self.width),
            scale: R::splat(self.scale),
        }
    }
}

impl TruncatedCauchy {
    /// This distribution in f32 ([`TruncatedCauchyOf`]), its constants (x_lo, A − B and the normalisation (A − B)γ)
    /// taken from the f64 ones once: for distributions that depend on the parameters only (ISHair's azimuths, eq.
    /// 21b and 21d), which then cost no arctangent per call.
    pub fn to_f32(&self) -> TruncatedCauchyOf<f32> {
        let (inv_gamma, scale) = if self.width == 0.0 {
            (0.0, self.hi - self.lo)
        } else {
            (1.0 / self.gamma, self.width * self.gamma)
        };
        TruncatedCauchyOf {
            c: self.c as f32,
            gamma: self.gamma as f32,
            inv_gamma: inv_gamma as f32,
            lo: self.lo as f32,
            hi: self.hi as f32,
            x_lo: self.x_lo as f32,
            width: self.width as f32,
            scale: scale as f32,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wide::f32x8;

    #[test]
    fn generic_pdf_matches_f64() {
        // ISHair's azimuth distributions: TT on [−π, π] about 0, the glint on [0, π/2] about φ_g, γ ∈ [1e-4, 1e6].
        let mut worst = 0.0f64;
        for gamma in [1e-4, 1e-3, 0.01, 0.1, 0.3, 1.0, 10.0, 1e6] {
            for (c, lo, hi) in [
                (0.0, -std::f64::consts::PI, std::f64::consts::PI),
                // φ_g is an f32 parameter: its f64 centre is exactly the f32 one.
                (0.6f32 as f64, 0.0, std::f64::consts::FRAC_PI_2),
                (0.0, 0.0, std::f64::consts::FRAC_PI_2),
            ] {
                let tc = TruncatedCauchy::new(c, gamma, lo, hi);
                let f = tc.to_f32();
                let lanes = f.splat::<f32x8>();
                for j in 1..1000 {
                    let x = (lo + (hi - lo) * j as f64 / 1000.0) as f32;
                    let exact = tc.pdf(x as f64);
                    let xs = f32x8::new(std::array::from_fn(|k| x + k as f32 * 0.01));
                    for got in [f.pdf(x), lanes.pdf(xs).lane(0)] {
                        worst = worst.max((got as f64 / exact - 1.0).abs());
                    }
                }
                // 0 outside the support, in both forms.
                assert_eq!(f.pdf(hi as f32 + 0.01), 0.0);
                assert_eq!(lanes.pdf(f32x8::splat(lo as f32 - 0.01)).lane(4), 0.0);
            }
        }
        // (x − c)/γ rounded in f32 (z² doubles its 6e-8) and the final division.
        assert!(worst < 1e-6, "worst relative error {worst:e}");
    }

    #[test]
    fn generic_zero_width_is_the_uniform_fallback() {
        for width in [0.0f32, -1.0, f32::NAN] {
            let flat = TruncatedCauchyOf::new(0.0f32, 1.0, 1.0, 2.0, 4.0, -2.0, width);
            assert_eq!(flat.sample(0.25), 2.5);
            assert_eq!(flat.pdf(3.0), 0.5);
            let flat8 = TruncatedCauchyOf::new(
                f32x8::splat(0.0),
                f32x8::splat(1.0),
                f32x8::splat(1.0),
                f32x8::splat(2.0),
                f32x8::splat(4.0),
                f32x8::splat(-2.0),
                f32x8::splat(width),
            );
            assert_eq!(flat8.sample(f32x8::splat(0.25)).lane(6), 2.5);
            assert_eq!(flat8.pdf(f32x8::splat(3.0)).lane(6), 0.5);
        }
    }

    #[test]
    fn sample_inverts_the_cdf_of_pdf() {
        for (c, gamma, lo, hi) in [
            (0.2, 0.1, -1.0, 1.0),
            (3.0, 1e-3, 0.0, 1.0),
            (0.0, 1e4, -3.0, 3.0),
            // ISHair's extremes: the narrowest TT azimuth about π (δ ∈ [−π, π]), the widest (γ = 1e6), and the
            // narrowest θh lobe seen from a grazing view (interval [θr/2 − π/4, θr/2 + π/4] at θr = −89°, α = π/4:
            // all in the left tail).
            (0.0, 1e-4, -std::f64::consts::PI, std::f64::consts::PI),
            (0.0, 1e6, -std::f64::consts::PI, std::f64::consts::PI),
            (
                std::f64::consts::FRAC_PI_4,
                1e-4,
                -1.5533 / 2.0 - std::f64::consts::FRAC_PI_4,
                -1.5533 / 2.0 + std::f64::consts::FRAC_PI_4,
            ),
        ] {
            let tc = TruncatedCauchy::new(c, gamma, lo, hi);
            // The CDF of the truncated Cauchy in closed form: (atan((x − c)/γ) − B)/(A − B).
            let cdf = |x: f64| (((x - c) / gamma).atan() - ((lo - c) / gamma).atan()) / tc.width();
            for k in 0..=20 {
                let u = k as f64 / 20.0;
                let x = tc.sample(u);
                assert!(
                    (cdf(x) - u).abs() < 1e-9,
                    "c {c} γ {gamma}: CDF(sample({u})) = {}",
                    cdf(x)
                );
            }
            // The f32 sampler, one value and eight lanes: the inverse CDF at a level within ~1e-7 of u (see
            // `TruncatedCauchyOf::sample`).
            let f = tc.to_f32();
            let lanes = f.splat::<f32x8>();
            let mut worst = 0.0f64;
            for k in 0..=1000 {
                let u = k as f32 / 1000.0;
                let us = f32x8::new(std::array::from_fn(|j| (u + 0.37 * j as f32).fract()));
                let us = f32x8::new(std::array::from_fn(|j| if j == 2 { u } else { us.lane(j) }));
                for x in [f.sample(u), lanes.sample(us).lane(2)] {
                    worst = worst.max((cdf(x as f64) - u as f64).abs());
                }
            }
            assert!(worst < 1e-6, "c {c} γ {gamma}: f32 sample off by {worst:e}");
            // ∫ pdf = 1 by Simpson on 1e5 steps (pdf ≤ 1/(width γ)).
            let n = 100_000;
            let h = (hi - lo) / n as f64;
            let mut s = 0.0;
            for i in 0..n {
                let x0 = lo + i as f64 * h;
                s += h / 6.0 * (tc.pdf(x0) + 4.0 * tc.pdf(x0 + h / 2.0) + tc.pdf(x0 + h));
            }
            assert!((s - 1.0).abs() < 1e-4, "c {c} γ {gamma}: ∫ pdf = {s}");
        }
    }
}
