//! The pilot estimates: one render per seed cut into per-path-length estimates ([`Pilot`], two seeds as a
//! [`Pair`]) and the statistics read from them (relative MSE with its standard error, neighbours' means, the
//! sampler's gain); measurement, apart from the decisions [`super::plan`] makes with it.

use rayon::prelude::*;

use crate::render::adaptive::neighbourhood;
use crate::render::integrator::RayCounts;
use crate::render::settings::RenderSettings;
use crate::render::{render_bounces, BounceRender, Frame, Region};
use crate::shadow::ShadowMaps;

use super::{PILOT_SPP, SEEDS};

/// One pilot estimate: the beauty (RGB) of every window pixel, in window order, with each window's rays, and the
/// render's wall time.
pub(super) struct Pilot {
    pub(super) rgb: Vec<[f32; 3]>,
    /// Each pixel's sample variance per channel, beside `rgb` ([`BounceRender::variances`]).
    pub(super) var: Vec<[f32; 3]>,
    pub(super) seconds: f64,
    pub(super) samples: u64,
    /// Rays traced, by kind (deterministic, unlike `seconds`: the cost decisions are made on).
    pub(super) rays: RayCounts,
    /// Each window's pixels in `rgb` (`start..start + len`) and its rays.
    pub(super) windows: Vec<(usize, usize, RayCounts)>,
}

impl Pilot {
    /// The pilot estimate at path length `j` cut from `renders` (one per window, at a path length ≥ `j`) that took
    /// `seconds` of wall time at `spp`; the time is shared by the cuts in proportion to their predicted cost.
    pub(super) fn cut(renders: &[BounceRender], j: usize, seconds: f64, spp: u32) -> Pilot {
        let mut rgb = Vec::new();
        let mut var = Vec::new();
        let mut rays = RayCounts::default();
        let mut all = RayCounts::default();
        let mut windows = Vec::with_capacity(renders.len());
        for r in renders {
            let start = rgb.len();
            rgb.extend(r.pixels[j].iter().map(|p| p.to_array()));
            var.extend(r.variances[j].iter().map(|p| p.to_array()));
            windows.push((start, rgb.len() - start, r.rays[j]));
            rays.add(&r.rays[j]);
            all.add(r.rays.last().expect("path length 0 at least"));
        }
        let share = super::super::cost::WEIGHTS.seconds(&rays)
            / super::super::cost::WEIGHTS
                .seconds(&all)
                .max(f64::MIN_POSITIVE);
        Pilot {
            samples: rgb.len() as u64 * u64::from(spp),
            rgb,
            var,
            seconds: seconds * share.min(1.0),
            rays,
            windows,
        }
    }

    /// The windows `parts` (each a pilot and one of its window indices), in that order, as one pilot; its time and
    /// samples are the caller's.
    pub(super) fn gather<'a>(
        parts: impl Iterator<Item = (&'a Pilot, usize)>,
        seconds: f64,
        samples: u64,
    ) -> Pilot {
        let mut rgb = Vec::new();
        let mut var = Vec::new();
        let mut rays = RayCounts::default();
        let mut windows = Vec::new();
        for (p, i) in parts {
            let (start, len, counts) = p.windows[i];
            windows.push((rgb.len(), len, counts));
            rgb.extend_from_slice(&p.rgb[start..start + len]);
            var.extend_from_slice(&p.var[start..start + len]);
            rays.add(&counts);
        }
        Pilot {
            rgb,
            var,
            seconds,
            samples,
            rays,
            windows,
        }
    }

    /// The pilot of the windows `picked` (indices into this pilot's windows, in that order) alone; its time is
    /// this one's share by pixels.
    pub(super) fn subset(&self, picked: &[usize]) -> Pilot {
        let pixels: usize = picked.iter().map(|&i| self.windows[i].1).sum();
        let share = pixels as f64 / self.rgb.len().max(1) as f64;
        Pilot::gather(
            picked.iter().map(|&i| (self, i)),
            self.seconds * share,
            (self.samples as f64 * share).round() as u64,
        )
    }

