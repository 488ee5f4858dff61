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
//! # Under a splatting film
//!
//! A splatted pixel is the filter-weighted mean of its neighbours' samples ([`super::splat`]), so its noise is not
//! its own samples' alone. Each pixel still keeps the statistics of its own samples, and the stop reads them times
//! the pixel's **share** of the splatted image's noise ([`Convergence::splatted`],
//! [`SplatFilter::noise_shares`]: 0.32 inside the frame for the 3-pixel Gaussian): for independent samples the
//! splatted image's mean variance is the mean over source pixels of share × (variance of the pixel's mean), where
//! brightness varies slowly. Who gets the samples is unchanged (the share is the same for every pixel inside the
//! frame). Each source pixel keeps its splats towards its targets between rounds ([`SourceSums`]); after the last
//! round they are summed exactly as at a fixed spp, each source's divided by its own count first, so that a pixel
//! which took more samples weighs no more in its neighbours' means: the weighted mean converges to the filter's
//! image whatever the counts. A region rendered alone also renders its margin pixels, each at its nearest region
//! pixel's count.
//!
//! Measured on the default scene at 256×192 (`--quality auto`, seeds 1 and 2, against a 1024-spp path-12
//! reference, `docs/measured/auto.md`): at target 0.05 the splatted frame took a mean 7.3 spp and 1.4 s,
//! delivering 0.041, where filter importance sampling took 21.2 spp and 4.0 s for 0.040; the stop read 0.049 for
//! both.
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

use super::driver::Rendered;
use super::film::{self, Accumulate, PixelSums, Tile};
use super::integrator::{PathSample, RayCost, RayCounts};
use super::splat::{self, NoiseShares, SourceSums, SplatFilter, Summed};
use super::Region;

/// One pixel's accumulators between rounds.
#[derive(Default)]
struct Pixel {
    sums: PixelSums,
    stats: Convergence,
    taken: u32,
}

/// A splatting film's state between rounds ([`super::splat`]): the film's filter, what it sums, and each pixel's
/// share of the image's noise.
pub(super) struct Splatting<'a> {
    pub(super) filter: SplatFilter,
    pub(super) summed: &'a Summed,
    pub(super) shares: NoiseShares,
    /// The frame's size: margin pixels outside a region are inside it.
    pub(super) size: [u32; 2],
}

/// A work tile's source pixels under a splatting film ([`splat::sources`]: its own and its margin), each one's
/// splats towards its targets kept between rounds, and its count.
struct Sources {
    at: Vec<(u32, u32)>,
    /// Each source's [`SourceSums::sums`], one block after another.
    sums: Vec<f32>,
    taken: Vec<u32>,
}

/// One work tile's pixels (row-major inside the tile) between rounds.
struct Work {
    tile: Tile,
    pixels: Vec<Pixel>,
    counts: RayCounts,
    /// Under a splatting film, the tile's sources.
    sources: Option<Sources>,
}

/// What takes a pixel's samples: handed each sample in index order with the rays it traced.
pub(super) type Sink<'s> = &'s mut dyn FnMut(u32, &PathSample, &RayCounts);

/// Adds one sample to a pixel's statistics (and its cost).
#[inline]
fn record(stats: &mut Convergence, s: &PathSample, rays: &RayCounts, cost: Option<&RayCost>) {
    if let Some(cost) = cost {
        stats.add_cost(cost.seconds(rays));
    }
    if s.beauty.is_finite() {
        if s.alpha > 0.0 {
            stats.add(s.beauty);
        } else {
            stats.add_uncovered(s.beauty);
        }
    }
}

impl Work {
    /// Takes each pixel's samples up to `goal(x, y)`, in index order; under a splatting film (`splatting`) a margin
    /// pixel of `region` takes its home pixel's goal ([`splat::home_of`]).
    fn grow(
        &mut self,
        goal: impl Fn(u32, u32) -> u32,
        cost: Option<RayCost>,
        samples: &(impl Fn(u32, u32, Range<u32>, &mut RayCounts, Sink) + Sync),
        splatting: Option<(&Splatting, Region)>,
    ) {
        let t = &self.tile;
        let (x0, y0, x1, y1) = (t.x0, t.y0, t.x1, t.y1);
        let own = |x: u32, y: u32| {
            ((x0..x1).contains(&x) && (y0..y1).contains(&y))
                .then(|| ((y - y0) * (x1 - x0) + (x - x0)) as usize)
        };
        match (&mut self.sources, splatting) {
            (Some(sources), Some((sp, region))) => {
                let mut source = SourceSums::new(sp.filter, sp.summed.clone());
                let block = source.sums().len();
                for (k, &(x, y)) in sources.at.iter().enumerate() {
                    let (hx, hy) = splat::home_of(x, y, region);
                    let g = goal(hx, hy);
                    let taken = sources.taken[k];
                    if taken >= g {
                        continue;
                    }
                    let stored = &mut sources.sums[k * block..(k + 1) * block];
                    source.load(stored);
                    let mut pixel = own(x, y).map(|i| &mut self.pixels[i]);
                    samples(x, y, taken..g, &mut self.counts, &mut |_, s, rays| {
                        if let Some(p) = pixel.as_mut() {
                            record(&mut p.stats, s, rays, cost.as_ref());
                            p.taken += 1;
                        }
                        source.add(s);
                    });
                    stored.copy_from_slice(source.sums());
                    sources.taken[k] = g;
                }
            }
            _ => {
                let mut k = 0;
                for y in y0..y1 {
                    for x in x0..x1 {
                        let p = &mut self.pixels[k];
                        k += 1;
                        let g = goal(x, y);
                        if p.taken >= g {
                            continue;
                        }
                        samples(x, y, p.taken..g, &mut self.counts, &mut |_, s, rays| {
                            record(&mut p.stats, s, rays, cost.as_ref());
                            p.sums.add(s);
                            p.taken += 1;
                        });
                    }
                }
            }
        }
    }

