//! Adaptive sampling: camera samples in rounds, more where the image is noisier, until the estimated
//! error is under the target, between a minimum and a maximum per pixel.
//!
//! # The image-level rule (what `--quality auto` uses, and the renderer runs)
//!
//! The frame's target is a relative RMSE over the image ([`crate::quality`]), so the rule stops on the *image's*
//! estimated noise, not each pixel's. A pixel's beauty is the mean of its n samples; its per-sample relative variance
//! is v = mean over RGB of s² / (x̄² + 0.01) (s² each channel's sample variance, x̄ its running mean standing in for
//! the converged value), so its contribution to the image's relMSE is v / n, and the estimated image relMSE is the
//! mean of v / n over the region's pixels. Every pixel first takes `min` samples; then, at each round boundary, if
//! the estimate is over target², the samples go where they buy the most: minimising Σ v / n for a given Σ n gives n ∝
//! √v (a Lagrange multiplier), so each pixel's goal is n* = √v · Σ √v / (target² · N) (water-filled: pixels at `max`,
//! or already past their goal, are held and the rest share what is left of the budget). With a cost model
//! ([`Schedule::cost`], what `--quality auto` sets) the samples are weighed by what they cost: a pixel's c is the
//! mean predicted CPU time of its samples (from the rays each traced, weighed per kind, never the clock), and
//! minimising the cost Σ c n for the same Σ v / n gives n ∝ √(v/c), goal n* = √(v/c) · Σ √(v c) / (target² · N). A
//! pixel of the fur's edge, noisy and cheap (many of its camera rays miss), then gets more of the samples, and one
//! deep in the fur, where every sample traces a full path, fewer. A round takes every pixel to its goal, at most
//! doubling its count (its v is re-estimated from more samples before it grows further). The region is done when the
//! estimate meets the budget or no pixel may grow.
//!
//! Allocation and stop read different variances. Who gets the samples reads each pixel's neighbours' v, never its
//! own ([`neighbour_shape`](schedule::neighbour_shape)): a count that follows the pixel's own samples
//! biases its mean low where rare bright paths carry the light (11 % dark on a generated wavy patch whose light is
//! mostly in deep bounces), and its neighbours' v is also the best prior a hair-edge pixel whose first samples
//! missed the strand has. The stop, and how many samples a round hands out in that shape, read the pixels' **own**
//! v (mean of v / n, unbiased for the mean relMSE of the pixels' means now that n does not follow v). The
//! neighbours' v in the stop would overstate the noise where noisy pixels neighbour constant ones: on the default
//! scene at 0.05 a stop of that kind delivered 0.036 against an aim of 0.0424 (1.36× under in relMSE), 1.5–2.1× on
//! straight hair under the city map.
//!
//! # The stop reads the frame's own samples twice
//!
//! s² / n is the variance of a mean of *independent* samples; the sampler's Owen-scrambled Sobol samples converge
//! faster, by a gain that grows with n at a rate that differs by scene (slow on the fur ball, fast under the city
//! map). The model's estimate divides by a gain curve extrapolated from the pilots' 4 spp
//! ([`Schedule::gain`]), and that extrapolation is the model's largest error: it reads the fur ball, the sunset
//! map and the Cornell box up to 8 % low in relative RMSE, so that a margin for them would make the scenes where it
//! is right over-deliver (`docs/measured/auto.md`). So the stop also reads each pixel's **halves**
//! ([`Convergence::split_rel_mse`]): the means of its first P/2 and next P/2 samples (P the largest power of two
//! ≤ n), whose squared difference over 4 is the variance of the mean of P samples *or more* for any sampler that
//! converges no slower than independent samples — this frame's own convergence at the counts it reached, no
//! gain model. The image's estimate is the larger of the model's and the halves' means over the pixels (the
//! halves, one pair per pixel, are noisy per pixel and exact on average; the model floors them where a pixel's
//! halves happen to agree), and when the halves read more, the round's samples are counted at their level.
//! Measured on the seven shipped scenes (two-seed renders of auto's frame at both targets): the frames' noise comes
//! out 3–12 % under the stop's aim in relative RMSE, never over; with the model alone, and no margins, frames miss
//! the target itself by up to 8 %.
//!
//! Pixels that see only the **background** (every sample's camera ray hit nothing: the environment through the
//! pixel filter) are read apart ([`Schedule::split_per_pixel`]): their samples differ only by where they fall in the
//! pixel, and the stratified sampler converges on them at about m^−1.6, not the hair's m^−1.1, so both estimates
//! above read them 2–4× too noisy. Their halves are divided by 2^α − 1, α the order the background pixels' own
//! quarters against their halves measure (one octave below, pooled over the background) but at most 4/3
//! ([`BACKGROUND_MAX_ORDER`]), and the model takes the same for them.
//!
//! Against the per-pixel rule ([`Schedule::next_total`]) this spends nothing on pixels whose error is already small
//! relative to the image's, and lets a bright noisy pixel exceed the others: the image's error, not the worst
//! pixel's, meets the target. What it cannot see (like any rule reading the samples) is a rare bright path that
//! none of a pixel's first samples found: that pixel's v is 0 and it keeps `min`.
//!
//! # Determinism, threads and bands
//!
//! A pixel's samples are drawn in index order 0, 1, 2, … from its own sample stream. The decisions are made
//! between rounds, after every pixel of the round is done, from all the region's pixels in row-major order (sums in
//! f64 in that order), so neither the thread count nor the 32² work tiles change them: the same image for any
//! thread count. A region rendered alone (`--crop`, `--tile I/N`) decides from **its own pixels**: each band meets
//! the target by itself (so the merged frame, whose relMSE is the pixel-weighted mean of the bands', meets it
//! too), but its pixels are not bit-identical to the same pixels of a full-frame render, as they are at a fixed
//! spp.
//!
//! # The per-pixel rule ([`Schedule::next_total`], the baseline the tests compare against)
//!
//! Each pixel alone: e² = mean over RGB of (s²/n) / (x̄² + 0.01) with the variance at its 95 % **upper confidence
//! bound** (n − 1) s² / χ²₀.₀₅(n − 1) (Wilson–Hilferty), in doubling rounds min, 2·min, … up to max until e is
//! under the target. It needs no barrier, but sends nearly every hair pixel to the maximum. The renderer does not
//! run it: the tests that compare the rules run it on synthetic pixels, and on a frame through a sampling strategy
//! of their own ([`crate::render::Request::sampling`]).

