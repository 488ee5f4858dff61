//! Unit tests of the Gaussian tools, apart because they outweigh the tools themselves.

use super::*;

#[test]
fn f32_pdf_matches_f64() {
    // Marschner's θh distributions: μ = α ∈ [−π/4, π/4], σ = β ∈ [1e-4, π/2], [θr/2 − π/4, θr/2 + π/4],
    // at points across the interval. Relative error where the density is within e^{−20} of the interval's
    // largest, compared in log form so far tails count too, less the f32 rounding of the exponent (6e-8 per
    // unit of it; the error allowed grows by 1e-7 per unit).
    let (mut worst, mut fallbacks) = (0.0f64, 0);
    for (mu, sigma, lo, hi) in super::super::testing::theta_h_grid() {
        let tg = TruncatedGaussian::new(mu, sigma, lo, hi);
        let tg32 = TruncatedGaussianF32::new(mu, sigma, 1.0 / sigma, lo, hi);
        fallbacks += (tg.mass() == 0.0) as u32;
        let peak = tg.pdf(mu.clamp(lo, hi));
        for j in 0..=200 {
            let y = lo + (hi - lo) * j as f64 / 200.0;
            let exact = tg.pdf(y);
            if exact == 0.0 || (peak / exact).ln() > 20.0 {
                continue;
            }
            let got = tg32.pdf(y) as f64;
            // Allowance: 1e-7 per unit of the exponent (f32 rounding of −(x² − b²)/2, 6e-8 per unit).
            let e =
                0.5 * (((y - mu) / sigma).powi(2) - (((mu.clamp(lo, hi)) - mu) / sigma).powi(2));
            worst = worst.max((got / exact).ln().abs() / (1.0 + 0.1 * e));
        }
    }
    assert!(
        fallbacks > 0 && worst < 1e-6,
        "worst relative error {worst:e}"
    );
}

#[test]
fn f32_sampler_matches_f64() {
    // The grid of `f32_pdf_matches_f64`. For each u, the f32 sampler's value y32 and the f64 one's y64 differ
    // in CDF level by ≈ pdf · |y32 − y64| (the density is smooth on that scale): bounded like the pdfs' own
    // relative error, which the tails and Z carry. Central case only: the others call the f64 sampler.
    let (mut worst, mut central) = (0.0f64, 0);
    for (mu, sigma, lo, hi) in super::super::testing::theta_h_grid() {
        let tg = TruncatedGaussian::new(mu, sigma, lo, hi);
        let tg32 = TruncatedGaussianF32::new(mu, sigma, 1.0 / sigma, lo, hi);
        central += matches!(tg32.mass, Mass::Central { .. }) as u32;
        for j in 0..=100 {
            let u = j as f64 / 100.0;
            let (y64, y32) = (tg.sample(u), tg32.sample(u));
            let level = (y32 - y64).abs() * tg.pdf(0.5 * (y32 + y64));
            worst = worst.max(level);
        }
    }
    assert!(central > 1000 && worst < 1e-6, "worst {worst:e}");
}

/// Independent erfc: the Taylor series e^{−x²}·Σ 2ⁿx^{2n+1}/(1·3···(2n+1)) (all terms positive) for x < 3,
/// the continued fraction beyond (where 1 − erf would cancel). Slow, exact to ~1e-14.
fn erfc_reference(x: f64) -> f64 {
    if x < 0.0 {
        return 2.0 - erfc_reference(-x);
    }
    if x < 2.0 {
        let (mut term, mut sum, mut n) = (x, x, 0.0);
        while term > 1e-18 * sum {
            n += 1.0;
            term *= 2.0 * x * x / (2.0 * n + 1.0);
            sum += term;
        }
        1.0 - std::f64::consts::FRAC_2_SQRT_PI * (-x * x).exp() * sum
    } else {
        // erfc x = e^{−x²}/√π · 1/(x + (1/2)/(x + 1/(x + (3/2)/(x + ...)))), evaluated bottom-up.
        let mut f = x;
        for k in (1..4000).rev() {
            f = x + (k as f64 / 2.0) / f;
        }
        (-x * x).exp() / (std::f64::consts::PI.sqrt() * f)
    }
}