    /// The tile's pixels written (`centre` writes their centre-ray channels), with the splats it gave pixels it
    /// could not finish.
    fn finish(
        mut self,
        region: Region,
        splatting: Option<&Splatting>,
        centre: &(impl Fn(u32, u32, &mut [f32], &mut RayCounts) + Sync),
    ) -> Rendered {
        let counts = &mut self.counts;
        let t = &mut self.tile;
        let edges = match (self.sources, splatting) {
            (Some(sources), Some(sp)) => {
                let mut scratch = splat::Scratch::default();
                let mut splats =
                    splat::TileSplats::new(&mut scratch, t, region, sp.size, sp.filter, sp.summed);
                let mut source = SourceSums::new(sp.filter, sp.summed.clone());
                let block = source.sums().len();
                for (k, &(x, y)) in sources.at.iter().enumerate() {
                    let n = sources.taken[k];
                    if n == 0 {
                        continue;
                    }
                    // Each source counts as the mean of its own samples: a pixel that took more samples than its
                    // neighbour weighs no more in their targets (the filter's image, whatever the counts).
                    source.load(&sources.sums[k * block..(k + 1) * block]);
                    splats.add(x, y, &source, 1.0 / n as f32);
                }
                let taken: Vec<u32> = self.pixels.iter().map(|p| p.taken).collect();
                splats.finish(t, sp.summed, &taken, |x, y, n, pixel| {
                    pixel[film::channel("spp")] = n as f32;
                    centre(x, y, pixel, counts);
                })
            }
            _ => {
                let mut k = 0;
                for y in t.y0..t.y1 {
                    for x in t.x0..t.x1 {
                        let p = &self.pixels[k];
                        k += 1;
                        t.set_pixel(x, y, |pixel| {
                            p.sums.write(p.taken, pixel);
                            centre(x, y, pixel, counts);
                        });
                    }
                }
                Vec::new()
            }
        };
        (self.tile, self.counts, edges)
    }
}

/// The pixel loop of the image-level rule over `tiles` (work tiles of `region`, made by `new_tile`): a first round to
/// `schedule.min` everywhere, then rounds decided by [`Schedule::next_round`] from the whole region's pixels in
/// row-major order, each after every tile of the round before is done (rayon's join is the barrier). `samples`
/// draws a range of a pixel's camera samples, `centre` writes its centre-ray channels. Under a splatting film
/// (`splatting`) each tile also renders its margin sources, keeps every source's splats between rounds and sums them
/// at the end, each source as the mean of its own samples; the stop reads each pixel's share of the splatted image's
/// noise ([`Convergence::splatted`]). Once `cancelled` holds no new tile of the first round starts and no further
/// round does (the tiles rendered keep the samples they took).
#[allow(clippy::too_many_arguments)]
pub(super) fn render_rounds(
    tiles: &[(u32, u32)],
    region: Region,
    schedule: Schedule,
    splatting: Option<&Splatting>,
    progress: &indicatif::ProgressBar,
    new_tile: &(impl Fn(u32, u32) -> Tile + Sync),
    samples: &(impl Fn(u32, u32, Range<u32>, &mut RayCounts, Sink) + Sync),
    centre: &(impl Fn(u32, u32, &mut [f32], &mut RayCounts) + Sync),
    cancelled: &(impl Fn() -> bool + Sync),
) -> (Vec<Rendered>, Option<NoiseEstimate>) {
    let splat_in = splatting.map(|s| (s, region));
    let mut work: Vec<Work> = tiles
        .par_iter()
        .filter_map(|&(tx, ty)| {
            if cancelled() {
                return None;
            }
            let tile = new_tile(tx, ty);
            let mut pixels: Vec<Pixel> = Vec::new();
            for y in tile.y0..tile.y1 {
                for x in tile.x0..tile.x1 {
                    let mut p = Pixel::default();
                    if let Some(sp) = splatting {
                        p.stats.splatted(sp.shares.at(x, y) as f32);
                    }
                    pixels.push(p);
                }
            }
            let sources = splatting.map(|sp| {
                let at: Vec<(u32, u32)> =
                    splat::sources(&tile, region, sp.size, sp.filter.reach()).collect();
                let block = SourceSums::len(sp.filter, sp.summed);
                Sources {
                    sums: vec![0.0; at.len() * block],
                    taken: vec![0; at.len()],
                    at,
                }
            });
            let mut w = Work {
                tile,
                pixels,
                counts: RayCounts::default(),
                sources,
            };
            w.grow(|_, _| schedule.min, schedule.cost, samples, splat_in);
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
            w.grow(|x, y| next[index(x, y)], schedule.cost, samples, splat_in);
            progress.inc(1);
        });
    }
    let tiles = work
        .into_par_iter()
        .map(|w| w.finish(region, splatting, centre))
        .collect();
    (tiles, estimate)
}
