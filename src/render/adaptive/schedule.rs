//! The rules that decide how many samples each pixel takes ([`Schedule`]): the per-pixel bound, the
//! image-level estimate and allocation of each round, and the neighbourhood smoothing and background order they
//! read; decisions only, apart from the pixel loop that carries them out.

use super::super::integrator::RayCost;
use super::convergence::{Convergence, SplitTerms};
use crate::util::hash::{mix64, GOLDEN_GAMMA};

/// An adaptive sampling schedule: at least `min` and at most `max` samples per pixel, in rounds, until the
/// image's estimated noise is at most `target` (the image-level rule); [`Schedule::next_total`] reads the same
/// schedule as the per-pixel rule, each pixel's own bound, which tests compare the image-level rule against.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Schedule {
    /// Samples before the first test (≥ 2).
    pub min: u32,
    /// Samples never exceeded.
    pub max: u32,
    /// Relative error to reach: the region's noise relative RMSE (the image-level rule) or each pixel's (the
    /// per-pixel rule, [`Schedule::next_total`]).
    pub target: f64,
    /// The image-level rule with a cost model: each pixel's samples are weighed by their predicted cost (from the rays
    /// they traced, never the clock), and the samples go where they buy the most error per second instead of per
    /// sample (module docs). `None`: every sample costs the same.
    pub cost: Option<RayCost>,
    /// The image-level rule: how much less relMSE the sampler's stratified samples have at 4 spp than independent ones
    /// (g₄ ≥ 1, measured by auto's pilots; 1: none assumed). The stop reads each pixel's independent-samples
    /// variance s² / n, so it divides it by the gain at the pixel's n ([`Schedule::gain`]).
    pub sampler_gain: f64,
}

/// The noise an adaptive render delivered, as its stop read it after the last round: the image's relMSE (noise
/// only, over the frame's own means) by the model and by the pixels' halves, the stop's target, and how many pixels
/// ended at the schedule's cap.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseEstimate {
    /// relMSE from each pixel's own variance over its count and the sampler's gain.
    pub model: f64,
    /// relMSE from the pixels' halves.
    pub split: f64,
    /// Pixels that took the schedule's `max` samples.
    pub capped: usize,
    /// Pixels in the region.
    pub pixels: usize,
    /// The stop's target (relative RMSE, noise only).
    pub target: f64,
    /// The schedule's most samples per pixel.
    pub max: u32,
}

impl NoiseEstimate {
    /// The relative RMSE the stop reads: the larger of the two estimates.
    pub fn rel_rmse(&self) -> f64 {
        self.model.max(self.split).sqrt()
    }

    /// The two estimates' relative RMSEs, smaller first: how far apart the two ways of reading it are.
    pub fn range(&self) -> (f64, f64) {
        let (a, b) = (self.model.sqrt(), self.split.sqrt());
        (a.min(b), a.max(b))
    }
}

/// Each pixel's weight in a round's allocation, √(v/c), from its neighbours alone: v and c the mean relative
/// variance and mean predicted cost per sample of the other pixels of its 3×3 neighbourhood (inside the region,
/// `width` pixels wide, row-major; its own where it has no neighbour; c = 1 unless every pixel's cost was recorded).
///
/// A pixel's count must not follow its own samples, or its mean is biased: read from its own v, a pixel that has
/// seen a rare bright sample gets more samples, which dilute it, and one that has not stops early and misses it,
/// both low (the classic bias of adaptive sampling), and the stop, reading v / n where n followed v, reads the
/// noise low with it. The same holds for its own cost, which its long (deep, bright) paths raise. Its neighbours'
/// samples are independent of its own, so its count is too, to first order (their counts read its v in turn).
///
/// Measured at target 0.1, 128², frame means against unbiased renders: with the larger of the pixel's own v and
/// its neighbours' mean, a wavy patch whose light is two thirds in bounces past the second (gen-2-01,
/// `cuticle study scenes --seed 2`) rendered 9–11 % dark, a back-lit fur ball (gen-2-07) 3 %, two seed-1 scenes
/// and the Cornell box 0.4–0.6 %; from the neighbours alone, 1.2 % and 0.0–0.3 %. The price is samples where the
/// noise is in isolated pixels that their neighbours do not predict: mean spp 1.5–2.1× on those scenes (4.7 → 9.7
/// on the fur ball, 54 → 83 on the Cornell box), 1.03–1.17× on the default scene and straight hair under the city
/// map. Capping the own v at 2× or 4× the neighbours' kept a third to two thirds of the bias. The test
/// `where_the_samples_go_does_not_bias_the_pixels_means_low` reads 0.958 ± 0.009 for 1 with the own v, 1.003 ±
/// 0.006 without. A hair-edge pixel whose first samples all missed the strand gets its neighbours' share.
pub(super) fn neighbour_shape(width: usize, pixels: &[Convergence]) -> Vec<f64> {
    let costed = pixels.iter().all(|p| p.mean_cost().is_some());
    let values: Vec<[f64; 3]> = pixels
        .iter()
        .map(|p| {
            let cost = p.mean_cost().filter(|_| costed).unwrap_or(1.0);
            [p.relative_variance(), cost, 1.0]
        })
        .collect();
    box_sums(width, &values)
        .iter()
        .zip(&values)
        .map(|(&[v, c, n], &[own_v, own_c, _])| {
            let (v, c) = if n > 1.5 {
                ((v - own_v) / (n - 1.0), (c - own_c) / (n - 1.0))
            } else {
                (own_v, own_c)
            };
            (v / c).sqrt()
        })
        .collect()
}