mod convergence;
mod schedule;
#[cfg(test)]
mod tests;

pub use convergence::Convergence;
pub(crate) use schedule::neighbourhood;
pub use schedule::{NoiseEstimate, Schedule, BACKGROUND_MAX_ORDER};

use std::ops::Range;

use rayon::prelude::*;

use super::film::{Accumulate, PixelSums, Tile};
use super::integrator::{PathSample, RayCost, RayCounts};
use super::Region;

/// One pixel's accumulators between rounds.
#[derive(Default)]
struct Pixel {
    sums: PixelSums,
    stats: Convergence,
    taken: u32,
}

/// One work tile's pixels (row-major inside the tile) between rounds.
struct Work {
    tile: Tile,
    pixels: Vec<Pixel>,
    counts: RayCounts,
}

/// What takes a pixel's samples: handed each sample in index order with the rays it traced.
pub(super) type Sink<'s> = &'s mut dyn FnMut(u32, &PathSample, &RayCounts);

impl Work {
    /// Takes each pixel's samples up to `goal(x, y)`, in index order.
    fn grow(
        &mut self,
        goal: impl Fn(u32, u32) -> u32,
        cost: Option<RayCost>,
        samples: &(impl Fn(u32, u32, Range<u32>, &mut RayCounts, Sink) + Sync),
    ) {
        let t = &self.tile;
        let mut k = 0;
        for y in t.y0..t.y1 {
            for x in t.x0..t.x1 {
                let p = &mut self.pixels[k];
                k += 1;
                let g = goal(x, y);
                if p.taken >= g {
                    continue;
                }
                samples(x, y, p.taken..g, &mut self.counts, &mut |_, s, rays| {
                    if let Some(cost) = &cost {
                        p.stats.add_cost(cost.seconds(rays));
                    }
                    if s.beauty.is_finite() {
                        if s.alpha > 0.0 {
                            p.stats.add(s.beauty);
                        } else {
                            p.stats.add_uncovered(s.beauty);
                        }
                    }
                    p.sums.add(s);
                    p.taken += 1;
                });
            }
        }
    }
}

