//! `cuticle study auto SCENE... [--targets 0.1,0.05]` (issue 18, "Proof"): does `--quality auto` meet its error
//! target, and how does its time compare with the fastest fixed configuration that meets it, and with the scene's
//! shipped settings?
//!
//! # Method
//!
//! Per scene (film from `--res`, default 128×128):
//! 1. **Reference**: the scene's own curves and materials, ray-traced shadows, path length
//!    [`REFERENCE_PATH_LENGTH`], `reference_spp` samples, its own seed; cached by a hash of the scene and these
//!    settings.
//! 2. **Every fixed configuration** the other studies sweep: curves {round, flat} × shadows {ray-traced, deep
//!    opacity} × path length {0, 1, 2, 3} (the scene's light and material samples). Each is rendered at
//!    [`FIT_SPP`] = 4 and 16 spp; the squared relative error is fitted as err²(n) = b² + v/n (bias and noise), and
//!    the spp that meets a target T is v / (T² − b²), none when b ≥ T. Its time is predicted from the 16-spp
//!    render's time per sample plus the map build.
//! 3. Per target: the **fastest fixed configuration** (by prediction) and the **shipped settings** (the scene's
//!    configuration at the spp its fit says meets T) are rendered at those spp and measured; **auto** is planned
//!    (`quality::plan_curves` + `quality::plan_frame`) and rendered, its time counting the pilots and maps, and
//!    again with bare point estimates ([`quality::Margins::POINT`]: no standard errors on the bounces' bias, the
//!    adaptive rule aimed at the whole noise budget) to measure whether auto's margins are needed.
//!
//! The fits are cached next to the reference (keyed by the scene and the study's settings): they only choose
//! which fixed configurations are rendered, and those are measured again by every run.
//!
//! "Met" means the measured relative RMSE (√relMSE, [`crate::measure::metrics`]) is at most T. Times are wall
//! times on whatever machine runs the study, with the process's CPU time beside them (on a shared machine the
//! wall time also counts the other work; the CPU time counts this study's): read the ratios, measured in one run.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::accel::CurveKind;
use crate::image::Image;
use crate::measure::metrics;
use crate::quality::{self, Fixed, QualityConfig};
use crate::render::{thread_pool, Frame, Options, RenderSettings};
use crate::scene::{ShadowMode, TransmittanceMode};

use super::{cache, cached_reference, create_dir, load_scene, StudyError};

/// Indirect bounces of the reference (the fixed configurations sweep 0–3 below it).
pub const REFERENCE_PATH_LENGTH: u32 = 4;
/// The two sample counts each fixed configuration is fitted from.
pub const FIT_SPP: [u32; 2] = [4, 16];
/// Most spp a fixed configuration or auto may be rendered at in the study.
pub const MAX_SPP: u32 = 4096;

/// What `study auto` runs.
#[derive(Debug, Clone)]
pub struct AutoStudyConfig {
    /// Scene files.
    pub scenes: Vec<PathBuf>,
    /// Error targets (relative RMSE).
    pub targets: Vec<f32>,
    /// Film resolution.
    pub resolution: [u32; 2],
    /// Reference samples per pixel.
    pub reference_spp: u32,
    /// Output directory.
    pub out: PathBuf,
    /// Worker threads.
    pub threads: usize,
}

/// One fixed configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Config {
    curves: CurveKind,
    shadows: ShadowMode,
    path_length: u32,
}

impl Config {
    fn name(&self) -> String {
        format!(
            "{} {} path {}",
            self.curves.name(),
            match self.shadows {
                ShadowMode::Raytraced => "rays",
                ShadowMode::DeepOpacity => "maps",
                ShadowMode::None => "none",
            },
            self.path_length
        )
    }
}

/// A fixed configuration's fit.
#[derive(Debug, Clone, Copy)]
struct Fit {
    config: Config,
    bias2: f64,
    variance: f64,
    seconds_per_spp: f64,
    setup_seconds: f64,
}

impl Fit {
    /// The spp that meets `target`, if any within [`MAX_SPP`].
    fn spp_for(&self, target: f64) -> Option<u32> {
        let room = target * target - self.bias2;
        if room <= 0.0 {
            return None;
        }
        let n = (self.variance / room).ceil().max(1.0);
        (n <= f64::from(MAX_SPP)).then_some(n as u32)
    }

