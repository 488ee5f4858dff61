//! The path length: how much each bounce adds as bias when left out ([`Bounce`]), the geometric tail after the last
//! one measured and the cheapest path length that meets the target; one decision of [`super::plan`], apart from
//! the sample candidates'.

use crate::render::adaptive::neighbourhood;
use crate::render::settings::RenderSettings;
use crate::render::{Frame, Region};
use crate::shadow::ShadowMaps;

use super::pair::{mean_and_error, neighbour_means, render_seeds, Pair};

/// The path length of the first pilot render of the path-length search: every shorter one is cut from it
/// ([`bounce_pairs`]). Three is what the hair scenes need at 0.1 (default, straight hair under the city map and
/// the fur ball stop at bounce 3, under the sunset map at 2), and a vertex the search did not need costs little
/// (Russian roulette ends most paths before it).
pub(super) const FIRST_PILOT_PATH_LENGTH: u32 = 3;
/// How many bounces each further pilot render of the search adds.
pub(super) const PILOT_PATH_LENGTH_STEP: u32 = 2;
/// Samples per pixel of each further pilot render of the search, as a multiple of [`PILOT_SPP`](super::PILOT_SPP). A
/// bounce past the third is found by few of 4 samples: on the Cornell box the relative means of bounces 5, 6 and 7
/// carried standard errors of 12, 16 and 34 %, their ratios come out 0.81 and 0.80 where 256-spp renders measure a
/// decay of about 0.54, and the tail after path 7 reads 0.032 for a true 0.004 at 4 samples
/// (`docs/measured/auto.md`). Four times the samples halve those errors; the further renders cost about 1 % of
/// the frames that need them (tight targets, deep paths). Their pairs are not reused by the decisions after the path
/// length, which read the pilots at [`PILOT_SPP`](super::PILOT_SPP).
pub(super) const PILOT_EXTENSION_SPP_FACTOR: u32 = 4;

/// The pilot pairs at every path length 0 ..= `settings`' from one render per seed
/// ([`render_bounces`](crate::render::render_bounces)): a render at path length j traces the same paths up to vertex
/// j as one at K > j, so cutting the longer one's samples gives j's estimate and its rays without tracing the shared
/// vertices again (one path-3 render per seed instead of the four renders at path lengths 0 to 3, which traced vertex
/// 0 four times). Returns the pairs and their predicted CPU seconds.
pub(super) fn bounce_pairs(
    frame: &Frame,
    settings: &RenderSettings,
    maps: Option<&ShadowMaps>,
    windows: &[Region],
) -> (Vec<Pair>, f64) {
    let lengths = settings.integrator.path_length as usize + 1;
    let seeds = render_seeds(frame, settings, maps, windows);
    let pairs: Vec<Pair> = (0..lengths)
        .map(|j| Pair::cut(&seeds, j, settings.film.spp))
        .collect();
    let predicted = 2.0 * pairs[lengths - 1].predicted_seconds();
    (pairs, predicted)
}

