//! The one study framework (issue 17): a study **kind** is a named list of variants (a method and its settings,
//! each a set of scene-key overrides) × seeds, measured against converged references. Every kind of
//! `cuticle study` ([`super::kinds`]) is data for [`run_kind`]; this file renders, measures and writes.
//!
//! # What is rendered
//!
//! A variant is the scene file with some keys replaced ([`Overrides`]: dotted TOML paths, e.g.
//! `integrator.light_samples = 16` or a whole `material` table), re-parsed and validated like a scene file, so a
//! variant can change anything a scene can say. Each variant is rendered with [`StudyConfig::seeds`] seeds (the
//! scene's `film.seed` + 0, 1, 2, …). Each variant names one of its kind's references: the scene with that
//! reference's overrides at the kind's reference spp ([`Budget::reference_spp`], else
//! [`StudyConfig::reference_spp`]). A reference is cached as `reference-<hash>.exr` (with `reference-<hash>.txt`
//! holding the seconds it took and its noise, below) in the cache directory, the hash ([`super::cache`]) covering
//! the overridden scene text as parsed and re-serialised, its directory and a format version: the hair and map
//! files and the renderer's code are not covered (delete the files after changing them). Settings that cannot
//! change a reference's pixels are left out of the key: `[shadows.deep_opacity]` when the reference's shadows are
//! not deep opacity maps (so a scene's map settings keep its ray-traced reference).
//!
//! # References in two halves
//!
//! A reference of n spp is rendered as two halves of ⌊n/2⌋ and ⌈n/2⌉ spp with the seeds `film.seed` +
//! [`REFERENCE_SEED_OFFSET`] and that + 1, and their R, G, B averaged by spp. The halves' RMSE
//! against each other gives, at no extra cost, the RMSE of the reference against a second reference with other
//! seeds ([`ReferenceRun::second_rmse`]); each kind's read-outs print it beside the smallest RMSE of the variants
//! measured against that reference, so a sweep whose errors are the reference's own noise shows.
//!
//! # Budgets
//!
//! A kind may render only the centred `c × c` window of the study's film ([`Budget::crop`]): the film becomes
//! `c × c`, `camera.fov` narrows to the window's rows and `camera.margin` scales so that an auto-framed eye stays
//! where the whole film puts it ([`crop_overrides`]): the same pixels of the same view, for a fraction of the rays.
//! [`super::kinds`] says what each kind spends and why.
//!
//! The frame (hair, BVH, lights) is set up once for every run of variants sharing the scene's `hair`, `light`,
//! `environment` and `shape` tables; the material, camera, film, integrator and shadow settings are applied per
//! render. So **set-up time** (resolving lights and maps, loading the hair, building the BVH) is measured once per
//! such group and reported on each of its points; **render time** is the pixel loop plus any shadow-map build,
//! whose part is also reported on its own (`maps_s`, with the maps' memory `map_mb`). A variant whose scene equals
//! an earlier variant's (a setting in two series, e.g. 16 map layers at 1024² in both the layer and the resolution
//! series of `shadows`) is rendered once; its points are copied.
//!
//! # What is measured, per point ([`Point`])
//!
//! Set-up, render and shadow-map seconds; shadow-map bytes; rays by kind (camera, shadow, material); RMSE and relMSE
//! ([`crate::measure::metrics`]), and the RMSE over the pixels the reference sees shadowed (`rmse_shadowed`, NaN
//! when there are none);
//! SSIM, fireflies and non-finite pixels ([`crate::measure::pixels`], which says why SSIM and defines "local");
//! `mean_diff`, the relative difference of the image's mean luminance from the reference's (a bias that no sample
//! count removes shows here); and **peak memory**: the process's peak resident set size is reset before the render
//! ([`crate::measure::reset_peak_rss`], Linux `clear_refs`) and read after it, so `peak_mb` is the largest resident
//! size *during this render*: the frame, the references in memory and the render's own buffers. Differences between
//! points are the renders' own memory. Where the reset is unavailable the column holds the process's lifetime peak.
//!
//! Per variant, the seeds' mean and sample standard deviation of every measure ([`Summary`]).
//!
//! # What is written (per kind, into the output directory)
//!
//! - `<kind>.csv`: one row per point ([`POINT_HEADER`]); `<kind>-summary.csv`: one row per variant ([`SUMMARY_HEADER`]);
//! - `<kind>-error-time.png/.svg`: mean RMSE against mean time, log–log, one series per method, each point labelled
//!   with its swept setting, and under the chart the **read-outs** ([`readouts`]);
//! - `<kind>-time.png/.svg`: mean render time against the swept setting (the thesis' figure 17 for `samples`);
//! - `<kind>-readouts.txt`: the read-outs as text;
//! - for kinds with [`Kind::differences`] (pairs of series rendered with the same seeds, e.g. Embree and the BVH):
//!   `<kind>-differences.csv` ([`DIFFERENCE_HEADER`]: per common setting and seed the RMSE between the two
//!   images, beside each one's RMSE against the reference: far below them means the same image), a read-out line
//!   per pair, and `<kind>-diff-<a>-vs-<b>.png`: |A − B| at the largest common setting, seed 0, scaled so that the
//!   reference's 99th percentile is white (structure in it would mean the two trace differently; isolated pixels
//!   are paths sent elsewhere by one graze).
//!
//! # Read-outs
//!
//! For each pair (A, B) a kind compares: **equal error** — the time at which A's curve reaches the error of B's
//! last (most converged) point, by linear interpolation between A's measured points in log time and log error;
//! written "A reaches B's RMSE e (at t s) in N× less time" — and **equal time** — A's error at B's last time, by
//! the same interpolation, as a ratio to B's — and **equal setting** — A's error and time as ratios to B's at the
//! largest swept value both measured (equal samples, for most kinds). Outside A's measured range nothing is
//! extrapolated: the line says so.

use crate::render::settings::ALL_AOVS;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use super::cache::{scene_key, write_text};
use super::figures::{self, ChartSeries};
use super::StudyError;
use crate::image::{self, Image};
use crate::measure::{metrics, peak_rss_bytes, pixels, reset_peak_rss};
use crate::plot::{self, hex, Axis, LineChart, Series, WithNotes};
use crate::render::{thread_pool, Frame, Options};
use crate::scene::Scene;

