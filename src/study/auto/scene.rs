//! One scene of `study auto`: its reference, the fits, and per target the fixed configurations, the shipped settings
//! and auto, measured ([`study_scene`]).

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::accel::CurveKind;
use crate::quality::{self, Fixed, QualityConfig};
use crate::render::{Frame, Request};
use crate::scene::{ShadowMode, TransmittanceMode};

use super::super::{cache, cached_reference, SceneFile, StudyError};
use super::fits::{fit_all, fits_csv, parse_fits};
use super::measure::{
    cpu_seconds, equal_error_target, fastest_of, mean_spp, render, time_once, Config, Measured,
    Yardstick, INTERLEAVED_TIMINGS, INTERLEAVED_TIMINGS_SHORT, REPEAT_BELOW_CPU_SECONDS,
};
use super::search::{fastest_measured, Search};
use super::{
    AutoStudyConfig, FIT_SPP, FIXED_CONFIGS, FIXED_PATH_LENGTHS, MAX_SPP, REFERENCE_PATH_LENGTH,
};

/// One scene's measurements at one target.
pub(super) struct Row {
    pub(super) target: f32,
    pub(super) auto: Measured,
    pub(super) point: Measured,
    /// The fastest fixed configuration by the fits, rendered at its fit's spp (it may miss the target).
    pub(super) fastest: Option<Measured>,
    /// The fastest fixed configuration that measured meets the target, every render of the search.
    pub(super) measured_fastest: Search,
    pub(super) shipped: Option<Measured>,
    /// Auto asked for the shipped frame's measured error, where that frame met the target and auto at the target
    /// was not faster.
    pub(super) equal_error: Option<Measured>,
}

