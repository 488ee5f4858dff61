//! `cuticle study temporal [SCENE...]`: how much a sequence of frames flickers, beside each frame's error, for
//! each shadowing and transmittance mode, with and without the denoiser, with a new seed per frame or one seed.
//!
//! The thesis saw (§8.1) that moving images show noise that stills hide, mostly from the shadowing. Per scene
//! (each scene file carries its fibre model, so "each model" is a scene per model), per **camera** — `static` (the
//! scene's camera for every frame) and `turntable` (the camera turning `orbit` degrees a frame about the hair, as
//! `render --frames` with `camera.orbit_degrees_per_frame` does) — per **method** — ray-traced shadows with
//! stochastic transmittance (`rt-stochastic`), with exact transmittance (`rt-exact`), deep opacity maps
//! (`deep-opacity`, the scene's map settings, built once: the lights do not move) — per spp and per **seed** mode
//! (`per-frame`: the scene's seed plus the frame number; `fixed`: the scene's seed for every frame), `frames`
//! frames are rendered at a fixed spp, and each is also denoised (colour guide, [`denoise`]).
//!
//! Measured, against references of `reference_spp` rendered per frame (ray traced, stochastic transmittance, which
//! converges to the exact transmittance's image at a fraction of its cost per ray; seeds of their own; the static
//! camera has one):
//!
//! - **still error**: each frame's relative RMSE against its reference (√ mean of (x − r)² / (r² + 0.01)), the
//!   mean over the frames: what a still shows;
//! - **flicker**: for each pair of consecutive frames, their difference less the references' difference (the motion
//!   a converged sequence shows; zero on the static camera), weighed as the still error weighs an error
//!   (1 / (r̄² + 0.01), r̄ the two references' mean) and divided by 2: √ of its mean over pixels, channels and
//!   pairs. So noise drawn anew each frame flickers by the noise part of the still error (the difference of two
//!   independent errors has twice their variance), noise that stays in place by 0, and a bias that is the same in
//!   every frame not at all: flicker ÷ still error is the share of a still's error that moves.
//!
//! A fixed seed on the static camera renders the same frame every time, so it cannot flicker (measured as 0, and
//! listed so the table is complete); on the turntable the same seed is a noise pattern fixed to the screen while
//! the hair turns under it. The reference of a deep-opacity frame is the ray-traced one, so its still error holds the
//! maps' bias and its flicker on the turntable the difference of the maps' converged motion from the rays' (small
//! beside the noise at the spp swept; the static camera has none).
//!
//! Written: `temporal.csv` (one row per scene, camera, seeds, method, spp and denoised or not; `series` names the
//! curve for `cuticle plot-csv`) and `temporal.md`: the table, and per scene, camera and seed mode the read-out —
//! each method's flicker at the same still error (interpolated in log–log between the spp swept, at the smallest
//! still error every method reaches), which flickers least and by how much, and the denoiser's factor on flicker
//! at equal spp (the median over the spp) and at equal still error (the geometric middle of the still errors both
//! the noisy and the denoised sequences reach, when they overlap).

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use super::cache::{scene_key, write_text};
use super::denoise::{errors, rgb_of, setup};
use super::{cached_reference, SceneFile, StudyError};
use crate::image::{denoise, Image};
use crate::measure::metrics::REL_EPSILON;
use crate::render::{Frame, RenderSettings, Request, ShadowMode, TransmittanceMode};

/// Added to the scene's seed (and the frame number) for the references, so no sweep frame shares their samples.
const REFERENCE_SEED_OFFSET: u32 = 0x0003_0007;

/// What `study temporal` renders.
#[derive(Debug, Clone)]
pub struct TemporalStudyConfig {
    /// The scenes (one per fibre model to compare).
    pub scenes: Vec<SceneFile>,
    /// Film resolution.
    pub resolution: [u32; 2],
    /// Frames per sequence (at least 2).
    pub frames: u32,
    /// Degrees the turntable turns per frame.
    pub orbit_degrees: f32,
    /// The samples per pixel swept.
    pub spp: Vec<u32>,
    /// Samples per pixel of the references.
    pub reference_spp: u32,
    /// Output directory.
    pub out: PathBuf,
    /// Worker threads (the denoiser gets as many).
    pub threads: usize,
}

/// The shadowing methods compared.
pub const METHODS: [&str; 3] = ["rt-stochastic", "rt-exact", "deep-opacity"];
/// The cameras.
pub const CAMERAS: [&str; 2] = ["static", "turntable"];
/// The seed modes.
pub const SEEDS: [&str; 2] = ["per-frame", "fixed"];

