//! Pilot renders: a few windows of the frame at full resolution, rendered cheaply before the frame to measure what
//! auto cannot know from the scene file — how much light each bounce adds and how noisy a sample is.
//!
//! The windows are a regular grid of small [`WINDOW`]² squares spread over the film (background included, as the
//! error target counts every pixel). Each is rendered with [`render_bounces`], whose pixel is the mean of the
//! same camera samples the frame's pixel takes (with the pilots' seeds), so a pilot pixel integrates exactly what
//! the frame's pixel will, and which gives every shorter path length's estimate of it from one render. Pilots are
//! deterministic (fixed seeds, independent of the frame's seed and of the thread count), so the decisions are
//! too.

use rayon::prelude::*;

use crate::render::adaptive::neighbourhood;
use crate::render::integrator::{RayCounts, MAX_PATH_LENGTH};
use crate::render::settings::RenderSettings;
use crate::render::{render_bounces, BounceRender, Frame, Region};
use crate::shadow::ShadowMaps;

use super::{Decision, QualityConfig};

/// Side of a pilot window, pixels: small, so that the windows can be many and spread over the whole film, with
/// each pixel keeping up to eight neighbours in its window for [`bounce_bias`]'s denominators.
pub const WINDOW: u32 = 4;
/// Camera samples per pixel of one pilot estimate.
pub const PILOT_SPP: u32 = 4;
/// Seeds of the two independent pilot estimates (far from the small seeds scenes use).
const SEEDS: [u32; 2] = [0x5eed_0001, 0x5eed_0002];

/// Fewest pilot pixels (36 windows), unless the film has fewer.
pub const MIN_PILOT_PIXELS: u32 = 576;
/// Most pilot pixels (576 windows): the statistics the pilots need do not grow with the film.
pub const MAX_PILOT_PIXELS: u32 = 9216;

/// The pilot windows of a `width`×`height` film: [`WINDOW`]² squares on an nx × ny grid of the film's aspect,
/// evenly spaced, holding about a sixteenth of the film's pixels (between [`MIN_PILOT_PIXELS`] and
/// [`MAX_PILOT_PIXELS`]), smaller on a film narrower than a window.
///
/// The windows must represent the film: the pilots' relMSE is a mean over their pixels standing for the mean over
/// the film's. Nine windows of 10² on a 128² film (the layout before 2 Dec 2026) sat mostly on the background of
/// the default scene and put the bias of its first two bounces at 0.053 and 0.024 (relative RMSE, 2 standard
/// errors added), where the whole film, as 1 024 windows of 4², measures 0.108 and 0.038; 64 windows of 4² (as
/// many pixels as the nine) measure 0.106 and 0.038. (The 0.0537 relative RMSE the study's fits measure for
/// leaving out every bounce after the first agrees with the second.)
pub fn windows(width: u32, height: u32) -> Vec<Region> {
    let (w, h) = (WINDOW.min(width), WINDOW.min(height));
    let pixels = f64::from(width) * f64::from(height);
    let wanted = (pixels / 16.0).clamp(f64::from(MIN_PILOT_PIXELS), f64::from(MAX_PILOT_PIXELS));
    let count = (wanted / f64::from(w * h)).max(1.0);
    let aspect = f64::from(width) / f64::from(height);
    let nx = ((count * aspect).sqrt().round() as u32).clamp(1, width / w);
    let ny = ((count / f64::from(nx)).round() as u32).clamp(1, height / h);
    let mut out = Vec::with_capacity((nx * ny) as usize);
    for j in 0..ny {
        for i in 0..nx {
            // Window centres at (i + 0.5) / nx of the film.
            let x0 = ((2 * i + 1) * width / (2 * nx))
                .saturating_sub(w / 2)
                .min(width - w);
            let y0 = ((2 * j + 1) * height / (2 * ny))
                .saturating_sub(h / 2)
                .min(height - h);
            out.push(Region {
                x0,
                y0,
                x1: x0 + w,
                y1: y0 + h,
            });
        }
    }
    out
}

/// One pilot estimate: the beauty (RGB) of every window pixel, in window order, with each window's rays, and the
/// render's wall time.
struct Pilot {
    rgb: Vec<[f32; 3]>,
    /// Each pixel's sample variance per channel, beside `rgb` ([`BounceRender::variances`]).
    var: Vec<[f32; 3]>,
    seconds: f64,
    samples: u64,
    /// Rays traced, by kind (deterministic, unlike `seconds`: the cost decisions are made on).
    rays: RayCounts,
    /// Each window's pixels in `rgb` (`start..start + len`) and its rays.
    windows: Vec<(usize, usize, RayCounts)>,
}