/// The relative MSE a bounce adds as bias when left out: `before` and `after` are the pilot pixels of both seeds
/// without and with it, in `windows` order (see [`plan`](super::plan)). The mean of the per-pixel products and its
/// standard error.
///
/// A pixel's term is d_a d_b / (m̃² + 0.01), d_s its bounce in seed s and m̃ the mean of both seeds' `after` over
/// the pixel's neighbours in its window (3×3 without the centre). The denominator must not read the pixel's own
/// samples: with m the pixel's own mean, a sample that found much of the bounce also raised m, so the large
/// products were divided by large denominators. On the fur ball (`scenes/furball.toml`, 128², flat, path 3 against
/// 2, seeds' products over the whole film) that put bounce 3 at 1.5e-4 at 4 spp where a denominator from an
/// independent 64-spp render gives 3.1e-4 (and 5.9e-4 at 32 spp); the neighbours' gives 3.1e-4 and 5.8e-4, and
/// on the default scene within 10 % of the independent one too (the own mean's 2.4e-4 at 32 spp against 4.8e-5:
/// the error is not even one-sided). The fur ball's pilots put bounce 3 at 0.0054 (relative RMSE, with 2 standard
/// errors), chose path 2, and missed 0.05 (0.0538).
/// The neighbours' samples are independent of the pixel's, so the mean product over their mean is unbiased for
/// the squared bounce over the neighbourhood's squared mean.
pub(super) fn bounce_bias(
    before: [&[[f32; 3]]; 2],
    after: [&[[f32; 3]]; 2],
    windows: &[Region],
) -> Bounce {
    let value = |img: [&[[f32; 3]]; 2], s: usize, i: usize, c: usize| f64::from(img[s][i][c]);
    let means = neighbour_means(after, windows);
    // Per pixel and channel: each seed's bounce over the neighbours' denominator, (d_a / √den, d_b / √den).
    let mut relative = Vec::with_capacity(before[0].len() * 3);
    // Per pixel and channel: the two seeds' relative bounces pooled over the pixel's 3×3 neighbourhood in its
    // window (itself included), as products ([`Bounce::pooled_mean`]).
    let mut pooled = Vec::with_capacity(before[0].len() * 3);
    let mut start = 0usize;
    for r in windows {
        let (w, h) = (r.width() as usize, r.height() as usize);
        let first = relative.len();
        for p in 0..w * h {
            let i = start + p;
            for (c, &m) in means[i].iter().enumerate() {
                let den = (m * m + 0.01).sqrt();
                let da = value(after, 0, i, c) - value(before, 0, i, c);
                let db = value(after, 1, i, c) - value(before, 1, i, c);
                relative.push([da / den, db / den]);
            }
        }
        for p in 0..w * h {
            for c in 0..3 {
                let (mut a, mut b, mut n) = (0.0f64, 0.0f64, 0.0f64);
                for j in neighbourhood(w, w * h, p) {
                    let [ea, eb] = relative[first + j * 3 + c];
                    a += ea;
                    b += eb;
                    n += 1.0;
                }
                pooled.push(a / n * (b / n));
            }
        }
        start += w * h;
    }
    debug_assert_eq!(start, before[0].len());
    let finite = |t: &f64| t.is_finite();
    let (mean, standard_error) = mean_and_error(relative.iter().map(|[a, b]| a * b).filter(finite));
    let (pooled_mean, _) = mean_and_error(pooled.iter().copied().filter(finite));
    let (relative_mean, _) =
        mean_and_error(relative.iter().map(|[a, b]| 0.5 * (a + b)).filter(finite));
    Bounce {
        mean,
        standard_error,
        relative_mean,
        pooled_mean,
    }
}

/// The path length of least predicted cost for `target` among those rendered (`pairs[j]` at path length j) whose
/// bias left out, the geometric tail of `biases` (`biases[i]`: bounce i + 1, [`bias_left`] at the bounces'
/// [`decay_ratio`]), is at most half the target: (path length, its bias left out, the candidates listed for the
/// decision's reason). `biases` holds one bounce fewer than `pairs` paths: the longest path rendered, whose last
/// bounce was under a quarter of the target, takes the next bounce as the last one times the decay ratio, so its
/// tail is within half the target (the ratio is at most ¾) and the choice is total.
///
/// The cost of reaching the target at path length j is its CPU seconds per sample times the samples its noise
/// needs, ∝ seconds_j × relMSE_j / (target² − left_j²), relMSE_j over the longest path's means (the pilots' best
/// stand-in for the converged image, which the target is measured against): over its own means, darker by the
/// bounces it leaves out, a short path's relative noise reads high (on the default scene at 0.1, path 2 7.62e-2
/// against path 3 7.61e-2, where over the longest path's means path 2 is 7.29e-2; the fixed path-2 frame meets
/// 0.1 at 14 spp where path 3 takes 9 spp at 1.37× its time). A bounce just over a quarter of the target
/// takes 1 % of target² as bias when left out and may cost a tenth more per sample to trace: on straight hair
/// under the city map at 0.1 the pilots put bounce 2 at 0.029, the bounces after the first at 0.033 together
/// (2 × 128-spp renders of the whole film), and path 1 meets 0.1 at 20 spp where path 2 needs 21 spp. The
/// longest path is a candidate because its pilots are rendered anyway and a deep bounce can cost little: on the
/// fur ball (128²) the study's fits put path 3 at 0.070 s per spp against path 2's 0.074 (Russian roulette ends
/// most paths early), and path 3 has no bias left to pay for, where path 2 leaves 0.0315 of it.
///
/// The denominators are `means`, the longest path's pixel means from each pixel's neighbours alone
/// ([`neighbour_means`]). The longest pair's own means per pixel would read the longest path's own noise low
/// (its bright samples raise its denominators) and so favour it: over whole 128²
/// films at 4 spp (two seeds, flat, path 1/2/3; "true" is over a 2 × 64-spp path-3 reference), over the own means,
/// default 2.77/3.07/3.24
/// (e-2) for a true 2.85/3.28/3.56, sunset 3.76/3.91/3.98 for 4.17/4.46/4.67, fur ball 8.31/9.27/9.67 for
/// 8.22/9.50/10.15, straight-city path 1/3 4.35/4.77 for 4.71/5.56 (path 3 ÷ path 1 1.10 for 1.18); over the
/// neighbours' means 2.90/3.35/3.64, 4.16/4.44/4.69, 8.30/9.63/10.29 and 4.55/5.52: within 3.5 % of true.
pub(super) fn cheapest_path_length(
    pairs: &[Pair],
    means: &[[f64; 3]],
    biases: &[f64],
    target: f64,
) -> (u32, f64, String) {
    let mut best: Option<(u32, f64, f64)> = None;
    let mut listed = Vec::new();
    let last = pairs.len().min(biases.len() + 1).saturating_sub(1);
    let ratio = decay_ratio(biases);
    let continuation = biases.last().copied().unwrap_or(0.0) * ratio;
    for (j, pair) in pairs.iter().enumerate().take(last + 1) {
        let next = biases.get(j).copied().unwrap_or(continuation);
        let left = bias_left(next, ratio);
        // The longest path rendered is always a candidate (its next bounce is under a quarter of the target, so
        // its tail is within half), which keeps the choice total.
        if left > 0.5 * target && j < last {
            continue;
        }
        let cost = pair.predicted_seconds() * pair.rel_mse_over_means(means).0
            / (target * target - left * left);
        listed.push(format!("path {j} {cost:.2e}"));
        if best.is_none_or(|b| cost < b.2) {
            best = Some((j as u32, left, cost));
        }
    }
    let (j, left, _) = best.expect("the longest path rendered is a candidate");
    (j, left, listed.join(", "))
}