/// One sequence measured.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// The scene's name.
    pub scene: String,
    /// `static` or `turntable`.
    pub camera: &'static str,
    /// `per-frame` or `fixed`.
    pub seeds: &'static str,
    /// One of [`METHODS`].
    pub method: &'static str,
    /// Samples per pixel.
    pub spp: u32,
    /// Whether the frames were denoised.
    pub denoised: bool,
    /// Mean relative RMSE of the frames against their references.
    pub still_error: f64,
    /// Consecutive frames' difference less the references', as a relative RMSE over √2 ([`flicker`]).
    pub flicker: f64,
    /// Mean seconds per frame (render, maps and, when denoised, the denoiser).
    pub seconds: f64,
}

impl Row {
    /// The curve this row is a point of: camera, seeds, method, noisy or denoised.
    pub fn series(&self) -> String {
        format!(
            "{} {} {}{}",
            self.camera,
            self.seeds,
            self.method,
            if self.denoised { " denoised" } else { "" }
        )
    }
}

/// What the study wrote.
#[derive(Debug)]
pub struct TemporalReport {
    /// Every row.
    pub rows: Vec<Row>,
    /// The Markdown report.
    pub markdown: String,
    /// The files written.
    pub files: Vec<PathBuf>,
}

/// The settings of `method`.
fn with_method(settings: &RenderSettings, method: &str) -> RenderSettings {
    let mut s = settings.clone();
    s.adaptive = None;
    match method {
        "rt-stochastic" => {
            s.shadows.mode = ShadowMode::Raytraced;
            s.shadows.transmittance = TransmittanceMode::Stochastic;
        }
        "rt-exact" => {
            s.shadows.mode = ShadowMode::Raytraced;
            s.shadows.transmittance = TransmittanceMode::Exact;
        }
        _ => s.shadows.mode = ShadowMode::DeepOpacity,
    }
    s
}

/// R, G, B of `image` as RGB triples.
fn rgb(image: &Image) -> Result<Vec<f32>, StudyError> {
    Ok(rgb_of(image, ["R", "G", "B"])?.data)
}

/// The flicker of `frames` against the references' motion (`references[i]` for frame i; one for a static camera):
/// √ of the mean over consecutive pairs, pixels and channels of ((b − a) − (r_b − r_a))² / (r̄² + 0.01) / 2, with r̄
/// the two references' mean (see the module docs). Frames are RGB triples, all of one length.
pub fn flicker(frames: &[Vec<f32>], references: &[Vec<f32>]) -> f64 {
    let reference = |i: usize| &references[i.min(references.len() - 1)];
    let pairs = frames.len().saturating_sub(1);
    if pairs == 0 {
        return 0.0;
    }
    let mut sum = 0.0;
    for i in 0..pairs {
        let (a, b, ra, rb) = (&frames[i], &frames[i + 1], reference(i), reference(i + 1));
        let s: f64 = (0..a.len())
            .map(|k| {
                let d = f64::from(b[k] - a[k]) - f64::from(rb[k] - ra[k]);
                let r = 0.5 * (f64::from(ra[k]) + f64::from(rb[k]));
                d * d / (r * r + REL_EPSILON)
            })
            .sum();
        sum += s / a.len().max(1) as f64;
    }
    (0.5 * sum / pairs as f64).sqrt()
}