impl Pilot {
    /// The pilot estimate at path length `j` cut from `renders` (one per window, at a path length ≥ `j`) that took
    /// `seconds` of wall time at `spp`; the time is shared by the cuts in proportion to their predicted cost.
    fn cut(renders: &[BounceRender], j: usize, seconds: f64, spp: u32) -> Pilot {
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
        let share = super::cost::WEIGHTS.seconds(&rays)
            / super::cost::WEIGHTS.seconds(&all).max(f64::MIN_POSITIVE);
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
    fn gather<'a>(
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
    fn subset(&self, picked: &[usize]) -> Pilot {
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
    fn merge(a: &Pilot, a_picked: &[usize], b: &Pilot, count: usize) -> Pilot {
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
fn render_seeds(
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
struct Pair([Pilot; 2]);

impl Pair {
    /// The pair of `settings` over `windows`, at its path length.
    fn render(
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
    fn cut(seeds: &[(Vec<BounceRender>, f64); 2], j: usize, spp: u32) -> Pair {
        Pair(
            seeds
                .each_ref()
                .map(|(renders, seconds)| Pilot::cut(renders, j, *seconds, spp)),
        )
    }

    /// The pair of the windows `picked` alone ([`Pilot::subset`]).
    fn subset(&self, picked: &[usize]) -> Pair {
        Pair(self.0.each_ref().map(|p| p.subset(picked)))
    }

    /// The pair of all `count` windows from pairs of complementary windows ([`Pilot::merge`]).
    fn merge(a: &Pair, a_picked: &[usize], b: &Pair, count: usize) -> Pair {
        Pair([0, 1].map(|s| Pilot::merge(&a.0[s], a_picked, &b.0[s], count)))
    }

    /// The relative MSE of one estimate, E[(x − y)²] / 2 over (m² + 0.01) per pixel and channel (the variance of
    /// each of two independent estimates), as (mean, standard error of the mean) over the pilot pixels.
    fn rel_mse_with_error(&self) -> (f64, f64) {
        self.rel_mse_over(self)
    }

    /// The relative MSE of one estimate of `self` as [`Pair::rel_mse_with_error`], but over denominators
    /// (m² + 0.01) from `means` (another pair of the same windows): (mean, standard error of the mean).
    fn rel_mse_over(&self, means: &Pair) -> (f64, f64) {
        let [a, b] = &self.0;
        let [ma, mb] = &means.0;
        rel_mse_of(
            channels([&a.rgb, &b.rgb, &ma.rgb, &mb.rgb]).map(|[x, y, p, q]| (x, y, 0.5 * (p + q))),
        )
    }

    /// The relative MSE of one estimate of `self` as [`Pair::rel_mse_with_error`], but over denominators
    /// (m² + 0.01) from per-pixel `means` (one per pixel and channel, in the pair's order, [`neighbour_means`]):
    /// (mean, standard error of the mean).
    fn rel_mse_over_means(&self, means: &[[f64; 3]]) -> (f64, f64) {
        let [a, b] = &self.0;
        debug_assert_eq!(a.rgb.len(), means.len());
        rel_mse_of(
            a.rgb.iter().zip(&b.rgb).zip(means).flat_map(|((x, y), m)| {
                (0..3).map(move |c| (f64::from(x[c]), f64::from(y[c]), m[c]))
            }),
        )
    }

    /// The mean relative MSE of one estimate (see [`Pair::rel_mse_with_error`]).
    fn rel_mse(&self) -> f64 {
        self.rel_mse_with_error().0
    }

    /// Rays per estimate.
    fn rays(&self) -> f64 {
        0.5 * (self.0[0].rays.total() + self.0[1].rays.total()) as f64
    }

    /// Predicted CPU seconds per estimate ([`super::cost::WEIGHTS`] over the rays of each kind).
    fn predicted_seconds(&self) -> f64 {
        0.5 * (super::cost::WEIGHTS.seconds(&self.0[0].rays)
            + super::cost::WEIGHTS.seconds(&self.0[1].rays))
    }

    fn rgb(&self) -> [&[[f32; 3]]; 2] {
        [&self.0[0].rgb, &self.0[1].rgb]
    }
}

/// The path length of the first pilot render of the path-length search: every shorter one is cut from it
/// ([`bounce_pairs`]). Three is what the hair scenes need at 0.1 (default, straight hair under the city map and
/// the fur ball stop at bounce 3, under the sunset map at 2), and a vertex the search did not need costs little
/// (Russian roulette ends most paths before it).
const FIRST_PILOT_PATH_LENGTH: u32 = 3;
/// How many bounces each further pilot render of the search adds.
const PILOT_PATH_LENGTH_STEP: u32 = 2;
/// Samples per pixel of each further pilot render of the search, as a multiple of [`PILOT_SPP`]. A bounce past
/// the third is found by few of 4 samples: on the Cornell box the relative means of bounces 5, 6 and 7 carried
/// standard errors of 12, 16 and 34 %, their ratios came out 0.81 and 0.80 where 256-spp renders measure a decay of
/// about 0.54, and the tail after path 7 read 0.032 for a true 0.004 (`docs/study/auto/README.md`, fifteenth
/// run). Four times the samples halve those errors; the further renders cost about 1 % of the frames that need
/// them (tight targets, deep paths). Their pairs are not reused by the decisions after the path length, which
/// read the pilots at [`PILOT_SPP`].
const PILOT_EXTENSION_SPP_FACTOR: u32 = 4;

/// The pilot pairs at every path length 0 ..= `settings`' from one render per seed ([`render_bounces`]): a render
/// at path length j traces the same paths up to vertex j as one at K > j, so cutting the longer one's samples
/// gives j's estimate and its rays without tracing the shared vertices again (one path-3 render per seed instead
/// of the four renders at path lengths 0 to 3, which traced vertex 0 four times). Returns the pairs and their
/// predicted CPU seconds.
fn bounce_pairs(
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

/// The windows (indices into `windows`, in order) on which the light and material sample candidates are compared:
/// on the [`windows`] grid, every second column of every second row (a quarter, spread over the film as evenly as
/// the whole grid), or all of them where that would leave fewer than 16.
///
/// The candidates' relMSE relative to the scene's samples on the same pixels is what decides, and the pixels' own
/// spread (background against fur) is common to all of them, so a quarter of the windows decides nearly as well as
/// all of them at a quarter of the cost: on the default scene (128², 64 windows) the candidates other than the
/// path-length pilots' own were ~40 % of the pilots' predicted CPU time. (Every fourth window in row order would
/// sit in two columns of an 8-wide grid.)
fn comparison_windows(windows: &[Region]) -> Vec<usize> {
    let columns = windows
        .iter()
        .take_while(|r| r.y0 == windows[0].y0)
        .count()
        .max(1);
    let picked: Vec<usize> = (0..windows.len())
        .filter(|i| (i % columns) % 2 == 0 && (i / columns) % 2 == 0)
        .collect();
    if picked.len() < 16 {
        (0..windows.len()).collect()
    } else {
        picked
    }
}

/// Light and material samples at the first vertex auto compares (the thesis tuned them by hand, §6.2, table 3).
const SAMPLE_CANDIDATES: [(u32, u32); 4] = [(1, 1), (1, 4), (4, 1), (4, 4)];

/// A candidate whose predicted cost (relMSE × CPU s, [`predicted_both`]) is over this many times the best
/// measured one's is not rendered. The prediction is optimistic: with 1.2 here (until 5 Dec 2026) (4, 4) was
/// rendered on 4 of the 14 rows of `study auto` (straight hair under the city, sunset and interior maps, 128²),
/// measuring 1.08, 1.38, 1.17 and 1.23× its predicted relMSE and 1.17–1.51× the best's cost, winning none; at 1.05
/// three of them are not rendered, which saves the most expensive pilot pair (straight-city at 0.1: 3 320 M →
/// 3 278 M instructions in the pilots and the frame, callgrind, one thread) and changes no decision.
const SKIP_MARGIN: f64 = 1.05;

/// The relative MSE and predicted CPU seconds of the (4, 4) candidate from the pilots of (1, 1), (1, 4) and
/// (4, 1) (`measured`: candidate, relMSE, seconds), `None` for any other candidate or before the three are
/// measured. A pixel's variance is taken as a part the first vertex's samples do not touch (the camera's, the
/// strands' coverage) plus a light part and a material part, each divided by its sample count, so
/// v(4, 4) = v(4, 1) + v(1, 4) − v(1, 1); the rays add the same way. On the fur ball (128², path 3) that predicts
/// relMSE 6.5e-2 and 0.075 s where the pilots measured 7.2e-2 and 0.074 s (the variance parts are not quite
/// independent, so the prediction is optimistic for (4, 4) and skipping it on the prediction is safe), its cost
/// 1.6× (1, 1)'s: the most expensive of the eight pilot pairs is then not rendered.
fn predicted_both(
    candidate: (u32, u32),
    measured: &[((u32, u32), f64, f64)],
) -> Option<(f64, f64)> {
    if candidate != (4, 4) {
        return None;
    }
    let get = |c: (u32, u32)| measured.iter().find(|m| m.0 == c).map(|m| (m.1, m.2));
    let (v11, s11) = get((1, 1))?;
    let (v14, s14) = get((1, 4))?;
    let (v41, s41) = get((4, 1))?;
    Some(((v14 + v41 - v11).max(0.0), (s14 + s41 - s11).max(0.0)))
}

/// The relative MSE a bounce adds as bias when left out: `before` and `after` are the pilot pixels of both seeds
/// without and with it, in `windows` order (see [`plan`]). The mean of the per-pixel products and its standard
/// error.
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
fn bounce_bias(before: [&[[f32; 3]]; 2], after: [&[[f32; 3]]; 2], windows: &[Region]) -> Bounce {
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

/// Each pilot pixel's mean from its neighbours alone, per channel: the mean of both seeds' `pair` values over the
/// pixel's 3×3 neighbourhood in its window without the pixel (the pixel's own mean where it has no neighbours, in
/// a 1×1 window); `pair` in `windows` order.
///
/// A relative error over a denominator that reads the pixel's own samples reads low where the samples are noisy:
/// a sample that raised the error also raised the denominator. The neighbours' samples are independent of the
/// pixel's. [`bounce_bias`] divides by these means, and so does [`cheapest_path_length`].
fn neighbour_means(pair: [&[[f32; 3]]; 2], windows: &[Region]) -> Vec<[f64; 3]> {
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
fn rel_mse_of(terms: impl Iterator<Item = (f64, f64, f64)>) -> (f64, f64) {
    mean_and_error(
        terms
            .filter(|&(x, y, m)| x.is_finite() && y.is_finite() && m.is_finite())
            .map(|(x, y, m)| 0.5 * (x - y) * (x - y) / (m * m + 0.01)),
    )
}

/// Four pixel arrays of the same windows walked together, one item per pixel and channel: the four values in `f64`.
fn channels<'a>(arrays: [&'a [[f32; 3]]; 4]) -> impl Iterator<Item = [f64; 4]> + 'a {
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
/// sample variances. The pair measures both sides at once: relMSE(n) from the two seeds' difference, and the
/// pixels' sample variance s² (what the stop reads) from their samples. For any samples with the same marginal,
/// E(s²) = n (σ² − Var x̄) / (n − 1), so G = E(s²) / (n relMSE(n)) = (n g − 1) / (n − 1), and g = ((n − 1) G + 1) / n.
///
/// Until 3 Dec 2026 the gain came from a separate pair at 1 spp, g = relMSE(1) / (n relMSE(n)): a 1-spp pixel is
/// one heavy-tailed sample, and on the fur ball (128², path 3) it measured 1.049 ± 0.05 (1.0 after a standard
/// error off) where two-seed renders of the whole film measure 1.14 at 4 spp (1.19 at 16, 1.35 at 64), and the
/// adaptive stop delivered 1.2× less relMSE than it aimed at. Two-seed renders of 128² frames (flat, path 1) measured
/// the gain at 4, 16, 64 spp as 1.05, 1.14, 1.23 on the default scene and 1.28, 1.47, 1.84 on straight hair under
/// the city map (the strands' coverage of a pixel is what the filter dimensions stratify). The gain grows with n;
/// adaptive sampling extrapolates the gain at `PILOT_SPP` at half the rate seen between 1 and `PILOT_SPP`
/// ([`crate::render::adaptive::Schedule::gain`]): at the full rate it would have overshot straight hair's at 64
/// spp (2.1 for 1.84).
fn sampler_gain(pair: &Pair, standard_errors: f64) -> (f64, f64) {
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
/// bounces it leaves out, a short path's relative noise read high (on the default scene at 0.1, path 2 7.62e-2
/// against path 3 7.61e-2, where over the longest path's means path 2 is 7.29e-2; the fixed path-2 frame meets
/// 0.1 at 14 spp where auto's path 3 took 9 spp at 1.37× its time). A bounce just over a quarter of the target
/// takes 1 % of target² as bias when left out and may cost a tenth more per sample to trace: on straight hair
/// under the city map at 0.1 the pilots put bounce 2 at 0.029, the bounces after the first at 0.033 together
/// (2 × 128-spp renders of the whole film), and path 1 met 0.1 at 20 spp where auto took path 2 and 21 spp. The
/// longest path is a candidate because its pilots are rendered anyway and a deep bounce can cost little: on the
/// fur ball (128²) the study's fits put path 3 at 0.070 s per spp against path 2's 0.074 (Russian roulette ends
/// most paths early), and path 3 has no bias left to pay for, where auto took path 2 with 0.0315 of it.
///
/// The denominators are `means`, the longest path's pixel means from each pixel's neighbours alone
/// ([`neighbour_means`]). Until 4 Dec 2026 they were the longest pair's own means per pixel, which read the
/// longest path's own noise low (its bright samples raised its denominators) and so favoured it: over whole 128²
/// films at 4 spp (two seeds, flat, path 1/2/3; "true" is over a 2 × 64-spp path-3 reference) default 2.77/3.07/3.24
/// (e-2) for a true 2.85/3.28/3.56, sunset 3.76/3.91/3.98 for 4.17/4.46/4.67, fur ball 8.31/9.27/9.67 for
/// 8.22/9.50/10.15, straight-city path 1/3 4.35/4.77 for 4.71/5.56 (path 3 ÷ path 1 1.10 for 1.18); over the
/// neighbours' means 2.90/3.35/3.64, 4.16/4.44/4.69, 8.30/9.63/10.29 and 4.55/5.52: within 3.5 % of true.
fn cheapest_path_length(
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

/// [`PilotPlan::darkening`] of the pilot pair `chosen` against the longest path's pair `longest`: its relMSE over
/// `longest`'s means per its relMSE over its own, within [½, 1] (1 for a pair without noise).
fn darkening_of(chosen: &Pair, longest: &Pair) -> f64 {
    let own = chosen.rel_mse();
    if own > 0.0 {
        (chosen.rel_mse_over(longest).0 / own).clamp(0.5, 1.0)
    } else {
        1.0
    }
}

/// What the pilots measured of one bounce ([`bounce_bias`]).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Bounce {
    /// Mean over pilot pixels and channels of d_a d_b / (m̃² + 0.01): the relMSE the bounce adds as bias.
    mean: f64,
    /// Standard error of `mean`.
    standard_error: f64,
    /// Mean of (d_a + d_b) / 2 / √(m̃² + 0.01): the bounce's mean relative contribution, a linear statistic with
    /// far less noise than the products (see [`next_bias`]).
    relative_mean: f64,
    /// Mean over pilot pixels and channels of ā_a ā_b, ā_s the mean of d_s / √(m̃² + 0.01) over the pixel's 3×3
    /// neighbourhood in its window: the squared bias smoothed over about a pixel, with far less noise than the
    /// pixel's own products (see [`pooled_bias`]).
    pooled_mean: f64,
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
fn next_bias(last: f64, before: &Bounce, this: &Bounce) -> Option<f64> {
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
fn pooled_bias(bounce: &Bounce) -> f64 {
    bounce.pooled_mean.max(0.0).sqrt()
}

/// The largest ratio of one bounce's bias to the one before's that the geometric extrapolations
/// ([`decay_ratio`], [`bias_left`]) carry on: a bounce that grew is not extrapolated as growing, and the tail
/// next / (1 − r) stays within 4× the next bounce. It was ½ until 3 Dec 2026: in the Cornell box (a closed box of
/// diffuse walls) the pilots measured bounces 1, 2, 3 at 0.156, 0.089, 0.050 (ratios 0.57, 0.56); capped at ½ the
/// tail after path 5 came out 0.0124, auto chose path 5 for 0.05 and measured 0.0527 against a path-10 reference.
/// The hair scenes' ratios are 0.3–0.5 (the fur ball's 32-spp renders 0.35, 0.45, 0.50, 0.45), below either cap.
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

/// The mean of `terms` and the standard error of that mean (0 and 0 for none).
fn mean_and_error(terms: impl Iterator<Item = f64>) -> (f64, f64) {
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

/// What the pilots measured and decided.
#[derive(Debug, Clone)]
pub struct PilotPlan {
    /// Indirect bounces chosen (or the fixed one).
    pub path_length: u32,
    /// Light samples at the first vertex chosen (or the fixed ones).
    pub light_samples: u32,
    /// Material samples at the first vertex chosen (or the fixed ones).
    pub material_samples: u32,
    /// Camera samples per pixel chosen (or the fixed one).
    pub spp: u32,
    /// The decisions, for printing (none for what was fixed).
    pub decisions: Vec<Decision>,
    /// Predicted seconds of the frame's pixel loop at `spp`, from the pilots' time per sample.
    pub predicted_seconds: f64,
    /// Predicted relative RMSE (noise only) at `spp` uniform samples per pixel, over the converged image's means
    /// as the target is ([`PilotPlan::darkening`]).
    pub predicted_noise: f64,
    /// The noise the frame may have, relative RMSE: √(target² − bias²) with the bias the pilots measured for the
    /// bounces left out (half the target when the path length was fixed).
    pub noise_budget: f64,
    /// How much faster than independent samples the frame's error falls ([`sampler_gain`]; 1 when the spp was
    /// fixed): adaptive sampling's stop divides the noise it reads from the pixels' sample variances by it.
    pub sampler_gain: f64,
    /// The chosen path's relMSE over the longest pilot path's means per its relMSE over its own (at most 1; 1 when
    /// the path length was fixed or is the longest): how much lower the frame's noise reads relative to the
    /// converged image than relative to its own means, which are darker by the bounces left out. The target is a
    /// relative RMSE against the converged image, so the spp and the adaptive stop read the noise times this
    /// (the pilots' path comparison does the same, [`cheapest_path_length`]). On the pilots of the shipped scenes
    /// it is 0.95–0.97 where the chosen path is shorter than the longest rendered (default, sunset, studio and
    /// interior at 0.1), 1 elsewhere; two-seed renders of the fur ball at path 2 measured 0.893 against its path-2
    /// means (its noise 0.0870 over them, 0.0822 over the path-8 reference's). The longest pilot path is darker
    /// than the converged image too, so this reads less than the whole effect.
    pub darkening: f64,
    /// Wall time the pilots took, seconds.
    pub pilot_seconds: f64,
    /// CPU seconds of the pilots predicted from their rays ([`super::cost::WEIGHTS`]): their cost without the
    /// machine's load.
    pub pilot_predicted_seconds: f64,
}

/// Chooses the path length (unless `fixed.path_length`), the first vertex's light and material samples (unless
/// `fixed.samples`) and then the samples per pixel (unless `fixed.spp`), with the safety `margins` of
/// [`super::Margins`], for
/// `quality.target`, by pilot renders of `frame` under `settings` (its shadows already decided; `maps` built for
/// them when they are deep-opacity).
pub fn plan(
    frame: &Frame,
    settings: &RenderSettings,
    maps: Option<&ShadowMaps>,
    quality: &QualityConfig,
    fixed: super::Fixed,
    margins: super::Margins,
) -> PilotPlan {
    let bias_standard_errors = margins.bias_standard_errors;
    let start = std::time::Instant::now();
    let [width, height] = settings.film.resolution;
    let windows = windows(width, height);
    let target = f64::from(quality.target);
    let mut pilot = settings.clone();
    pilot.film.spp = PILOT_SPP;
    let mut decisions = Vec::new();
    let spent = std::cell::Cell::new(0.0f64);
    let render_pair = |settings: &RenderSettings, windows: &[Region]| {
        let pair = Pair::render(frame, settings, maps, windows);
        spent.set(spent.get() + 2.0 * pair.predicted_seconds());
        pair
    };

    // Bounces: each pilot path length k is rendered with both seeds. A pixel's k-th bounce is d = x_k − x_{k−1}
    // (same seed: the paths agree up to vertex k), and the product of the two seeds' independent d is an unbiased
    // estimate of its squared mean, so Σ d_a d_b / (m² + 0.01) estimates the relMSE the bounce adds as bias when
    // left out: that is bounce 1's estimate. A later bounce's products are too noisy at the pilots' spp, so its bias
    // is the one before's scaled by the ratio of their mean relative contributions ([`next_bias`]), or its products
    // pooled over each pixel's neighbours where that reads more ([`pooled_bias`]). Bounces are
    // added until the next one's bias is under a quarter of the target (half the target is the bias budget; the
    // other half leaves room for the bounces after it).
    // The pair rendered at the chosen path length with the scene's light and material samples, kept for reuse.
    let mut kept: Option<Pair> = None;
    // The relative RMSE of the bias the bounces left out (measured when the path length is decided here).
    let mut left: Option<f64> = None;
    // The chosen path's relMSE over the longest path's means, per its relMSE over its own ([`PilotPlan::darkening`]).
    let mut darkening = 1.0f64;
    let path_length = if fixed.path_length {
        settings.integrator.path_length
    } else {
        let mut biases = Vec::new();
        let mut measurements: Vec<Bounce> = Vec::new();
        // pairs[j]: the pilots at path length j, every one cut from a render at the longest ([`bounce_pairs`]),
        // rendered again longer when the last bounce is still over a quarter of the target.
        let mut pairs: Vec<Pair> = Vec::new();
        let mut pairs_spp = PILOT_SPP;
        for k in 1..=MAX_PATH_LENGTH {
            if k as usize >= pairs.len() {
                let (longest, spp) = if pairs.is_empty() {
                    (FIRST_PILOT_PATH_LENGTH, PILOT_SPP)
                } else {
                    (
                        k + PILOT_PATH_LENGTH_STEP - 1,
                        PILOT_SPP * PILOT_EXTENSION_SPP_FACTOR,
                    )
                };
                pilot.integrator.path_length = longest.min(MAX_PATH_LENGTH);
                pilot.film.spp = spp;
                let (cut, predicted) = bounce_pairs(frame, &pilot, maps, &windows);
                pilot.film.spp = PILOT_SPP;
                spent.set(spent.get() + predicted);
                pairs = cut;
                pairs_spp = spp;
            }
            let bounce = bounce_bias(
                pairs[k as usize - 1].rgb(),
                pairs[k as usize].rgb(),
                &windows,
            );
            let measured = match (biases.last(), measurements.last()) {
                (Some(&last), Some(before)) => {
                    next_bias(last, before, &bounce).map(|b| b.max(pooled_bias(&bounce)))
                }
                _ => None,
            }
            .unwrap_or_else(|| {
                (bounce.mean + bias_standard_errors * bounce.standard_error)
                    .max(0.0)
                    .sqrt()
            });
            measurements.push(bounce);
            biases.push(measured);
            if measured < 0.25 * target {
                break;
            }
        }
        pairs.truncate(biases.len() + 1);
        let means = neighbour_means(pairs[pairs.len() - 1].rgb(), &windows);
        let (chosen, tail, candidates) = cheapest_path_length(&pairs, &means, &biases, target);
        left = Some(tail);
        darkening = darkening_of(&pairs[chosen as usize], &pairs[pairs.len() - 1]);
        // The decisions after this one read pilots at PILOT_SPP: a pair from a further render is not theirs.
        kept = (pairs_spp == PILOT_SPP)
            .then(|| pairs.into_iter().nth(chosen as usize))
            .flatten();
        let listed: Vec<String> = biases
            .iter()
            .enumerate()
            .map(|(i, b)| format!("bounce {} {:.4}", i + 1, b))
            .collect();
        decisions.push(Decision {
            key: "integrator.path_length",
            value: chosen.to_string(),
            reason: format!(
                "the relative RMSE each bounce would leave out as bias, measured by the pilots (the first with {} \
                 standard errors, each later one scaled from the one before by the ratio of their mean relative \
                 contributions or its own products pooled over 3×3 pixels, the larger: {}), \
                 rendered until the next one is under a quarter of the target {}; of the path lengths whose \
                 bounces left out (a geometric tail at the bounces' largest ratio, {:.3}) are within half the \
                 target, the least predicted cost for the \
                 target, CPU s × relMSE at {PILOT_SPP} spp / (target² − bias²): {}{}",
                bias_standard_errors,
                listed.join(", "),
                quality.target,
                decay_ratio(&biases),
                candidates,
                left.map_or(String::new(), |b| format!(
                    "; all bounces left out together about {b:.4}"
                ))
            ),
        });
        chosen
    };
    pilot.integrator.path_length = path_length;

    // Light against material samples: the candidate that reaches a given relMSE at the least predicted cost
    // (relMSE × predicted seconds per estimate is the inverse of its efficiency). The cost is predicted from the
    // rays of each kind (super::cost), not read from the clock, so the choice is deterministic. Counting rays alone
    // picked (1, 4) on the default scene, where its material rays made it 1.4× the cost of (1, 1) per sample.
    let scene_samples = (
        settings.integrator.light_samples,
        settings.integrator.material_samples,
    );
    let (pair, light_samples, material_samples) = if fixed.samples {
        let pair = kept.take().unwrap_or_else(|| render_pair(&pilot, &windows));
        (pair, scene_samples.0, scene_samples.1)
    } else {
        // The scene's samples on every window (the path-length pilots' pair when there is one); the other
        // candidates on a subset of the windows only, compared with the scene's pair on the same windows, and the
        // winner completed on the rest.
        let base = kept.take().unwrap_or_else(|| render_pair(&pilot, &windows));
        let picked = comparison_windows(&windows);
        let rest: Vec<usize> = (0..windows.len()).filter(|i| !picked.contains(i)).collect();
        let regions = |indices: &[usize]| indices.iter().map(|&i| windows[i]).collect::<Vec<_>>();
        let base_subset = base.subset(&picked);
        let mut best: Option<((u32, u32), Option<Pair>, f64)> = None;
        let mut listed = Vec::new();
        let mut measured: Vec<((u32, u32), f64, f64)> = Vec::new();
        for (l, m) in SAMPLE_CANDIDATES {
            let is_base = (l, m) == scene_samples;
            if let (false, Some((v, seconds)), Some(b)) =
                (is_base, predicted_both((l, m), &measured), best.as_ref())
            {
                if v * seconds > SKIP_MARGIN * b.2 {
                    listed.push(format!(
                        "{l} light + {m} material: not rendered, predicted from the three others relMSE \
                         {v:.2e}, {seconds:.4} CPU s (over {SKIP_MARGIN} × the best's cost)"
                    ));
                    continue;
                }
            }
            let rendered = (!is_base).then(|| {
                pilot.integrator.light_samples = l;
                pilot.integrator.material_samples = m;
                render_pair(&pilot, &regions(&picked))
            });
            let p = rendered.as_ref().unwrap_or(&base_subset);
            let cost = p.rel_mse() * p.predicted_seconds();
            measured.push(((l, m), p.rel_mse(), p.predicted_seconds()));
            listed.push(format!(
                "{l} light + {m} material: relMSE {:.2e} with {:.0} rays, predicted {:.4} CPU s",
                p.rel_mse(),
                p.rays(),
                p.predicted_seconds()
            ));
            if best.as_ref().is_none_or(|b| cost < b.2) {
                best = Some(((l, m), rendered, cost));
            }
        }
        let ((l, m), rendered, _) = best.expect("candidates are not empty");
        let pair = match rendered {
            None => base,
            Some(subset) if rest.is_empty() => subset,
            Some(subset) => {
                pilot.integrator.light_samples = l;
                pilot.integrator.material_samples = m;
                let completed = render_pair(&pilot, &regions(&rest));
                Pair::merge(&subset, &picked, &completed, windows.len())
            }
        };
        decisions.push(Decision {
            key: "integrator.light_samples, material_samples",
            value: format!("{l}, {m}"),
            reason: format!(
                "the least predicted cost for a given noise (relMSE × CPU s predicted from the rays of each kind) \
                 among the pilots at {PILOT_SPP} spp on {} of the {} windows: {}",
                picked.len(),
                windows.len(),
                listed.join("; ")
            ),
        });
        (pair, l, m)
    };

    // Noise: two independent pilot estimates give each pixel's variance at PILOT_SPP; relMSE falls as 1/spp. The
    // noise budget is what the bias leaves of target²: T² − (bias left out)², or ¾ T² when the path length was
    // fixed (half the target to bias). The spp is the mean frame's: adaptive sampling spends it where the noise is.
    let (mean, standard_error) = pair.rel_mse_with_error();
    let [a, b] = &pair.0;
    let bias = left.unwrap_or(0.5 * target).min(0.5 * target);
    let noise_budget = target * target - bias * bias;
    let spp = if fixed.spp {
        settings.film.spp
    } else {
        // Noise over the converged image's means, which the target is measured against ([`PilotPlan::darkening`]).
        let wanted = (f64::from(PILOT_SPP) * mean * darkening / noise_budget).ceil();
        let spp = (wanted as u32).clamp(quality.min_spp, quality.max_spp);
        let limit = if wanted as u32 > quality.max_spp {
            format!(" (capped by quality.max_spp = {})", quality.max_spp)
        } else if (wanted as u32) < quality.min_spp {
            format!(" (raised to quality.min_spp = {})", quality.min_spp)
        } else {
            String::new()
        };
        decisions.push(Decision {
            key: "film.spp",
            value: spp.to_string(),
            reason: format!(
                "the pilot's relative MSE at {PILOT_SPP} spp is {mean:.3e} ± {standard_error:.1e} (two independent \
                 estimates; × {darkening:.3} over the longest pilot path's means, as the target's converged image is \
                 brighter by the bounces left out); noise within {:.4} (√(target² − bias²), target {}) needs \
                 {wanted} spp on average{limit}",
                noise_budget.sqrt(),
                quality.target
            ),
        });
        spp
    };
    let sampler_gain = if fixed.spp {
        1.0
    } else {
        let standard_errors = margins.gain_standard_errors;
        let (gain, point) = sampler_gain(&pair, standard_errors);
        decisions.push(Decision {
            key: "sampler gain",
            value: format!("{gain:.3}"),
            reason: format!(
                "from the pilots' pixels' sample variance over {PILOT_SPP}× their relMSE at {PILOT_SPP} spp, \
                 {point:.3} (with {standard_errors} standard error(s) off, at least 1): stratified samples converge \
                 that much faster than the independent samples whose variance adaptive sampling reads"
            ),
        });
        gain
    };
    let seconds_per_sample = (a.seconds + b.seconds) / (a.samples + b.samples).max(1) as f64;
    let predicted_seconds =
        seconds_per_sample * f64::from(width) * f64::from(height) * f64::from(spp);
    PilotPlan {
        path_length,
        light_samples,
        material_samples,
        spp,
        decisions,
        predicted_seconds,
        predicted_noise: (mean * darkening * f64::from(PILOT_SPP) / f64::from(spp)).sqrt(),
        noise_budget: noise_budget.sqrt(),
        sampler_gain,
        darkening,
        pilot_seconds: start.elapsed().as_secs_f64(),
        pilot_predicted_seconds: spent.get(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::Rng;

    #[test]
    fn windows_lie_inside_the_film_and_do_not_overlap() {
        for (w, h) in [
            (640, 480),
            (512, 512),
            (128, 128),
            (96, 72),
            (20, 10),
            (1, 1),
            (97, 33),
        ] {
            let ws = windows(w, h);
            assert!(!ws.is_empty());
            for (i, r) in ws.iter().enumerate() {
                assert!(r.check_inside(w, h).is_ok(), "{r:?} in {w}x{h}");
                assert!(r.width() > 0 && r.height() > 0);
                for s in &ws[i + 1..] {
                    let overlap = r.x0 < s.x1 && s.x0 < r.x1 && r.y0 < s.y1 && s.y0 < r.y1;
                    assert!(!overlap, "{r:?} overlaps {s:?} in {w}x{h}");
                }
            }
        }
        // A sixteenth of the film, spread over it: 640x480 has 19 200 pixels to sample, capped at 9 216 (576
        // windows); 128² has 1 024 (64 windows, 8 × 8); small films at least 576 pixels.
        // The grid follows the film's aspect, so the count is rounded: 28 × 21 on 640x480.
        assert_eq!(windows(640, 480).len(), 28 * 21);
        let w128 = windows(128, 128);
        assert_eq!(w128.len(), 64);
        assert_eq!((w128[0].x0, w128[63].x1), (6, 122));
        assert_eq!(windows(96, 72).len(), 7 * 5);
    }

    #[test]
    fn four_light_and_four_material_samples_are_predicted_from_the_other_three() {
        let fur = [
            ((1, 1), 8.73e-2, 0.035),
            ((1, 4), 7.51e-2, 0.055),
            ((4, 1), 7.68e-2, 0.055),
        ];
        assert_eq!(predicted_both((1, 4), &fur), None);
        assert_eq!(predicted_both((4, 4), &fur[..2]), None);
        let (v, s) = predicted_both((4, 4), &fur).unwrap();
        assert!(
            (v - 6.46e-2).abs() < 1e-9 && (s - 0.075).abs() < 1e-9,
            "{v} {s}"
        );
        // The fur ball's: 1.6x (1, 1)'s cost, not rendered.
        assert!(v * s > SKIP_MARGIN * 8.73e-2 * 0.035);
        // Where the light and material noise dominate and each halves, (4, 4) is predicted to win: rendered.
        let noisy = [((1, 1), 1.0, 1.0), ((1, 4), 0.55, 1.3), ((4, 1), 0.55, 1.3)];
        let (v, s) = predicted_both((4, 4), &noisy).unwrap();
        assert!(v * s < SKIP_MARGIN * 1.0 * 1.0, "{v} {s}");
    }

    /// Path lengths are compared by their noise over the longest path's means: a short path, darker by the bounce
    /// it leaves out, has the same absolute noise but is not read as relatively noisier. Here path 0 is half as
    /// bright as path 1, as noisy per pixel, and two thirds of its rays: over its own means it would cost 2.6×
    /// path 1 per unit of relMSE and lose; over path 1's it costs 2/3 and, its bias within budget, wins.
    #[test]
    fn path_lengths_are_compared_over_the_longest_paths_means() {
        let pair = |level: f32, camera: u64| {
            let pixels = |sign: f32| -> Vec<[f32; 3]> {
                (0..64)
                    .map(|i| [level + if i % 2 == 0 { 0.1 } else { -0.1 } * sign; 3])
                    .collect()
            };
            let mut pair = with_variances(pixels(1.0), pixels(-1.0), 0.01);
            for p in &mut pair.0 {
                p.rays.camera = camera;
            }
            pair
        };
        let pairs = [pair(0.5, 2_000_000), pair(1.0, 3_000_000)];
        // Path 1's pixels mean 1 everywhere, so its neighbours' means are 1 too.
        let means = neighbour_means(pairs[1].rgb(), &[region(8, 8)]);
        assert!(means.iter().flatten().all(|&m| (m - 1.0).abs() < 1e-6));
        // Bounce 1's bias 0.02, within half of 0.1 when left out (its tail 0.04 with the unknown ratio ½).
        let (chosen, left, listed) = cheapest_path_length(&pairs, &means, &[0.02], 0.1);
        assert_eq!(chosen, 0, "{listed}");
        assert!((left - 0.04).abs() < 1e-12, "{left}");
        // Over its own means path 0's relMSE is (1.01 / 0.26)× path 1's.
        let own = pairs[0].rel_mse() / pairs[1].rel_mse();
        // (f32 pixel values: to 1e-6 relative.)
        assert!((own / (1.01 / 0.26) - 1.0).abs() < 1e-5, "{own}");
    }

    #[test]
    fn the_tail_falls_at_the_largest_ratio_of_the_bounces_measured() {
        assert_eq!(decay_ratio(&[]), 0.5);
        assert_eq!(decay_ratio(&[0.15]), 0.5);
        // A bounce that grew is not extrapolated as growing.
        assert_eq!(decay_ratio(&[0.01, 0.04]), MAX_BOUNCE_RATIO);
        assert_eq!(decay_ratio(&[0.0, 0.04]), 0.5);
        // The Cornell box's pilots (pooled products, 128²) read bounces 1-5 at 0.156, 0.089, 0.050, 0.0214, 0.0102,
        // where two 256-spp seeds per path length measure the bias left after path 3 at ≈ 0.045-0.049 and after
        // path 5 at 0.0143: the rate dips (0.43) and recovers (0.61 for bounce 6), so the last ratio (0.48) reads
        // those tails at 0.041 and 0.0092, and the largest (0.57) at 0.050 and 0.0136.
        let cornell = [0.156, 0.089, 0.050, 0.0214, 0.0102];
        let r = decay_ratio(&cornell);
        assert!((r - 0.089 / 0.156).abs() < 1e-12, "{r}");
        let after_3 = bias_left(cornell[3], r);
        let after_5 = bias_left(cornell[4] * r, r);
        assert!((0.045..0.055).contains(&after_3), "{after_3}");
        assert!((0.0125..0.016).contains(&after_5), "{after_5}");
        let last = cornell[4] / cornell[3];
        assert!(bias_left(cornell[4] * last, last) < 0.0143 * 0.7);
        // The fur ball's ratios grow with depth: the largest is the last.
        let fur = [0.155, 0.058, 0.023];
        assert!((decay_ratio(&fur) - 0.023 / 0.058).abs() < 1e-12);
    }

    /// A later bounce's bias is the one before's scaled by the ratio of their mean relative contributions, at most
    /// 1, and unknown when the one before has no positive mean.
    #[test]
    fn a_later_bounce_is_scaled_by_the_ratio_of_relative_means() {
        let bounce = |relative_mean| Bounce {
            mean: 1.0,
            standard_error: 1.0,
            relative_mean,
            pooled_mean: 0.0,
        };
        let b = next_bias(0.1, &bounce(0.05), &bounce(0.02)).unwrap();
        assert!((b - 0.04).abs() < 1e-12, "{b}");
        assert_eq!(next_bias(0.1, &bounce(0.05), &bounce(0.08)), Some(0.1));
        assert_eq!(next_bias(0.1, &bounce(0.05), &bounce(-0.01)), Some(0.0));
        assert_eq!(next_bias(0.1, &bounce(0.0), &bounce(0.02)), None);
    }

    /// The light/material candidates are compared on every second window of every second row of the grid: a
    /// quarter spread over the whole film (not two columns of it), or every window where that leaves fewer than 16.
    #[test]
    fn the_sample_candidates_are_compared_on_a_spread_quarter_of_the_windows() {
        let ws = windows(128, 128);
        let picked = comparison_windows(&ws);
        assert_eq!(picked.len(), 16);
        let xs: std::collections::BTreeSet<u32> = picked.iter().map(|&i| ws[i].x0).collect();
        let ys: std::collections::BTreeSet<u32> = picked.iter().map(|&i| ws[i].y0).collect();
        assert_eq!((xs.len(), ys.len()), (4, 4), "{picked:?}");
        // 640x480: 28 x 21 windows, 14 x 11 picked.
        assert_eq!(comparison_windows(&windows(640, 480)).len(), 14 * 11);
        // 96x72: 7 x 5 windows, a quarter would be 12: all of them.
        assert_eq!(comparison_windows(&windows(96, 72)).len(), 35);
    }

    /// A subset of a pilot's windows and the rest merge back into the pilot: pixels and rays, in window order.
    #[test]
    fn a_pilot_split_into_windows_merges_back() {
        let rays = |k: u64| RayCounts {
            camera: k,
            shadow: 2 * k,
            ..RayCounts::default()
        };
        let full = Pilot {
            rgb: (0..12).map(|i| [i as f32, 0.0, 1.0]).collect(),
            var: (0..12).map(|i| [0.0, i as f32, 0.0]).collect(),
            seconds: 3.0,
            samples: 48,
            rays: rays(6),
            windows: (0..3).map(|w| (4 * w, 4, rays(w as u64 + 1))).collect(),
        };
        let a = full.subset(&[0, 2]);
        assert_eq!(a.rgb.len(), 8);
        assert_eq!(a.rgb[4][0], 8.0);
        assert_eq!(a.rays, rays(4));
        let b = full.subset(&[1]);
        let merged = Pilot::merge(&a, &[0, 2], &b, 3);
        assert_eq!(merged.rgb, full.rgb);
        assert_eq!(merged.var, full.var);
        assert_eq!(merged.rays, full.rays);
        assert_eq!(merged.samples, full.samples);
        assert!((merged.seconds - full.seconds).abs() < 1e-12);
        assert_eq!(merged.windows, full.windows);
    }

    /// A `w`×`h` window at the film's corner.
    fn region(w: u32, h: u32) -> Region {
        Region {
            x0: 0,
            y0: 0,
            x1: w,
            y1: h,
        }
    }

    /// Pixels whose estimates are skewed (mostly a little dim, now and then bright, as where few samples find a
    /// bright path): each seed's pixel value 0.9 with probability 0.9 and 1.9 with 0.1, mean 1 and variance 0.09
    /// (relMSE 0.089, as noisy as the shipped scenes' pilots), so the true relMSE of one estimate is 0.09 / 1.01.
    /// Over the pair's own means a pixel whose seeds differ (one bright) divides its error by the bright mean:
    /// 1² / 2 / (1.4² + 0.01) with probability 0.18, 0.51 of the truth. Over its neighbours' means (3×3 in 4×4
    /// windows, both seeds) the pixel's own samples do not divide, and only the neighbours' noise is left (3 to
    /// 8 pixels: 1/(m̃² + 0.01) is convex, so it reads 2–5 % high).
    #[test]
    fn a_pixels_own_bright_samples_do_not_divide_its_error() {
        let mut rng = rand_pcg::Pcg32::new(7, 7);
        let windows = vec![region(4, 4); 400];
        let mut draw = || -> Vec<[f32; 3]> {
            (0..16 * windows.len())
                .map(|_| std::array::from_fn(|_| if rng.random::<f32>() < 0.1 { 1.9 } else { 0.9 }))
                .collect()
        };
        let pair = with_variances(draw(), draw(), 0.0);
        let truth = 0.09 / 1.01;
        let own = pair.rel_mse() / truth;
        let neighbours = pair
            .rel_mse_over_means(&neighbour_means(pair.rgb(), &windows))
            .0
            / truth;
        assert!((0.45..0.57).contains(&own), "own means: {own} of the truth");
        assert!(
            (0.95..1.1).contains(&neighbours),
            "neighbours' means: {neighbours} of the truth"
        );
    }

    /// A pair of pilot estimates from two seeds' pixel values, every pixel's sample variance `v`.
    fn with_variances(a: Vec<[f32; 3]>, b: Vec<[f32; 3]>, v: f32) -> Pair {
        let pilot = |rgb: Vec<[f32; 3]>| Pilot {
            windows: vec![(0, rgb.len(), RayCounts::default())],
            var: vec![[v; 3]; rgb.len()],
            rgb,
            seconds: 0.0,
            samples: 0,
            rays: RayCounts::default(),
        };
        Pair([pilot(a), pilot(b)])
    }

    /// A shorter path's means are darker than the longest's by the bounces it leaves out, so its noise reads
    /// lower over the longest's means: pixels 1 ± d against 1.2 ± d give (1 + 0.01) / (1.44 + 0.01); a pair
    /// against itself 1; never above 1.
    #[test]
    fn a_darker_path_reads_less_noise_over_the_longest_paths_means() {
        let d = 0.1f32;
        let pixels = |m: f32, sign: f32| vec![[m + sign * d; 3]; 64];
        let short = with_variances(pixels(1.0, 1.0), pixels(1.0, -1.0), 0.0);
        let long = with_variances(pixels(1.2, 1.0), pixels(1.2, -1.0), 0.0);
        let f = darkening_of(&short, &long);
        let expected = 1.01 / 1.45;
        assert!((f - expected).abs() < 1e-4, "{f} against {expected}");
        assert!((darkening_of(&short, &short) - 1.0).abs() < 1e-12);
        assert_eq!(darkening_of(&long, &short), 1.0);
    }

    /// The sampler's gain from the pilot pair alone: G = mean s² / (4 relMSE(4)) = (4g − 1) / 3. Pixels 1 ± d
    /// (relMSE 2d² / 1.01 per channel) with s² = 8d² · 7/3 give G = 7/3, g = 2; lowered by its standard errors but
    /// never under 1; and 1 where the pair is noisier than its samples' variance predicts (nothing to credit).
    #[test]
    fn the_sampler_gain_compares_the_pixels_sample_variance_with_the_pair() {
        let d = 0.1f32;
        let pair = |variance: f32| {
            let v = |s: f32| -> Vec<[f32; 3]> {
                (0..400)
                    .map(|i| [1.0 + s * d * (1.0 + 0.1 * ((i % 3) as f32 - 1.0)); 3])
                    .collect()
            };
            with_variances(v(1.0), v(-1.0), variance)
        };
        // The ±10 % spread of d makes the mean of d² 1.00667 d².
        let two = pair(8.0 * d * d * 1.00667 * 7.0 / 3.0);
        let (exact, point) = sampler_gain(&two, 0.0);
        assert!(
            (point - 2.0).abs() < 0.01 && exact == point,
            "{point} {exact}"
        );
        let (lowered, _) = sampler_gain(&two, 2.0);
        assert!(lowered < point && lowered >= 1.0, "{lowered}");
        let noisy = pair(8.0 * d * d * 0.5);
        let (gain, point) = sampler_gain(&noisy, 0.0);
        assert!(point < 1.0 && gain == 1.0, "{point} {gain}");
    }

    /// Pilot pixels of a bounce found by few samples (each of 4 samples hits with probability 0.3, and a hit
    /// carries the bounce, as on dense fur): the pixel's own mean rises with its bounce, so a denominator from it
    /// underestimates the bias; the neighbours' does not. Pooled over the 3×3 neighbourhoods, the products read
    /// the same bias with less than half the spread.
    #[test]
    fn a_bounce_found_by_few_samples_is_not_underestimated() {
        let ws = windows(256, 256);
        let pixels: usize = ws.iter().map(|r| (r.width() * r.height()) as usize).sum();
        let mut state = 0x1234_5678_u64;
        let mut uniform = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            ((state >> 40) as f64) / f64::from(1u32 << 24)
        };
        let (p, beta) = (0.3, 0.2);
        let mut render = || {
            let (mut before, mut after) = (Vec::new(), Vec::new());
            for _ in 0..pixels {
                let (mut b, mut a) = ([0.0f32; 3], [0.0f32; 3]);
                for c in 0..3 {
                    let (mut x, mut d) = (0.0, 0.0);
                    for _ in 0..PILOT_SPP {
                        if uniform() < p {
                            x += 1.0 / p;
                            d += beta / p * 2.0 * uniform();
                        }
                    }
                    let n = f64::from(PILOT_SPP);
                    b[c] = (x / n) as f32;
                    a[c] = ((x + d) / n) as f32;
                }
                before.push(b);
                after.push(a);
            }
            (before, after)
        };
        let truth = beta * beta / ((1.0 + beta) * (1.0 + beta) + 0.01);
        // Six independent pilot pairs: the pixel products and the pooled ones ([`pooled_bias`]) read the same
        // squared bias, the pooled with far less spread between pairs.
        let pairs: Vec<Bounce> = (0..6)
            .map(|_| {
                let (b0, a0) = render();
                let (b1, a1) = render();
                bounce_bias([&b0, &b1], [&a0, &a1], &ws)
            })
            .collect();
        let spread = |f: fn(&Bounce) -> f64| {
            let (m, _) = mean_and_error(pairs.iter().map(f));
            let var = pairs.iter().map(|b| (f(b) - m).powi(2)).sum::<f64>() / 5.0;
            (m, var.sqrt())
        };
        let (pixel_mean, pixel_spread) = spread(|b| b.mean);
        let (pooled_mean, pooled_spread) = spread(|b| b.pooled_mean);
        assert!(
            (pooled_mean / truth - 1.0).abs() < 0.15,
            "pooled {pooled_mean:.4e} against {truth:.4e}"
        );
        assert!(
            pooled_spread < 0.5 * pixel_spread,
            "pooled {pooled_mean:.4e} ± {pooled_spread:.1e}, pixel products {pixel_mean:.4e} ± {pixel_spread:.1e} \
             (mean ± spread over six pairs)"
        );
        let (b0, a0) = render();
        let (b1, a1) = render();
        let Bounce {
            mean,
            standard_error: error,
            ..
        } = bounce_bias([&b0, &b1], [&a0, &a1], &ws);
        // The same products over each pixel's own mean (the estimator before): far under the truth.
        let own = (0..pixels)
            .flat_map(|i| (0..3).map(move |c| (i, c)))
            .map(|(i, c)| {
                let (da, db) = (
                    f64::from(a0[i][c] - b0[i][c]),
                    f64::from(a1[i][c] - b1[i][c]),
                );
                let m = 0.5 * f64::from(a0[i][c] + a1[i][c]);
                da * db / (m * m + 0.01)
            })
            .sum::<f64>()
            / (3 * pixels) as f64;
        assert!(
            own < 0.8 * truth,
            "the model shows the failure: {own:.4e} against {truth:.4e}"
        );
        assert!(
            mean > 0.9 * truth && mean < 1.3 * truth,
            "{mean:.4e} ± {error:.1e} against {truth:.4e}"
        );
    }
}