    /// The pilot of `count` windows from two pilots of complementary windows: `a` holds the windows `a_picked`
    /// (in that order), `b` the rest (in window order).
    pub(super) fn merge(a: &Pilot, a_picked: &[usize], b: &Pilot, count: usize) -> Pilot {
        let (mut ia, mut ib) = (0, 0);
        let parts = (0..count).map(|i| {
            if a_picked.get(ia) == Some(&i) {
                ia += 1;
                (a, ia - 1)
            } else {
                ib += 1;
                (b, ib - 1)
            }
        });
        Pilot::gather(parts, a.seconds + b.seconds, a.samples + b.samples)
    }
}

/// [`render_bounces`] of every window (in parallel) with each of the two [`SEEDS`], and the wall time each took.
pub(super) fn render_seeds(
    frame: &Frame,
    settings: &RenderSettings,
    maps: Option<&ShadowMaps>,
    windows: &[Region],
) -> [(Vec<BounceRender>, f64); 2] {
    SEEDS.map(|seed| {
        let mut s = settings.clone();
        s.film.seed = seed;
        let start = std::time::Instant::now();
        let renders = windows
            .par_iter()
            .map(|&r| render_bounces(frame, &s, maps, r))
            .collect();
        (renders, start.elapsed().as_secs_f64())
    })
}

/// Two independent pilot estimates (the two seeds) of one setting.
pub(super) struct Pair(pub(super) [Pilot; 2]);

impl Pair {
    /// The pair of `settings` over `windows`, at its path length.
    pub(super) fn render(
        frame: &Frame,
        settings: &RenderSettings,
        maps: Option<&ShadowMaps>,
        windows: &[Region],
    ) -> Pair {
        Pair::cut(
            &render_seeds(frame, settings, maps, windows),
            settings.integrator.path_length as usize,
            settings.film.spp,
        )
    }

    /// The pair at path length `j` cut from both seeds' renders ([`Pilot::cut`]).
    pub(super) fn cut(seeds: &[(Vec<BounceRender>, f64); 2], j: usize, spp: u32) -> Pair {
        Pair(
            seeds
                .each_ref()
                .map(|(renders, seconds)| Pilot::cut(renders, j, *seconds, spp)),
        )
    }

    /// The pair of the windows `picked` alone ([`Pilot::subset`]).
    pub(super) fn subset(&self, picked: &[usize]) -> Pair {
        Pair(self.0.each_ref().map(|p| p.subset(picked)))
    }

    /// The pair of all `count` windows from pairs of complementary windows ([`Pilot::merge`]).
    pub(super) fn merge(a: &Pair, a_picked: &[usize], b: &Pair, count: usize) -> Pair {
        Pair([0, 1].map(|s| Pilot::merge(&a.0[s], a_picked, &b.0[s], count)))
    }

    /// The relative MSE of one estimate, E[(x − y)²] / 2 over (m² + 0.01) per pixel and channel (the variance of
    /// each of two independent estimates), as (mean, standard error of the mean) over the pilot pixels.
    pub(super) fn rel_mse_with_error(&self) -> (f64, f64) {
        self.rel_mse_over(self)
    }

    /// The relative MSE of one estimate of `self` as [`Pair::rel_mse_with_error`], but over denominators
    /// (m² + 0.01) from `means` (another pair of the same windows): (mean, standard error of the mean).
    pub(super) fn rel_mse_over(&self, means: &Pair) -> (f64, f64) {
        let [a, b] = &self.0;
        let [ma, mb] = &means.0;
        rel_mse_of(
            channels([&a.rgb, &b.rgb, &ma.rgb, &mb.rgb]).map(|[x, y, p, q]| (x, y, 0.5 * (p + q))),
        )
    }

