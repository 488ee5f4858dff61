//! `cuticle study auto --auto-only SCENE...`: auto alone against the study's yardstick (to every bounce,
//! [`HELD_OUT_REFERENCE_DEPTH`]), for many scenes at a time (the held-out set of `cuticle study scenes`): per scene and target, does the frame meet the target, and
//! how close is the error it says it delivered (`quality::delivered`) to the error measured? No fixed
//! configurations are rendered, so a scene costs its reference and auto's renders.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use crate::accel::CurveKind;
use crate::quality::delivered::{delivered, delivered_denoised};
use crate::quality::denoised::{self, DenoisedSchedule};
use crate::quality::{self, Fixed, QualityConfig};
use crate::render::{thread_pool, Frame, Request};

use super::super::denoise::rgb_of;
use super::super::{cache, create_dir, SceneFile, StudyError};
use super::measure::mean_spp;
use super::scene::{reference_of, Depth};

/// The held-out yardstick's depth: every bounce, until Russian roulette ends the path. The generated set's light
/// hair keeps much of its light past bounce 10 (the study's [`super::REFERENCE_PATH_LENGTH`], which the tuned scenes'
/// darker hair does not need) and some of it past bounce 30: on seed 2's scene 2 (`furball.hair`, Chiang of
/// lightness 0.51 under the city map, 128²) a yardstick cut at path 30 is 6.9 % darker than one that follows every
/// bounce (64 spp: image means 0.2592 and 0.2771), and auto's frames, whose tail follows every bounce too (mean
/// 0.2769), measured 0.161 for a target of 0.1 against the cut one. Russian roulette keeps dark hair's deep bounces
/// cheap.
pub const HELD_OUT_REFERENCE_DEPTH: Depth = Depth::Every;
use super::{AutoReport, AutoStudyConfig, MAX_SPP};

/// One scene at one target.
#[derive(Debug, Clone, PartialEq)]
pub struct HeldOutRow {
    /// The scene's name (file stem).
    pub scene: String,
    /// The error target.
    pub target: f32,
    /// Auto's error against the yardstick, relative RMSE (the reference's own noise taken off).
    pub measured: f64,
    /// The standard error of `measured` over the pixels: how well the yardstick reads it.
    pub measured_se: f64,
    /// The reference's own noise, relative RMSE.
    pub reference_noise: f64,
    /// The error auto's frame says it delivered.
    pub estimated: f64,
    /// Mean samples per pixel.
    pub spp: f64,
    /// Wall time of auto's pilots, maps and render, seconds (the curve decision, made once per scene, not in it).
    pub seconds: f64,
    /// Curves, shadows, path length chosen (and the denoised rounds' spp).
    pub settings: String,
    /// Under `--denoise`, the same frame's error before denoising.
    pub noisy: Option<f64>,
}

impl HeldOutRow {
    /// Whether the measured error is at most the target.
    pub fn met(&self) -> bool {
        self.measured <= f64::from(self.target)
    }

    /// Whether the yardstick cannot tell met from missed: the measurement is within 2 standard errors of the target.
    pub fn undecided(&self) -> bool {
        (self.measured - f64::from(self.target)).abs() < 2.0 * self.measured_se
    }

    /// The estimate over the measurement.
    pub fn estimate_ratio(&self) -> f64 {
        self.estimated / self.measured.max(1e-12)
    }
}

/// Auto on one scene at every target of `config`.
fn scene_rows(
    file: &SceneFile,
    config: &AutoStudyConfig,
    cache_dir: &std::path::Path,
) -> Result<Vec<HeldOutRow>, StudyError> {
    let scene = file.scene(Some(config.resolution))?;
    let base = scene.render_settings();
    let load = |curves: CurveKind| -> Result<Frame, StudyError> {
        let mut spec = scene.resolve()?;
        spec.curves = curves;
        Ok(Frame::load(spec)?)
    };
    let own = load(scene.hair.curves)?;
    let reference = reference_of(
        file,
        config,
        cache_dir,
        &own,
        &base,
        HELD_OUT_REFERENCE_DEPTH,
    )?;
    // Auto's curve decision reads the strands and the camera, not the target: made once, and the frame it renders
    // loaded once, before any timing (as `study_scene` loads its frames).
    let (curves, _) = quality::plan_curves(
        &own.strands,
        &own.material,
        &base.camera,
        base.film.resolution,
    );
    let other;
    let frame = if curves == scene.hair.curves {
        &own
    } else {
        other = load(curves)?;
        &other
    };
    let mut rows = Vec::new();
    for &target in &config.targets {
        let start = Instant::now();
        let q = QualityConfig {
            target,
            max_spp: MAX_SPP,
            ..scene.quality.clone()
        };
        let planned = quality::plan_frame(frame, &base, &q, Fixed::default());
        let request =
            Request::new(&planned.settings).maps(planned.maps.as_ref(), planned.maps_seconds);
        let rendered_on = planned.frame_or(frame);
        let s = &planned.settings;
        let (image, said, rounds) = match config.denoise {
            Some(guide) => {
                let schedule = DenoisedSchedule::new(&planned.pilot, &q, guide);
                let threads = rayon::current_num_threads();
                let d = denoised::render(rendered_on, request, &schedule, threads)
                    .map_err(|e| StudyError::Config(format!("--denoise: {e}")))?;
                let said = delivered_denoised(&planned.pilot, target, &d.rounds);
                (d.render.image, said, Some(d.rounds))
            }
            None => {
                let rendered = rendered_on.render(request);
                let said = delivered(&planned.pilot, target, rendered.stats.noise.as_ref());
                (rendered.image, said, None)
            }
        };
        let seconds = start.elapsed().as_secs_f64();
        let (measured, noisy) = match &rounds {
            Some(_) => (
                reference.measure(&rgb_of(&image, crate::image::denoise::CHANNELS)?)?,
                Some(reference.measure(&image)?.error),
            ),
            None => (reference.measure(&image)?, None),
        };
        rows.push(HeldOutRow {
            scene: file.name(),
            target,
            measured: measured.error,
            measured_se: measured.standard_error,
            reference_noise: reference.noise(),
            estimated: said.error,
            spp: mean_spp(&image),
            seconds,
            settings: format!(
                "{:?} {:?} path {}{}",
                rendered_on.curves,
                s.shadows.mode,
                s.integrator.path_length,
                rounds
                    .map(|r| format!(", denoised rounds {} spp", r.path()))
                    .unwrap_or_default()
            ),
            noisy,
        });
    }
    Ok(rows)
}

