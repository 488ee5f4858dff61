//! Pilot renders: a few windows of the frame at full resolution, rendered cheaply before the frame to measure what
//! auto cannot know from the scene file — how much light each bounce adds and how noisy a sample is.
//!
//! The windows are a regular grid of [`WINDOW`]² squares over the film (background included, as the error target
//! counts every pixel). Each is rendered with [`Frame::render_region`], whose pixels equal the full frame's, so a
//! pilot pixel integrates exactly what the frame's pixel will. Pilots are deterministic (fixed seeds, independent of
//! the frame's seed and of the thread count), so the decisions are too.

use rayon::prelude::*;

use crate::image::Image;
use crate::render::integrator::{RayCounts, MAX_PATH_LENGTH};
use crate::render::settings::RenderSettings;
use crate::render::{Frame, Options, Region};
use crate::shadow::ShadowMaps;

use super::{Decision, QualityConfig};

/// Side of a pilot window, pixels.
pub const WINDOW: u32 = 16;
/// Windows along each axis of the film (fewer on a film too small for them).
pub const GRID: u32 = 6;
/// Camera samples per pixel of one pilot estimate.
pub const PILOT_SPP: u32 = 4;
/// Seeds of the two independent pilot estimates (far from the small seeds scenes use).
const SEEDS: [u32; 2] = [0x5eed_0001, 0x5eed_0002];

/// Smallest side of a pilot window on a small film, pixels.
pub const MIN_WINDOW: u32 = 8;

