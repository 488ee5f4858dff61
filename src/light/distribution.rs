//! Piecewise-constant distributions on [0, 1) and [0, 1)², sampled by inverting their tabulated CDFs (pbrt-v3
//! §13.6.7 and §14.2.4, `Distribution1D` / `Distribution2D`).
//!
//! - [`Distribution1D`]: n non-negative weights f₀ … f_{n−1}, read as the step function f(x) = f_⌊nx⌋ on
//!   [0, 1). Its integral is ∫₀¹ f = Σ fᵢ / n and its density p(x) = f(x) / ∫f.
//! - [`Distribution2D`]: a `width × height` table read as f(u, v) on [0, 1)² (u along a row, v down the rows),
//!   sampled as the marginal density of v (the row integrals) times the conditional density of u in that row.
//!
//! Weights that are negative or NaN count as 0. A table whose weights are all 0 falls back to the uniform
//! density, so sampling never fails; [`Distribution1D::integral`] still reports 0, which tells the caller that
//! nothing is there. Sampling inverts the CDF without allocating: a guide table (Chen & Asau 1974's cutpoint
//! method; Devroye 1986, §III.2.4) of one entry per [`GUIDE_BINS`] bins gives, for the interval of u-space that
//! u falls in, the first and last CDF index u can invert to, and a binary search inside that bracket finds the bin:
//! a few loads from one or two cache lines instead of a search over the whole table (an environment map's rows are
//! 1 024 entries: ten dependent loads, most of them cache misses, were half of its light sampling). The bin is the
//! one the plain binary search over the whole CDF finds, for every u (the search ends by stepping to the exact
//! boundary), so the samples are the same. The CDF is summed in f64 so a table of 10⁶ entries keeps every bin's
//! probability.

/// Bins per guide-table entry: 4 keeps the table at a quarter of the CDF's size (one byte per bin) while a
/// bracket spans about four CDF entries, one cache line, where the density is even.
const GUIDE_BINS: usize = 4;

/// A piecewise-constant density on [0, 1) from n ≥ 1 non-negative weights.
#[derive(Debug, Clone, PartialEq)]
pub struct Distribution1D {
    /// p(x) on bin i: fᵢ / ∫f (1 for the uniform fallback).
    density: Vec<f32>,
    /// CDF at the bin edges: `cdf[0]` = 0, `cdf[n]` = 1, non-decreasing.
    cdf: Vec<f32>,
    /// ∫₀¹ f = Σ fᵢ / n of the weights as given (0 for an all-zero table).
    integral: f32,
    /// `guide[g]`: the first CDF index greater than g / G (G = `guide.len()` − 1 intervals of u-space, G ≥ 1):
    /// for u in [g / G, (g + 1) / G) the index the search looks for lies in `guide[g] ..= guide[g + 1]`.
    guide: Vec<u32>,
}

impl Distribution1D {
    /// The distribution of `weights`. Negative and NaN weights count as 0; an empty slice or all-zero weights
    /// give the uniform density (with [`Distribution1D::integral`] 0; an empty slice is treated as one bin), and so
    /// does an infinite weight (with integral `f32::MAX`).
    pub fn new(weights: &[f32]) -> Distribution1D {
        let n = weights.len().max(1);
        let clean = |w: f32| if w > 0.0 { w as f64 } else { 0.0 };
        let sum: f64 = weights.iter().map(|&w| clean(w)).sum();
        let mut cdf = Vec::with_capacity(n + 1);
        cdf.push(0.0f32);
        let density: Vec<f32> = if sum > 0.0 && sum.is_finite() {
            let mut running = 0.0f64;
            for &w in weights {
                running += clean(w);
                cdf.push((running / sum) as f32);
            }
            weights
                .iter()
                .map(|&w| (clean(w) * n as f64 / sum) as f32)
                .collect()
        } else {
            // All zero, or an infinite weight (which no density can represent): uniform.
            for i in 1..=n {
                cdf.push(i as f32 / n as f32);
            }
            vec![1.0; n]
        };
        // Rounding must not leave the last edge short of 1: u just below 1 has to land in a bin.
        cdf[n] = 1.0;
        let integral = if sum.is_finite() {
            (sum / n as f64) as f32
        } else {
            f32::MAX
        };
        let intervals = n.div_ceil(GUIDE_BINS);
        let guide = (0..=intervals)
            .map(|g| {
                let t = (g as f64 / intervals as f64) as f32;
                cdf.partition_point(|&c| c <= t) as u32
            })
            .collect();
        Distribution1D {
            density,
            cdf,
            integral,
            guide,
        }
    }