/// Measures `file` at every target of `config`, references and fits cached in `cache_dir`: the rows, the
/// reference's own noise (relative RMSE) and the fits' table written (`auto-fits-<scene>.csv`).
pub(super) fn study_scene(
    file: &SceneFile,
    config: &AutoStudyConfig,
    cache_dir: &Path,
) -> Result<(Vec<Row>, f64, PathBuf), StudyError> {
    // One piece: per target, every measurement shares the scene's frames, reference and fits, set up once here.
    let scene = file.scene(Some(config.resolution))?;
    let text = &file.text;
    let spec_for = |curves: CurveKind| -> Result<Frame, StudyError> {
        let mut spec = scene.resolve()?;
        spec.curves = curves;
        Ok(Frame::load(spec)?)
    };
    // Each geometry's frame, and the CPU seconds a render process spends loading the hair and building that
    // tracer (the fewer of two loads): the study's renders start from frames built once, where a user's process
    // builds the one it renders from first (auto: the rule's curves, and within its own timed span the tubes it
    // compares the ribbons with). Every method is charged its process's load and build ([`Measured::setup`]).
    let load = |curves: CurveKind| -> Result<(Frame, f64), StudyError> {
        let mut fewest = f64::INFINITY;
        let mut frame = None;
        for _ in 0..2 {
            drop(frame.take());
            let cpu = cpu_seconds();
            frame = Some(spec_for(curves)?);
            fewest = fewest.min(cpu_seconds() - cpu);
        }
        Ok((frame.expect("loaded"), fewest))
    };
    let ((round, round_setup), (flat, flat_setup)) =
        (load(CurveKind::Round)?, load(CurveKind::Flat)?);
    let frames = [round, flat];
    let setups = [round_setup, flat_setup];
    let frame_of = |c: CurveKind| &frames[usize::from(c == CurveKind::Flat)];
    let setup_of = |c: CurveKind| setups[usize::from(c == CurveKind::Flat)];
    let base = scene.render_settings();
    let stem = file.name();
    // Reference, every configuration × 2 fits, then per target four renders.
    let steps = 1 + 2 * FIXED_CONFIGS as u64 + 4 * config.targets.len() as u64;
    let progress = crate::study::steps_bar(steps, format!("study auto {stem}"));
    progress.set_message("reference");

    // 1. The reference: two independent halves (their mean, and its noise from their difference).
    let reference = reference_of(
        file,
        config,
        cache_dir,
        frame_of(scene.hair.curves),
        &base,
        Depth::Cut(REFERENCE_PATH_LENGTH),
    )?;
    progress.inc(1);

    // 2. Every fixed configuration, fitted (cached like the reference: the fits only pick which configurations
    // are rendered and measured per target, so a rerun measures those again under its own load).
    let fit_key = cache::scene_key(
        "auto-fits-2",
        text,
        file,
        &[],
        &format!(
            "{:?} {} {} {:?}",
            config.resolution, config.reference_spp, REFERENCE_PATH_LENGTH, FIT_SPP
        ),
    );
    let fit_cache = cache_dir.join(format!("fits-{fit_key:016x}.csv"));
    let cached = std::fs::read_to_string(&fit_cache)
        .ok()
        .and_then(|t| parse_fits(&t));
    let fits = match cached {
        Some(f) => {
            progress.inc(2 * FIXED_CONFIGS as u64);
            f
        }
        None => {
            let f = fit_all(&frames, &base, &reference, &progress)?;
            cache::write_text(&fit_cache, &fits_csv(&f, true))?;
            f
        }
    };
    let fits_table = config.out.join(format!("auto-fits-{stem}.csv"));
    cache::write_text(&fits_table, &fits_csv(&fits, false))?;

    let shipped_config = Config {
        curves: scene.hair.curves,
        shadows: base.shadows.mode,
        path_length: base.integrator.path_length.min(*FIXED_PATH_LENGTHS.end()),
    };
    let mut rows = Vec::new();
    for &target in &config.targets {
        let t = f64::from(target);
        progress.set_message(format!("target {target}"));
        // The fastest fixed configuration by the fits (a lower bound where it misses), then the fastest that
        // measured meets the target (see [`fastest_measured`]); the first render of the second is the first.
        let fixed_settings = |config: Config, spp: u32| {
            let mut s = base.clone();
            s.shadows.mode = config.shadows;
            s.integrator.path_length = config.path_length;
            s.film.spp = spp;
            s
        };
        let render_fixed = |config: Config, spp: u32, what: &str| -> Result<Measured, StudyError> {
            let s = fixed_settings(config, spp);
            let (image, seconds, cpu_seconds) = fastest_of(|| render(frame_of(config.curves), &s));
            let setup = setup_of(config.curves);
            Ok(Measured {
                what: what.into(),
                settings: config.name(),
                config: Some(config),
                spp,
                seconds,
                rel_rmse: reference.rel_rmse(&image)?,
                pilot_seconds: 0.0,
                cpu_seconds: cpu_seconds + setup,
                setup,
            })
        };
        progress.inc(1);
        let (_, mut measured_fastest) = fastest_measured(&fits, t, |config, spp, first| {
            render_fixed(
                config,
                spp,
                if first {
                    "fastest fixed"
                } else {
                    "fixed search"
                },
            )
        })?;
        progress.inc(1);
        let mut shipped = fits
            .iter()
            .find(|f| f.config == shipped_config)
            .and_then(|f| f.spp_for(t).map(|spp| (f.config, spp)))
            .map(|(config, spp)| render_fixed(config, spp, "shipped"))
            .transpose()?;

        // Auto, timed from the curve decision to the last pixel; with its margins and with bare point estimates.
        let plan_and_render = |margins: quality::Margins, target: f32| {
            let start = Instant::now();
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
            let request =
                Request::new(&planned.settings).maps(planned.maps.as_ref(), planned.maps_seconds);
            let rendered_on = planned.frame_or(frame);
            let image = rendered_on.render(request).image;
            (
                (curves, rendered_on.curves, planned, image),
                start.elapsed().as_secs_f64(),
            )
        };
        let auto_with =
            |margins: quality::Margins, target: f32, what: &str| -> Result<Measured, StudyError> {
                progress.inc(1);
                let ((rule, curves, planned, image), seconds, cpu_seconds) =
                    fastest_of(|| plan_and_render(margins, target));
                let setup = setup_of(rule);
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
                    config: None,
                    spp: mean_spp(&image).round() as u32,
                    seconds,
                    rel_rmse: reference.rel_rmse(&image)?,
                    pilot_seconds: planned.pilot.pilot_seconds,
                    cpu_seconds: cpu_seconds + setup,
                    setup,
                })
            };
        let mut auto = auto_with(quality::Margins::DEFAULT, target, "auto")?;
        let point = auto_with(quality::Margins::POINT, target, "auto point estimates")?;
        // Auto (asked for `asked`) and a fixed frame timed again in turns, each keeping its fastest
        // ([`INTERLEAVED_TIMINGS`]): the same deterministic frames' clocks move between runs.
        let in_turns = |asked: f32, auto: &mut Measured, fixed: &mut Measured| {
            let Some(c) = fixed.config else {
                return;
            };
            let settings = fixed_settings(c, fixed.spp);
            let short = auto.cpu_seconds.max(fixed.cpu_seconds) < REPEAT_BELOW_CPU_SECONDS;
            let turns = if short {
                INTERLEAVED_TIMINGS_SHORT
            } else {
                INTERLEAVED_TIMINGS
            };
            for _ in 0..turns {
                let (_, seconds, cpu) =
                    time_once(&mut || plan_and_render(quality::Margins::DEFAULT, asked));
                auto.seconds = auto.seconds.min(seconds);
                auto.cpu_seconds = auto.cpu_seconds.min(cpu + auto.setup);
                let (_, seconds, cpu) = time_once(&mut || render(frame_of(c.curves), &settings));
                fixed.seconds = fixed.seconds.min(seconds);
                fixed.cpu_seconds = fixed.cpu_seconds.min(cpu + fixed.setup);
            }
        };
        // Auto and the fastest fixed frame that met the target.
        if let Some(best) = measured_fastest.best {
            in_turns(target, &mut auto, &mut measured_fastest.renders[best]);
        }
        // Where the shipped settings meet the target with a larger error than auto's and auto is not faster,
        // auto asked for the shipped frame's error ("faster at equal error"): the target scaled by the
        // ratio of the two errors, one secant step (auto's error is about proportional to its target).
        let equal_error = match shipped
            .as_ref()
            .and_then(|s| equal_error_target(t, s, &auto))
        {
            Some(asked) => {
                let mut m = auto_with(
                    quality::Margins::DEFAULT,
                    asked,
                    "auto at the shipped error",
                )?;
                m.settings += &format!(" (target {asked:.4})");
                // Timed in turns with the shipped frame, as auto is with the fastest fixed one.
                if let Some(s) = shipped.as_mut() {
                    in_turns(asked, &mut m, s);
                }
                Some(m)
            }
            None => None,
        };
        // The fits' pick is the search's first render (taken after the timings above, which it shares when it is
        // also the fastest that met).
        let fastest = measured_fastest.renders.first().cloned();
        rows.push(Row {
            target,
            auto,
            point,
            fastest,
            measured_fastest,
            shipped,
            equal_error,
        });
    }
    progress.finish_and_clear();
    Ok((rows, reference.noise(), fits_table))
}