/// The pilot windows of a `width`×`height` film: n² squares, evenly spaced, with n from 3 to [`GRID`], so that
/// the windows hold about a sixteenth of the film's pixels: [`WINDOW`]² pixels each, smaller on a small film
/// (down to [`MIN_WINDOW`]²: 9 windows of 16² were a seventh of a 128² film and made the pilots up to a third of
/// its frame time; now 9 of 10²). n stays at least 3, so a window sits at the film's centre.
pub fn windows(width: u32, height: u32) -> Vec<Region> {
    let pixels = f64::from(width) * f64::from(height);
    let n = ((pixels / 16.0 / f64::from(WINDOW * WINDOW)).sqrt() as u32).clamp(3, GRID);
    let side = ((pixels / 16.0 / f64::from(n * n)).sqrt() as u32).clamp(MIN_WINDOW, WINDOW);
    let w = side.min(width);
    let h = side.min(height);
    let nx = n.min(width / w).max(1);
    let ny = n.min(height / h).max(1);
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

/// One pilot estimate: the beauty (RGB) of every window pixel, in window order, and the render's wall time.
struct Pilot {
    rgb: Vec<[f32; 3]>,
    seconds: f64,
    samples: u64,
    /// Rays traced, by kind (deterministic, unlike `seconds`: the cost decisions are made on).
    rays: RayCounts,
}

fn render_windows(
    frame: &Frame,
    settings: &RenderSettings,
    maps: Option<&ShadowMaps>,
    windows: &[Region],
) -> Pilot {
    let start = std::time::Instant::now();
    let renders: Vec<(Image, RayCounts)> = windows
        .par_iter()
        .map(|&r| {
            let r = frame.render_region(settings, maps, 0.0, Options { progress: false }, r, None);
            (r.image, r.stats.rays)
        })
        .collect();
    let seconds = start.elapsed().as_secs_f64();
    let mut rgb = Vec::new();
    let mut samples = 0u64;
    let mut rays = RayCounts::default();
    for (_, counts) in &renders {
        rays.add(counts);
    }
    for (image, _) in &renders {
        samples += (image.width * image.height) as u64 * u64::from(settings.film.spp);
        for y in 0..image.height {
            for x in 0..image.width {
                let p = image.pixel(x, y);
                rgb.push([p[0], p[1], p[2]]);
            }
        }
    }
    Pilot {
        rgb,
        seconds,
        samples,
        rays,
    }
}

/// Two independent pilot estimates (the two seeds) of one setting.
struct Pair([Pilot; 2]);

impl Pair {
    fn render(
        frame: &Frame,
        settings: &RenderSettings,
        maps: Option<&ShadowMaps>,
        windows: &[Region],
    ) -> Pair {
        let mut s = settings.clone();
        s.film.seed = SEEDS[0];
        let a = render_windows(frame, &s, maps, windows);
        s.film.seed = SEEDS[1];
        let b = render_windows(frame, &s, maps, windows);
        Pair([a, b])
    }

    /// The relative MSE of one estimate, E[(x − y)²] / 2 over (m² + 0.01) per pixel and channel (the variance of
    /// each of two independent estimates), as (mean, standard error of the mean) over the pilot pixels.
    fn rel_mse_with_error(&self) -> (f64, f64) {
        let [a, b] = &self.0;
        mean_and_error(a.rgb.iter().zip(&b.rgb).flat_map(|(x, y)| {
            (0..3).filter_map(move |c| {
                let (x, y) = (f64::from(x[c]), f64::from(y[c]));
                let m = 0.5 * (x + y);
                (x.is_finite() && y.is_finite()).then(|| 0.5 * (x - y) * (x - y) / (m * m + 0.01))
            })
        }))
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

/// Light and material samples at the first vertex auto compares (the thesis tuned them by hand, §6.2, table 3).
const SAMPLE_CANDIDATES: [(u32, u32); 4] = [(1, 1), (1, 4), (4, 1), (4, 4)];

/// The relative MSE a bounce adds as bias when left out: `before` and `after` are the pilot pixels of both seeds
/// without and with it (see [`plan`]). The mean of the per-pixel products and its standard error.
fn bounce_bias(before: [&[[f32; 3]]; 2], after: [&[[f32; 3]]; 2]) -> (f64, f64) {
    mean_and_error((0..before[0].len()).flat_map(|i| {
        (0..3).filter_map(move |c| {
            let v = |img: [&[[f32; 3]]; 2], s: usize| f64::from(img[s][i][c]);
            let (da, db) = (v(after, 0) - v(before, 0), v(after, 1) - v(before, 1));
            let m = 0.5 * (v(after, 0) + v(after, 1));
            (da.is_finite() && db.is_finite()).then(|| da * db / (m * m + 0.01))
        })
    }))
}

/// The relative RMSE of the bias of every bounce after the chosen ones, from the measured bias of the first left
/// out (`next`, relative RMSE) and of the last kept (`last`, `None` for path length 0): the bounces' bias falls
/// about geometrically, so the tail is next / (1 − r) with r = next / last, r at most ½ (and ½ when unknown).
pub fn bias_left(next: f64, last: Option<f64>) -> f64 {
    let r = match last {
        Some(l) if l > 0.0 => (next / l).clamp(0.0, 0.5),
        _ => 0.5,
    };
    next / (1.0 - r)
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
    /// Predicted relative RMSE (noise only) at `spp` uniform samples per pixel.
    pub predicted_noise: f64,
    /// The noise the frame may have, relative RMSE: √(target² − bias²) with the bias the pilots measured for the
    /// bounces left out (half the target when the path length was fixed).
    pub noise_budget: f64,
    /// Wall time the pilots took, seconds.
    pub pilot_seconds: f64,
}

/// Chooses the path length (unless `fixed.path_length`), the first vertex's light and material samples (unless
/// `fixed.samples`) and then the samples per pixel (unless `fixed.spp`), a bounce's bias with
/// `bias_standard_errors` ([`super::Margins`]), for
/// `quality.target`, by pilot renders of `frame` under `settings` (its shadows already decided; `maps` built for
/// them when they are deep-opacity).
pub fn plan(
    frame: &Frame,
    settings: &RenderSettings,
    maps: Option<&ShadowMaps>,
    quality: &QualityConfig,
    fixed: super::Fixed,
    bias_standard_errors: f64,
) -> PilotPlan {
    let start = std::time::Instant::now();
    let [width, height] = settings.film.resolution;
    let windows = windows(width, height);
    let target = f64::from(quality.target);
    let mut pilot = settings.clone();
    pilot.film.spp = PILOT_SPP;
    let mut decisions = Vec::new();

    // Bounces: each pilot path length k is rendered with both seeds. A pixel's k-th bounce is d = x_k − x_{k−1}
    // (same seed: the paths agree up to vertex k), and the product of the two seeds' independent d is an unbiased
    // estimate of its squared mean, so Σ d_a d_b / (m² + 0.01) estimates the relMSE the bounce adds as bias when
    // left out. Bounces are added until the next one's bias is under a quarter of the target (half the target is
    // the bias budget; the other half leaves room for the bounces after it).
    // The pair rendered at the chosen path length with the scene's light and material samples, kept for reuse.
    let mut kept: Option<Pair> = None;
    // The relative RMSE of the bias the bounces left out (measured when the path length is decided here).
    let mut left: Option<f64> = None;
    let path_length = if fixed.path_length {
        settings.integrator.path_length
    } else {
        let mut biases = Vec::new();
        pilot.integrator.path_length = 0;
        let mut previous = Pair::render(frame, &pilot, maps, &windows);
        let mut chosen = MAX_PATH_LENGTH;
        for k in 1..=MAX_PATH_LENGTH {
            pilot.integrator.path_length = k;
            let next = Pair::render(frame, &pilot, maps, &windows);
            let (mean, standard_error) = bounce_bias(previous.rgb(), next.rgb());
            let bias = (mean + bias_standard_errors * standard_error)
                .max(0.0)
                .sqrt();
            biases.push(bias);
            if bias < 0.25 * target {
                chosen = k - 1;
                let last = (k >= 2).then(|| biases[k as usize - 2]);
                left = Some(bias_left(bias, last));
                break;
            }
            previous = next;
        }
        kept = Some(previous);
        let listed: Vec<String> = biases
            .iter()
            .enumerate()
            .map(|(i, b)| format!("bounce {} {:.4}", i + 1, b))
            .collect();
        decisions.push(Decision {
            key: "integrator.path_length",
            value: chosen.to_string(),
            reason: format!(
                "the relative RMSE each bounce would leave out as bias, measured by the pilots (with {} standard \
                 errors: {}): the next one is under a quarter of the target {}{}",
                bias_standard_errors,
                listed.join(", "),
                quality.target,
                left.map_or(String::new(), |b| format!(
                    "; all bounces left out together about {b:.4} (geometric tail)"
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
        let pair = kept
            .take()
            .unwrap_or_else(|| Pair::render(frame, &pilot, maps, &windows));
        (pair, scene_samples.0, scene_samples.1)
    } else {
        let mut best: Option<(Pair, u32, u32, f64)> = None;
        let mut listed = Vec::new();
        for (l, m) in SAMPLE_CANDIDATES {
            pilot.integrator.light_samples = l;
            pilot.integrator.material_samples = m;
            let pair = match kept.take() {
                Some(p) if (l, m) == scene_samples => p,
                other => {
                    kept = other;
                    Pair::render(frame, &pilot, maps, &windows)
                }
            };
            let cost = pair.rel_mse() * pair.predicted_seconds();
            listed.push(format!(
                "{l} light + {m} material: relMSE {:.2e} with {:.0} rays, predicted {:.3} CPU s",
                pair.rel_mse(),
                pair.rays(),
                pair.predicted_seconds()
            ));
            if best.as_ref().is_none_or(|b| cost < b.3) {
                best = Some((pair, l, m, cost));
            }
        }
        let (pair, l, m, _) = best.expect("candidates are not empty");
        decisions.push(Decision {
            key: "integrator.light_samples, material_samples",
            value: format!("{l}, {m}"),
            reason: format!(
                "the least predicted cost for a given noise (relMSE × CPU s predicted from the rays of each kind) \
                 among the pilots at {PILOT_SPP} spp: {}",
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
        let wanted = (f64::from(PILOT_SPP) * mean / noise_budget).ceil();
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
                 estimates); noise within {:.4} (√(target² − bias²), target {}) needs {wanted} spp on average{limit}",
                noise_budget.sqrt(),
                quality.target
            ),
        });
        spp
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
        predicted_noise: (mean * f64::from(PILOT_SPP) / f64::from(spp)).sqrt(),
        noise_budget: noise_budget.sqrt(),
        pilot_seconds: start.elapsed().as_secs_f64(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_lie_inside_the_film_and_do_not_overlap() {
        for (w, h) in [(640, 480), (512, 512), (20, 10), (1, 1), (97, 33)] {
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
        assert_eq!(windows(640, 480).len(), (GRID * GRID) as usize);
    }
}