/// The sums of `values` over each pixel's 3×3 neighbourhood, itself included, clipped at the edges of a row-major
/// film `width` pixels wide (the pixels [`neighbourhood`] lists), for the pixels of its whole rows; a pixel past the
/// last whole row gets its own value. Separable — a sum of three along each row, then of three of those down each
/// column — so a pixel costs two passes of three adds per component where walking its neighbours costs nine.
pub(super) fn box_sums<const K: usize>(width: usize, values: &[[f64; K]]) -> Vec<[f64; K]> {
    let width = width.max(1);
    let rows = values.len() / width;
    let whole = rows * width;
    let add = |a: [f64; K], b: [f64; K]| std::array::from_fn(|k| a[k] + b[k]);
    let mut across = vec![[0.0; K]; whole];
    for (row, out) in values[..whole]
        .chunks_exact(width)
        .zip(across.chunks_exact_mut(width))
    {
        for x in 0..width {
            let mut s = row[x];
            if x > 0 {
                s = add(row[x - 1], s);
            }
            if x + 1 < width {
                s = add(s, row[x + 1]);
            }
            out[x] = s;
        }
    }
    let mut out = values.to_vec();
    for (i, o) in out.iter_mut().enumerate().take(whole) {
        let mut s = across[i];
        if i >= width {
            s = add(across[i - width], s);
        }
        if i + width < whole {
            s = add(s, across[i + width]);
        }
        *o = s;
    }
    out
}

/// The indices of pixel `i`'s 3×3 neighbourhood, itself included, row by row, clipped at the edges of a row-major
/// film `width` pixels wide with `len` pixels in its whole rows.
pub(crate) fn neighbourhood(width: usize, len: usize, i: usize) -> Neighbourhood {
    let height = len / width;
    let (x, y) = (i % width, i / width);
    let x0 = x.saturating_sub(1);
    Neighbourhood {
        width,
        x0,
        x1: (x + 2).min(width),
        x: x0,
        y: y.saturating_sub(1),
        y1: (y + 2).min(height),
    }
}

/// The iterator of [`neighbourhood`]: columns `x0..x1` (never empty) of rows `y..y1`, row by row, a plain counter
/// pair. (The adaptive stop, which sums every pixel's neighbours every round, uses the separable [`box_sums`].)
pub(crate) struct Neighbourhood {
    width: usize,
    x0: usize,
    x1: usize,
    x: usize,
    y: usize,
    y1: usize,
}

impl Iterator for Neighbourhood {
    type Item = usize;

    #[inline]
    fn next(&mut self) -> Option<usize> {
        if self.y >= self.y1 {
            return None;
        }
        let i = self.y * self.width + self.x;
        self.x += 1;
        if self.x == self.x1 {
            self.x = self.x0;
            self.y += 1;
        }
        Some(i)
    }
}

/// Rounds after the first at most (a safeguard: doubling from `min` reaches any `max` ≤ 65536 in 16).
pub(super) const MAX_ROUNDS: usize = 24;