/// Runs the study (see the module docs).
pub fn run(config: &TemporalStudyConfig) -> Result<TemporalReport, StudyError> {
    if config.scenes.is_empty()
        || config.frames < 2
        || config.spp.is_empty()
        || config.spp.contains(&0)
    {
        return Err(StudyError::Config(
            "study temporal: at least one scene, 2 frames and positive spp".to_owned(),
        ));
    }
    if config.reference_spp == 0 || !config.orbit_degrees.is_finite() {
        return Err(StudyError::Config(
            "study temporal: the reference's spp must be positive and the orbit finite".to_owned(),
        ));
    }
    let (cache, pool) = setup("study temporal", &config.out, config.threads)?;
    let n = config.frames as usize;
    let sequences = CAMERAS.len() * SEEDS.len() * METHODS.len() * config.spp.len();
    let steps = (config.scenes.len() * (n + sequences)) as u64;
    let progress = super::steps_bar(steps, "study temporal");
    let mut rows = Vec::new();
    for file in &config.scenes {
        progress.set_message(file.name());
        let scene = file.scene(Some(config.resolution))?;
        let frame = pool.install(|| Frame::load(scene.resolve()?).map_err(StudyError::from))?;
        let mut base = scene.render_settings();
        base.camera.orbit_degrees_per_frame = config.orbit_degrees;
        // Frames by filter importance sampling, as `render --denoise` renders them (Open Image Denoise cannot
        // remove a splat's noise, shared by neighbouring pixels): the noisy and denoised rows are of one frame.
        base.film.reconstruction = crate::render::Reconstruction::Importance;
        let seed = base.film.seed;
        // References: frame i of the turntable (frame 0 is the static camera's).
        let mut references = Vec::with_capacity(n);
        for i in 0..n {
            let key = scene_key(
                "cuticle study temporal reference v2",
                &file.text,
                file,
                &[],
                &format!(
                    "{}x{} {} spp orbit {} frame {i}",
                    config.resolution[0],
                    config.resolution[1],
                    config.reference_spp,
                    config.orbit_degrees
                ),
            );
            let path = cache.join(format!("temporal-{}-{key:016x}.exr", file.name()));
            let (image, _, _) = cached_reference(&path, config.resolution, || {
                // Stochastic transmittance is an unbiased estimate of the exact product, and much cheaper per ray:
                // converged, the two are the same image.
                let mut s = with_method(&base, "rt-stochastic");
                s.film.spp = config.reference_spp;
                s.film.seed = seed.wrapping_add(REFERENCE_SEED_OFFSET + i as u32);
                s.camera.frame = i as i32;
                let start = Instant::now();
                let image = pool.install(|| frame.render(Request::new(&s)).image);
                (image, start.elapsed().as_secs_f64())
            })?;
            references.push(rgb(&image)?);
            progress.inc(1);
        }
        for method in METHODS {
            let settings = with_method(&base, method);
            let start = Instant::now();
            let maps = (settings.shadows.mode == ShadowMode::DeepOpacity)
                .then(|| pool.install(|| frame.shadow_maps(&settings)));
            let maps_seconds = start.elapsed().as_secs_f64();
            for camera in CAMERAS {
                let refs = if camera == "static" {
                    &references[..1]
                } else {
                    &references[..]
                };
                for seeds in SEEDS {
                    for &spp in &config.spp {
                        let (mut noisy, mut clean) = (Vec::new(), Vec::new());
                        let (mut render_seconds, mut denoise_seconds) = (maps_seconds, 0.0);
                        for i in 0..n {
                            let mut s = settings.clone();
                            s.film.spp = spp;
                            s.film.seed = if seeds == "fixed" {
                                seed
                            } else {
                                seed.wrapping_add(i as u32)
                            };
                            s.camera.frame = if camera == "static" { 0 } else { i as i32 };
                            let start = Instant::now();
                            let image = pool
                                .install(|| frame.render(Request::new(&s).maps(maps.as_ref(), 0.0)))
                                .image;
                            render_seconds += start.elapsed().as_secs_f64();
                            let start = Instant::now();
                            let d =
                                denoise::denoised(&image, denoise::Guide::Color, config.threads)
                                    .map_err(|e| {
                                        StudyError::Config(format!("study temporal: {e}"))
                                    })?;
                            denoise_seconds += start.elapsed().as_secs_f64();
                            noisy.push(rgb(&image)?);
                            clean.push(d);
                        }
                        for (denoised, frames) in [(false, &noisy), (true, &clean)] {
                            let still = frames
                                .iter()
                                .enumerate()
                                .map(|(i, f)| errors(f, &refs[i.min(refs.len() - 1)]).1)
                                .sum::<f64>()
                                / n as f64;
                            let seconds =
                                render_seconds + if denoised { denoise_seconds } else { 0.0 };
                            rows.push(Row {
                                scene: file.name(),
                                camera,
                                seeds,
                                method,
                                spp,
                                denoised,
                                still_error: still,
                                flicker: flicker(frames, refs),
                                seconds: seconds / n as f64,
                            });
                        }
                        progress.inc(1);
                    }
                }
            }
        }
        // Written after each scene, so an interrupted run keeps what it measured.
        write_text(&config.out.join("temporal.csv"), &csv_of(&rows)?)?;
    }
    progress.finish_and_clear();
    // temporal.csv was last written after the last scene.
    let md = markdown(&rows, config);
    let (csv_path, md_path) = (
        config.out.join("temporal.csv"),
        config.out.join("temporal.md"),
    );
    write_text(&md_path, &md)?;
    Ok(TemporalReport {
        rows,
        markdown: md,
        files: vec![csv_path, md_path],
    })
}