    fn predicted_seconds(&self, spp: u32) -> f64 {
        self.setup_seconds + self.seconds_per_spp * f64::from(spp)
    }
}

/// One measured render.
#[derive(Debug, Clone)]
struct Measured {
    what: String,
    settings: String,
    /// Samples per pixel (auto: the mean its adaptive sampling took, rounded).
    spp: u32,
    seconds: f64,
    rel_rmse: f64,
    /// Auto only: the pilots' wall time, seconds (included in `seconds`).
    pilot_seconds: f64,
    /// The process's CPU time (user + system, all threads) over the same span, seconds: on a machine shared
    /// with other work it measures the work done where wall time also measures the others'.
    cpu_seconds: f64,
}

/// The process's CPU time so far (user + system, all threads), seconds, from `/proc/self/stat` (Linux; clock
/// ticks of 1/100 s, the fixed USER_HZ of that interface); 0 where it cannot be read.
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // The fields after the command name (in parentheses, which may hold spaces): utime and stime are the 14th
    // and 15th of the line, the 12th and 13th after the name.
    let Some(rest) = stat.rfind(')').map(|i| &stat[i + 1..]) else {
        return 0.0;
    };
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    (ticks(11) + ticks(12)) / 100.0
}

/// The mean of the `spp` channel: the camera samples per pixel a render took.
fn mean_spp(image: &Image) -> f64 {
    let Some(n) = image.channel_index("spp") else {
        return 0.0;
    };
    let sum: f64 = image
        .data
        .chunks_exact(image.channels.len())
        .map(|p| f64::from(p[n]))
        .sum();
    sum / (image.width * image.height).max(1) as f64
}

fn rel_rmse(image: &Image, reference: &Image) -> Result<f64, StudyError> {
    let mask = vec![false; image.width * image.height];
    let e = metrics::errors(image, reference, &mask).map_err(StudyError::Config)?;
    Ok(e.relmse.sqrt())
}

/// Renders `settings` on `frame`, building maps if it uses them: the image and the seconds (maps + pixels).
fn render(frame: &Frame, settings: &RenderSettings) -> (Image, f64) {
    let (image, stats) = frame.render_with(settings, Options::default());
    (image, stats.seconds + stats.shadow_build_seconds)
}

