//! Pearson's chi-square goodness-of-fit test of sampled directions against the integrated pdf, after pbrt-v4's
//! `ChiSquareTest` (`src/pbrt/util/math_test.cpp`'s harness used for its BSDF samplers): cells with an expected
//! count below a minimum are pooled into one, and the p-value comes from the regularised upper incomplete gamma
//! function, implemented here (series and continued fraction; e.g. Press et al., Numerical Recipes §6.2).

/// The outcome of [`chi_square`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChiSquare {
    /// Pearson's statistic Σ (observed − expected)² / expected over the (pooled) cells.
    pub statistic: f64,
    /// Degrees of freedom: cells used − 1.
    pub dof: usize,
    /// P(χ²_dof ≥ statistic) under the hypothesis that the samples follow the expected density.
    pub p_value: f64,
    /// Observations in cells whose expected count is 0: any is proof the sampler leaves the pdf's support.
    pub outside_support: f64,
}

/// Pearson's test of `observed` counts against `expected` counts (same cells, same order). Cells expecting fewer
/// than `min_expected` are pooled, smallest first, as pbrt-v4 does.
pub fn chi_square(observed: &[f64], expected: &[f64], min_expected: f64) -> ChiSquare {
    assert_eq!(
        observed.len(),
        expected.len(),
        "histograms of different sizes"
    );
    let mut order: Vec<usize> = (0..expected.len()).collect();
    order.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]));
    let (mut pooled_obs, mut pooled_exp, mut pooled_cells) = (0.0, 0.0, 0usize);
    let (mut statistic, mut cells, mut outside_support) = (0.0, 0usize, 0.0);
    for &i in &order {
        let (o, e) = (observed[i], expected[i]);
        if e <= 0.0 {
            outside_support += o;
        } else if e < min_expected || (pooled_exp > 0.0 && pooled_exp < min_expected) {
            pooled_obs += o;
            pooled_exp += e;
            pooled_cells += 1;
        } else {
            statistic += (o - e) * (o - e) / e;
            cells += 1;
        }
    }
    if pooled_cells > 0 && pooled_exp > 0.0 {
        statistic += (pooled_obs - pooled_exp) * (pooled_obs - pooled_exp) / pooled_exp;
        cells += 1;
    }
    let dof = cells.saturating_sub(1).max(1);
    ChiSquare {
        statistic,
        dof,
        p_value: chi_square_sf(statistic, dof as f64),
        outside_support,
    }
}

/// The per-test significance that keeps the family-wise rate at `alpha` over `tests` independent tests (Šidák):
/// 1 − (1 − α)^{1/m}.
pub fn sidak(alpha: f64, tests: usize) -> f64 {
    1.0 - (1.0 - alpha).powf(1.0 / tests as f64)
}

/// The survival function of the chi-square distribution with `dof` degrees of freedom: Q(dof/2, x/2).
pub fn chi_square_sf(x: f64, dof: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    gamma_q(0.5 * dof, 0.5 * x)
}

/// ln Γ(x) for x > 0: Lanczos approximation (g = 7, n = 9; relative error < 1e-15), with the reflection-free
/// shift for x < 0.5 not needed here (dof/2 ≥ 0.5).
pub fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Γ(x) Γ(1 − x) = π / sin(πx).
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + G + 0.5;
    for (i, &c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * std::f64::consts::TAU.ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// The regularised upper incomplete gamma function Q(a, x) = Γ(a, x)/Γ(a), a > 0, x ≥ 0: the series of P for
/// x < a + 1, the continued fraction (modified Lentz) of Q otherwise; both to relative 1e-15.
pub fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let ln_prefactor = a * x.ln() - x - ln_gamma(a);
    if x < a + 1.0 {
        // P(a, x) = e^{−x} x^a / Γ(a+1) Σ xⁿ / ((a+1)···(a+n)).
        let (mut ap, mut term) = (a, 1.0 / a);
        let mut sum = term;
        for _ in 0..10_000 {
            ap += 1.0;
            term *= x / ap;
            sum += term;
            if term.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        (1.0 - sum * ln_prefactor.exp()).max(0.0)
    } else {
        // Q(a, x) = e^{−x} x^a / Γ(a) · 1/(x + 1 − a − 1·(1 − a)/(x + 3 − a − 2·(2 − a)/(x + 5 − a − ...))).
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let delta = d * c;
            h *= delta;
            if (delta - 1.0).abs() < 1e-16 {
                break;
            }
        }
        (ln_prefactor.exp() * h).clamp(0.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ln_gamma_known_values() {
        assert!(ln_gamma(1.0).abs() < 1e-14);
        assert!(ln_gamma(2.0).abs() < 1e-14);
        assert!((ln_gamma(0.5) - std::f64::consts::PI.sqrt().ln()).abs() < 1e-14);
        assert!((ln_gamma(10.0) - 362_880f64.ln()).abs() < 1e-12);
        assert!((ln_gamma(100.5) - 361.435_540_467_777_6).abs() < 1e-10);
    }

    #[test]
    fn chi_square_survival_known_values() {
        // Tables: P(χ²_1 ≥ 3.841459) = 0.05, P(χ²_10 ≥ 23.20925) = 0.01, P(χ²_2 ≥ x) = e^{−x/2}.
        assert!((chi_square_sf(3.841_459, 1.0) - 0.05).abs() < 1e-7);
        assert!((chi_square_sf(23.209_25, 10.0) - 0.01).abs() < 1e-7);
        assert!((chi_square_sf(7.0, 2.0) - (-3.5f64).exp()).abs() < 1e-14);
        // Large dof (the histograms here have ~10⁴ cells): the mean of χ²_k is k, its median ≈ k(1 − 2/9k)³.
        let k: f64 = 10_000.0;
        let median = k * (1.0 - 2.0 / (9.0 * k)).powi(3);
        assert!((chi_square_sf(median, k) - 0.5).abs() < 1e-3);
        assert!(chi_square_sf(k + 10.0 * (2.0 * k).sqrt(), k) < 1e-15);
    }

    #[test]
    fn pooling_and_support() {
        let expected = [100.0, 100.0, 2.0, 2.0, 2.0, 0.0];
        let observed = [100.0, 100.0, 2.0, 2.0, 2.0, 3.0];
        let r = chi_square(&observed, &expected, 5.0);
        // Three small cells pooled into one: 3 cells, 2 dof, perfect fit.
        assert_eq!(r.dof, 2);
        assert!(r.statistic.abs() < 1e-12);
        assert_eq!(r.outside_support, 3.0);
        // A misfit of 50 in the first two cells: χ² = 2·25 = 50 on 2 dof ⇒ p = e^{−25}.
        let r = chi_square(&[150.0, 50.0, 2.0, 2.0, 2.0, 0.0], &expected, 5.0);
        assert!((r.statistic - 50.0).abs() < 1e-9);
        assert!((r.p_value - (-25.0f64).exp()).abs() < 1e-15);
        assert!((sidak(0.01, 1) - 0.01).abs() < 1e-15);
        assert!((sidak(0.01, 4) - 0.002_509_4).abs() < 1e-6);
    }
}