    /// The relative MSE of one estimate of `self` as [`Pair::rel_mse_with_error`], but over denominators
    /// (m² + 0.01) from per-pixel `means` (one per pixel and channel, in the pair's order, [`neighbour_means`]):
    /// (mean, standard error of the mean).
    pub(super) fn rel_mse_over_means(&self, means: &[[f64; 3]]) -> (f64, f64) {
        let [a, b] = &self.0;
        debug_assert_eq!(a.rgb.len(), means.len());
        rel_mse_of(
            a.rgb.iter().zip(&b.rgb).zip(means).flat_map(|((x, y), m)| {
                (0..3).map(move |c| (f64::from(x[c]), f64::from(y[c]), m[c]))
            }),
        )
    }

    /// The mean relative MSE of one estimate (see [`Pair::rel_mse_with_error`]).
    pub(super) fn rel_mse(&self) -> f64 {
        self.rel_mse_with_error().0
    }

    /// Rays per estimate.
    pub(super) fn rays(&self) -> f64 {
        0.5 * (self.0[0].rays.total() + self.0[1].rays.total()) as f64
    }

    /// Predicted CPU seconds per estimate ([`super::super::cost::WEIGHTS`] over the rays of each kind).
    pub(super) fn predicted_seconds(&self) -> f64 {
        0.5 * (super::super::cost::WEIGHTS.seconds(&self.0[0].rays)
            + super::super::cost::WEIGHTS.seconds(&self.0[1].rays))
    }

    pub(super) fn rgb(&self) -> [&[[f32; 3]]; 2] {
        [&self.0[0].rgb, &self.0[1].rgb]
    }
}

/// Each pilot pixel's mean from its neighbours alone, per channel: the mean of both seeds' `pair` values over the
/// pixel's 3×3 neighbourhood in its window without the pixel (the pixel's own mean where it has no neighbours, in
/// a 1×1 window); `pair` in `windows` order.
///
/// A relative error over a denominator that reads the pixel's own samples reads low where the samples are noisy: a
/// sample that raised the error also raised the denominator. The neighbours' samples are independent of the pixel's.
/// [`bounce_bias`](super::bounces::bounce_bias) divides by these means, and so does
/// [`cheapest_path_length`](super::bounces::cheapest_path_length).
pub(super) fn neighbour_means(pair: [&[[f32; 3]]; 2], windows: &[Region]) -> Vec<[f64; 3]> {
    let mean = |i: usize, c: usize| 0.5 * (f64::from(pair[0][i][c]) + f64::from(pair[1][i][c]));
    let mut out = Vec::with_capacity(pair[0].len());
    let mut start = 0usize;
    for r in windows {
        let (w, h) = (r.width() as usize, r.height() as usize);
        for p in 0..w * h {
            out.push(std::array::from_fn(|c| {
                let (mut sum, mut n) = (0.0f64, 0u32);
                for q in neighbourhood(w, w * h, p).filter(|&q| q != p) {
                    sum += mean(start + q, c);
                    n += 1;
                }
                if n > 0 {
                    sum / f64::from(n)
                } else {
                    mean(start + p, c)
                }
            }));
        }
        start += w * h;
    }
    debug_assert_eq!(start, pair[0].len());
    out
}

/// The relative MSE of one of two independent estimates (x, y) of a pixel channel over (m² + 0.01), from
/// (x, y, m) per pixel and channel, the non-finite left out: (mean, standard error of the mean) ([`Pair`]'s
/// relative MSEs, over whichever means).
pub(super) fn rel_mse_of(terms: impl Iterator<Item = (f64, f64, f64)>) -> (f64, f64) {
    mean_and_error(
        terms
            .filter(|&(x, y, m)| x.is_finite() && y.is_finite() && m.is_finite())
            .map(|(x, y, m)| 0.5 * (x - y) * (x - y) / (m * m + 0.01)),
    )
}