/// Runs the study; returns the Markdown summary it wrote to `out/auto.md`.
pub fn run(config: &AutoStudyConfig) -> Result<String, StudyError> {
    if config.scenes.is_empty() || config.targets.is_empty() {
        return Err(StudyError::Config(
            "study auto needs at least one scene and one target".into(),
        ));
    }
    for &t in &config.targets {
        if !(t.is_finite() && t > 0.0 && t <= 1.0) {
            return Err(StudyError::Config(format!(
                "--targets must be in (0, 1], got {t}"
            )));
        }
    }
    create_dir(&config.out)?;
    let pool = thread_pool(Some(config.threads))?;
    let mut csv =
        String::from("scene,target,method,settings,spp,seconds,rel_rmse,met,cpu_seconds\n");
    let mut md = String::from(
        "| scene | target | auto: met? | auto s (CPU s) | pilots s (share) | auto settings, mean spp | fastest fixed (predicted) | its s (CPU s) | auto ÷ fastest (CPU) | shipped s (CPU s) | auto ÷ shipped (CPU) | point estimates: met?, s |\n\
         |---|---:|---|---:|---:|---|---|---:|---:|---:|---:|---|\n",
    );
    for path in &config.scenes {
        let rows = pool.install(|| study_scene(path, config))?;
        for (target, auto, point, fastest, shipped) in rows {
            let name = path.file_stem().unwrap_or_default().to_string_lossy();
            for m in [
                Some(&auto),
                Some(&point),
                fastest.as_ref(),
                shipped.as_ref(),
            ]
            .into_iter()
            .flatten()
            {
                let _ = writeln!(
                    csv,
                    "{name},{target},{},{},{},{:.3},{:.5},{},{:.2}",
                    m.what,
                    m.settings,
                    m.spp,
                    m.seconds,
                    m.rel_rmse,
                    m.rel_rmse <= f64::from(target),
                    m.cpu_seconds
                );
            }
            let fmt_s = |m: &Option<Measured>| {
                m.as_ref().map_or("–".to_string(), |m| {
                    format!("{:.2} ({:.2})", m.seconds, m.cpu_seconds)
                })
            };
            let ratio = |m: &Option<Measured>| {
                m.as_ref().map_or("–".to_string(), |m| {
                    format!(
                        "{:.2} ({:.2})",
                        auto.seconds / m.seconds,
                        auto.cpu_seconds / m.cpu_seconds.max(0.01)
                    )
                })
            };
            let _ = writeln!(
                md,
                "| {name} | {target} | {} ({:.4}) | {:.2} ({:.2}) | {:.2} ({:.0} %) | {}, {} spp | {} | {} | {} | {} | {} | {} ({:.4}), {:.2} |",
                if auto.rel_rmse <= f64::from(target) {
                    "yes"
                } else {
                    "**no**"
                },
                auto.rel_rmse,
                auto.seconds,
                auto.cpu_seconds,
                auto.pilot_seconds,
                100.0 * auto.pilot_seconds / auto.seconds.max(1e-9),
                auto.settings,
                auto.spp,
                fastest
                    .as_ref()
                    .map_or("none meets it".to_string(), |m| format!(
                        "{}, {} spp ({:.4})",
                        m.settings, m.spp, m.rel_rmse
                    )),
                fmt_s(&fastest),
                ratio(&fastest),
                fmt_s(&shipped),
                ratio(&shipped),
                if point.rel_rmse <= f64::from(target) {
                    "yes"
                } else {
                    "**no**"
                },
                point.rel_rmse,
                point.seconds,
            );
        }
        // Written after every scene, so a long run's finished scenes are kept.
        cache::write_text(&config.out.join("auto.csv"), &csv)?;
        cache::write_text(&config.out.join("auto.md"), &md)?;
    }
    Ok(md)
}

/// Renders every fixed configuration at [`FIT_SPP`] and fits err² = b² + v/n.
fn fit_all(
    frames: &[Frame; 2],
    base: &RenderSettings,
    reference_image: &Image,
    progress: &indicatif::ProgressBar,
) -> Result<Vec<Fit>, StudyError> {
    let frame_of = |c: CurveKind| &frames[usize::from(c == CurveKind::Flat)];
    let mut fits = Vec::new();
    for (curves, shadows, path_length) in configs() {
        let c = Config {
            curves,
            shadows,
            path_length,
        };
        let mut s = base.clone();
        s.shadows.mode = shadows;
        s.integrator.path_length = path_length;
        let frame = frame_of(curves);
        let mut e2 = [0.0; 2];
        let mut last = (0.0, 0.0);
        progress.set_message(c.name());
        for (k, &spp) in FIT_SPP.iter().enumerate() {
            progress.inc(1);
            s.film.spp = spp;
            let (image, stats) = frame.render_with(&s, Options::default());
            e2[k] = rel_rmse(&image, reference_image)?.powi(2);
            last = (stats.seconds, stats.shadow_build_seconds);
        }
        let (n1, n2) = (f64::from(FIT_SPP[0]), f64::from(FIT_SPP[1]));
        let variance = ((e2[0] - e2[1]) / (1.0 / n1 - 1.0 / n2)).max(0.0);
        let bias2 = (e2[1] - variance / n2).max(0.0);
        fits.push(Fit {
            config: c,
            bias2,
            variance,
            seconds_per_spp: last.0 / n2,
            setup_seconds: last.1,
        });
    }
    Ok(fits)
}

/// The 16 fixed configurations, in the order of the fits' table.
fn configs() -> impl Iterator<Item = (CurveKind, ShadowMode, u32)> {
    [CurveKind::Round, CurveKind::Flat]
        .into_iter()
        .flat_map(|c| {
            [ShadowMode::Raytraced, ShadowMode::DeepOpacity]
                .into_iter()
                .flat_map(move |s| (0..REFERENCE_PATH_LENGTH).map(move |p| (c, s, p)))
        })
}