impl Schedule {
    /// The per-pixel rule: how many samples the pixel should have taken in total after its next round, given the
    /// `taken` it has and the statistics of those of them that were finite (`pixel`); `None` when it is done
    /// (converged, or at `max`). Rounds count samples taken, so a dropped non-finite sample cannot stall the
    /// schedule.
    pub fn next_total(&self, taken: u32, pixel: &Convergence) -> Option<u32> {
        let n = taken;
        if n >= self.max {
            return None;
        }
        if n < self.min {
            return Some(self.min.min(self.max));
        }
        if pixel.relative_error() <= self.target {
            return None;
        }
        Some((2 * n).min(self.max))
    }

    /// The sampler's gain over independent samples at `n` samples per pixel, from the gain g₄ at 4
    /// ([`Schedule::sampler_gain`]): n^β up to 4 with β = log₄ g₄ (1 at one sample, g₄ at 4), then
    /// g₄ · (n / 4)^(β/2), growing at half the rate seen between 1 and 4.
    ///
    /// Measured (two-seed 128² renders, n · relMSE(n) / relMSE(1) at 4, 16, 64 spp): default scene 1.05, 1.14, 1.23;
    /// straight hair under the city map 1.28, 1.47, 1.84. The gain grows with n on both, but its growth rate
    /// between 1 and 4 spp over-predicts straight hair's (1.28 · 16^0.178 = 2.10 at 64 for 1.84); at half that rate
    /// the model stays under both (1.10 and 1.64 at 64).
    pub fn gain(&self, n: f64) -> f64 {
        let g4 = self.sampler_gain.max(1.0);
        let beta = g4.ln() / 4f64.ln();
        if n <= 4.0 {
            n.max(1.0).powf(beta)
        } else {
            g4 * (n / 4.0).powf(0.5 * beta)
        }
    }

    /// The image-level rule: the estimated relMSE (noise) of a region whose pixels took `taken` samples with
    /// statistics `pixels` (both in row-major order): the larger of the model's and the halves' estimates (module
    /// docs). The model's is the mean of v / (n g(n)) with each pixel's **own** v, an unbiased estimate of the mean
    /// relMSE of the pixels' means for independent samples (g = 1), and with the sampler's gain g
    /// ([`Schedule::gain`]) for its stratified ones (the neighbours' v of [`neighbour_shape`] only decides where
    /// the samples go: as a stop it overstated the noise, and the rule delivered 1.36–2.1× less than it aimed at);
    /// the halves' is the mean of [`Convergence::split_rel_mse`].
    pub fn image_rel_mse(&self, width: usize, taken: &[u32], pixels: &[Convergence]) -> f64 {
        let (_, model, split) = self.estimates(width, taken, pixels);
        model.max(split)
    }

    /// What a region that took `taken` samples with statistics `pixels` delivers, as the stop reads it
    /// ([`NoiseEstimate`]).
    pub fn noise_estimate(
        &self,
        width: usize,
        taken: &[u32],
        pixels: &[Convergence],
    ) -> NoiseEstimate {
        let (_, model, split) = self.estimates(width, taken, pixels);
        NoiseEstimate {
            model,
            split,
            capped: taken.iter().filter(|&&n| n >= self.max).count(),
            pixels: taken.len(),
            target: self.target,
            max: self.max,
        }
    }

    /// What the stop reads ([`Schedule::image_rel_mse`] is the larger of the last two): each pixel's own v over
    /// the sampler's gain at its count ([`Schedule::gained_variances`]), the model's image relMSE from them, and
    /// the image's relMSE from the pixels' halves, all over the same robust denominators.
    pub(super) fn estimates(
        &self,
        width: usize,
        taken: &[u32],
        pixels: &[Convergence],
    ) -> (Vec<f64>, f64, f64) {
        let means = Self::robust_means(width, pixels);
        let mut own = self.gained_variances(&means, taken, pixels);
        let mut split = Self::split_per_pixel(&means, pixels);
        // A background pixel's s² / (n g(n)) reads the hair's gain, far below its own (module docs): the model
        // takes its corrected halves instead, as a per-sample v for the round's budget.
        for ((o, (t, p)), &n) in own.iter_mut().zip(split.iter().zip(pixels)).zip(taken) {
            if let (true, Some(t)) = (p.background(), t) {
                *o = t * f64::from(n.max(1));
            }
        }
        // A splatted pixel's noise reaches the image as a share of its own ([`Convergence::share`]).
        for ((o, s), p) in own.iter_mut().zip(split.iter_mut()).zip(pixels) {
            let share = p.share();
            *o *= share;
            if let Some(s) = s {
                *s *= share;
            }
        }
        let model = Self::mean_over_counts(&own, taken);
        let count = pixels.len().max(1) as f64;
        (own, model, split.iter().flatten().sum::<f64>() / count)
    }