#[test]
fn erfc_known_values() {
    // Abramowitz & Stegun Table 7.1 / high-precision values.
    for (x, want) in [
        (0.0, 1.0),
        (0.5, 0.479_500_122_186_953_5),
        (1.0, 0.157_299_207_050_285_1),
        (3.0, 2.209_049_699_858_544e-5),
        (10.0, 2.088_487_583_762_545e-45),
        (-1.0, 1.842_700_792_949_715),
    ] {
        let got = erfc(x);
        assert!(
            ((got - want) / want).abs() < 1.2e-7,
            "erfc({x}) = {got}, want {want}"
        );
    }
    assert!((erf(1.0) - 0.842_700_792_949_714_9).abs() < 2e-8);
    // Near 0 erf keeps its relative accuracy (series), which the truncated Gaussian's mass relies on.
    assert!((erf(0.01) / 0.011_283_415_555_849_618 - 1.0).abs() < 1e-14);
    assert!((erf(-0.3) / -0.328_626_759_459_127_4 - 1.0).abs() < 1e-14);
}

#[test]
fn erfc_matches_independent_series_and_continued_fraction() {
    // Out to x = 26 (erfc = 6e-296): the fit keeps its relative accuracy deep in the tail.
    for i in 0..=1000 {
        let x = -5.0 + i as f64 * 0.031;
        let (got, want) = (erfc(x), erfc_reference(x));
        assert!(
            ((got - want) / want).abs() < 1.2e-7,
            "erfc({x}) = {got}, reference {want}"
        );
    }
}

#[test]
fn erfc_inv_inverts_erfc_into_the_tails() {
    for p in [
        1e-300,
        1e-100,
        1e-20,
        1e-5,
        0.01,
        0.3,
        0.999,
        1.0,
        1.2,
        1.99,
        2.0 - 1e-12,
    ] {
        let x = erfc_inv(p);
        assert!(
            ((erfc(x) - p) / p).abs() < 1e-11,
            "erfc(erfc_inv({p})) = {}",
            erfc(x)
        );
    }
    assert_eq!(erfc_inv(0.0), 100.0);
    assert_eq!(erfc_inv(2.0), -100.0);
}

#[test]
fn normal_quantile_inverts_the_cdf_into_the_tails() {
    // Φ(Φ⁻¹(p)) = p to erfc's own accuracy (1.2e-7), both tails and all three pieces of AS 241.
    for p in [
        1e-300, 1e-100, 1e-20, 1e-9, 1e-5, 0.01, 0.07, 0.075, 0.3, 0.5, 0.7, 0.925, 0.99, 0.999_999,
    ] {
        let x = normal_quantile(p);
        let back = if x > 0.0 {
            1.0 - normal_cdf(-x)
        } else {
            normal_cdf(x)
        };
        assert!(((back - p) / p).abs() < 2e-7, "Φ(Φ⁻¹({p})) = {back}");
        // The upper tail by symmetry: Φ⁻¹(1 − p) = −Φ⁻¹(p) where 1 − p is exact.
        if p < 0.5 && p > 1e-9 {
            assert!((normal_quantile(1.0 - p) + x).abs() < 1e-9 * x.abs().max(1.0));
        }
    }
    assert_eq!(normal_quantile(0.5), 0.0);
    assert_eq!(normal_quantile(0.0), f64::NEG_INFINITY);
    assert_eq!(normal_quantile(1.0), f64::INFINITY);
}

#[test]
fn f32_quantile_and_tail_match_f64_in_both_forms() {
    // Φ⁻¹ by PPND7 against PPND16 (relative, absolute within 1e-3 of 0) over levels from f32's smallest normal
    // number to 1 − 2⁻²⁴ (log-spaced tails, linear middle), one level per lane and one at a time; and Φ(−z)
    // against the f64 erfc for z ∈ [0, 7] (0 beyond 6).
    use wide::f32x8;
    let mut levels: Vec<f32> = (0..=370)
        .map(|i| 10f32.powf(-37.9 + 0.1 * i as f32))
        .collect();
    levels.extend((1..1000).map(|i| i as f32 / 1000.0));
    levels.extend(levels.clone().iter().map(|&p| 1.0 - p).filter(|&p| p < 1.0));
    let (mut worst_q, mut worst_t) = (0.0f64, 0.0f64);
    for chunk in levels.chunks(8) {
        let lanes = normal_quantile_of(f32x8::new(std::array::from_fn(|k| {
            chunk[k.min(chunk.len() - 1)]
        })));
        for (k, &p) in chunk.iter().enumerate() {
            let want = normal_quantile(p as f64);
            for got in [normal_quantile_of(p), lanes.lane(k)] {
                let err = (got as f64 - want).abs() / want.abs().max(1e-3);
                worst_q = worst_q.max(err);
                // PPND7's own error reaches 2.6e-7 (near |p − ½| = 0.44), plus the f32 rounding.
                assert!(err < 5e-7, "Φ⁻¹({p}) = {got}, want {want}");
            }
        }
    }
    let zs: Vec<f32> = (0..=700).map(|i| i as f32 * 0.01).collect();
    for chunk in zs.chunks(8) {
        let lanes = upper_tail_of(f32x8::new(std::array::from_fn(|k| {
            chunk[k.min(chunk.len() - 1)]
        })));
        for (k, &z) in chunk.iter().enumerate() {
            let want = if z as f64 > NEGLIGIBLE_TAIL {
                0.0
            } else {
                normal_cdf(-(z as f64))
            };
            for got in [upper_tail_of(z), lanes.lane(k)] {
                let err = if want == 0.0 {
                    got as f64
                } else {
                    (got as f64 / want - 1.0).abs()
                };
                // The fit's 1.2e-7 plus the f32 rounding of the exponent z²/2 (about 1.2e-7 per unit: the
                // argument's rounding doubles in its square).
                let e = 0.5 * (z as f64).powi(2);
                worst_t = worst_t.max(err / (1.0 + e));
                assert!(err < 3e-7 * (1.0 + e), "Φ(−{z}) = {got}, want {want}");
            }
        }
    }
    eprintln!("worst Φ⁻¹ {worst_q:e}, worst Φ(−z) {worst_t:e} × (1 + z²/2)");
}