/// The fits' table: `exact` writes b² and v in full (the cache, read back by [`parse_fits`]), otherwise rounded
/// for reading.
fn fits_csv(fits: &[Fit], exact: bool) -> String {
    // Every digit (shortest round-trip form) for the cache, `decimals` places for reading.
    let number = |x: f64, decimals: usize| {
        if exact {
            format!("{x:e}")
        } else {
            format!("{x:.decimals$}")
        }
    };
    let mut csv = String::from("config,bias,variance_x_spp,seconds_per_spp,setup_seconds\n");
    for f in fits {
        let _ = writeln!(
            csv,
            "{},{},{},{},{}",
            f.config.name(),
            number(f.bias2.sqrt(), 5),
            number(f.variance, 5),
            number(f.seconds_per_spp, 4),
            number(f.setup_seconds, 3)
        );
    }
    csv
}

/// A cached fits table ([`fits_csv`] exact), `None` unless it lists all 16 configurations in order.
fn parse_fits(text: &str) -> Option<Vec<Fit>> {
    let mut fits = Vec::new();
    for ((curves, shadows, path_length), line) in configs().zip(text.lines().skip(1)) {
        let config = Config {
            curves,
            shadows,
            path_length,
        };
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 5 || f[0] != config.name() {
            return None;
        }
        let num = |i: usize| f[i].parse::<f64>().ok().filter(|v| v.is_finite());
        let bias = num(1)?;
        fits.push(Fit {
            config,
            bias2: bias * bias,
            variance: num(2)?,
            seconds_per_spp: num(3)?,
            setup_seconds: num(4)?,
        });
    }
    (fits.len() == 16).then_some(fits)
}

type SceneRows = Vec<(f32, Measured, Measured, Option<Measured>, Option<Measured>)>;