/// `temporal.csv`.
fn csv_of(rows: &[Row]) -> Result<String, csv::Error> {
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record([
        "scene",
        "camera",
        "seeds",
        "method",
        "spp",
        "denoised",
        "series",
        "still_error",
        "flicker",
        "seconds",
    ])?;
    for r in rows {
        w.write_record([
            r.scene.clone(),
            r.camera.to_owned(),
            r.seeds.to_owned(),
            r.method.to_owned(),
            r.spp.to_string(),
            r.denoised.to_string(),
            r.series(),
            format!("{:.6}", r.still_error),
            format!("{:.6}", r.flicker),
            format!("{:.4}", r.seconds),
        ])?;
    }
    super::framework::finish_csv(w)
}

/// The flicker of a series at still error `e`, interpolated in log–log between its points (sorted by spp);
/// `None` when `e` is outside the still errors the series reached or a value is not positive.
pub fn flicker_at(points: &[(f64, f64)], e: f64) -> Option<f64> {
    points.windows(2).find_map(|w| {
        let ((e0, f0), (e1, f1)) = (w[0], w[1]);
        let (lo, hi) = (e0.min(e1), e0.max(e1));
        if !(lo..=hi).contains(&e) || e0 <= 0.0 || e1 <= 0.0 || f0 <= 0.0 || f1 <= 0.0 {
            return None;
        }
        if e0 == e1 {
            return Some(f0.max(f1));
        }
        let t = (e.ln() - e0.ln()) / (e1.ln() - e0.ln());
        Some((f0.ln() + t * (f1.ln() - f0.ln())).exp())
    })
}

/// The table and the read-outs.
fn markdown(rows: &[Row], config: &TemporalStudyConfig) -> String {
    let mut md = format!(
        "# study temporal\n\n{}x{}, {} frames, turntable {}° a frame, references {} spp (ray traced), {} \
         threads. Still error: mean relative RMSE of a frame; flicker: consecutive frames' difference less \
         the references', as a relative RMSE over √2 (independent noise: the still error's noise). Seconds: per \
         frame.\n\n\
         | scene | camera | seeds | method | spp | denoised | still error | flicker | s |\n\
         |---|---|---|---|---:|---|---:|---:|---:|\n",
        config.resolution[0],
        config.resolution[1],
        config.frames,
        config.orbit_degrees,
        config.reference_spp,
        config.threads
    );
    for r in rows {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} | {:.4} | {:.4} | {:.3} |",
            r.scene,
            r.camera,
            r.seeds,
            r.method,
            r.spp,
            if r.denoised { "yes" } else { "no" },
            r.still_error,
            r.flicker,
            r.seconds
        );
    }
    md.push('\n');
    let mut scenes: Vec<&str> = rows.iter().map(|r| r.scene.as_str()).collect();
    scenes.dedup();
    for scene in scenes {
        for camera in CAMERAS {
            for seeds in SEEDS {
                let _ = writeln!(md, "{}", readout(rows, scene, camera, seeds));
            }
        }
    }
    md
}

