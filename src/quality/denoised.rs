//! `--quality auto --denoise`: the samples per pixel for a target that applies to the **denoised** frame, measured
//! on the frame itself.
//!
//! # Why not the pilots
//!
//! The pilots ([`super::pilot`]) render 4² windows: enough to measure a pixel's noise, far too small to denoise
//! (the filter reads a neighbourhood tens of pixels wide, so a window's denoised error says nothing of the
//! frame's). And the denoised error does not fall as 1/spp: it is the noise the filter leaves plus the detail it
//! smooths away, and the second shrinks only as the input gets cleaner (`docs/measured/denoise.md`: on straight
//! hair under the city map the denoised RMSE falls as spp^−0.17…−0.42 between 16 and 256 spp, where the noisy
//! frame's falls as spp^−0.5). So the pilots still decide everything else (curves, shadows, path length, light
//! and material samples, the bias the target leaves for noise), and the samples per pixel are found by rendering
//! the frame in rounds and measuring its denoised error after each.
//!
//! # The estimate: two halves, one denoised
//!
//! Each round doubles the frame's samples, so the frame after a round at N spp is the mean of two halves A
//! (N/2 samples, everything rendered before) and B (N/2 samples, the round's new block), whose noises are
//! independent: every block is drawn under a seed of its own (see below). With r the converged image and
//! w = 1 / (r² + 0.01) the target's weight ([`crate::quality`]), for the half A denoised, D(A):
//!
//! E w (D(A) − B)² = E w (D(A) − r)² + E w (B − r)²  (B's error is independent of D(A)'s and has mean 0), and
//! E w (A − B)² = 2 E w (B − r)², so
//!
//! **e²(D(A)) = E w (D(A) − B)² − ½ E w (A − B)²**,
//!
//! an unbiased estimate of the denoised half's relMSE against the converged image without any reference: the
//! filter's smoothing counts in it as well as its leftover noise. w is taken from D(A) (smooth, so its noise does
//! not bias the weights). The estimate's standard error over 16² tiles of pixels (the filter's output is correlated
//! between neighbouring pixels, so single pixels are not independent draws) gives an upper bound, the estimate plus
//! two standard errors, and the stop reads that bound.
//!
//! The frame denoised is the mean of both halves, at twice a half's samples. Its error is predicted from the half's
//! as e²(N) = e²(N/2) · 2^−p, the order p measured between the last two rounds' halves, clamped to [0,
//! [`MAX_ORDER`]], and taken as 0 after the first round, when there is only one: the first stop can only trust
//! the half. The frame's estimate is over its own
//! means, as the adaptive stop's is, and is scaled by the pilots' darkening to be over the converged image's
//! ([`super::pilot::PilotPlan::darkening`]).
//!
//! The halves must be independent. Two consecutive blocks of one Owen-scrambled Sobol sequence are not: their errors
//! are negatively correlated (the whole is better stratified than either half), so E w (A − B)² exceeds twice B's
//! own error and the estimate reads low by the covariance. Drawn that way, straight hair under the city map at
//! 600×800 measured e² = −0.0022 ± 0.0007 after the first round (2-spp halves) and stopped at 4 spp for a target
//! of 0.02 that the pilots put at ~330 spp undenoised. So each block is samples 0 .. n of the pixel's sequence under
//! a seed of its own ([`block_seed`]): each block is as well stratified as a render of its size, and blocks are
//! independent of each other. The frame gives up what one longer sequence would gain over independent blocks
//! (the sampler gain auto prints: 1.06 at 4 spp on the default scene, 1.22–1.24 on straight hair under the city).
//!
//! # The rounds
//!
//! From `first` samples per pixel (auto's `min_spp` raised to 4 and rounded up to a power of two), doubling until the frame's predicted denoised error is within the noise
//! budget the pilots left ([`super::pilot::PilotPlan::noise_budget`]: the target less the bias of the bounces left
//! out and of the approximations kept), or the next round would pass `quality.max_spp`. Every sample rendered is in
//! the frame: a round renders only the new half, and the rounds cost one extra denoise each (D(A); the frame's
//! own denoise is the one `--denoise` runs anyway). The frame after the rounds holds N samples in every pixel, from
//! blocks of 2, 2, 4, 8, … (first = 4) under their own seeds.
//!
//! The blocks are mixed channel by channel as means weighted by their samples (the `spp` channel summed): exact
//! for the beauty and every AOV that is a mean of samples, and for the centre-ray channels, which are equal in every
//! block; `shadow.Y`, a ratio of sums, becomes a weighted mean of the blocks' ratios.
//!
//! All decisions read image statistics summed in a fixed order after whole renders, and the denoiser runs on a
//! fixed thread count (the job's), so the frame is the same for any number of worker threads.