/// How deep a yardstick's paths go.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Depth {
    /// Cut after this many bounces ([`REFERENCE_PATH_LENGTH`] for the study of the tuned scenes, whose darker hair
    /// keeps no measurable light past it).
    Cut(u32),
    /// Every bounce: path length [`crate::render::integrator::MAX_PATH_LENGTH`] and a tail of 1, so Russian roulette
    /// alone ends a path (the held-out set's light hair).
    Every,
}

/// The study's yardstick for `file` rendered by `frame` at `base`: the scene's own curves and materials, ray-traced
/// shadows with exact transmittance, paths as deep as `depth`, `reference_spp` samples in two independent halves
/// (their own seeds), each cached by a hash of the scene and these settings.
pub(super) fn reference_of(
    file: &SceneFile,
    config: &AutoStudyConfig,
    cache_dir: &Path,
    frame: &Frame,
    base: &crate::render::RenderSettings,
    depth: Depth,
) -> Result<Yardstick, StudyError> {
    let mut reference = base.clone();
    let (path_length, depth_key) = match depth {
        Depth::Cut(n) => (n, String::new()),
        Depth::Every => {
            reference.integrator.tail = 1.0;
            (
                crate::render::integrator::MAX_PATH_LENGTH,
                " every bounce".to_owned(),
            )
        }
    };
    reference.integrator.path_length = path_length;
    reference.shadows.mode = ShadowMode::Raytraced;
    reference.shadows.transmittance = TransmittanceMode::Exact;
    reference.film.spp = (config.reference_spp / 2).max(1);
    let mut halves = Vec::with_capacity(2);
    for (half, seed) in [0x7e7e, 0x7e7f].into_iter().enumerate() {
        reference.film.seed = seed;
        let key = cache::scene_key(
            "auto-reference-2",
            &file.text,
            file,
            &[],
            &format!(
                "{:?} {} {}{depth_key} half {half}",
                config.resolution, config.reference_spp, path_length
            ),
        );
        let (image, _, _) = cached_reference(
            &cache_dir.join(format!("reference-{key:016x}.exr")),
            config.resolution,
            || render(frame, &reference),
        )?;
        halves.push(image);
    }
    Yardstick::from_halves(&halves[0], &halves[1])
}