/// The headline of `rows`: how many met the target, how many were more than 5 % over, how many estimates were
/// within 20 % of the measurement.
pub fn headline(rows: &[HeldOutRow]) -> String {
    let n = rows.len();
    let met = rows.iter().filter(|r| r.met()).count();
    let far = rows
        .iter()
        .filter(|r| r.measured > 1.05 * f64::from(r.target))
        .count();
    let close = rows
        .iter()
        .filter(|r| (r.estimate_ratio() - 1.0).abs() <= 0.2)
        .count();
    let undecided = rows.iter().filter(|r| r.undecided()).count();
    format!(
        "{met} of {n} rows met the target; {far} were more than 5 % over it; the estimate of the delivered error was \
         within 20 % of the measured one in {close} of {n}. In {undecided} of {n} the measurement is within 2 \
         standard errors of the target (the yardstick cannot tell met from missed)."
    )
}

/// Runs auto alone on every scene and writes `auto-held-out.csv` and `auto-held-out.md` into `config.out`.
pub fn run_auto_only(config: &AutoStudyConfig) -> Result<AutoReport, StudyError> {
    if config.scenes.is_empty() || config.targets.is_empty() {
        return Err(StudyError::Config(
            "study auto needs at least one scene and one target".into(),
        ));
    }
    create_dir(&config.out)?;
    let cache_dir = config.cache();
    create_dir(&cache_dir)?;
    let pool = thread_pool(Some(config.threads))?;
    let progress = indicatif::ProgressBar::new(config.scenes.len() as u64);
    let mut rows = Vec::new();
    let csv_path: PathBuf = config.out.join("auto-held-out.csv");
    let md_path: PathBuf = config.out.join("auto-held-out.md");
    for file in &config.scenes {
        progress.set_message(file.name());
        rows.extend(pool.install(|| scene_rows(file, config, &cache_dir))?);
        progress.inc(1);
        // Rewritten after each scene, so an interrupted run keeps what it measured.
        let mut csv = String::from(
            "scene,target,measured,measured_se,reference_noise,estimated,estimate_ratio,met,mean_spp,seconds,settings,noisy_measured\n",
        );
        let mut md = format!(
            "# `--quality auto` alone against the study's yardstick\n\n{}\n\n| scene | target | measured ± \
             s.e. | reference's noise | estimated | estimate ÷ measured | met | mean spp | s | settings |\n\
             |---|---:|---:|---:|---:|---:|---|---:|---:|---|\n",
            headline(&rows)
        );
        for r in &rows {
            let _ = writeln!(
                csv,
                "{},{},{:.5},{:.5},{:.5},{:.5},{:.3},{},{:.1},{:.2},\"{}\",{}",
                r.scene,
                r.target,
                r.measured,
                r.measured_se,
                r.reference_noise,
                r.estimated,
                r.estimate_ratio(),
                r.met(),
                r.spp,
                r.seconds,
                r.settings,
                r.noisy.map(|e| format!("{e:.5}")).unwrap_or_default()
            );
            let _ = writeln!(
                md,
                "| {} | {} | {:.4} ± {:.4} | {:.4} | {:.4} | {:.2} | {} | {:.1} | {:.2} | {} |",
                r.scene,
                r.target,
                r.measured,
                r.measured_se,
                r.reference_noise,
                r.estimated,
                r.estimate_ratio(),
                if r.met() { "yes" } else { "**no**" },
                r.spp,
                r.seconds,
                r.settings
            );
        }
        cache::write_text(&csv_path, &csv)?;
        cache::write_text(&md_path, &md)?;
    }
    progress.finish_and_clear();
    let markdown = std::fs::read_to_string(&md_path).unwrap_or_default();
    Ok(AutoReport {
        markdown,
        files: vec![csv_path, md_path],
        cache_dir,
    })
}