use crate::image::denoise::{self, Guide};
use crate::image::Image;
use crate::render::film::Accumulate;
use crate::render::strategy::{PixelSampling, PixelSource};
use crate::render::{Frame, RegionRender, Request};
use crate::sys::oidn::OidnError;

use super::pilot::PilotPlan;
use super::QualityConfig;

/// The relative error's floor in the target's weight 1 / (r² + 0.01) ([`crate::quality`]'s docs; the measure
/// layer's `REL_EPSILON`, which this layer may not import).
const REL_EPSILON: f64 = 0.01;

/// Side of the tiles over which [`estimate`]'s standard error is taken, pixels: wider than the filter's correlation
/// between neighbouring output pixels, small enough that a 128² frame has 64 of them.
const ESTIMATE_TILE: usize = 16;

/// The largest order p the prediction from a half to the whole frame takes (e² ∝ spp^−p). A denoised frame's error
/// falls slower than the noisy frame's order 1: its smoothing shrinks only as the input gets cleaner. Tuned on the
/// thesis frame (straight hair under the city map, 300×400): `study denoise` measured orders 0.34, 0.83 and 0.55
/// between 16, 32, 64 and 256 spp, and with the cap at 1 auto's estimate at a target of 0.02 read 0.79× the
/// measured error (64 spp). Judged on the held-out generated set (`study auto --auto-only --denoise`,
/// docs/measured/denoise.md).
pub const MAX_ORDER: f64 = 0.5;

/// Fewest samples per pixel of the first round (halves of 2).
pub const FIRST_SPP: u32 = 4;

/// The rounds' bounds and aim.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DenoisedSchedule {
    /// Samples per pixel after the first round (a power of two).
    pub first: u32,
    /// Most samples per pixel: `first` times the largest power of two within `quality.max_spp`.
    pub max: u32,
    /// The denoised frame's relative RMSE aim: the pilots' noise budget.
    pub budget: f64,
    /// Over the converged image's means per over the frame's own ([`PilotPlan::darkening`]).
    pub darkening: f64,
    /// The denoiser's guide.
    pub guide: Guide,
    /// The mean spp the pilots predicted the frame would need undenoised.
    pub noisy_spp: u32,
}

impl DenoisedSchedule {
    /// The schedule for a frame the pilots planned as `pilot` under `quality`.
    pub fn new(pilot: &PilotPlan, quality: &QualityConfig, guide: Guide) -> DenoisedSchedule {
        let first = quality.min_spp.max(FIRST_SPP).next_power_of_two();
        let mut max = first;
        while max * 2 <= quality.max_spp {
            max *= 2;
        }
        DenoisedSchedule {
            first,
            max,
            budget: pilot.noise_budget,
            darkening: pilot.darkening,
            guide,
            noisy_spp: pilot.spp,
        }
    }