    /// Each pixel's own v over the sampler's gain at its present count, v / g(n): what the stop and the round's
    /// budget read (the gain only grows with more samples, so a round's goals from it are a little high, never
    /// low).
    ///
    /// The denominators are a robust estimate of each pixel's mean, per channel min(x̄, max(x̄ₙ, x̄₋)): x̄ the
    /// pixel's own mean, x̄ₙ its 3×3 neighbours' (without it), x̄₋ its own without its largest sample. A rare bright
    /// sample raises x̄ with s², so s² / (x̄² + 0.01) reads low on heavy-tailed pixels (the Cornell box's area light;
    /// the bias the pilots' bounce estimate had, `quality::pilot::bounce_bias`): there x̄ₙ or x̄₋ stands in, both
    /// below x̄. At a sharp edge (a bright strand beside the background) x̄ₙ alone would read far too low; x̄₋ keeps
    /// it near x̄. Where neither is below x̄, x̄ it is. Measured: own means alone missed the Cornell box's 0.1
    /// (0.1047); neighbours' means alone over-delivered a synthetic edge 2.8× (0.0181 for 0.05); x̄₋ alone was
    /// 1.6× slower than needed at 8–16 spp (it is biased low there).
    pub(super) fn gained_variances(
        &self,
        means: &[[f64; 3]],
        taken: &[u32],
        pixels: &[Convergence],
    ) -> Vec<f64> {
        let mut last = (u32::MAX, 1.0);
        pixels
            .iter()
            .zip(means)
            .zip(taken)
            .map(|((p, &m), &n)| {
                // Neighbouring pixels mostly share a count: the gain (a log and a power) is taken once per run.
                if last.0 != n {
                    last = (n, self.gain(f64::from(n.max(1))));
                }
                p.relative_variance_over(m) / last.1
            })
            .collect()
    }

    /// Each pixel's robust mean per channel, the denominators of the stop (see [`Schedule::gained_variances`]).
    pub(super) fn robust_means(width: usize, pixels: &[Convergence]) -> Vec<[f64; 3]> {
        // Each pixel's mean and a 1 where it has samples, summed over its 3×3 neighbourhood; less its own, the
        // neighbours' sums and count.
        let own: Vec<[f64; 4]> = pixels
            .iter()
            .map(|p| {
                let [r, g, b] = p.mean;
                if p.n > 0 {
                    [r, g, b, 1.0]
                } else {
                    [0.0; 4]
                }
            })
            .collect();
        box_sums(width, &own)
            .iter()
            .zip(&own)
            .zip(pixels)
            .map(|((sums, mine), p)| {
                let k = sums[3] - mine[3];
                let n = f64::from(p.n);
                std::array::from_fn(|c| {
                    let own = p.mean[c];
                    let neighbours = if k > 0.5 {
                        ((sums[c] - mine[c]) / k).max(0.0)
                    } else {
                        own
                    };
                    let without_max = if p.n > 1 {
                        ((n * own - p.max[c]) / (n - 1.0)).max(0.0)
                    } else {
                        own
                    };
                    own.min(neighbours.max(without_max))
                })
            })
            .collect()
    }