/// Four pixel arrays of the same windows walked together, one item per pixel and channel: the four values in `f64`.
pub(super) fn channels<'a>(arrays: [&'a [[f32; 3]]; 4]) -> impl Iterator<Item = [f64; 4]> + 'a {
    let [a, b, c, d] = arrays;
    a.iter()
        .zip(b)
        .zip(c.iter().zip(d))
        .flat_map(|((a, b), (c, d))| (0..3).map(move |k| [a[k], b[k], c[k], d[k]].map(f64::from)))
}

/// How much less relMSE the sampler's stratified samples have at [`PILOT_SPP`] than independent samples would,
/// from the pilot `pair` alone: g with n · relMSE(n) = σ² / g, lowered by `standard_errors` of its statistical
/// error (delta method) and never under 1. Returns (that, the point estimate).
///
/// The sample streams are Owen-scrambled Sobol points ([`crate::render::sampler`]), so a pixel's mean converges
/// faster than σ² / n, the variance of independent samples that adaptive sampling's stop reads from the pixels'
/// sample variances. The pair measures both sides at once: relMSE(n) from the two seeds' difference, and the pixels'
/// sample variance s² (what the stop reads) from their samples. For any samples with the same marginal, E(s²) = n (σ²
/// − Var x̄) / (n − 1), so G = E(s²) / (n relMSE(n)) = (n g − 1) / (n − 1), and g = ((n − 1) G + 1) / n.
///
/// A separate pair at 1 spp, g = relMSE(1) / (n relMSE(n)), does not measure the gain: a 1-spp pixel is one
/// heavy-tailed sample, and on the fur ball (128², path 3) it measures 1.049 ± 0.05 (1.0 after a standard error
/// off) where two-seed renders of the whole film measure 1.14 at 4 spp (1.19 at 16, 1.35 at 64), so the adaptive
/// stop delivers 1.2× less relMSE than it aims at. Two-seed renders of 128² frames (flat, path 1) measure
/// the gain at 4, 16, 64 spp as 1.05, 1.14, 1.23 on the default scene and 1.28, 1.47, 1.84 on straight hair under
/// the city map (the strands' coverage of a pixel is what the filter dimensions stratify). The gain grows with n;
/// adaptive sampling extrapolates the gain at `PILOT_SPP` at half the rate seen between 1 and `PILOT_SPP`
/// ([`crate::render::adaptive::Schedule::gain`]): at the full rate it overshoots straight hair's at 64 spp (2.1
/// for 1.84).
pub(super) fn sampler_gain(pair: &Pair, standard_errors: f64) -> (f64, f64) {
    let n = f64::from(PILOT_SPP);
    let (rp, ep) = pair.rel_mse_with_error();
    let [a, b] = &pair.0;
    let (sv, es) = mean_and_error(channels([&a.rgb, &b.rgb, &a.var, &b.var]).filter_map(
        |[x, y, vx, vy]| {
            let m = 0.5 * (x + y);
            let v = 0.5 * (vx + vy);
            (m.is_finite() && v.is_finite()).then(|| v / (m * m + 0.01))
        },
    ));
    if !(sv > 0.0 && rp > 0.0) {
        return (1.0, 1.0);
    }
    let big_g = sv / (n * rp);
    let gain = |g: f64| ((n - 1.0) * g + 1.0) / n;
    let relative_error = ((es / sv).powi(2) + (ep / rp).powi(2)).sqrt();
    (
        gain(big_g * (1.0 - standard_errors * relative_error)).max(1.0),
        gain(big_g),
    )
}

/// The mean of `terms` and the standard error of that mean (0 and 0 for none).
pub(super) fn mean_and_error(terms: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut sum, mut sum2, mut n) = (0.0f64, 0.0f64, 0usize);
    for t in terms {
        sum += t;
        sum2 += t * t;
        n += 1;
    }
    let n = n.max(1) as f64;
    let mean = sum / n;
    (mean, ((sum2 / n - mean * mean).max(0.0) / n).sqrt())
}