/// The read-out of one scene, camera and seed mode (see the module docs).
fn readout(rows: &[Row], scene: &str, camera: &str, seeds: &str) -> String {
    let series = |method: &str, denoised: bool| -> Vec<(f64, f64)> {
        let mut v: Vec<&Row> = rows
            .iter()
            .filter(|r| {
                r.scene == scene
                    && r.camera == camera
                    && r.seeds == seeds
                    && r.method == method
                    && r.denoised == denoised
            })
            .collect();
        v.sort_by_key(|r| r.spp);
        v.iter().map(|r| (r.still_error, r.flicker)).collect()
    };
    let mut out = format!("- **{scene}, {camera} camera, {seeds} seeds**: ");
    let noisy: Vec<Vec<(f64, f64)>> = METHODS.iter().map(|&m| series(m, false)).collect();
    let denoised: Vec<Vec<(f64, f64)>> = METHODS.iter().map(|&m| series(m, true)).collect();
    if noisy
        .iter()
        .chain(&denoised)
        .all(|s| s.iter().all(|p| p.1 == 0.0))
    {
        out.push_str("no flicker (every frame the same).");
        return out;
    }
    // The smallest still error every noisy method reaches.
    let common = noisy
        .iter()
        .filter(|s| !s.is_empty())
        .map(|s| s.iter().map(|p| p.0).fold(f64::INFINITY, f64::min))
        .fold(0.0f64, f64::max);
    let at: Vec<(&str, Option<f64>)> = METHODS
        .iter()
        .map(|&m| (m, flicker_at(&series(m, false), common)))
        .collect();
    let _ = write!(out, "at still error {common:.4}, flicker ");
    let parts: Vec<String> = at
        .iter()
        .map(|(m, f)| match f {
            Some(f) => format!("{m} {f:.4}"),
            None => format!("{m} —"),
        })
        .collect();
    out.push_str(&parts.join(", "));
    let known: Vec<(&str, f64)> = at.iter().filter_map(|(m, f)| f.map(|f| (*m, f))).collect();
    if let Some(&(best, fb)) = known
        .iter()
        .min_by(|a, b| a.1.partial_cmp(&b.1).unwrap_or(std::cmp::Ordering::Equal))
    {
        let others: Vec<String> = known
            .iter()
            .filter(|(m, _)| *m != best)
            .map(|(m, f)| format!("{:.2}× less than {m}", f / fb.max(1e-12)))
            .collect();
        let _ = write!(out, "; **{best} flickers least** ({})", others.join(", "));
    }
    // The denoiser: flicker denoised over noisy at equal spp (median over the spp), and at equal still error.
    let ratios: Vec<String> = METHODS
        .iter()
        .map(|&m| {
            let (a, b) = (series(m, false), series(m, true));
            let mut r: Vec<f64> = a
                .iter()
                .zip(&b)
                .filter(|(x, _)| x.1 > 0.0)
                .map(|(x, y)| y.1 / x.1)
                .collect();
            r.sort_by(|x, y| x.partial_cmp(y).unwrap_or(std::cmp::Ordering::Equal));
            let median = r.get(r.len() / 2).copied();
            // Equal still error: both series' flicker at the geometric middle of the still errors both reach.
            let range = |s: &[(f64, f64)]| {
                s.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), p| {
                    (lo.min(p.0), hi.max(p.0))
                })
            };
            let ((lo_a, hi_a), (lo_b, hi_b)) = (range(&a), range(&b));
            let (lo, hi) = (lo_a.max(lo_b), hi_a.min(hi_b));
            let equal = (lo <= hi)
                .then(|| (lo * hi).sqrt())
                .and_then(|e| Some(flicker_at(&b, e)? / flicker_at(&a, e)?.max(1e-12)));
            format!(
                "{m} ×{} at equal spp, {} at equal still error",
                median.map_or("—".to_owned(), |x| format!("{x:.2}")),
                equal.map_or("— (no still error both reach)".to_owned(), |x| format!(
                    "×{x:.2}"
                ))
            )
        })
        .collect();
    let _ = write!(
        out,
        ". The denoiser's factor on flicker: {}.",
        ratios.join("; ")
    );
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn independent_noise_flickers_by_its_relative_error_and_motion_does_not_count() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg32::seed_from_u64(3);
        let n = 30_000;
        let sigma = 0.1f32;
        // A moving reference: each frame shifts the image's values.
        let references: Vec<Vec<f32>> = (0..4)
            .map(|i| {
                (0..n)
                    .map(|k| 1.0 + 0.5 * ((k + 97 * i) % 7) as f32)
                    .collect()
            })
            .collect();
        // The weight 1 / (r̄² + 0.01) averaged over the pairs and pixels, r̄ the pair's mean reference.
        let weight = references
            .windows(2)
            .flat_map(|w| w[0].iter().zip(&w[1]))
            .map(|(&a, &b)| 1.0 / ((0.5 * f64::from(a + b)).powi(2) + REL_EPSILON))
            .sum::<f64>()
            / (3 * n) as f64;
        let noisy: Vec<Vec<f32>> = references
            .iter()
            .map(|r| {
                r.iter()
                    .map(|&v| v + sigma * (rng.random::<f32>() - 0.5) * 12f32.sqrt())
                    .collect()
            })
            .collect();
        let f = flicker(&noisy, &references);
        // The noise part of a frame's relative error: σ² weighed.
        let expected = (f64::from(sigma).powi(2) * weight).sqrt();
        assert!(
            (f / expected - 1.0).abs() < 0.02,
            "flicker {f}, expected {expected}"
        );
        // The converged sequence itself does not flicker, however it moves.
        assert_eq!(flicker(&references, &references), 0.0);
        // A fixed noise pattern on a still camera does not either.
        let still = vec![noisy[0].clone(); 3];
        assert_eq!(flicker(&still, &references[..1]), 0.0);
    }

    #[test]
    fn flicker_is_read_at_a_still_error_between_two_points_in_log_log() {
        let points = [(0.1, 0.2), (0.05, 0.1), (0.025, 0.05)];
        let f = flicker_at(&points, 0.0707).unwrap();
        assert!((f - 0.1414).abs() < 1e-3, "{f}");
        assert_eq!(flicker_at(&points, 0.2), None);
        assert_eq!(flicker_at(&points, 0.01), None);
    }
}
