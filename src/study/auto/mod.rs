//! `cuticle study auto [SCENE...] [--targets 0.1,0.05]` (no scene: the built-in default scene): does `--quality auto` meet its error
//! target, and how does its time compare with the fastest fixed configuration that meets it, and with the scene's
//! shipped settings?
//!
//! # Method
//!
//! Per scene (film from `--res`, default 128×128):
//! 1. **Reference**: the scene's own curves and materials, ray-traced shadows, path length
//!    [`REFERENCE_PATH_LENGTH`], `reference_spp` samples in two independent halves (their own seeds); cached by a
//!    hash of the scene and these settings. Every error is measured against the halves' mean less the reference's
//!    own noise (from the halves' difference, `Yardstick`), so it is the image's error against the truth.
//! 2. **Every fixed configuration** the other studies sweep: curves {round, flat} × shadows {ray-traced, deep
//!    opacity} × path length 0–5 ([`FIXED_PATH_LENGTHS`]; the scene's light and material samples). Each is rendered at
//!    [`FIT_SPP`] = 4 and 16 spp; the squared relative error is fitted as err²(n) = b² + v/n (bias and noise), and
//!    the spp that meets a target T is v / (T² − b²), none when b ≥ T. Its time is predicted from the 16-spp
//!    render's time per sample plus the map build.
//! 3. Per target: the **fastest fixed configuration** by the fits, rendered at its fit's spp (a lower bound on a
//!    fixed configuration's time where it misses T); the **fastest fixed configuration that measured meets T**
//!    ([`fastest_measured`](search::fastest_measured): up to [`SEARCH_CONFIGS`] configurations in order of predicted time, each raised
//!    from its fit's spp by (measured / T)² × 1.1 until it meets T, at most [`SEARCH_TRIES`] renders); and the
//!    **shipped settings** (the scene's configuration at the spp its fit says meets T), all measured; **auto** is planned
//!    (`quality::plan_curves` + `quality::plan_frame`) and rendered, its time counting the pilots and maps, and
//!    again with bare point estimates ([`quality::Margins::POINT`](crate::quality::Margins::POINT): no standard errors on the bounces' bias, the
//!    adaptive rule aimed at the whole noise budget) to measure whether auto's margins are needed.
//! 4. **At equal error**: where the shipped settings meet T with a larger error than auto's and auto at T is not
//!    faster, auto is planned and rendered again for the shipped frame's error (T × shipped / auto, one secant step:
//!    auto's error is about proportional to its target), and its CPU time compared with the shipped frame's (the
//!    point is auto faster than the shipped settings *at equal error*; asked for the same target, auto
//!    delivers less error than a fixed frame that barely meets it).
//!
//! The references and fits are cached in `cache/` in the output directory (or `--cache-dir`), keyed by the scene
//! and the study's settings. The fits only choose which fixed configurations are rendered, and those are measured
//! again by every run.
//!
//! "Met" means the measured relative RMSE (√relMSE, [`crate::measure::metrics`], less the reference's noise) is at
//! most T. Times are wall
//! times on whatever machine runs the study, with the process's CPU time beside them (on a shared machine the
//! wall time also counts the other work; the CPU time counts this study's): read the ratios, measured in one run.
//! The CPU time is the render process's: every method is charged the hair's load and its tracer's build (measured
//! once per geometry; auto is charged the rule's geometry, and its own comparison tracer is inside its timed
//! span), as a user's `cuticle render` pays them; the CSV gives that share (`setup_cpu_seconds`).
//! A render under [`REPEAT_BELOW_CPU_SECONDS`](measure::REPEAT_BELOW_CPU_SECONDS) (auto's, pilots included, or a fixed one) is timed
//! [`TIMING_RUNS`](measure::TIMING_RUNS) times and its fastest wall and CPU times kept.

mod fits;
mod held_out;
mod measure;
mod scene;
mod search;

use std::fmt::Write as _;
use std::path::PathBuf;

use crate::render::thread_pool;

use super::framework::CACHE_DIR;
use super::{cache, create_dir, SceneFile, StudyError};
pub use held_out::{headline, run_auto_only, HeldOutRow};
use measure::Measured;
use scene::{study_scene, Row};
use search::Search;
pub use search::{SEARCH_CONFIGS, SEARCH_TRIES};

