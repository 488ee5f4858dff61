//! Running one kind: preparing each variant's scene from its overrides, setting up frames once per shared setup,
//! rendering the references in two halves and the variants, measuring each point, then writing the tables, charts
//! and read-outs ([`run_kind`]); apart from the types the other parts share.

use crate::render::settings::ALL_AOVS;
use std::collections::HashMap;
use std::time::Instant;

use super::super::cache::{scene_key, write_text};
use super::super::figures;
use super::super::{SceneFile, StudyError};
use super::charts::{category_figure, crops_mosaic, error_time_figure, rmse_of, time_figure};
use super::differences::{
    difference_images, difference_readouts, differences, differences_csv, rgb_pixels,
};
use super::readouts::{chart_time, readouts, reference_checks, summarise};
use super::tables::{points_csv, summary_csv};
use super::{
    Kind, KindReport, Overrides, Point, ReferenceRun, StudyConfig, Summary, QUICK_RESOLUTION,
    REFERENCE_FORMAT, REFERENCE_SEED_OFFSET, SETUP_TABLES,
};
use crate::image::{self, Image};
use crate::measure::{metrics, peak_rss_bytes, pixels, reset_peak_rss};
use crate::plot;
use crate::render::{thread_pool, Frame, Request};
use crate::scene::Scene;

/// Sets the dotted key `path` of `table` to `value`, creating tables on the way.
pub(super) fn set_key(
    table: &mut toml::Table,
    path: &str,
    value: toml::Value,
) -> Result<(), StudyError> {
    let mut parts: Vec<&str> = path.split('.').collect();
    let last = parts.pop().unwrap_or_default();
    let mut t = table;
    for p in parts {
        t = t
            .entry(p)
            .or_insert_with(|| toml::Value::Table(toml::Table::new()))
            .as_table_mut()
            .ok_or_else(|| {
                StudyError::Config(format!("study override {path}: {p} is not a table"))
            })?;
    }
    t.insert(last.to_owned(), value);
    Ok(())
}

/// A scene text and the scene it parses to.
pub(super) struct Prepared {
    text: String,
    scene: Scene,
}

/// The scene's table `base` with `overrides` applied, as text and as a validated scene (named and resolved as
/// `file`).
pub(super) fn prepare(
    base: &toml::Table,
    overrides: &Overrides,
    file: &SceneFile,
) -> Result<Prepared, StudyError> {
    let mut table = base.clone();
    for (k, v) in overrides {
        set_key(&mut table, k, v.clone())?;
    }
    let text = toml::to_string(&table)
        .map_err(|e| StudyError::Config(format!("{}: {e}", file.source.display())))?;
    let scene = Scene::parse(&text, &file.source, &file.base_dir)?;
    Ok(Prepared { text, scene })
}

/// `text` without what cannot change the pixels of its render (see the module docs, "What is rendered"), for the
/// references' cache key.
pub(super) fn key_text(text: &str) -> String {
    let mut table: toml::Table = toml::from_str(text).unwrap_or_default();
    if let Some(shadows) = table.get_mut("shadows").and_then(|s| s.as_table_mut()) {
        if shadows.get("mode").and_then(|m| m.as_str()) != Some("deep-opacity") {
            shadows.remove("deep_opacity");
        }
    }
    toml::to_string(&table).unwrap_or_else(|_| text.to_owned())
}

/// The key of the frame set-up of `text` (see [`SETUP_TABLES`]).
pub(super) fn setup_key(text: &str) -> String {
    let table: toml::Table = toml::from_str(text).unwrap_or_default();
    let kept: toml::Table = table
        .into_iter()
        .filter(|(k, _)| SETUP_TABLES.contains(&k.as_str()))
        .collect();
    toml::to_string(&kept).unwrap_or_default()
}

/// A frame kept while consecutive renders share its set-up.
pub(super) struct FrameCache {
    key: String,
    frame: Option<Frame>,
    setup_s: HashMap<String, f64>,
}