fn study_scene(path: &Path, config: &AutoStudyConfig) -> Result<SceneRows, StudyError> {
    let (text, scene) = load_scene(path, Some(config.resolution))?;
    let spec_for = |curves: CurveKind| -> Result<Frame, StudyError> {
        let mut spec = scene.resolve()?;
        spec.curves = curves;
        Ok(Frame::load(spec)?)
    };
    let frames = [spec_for(CurveKind::Round)?, spec_for(CurveKind::Flat)?];
    let frame_of = |c: CurveKind| &frames[usize::from(c == CurveKind::Flat)];
    let base = scene.render_settings();
    let stem = path.file_stem().unwrap_or_default().to_string_lossy();
    // Reference, 16 configurations × 2 fits, then per target four renders.
    let steps = 1 + 2 * 16 + 4 * config.targets.len() as u64;
    let progress = indicatif::ProgressBar::new(steps);
    progress.set_style(
        indicatif::ProgressStyle::with_template(
            "{prefix} [{bar:30}] {pos}/{len} {msg} ({elapsed})",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    progress.set_prefix(format!("study auto {stem}"));
    progress.set_message("reference");

    // 1. The reference.
    let mut reference = base.clone();
    reference.integrator.path_length = REFERENCE_PATH_LENGTH;
    reference.shadows.mode = ShadowMode::Raytraced;
    reference.shadows.transmittance = TransmittanceMode::Exact;
    reference.film.spp = config.reference_spp;
    reference.film.seed = 0x7e7e;
    let key = cache::scene_key(
        "auto-reference-1",
        &text,
        &scene,
        &[],
        &format!(
            "{:?} {} {}",
            config.resolution, config.reference_spp, REFERENCE_PATH_LENGTH
        ),
    );
    let (reference_image, _, _) = cached_reference(
        &config.out.join(format!("reference-{key:016x}.exr")),
        config.resolution,
        || render(frame_of(scene.hair.curves), &reference),
    )?;
    progress.inc(1);

    // 2. Every fixed configuration, fitted (cached like the reference: the fits only pick which configurations
    // are rendered and measured per target, so a rerun measures those again under its own load).
    let fit_key = cache::scene_key(
        "auto-fits-1",
        &text,
        &scene,
        &[],
        &format!(
            "{:?} {} {} {:?}",
            config.resolution, config.reference_spp, REFERENCE_PATH_LENGTH, FIT_SPP
        ),
    );
    let fit_cache = config.out.join(format!("fits-{fit_key:016x}.csv"));
    let cached = std::fs::read_to_string(&fit_cache)
        .ok()
        .and_then(|t| parse_fits(&t));
    let fits = match cached {
        Some(f) => {
            progress.inc(2 * 16);
            f
        }
        None => {
            let f = fit_all(&frames, &base, &reference_image, &progress)?;
            cache::write_text(&fit_cache, &fits_csv(&f, true))?;
            f
        }
    };
    cache::write_text(
        &config.out.join(format!("auto-fits-{stem}.csv")),
        &fits_csv(&fits, false),
    )?;

    let shipped_config = Config {
        curves: scene.hair.curves,
        shadows: base.shadows.mode,
        path_length: base.integrator.path_length.min(REFERENCE_PATH_LENGTH - 1),
    };
    let mut rows = Vec::new();
    for &target in &config.targets {
        let t = f64::from(target);
        progress.set_message(format!("target {target}"));
        let measure_fixed = |fit: &Fit, what: &str| -> Result<Option<Measured>, StudyError> {
            progress.inc(1);
            let Some(spp) = fit.spp_for(t) else {
                return Ok(None);
            };
            let mut s = base.clone();
            s.shadows.mode = fit.config.shadows;
            s.integrator.path_length = fit.config.path_length;
            s.film.spp = spp;
            let cpu = cpu_seconds();
            let (image, seconds) = render(frame_of(fit.config.curves), &s);
            let cpu_seconds = cpu_seconds() - cpu;
            Ok(Some(Measured {
                what: what.into(),
                settings: fit.config.name(),
                spp,
                seconds,
                rel_rmse: rel_rmse(&image, &reference_image)?,
                pilot_seconds: 0.0,
                cpu_seconds,
            }))
        };
        let fastest = fits
            .iter()
            .filter_map(|f| f.spp_for(t).map(|n| (f, f.predicted_seconds(n))))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(f, _)| *f);
        let fastest = match fastest {
            Some(f) => measure_fixed(&f, "fastest fixed")?,
            None => None,
        };
        let shipped = fits
            .iter()
            .find(|f| f.config == shipped_config)
            .copied()
            .map(|f| measure_fixed(&f, "shipped"))
            .transpose()?
            .flatten();

        // Auto, timed from the curve decision to the last pixel; with its margins and with bare point estimates.
        let auto_with = |margins: quality::Margins, what: &str| -> Result<Measured, StudyError> {
            progress.inc(1);
            let start = Instant::now();
            let cpu = cpu_seconds();
            let strands = &frames[0].strands;
            let (curves, _) = quality::plan_curves(
                strands,
                &frames[0].material,
                &base.camera,
                base.film.resolution,
            );
            let frame = frame_of(curves);
            let q = QualityConfig {
                target,
                max_spp: MAX_SPP,
                ..scene.quality.clone()
            };
            let planned = quality::plan_frame_with(frame, &base, &q, Fixed::default(), margins);
            let (image, _) = frame.render_with_maps(
                &planned.settings,
                planned.maps.as_ref(),
                planned.maps_seconds,
                Options::default(),
            );
            let seconds = start.elapsed().as_secs_f64();
            let cpu_seconds = cpu_seconds() - cpu;
            let s = &planned.settings;
            Ok(Measured {
                what: what.into(),
                settings: Config {
                    curves,
                    shadows: s.shadows.mode,
                    path_length: s.integrator.path_length,
                }
                .name()
                    + &format!(
                        " {}L {}M",
                        s.integrator.light_samples, s.integrator.material_samples
                    ),
                spp: mean_spp(&image).round() as u32,
                seconds,
                rel_rmse: rel_rmse(&image, &reference_image)?,
                pilot_seconds: planned.pilot.pilot_seconds,
                cpu_seconds,
            })
        };
        let auto = auto_with(quality::Margins::DEFAULT, "auto")?;
        let point = auto_with(quality::Margins::POINT, "auto point estimates")?;
        rows.push((target, auto, point, fastest, shipped));
    }
    progress.finish_and_clear();
    Ok(rows)
}