    /// The number of bins n.
    pub fn len(&self) -> usize {
        self.density.len()
    }

    /// Always false: a distribution has at least one bin.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// ∫₀¹ f = Σ fᵢ / n of the weights given (0 when all were 0, although sampling is then uniform).
    pub fn integral(&self) -> f32 {
        self.integral
    }

    /// Draws x ∈ [0, 1) from a uniform `u` ∈ [0, 1): returns (x, p(x), bin index). The bin has p > 0; x is
    /// the inverse CDF, linear inside the bin, so stratified `u` stay stratified.
    #[inline]
    pub fn sample_continuous(&self, u: f32) -> (f32, f32, usize) {
        let n = self.len();
        let u = clamp_unit(u);
        let i = self.find_bin(u);
        let (c0, c1) = (self.cdf[i], self.cdf[i + 1]);
        let du = if c1 > c0 { (u - c0) / (c1 - c0) } else { 0.0 };
        let x = ((i as f32 + du.clamp(0.0, 1.0)) / n as f32).min(ONE_MINUS_EPSILON);
        (x, self.density[i], i)
    }

    /// Draws a bin index from a uniform `u` ∈ [0, 1) with probability fᵢ / Σf: returns (index, probability,
    /// u remapped to [0, 1) within the bin, for reuse as a fresh uniform number).
    #[inline]
    pub fn sample_discrete(&self, u: f32) -> (usize, f32, f32) {
        let u = clamp_unit(u);
        let i = self.find_bin(u);
        let (c0, c1) = (self.cdf[i], self.cdf[i + 1]);
        let remapped = if c1 > c0 {
            ((u - c0) / (c1 - c0)).clamp(0.0, ONE_MINUS_EPSILON)
        } else {
            0.0
        };
        (i, self.pmf(i), remapped)
    }

    /// The probability with which [`Distribution1D::sample_discrete`] returns `index` (0 out of range).
    #[inline]
    pub fn pmf(&self, index: usize) -> f32 {
        self.density
            .get(index)
            .map_or(0.0, |&d| d / self.len() as f32)
    }

    /// The density p(x) with which [`Distribution1D::sample_continuous`] draws x; 0 outside [0, 1] or for NaN
    /// (x = 1 counts as the last bin).
    #[inline]
    pub fn pdf(&self, x: f32) -> f32 {
        if !(0.0..=1.0).contains(&x) {
            return 0.0;
        }
        let n = self.len();
        self.density[((x * n as f32) as usize).min(n - 1)]
    }

    /// The bin i with `cdf[i]` ≤ u < `cdf[i+1]` (so a bin of positive probability) for u ∈ [0, 1).
    #[inline]
    fn find_bin(&self, u: f32) -> usize {
        // The first CDF index greater than u, searched inside the guide table's bracket for u's interval of
        // u-space, then stepped to the exact boundary of `c <= u` (no steps unless rounding put u in a
        // neighbouring interval): the index `cdf.partition_point(|&c| c <= u)` gives, for any u.
        let intervals = self.guide.len() - 1;
        let g = ((u * intervals as f32) as usize).min(intervals - 1);
        let (lo, hi) = (self.guide[g] as usize, self.guide[g + 1] as usize);
        let mut p = lo + self.cdf[lo..hi].partition_point(|&c| c <= u);
        while p > 0 && self.cdf[p - 1] > u {
            p -= 1;
        }
        while p < self.cdf.len() && self.cdf[p] <= u {
            p += 1;
        }
        (p - 1).min(self.len() - 1)
    }
}