impl FrameCache {
    /// The frame of `p` with `p`'s material, and its set-up seconds.
    fn get(&mut self, p: &Prepared) -> Result<(&mut Frame, f64), StudyError> {
        let key = setup_key(&p.text);
        if self.frame.is_none() || self.key != key {
            self.frame = None; // free the old BVH first
            let start = Instant::now();
            let frame = Frame::load(p.scene.resolve()?)?;
            let seconds = start.elapsed().as_secs_f64();
            self.setup_s.entry(key.clone()).or_insert(seconds);
            self.frame = Some(frame);
            self.key = key.clone();
        }
        let frame = self.frame.as_mut().expect("set above");
        frame.material = p
            .scene
            .material
            .build()
            .map_err(|m| StudyError::Config(format!("{}: {m}", p.scene.source.display())))?;
        Ok((frame, self.setup_s[&key]))
    }
}

/// The measures of `image` against a reference (see the module docs).
pub(super) struct Judge {
    pub(super) reference: Image,
    mask: Vec<bool>,
    thresholds: Vec<f64>,
    mean: f64,
}

impl Judge {
    fn new(reference: Image) -> Result<Judge, StudyError> {
        let mask = metrics::shadowed_mask(&reference).map_err(StudyError::Config)?;
        let y = pixels::luminance(&reference).map_err(StudyError::Config)?;
        let thresholds = pixels::firefly_thresholds(&y, reference.width, reference.height);
        let mean = mean_finite(&y);
        Ok(Judge {
            reference,
            mask,
            thresholds,
            mean,
        })
    }

    fn judge(&self, image: &Image) -> Result<Measures, StudyError> {
        let c = StudyError::Config;
        let e = metrics::errors(image, &self.reference, &self.mask).map_err(c)?;
        let ssim = pixels::ssim(image, &self.reference).map_err(c)?;
        let fireflies = pixels::fireflies(image, &self.thresholds).map_err(c)?;
        let non_finite = pixels::non_finite(image).map_err(c)?;
        let mean = mean_finite(&pixels::luminance(image).map_err(c)?);
        let mean_diff = if self.mean > 0.0 {
            (mean - self.mean) / self.mean
        } else {
            0.0
        };
        Ok(Measures {
            errors: e,
            ssim,
            fireflies,
            non_finite,
            mean_diff,
        })
    }
}

/// What [`Judge::judge`] measures of one image.
pub(super) struct Measures {
    errors: metrics::Errors,
    ssim: f64,
    fireflies: usize,
    non_finite: usize,
    mean_diff: f64,
}

pub(super) fn mean_finite(values: &[f64]) -> f64 {
    let finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    finite.iter().sum::<f64>() / finite.len().max(1) as f64
}