    /// Each pixel's relMSE (noise) from its halves ([`Convergence::split_terms`]) over the denominators `means`;
    /// `None` below 2 samples. A pixel that sees hair takes its halves as they are, V(P/2) − V(P) ≥ V(P) for any
    /// sampler no slower than independent samples, times P / n for its samples past P. A background pixel
    /// ([`Convergence::background`]) takes them divided by 2^α − 1 and times (P / n)^α, α the order of the
    /// background pixels' own convergence, V(m) ∝ m^−α, from their quarters and halves pooled
    /// ([`convergence_order`]), at most [`BACKGROUND_MAX_ORDER`].
    ///
    /// Why the background apart: its samples are the environment seen through the pixel filter, a function of the
    /// sample's position in the pixel alone, on which Owen-scrambled Sobol points converge at about m^−1.6
    /// (straight hair under the city map, 128², two-seed renders at 1–64 spp, path 3: the background's relMSE
    /// falls by 2.8–3.4 per doubling, its gain n · relMSE(n) / relMSE(1) is 5.2 at 16 spp and 12.2 at 64, where
    /// the pixels that see hair reach 1.22 and 1.36). Its halves read (2^α − 1) ≈ 2× its variance and its s² / n
    /// over the hair's gain ~4×, and on that scene the background is 74 % of the pixels: at 0.1 the stop's last
    /// round read 4.6e-4 of its 9.6e-3 budget from the background's halves, 3.0e-4 divided at the cap (1.6e-4 at
    /// the α of 1.7 its quarters measured). The hair's order cannot be measured so (one octave below is not its
    /// rate at the halves' octave: straight hair under the sunset map missed its target when the whole image's was
    /// used, `docs/measured/auto.md`), so its halves stay an upper bound.
    fn split_per_pixel(means: &[[f64; 3]], pixels: &[Convergence]) -> Vec<Option<f64>> {
        let terms: Vec<Option<SplitTerms>> = pixels
            .iter()
            .zip(means)
            .map(|(p, &m)| p.split_terms(m))
            .collect();
        let background = terms
            .iter()
            .zip(pixels)
            .filter_map(|(t, p)| t.as_ref().filter(|_| p.background()));
        let alpha = convergence_order(background).min(BACKGROUND_MAX_ORDER);
        let over = 2f64.powf(alpha) - 1.0;
        terms
            .iter()
            .zip(pixels)
            .map(|(t, p)| {
                t.map(|t| {
                    let beyond = f64::from(t.p) / f64::from(p.n);
                    if p.background() {
                        t.halves * beyond.powf(alpha) / over
                    } else {
                        t.halves * beyond
                    }
                })
            })
            .collect()
    }

    /// The image's relMSE (noise) from its pixels' halves: the mean over the pixels of [`Schedule::split_per_pixel`].
    #[cfg(test)]
    pub(super) fn split_rel_mse(means: &[[f64; 3]], pixels: &[Convergence]) -> f64 {
        let sum: f64 = Self::split_per_pixel(means, pixels).iter().flatten().sum();
        sum / pixels.len().max(1) as f64
    }

    /// The mean over pixels of `v / n` (`n` at least 1).
    pub(super) fn mean_over_counts(v: &[f64], taken: &[u32]) -> f64 {
        let sum: f64 = v
            .iter()
            .zip(taken)
            .map(|(v, &n)| v / f64::from(n.max(1)))
            .sum();
        sum / taken.len().max(1) as f64
    }

    /// The image-level rule: every pixel's total after the next round (at least what it `taken`), or `None` when the
    /// region is done: its estimated relMSE is at most target², or no pixel may grow. `round` counts the rounds
    /// after the first (which takes every pixel to `min`). `taken` and `pixels` are the region's pixels in
    /// row-major order; the result depends on them alone.
    // One piece: the stop and the water-filling of the round's goals read the same per-pixel vectors in one pass.
    pub fn next_round(
        &self,
        round: usize,
        width: usize,
        taken: &[u32],
        pixels: &[Convergence],
    ) -> Option<Vec<u32>> {
        let budget = self.target * self.target;
        // The stop reads the larger of the model's and the halves' estimates ([`Schedule::estimates`]).
        let (mut own, model, split) = self.estimates(width, taken, pixels);
        if round >= MAX_ROUNDS || model.max(split) <= budget {
            return None;
        }
        // Where the halves read more noise than the model, the round's samples are counted for the halves' level.
        if split > model && model > 0.0 {
            let scale = split / model;
            own.iter_mut().for_each(|v| *v *= scale);
        }
        let count = taken.len() as f64;
        // Who gets the samples: the neighbours' v (never the pixel's own, which would bias its mean); how many:
        // enough that the pixels' own v / (n g(n)) meet the budget.
        let shape = neighbour_shape(width, pixels);
        let max = f64::from(self.max);
        // Water-filling: `held` pixels keep a fixed count (at max, or already past their goal); the others share
        // the budget left by the held ones in the shape w = √(v/c) of the neighbours' v: n* = λ w with
        // Σ own / (λ w) = room, so λ = Σ own / w / room (with own = v: n* = √(v/c) · Σ√(v c) / room).
        let mut held: Vec<Option<f64>> = taken
            .iter()
            .map(|&n| (n >= self.max).then_some(max))
            .collect();
        let mut goal = vec![0.0f64; taken.len()];
        for _ in 0..32 {
            let (mut scale_sum, mut held_mse) = (0.0f64, 0.0f64);
            for (i, h) in held.iter().enumerate() {
                match h {
                    Some(n) => held_mse += own[i] / n,
                    None if shape[i] > 0.0 => scale_sum += own[i] / shape[i],
                    None => held_mse += own[i] / f64::from(taken[i].max(1)),
                }
            }
            let room = budget * count - held_mse;
            let mut changed = false;
            for i in 0..taken.len() {
                if held[i].is_some() {
                    continue;
                }
                let g = if room > 0.0 {
                    shape[i] * scale_sum / room
                } else {
                    max
                };
                goal[i] = g;
                if g >= max {
                    held[i] = Some(max);
                    changed = true;
                } else if g <= f64::from(taken[i]) {
                    held[i] = Some(f64::from(taken[i]));
                    changed = true;
                }
            }
            if !changed {
                break;
            }
        }
        // Fractional goals are rounded up or down by a fixed hash of the pixel and the round (up with probability
        // their fraction), so the round's total is its goals' sum, not a sample more per pixel: rounding every goal
        // up, the default scene at target 0.1 (128²) took a mean 8.95 spp and 558 k rays, rounded so 8.8 and 546 k,
        // delivering 0.0917 and 0.0930 (against one 256-spp half of the study's reference; target 0.1). Should no
        // pixel grow so, every goal is rounded up instead.
        let totals = |dither: bool| {
            let mut grows = false;
            let next: Vec<u32> = taken
                .iter()
                .enumerate()
                .map(|(i, &n)| {
                    let want = match held[i] {
                        Some(h) => h,
                        None if dither => {
                            let g = goal[i];
                            g.floor() + f64::from(u8::from(unit_hash(i, round) < g - g.floor()))
                        }
                        None => goal[i].ceil(),
                    };
                    let limit = n.saturating_mul(2).max(n + 1).min(self.max);
                    let t = (want.min(f64::from(limit)) as u32).max(n);
                    grows |= t > n;
                    t
                })
                .collect();
            grows.then_some(next)
        };
        totals(true).or_else(|| totals(false))
    }
}