/// A piecewise-constant density on [0, 1)², from a `width × height` table of non-negative weights in row order
/// (row 0 first; u runs along a row, v across rows).
#[derive(Debug, Clone, PartialEq)]
pub struct Distribution2D {
    /// p(u | v) for each row.
    conditional: Vec<Distribution1D>,
    /// p(v): the rows' integrals.
    marginal: Distribution1D,
}

impl Distribution2D {
    /// The distribution of `weights` (`width × height` entries, row after row). Rows of zeros are never chosen
    /// (unless the whole table is zero: then the density is uniform).
    ///
    /// # Panics
    /// If `weights.len() != width * height` or either size is 0: a broken invariant of the caller.
    pub fn new(weights: &[f32], width: usize, height: usize) -> Distribution2D {
        assert!(
            width > 0 && height > 0 && weights.len() == width * height,
            "a {width} x {height} distribution needs {} weights, got {}",
            width * height,
            weights.len()
        );
        let conditional: Vec<Distribution1D> = weights
            .chunks_exact(width)
            .map(Distribution1D::new)
            .collect();
        let row_integrals: Vec<f32> = conditional.iter().map(|c| c.integral()).collect();
        Distribution2D {
            marginal: Distribution1D::new(&row_integrals),
            conditional,
        }
    }

    /// ∫∫ f du dv of the weights given (0 when all were 0).
    pub fn integral(&self) -> f32 {
        self.marginal.integral()
    }

    /// (width, height) of the table.
    pub fn size(&self) -> (usize, usize) {
        (self.conditional[0].len(), self.conditional.len())
    }

    /// Draws (u, v) ∈ [0, 1)² from two uniform numbers: `u[1]` picks the row (v), `u[0]` the position in it.
    /// Returns the point and its density p(u, v) = p(v) p(u | v) > 0.
    #[inline]
    pub fn sample(&self, u: [f32; 2]) -> ([f32; 2], f32) {
        let (v, pdf_v, row) = self.marginal.sample_continuous(u[1]);
        let (x, pdf_u, _) = self.conditional[row].sample_continuous(u[0]);
        ([x, v], pdf_v * pdf_u)
    }

    /// The density p(u, v) with which [`Distribution2D::sample`] draws `uv`; 0 outside [0, 1]².
    #[inline]
    pub fn pdf(&self, uv: [f32; 2]) -> f32 {
        if !(0.0..=1.0).contains(&uv[0]) || !(0.0..=1.0).contains(&uv[1]) {
            return 0.0;
        }
        let height = self.conditional.len();
        let row = ((uv[1] * height as f32) as usize).min(height - 1);
        self.marginal.pdf(uv[1]) * self.conditional[row].pdf(uv[0])
    }
}