    /// Bytes the rounds hold beyond a frame's own film (`settings`' film): the frame so far and the round's new
    /// block besides the block being assembled (two copies of the film), and the denoised half with the filter's
    /// input and output (three RGB buffers).
    pub fn extra_bytes(settings: &crate::render::RenderSettings) -> u64 {
        let [w, h] = settings.film.resolution;
        let rgb = (u64::from(w) * u64::from(h)).saturating_mul(3 * 4);
        crate::render::budget::film_copy_bytes(settings)
            .saturating_mul(2)
            .saturating_add(rgb.saturating_mul(3))
    }

    /// The decision auto prints for the rounds.
    pub fn decision(&self) -> super::Decision {
        super::Decision {
            key: "film.spp",
            value: format!("{}..{} spp, denoised rounds", self.first, self.max),
            reason: format!(
                "--denoise: the target applies to the denoised frame, whose error the 4x4 pilots cannot measure; \
                 the frame doubles its samples from {} until its denoised error, estimated from its two halves \
                 (one denoised, against the other) plus two standard errors, over the converged image's means \
                 (darkening {:.3}), is within the noise budget {:.4} (the target less the bias of bounces left out \
                 and approximations kept), or {} spp; undenoised, the pilots predict about {} spp on average",
                self.first, self.darkening, self.budget, self.max, self.noisy_spp
            ),
        }
    }
}

/// What one round measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Round {
    /// Samples per pixel of the frame after the round.
    pub spp: u32,
    /// The denoised half's relMSE estimate (may be negative by noise where it is small).
    pub half_rel_mse: f64,
    /// Its standard error over the pixels.
    pub half_standard_error: f64,
    /// The noisy frame's relMSE at `spp`, ¼ E w (A − B)², over the converged image's means (× darkening).
    pub noisy_rel_mse: f64,
    /// The order p the prediction used.
    pub order: f64,
    /// The denoised frame's predicted relative RMSE over the converged image (point estimate).
    pub predicted: f64,
    /// Its upper bound (the half's estimate plus two standard errors), which the stop reads.
    pub predicted_upper: f64,
}

/// The rounds of a frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Rounds {
    /// Each round, in order.
    pub rounds: Vec<Round>,
    /// Whether the last round stopped at the schedule's maximum with the aim unmet.
    pub capped: bool,
    /// The schedule's maximum samples per pixel.
    pub max: u32,
}

impl Rounds {
    /// The last round (none if the first was interrupted).
    pub fn last(&self) -> Option<&Round> {
        self.rounds.last()
    }

    /// A warning when the last round measured the noisy frame closer to the converged image than the denoised
    /// one: at that error the filter's smoothing outweighs the noise it removes, so the rounds spend samples the
    /// noisy frame would not need.
    pub fn denoiser_warning(&self) -> Option<String> {
        let r = self.last()?;
        let noisy = r.noisy_rel_mse.sqrt();
        (noisy < r.predicted).then(|| {
            format!(
                "at {} spp the noisy frame's error ({noisy:.4}) is below the denoised frame's ({:.4}): at this \
                 target the denoiser smooths more than it removes; render without --denoise",
                r.spp, r.predicted
            )
        })
    }

    /// The samples per pixel of each round, as `4 → 8 → 16`.
    pub fn path(&self) -> String {
        let spp: Vec<String> = self.rounds.iter().map(|r| r.spp.to_string()).collect();
        spp.join(" → ")
    }
}

/// The rounds of a frame and the render they made.
#[derive(Debug, Clone)]
pub struct DenoisedRender {
    /// The frame: every block mixed, with `denoised.R/G/B` added.
    pub render: RegionRender,
    /// What each round measured.
    pub rounds: Rounds,
    /// Wall seconds spent denoising (the rounds' halves and the frame).
    pub denoise_seconds: f64,
}

/// The seed of block `k` of a frame of seed `seed`: block 0 keeps the frame's own, the others are spread by the
/// golden-ratio constant (wrapping), so no two blocks of a frame share a scramble.
fn block_seed(seed: u32, k: u32) -> u32 {
    seed.wrapping_add(k.wrapping_mul(0x9e37_79b9))
}