/// The largest order of convergence, V(m) ∝ m^−α, that the stop credits the background with
/// ([`Schedule::split_per_pixel`]): 4/3, the order of the mean squared error He & Wang (2015, "On the convergence
/// rate of randomized quasi-Monte Carlo for discontinuous functions", SIAM J. Numer. Anal. 53) prove for scrambled
/// nets on d-dimensional integrands with discontinuities, m^(−1 − 1/(2d − 1)), at d = 2: the background seen through
/// a pinhole camera's pixel filter is such an integrand of the sample's 2-D position (texel and object edges). The
/// order the quarters measure one octave below is not safe alone: Sobol points' octaves alternate (edges in 64
/// directions, the test `background_pixels_are_read_at_their_own_faster_convergence`, read 1.83 from the quarters at
/// 8 samples where the halves' octave converges at about 1.5, and their noise 0.46–0.88× true at 5, 8, 12, 24 and 32
/// samples), while at most 4/3 it reads 1.06–1.30× true at 5–64 samples. Straight hair under the city map measures
/// 1.43–1.79 per octave from 1 to 64 spp.
pub const BACKGROUND_MAX_ORDER: f64 = 4.0 / 3.0;

/// The order α of the convergence of the pixels with `terms` (the background's, [`Schedule::split_per_pixel`]),
/// V(m) ∝ m^−α, from their quarters and halves pooled: the quarters read V(P/4) − V(P/2) and the halves
/// V(P/2) − V(P), whose ratio is 2^α; α in [1, 2] (1, independent samples' rate, when no pixel has quarters yet or
/// the ratio says slower).
pub(super) fn convergence_order<'a>(terms: impl Iterator<Item = &'a SplitTerms>) -> f64 {
    let (mut halves, mut quarters) = (0.0f64, 0.0f64);
    for t in terms {
        if let Some(q) = t.quarters {
            if t.halves.is_finite() && q.is_finite() {
                halves += t.halves;
                quarters += q;
            }
        }
    }
    if halves > 0.0 && quarters > 0.0 {
        (quarters / halves).log2().clamp(1.0, 2.0)
    } else {
        1.0
    }
}

/// A number in [0, 1) fixed by a pixel's index and the round (the crate's integer hash, [`mix64`]): the same for any
/// thread count.
pub(super) fn unit_hash(pixel: usize, round: usize) -> f64 {
    let z = mix64((pixel as u64) ^ ((round as u64) << 48) ^ GOLDEN_GAMMA);
    (z >> 11) as f64 / (1u64 << 53) as f64
}