#[test]
fn gaussian_normalisations() {
    // Midpoint rule over ±10β: ∫ g = 1 (eq. 5), ∫ unit-height = β√(2π) (eq. 16).
    let beta = 0.1f32;
    let n = 4000;
    let h = 20.0 * beta / n as f32;
    let (mut s, mut su) = (0.0f64, 0.0f64);
    for i in 0..n {
        let x = -10.0 * beta + (i as f32 + 0.5) * h;
        s += (gaussian(beta, x) * h) as f64;
        su += (gaussian_unit(beta, x) * h) as f64;
    }
    assert!((s - 1.0).abs() < 1e-5, "{s}");
    let want = beta as f64 * std::f64::consts::TAU.sqrt();
    assert!((su - want).abs() < 1e-5, "{su}");
    assert!((gaussian_unit_integral(beta, -1.0, 1.0) as f64 - want).abs() < 1e-6);
    assert!((gaussian_unit_integral(beta, 0.0, 1.0) as f64 - want / 2.0).abs() < 1e-6);
}

/// Checks sample(u) is the inverse of the CDF implied by pdf(): ∫_lo^{sample(u)} pdf = u.
fn check_inverse_cdf(tg: &TruncatedGaussian, lo: f64, hi: f64) {
    let n = 20_000;
    let h = (hi - lo) / n as f64;
    let mut cdf = vec![0.0; n + 1];
    for i in 0..n {
        // Simpson on each step.
        let (x0, x1) = (lo + i as f64 * h, lo + (i + 1) as f64 * h);
        cdf[i + 1] = cdf[i] + h / 6.0 * (tg.pdf(x0) + 4.0 * tg.pdf(0.5 * (x0 + x1)) + tg.pdf(x1));
    }
    assert!((cdf[n] - 1.0).abs() < 1e-6, "pdf integrates to {}", cdf[n]);
    for k in 1..40 {
        let u = k as f64 / 40.0;
        let y = tg.sample(u);
        assert!((lo..=hi).contains(&y));
        let i = (((y - lo) / h) as usize).min(n - 1);
        // Linear interpolation of the tabulated CDF (error ≤ h·pdf ≤ 1e-4 here).
        let c = cdf[i] + (cdf[i + 1] - cdf[i]) * ((y - lo) / h - i as f64);
        assert!((c - u).abs() < 2e-4, "{tg:?}: CDF(sample({u})) = {c}");
    }
}

#[test]
fn truncated_gaussian_is_consistent() {
    // Mode inside, mode below, mode above (far tails: 30σ), and a wide σ (nearly uniform).
    for (mu, sigma, lo, hi) in [
        (0.1, 0.2, -0.7, 0.9),
        (-1.0, 0.05, 0.0, 1.5),
        (2.0, 0.05, -0.5, 0.5),
        (0.0, 30.0, -1.0, 1.0),
    ] {
        check_inverse_cdf(&TruncatedGaussian::new(mu, sigma, lo, hi), lo, hi);
    }
}

#[test]
fn truncated_gaussian_underflow_falls_back_to_uniform() {
    let tg = TruncatedGaussian::new(100.0, 0.1, 0.0, 1.0);
    assert_eq!(tg.mass(), 0.0);
    assert_eq!(tg.pdf(0.3), 1.0);
    assert!((tg.sample(0.25) - 0.25).abs() < 1e-12);
}
