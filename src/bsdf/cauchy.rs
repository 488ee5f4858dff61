//! The truncated Cauchy distribution Ou et al. 2012 sample every ISHair lobe with (thesis eq. 18–21): density
//! ∝ γ / ((x − c)² + γ²) on [lo, hi], sampled by inverting its CDF, x = c + γ tan(B + ξ(A − B)) with
//! A = atan((hi − c)/γ), B = atan((lo − c)/γ).
//!
//! Arithmetic is in f64: with narrow γ, A and B both approach ±π/2 and their difference would lose most of its
//! digits in f32.

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

    /// The same distribution with its normalisation A − B given instead of computed: for a sampler whose pdf is
    /// normalised with [`width_f32`] (ISHair computes the widths of all three θh distributions for its mixture pdf
    /// anyway), so sampler and pdf share one A − B and the constructor's f64 arctangent is saved. A width within
    /// 1e-6 (relative) of the exact one moves the drawn distribution by as little: the top 1e-6 of the CDF is cut
    /// off, or piles up at `hi` by the clamp in [`TruncatedCauchy::sample`]. `width` ≤ 0 selects the uniform
    /// fallback, as [`width_f32`]'s 0 does. `inv_gamma` = 1/`gamma` (callers keep both: no division on the
    /// sampling path).
    #[inline]
    pub fn with_width(
        c: f64,
        gamma: f64,
        inv_gamma: f64,
        lo: f64,
        hi: f64,
        width: f64,
    ) -> TruncatedCauchy {
        TruncatedCauchy {
            c,
            gamma,
            lo,
            hi,
            x_lo: (lo - c) * inv_gamma,
            width: if width > 0.0 { width } else { 0.0 },
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

    /// [`TruncatedCauchy::sample`] with the tangent in f32 (libm's `tanf` instead of `tan`, a third of the cost).
    /// The argument w = u(A − B) rounded to f32 and `tanf`'s own error perturb w by a few parts in 1e7 of w (or of
    /// π/2 near the pole, where tan w is huge): the same as drawing with u off by that much relative, u' = w'/(A − B)
    /// (exact inversion of a CDF that is *uniform* in w). The tangent-sum step stays f64, so the value drawn is the
    /// exact inverse CDF at a level within ~4e-7 (relative to u, or 1e-6 absolute near tan's pole) of `u`; a
    /// sampler test bounds |CDF(sample_f32(u)) − u| against the closed form.
    #[inline]
    pub fn sample_f32(&self, u: f32) -> f64 {
        if self.width == 0.0 {
            return self.lo + u as f64 * (self.hi - self.lo);
        }
        let t = ((u as f64 * self.width) as f32).tan() as f64;
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

/// [`TruncatedCauchy::pdf`] in f32 with its constants taken once ([`TruncatedCauchy::pdf_f32`]): for the
/// parameter-only azimuth distributions of ISHair (eq. 21b, 21d), whose pdf is then one f32 division per call
/// instead of two f64 ones. The uniform fallback is the same formula with 1/γ = 0.
#[derive(Debug, Clone, Copy)]
pub struct CauchyPdfF32 {
    c: f32,
    inv_gamma: f32,
    /// 1 / ((A − B) γ) (eq. 20), or 1 / (hi − lo) for the fallback.
    norm: f32,
    lo: f32,
    hi: f32,
}

impl CauchyPdfF32 {
    /// The density at `x` (0 outside [lo, hi]): norm / (1 + ((x − c)/γ)²).
    #[inline]
    pub fn pdf(&self, x: f32) -> f32 {
        if !(self.lo..=self.hi).contains(&x) {
            return 0.0;
        }
        let z = (x - self.c) * self.inv_gamma;
        self.norm / (1.0 + z * z)
    }
}

impl TruncatedCauchy {
    /// This distribution's pdf in f32 (see [`CauchyPdfF32`]).
    pub fn pdf_f32(&self) -> CauchyPdfF32 {
        let (inv_gamma, norm) = if self.width == 0.0 {
            (0.0, 1.0 / (self.hi - self.lo))
        } else {
            (1.0 / self.gamma, 1.0 / (self.width * self.gamma))
        };
        CauchyPdfF32 {
            c: self.c as f32,
            inv_gamma: inv_gamma as f32,
            norm: norm as f32,
            lo: self.lo as f32,
            hi: self.hi as f32,
        }
    }
}

/// A − B of [`TruncatedCauchy::new`] for pdfs that are f32 anyway: the same one-arctangent form, its arguments
/// formed in f64 as there (lo − c and hi − c cancel when γ is small; in f64 that costs nothing), but the
/// arctangent is [`super::frame::atan2`] in f32 (absolute error < 6e-7 rad, and a few ulps relative also for
/// small widths, where it is its unreduced series) instead of libm's f64 `atan2`, the cost of the constructor.
/// Relative error < 1e-6 (tested): a sampler built by [`TruncatedCauchy::new`] draws the density that a pdf
/// normalised with this width returns, to that. 0 (callers fall back to uniform) where it is not positive.
/// Takes 1/γ (`inv_gamma`): callers keep it, and f64 divisions were most of what is left of the cost.
#[inline]
pub fn width_f32(c: f64, inv_gamma: f64, lo: f64, hi: f64) -> f32 {
    let x_lo = (lo - c) * inv_gamma;
    let x_hi = (hi - c) * inv_gamma;
    let width = super::frame::atan2((x_hi - x_lo) as f32, (1.0 + x_lo * x_hi) as f32);
    if width > 0.0 && width.is_finite() {
        width
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f32_pdf_matches_f64() {
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
                let f = tc.pdf_f32();
                for j in 1..1000 {
                    let x = (lo + (hi - lo) * j as f64 / 1000.0) as f32;
                    let exact = tc.pdf(x as f64);
                    worst = worst.max((f.pdf(x) as f64 / exact - 1.0).abs());
                }
            }
        }
        // (x − c)/γ rounded in f32 (z² doubles its 6e-8) and the final division.
        assert!(worst < 1e-6, "worst relative error {worst:e}");
    }

    #[test]
    fn f32_width_matches_f64() {
        // The θh distributions of ISHair: c = α, γ = β, [θr/2 − π/4, θr/2 + π/4] (`theta_h_grid`).
        let mut worst = 0.0f64;
        for (c, gamma, lo, hi) in super::super::testing::theta_h_grid() {
            let exact = TruncatedCauchy::new(c, gamma, lo, hi).width();
            let got = width_f32(c, 1.0 / gamma, lo, hi) as f64;
            worst = worst.max((got - exact).abs() / exact);
        }
        // The f32 rounding of the arctangent's arguments (6e-8 each) and its 6e-7 absolute error.
        assert!(worst < 1e-6, "worst relative error {worst:e}");
    }

    #[test]
    fn with_width_is_the_same_distribution() {
        for (c, gamma, lo, hi) in [(0.2, 0.1, -1.0, 1.0), (3.0, 1e-3, 0.0, 1.0)] {
            let tc = TruncatedCauchy::new(c, gamma, lo, hi);
            let given = TruncatedCauchy::with_width(c, gamma, 1.0 / gamma, lo, hi, tc.width());
            for k in 0..=20 {
                let u = k as f64 / 20.0;
                assert!((tc.sample(u) - given.sample(u)).abs() < 1e-12);
                let x = lo + (hi - lo) * u;
                assert!((tc.pdf(x) / given.pdf(x) - 1.0).abs() < 1e-12);
            }
        }
        // A width of 0 is the uniform fallback, as `width_f32`'s 0 means.
        let flat = TruncatedCauchy::with_width(0.0, 1.0, 1.0, 2.0, 4.0, 0.0);
        assert_eq!(flat.sample(0.25), 2.5);
        assert_eq!(flat.pdf(3.0), 0.5);
    }

    #[test]
    fn sample_inverts_the_cdf_of_pdf() {
        for (c, gamma, lo, hi) in [
            (0.2, 0.1, -1.0, 1.0),
            (3.0, 1e-3, 0.0, 1.0),
            (0.0, 1e4, -3.0, 3.0),
            // ISHair's extremes: the narrowest TT azimuth about π (δ ∈ [−π, π]), and the narrowest θh lobe seen
            // from a grazing view (interval [θr/2 − π/4, θr/2 + π/4] at θr = −89°, α = π/4: all in the left tail).
            (0.0, 1e-4, -std::f64::consts::PI, std::f64::consts::PI),
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
            // The f32-tangent sampler: the inverse CDF at a level within ~1e-7 of u (see `sample_f32`).
            let mut worst = 0.0f64;
            for k in 0..=1000 {
                let u = k as f32 / 1000.0;
                worst = worst.max((cdf(tc.sample_f32(u)) - u as f64).abs());
            }
            assert!(worst < 1e-6, "c {c} γ {gamma}: sample_f32 off by {worst:e}");
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
