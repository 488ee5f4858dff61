//! Pearson's chi-square goodness-of-fit test of sampled directions against the integrated pdf, after pbrt-v4's
//! `ChiSquareTest` (`src/pbrt/util/math_test.cpp`'s harness used for its BSDF samplers): cells with an expected
//! count below a minimum are pooled into one (our step, as pbrt-v4's; `statrs` has none), and the p-value is the
//! survival function of the χ² distribution from `statrs`.

use statrs::distribution::{ChiSquared, ContinuousCDF};

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
/// than `min_expected` are pooled, smallest first, as pbrt-v4's `ChiSquareTest` does: the χ² approximation of
/// Pearson's statistic needs about 5 expected counts per cell.
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
        p_value: chi_square_sf(statistic, dof),
        outside_support,
    }
}

/// The per-test significance that keeps the family-wise rate at `alpha` over `tests` independent tests (Šidák):
/// 1 − (1 − α)^{1/m}.
pub fn sidak(alpha: f64, tests: usize) -> f64 {
    1.0 - (1.0 - alpha).powf(1.0 / tests as f64)
}

/// P(χ²_dof ≥ x), the survival function of the chi-square distribution with `dof` ≥ 1 degrees of freedom (1 for
/// x ≤ 0).
fn chi_square_sf(x: f64, dof: usize) -> f64 {
    ChiSquared::new(dof as f64)
        .expect("dof >= 1 is a valid chi-square distribution")
        .sf(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi_square_survival_known_values() {
        // Tables: P(χ²_1 ≥ 3.841459) = 0.05, P(χ²_10 ≥ 23.20925) = 0.01, P(χ²_2 ≥ x) = e^{−x/2}.
        assert!((chi_square_sf(3.841_459, 1) - 0.05).abs() < 1e-7);
        assert!((chi_square_sf(23.209_25, 10) - 0.01).abs() < 1e-7);
        assert!((chi_square_sf(7.0, 2) - (-3.5f64).exp()).abs() < 1e-14);
        assert_eq!(chi_square_sf(0.0, 3), 1.0);
        // Large dof (the histograms here have ~10⁴ cells): the mean of χ²_k is k, its median ≈ k(1 − 2/9k)³.
        let k = 10_000;
        let median = k as f64 * (1.0 - 2.0 / (9.0 * k as f64)).powi(3);
        assert!((chi_square_sf(median, k) - 0.5).abs() < 1e-3);
        assert!(chi_square_sf(k as f64 + 10.0 * (2.0 * k as f64).sqrt(), k) < 1e-15);
    }

    #[test]
    fn pooling_and_support() {
        let expected = [100.0, 100.0, 2.0, 2.0, 2.0, 0.0];
        let observed = [100.0, 100.0, 2.0, 2.0, 2.0, 3.0];
        let r = chi_square(&observed, &expected, 5.0);
        // Three small cells pooled into one: 3 cells, 2 dof, perfect fit.
        assert_eq!(r.dof, 2);
        assert!(r.statistic.abs() < 1e-12);
        assert_eq!(r.p_value, 1.0);
        assert_eq!(r.outside_support, 3.0);
        // A misfit of 50 in the first two cells: χ² = 2·25 = 50 on 2 dof ⇒ p = e^{−25}.
        let r = chi_square(&[150.0, 50.0, 2.0, 2.0, 2.0, 0.0], &expected, 5.0);
        assert!((r.statistic - 50.0).abs() < 1e-9);
        assert!((r.p_value - (-25.0f64).exp()).abs() < 1e-15);
        // The pooled cell counts: a misfit of 3 in it alone (6 + 3 = 9 observed against 6): χ² = 9/6 on 2 dof.
        let r = chi_square(&[100.0, 100.0, 5.0, 2.0, 2.0, 0.0], &expected, 5.0);
        assert!((r.statistic - 1.5).abs() < 1e-12);
        assert!((r.p_value - (-0.75f64).exp()).abs() < 1e-14);
    }

    #[test]
    fn sidak_known_values() {
        assert!((sidak(0.01, 1) - 0.01).abs() < 1e-15);
        assert!((sidak(0.01, 4) - 0.002_509_4).abs() < 1e-6);
    }
}