/// Dotted scene keys and the values that replace them, in order.
pub type Overrides = Vec<(String, toml::Value)>;

/// Added to the scene's seed for the references' first half (the second takes the next seed), so no variant shares
/// its samples with a reference.
pub const REFERENCE_SEED_OFFSET: u32 = 0x0001_0001;
/// Bumped when the references' recipe changes, so old cached files are not reused.
const REFERENCE_FORMAT: &str = "cuticle study reference v2 (two halves)";
/// Side of the crop window of `<kind>-crops.png` by default, pixels (clamped to the image).
pub const CROP: usize = 64;
/// Tables of the scene that decide the frame's set-up (hair, BVH, lights); the rest is applied per render.
const SETUP_TABLES: [&str; 4] = ["hair", "light", "environment", "shape"];

/// One method at one setting.
#[derive(Debug, Clone, PartialEq)]
pub struct Variant {
    /// The chart series it belongs to (one method, its setting swept).
    pub series: String,
    /// The method, e.g. `marschner importance`.
    pub method: String,
    /// Its settings as written in the CSV, e.g. `light_samples=16 material_samples=64`.
    pub settings: String,
    /// The swept setting's value (the x of `<kind>-time`, the label of the point).
    pub x: f64,
    /// The scene keys it changes.
    pub overrides: Overrides,
    /// Index of its reference in [`Kind::references`].
    pub reference: usize,
}

/// A converged reference of a kind.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    /// What it is, e.g. `chiang, MIS`.
    pub label: String,
    /// The scene keys it changes (its spp and seed are the study's).
    pub overrides: Overrides,
}

/// A study kind: what [`run_kind`] renders.
#[derive(Debug, Clone, PartialEq)]
pub struct Kind {
    /// The name (`samples`, `sampling`, …): the files' stem.
    pub name: String,
    /// What it asks, one line (chart and report title).
    pub title: String,
    /// What [`Variant::x`] is (the `<kind>-time` chart's x axis).
    pub x_label: String,
    /// Charts count set-up time in the time axis (when methods differ in set-up, e.g. tubes and ribbons).
    pub time_includes_setup: bool,
    /// The references.
    pub references: Vec<Reference>,
    /// The variants, in rendering order.
    pub variants: Vec<Variant>,
    /// Pairs of series (A, B) to read out "A against B".
    pub compare: Vec<(String, String)>,
    /// Also read out each series' bias: the relative difference of its most converged point's image mean from the
    /// reference's (for samplers whose error levels off).
    pub bias_readout: bool,
    /// The compared series sweep the same setting, so "at equal setting" read-outs mean something (not so when
    /// one sweeps spp and the other map layers).
    pub equal_setting: bool,
    /// What the kind may spend: its reference spp and film crop (see [`Budget`]).
    pub budget: Budget,
    /// Pairs of series (A, B) rendered with the same seeds whose images are compared with each other directly
    /// (`<kind>-differences.csv`, `<kind>-diff-<a>-vs-<b>.png`; see the module docs).
    pub differences: Vec<(String, String)>,
}

/// A kind's ray budget (see the module docs, "Budgets").
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Budget {
    /// Render only the centred `crop × crop` window of the study's film (same pixel size and view; clamped to the
    /// film), or the whole film.
    pub crop: Option<u32>,
    /// Samples per pixel of the kind's references, or the study's [`StudyConfig::reference_spp`].
    pub reference_spp: Option<u32>,
}

/// How a study runs and where it writes.
#[derive(Debug, Clone, PartialEq)]
pub struct StudyConfig {
    /// Output directory (created if needed).
    pub out_dir: PathBuf,
    /// Where references are cached (default: `out_dir`).
    pub cache_dir: Option<PathBuf>,
    /// Small sweeps and a tiny image (what CI runs).
    pub quick: bool,
    /// Seeds per variant.
    pub seeds: u32,
    /// Samples per pixel of the references.
    pub reference_spp: u32,
    /// Film resolution override (default: the scene's, or [`QUICK_RESOLUTION`] with `quick`).
    pub resolution: Option<[u32; 2]>,
    /// Worker threads.
    pub threads: usize,
    /// Progress bars on stderr.
    pub progress: bool,
    /// Side of the window of `<kind>-crops.png`, pixels (the one with the most shadowed reference pixels).
    pub crop: usize,
}

/// The film of `--quick` unless `--res` says otherwise.
pub const QUICK_RESOLUTION: [u32; 2] = [32, 24];

impl StudyConfig {
    /// The defaults of `cuticle study <kind>`: 3 seeds, references at 256 spp (64 with `quick`), 2 threads.
    pub fn new(out_dir: impl Into<PathBuf>, quick: bool) -> Self {
        StudyConfig {
            out_dir: out_dir.into(),
            cache_dir: None,
            quick,
            seeds: 3,
            reference_spp: if quick { 64 } else { 256 },
            resolution: None,
            threads: 2,
            progress: false,
            crop: CROP,
        }
    }
}

/// What was measured for one variant and seed (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Point {
    /// Index into [`Kind::variants`].
    pub variant: usize,
    /// The seed rendered.
    pub seed: u32,
    /// Set-up seconds of the frame it was rendered on.
    pub setup_s: f64,
    /// Pixel loop (plus shadow-map build) seconds.
    pub render_s: f64,
    /// Of `render_s`, building the shadow maps (0 without maps).
    pub maps_s: f64,
    /// Bytes held by the shadow maps.
    pub map_bytes: usize,
    /// Camera rays.
    pub camera_rays: u64,
    /// Shadow rays.
    pub shadow_rays: u64,
    /// Material-sample and continuation rays.
    pub material_rays: u64,
    /// Error against the variant's reference.
    pub rmse: f64,
    /// Relative MSE against the reference.
    pub relmse: f64,
    /// RMSE over the pixels the reference sees shadowed (NaN if there are none).
    pub rmse_shadowed: f64,
    /// Mean SSIM against the reference.
    pub ssim: f64,
    /// Pixels above 10× the reference's local median.
    pub fireflies: usize,
    /// Pixels with a NaN or infinite channel.
    pub non_finite: usize,
    /// (mean luminance − reference's) / reference's.
    pub mean_diff: f64,
    /// Peak resident memory during the render, bytes.
    pub peak_bytes: Option<u64>,
}