/// Indirect bounces of the reference: deep enough that no path length auto or the fixed sweep takes is near it.
/// At 4, auto's path 5 on the Cornell box at 0.05 (its pilots measure bounce 5 above a quarter of the target)
/// would be judged against a reference that leaves bounce 5 out, and so would the fixed configurations' bias. Russian roulette keeps the deep bounces
/// cheap.
pub const REFERENCE_PATH_LENGTH: u32 = 10;
/// The path lengths of the fixed configurations: 0 to 5 (the Cornell box's light needs more bounces than the hair
/// scenes').
pub const FIXED_PATH_LENGTHS: std::ops::RangeInclusive<u32> = 0..=5;
/// How many fixed configurations there are: curves × shadows × path lengths.
const FIXED_CONFIGS: usize = 2 * 2 * (*FIXED_PATH_LENGTHS.end() as usize + 1);
/// The two sample counts each fixed configuration is fitted from.
pub const FIT_SPP: [u32; 2] = [4, 16];
/// Most spp a fixed configuration or auto may be rendered at in the study.
pub const MAX_SPP: u32 = 4096;

/// What `study auto` runs.
#[derive(Debug, Clone)]
pub struct AutoStudyConfig {
    /// The scenes (files, or the default scene).
    pub scenes: Vec<SceneFile>,
    /// Error targets (relative RMSE).
    pub targets: Vec<f32>,
    /// Film resolution.
    pub resolution: [u32; 2],
    /// Reference samples per pixel.
    pub reference_spp: u32,
    /// Output directory.
    pub out: PathBuf,
    /// Where the references and fits are cached (default: [`CACHE_DIR`] in `out`).
    pub cache_dir: Option<PathBuf>,
    /// Worker threads.
    pub threads: usize,
    /// With `--auto-only`: render auto's frames denoised with this guide, the target applying to the denoised frame
    /// ([`crate::quality::denoised`]).
    pub denoise: Option<crate::image::denoise::Guide>,
}

impl AutoStudyConfig {
    /// Where the references and fits are cached: `cache_dir`, or [`CACHE_DIR`] in the output directory.
    pub fn cache(&self) -> PathBuf {
        self.cache_dir
            .clone()
            .unwrap_or_else(|| self.out.join(CACHE_DIR))
    }
}

/// What [`run`] wrote.
#[derive(Debug, Clone)]
pub struct AutoReport {
    /// The Markdown summary (`auto.md`'s text).
    pub markdown: String,
    /// Every file written, once each, in the order first written: per scene `auto-fits-<scene>.csv`, then
    /// `auto.csv` and `auto.md` (rewritten after each scene). Not the cached references and fits.
    pub files: Vec<PathBuf>,
    /// Where the references and fits are cached.
    pub cache_dir: PathBuf,
}