/// The pixel loop of the image-level rule over `tiles` (work tiles of `region`, made by `new_tile`): a first round to
/// `schedule.min` everywhere, then rounds decided by [`Schedule::next_round`] from the whole region's pixels in
/// row-major order, each after every tile of the round before is done (rayon's join is the barrier). `samples`
/// draws a range of a pixel's camera samples, `centre` writes its centre-ray channels. Once `cancelled` holds no new
/// tile of the first round starts and no further round does (the tiles rendered keep the samples they took).
#[allow(clippy::too_many_arguments)]
pub(super) fn render_rounds(
    tiles: &[(u32, u32)],
    region: Region,
    schedule: Schedule,
    progress: &indicatif::ProgressBar,
    new_tile: &(impl Fn(u32, u32) -> Tile + Sync),
    samples: &(impl Fn(u32, u32, Range<u32>, &mut RayCounts, Sink) + Sync),
    centre: &(impl Fn(u32, u32, &mut [f32], &mut RayCounts) + Sync),
    cancelled: &(impl Fn() -> bool + Sync),
) -> (Vec<(Tile, RayCounts)>, Option<NoiseEstimate>) {
    let mut work: Vec<Work> = tiles
        .par_iter()
        .filter_map(|&(tx, ty)| {
            if cancelled() {
                return None;
            }
            let tile = new_tile(tx, ty);
            let n = ((tile.x1 - tile.x0) * (tile.y1 - tile.y0)) as usize;
            let mut w = Work {
                tile,
                pixels: (0..n).map(|_| Pixel::default()).collect(),
                counts: RayCounts::default(),
            };
            w.grow(|_, _| schedule.min, schedule.cost, samples);
            progress.inc(1);
            Some(w)
        })
        .collect();
    let width = region.width() as usize;
    let index = move |x: u32, y: u32| (y - region.y0) as usize * width + (x - region.x0) as usize;
    let pixels = width * region.height() as usize;
    let mut round = 0;
    // The stop's reading of the region after the last round (none if cancelled or a tile is missing).
    let mut estimate = None;
    while work.len() == tiles.len() && !cancelled() {
        let mut taken = vec![0u32; pixels];
        let mut stats = vec![Convergence::default(); pixels];
        for w in &work {
            let t = &w.tile;
            let mut k = 0;
            for y in t.y0..t.y1 {
                for x in t.x0..t.x1 {
                    taken[index(x, y)] = w.pixels[k].taken;
                    stats[index(x, y)] = w.pixels[k].stats;
                    k += 1;
                }
            }
        }
        let Some(next) = schedule.next_round(round, width, &taken, &stats) else {
            estimate = Some(schedule.noise_estimate(width, &taken, &stats));
            break;
        };
        round += 1;
        progress.set_prefix(format!("round {}", round + 1));
        progress.set_length(progress.length().unwrap_or(0) + tiles.len() as u64);
        work.par_iter_mut().for_each(|w| {
            w.grow(|x, y| next[index(x, y)], schedule.cost, samples);
            progress.inc(1);
        });
    }
    let tiles = work
        .into_par_iter()
        .map(|mut w| {
            let t = &mut w.tile;
            let mut k = 0;
            for y in t.y0..t.y1 {
                for x in t.x0..t.x1 {
                    let p = &w.pixels[k];
                    k += 1;
                    t.set_pixel(x, y, |pixel| {
                        p.sums.write(p.taken, pixel);
                        centre(x, y, pixel, &mut w.counts);
                    });
                }
            }
            (w.tile, w.counts)
        })
        .collect();
    (tiles, estimate)
}