/// Mean and sample standard deviation over seeds.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Stat {
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation (0 with one seed).
    pub sd: f64,
}

impl Stat {
    /// Of `values`.
    pub fn of(values: &[f64]) -> Stat {
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let sd = if values.len() > 1 {
            (values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (n - 1.0)).sqrt()
        } else {
            0.0
        };
        Stat { mean, sd }
    }
}

/// One variant over its seeds.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// Index into [`Kind::variants`].
    pub variant: usize,
    /// Seeds.
    pub seeds: usize,
    /// Set-up seconds.
    pub setup_s: f64,
    /// Render seconds.
    pub render_s: Stat,
    /// Shadow-map build seconds (part of `render_s`).
    pub maps_s: Stat,
    /// Largest shadow-map memory over the seeds, bytes.
    pub map_bytes: usize,
    /// RMSE.
    pub rmse: Stat,
    /// relMSE.
    pub relmse: Stat,
    /// RMSE over the shadowed pixels.
    pub rmse_shadowed: Stat,
    /// SSIM.
    pub ssim: Stat,
    /// Fireflies.
    pub fireflies: Stat,
    /// Non-finite pixels, summed over seeds.
    pub non_finite: usize,
    /// Relative mean difference.
    pub mean_diff: Stat,
    /// Largest peak memory over the seeds, bytes.
    pub peak_bytes: Option<u64>,
}

/// A reference as used by a run.
#[derive(Debug, Clone)]
pub struct ReferenceRun {
    /// Where it is cached.
    pub path: PathBuf,
    /// Read from the cache rather than rendered now.
    pub cached: bool,
    /// Its render seconds (now or when it was cached; `None` if the record is missing).
    pub seconds: Option<f64>,
    /// RMSE of the reference against itself (0: the measures' sanity check).
    pub self_rmse: f64,
    /// Fireflies of the reference against itself (0).
    pub self_fireflies: usize,
    /// RMSE of this reference against a second one with other seeds, estimated from its two halves (see the
    /// module docs, "References"); `None` for a reference of 1 spp or an old cache record.
    pub second_rmse: Option<f64>,
}

/// The outcome of [`run_kind`].
#[derive(Debug, Clone)]
pub struct KindReport {
    /// What was run.
    pub kind: Kind,
    /// Every point, in rendering order.
    pub points: Vec<Point>,
    /// Per variant.
    pub summaries: Vec<Summary>,
    /// Per reference.
    pub references: Vec<ReferenceRun>,
    /// The read-out lines.
    pub readouts: Vec<String>,
    /// Files written: the CSVs, charts (PNG then SVG) and read-outs.
    pub files: Vec<PathBuf>,
    /// Film resolution rendered (the crop's, when the kind crops).
    pub resolution: [u32; 2],
    /// Samples per pixel of the references.
    pub reference_spp: u32,
    /// Per reference: its estimated noise against the smallest RMSE of its variants (the check that the sweep's
    /// errors are not the reference's noise).
    pub reference_checks: Vec<String>,
    /// Per point of the first series of a [`Kind::differences`] pair that the second measured too.
    pub differences: Vec<Difference>,
}

/// Two series' images at the same setting and seed, compared with each other (see [`Kind::differences`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Difference {
    /// Series A (the first of the pair).
    pub a: String,
    /// Series B.
    pub b: String,
    /// The common setting.
    pub x: f64,
    /// The seed.
    pub seed: u32,
    /// RMSE between A's and B's images.
    pub rmse: f64,
    /// A's RMSE against its reference.
    pub rmse_a: f64,
    /// B's RMSE against its reference.
    pub rmse_b: f64,
}