/// Runs the study and writes `auto.md`, `auto.csv` and the fits' tables into `out`.
pub fn run(config: &AutoStudyConfig) -> Result<AutoReport, StudyError> {
    // One piece: the scenes are measured in turn and their rows written to one table and one report as they come.
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
    let cache_dir = config.cache();
    create_dir(&cache_dir)?;
    let mut files: Vec<PathBuf> = Vec::new();
    let mut wrote = |path: PathBuf| {
        if !files.contains(&path) {
            files.push(path);
        }
    };
    let pool = thread_pool(Some(config.threads))?;
    let mut csv = String::from(
        "scene,target,method,settings,spp,seconds,rel_rmse,met,cpu_seconds,setup_cpu_seconds\n",
    );
    let mut md = String::from(
        "| scene | target | auto: met? | auto s (CPU s) | pilots s (share) | auto settings, mean spp | fastest fixed by the fits: measured | its s (CPU s) | auto ÷ it (CPU) | fastest fixed that measured meets it | its s (CPU s) | auto ÷ it (CPU) | fixed renders searched | shipped s (CPU s) | auto ÷ shipped (CPU) | point estimates: met?, s |\n\
         |---|---:|---|---:|---:|---|---|---:|---:|---|---:|---:|---:|---:|---:|---|\n",
    );
    let mut notes = String::from(
        "\nEvery error above is measured against a reference of two independent halves, less the reference's own \
         noise in quadrature (`Yardstick`); that noise, relative RMSE, per scene:\n\n",
    );
    for scene in &config.scenes {
        let name = scene.name();
        let (rows, reference_noise, fits_table) =
            pool.install(|| study_scene(scene, config, &cache_dir))?;
        wrote(fits_table);
        let _ = writeln!(notes, "- {name}: {reference_noise:.4}");
        for row in rows {
            let Row {
                target,
                auto,
                point,
                fastest,
                measured_fastest,
                shipped,
                equal_error,
            } = row;
            let best = measured_fastest.best().cloned().map(|mut m| {
                m.what = "fastest fixed measured".into();
                m
            });
            for m in [Some(&auto), Some(&point)]
                .into_iter()
                .chain(measured_fastest.renders.iter().map(Some))
                .chain([best.as_ref(), shipped.as_ref(), equal_error.as_ref()])
                .flatten()
            {
                let _ = writeln!(
                    csv,
                    "{name},{target},{},{},{},{:.3},{:.5},{},{:.4},{:.4}",
                    m.what,
                    m.settings,
                    m.spp,
                    m.seconds,
                    m.rel_rmse,
                    m.meets(f64::from(target)),
                    m.cpu_seconds,
                    m.setup
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
                        "{:.2} ({:.3})",
                        auto.seconds / m.seconds,
                        auto.cpu_seconds / m.cpu_seconds.max(0.01)
                    )
                })
            };
            let verdict = |m: &Measured| {
                if m.meets(f64::from(target)) {
                    "yes"
                } else {
                    "**no**"
                }
            };
            let searched = |search: &Search| {
                let mut cell = search.renders.len().to_string();
                if !search.dropped.is_empty() {
                    let dropped: Vec<String> = search
                        .dropped
                        .iter()
                        .map(|(c, b)| format!("{} bias {b:.3}", c.name()))
                        .collect();
                    let _ = write!(
                        cell,
                        "; dropped, bias over the target: {}",
                        dropped.join(", ")
                    );
                }
                cell
            };
            let described = |m: &Option<Measured>, none: &str| {
                m.as_ref().map_or(none.to_string(), |m| {
                    format!("{}, {} spp ({:.4})", m.settings, m.spp, m.rel_rmse)
                })
            };
            let _ = writeln!(
                md,
                "| {name} | {target} | {} ({:.4}) | {:.2} ({:.2}) | {:.2} ({:.0} %) | {}, {} spp | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} ({:.4}), {:.2} |",
                verdict(&auto),
                auto.rel_rmse,
                auto.seconds,
                auto.cpu_seconds,
                auto.pilot_seconds,
                100.0 * auto.pilot_seconds / auto.seconds.max(1e-9),
                auto.settings,
                auto.spp,
                described(&fastest, "none meets it"),
                fmt_s(&fastest),
                ratio(&fastest),
                described(&best, "none measured meets it"),
                fmt_s(&best),
                ratio(&best),
                searched(&measured_fastest),
                fmt_s(&shipped),
                ratio(&shipped)
                    + &match (&equal_error, &shipped) {
                        (Some(e), Some(s)) => format!(
                            "; auto asked for its error: {:.4} in {:.2} CPU s, {:.3}",
                            e.rel_rmse,
                            e.cpu_seconds,
                            e.cpu_seconds / s.cpu_seconds.max(0.01)
                        ),
                        _ => String::new(),
                    },
                verdict(&point),
                point.rel_rmse,
                point.seconds,
            );
        }
        // Written after every scene, so a long run's finished scenes are kept.
        for (file, text) in [
            ("auto.csv", csv.clone()),
            ("auto.md", format!("{md}{notes}")),
        ] {
            let path = config.out.join(file);
            cache::write_text(&path, &text)?;
            wrote(path);
        }
    }
    Ok(AutoReport {
        markdown: format!("{md}{notes}"),
        files,
        cache_dir,
    })
}