pub(super) fn progress_bar(show: bool, len: u64, prefix: String) -> indicatif::ProgressBar {
    let bar = if show {
        indicatif::ProgressBar::new(len)
    } else {
        indicatif::ProgressBar::hidden()
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{prefix} [{bar:40}] {pos}/{len} {msg} {elapsed} (eta {eta})",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar.set_prefix(prefix);
    bar
}

/// Checks the study's own settings and the kind's shape.
pub(super) fn check(kind: &Kind, config: &StudyConfig) -> Result<(), StudyError> {
    let bad = |m: String| Err(StudyError::Config(m));
    if config.seeds == 0 {
        return bad("--seeds must be at least 1".into());
    }
    if config.reference_spp == 0 {
        return bad("--reference-spp must be at least 1".into());
    }
    if config.threads == 0 {
        return bad("--threads must be at least 1".into());
    }
    if kind.variants.is_empty() {
        return bad(format!("study {}: no variants", kind.name));
    }
    if let Some(v) = kind
        .variants
        .iter()
        .find(|v| v.reference >= kind.references.len())
    {
        return bad(format!(
            "study {}: variant {} has no reference",
            kind.name, v.method
        ));
    }
    Ok(())
}

/// Runs `kind` on `scene` (a scene file or the default scene; see the module docs).
// One piece: its stages run once, in order, sharing the frame cache, the judges and the points.
pub fn run_kind(
    scene_file: &SceneFile,
    kind: &Kind,
    config: &StudyConfig,
) -> Result<KindReport, StudyError> {
    check(kind, config)?;
    let config = &StudyConfig {
        reference_spp: config
            .reference_spp_override
            .or(kind.budget.reference_spp)
            .unwrap_or(config.reference_spp),
        ..config.clone()
    };
    check(kind, config)?;
    // Parsed once as a scene first, so a bad scene file is reported as such before any override.
    let scene = scene_file.scene(None)?;
    let base = scene_file.table()?;
    let full = config
        .resolution
        .or(config.quick.then_some(QUICK_RESOLUTION))
        .unwrap_or(scene.film.resolution);
    let resolution = match kind.budget.crop {
        Some(c) => [c.min(full[0]), c.min(full[1])],
        None => full,
    };
    let seed0 = scene.film.seed;
    let film = |spp: u32, seed: u32| -> Overrides {
        vec![
            (
                "film.resolution".into(),
                toml::Value::try_from(full).expect("array"),
            ),
            ("film.spp".into(), toml::Value::Integer(i64::from(spp))),
            ("film.seed".into(), toml::Value::Integer(i64::from(seed))),
            // Every AOV, whatever the scene keeps: the measures read `A` and `shadow.Y` (a scene such as the peer
            // scene writes the beauty alone).
            (
                "film.aovs".into(),
                toml::Value::Array(vec![toml::Value::String(ALL_AOVS.into())]),
            ),
        ]
    };
    // A scene with `overrides`, then (when the kind crops) its centred crop: the camera of its own settings.
    let make = |overrides: &Overrides| -> Result<Prepared, StudyError> {
        let p = prepare(&base, overrides, scene_file)?;
        if resolution == p.scene.film.resolution {
            return Ok(p);
        }
        let mut o = overrides.clone();
        o.extend(crop_overrides(
            &p.scene.camera,
            p.scene.film.resolution,
            resolution,
        ));
        prepare(&base, &o, scene_file)
    };
    // Every variant and reference is parsed and checked before anything is rendered.
    let with = |extra: &Overrides, film: Overrides| -> Overrides {
        extra.iter().cloned().chain(film).collect()
    };
    let reference_seed = seed0.wrapping_add(REFERENCE_SEED_OFFSET);
    let halves = reference_halves(config.reference_spp);
    let references = kind
        .references
        .iter()
        .map(|r| {
            let whole = make(&with(
                &film(config.reference_spp, reference_seed),
                r.overrides.clone(),
            ))?;
            let parts = halves
                .iter()
                .enumerate()
                .map(|(h, &spp)| {
                    make(&with(
                        &film(spp, reference_seed.wrapping_add(h as u32)),
                        r.overrides.clone(),
                    ))
                })
                .collect::<Result<Vec<_>, _>>()?;
            Ok((whole, parts))
        })
        .collect::<Result<Vec<_>, StudyError>>()?;
    let mut points_todo = Vec::new();
    for (i, v) in kind.variants.iter().enumerate() {
        for s in 0..config.seeds {
            // The variant's own spp (if it sets one) wins over the study's default of 1.
            let mut o = with(&film(1, seed0.wrapping_add(s)), Vec::new());
            o.extend(v.overrides.iter().cloned());
            points_todo.push((i, s, make(&o)?));
        }
    }

    super::super::create_dir(&config.out_dir)?;
    let cache_dir = &config.cache();
    super::super::create_dir(cache_dir)?;
    let pool = thread_pool(Some(config.threads))?;
    let mut frames = FrameCache {
        key: String::new(),
        frame: None,
        setup_s: HashMap::new(),
    };

    // The references: each rendered in two halves with their own seeds and averaged, so that their difference
    // estimates the reference's own noise at no extra cost.
    let reference_bar = progress_bar(
        config.progress,
        references.len() as u64,
        format!("study {} references", kind.name),
    );
    let mut judges = Vec::with_capacity(references.len());
    let mut reference_runs = Vec::with_capacity(references.len());
    for (r, (p, parts)) in kind.references.iter().zip(&references) {
        reference_bar.set_message(r.label.clone());
        let key = scene_key(REFERENCE_FORMAT, &key_text(&p.text), scene_file, &[], "");
        let path = cache_dir.join(format!("reference-{key:016x}.exr"));
        let record = path.with_extension("txt");
        let frame = if path.is_file() {
            None
        } else {
            Some(frames.get(p)?.0)
        };
        let mut second_rmse = None;
        let (reference, cached, seconds) =
            super::super::cached_reference(&path, p.scene.film.resolution, || {
                let frame = frame.expect("a frame is set up whenever the reference is not cached");
                let mut seconds = 0.0;
                let mut images = Vec::new();
                for part in parts.iter().chain(parts.is_empty().then_some(p)) {
                    let settings = part.scene.render_settings();
                    let r = pool.install(|| {
                        frame.render(Request::new(&settings).progress(config.progress))
                    });
                    let (image, stats) = (r.image, r.stats);
                    seconds += stats.seconds + stats.shadow_build_seconds;
                    images.push(image);
                }
                if let [a, b] = &images[..] {
                    let (na, nb) = (f64::from(halves[0]), f64::from(halves[1]));
                    second_rmse = second_reference_rmse(a, na, b, nb);
                    (average_rgb(a, na, b, nb), seconds)
                } else {
                    (images.swap_remove(0), seconds)
                }
            })?;
        let (seconds, second_rmse) = match seconds {
            Some(s) => {
                let noise = second_rmse.map(|e| format!("{e:e}\n")).unwrap_or_default();
                write_text(&record, &format!("{s:.4}\n{noise}"))?;
                (Some(s), second_rmse)
            }
            None => {
                let t = std::fs::read_to_string(&record).unwrap_or_default();
                let mut lines = t.lines().map(|l| l.trim().parse::<f64>().ok());
                (lines.next().flatten(), lines.next().flatten())
            }
        };
        reference_bar.inc(1);
        if config.progress {
            reference_bar.println(format!(
                "{}: reference {} ({} spp): {} {}",
                kind.name,
                r.label,
                config.reference_spp,
                if cached { "reused" } else { "rendered" },
                seconds.map(|s| format!("{s:.2} s")).unwrap_or_default()
            ));
        }
        let judge = Judge::new(reference)?;
        let itself = judge.judge(&judge.reference)?;
        judges.push(judge);
        reference_runs.push(ReferenceRun {
            path,
            cached,
            seconds,
            self_rmse: itself.errors.rmse,
            self_fireflies: itself.fireflies,
            second_rmse,
        });
    }
    reference_bar.finish_and_clear();

    // Crops for `<kind>-crops.png` (seed 0 of every variant): the window centred on the hair of the first
    // reference, when every reference has its size.
    let [w0, h0] = [judges[0].reference.width, judges[0].reference.height];
    let crop_window = judges
        .iter()
        .all(|j| (j.reference.width, j.reference.height) == (w0, h0))
        .then(|| figures::hair_window(&judges[0].reference, config.crop));
    let mut crops: Vec<Option<Vec<glam::Vec3>>> = vec![None; kind.variants.len()];

    // The sweep.
    let bar = progress_bar(
        config.progress,
        points_todo.len() as u64,
        format!("study {}", kind.name),
    );
    let mut points: Vec<Point> = Vec::with_capacity(points_todo.len());
    // Points already rendered, by scene text and reference: a variant equal to an earlier one is not rendered again.
    let mut rendered: HashMap<(&str, usize), usize> = HashMap::new();
    // R, G, B of the points of series in a difference pair, by (variant, seed).
    let paired = |i: usize| {
        let series = &kind.variants[i].series;
        kind.differences
            .iter()
            .any(|(a, b)| a == series || b == series)
    };
    let mut pair_images: HashMap<(usize, u32), Vec<glam::Vec3>> = HashMap::new();
    for (i, seed, p) in &points_todo {
        let v = &kind.variants[*i];
        bar.set_message(format!("{} {}", v.method, v.settings));
        if let Some(&earlier) = rendered.get(&(p.text.as_str(), v.reference)) {
            let copy = Point {
                variant: *i,
                ..points[earlier].clone()
            };
            let from = (points[earlier].variant, *seed);
            crops[*i] = crops[from.0].clone();
            if let Some(rgb) = pair_images.get(&from).cloned() {
                pair_images.insert((*i, *seed), rgb);
            }
            points.push(copy);
            bar.inc(1);
            continue;
        }
        let (frame, setup_s) = frames.get(p)?;
        reset_peak_rss();
        let settings = p.scene.render_settings();
        let r = pool.install(|| frame.render(Request::new(&settings)));
        let (image, stats) = (r.image, r.stats);
        let peak_bytes = peak_rss_bytes();
        let m = judges[v.reference].judge(&image)?;
        if let (Some((cx, cy, cs)), 0) = (crop_window, *seed) {
            crops[*i] = Some(figures::crop(&image, cx, cy, cs).map_err(StudyError::Config)?);
        }
        if paired(*i) {
            pair_images.insert((*i, *seed), rgb_pixels(&image)?);
        }
        rendered.insert((p.text.as_str(), v.reference), points.len());
        points.push(Point {
            variant: *i,
            seed: *seed,
            setup_s,
            render_s: stats.seconds + stats.shadow_build_seconds,
            maps_s: stats.shadow_build_seconds,
            map_bytes: stats.shadow_map_bytes,
            camera_rays: stats.rays.camera,
            shadow_rays: stats.rays.shadow,
            material_rays: stats.rays.material,
            rmse: m.errors.rmse,
            relmse: m.errors.relmse,
            rmse_shadowed: m.errors.rmse_shadowed,
            ssim: m.ssim,
            fireflies: m.fireflies,
            non_finite: m.non_finite,
            mean_diff: m.mean_diff,
            peak_bytes,
        });
        bar.inc(1);
    }
    bar.finish_and_clear();
    drop(frames);
    let differences = differences(kind, &points, &pair_images);

    let summaries = summarise(kind, &points);
    let mut readouts = readouts(kind, &summaries);
    readouts.extend(difference_readouts(kind, &differences));
    let mut files = Vec::new();
    let dir = &config.out_dir;
    let csv_path = dir.join(format!("{}.csv", kind.name));
    write_text(&csv_path, &points_csv(kind, &points)?)?;
    files.push(csv_path);
    let summary_path = dir.join(format!("{}-summary.csv", kind.name));
    write_text(&summary_path, &summary_csv(kind, &summaries)?)?;
    files.push(summary_path);
    let caption = format!(
        "{}×{}, {} seeds, reference {} spp",
        resolution[0], resolution[1], config.seeds, config.reference_spp
    );
    if kind.categories.is_empty() {
        files.extend(plot::write_figure(
            &error_time_figure(kind, &summaries, &readouts, &caption)?,
            dir,
            &format!("{}-error-time", kind.name),
        )?);
        files.extend(plot::write_figure(
            &time_figure(kind, &summaries, &caption)?,
            dir,
            &format!("{}-time", kind.name),
        )?);
    } else {
        // Unrelated cases: bars per case, not curves through them.
        for (stem, measure, notes) in [
            (
                "rmse",
                ("RMSE", rmse_of as fn(&Kind, &Summary) -> f64),
                &readouts[..],
            ),
            ("time", ("render time", chart_time), &[]),
        ] {
            files.extend(plot::write_figure(
                &category_figure(kind, &summaries, measure, notes, &caption)?,
                dir,
                &format!("{}-{stem}", kind.name),
            )?);
        }
    }
    if let Some(window) = crop_window {
        let path = dir.join(format!("{}-crops.png", kind.name));
        image::write(&path, &crops_mosaic(kind, &judges, window, &crops, config)?)?;
        files.push(path);
    }
    if !kind.differences.is_empty() {
        let path = dir.join(format!("{}-differences.csv", kind.name));
        write_text(&path, &differences_csv(&differences)?)?;
        files.push(path);
        files.extend(difference_images(
            kind,
            &judges,
            &pair_images,
            resolution,
            dir,
        )?);
    }
    let reference_checks = reference_checks(kind, &summaries, &reference_runs);
    let readouts_path = dir.join(format!("{}-readouts.txt", kind.name));
    let text: Vec<&String> = readouts.iter().chain(&reference_checks).collect();
    write_text(
        &readouts_path,
        &(text
            .iter()
            .map(|l| l.as_str())
            .collect::<Vec<_>>()
            .join("\n")
            + "\n"),
    )?;
    files.push(readouts_path);
    Ok(KindReport {
        kind: kind.clone(),
        points,
        summaries,
        references: reference_runs,
        readouts,
        files,
        resolution,
        reference_spp: config.reference_spp,
        reference_checks,
        differences,
    })
}
/// The spp of a reference's two halves (`[spp]` alone when it cannot be split).
pub(super) fn reference_halves(spp: u32) -> Vec<u32> {
    if spp >= 2 {
        vec![spp / 2, spp - spp / 2]
    } else {
        Vec::new()
    }
}

/// The RMSE of a reference of `na + nb` spp against a second, independent one, from its halves `a` (`na` spp) and
/// `b`: for unbiased halves with per-sample variance σ², E|a − b|² = σ²(1/na + 1/nb) and two independent
/// references of n = na + nb spp differ by 2σ²/n, so RMSE(ref, ref') = RMSE(a, b) · √(2/n / (1/na + 1/nb)).
pub(super) fn second_reference_rmse(a: &Image, na: f64, b: &Image, nb: f64) -> Option<f64> {
    let mask = vec![false; a.width * a.height];
    let e = metrics::errors(a, b, &mask).ok()?;
    Some(e.rmse * (2.0 / (na + nb) / (1.0 / na + 1.0 / nb)).sqrt())
}

/// `a` with its R, G, B replaced by the spp-weighted mean of `a`'s and `b`'s (the other channels, AOVs, are `a`'s).
pub(super) fn average_rgb(a: &Image, na: f64, b: &Image, nb: f64) -> Image {
    let mut out = a.clone();
    let (wa, wb) = ((na / (na + nb)) as f32, (nb / (na + nb)) as f32);
    let (ca, cb) = (a.channels.len(), b.channels.len());
    for name in ["R", "G", "B"] {
        if let (Some(i), Some(j)) = (a.channel_index(name), b.channel_index(name)) {
            for (p, q) in out.data.chunks_exact_mut(ca).zip(b.data.chunks_exact(cb)) {
                p[i] = wa * p[i] + wb * q[j];
            }
        }
    }
    out
}

/// The camera keys that show the centred `crop` window of a film of `full` pixels with the same pixels: the
/// vertical field of view narrowed to the crop's rows, and the auto-framing margin scaled so that an auto-framed
/// eye stays where the full film puts it (its distance is `margin · r / sin(min(half fov v, h))`,
/// [`crate::render::camera::Camera::from_config`]).
pub fn crop_overrides(
    camera: &crate::scene::CameraConfig,
    full: [u32; 2],
    crop: [u32; 2],
) -> Overrides {
    let [w, h] = full.map(f64::from);
    let [cw, ch] = crop.map(f64::from);
    let tan_v = (0.5 * f64::from(camera.fov).to_radians()).tan();
    let half = |tan_half: f64, aspect: f64| tan_half.atan().min((tan_half * aspect).atan());
    let full_half = half(tan_v, w / h);
    let crop_tan = tan_v * ch / h;
    let crop_half = half(crop_tan, cw / ch);
    let margin = f64::from(camera.margin) * crop_half.sin() / full_half.sin();
    vec![
        (
            "film.resolution".into(),
            toml::Value::try_from(crop).expect("array"),
        ),
        (
            "camera.fov".into(),
            toml::Value::Float((2.0 * crop_tan.atan()).to_degrees()),
        ),
        ("camera.margin".into(), toml::Value::Float(margin)),
    ]
}