/// [`PilotPlan::darkening`](super::PilotPlan::darkening) of the pilot pair `chosen` against the longest path's pair
/// `longest`: its relMSE over `longest`'s means per its relMSE over its own, within [½, 1] (1 for a pair without
/// noise).
pub(super) fn darkening_of(chosen: &Pair, longest: &Pair) -> f64 {
    let own = chosen.rel_mse();
    if own > 0.0 {
        (chosen.rel_mse_over(longest).0 / own).clamp(0.5, 1.0)
    } else {
        1.0
    }
}

/// What the pilots measured of one bounce ([`bounce_bias`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Bounce {
    /// Mean over pilot pixels and channels of d_a d_b / (m̃² + 0.01): the relMSE the bounce adds as bias.
    pub(super) mean: f64,
    /// Standard error of `mean`.
    pub(super) standard_error: f64,
    /// Mean of (d_a + d_b) / 2 / √(m̃² + 0.01): the bounce's mean relative contribution, a linear statistic with
    /// far less noise than the products (see [`next_bias`]).
    pub(super) relative_mean: f64,
    /// Mean over pilot pixels and channels of ā_a ā_b, ā_s the mean of d_s / √(m̃² + 0.01) over the pixel's 3×3
    /// neighbourhood in its window: the squared bias smoothed over about a pixel, with far less noise than the
    /// pixel's own products (see [`pooled_bias`]).
    pub(super) pooled_mean: f64,
}

/// The bias (relative RMSE) of bounce k ≥ 2 from bounce k − 1's (`last`, as estimated) and both bounces'
/// measurements: `last` times the ratio of their relative means, at most 1 (`None` where bounce k − 1 has no
/// positive mean to scale by).
///
/// A deep bounce's product estimate has a standard error about as large as itself at the pilots' 4 spp over a
/// sixteenth of the film: on straight hair under the city map (128²) the pilots put bounce 2 at 0.049 (point
/// estimate; 0.073 with 2 standard errors) where 2 × 128-spp renders of the whole film measure 0.021. The ratio of
/// the bounces' relative means is a linear statistic, and it follows the ratio of their relative RMSEs closely:
/// over the whole film at 128 spp, 0.380, 0.396, 0.420 against 0.402, 0.421, 0.447 for bounces 2, 3, 4 on the
/// default scene, and 0.297, 0.364, 0.412 against 0.311, 0.390, 0.458 on straight-city (5–10 % low; the margin
/// carried by bounce 1's estimate, which is large and well measured, covers it).
pub(super) fn next_bias(last: f64, before: &Bounce, this: &Bounce) -> Option<f64> {
    (before.relative_mean > 0.0)
        .then(|| last * (this.relative_mean / before.relative_mean).clamp(0.0, 1.0))
}