/// The largest f32 below 1.
const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// `u` clamped into [0, 1) (NaN → 0), so out-of-range sample inputs cannot index out of bounds.
#[inline]
fn clamp_unit(u: f32) -> f32 {
    if u > 0.0 {
        u.min(ONE_MINUS_EPSILON)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::util::stats::chi_square;
    use rand::Rng;
    use rand_pcg::Pcg32;

    /// Samples for the chi-square test: 200 000 over 48 cells expects ≈ 4 000 per cell, so a 5 % error in one
    /// cell's probability is ≈ 3 σ and shows up.
    const CHI2_SAMPLES: usize = 200_000;
    /// Significance of each chi-square test.
    const ALPHA: f64 = 0.01;

    #[test]
    fn the_guide_table_finds_the_bin_the_whole_search_finds() {
        // Even, peaked (a sun in a dark row), runs of zero bins, one bin, sizes off the guide's multiple; u drawn
        // at random, at every CDF value and its neighbours, and at every guide boundary and its neighbours.
        let mut rng = Pcg32::new(7, 11);
        let mut tables: Vec<Vec<f32>> = vec![
            vec![1.0; 1024],
            vec![2.5],
            (0..1023)
                .map(|i| if i == 700 { 1e6 } else { 1e-3 })
                .collect(),
            (0..37)
                .map(|i| if i % 5 < 3 { 0.0 } else { i as f32 })
                .collect(),
        ];
        tables.push((0..999).map(|_| rng.random::<f32>().powi(8)).collect());
        for weights in &tables {
            let d = Distribution1D::new(weights);
            let whole = |u: f32| (d.cdf.partition_point(|&c| c <= u) - 1).min(d.len() - 1);
            let intervals = d.guide.len() - 1;
            let mut us: Vec<f32> = (0..20_000).map(|_| rng.random::<f32>()).collect();
            for &c in &d.cdf {
                us.extend([c, c.next_down(), c.next_up()]);
            }
            for g in 0..=intervals {
                let t = g as f32 / intervals as f32;
                us.extend([t, t.next_down(), t.next_up()]);
            }
            for u in us.into_iter().filter(|u| (0.0..1.0).contains(u)) {
                assert_eq!(d.find_bin(u), whole(u), "u = {u} in a table of {}", d.len());
            }
        }
    }

    #[test]
    fn one_d_sample_matches_pdf_and_skips_zero_bins() {
        let d = Distribution1D::new(&[0.0, 1.0, 3.0, 0.0, -2.0, f32::NAN, 4.0, 0.0]);
        assert!((d.integral() - 8.0 / 8.0).abs() < 1e-6);
        let mut rng = Pcg32::new(3, 1);
        for _ in 0..10_000 {
            let (x, pdf, i) = d.sample_continuous(rng.random::<f32>());
            assert!((0.0..1.0).contains(&x), "x = {x}");
            assert_eq!(i, (x * 8.0) as usize, "x = {x} reported bin {i}");
            assert!(pdf > 0.0, "sampled a zero bin {i}");
            assert_eq!(pdf, d.pdf(x));
        }
        // Densities: weights / integral = [0, 1, 3, 0, 0, 0, 4, 0].
        assert!((d.pdf(0.3) - 3.0).abs() < 1e-6);
        assert_eq!(d.pdf(0.5), 0.0);
        assert_eq!(d.pdf(-0.1), 0.0);
        assert_eq!(d.pdf(f32::NAN), 0.0);
        // The ends of the unit interval land in bins of positive probability.
        assert_eq!(d.sample_continuous(0.0).2, 1);
        assert_eq!(d.sample_continuous(1.0).2, 6);
        assert!(d.sample_continuous(1.0).0 < 1.0);
        // cdf = [0, 0, 1/8, 1/2, 1/2, 1/2, 1/2, 1, 1]: u = 0.45 is in bin 2, u = 0.5 starts bin 6.
        let (i, pmf, _) = d.sample_discrete(0.45);
        assert_eq!(i, 2);
        assert_eq!(d.sample_discrete(0.5).0, 6);
        assert!((pmf - 3.0 / 8.0).abs() < 1e-6);
    }

    #[test]
    fn one_d_pdf_integrates_to_one_and_all_zero_is_uniform() {
        let mut rng = Pcg32::new(5, 2);
        let weights: Vec<f32> = (0..37).map(|_| rng.random::<f32>().powi(3)).collect();
        let d = Distribution1D::new(&weights);
        // Midpoint rule on a grid aligned with the bins is exact for a step function.
        let m = 37 * 16;
        let integral: f64 = (0..m)
            .map(|k| d.pdf((k as f32 + 0.5) / m as f32) as f64 / m as f64)
            .sum();
        assert!((integral - 1.0).abs() < 1e-5, "∫p = {integral}");
        let pmf_sum: f32 = (0..37).map(|i| d.pmf(i)).sum();
        assert!((pmf_sum - 1.0).abs() < 1e-5, "Σ pmf = {pmf_sum}");

        let zero = Distribution1D::new(&[0.0; 4]);
        assert_eq!(zero.integral(), 0.0);
        assert_eq!(zero.pdf(0.7), 1.0);
        let (x, pdf, i) = zero.sample_continuous(0.6);
        assert!((x - 0.6).abs() < 1e-6 && pdf == 1.0 && i == 2);
        let empty = Distribution1D::new(&[]);
        assert_eq!(empty.sample_continuous(0.5).1, 1.0);
    }

    #[test]
    fn two_d_sample_matches_pdf_and_integrates_to_one() {
        let mut rng = Pcg32::new(7, 3);
        let (w, h) = (5, 4);
        let mut weights: Vec<f32> = (0..w * h).map(|_| rng.random::<f32>()).collect();
        weights[2 * w..3 * w].fill(0.0); // A zero row is never drawn.
        let d = Distribution2D::new(&weights, w, h);
        for _ in 0..10_000 {
            let (uv, pdf) = d.sample(rng.random());
            assert!(uv.iter().all(|x| (0.0..1.0).contains(x)), "uv = {uv:?}");
            assert_ne!(
                (uv[1] * h as f32) as usize,
                2,
                "sampled the zero row: {uv:?}"
            );
            assert!(
                (pdf - d.pdf(uv)).abs() <= 1e-5 * pdf,
                "{pdf} vs {}",
                d.pdf(uv)
            );
        }
        // p(u, v) = f(u, v) / ∫∫f; midpoint rule on a grid aligned with the cells is exact.
        let m = 8;
        let mut integral = 0.0f64;
        for j in 0..h * m {
            for i in 0..w * m {
                let uv = [
                    (i as f32 + 0.5) / (w * m) as f32,
                    (j as f32 + 0.5) / (h * m) as f32,
                ];
                let f = weights[(j / m) * w + i / m] / d.integral();
                assert!((d.pdf(uv) - f).abs() < 1e-5 * f.max(1.0));
                integral += d.pdf(uv) as f64 / (w * h * m * m) as f64;
            }
        }
        assert!((integral - 1.0).abs() < 1e-5, "∫∫p = {integral}");
        let zero = Distribution2D::new(&[0.0; 6], 3, 2);
        assert_eq!(zero.integral(), 0.0);
        assert_eq!(zero.pdf([0.1, 0.9]), 1.0);
        assert_eq!(zero.sample([0.5, 0.5]).1, 1.0);
    }

    #[test]
    fn two_d_chi_square() {
        let mut rng = Pcg32::new(1, 4);
        let (w, h) = (8, 6);
        let weights: Vec<f32> = (0..w * h)
            .map(|_| rng.random::<f32>().powi(2) + 0.01)
            .collect();
        let d = Distribution2D::new(&weights, w, h);
        let mut observed = vec![0.0f64; w * h];
        for _ in 0..CHI2_SAMPLES {
            let (uv, _) = d.sample(rng.random());
            let (i, j) = ((uv[0] * w as f32) as usize, (uv[1] * h as f32) as usize);
            observed[j * w + i] += 1.0;
        }
        let total: f64 = weights.iter().map(|&x| x as f64).sum();
        let expected: Vec<f64> = weights
            .iter()
            .map(|&x| x as f64 / total * CHI2_SAMPLES as f64)
            .collect();
        let r = chi_square(&observed, &expected, 5.0);
        assert!(r.p_value > ALPHA, "chi-square rejects: {r:?}");
        assert_eq!(r.outside_support, 0.0);
    }
}