/// A block of every pixel's samples, by index.
struct Block(std::ops::Range<u32>);

impl PixelSampling for Block {
    fn take(&self, source: &mut PixelSource<'_>, sums: &mut dyn Accumulate) -> u32 {
        source.take(self.0.clone(), |_, s, _| sums.add(s));
        self.0.len() as u32
    }
}

/// Renders `frame` as `request` says (a whole film; its settings' own spp and adaptive rule are not read) in
/// rounds per `schedule`, denoising on `threads` threads (see the module docs).
pub fn render(
    frame: &Frame,
    request: Request<'_>,
    schedule: &DenoisedSchedule,
    threads: usize,
) -> Result<DenoisedRender, OidnError> {
    let started = std::time::Instant::now();
    let mut denoise_seconds = 0.0;
    // Block k: samples 0 .. count of every pixel under a seed of its own, so that its noise is independent of
    // every other block's.
    let block = |k: u32, count: u32| {
        let mut settings = request.settings.clone();
        settings.film.seed = block_seed(settings.film.seed, k);
        frame.render(Request {
            settings: &settings,
            ..request.sampling(&Block(0..count))
        })
    };
    // The first round's two halves.
    let half = schedule.first / 2;
    let a = block(0, half);
    if !a.is_complete() {
        return Ok(interrupted(a, Vec::new(), schedule, denoise_seconds));
    }
    let mut b = block(1, half);
    let mut blocks = 2;
    if !b.is_complete() {
        b.image = a.image;
        return Ok(interrupted(b, Vec::new(), schedule, denoise_seconds));
    }
    let mut a = a;
    let mut rounds: Vec<Round> = Vec::new();
    let mut n = schedule.first;
    loop {
        // The frame so far, n samples per pixel: A (the blocks before, n/2 samples) and B (the last block, n/2).
        let t = std::time::Instant::now();
        let denoised_a = denoise::denoised(&a.image, schedule.guide, threads)?;
        denoise_seconds += t.elapsed().as_secs_f64();
        let mixed = mix(&a.image, &b.image);
        let measured = estimate(&a.image, &b.image, &denoised_a)?;
        let order = match rounds.last() {
            Some(prev) if measured.half > 0.0 && prev.half_rel_mse > 0.0 => (prev.half_rel_mse
                / measured.half)
                .log2()
                .clamp(0.0, MAX_ORDER),
            Some(_) => MAX_ORDER,
            None => 0.0,
        };
        let scale = 2f64.powf(-order) * schedule.darkening;
        let round = Round {
            spp: n,
            half_rel_mse: measured.half,
            half_standard_error: measured.standard_error,
            noisy_rel_mse: measured.noisy * schedule.darkening,
            order,
            predicted: (measured.half.max(0.0) * scale).sqrt(),
            predicted_upper: ((measured.half + 2.0 * measured.standard_error).max(0.0) * scale)
                .sqrt(),
        };
        rounds.push(round);
        let stats = add_stats(&a, &b);
        let met = round.predicted_upper <= schedule.budget;
        if met || n * 2 > schedule.max {
            let mut render = RegionRender {
                image: mixed,
                stats,
                tiles_done: b.tiles_done,
                tiles_total: b.tiles_total,
            };
            render.stats.seconds = started.elapsed().as_secs_f64() - denoise_seconds;
            let t = std::time::Instant::now();
            denoise::add_denoised(&mut render.image, schedule.guide, threads)?;
            denoise_seconds += t.elapsed().as_secs_f64();
            return Ok(DenoisedRender {
                render,
                rounds: Rounds {
                    rounds,
                    capped: !met,
                    max: schedule.max,
                },
                denoise_seconds,
            });
        }
        // Next round: the frame so far is the new A, a new block of n samples the new B (the old halves freed
        // first).
        a = RegionRender {
            image: mixed,
            stats,
            tiles_done: a.tiles_done,
            tiles_total: a.tiles_total,
        };
        drop(b);
        let next = block(blocks, n);
        blocks += 1;
        if !next.is_complete() {
            let mut partial = next;
            partial.image = a.image;
            return Ok(interrupted(partial, rounds, schedule, denoise_seconds));
        }
        b = next;
        n *= 2;
    }
}