/// A bounce's bias (relative RMSE) from its pooled products ([`Bounce::pooled_mean`]), the point estimate: the
/// floor under a later bounce's scaled estimate ([`next_bias`]).
///
/// The ratio of relative means reads a deeper bounce low where its relative RMSE over its relative mean grows with
/// depth, as on dense fur: on the fur ball (`scenes/furball.toml`, 128², flat; two 256-spp seeds per path length
/// against path 8) that ratio is 1.39, 1.48, 1.61, 1.71 for bounces 1–4, the bounces measure 0.131, 0.051, 0.023,
/// 0.011 and the bias left after path 2 0.0458, where the pilots put bounce 3 at 0.0199 (ratio of relative means
/// 0.368 for a true 0.45) and the tail at 0.0314: auto's path 2 met 0.1 only on its noise's slack. A pixel's own
/// product d_a d_b is too noisy at 4 spp on a sixteenth of the film (four pilot pairs of the fur ball's windows:
/// bounce 3 at 0.028, 0.009, 0.014 and 0), but the bias varies little over a pixel's neighbours where the noise
/// does not correlate, so the means of each seed's relative bounce over the 3×3 neighbourhood multiply to the
/// squared local bias with about a ninth of the noise: the same four pairs give 0.0259, 0.0216, 0.0225, 0.0215
/// (true 0.0230). Smoothing loses the bias's variation inside the neighbourhood: over the whole film at 256 spp
/// the tail after path 2 reads 0.0455 pooled 3×3 against 0.0458. It is a floor, not a replacement: on straight
/// hair under the city map (strands 0.07 px wide) four pilot pairs read bounce 2 pooled at 0.022–0.029 where
/// 128-spp seeds measure 0.0212 and the pixel products read 0.019–0.023.
pub(super) fn pooled_bias(bounce: &Bounce) -> f64 {
    bounce.pooled_mean.max(0.0).sqrt()
}

/// The largest ratio of one bounce's bias to the one before's that the geometric extrapolations
/// ([`decay_ratio`], [`bias_left`]) carry on: a bounce that grew is not extrapolated as growing, and the tail
/// next / (1 − r) stays within 4× the next bounce. A cap of ½ is too low: in the Cornell box (a closed box of
/// diffuse walls) the pilots measure bounces 1, 2, 3 at 0.156, 0.089, 0.050 (ratios 0.57, 0.56); capped at ½ the
/// tail after path 5 comes out 0.0124, auto chooses path 5 for 0.05 and measures 0.0527 against a path-10
/// reference. The hair scenes' ratios are 0.3–0.5 (the fur ball's 32-spp renders 0.35, 0.45, 0.50, 0.45), below
/// either cap.
pub const MAX_BOUNCE_RATIO: f64 = 0.75;

/// The ratio by which the bounces' bias is taken to fall past the last one measured: the largest ratio of one
/// bounce's estimate to the one before's in `biases` (bounces 1, 2, …; each ratio at most [`MAX_BOUNCE_RATIO`],
/// none read where the one before is not positive), ½ with fewer than two bounces.
///
/// The largest, not the last: the bounces do not fall at one rate. In the Cornell box (128², two 256-spp seeds
/// per path length against path 10) bounces 1–6 measure 0.152, 0.083, 0.045, 0.020, 0.010, 0.0061 (ratios 0.55,
/// 0.54, 0.44, 0.50, 0.61), and the pilots' pooled products read them to within 3 % (0.152, 0.083, 0.045, 0.020,
/// 0.010, 0.0061); the bias left after path 3 measures ≈ 0.045 and after path 5 0.0143, where the last ratio
/// gives 0.038 and 0.0092 (the tail of a sequence whose rate dips and recovers), and the largest (0.57) gives
/// 0.050 and 0.0136. On the hair scenes the ratios grow with depth (the fur ball's 0.39, 0.45, 0.48), so the
/// largest is the last there.
pub fn decay_ratio(biases: &[f64]) -> f64 {
    biases
        .windows(2)
        .filter(|w| w[0] > 0.0)
        .map(|w| (w[1] / w[0]).clamp(0.0, MAX_BOUNCE_RATIO))
        .reduce(f64::max)
        .unwrap_or(0.5)
}

/// The relative RMSE of the bias of every bounce after the chosen ones, from the measured bias of the first left
/// out (`next`, relative RMSE) and the bounces' [`decay_ratio`] r: the tail is next / (1 − r).
pub fn bias_left(next: f64, ratio: f64) -> f64 {
    next / (1.0 - ratio)
}