/// Sets the dotted key `path` of `table` to `value`, creating tables on the way.
fn set_key(table: &mut toml::Table, path: &str, value: toml::Value) -> Result<(), StudyError> {
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
struct Prepared {
    text: String,
    scene: Scene,
}

/// The scene file's table with `overrides` applied, as text and as a validated scene.
fn prepare(
    base: &toml::Table,
    overrides: &Overrides,
    source: &Path,
    base_dir: &Path,
) -> Result<Prepared, StudyError> {
    let mut table = base.clone();
    for (k, v) in overrides {
        set_key(&mut table, k, v.clone())?;
    }
    let text = toml::to_string(&table)
        .map_err(|e| StudyError::Config(format!("{}: {e}", source.display())))?;
    let scene = Scene::parse(&text, source, base_dir)?;
    Ok(Prepared { text, scene })
}

/// `text` without what cannot change the pixels of its render (see the module docs, "What is rendered"), for the
/// references' cache key.
fn key_text(text: &str) -> String {
    let mut table: toml::Table = toml::from_str(text).unwrap_or_default();
    if let Some(shadows) = table.get_mut("shadows").and_then(|s| s.as_table_mut()) {
        if shadows.get("mode").and_then(|m| m.as_str()) != Some("deep-opacity") {
            shadows.remove("deep_opacity");
        }
    }
    toml::to_string(&table).unwrap_or_else(|_| text.to_owned())
}

/// The key of the frame set-up of `text` (see [`SETUP_TABLES`]).
fn setup_key(text: &str) -> String {
    let table: toml::Table = toml::from_str(text).unwrap_or_default();
    let kept: toml::Table = table
        .into_iter()
        .filter(|(k, _)| SETUP_TABLES.contains(&k.as_str()))
        .collect();
    toml::to_string(&kept).unwrap_or_default()
}

/// A frame kept while consecutive renders share its set-up.
struct FrameCache {
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
struct Judge {
    reference: Image,
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
struct Measures {
    errors: metrics::Errors,
    ssim: f64,
    fireflies: usize,
    non_finite: usize,
    mean_diff: f64,
}

fn mean_finite(values: &[f64]) -> f64 {
    let finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    finite.iter().sum::<f64>() / finite.len().max(1) as f64
}

fn progress_bar(show: bool, len: u64, prefix: String) -> indicatif::ProgressBar {
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
fn check(kind: &Kind, config: &StudyConfig) -> Result<(), StudyError> {
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

/// Runs `kind` on the scene file at `scene_path` (see the module docs).
pub fn run_kind(
    scene_path: &Path,
    kind: &Kind,
    config: &StudyConfig,
) -> Result<KindReport, StudyError> {
    check(kind, config)?;
    let config = &StudyConfig {
        reference_spp: kind.budget.reference_spp.unwrap_or(config.reference_spp),
        ..config.clone()
    };
    check(kind, config)?;
    let text = std::fs::read_to_string(scene_path).map_err(|source| StudyError::SceneFile {
        path: scene_path.to_path_buf(),
        source,
    })?;
    let base_dir = scene_path
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default();
    // Parsed once as a scene first, so a bad scene file is reported as such before any override.
    let scene = Scene::parse(&text, scene_path, &base_dir)?;
    let base: toml::Table = toml::from_str(&text)
        .map_err(|e| StudyError::Config(format!("{}: {e}", scene_path.display())))?;
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
        let p = prepare(&base, overrides, scene_path, &base_dir)?;
        if resolution == p.scene.film.resolution {
            return Ok(p);
        }
        let mut o = overrides.clone();
        o.extend(crop_overrides(
            &p.scene.camera,
            p.scene.film.resolution,
            resolution,
        ));
        prepare(&base, &o, scene_path, &base_dir)
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

    super::create_dir(&config.out_dir)?;
    let cache_dir = config.cache_dir.as_deref().unwrap_or(&config.out_dir);
    super::create_dir(cache_dir)?;
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
        let key = scene_key(REFERENCE_FORMAT, &key_text(&p.text), &p.scene, &[], "");
        let path = cache_dir.join(format!("reference-{key:016x}.exr"));
        let record = path.with_extension("txt");
        let frame = if path.is_file() {
            None
        } else {
            Some(frames.get(p)?.0)
        };
        let mut second_rmse = None;
        let (reference, cached, seconds) =
            super::cached_reference(&path, p.scene.film.resolution, || {
                let frame = frame.expect("a frame is set up whenever the reference is not cached");
                let options = Options {
                    progress: config.progress,
                };
                let mut seconds = 0.0;
                let mut images = Vec::new();
                for part in parts.iter().chain(parts.is_empty().then_some(p)) {
                    let (image, stats) =
                        pool.install(|| frame.render_with(&part.scene.render_settings(), options));
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

    // Crops for `<kind>-crops.png` (seed 0 of every variant): the window holding the most shadowed pixels of the
    // first reference, when every reference has its size.
    let [w0, h0] = [judges[0].reference.width, judges[0].reference.height];
    let crop_window = judges
        .iter()
        .all(|j| (j.reference.width, j.reference.height) == (w0, h0))
        .then(|| metrics::densest_window(&judges[0].mask, w0, h0, config.crop));
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
        let (image, stats) =
            pool.install(|| frame.render_with(&p.scene.render_settings(), Options::default()));
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

/// The R, G, B values of every pixel of a render, row-major.
fn rgb_pixels(image: &Image) -> Result<Vec<glam::Vec3>, StudyError> {
    let index = |c: &str| {
        image
            .channel_index(c)
            .ok_or_else(|| StudyError::Config(format!("the render has no {c} channel")))
    };
    let [r, g, b] = [index("R")?, index("G")?, index("B")?];
    let n = image.channels.len();
    Ok(image
        .data
        .chunks_exact(n)
        .map(|p| glam::Vec3::new(p[r], p[g], p[b]))
        .collect())
}

/// RMSE between two pixel lists, over R, G, B.
fn rgb_rmse(a: &[glam::Vec3], b: &[glam::Vec3]) -> f64 {
    let sum: f64 = a
        .iter()
        .zip(b)
        .map(|(p, q)| f64::from((*p - *q).length_squared()))
        .sum();
    (sum / (3 * a.len().max(1)) as f64).sqrt()
}

/// For each pair of [`Kind::differences`], each variant of A with a variant of B at the same setting, and each
/// seed both rendered: the RMSE between their images (see the module docs).
fn differences(
    kind: &Kind,
    points: &[Point],
    images: &HashMap<(usize, u32), Vec<glam::Vec3>>,
) -> Vec<Difference> {
    let mut out = Vec::new();
    for (a, b) in &kind.differences {
        for pa in points
            .iter()
            .filter(|p| kind.variants[p.variant].series == *a)
        {
            let x = kind.variants[pa.variant].x;
            let partner = points.iter().find(|p| {
                let v = &kind.variants[p.variant];
                v.series == *b && v.x == x && p.seed == pa.seed
            });
            let Some(pb) = partner else { continue };
            let (Some(ia), Some(ib)) = (
                images.get(&(pa.variant, pa.seed)),
                images.get(&(pb.variant, pb.seed)),
            ) else {
                continue;
            };
            out.push(Difference {
                a: a.clone(),
                b: b.clone(),
                x,
                seed: pa.seed,
                rmse: rgb_rmse(ia, ib),
                rmse_a: pa.rmse,
                rmse_b: pb.rmse,
            });
        }
    }
    out
}

/// Per pair: the images' difference at the largest common setting against their errors.
fn difference_readouts(kind: &Kind, differences: &[Difference]) -> Vec<String> {
    kind.differences
        .iter()
        .filter_map(|(a, b)| {
            let of_pair = || differences.iter().filter(|d| d.a == *a && d.b == *b);
            let x = of_pair().map(|d| d.x).reduce(f64::max)?;
            let at: Vec<&Difference> = of_pair().filter(|d| d.x == x).collect();
            let mean = |f: fn(&Difference) -> f64| at.iter().map(|d| f(d)).sum::<f64>() / at.len() as f64;
            let (d, ea, eb) = (mean(|d| d.rmse), mean(|d| d.rmse_a), mean(|d| d.rmse_b));
            Some(format!(
                "{a} against {b}, same seeds: their images differ by RMSE {d:.2e} at {} ({}; mean of {} seeds), \
                 {:.2e}× the smaller of their RMSEs against the reference ({ea:.2e}, {eb:.2e})",
                x_label(x),
                kind.x_label,
                at.len(),
                d / ea.min(eb)
            ))
        })
        .collect()
}

/// Header of `<kind>-differences.csv`.
pub const DIFFERENCE_HEADER: &str = "series_a,series_b,x,seed,diff_rmse,rmse_a,rmse_b";

/// `<kind>-differences.csv` ([`DIFFERENCE_HEADER`]).
pub fn differences_csv(differences: &[Difference]) -> Result<String, csv::Error> {
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(DIFFERENCE_HEADER.split(','))?;
    for d in differences {
        w.write_record([
            d.a.clone(),
            d.b.clone(),
            x_label(d.x),
            d.seed.to_string(),
            sci(d.rmse),
            sci(d.rmse_a),
            sci(d.rmse_b),
        ])?;
    }
    finish_csv(w)
}

/// `<kind>-diff-<a>-vs-<b>.png` per pair: |A − B| at the largest setting both rendered, their first seed, scaled
/// so that the reference's 99th percentile (largest channel) is white.
fn difference_images(
    kind: &Kind,
    judges: &[Judge],
    images: &HashMap<(usize, u32), Vec<glam::Vec3>>,
    [width, height]: [u32; 2],
    dir: &Path,
) -> Result<Vec<PathBuf>, StudyError> {
    let mut files = Vec::new();
    for (a, b) in &kind.differences {
        let both = images
            .keys()
            .filter(|(i, _)| kind.variants[*i].series == *a)
            .filter_map(|&(i, seed)| {
                let x = kind.variants[i].x;
                let j = (0..kind.variants.len()).find(|&j| {
                    let v = &kind.variants[j];
                    v.series == *b && v.x == x && images.contains_key(&(j, seed))
                })?;
                Some((x, seed, i, j))
            })
            .max_by(|p, q| p.0.total_cmp(&q.0).then(q.1.cmp(&p.1)));
        let Some((_, seed, i, j)) = both else {
            continue;
        };
        let reference = &judges[kind.variants[i].reference].reference;
        let white = figures::p99_largest_channel(rgb_pixels(reference)?)
            .filter(|&w| w > 0.0)
            .unwrap_or(1.0);
        let (w, h) = (width as usize, height as usize);
        let mut out = Image::new(w, h, vec!["R".into(), "G".into(), "B".into()]);
        for (k, (p, q)) in images[&(i, seed)]
            .iter()
            .zip(&images[&(j, seed)])
            .enumerate()
        {
            let d = (*p - *q).abs() / white;
            for c in 0..3 {
                out.set(k % w, k / w, c, d[c]);
            }
        }
        let slug = |s: &str| s.replace(' ', "-");
        let path = dir.join(format!("{}-diff-{}-vs-{}.png", kind.name, slug(a), slug(b)));
        image::write(&path, &out)?;
        files.push(path);
    }
    Ok(files)
}

/// The spp of a reference's two halves (`[spp]` alone when it cannot be split).
fn reference_halves(spp: u32) -> Vec<u32> {
    if spp >= 2 {
        vec![spp / 2, spp - spp / 2]
    } else {
        Vec::new()
    }
}

/// The RMSE of a reference of `na + nb` spp against a second, independent one, from its halves `a` (`na` spp) and
/// `b`: for unbiased halves with per-sample variance σ², E|a − b|² = σ²(1/na + 1/nb) and two independent
/// references of n = na + nb spp differ by 2σ²/n, so RMSE(ref, ref') = RMSE(a, b) · √(2/n / (1/na + 1/nb)).
fn second_reference_rmse(a: &Image, na: f64, b: &Image, nb: f64) -> Option<f64> {
    let mask = vec![false; a.width * a.height];
    let e = metrics::errors(a, b, &mask).ok()?;
    Some(e.rmse * (2.0 / (na + nb) / (1.0 / na + 1.0 / nb)).sqrt())
}

/// `a` with its R, G, B replaced by the spp-weighted mean of `a`'s and `b`'s (the other channels, AOVs, are `a`'s).
fn average_rgb(a: &Image, na: f64, b: &Image, nb: f64) -> Image {
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

/// Per reference: its estimated RMSE against a second reference and the smallest mean RMSE of its variants.
fn reference_checks(kind: &Kind, summaries: &[Summary], runs: &[ReferenceRun]) -> Vec<String> {
    kind.references
        .iter()
        .zip(runs)
        .enumerate()
        .filter_map(|(r, (reference, run))| {
            let noise = run.second_rmse?;
            let smallest = summaries
                .iter()
                .filter(|s| kind.variants[s.variant].reference == r)
                .map(|s| s.rmse.mean)
                .fold(f64::INFINITY, f64::min);
            Some(format!(
                "reference {}: RMSE against a second reference (other seeds) {noise:.2e}, {:.1}× below its \
                 variants' smallest mean RMSE {smallest:.2e}",
                reference.label,
                smallest / noise
            ))
        })
        .collect()
}

/// Per-variant mean and spread of `points`.
pub fn summarise(kind: &Kind, points: &[Point]) -> Vec<Summary> {
    (0..kind.variants.len())
        .filter_map(|i| {
            let ps: Vec<&Point> = points.iter().filter(|p| p.variant == i).collect();
            let first = ps.first()?;
            let stat =
                |f: &dyn Fn(&Point) -> f64| Stat::of(&ps.iter().map(|p| f(p)).collect::<Vec<_>>());
            Some(Summary {
                variant: i,
                seeds: ps.len(),
                setup_s: first.setup_s,
                render_s: stat(&|p| p.render_s),
                maps_s: stat(&|p| p.maps_s),
                map_bytes: ps.iter().map(|p| p.map_bytes).max().unwrap_or(0),
                rmse: stat(&|p| p.rmse),
                relmse: stat(&|p| p.relmse),
                rmse_shadowed: stat(&|p| p.rmse_shadowed),
                ssim: stat(&|p| p.ssim),
                fireflies: stat(&|p| p.fireflies as f64),
                non_finite: ps.iter().map(|p| p.non_finite).sum(),
                mean_diff: stat(&|p| p.mean_diff),
                peak_bytes: ps.iter().filter_map(|p| p.peak_bytes).max(),
            })
        })
        .collect()
}

/// The chart time of a summary: render, plus set-up when the kind says so.
fn chart_time(kind: &Kind, s: &Summary) -> f64 {
    s.render_s.mean
        + if kind.time_includes_setup {
            s.setup_s
        } else {
            0.0
        }
}

/// The (time, RMSE) curve of `series`, sorted by time.
fn curve(kind: &Kind, summaries: &[Summary], series: &str) -> Vec<(f64, f64)> {
    let mut c: Vec<(f64, f64)> = summaries
        .iter()
        .filter(|s| kind.variants[s.variant].series == series)
        .map(|s| (chart_time(kind, s), s.rmse.mean))
        .filter(|(t, e)| *t > 0.0 && *e > 0.0 && t.is_finite() && e.is_finite())
        .collect();
    c.sort_by(|a, b| a.0.total_cmp(&b.0));
    c
}

/// The time at which `curve` (sorted by time) first reaches `error`, interpolated in log–log; `None` if it does
/// not within its measured points, `Some(t0)` bounded above by its first point if it starts below.
pub fn time_to_reach(curve: &[(f64, f64)], error: f64) -> Option<(f64, bool)> {
    let first = curve.first()?;
    if first.1 <= error {
        return Some((first.0, true));
    }
    curve.windows(2).find_map(|w| {
        let ((t0, e0), (t1, e1)) = (w[0], w[1]);
        (e1 <= error && e0 > error).then(|| {
            let f = (error.ln() - e0.ln()) / (e1.ln() - e0.ln());
            ((t0.ln() + f * (t1.ln() - t0.ln())).exp(), false)
        })
    })
}

/// The error of `curve` at time `t`, interpolated in log–log; `None` outside its measured times.
pub fn error_at(curve: &[(f64, f64)], t: f64) -> Option<f64> {
    if let [(t0, e0)] = curve {
        return (*t0 == t).then_some(*e0);
    }
    curve.windows(2).find_map(|w| {
        let ((t0, e0), (t1, e1)) = (w[0], w[1]);
        (t0 <= t && t <= t1 && t1 > t0).then(|| {
            let f = (t.ln() - t0.ln()) / (t1.ln() - t0.ln());
            (e0.ln() + f * (e1.ln() - e0.ln())).exp()
        })
    })
}

/// The read-out lines of `kind` (see the module docs).
pub fn readouts(kind: &Kind, summaries: &[Summary]) -> Vec<String> {
    let mut out = Vec::new();
    for (a, b) in &kind.compare {
        let (ca, cb) = (curve(kind, summaries, a), curve(kind, summaries, b));
        let Some(&(tb, eb)) = cb.last() else { continue };
        let equal_error = match time_to_reach(&ca, eb) {
            Some((ta, bounded)) => {
                let ratio = tb / ta;
                let how = if ratio >= 1.0 {
                    format!("{}{ratio:.2}× less time", if bounded { "≥ " } else { "" })
                } else {
                    format!("{:.2}× more time", 1.0 / ratio)
                };
                format!("{a} reaches {b}'s RMSE {eb:.2e} ({tb:.3} s) in {how}")
            }
            None => format!(
                "{a} does not reach {b}'s RMSE {eb:.2e} in its measured range (best {:.2e})",
                ca.iter().map(|p| p.1).fold(f64::INFINITY, f64::min)
            ),
        };
        // Equal time: at the longest time both curves cover.
        let common = ca.last().map_or(0.0, |p| p.0).min(tb);
        let equal_time = match (error_at(&ca, common), error_at(&cb, common)) {
            (Some(ea), Some(e)) => format!(
                "; at equal time ({common:.3} s) its RMSE is {:.2}× {b}'s",
                ea / e
            ),
            _ => "; their times do not overlap".to_owned(),
        };
        // Equal setting: at the largest swept value both series measured (e.g. the same spp).
        let at_x = |series: &str, x: f64| {
            summaries.iter().find(|s| {
                let v = &kind.variants[s.variant];
                v.series == series && v.x == x
            })
        };
        let equal_setting = summaries
            .iter()
            .filter(|_| kind.equal_setting)
            .filter(|s| kind.variants[s.variant].series == *a)
            .map(|s| kind.variants[s.variant].x)
            .filter(|&x| at_x(b, x).is_some())
            .fold(None, |m: Option<f64>, x| Some(m.map_or(x, |m| m.max(x))))
            .and_then(|x| Some((x, at_x(a, x)?, at_x(b, x)?)))
            .map(|(x, sa, sb)| {
                format!(
                    "; at equal {} ({}) its RMSE is {:.2}× and its time {:.2}× {b}'s",
                    kind.x_label,
                    x_label(x),
                    sa.rmse.mean / sb.rmse.mean,
                    chart_time(kind, sa) / chart_time(kind, sb)
                )
            })
            .unwrap_or_default();
        out.push(equal_error + &equal_time + &equal_setting);
    }
    if kind.bias_readout {
        for name in series_names(kind) {
            let last = summaries
                .iter()
                .filter(|s| kind.variants[s.variant].series == name)
                .max_by(|a, b| {
                    kind.variants[a.variant]
                        .x
                        .total_cmp(&kind.variants[b.variant].x)
                });
            if let Some(s) = last {
                out.push(format!(
                    "{name}: image mean {:+.2} % (sd {:.2} %) of the reference's at {} ({}), RMSE {:.2e}",
                    100.0 * s.mean_diff.mean,
                    100.0 * s.mean_diff.sd,
                    x_label(kind.variants[s.variant].x),
                    kind.x_label,
                    s.rmse.mean
                ));
            }
        }
    }
    out
}

/// Rows of crops: per series, its reference's crop then each variant at seed 0 in sweep order; one exposure for
/// every panel (the first reference crop's 99th percentile maps to 0.9). Top left: the whole first reference with
/// the window outlined.
fn crops_mosaic(
    kind: &Kind,
    judges: &[Judge],
    (cx, cy, cs): (usize, usize, usize),
    crops: &[Option<Vec<glam::Vec3>>],
    config: &StudyConfig,
) -> Result<Image, StudyError> {
    let reference_crops = judges
        .iter()
        .map(|j| figures::crop(&j.reference, cx, cy, cs).map_err(StudyError::Config))
        .collect::<Result<Vec<_>, _>>()?;
    let p99 = figures::p99_largest_channel(reference_crops[0].iter().copied()).unwrap_or(1.0);
    let exposure = if p99 > 0.0 {
        (0.9 / p99).clamp(0.125, 64.0)
    } else {
        1.0
    };
    let mut rows = vec![vec![figures::Panel {
        label: "WHOLE IMAGE".into(),
        rgb: figures::overview(&judges[0].reference, cx, cy, cs, cs),
    }]];
    for name in series_names(kind) {
        let members: Vec<usize> = (0..kind.variants.len())
            .filter(|&i| kind.variants[i].series == name && crops[i].is_some())
            .collect();
        let Some(&first) = members.first() else {
            continue;
        };
        let r = kind.variants[first].reference;
        let mut row = vec![figures::Panel {
            label: format!("REFERENCE {} SPP", config.reference_spp),
            rgb: reference_crops[r].clone(),
        }];
        row.extend(members.iter().map(|&i| {
            figures::Panel {
                label: format!(
                    "{} {}",
                    kind.variants[i].series,
                    x_label(kind.variants[i].x)
                )
                .to_uppercase(),
                rgb: crops[i].clone().unwrap_or_default(),
            }
        }));
        rows.push(row);
    }
    Ok(figures::mosaic(
        &format!(
            "{}: crop {cs}×{cs} at ({cx}, {cy}), seed 0, reference {} spp, exposure ×{exposure:.2}",
            kind.name, config.reference_spp
        ),
        &rows,
        cs,
        exposure,
    )?)
}

/// Colours of the series, in order (Okabe & Ito, then greys).
fn color(i: usize) -> plotters::style::RGBColor {
    const C: [u32; 8] = [
        0x0072b2, 0xd55e00, 0x009e73, 0xcc79a7, 0xe69f00, 0x56b4e9, 0x555555, 0xf0e442,
    ];
    hex(C[i % C.len()])
}

/// Series names in order of first appearance.
fn series_names(kind: &Kind) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for v in &kind.variants {
        if !names.contains(&v.series) {
            names.push(v.series.clone());
        }
    }
    names
}

/// A number as a point label: integers without decimals.
fn x_label(x: f64) -> String {
    if x.fract() == 0.0 && x.abs() < 1e9 {
        format!("{}", x as i64)
    } else {
        format!("{x}")
    }
}

fn error_time_figure(
    kind: &Kind,
    summaries: &[Summary],
    notes: &[String],
    caption: &str,
) -> Result<plot::Figure, StudyError> {
    let series: Vec<ChartSeries> = series_names(kind)
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let mut pts: Vec<figures::Point> = summaries
                .iter()
                .filter(|s| &kind.variants[s.variant].series == name)
                .map(|s| figures::Point {
                    x: chart_time(kind, s),
                    y: s.rmse.mean,
                    label: x_label(kind.variants[s.variant].x),
                })
                .collect();
            pts.sort_by(|a, b| a.x.total_cmp(&b.x));
            ChartSeries {
                label: name.clone(),
                color: color(i),
                points: pts,
            }
        })
        .collect();
    let time = if kind.time_includes_setup {
        "set-up + render time (s)"
    } else {
        "render time (s)"
    };
    let chart = WithNotes {
        chart: figures::error_time_line_chart(
            &format!("{}: RMSE vs time, {caption}", kind.name),
            time,
            "RMSE (mean over seeds)",
            &series,
        ),
        notes: notes.to_vec(),
    };
    let height = 640 + chart.extra_height();
    Ok(plot::render(
        &chart,
        &format!("{} error-time", kind.name),
        (960, height),
    )?)
}

fn time_figure(
    kind: &Kind,
    summaries: &[Summary],
    caption: &str,
) -> Result<plot::Figure, StudyError> {
    let names = series_names(kind);
    let mut series = Vec::new();
    let (mut x_lo, mut x_hi, mut y_lo, mut y_hi) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
    for (i, name) in names.iter().enumerate() {
        let mut pts: Vec<(f64, f64)> = summaries
            .iter()
            .filter(|s| &kind.variants[s.variant].series == name)
            .map(|s| (kind.variants[s.variant].x, chart_time(kind, s)))
            .filter(|(x, y)| *x > 0.0 && *y > 0.0)
            .collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        for &(x, y) in &pts {
            (x_lo, x_hi, y_lo, y_hi) = (x_lo.min(x), x_hi.max(x), y_lo.min(y), y_hi.max(y));
        }
        series.push(Series {
            markers: true,
            ..Series::line(name, color(i), 2, pts)
        });
    }
    let chart = LineChart {
        title: format!("{}: time vs {}, {caption}", kind.name, kind.x_label),
        x: Axis::log_covering(&kind.x_label, x_lo, x_hi),
        y: Axis::log_covering("time (s, mean over seeds)", y_lo, y_hi),
        series,
    };
    Ok(plot::render(
        &chart,
        &format!("{} time", kind.name),
        (960, 640),
    )?)
}

/// Header of `<kind>.csv`.
pub const POINT_HEADER: &str = "kind,series,method,settings,x,seed,setup_s,render_s,camera_rays,shadow_rays,material_rays,rmse,relmse,ssim,fireflies,non_finite,mean_diff,peak_mb,maps_s,map_mb,rmse_shadowed";
/// Header of `<kind>-summary.csv`.
pub const SUMMARY_HEADER: &str = "kind,series,method,settings,x,seeds,setup_s,render_s,render_s_sd,rmse,rmse_sd,relmse,relmse_sd,ssim,ssim_sd,fireflies,fireflies_sd,non_finite,mean_diff,mean_diff_sd,peak_mb,maps_s,map_mb,rmse_shadowed,rmse_shadowed_sd";

#[derive(Serialize)]
struct PointRow<'a> {
    kind: &'a str,
    series: &'a str,
    method: &'a str,
    settings: &'a str,
    x: f64,
    seed: u32,
    setup_s: String,
    render_s: String,
    camera_rays: u64,
    shadow_rays: u64,
    material_rays: u64,
    rmse: String,
    relmse: String,
    ssim: String,
    fireflies: usize,
    non_finite: usize,
    mean_diff: String,
    peak_mb: Option<String>,
    maps_s: String,
    map_mb: String,
    rmse_shadowed: String,
}

#[derive(Serialize)]
struct SummaryRow<'a> {
    kind: &'a str,
    series: &'a str,
    method: &'a str,
    settings: &'a str,
    x: f64,
    seeds: usize,
    setup_s: String,
    render_s: String,
    render_s_sd: String,
    rmse: String,
    rmse_sd: String,
    relmse: String,
    relmse_sd: String,
    ssim: String,
    ssim_sd: String,
    fireflies: String,
    fireflies_sd: String,
    non_finite: usize,
    mean_diff: String,
    mean_diff_sd: String,
    peak_mb: Option<String>,
    maps_s: String,
    map_mb: String,
    rmse_shadowed: String,
    rmse_shadowed_sd: String,
}

fn sci(x: f64) -> String {
    format!("{x:.6e}")
}

fn mb(b: Option<u64>) -> Option<String> {
    b.map(|b| format!("{:.1}", b as f64 / 1e6))
}

fn finish_csv(writer: csv::Writer<Vec<u8>>) -> Result<String, csv::Error> {
    let bytes = writer.into_inner().map_err(|e| e.into_error())?;
    String::from_utf8(bytes)
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, e).into())
}

/// `<kind>.csv` ([`POINT_HEADER`]).
pub fn points_csv(kind: &Kind, points: &[Point]) -> Result<String, csv::Error> {
    let mut w = csv::Writer::from_writer(Vec::new());
    if points.is_empty() {
        w.write_record(POINT_HEADER.split(','))?;
    }
    for p in points {
        let v = &kind.variants[p.variant];
        w.serialize(PointRow {
            kind: &kind.name,
            series: &v.series,
            method: &v.method,
            settings: &v.settings,
            x: v.x,
            seed: p.seed,
            setup_s: format!("{:.4}", p.setup_s),
            render_s: format!("{:.4}", p.render_s),
            camera_rays: p.camera_rays,
            shadow_rays: p.shadow_rays,
            material_rays: p.material_rays,
            rmse: sci(p.rmse),
            relmse: sci(p.relmse),
            ssim: format!("{:.6}", p.ssim),
            fireflies: p.fireflies,
            non_finite: p.non_finite,
            mean_diff: sci(p.mean_diff),
            peak_mb: mb(p.peak_bytes),
            maps_s: format!("{:.4}", p.maps_s),
            map_mb: format!("{:.3}", p.map_bytes as f64 / 1e6),
            rmse_shadowed: sci(p.rmse_shadowed),
        })?;
    }
    finish_csv(w)
}

/// `<kind>-summary.csv` ([`SUMMARY_HEADER`]).
pub fn summary_csv(kind: &Kind, summaries: &[Summary]) -> Result<String, csv::Error> {
    let mut w = csv::Writer::from_writer(Vec::new());
    if summaries.is_empty() {
        w.write_record(SUMMARY_HEADER.split(','))?;
    }
    for s in summaries {
        let v = &kind.variants[s.variant];
        w.serialize(SummaryRow {
            kind: &kind.name,
            series: &v.series,
            method: &v.method,
            settings: &v.settings,
            x: v.x,
            seeds: s.seeds,
            setup_s: format!("{:.4}", s.setup_s),
            render_s: format!("{:.4}", s.render_s.mean),
            render_s_sd: format!("{:.4}", s.render_s.sd),
            rmse: sci(s.rmse.mean),
            rmse_sd: sci(s.rmse.sd),
            relmse: sci(s.relmse.mean),
            relmse_sd: sci(s.relmse.sd),
            ssim: format!("{:.6}", s.ssim.mean),
            ssim_sd: format!("{:.6}", s.ssim.sd),
            fireflies: format!("{:.2}", s.fireflies.mean),
            fireflies_sd: format!("{:.2}", s.fireflies.sd),
            non_finite: s.non_finite,
            mean_diff: sci(s.mean_diff.mean),
            mean_diff_sd: sci(s.mean_diff.sd),
            peak_mb: mb(s.peak_bytes),
            maps_s: format!("{:.4}", s.maps_s.mean),
            map_mb: format!("{:.3}", s.map_bytes as f64 / 1e6),
            rmse_shadowed: sci(s.rmse_shadowed.mean),
            rmse_shadowed_sd: sci(s.rmse_shadowed.sd),
        })?;
    }
    finish_csv(w)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a power law e = t^(-1/2) the log–log interpolation is exact.
    #[test]
    fn read_outs_interpolate_in_log_log() {
        let a: Vec<(f64, f64)> = [1.0f64, 4.0, 16.0]
            .iter()
            .map(|&t| (t, t.powf(-0.5)))
            .collect();
        let (t, bounded) = time_to_reach(&a, 8.0f64.powf(-0.5)).unwrap();
        assert!(!bounded && (t - 8.0).abs() < 1e-9, "{t}");
        assert!((error_at(&a, 2.0).unwrap() - 2.0f64.powf(-0.5)).abs() < 1e-12);
        assert_eq!(time_to_reach(&a, 0.01), None);
        assert_eq!(time_to_reach(&a, 2.0), Some((1.0, true)));
        assert_eq!(error_at(&a, 32.0), None);
    }

    #[test]
    fn stat_is_mean_and_sample_deviation() {
        let s = Stat::of(&[1.0, 2.0, 3.0]);
        assert_eq!((s.mean, s.sd), (2.0, 1.0));
        assert_eq!(Stat::of(&[5.0]).sd, 0.0);
    }

    #[test]
    fn overrides_replace_dotted_keys_and_whole_tables() {
        let mut t: toml::Table =
            toml::from_str("[material]\nmodel = \"marschner\"\ncolor = [1, 0, 0]\n").unwrap();
        set_key(&mut t, "integrator.light_samples", toml::Value::Integer(16)).unwrap();
        set_key(
            &mut t,
            "material",
            toml::Value::Table(toml::from_str("model = \"chiang\"").unwrap()),
        )
        .unwrap();
        assert_eq!(t["integrator"]["light_samples"].as_integer(), Some(16));
        assert_eq!(t["material"].as_table().unwrap().len(), 1);
        assert!(set_key(&mut t, "material.model.x", toml::Value::Integer(1)).is_err());
    }
}
