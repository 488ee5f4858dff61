//! Pilot renders: a few windows of the frame at full resolution, rendered cheaply before the frame to measure what
//! auto cannot know from the scene file — how much light each bounce adds and how noisy a sample is.
//!
//! The windows are a regular grid of small [`WINDOW`]² squares spread over the film (background included, as the
//! error target counts every pixel). Each is rendered with [`render_bounces`](crate::render::render_bounces), whose
//! pixel is the mean of the same camera samples the frame's pixel takes (with the pilots' seeds), so a pilot pixel
//! integrates exactly what the frame's pixel will, and which gives every shorter path length's estimate of it from
//! one render. Pilots are deterministic (fixed seeds, independent of the frame's seed and of the thread count), so
//! the decisions are too.

pub mod approximations;
mod bounces;
mod pair;
#[cfg(test)]
mod tests;

pub use bounces::{bias_left, decay_ratio, MAX_BOUNCE_RATIO};

use bounces::{
    bounce_bias, bounce_pairs, cheapest_path_length, darkening_of, next_bias, pooled_bias, Bounce,
    FIRST_PILOT_PATH_LENGTH, PILOT_EXTENSION_SPP_FACTOR, PILOT_PATH_LENGTH_STEP,
};
use pair::{neighbour_means, sampler_gain, Pair};

use crate::render::integrator::MAX_PATH_LENGTH;
use crate::render::settings::RenderSettings;
use crate::render::{Frame, Region};
use crate::shadow::ShadowMaps;

use super::{Decision, QualityConfig};
use approximations::Approximation;

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
/// the film's. Nine windows of 10² on a 128² film sit mostly on the background of
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
/// measured one's is not rendered. The prediction is optimistic: at a margin of 1.2, (4, 4) is
/// rendered on 4 of the 14 rows of `study auto` (straight hair under the city, sunset and interior maps, 128²),
/// measuring 1.08, 1.38, 1.17 and 1.23× its predicted relMSE and 1.17–1.51× the best's cost, winning none; at 1.05
/// three of them are not rendered, which saves the most expensive pilot pair (straight-city at 0.1: 3 278 M
/// instructions in the pilots and the frame against 3 320 M, callgrind, one thread) and changes no decision.
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
    /// The relative RMSE of the bounces left out, as the pilots measured it (`None` when the path length was
    /// fixed: then half the target is set aside for it, unmeasured).
    pub bias_left: Option<f64>,
    /// The approximations kept ([`approximations::choose`]) with their measured bias, which the noise budget pays
    /// for.
    pub approximations: Vec<Approximation>,
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
    /// Wall time the pilots took, seconds, the comparisons of approximations included (with any maps they built,
    /// which `maps_seconds` counts too).
    pub pilot_seconds: f64,
    /// CPU seconds of the pilots predicted from their rays ([`super::cost::WEIGHTS`]): their cost without the
    /// machine's load.
    pub pilot_predicted_seconds: f64,
}

/// Chooses the path length (unless `fixed.path_length`), the first vertex's light and material samples (unless
/// `fixed.samples`) and then the samples per pixel (unless `fixed.spp`), with the safety `margins` of
/// [`super::Margins`], for
/// `quality.target`, by pilot renders of `frame` under `settings` (its shadows already decided; `maps` built for
/// them when they are deep-opacity). `chosen` is what [`approximations::choose`] kept and measured: its
/// approximations' bias comes off the noise budget, its pilots start the path-length search, and its pilots' cost
/// counts in the pilots'.
// One piece: each decision reads the pilots and the decisions before it, in this order.
pub fn plan(
    frame: &Frame,
    settings: &RenderSettings,
    maps: Option<&ShadowMaps>,
    quality: &QualityConfig,
    fixed: super::Fixed,
    margins: super::Margins,
    chosen: approximations::Measured,
) -> PilotPlan {
    let approximations::Measured {
        pilots: first_pilots,
        approximations,
        predicted_seconds: spent_before,
        seconds: compared_seconds,
    } = chosen;
    let approximation_bias2 = approximations::bias2_of(&approximations);
    let bias_standard_errors = margins.bias_standard_errors;
    let start = std::time::Instant::now();
    let [width, height] = settings.film.resolution;
    let windows = windows(width, height);
    let target = f64::from(quality.target);
    let mut pilot = settings.clone();
    pilot.film.spp = PILOT_SPP;
    let mut decisions = Vec::new();
    let spent = std::cell::Cell::new(spent_before);
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
    let mut kept: Option<Pair>;
    // The relative RMSE of the bias the bounces left out (measured when the path length is decided here).
    let mut left: Option<f64> = None;
    // The chosen path's relMSE over the longest path's means, per its relMSE over its own ([`PilotPlan::darkening`]).
    let mut darkening = 1.0f64;
    let path_length = if fixed.path_length {
        kept = first_pilots.and_then(|p| {
            p.pairs
                .into_iter()
                .nth(settings.integrator.path_length as usize)
        });
        settings.integrator.path_length
    } else {
        let mut biases = Vec::new();
        let mut measurements: Vec<Bounce> = Vec::new();
        // pairs[j]: the pilots at path length j, every one cut from a render at the longest ([`bounce_pairs`]),
        // rendered again longer when the last bounce is still over a quarter of the target.
        let mut pairs: Vec<Pair> = first_pilots.map(|p| p.pairs).unwrap_or_default();
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
    // noise budget is what the bias leaves of target²: T² − (bias left out)² − the approximations' bias², with half
    // the target set aside for the bounces when the path length was fixed. The spp is the mean frame's: adaptive sampling spends it where the noise is.
    let (mean, standard_error) = pair.rel_mse_with_error();
    // The pilots measure each pixel's own noise (filter importance sampling); a splatting film puts a share of it
    // into the image ([`RenderSettings::noise_share`]).
    let share = settings.noise_share();
    let [a, b] = &pair.0;
    let bias = left.unwrap_or(0.5 * target).min(0.5 * target);
    let noise_budget = target * target - bias * bias - approximation_bias2;
    let spp = if fixed.spp {
        settings.film.spp
    } else {
        // Noise over the converged image's means, which the target is measured against ([`PilotPlan::darkening`]).
        let wanted = (f64::from(PILOT_SPP) * mean * darkening * share / noise_budget).ceil();
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
                 brighter by the bounces left out{}); noise within {:.4} (√(target² − bias²), target {}) needs \
                 {wanted} spp on average{limit}",
                if share < 1.0 {
                    format!("; × {share:.3}, the share of it the splatting film keeps")
                } else {
                    String::new()
                },
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
        predicted_noise: (mean * darkening * share * f64::from(PILOT_SPP) / f64::from(spp)).sqrt(),
        noise_budget: noise_budget.sqrt(),
        bias_left: left,
        approximations,
        sampler_gain,
        darkening,
        pilot_seconds: compared_seconds + start.elapsed().as_secs_f64(),
        pilot_predicted_seconds: spent.get(),
    }
}