/// An interrupted frame: `render` holds the last complete round's image (or, in the first round, the tiles done)
/// and the interrupted round's tile count, so the caller reports it as interrupted.
fn interrupted(
    render: RegionRender,
    rounds: Vec<Round>,
    schedule: &DenoisedSchedule,
    denoise_seconds: f64,
) -> DenoisedRender {
    DenoisedRender {
        render,
        rounds: Rounds {
            rounds,
            capped: false,
            max: schedule.max,
        },
        denoise_seconds,
    }
}

/// The counters of two blocks together.
fn add_stats(a: &RegionRender, b: &RegionRender) -> crate::render::RenderStats {
    let mut stats = a.stats;
    stats.rays.add(&b.stats.rays);
    stats.seconds += b.stats.seconds;
    stats.noise = None;
    stats
}

/// Two blocks of the same frame as one: every channel the mean of theirs weighted by their samples (the `spp`
/// channel, their sum). Blocks without an `spp` channel are weighted equally.
pub fn mix(a: &Image, b: &Image) -> Image {
    let spp = a.channel_index("spp");
    let channels = a.channels.len();
    let mut out = a.clone();
    for (i, (o, bv)) in out
        .data
        .chunks_exact_mut(channels)
        .zip(b.data.chunks_exact(channels))
        .enumerate()
    {
        let (na, nb) = match spp {
            Some(c) => (a.data[i * channels + c], bv[c]),
            None => (1.0, 1.0),
        };
        let total = na + nb;
        for (c, (x, y)) in o.iter_mut().zip(bv).enumerate() {
            *x = if Some(c) == spp {
                total
            } else if x == y || total <= 0.0 {
                // Equal in both (the centre ray's channels, +∞ where it missed), or no samples in either.
                *x
            } else {
                (*x * na + *y * nb) / total
            };
        }
    }
    out
}

/// What [`estimate`] measured, relMSE over the pixels and channels.
struct Estimate {
    /// e²(D(A)): E w (D(A) − B)² − ½ E w (A − B)².
    half: f64,
    /// The standard error of `half` over the pixels.
    standard_error: f64,
    /// The noisy frame (A + B) / 2: ¼ E w (A − B)².
    noisy: f64,
}

/// The denoised half's relMSE from the halves `a`, `b` and `a` denoised (RGB triples) (see the module docs).
fn estimate(a: &Image, b: &Image, denoised_a: &[f32]) -> Result<Estimate, OidnError> {
    let width = a.width.max(1);
    let beauty = |image: &Image| {
        image
            .triples(["R", "G", "B"])
            .filter(|v| v.len() == denoised_a.len())
            .ok_or_else(|| {
                OidnError("a half of the frame has no beauty of the frame's size".to_owned())
            })
    };
    let (a, b) = (beauty(a)?, beauty(b)?);
    let pixels = denoised_a.len() / 3;
    let height = pixels.div_ceil(width);
    let tiles_x = width.div_ceil(ESTIMATE_TILE);
    // Per tile of ESTIMATE_TILE² pixels: the sum of the pixels' terms and their count.
    let mut tiles = vec![(0.0f64, 0usize); tiles_x * height.div_ceil(ESTIMATE_TILE)];
    let (mut sum, mut noisy) = (0.0f64, 0.0f64);
    for p in 0..pixels {
        let mut term = 0.0;
        let mut ab = 0.0;
        for c in 3 * p..3 * p + 3 {
            let d = f64::from(denoised_a[c]);
            let w = 1.0 / (d * d + REL_EPSILON);
            let (x, y) = (f64::from(a[c]), f64::from(b[c]));
            let cross = w * (d - y) * (d - y);
            let diff = w * (x - y) * (x - y);
            term += cross - 0.5 * diff;
            ab += diff;
        }
        // Mean over the three channels.
        term /= 3.0;
        sum += term;
        noisy += ab / 3.0;
        let t = &mut tiles[(p / width / ESTIMATE_TILE) * tiles_x + (p % width) / ESTIMATE_TILE];
        t.0 += term;
        t.1 += 1;
    }
    let n = pixels.max(1) as f64;
    let mean = sum / n;
    // The ratio estimator's variance over the tiles, Σ (S_t − mean·N_t)² / N² · k / (k − 1): the filter's output
    // is correlated over a few pixels, so pixels are not independent draws and tiles nearly are.
    let k = tiles.iter().filter(|t| t.1 > 0).count() as f64;
    let spread: f64 = tiles
        .iter()
        .map(|&(s, c)| (s - mean * c as f64).powi(2))
        .sum();
    let variance = spread / (n * n) * k / (k - 1.0).max(1.0);
    Ok(Estimate {
        half: mean,
        standard_error: variance.sqrt(),
        noisy: 0.25 * noisy / n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(values: &[[f32; 4]]) -> Image {
        let mut im = Image::new(
            values.len(),
            1,
            vec!["R".into(), "G".into(), "B".into(), "spp".into()],
        );
        im.data = values.iter().flatten().copied().collect();
        im
    }

    #[test]
    fn mixing_weights_by_samples_and_sums_them() {
        let a = image(&[[1.0, 2.0, f32::INFINITY, 2.0]]);
        let b = image(&[[4.0, 2.0, f32::INFINITY, 6.0]]);
        let m = mix(&a, &b);
        assert_eq!(m.data, [3.25, 2.0, f32::INFINITY, 8.0]);
    }

    /// The estimator on synthetic halves: a "denoiser" that returns the truth plus a known error ±e, and halves of
    /// independent noise σ, must read e² (weighted as the target weighs it) whatever σ is, within its standard error.
    #[test]
    fn the_estimate_reads_the_denoised_error_without_a_reference() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg32::seed_from_u64(7);
        let n = 20_000;
        let truth = 0.5f32;
        let rgb = |v: &[f32]| {
            let mut im = Image::new(n, 1, vec!["R".into(), "G".into(), "B".into()]);
            im.data = v.iter().flat_map(|&x| [x; 3]).collect();
            im
        };
        for (sigma, e) in [(0.2f32, 0.02f32), (0.5, 0.05), (0.1, 0.0)] {
            let mut gauss = || {
                let (u, v): (f32, f32) = (rng.random::<f32>().max(1e-12), rng.random());
                (-2.0 * u.ln()).sqrt() * (std::f32::consts::TAU * v).cos()
            };
            let a: Vec<f32> = (0..n).map(|_| truth + sigma * gauss()).collect();
            let b: Vec<f32> = (0..n).map(|_| truth + sigma * gauss()).collect();
            // A fixed error of ±e (the filter's smoothing), alternating.
            let d: Vec<f32> = (0..n)
                .map(|i| truth + if i % 2 == 0 { e } else { -e })
                .collect();
            let w = |x: f32| 1.0 / (f64::from(x) * f64::from(x) + REL_EPSILON);
            let mean_w = 0.5 * (w(truth + e) + w(truth - e));
            let got = estimate(&rgb(&a), &rgb(&b), &rgb(&d).data).unwrap();
            let expected = f64::from(e * e) * mean_w;
            assert!(
                (got.half - expected).abs() < 3.0 * got.standard_error,
                "σ {sigma}, e {e}: estimate {} ± {} against {expected}",
                got.half,
                got.standard_error
            );
            let noisy = f64::from(sigma * sigma) / 2.0 * mean_w;
            assert!(
                (got.noisy / noisy - 1.0).abs() < 0.05,
                "noisy {} against {noisy}",
                got.noisy
            );
        }
    }
}
