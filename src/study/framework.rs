//! The one study framework: a study **kind** is a named list of variants (a method and its settings,
//! each a set of scene-key overrides) × seeds, measured against converged references. Every kind of
//! `cuticle study` ([`super::kinds`]) is data for [`run_kind`]; this module renders, measures and writes.
//!
//! # What is rendered
//!
//! A variant is the scene ([`super::SceneFile`]: a scene file, or the built-in default scene) with some keys replaced ([`Overrides`]: dotted TOML paths, e.g.
//! `integrator.light_samples = 16` or a whole `material` table), re-parsed and validated like a scene file, so a
//! variant can change anything a scene can say. Each variant is rendered with [`StudyConfig::seeds`] seeds (the
//! scene's `film.seed` + 0, 1, 2, …). Each variant names one of its kind's references: the scene with that
//! reference's overrides at the kind's reference spp ([`StudyConfig::reference_spp_override`], else
//! [`Budget::reference_spp`], else [`StudyConfig::reference_spp`]). A reference is cached as `reference-<hash>.exr`
//! (with `reference-<hash>.txt` holding the seconds it took and its noise, below) in the cache directory
//! ([`StudyConfig::cache`]: `cache/` in the output directory unless the study names another), the hash
//! ([`super::cache`]) covering the overridden scene text as parsed and re-serialised, the scene file's directory
//! (or the default scene's name) and a format version: the hair and map
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
//! - `<kind>.csv`: one row per point ([`POINT_HEADER`]); `<kind>-summary.csv`: one row per variant
//!   ([`SUMMARY_HEADER`]);
//! - `<kind>-error-time.png/.svg`: mean RMSE against mean time, log–log, one series per method, each point labelled
//!   with its swept setting, and under the chart the **read-outs** ([`readouts()`]);
//! - `<kind>-time.png/.svg`: mean render time against the swept setting (the thesis' figure 17 for `samples`);
//! - for a kind whose variants are unrelated cases rather than a sweep ([`Kind::categories`], e.g. `stress`), bar
//!   charts instead of both: `<kind>-rmse.png/.svg` (mean RMSE per case, a bar per series, the read-outs under it)
//!   and `<kind>-time.png/.svg` (mean render time per case);
//! - `<kind>-crops.png` (when every reference has the same size): the crop window ([`StudyConfig::crop`] pixels
//!   square, centred on the hair of the first reference: [`super::figures::hair_window`]) of each reference and of
//!   each variant at seed 0, and the whole first reference with the window outlined;
//! - `<kind>-readouts.txt`: the read-outs as text;
//! - for kinds with [`Kind::differences`] (pairs of series rendered with the same seeds, e.g. Embree and the BVH):
//!   `<kind>-differences.csv` ([`DIFFERENCE_HEADER`]: per common setting and seed the RMSE between the two
//!   images, beside each one's RMSE against the reference: far below them means the same image), a read-out line
//!   per pair, and `<kind>-diff-<a>-vs-<b>.png`: |A − B| at the largest common setting, seed 0, scaled so that the
//!   reference's 99th percentile is white (structure in it would mean the two trace differently; isolated pixels
//!   are paths sent elsewhere by one graze).
//!
//! [`KindReport::files`] lists them in the order they were written; the cached references are not among them.
//!
//! # Read-outs
//!
//! For each pair (A, B) a kind compares: **equal error** — the time at which A's curve reaches the error of B's
//! last (most converged) point, by linear interpolation between A's measured points in log time and log error;
//! written "A reaches B's RMSE e (at t s) in N× less time" — and **equal time** — A's error at B's last time, by
//! the same interpolation, as a ratio to B's — and **equal setting** — A's error and time as ratios to B's at the
//! largest swept value both measured (equal samples, for most kinds). Outside A's measured range nothing is
//! extrapolated: the line says so ("A does not reach B's RMSE e in its measured range (best e')", the two printed
//! with as many digits as show them apart). A ratio within 1 % of 1 is written "the same" ("in the same time");
//! otherwise "N× less time" (N > 1) or "N× more time". Series names ending in s are plurals ("light samples
//! reach material samples' RMSE …").

mod charts;
mod differences;
mod readouts;
mod run;
mod tables;

pub use differences::{differences_csv, DIFFERENCE_HEADER};
pub use readouts::{error_at, readouts, summarise, time_to_reach};
pub use run::{crop_overrides, run_kind};
pub(crate) use tables::finish_csv;
pub use tables::{points_csv, summary_csv, POINT_HEADER, SUMMARY_HEADER};

use std::path::PathBuf;

/// Dotted scene keys and the values that replace them, in order.
pub type Overrides = Vec<(String, toml::Value)>;

/// Added to the scene's seed for the references' first half (the second takes the next seed), so no variant shares
/// its samples with a reference.
pub const REFERENCE_SEED_OFFSET: u32 = 0x0001_0001;
/// Bumped when the references' recipe changes, so old cached files are not reused.
const REFERENCE_FORMAT: &str = "cuticle study reference v2 (two halves)";
/// Side of the crop window of `<kind>-crops.png` by default, pixels (clamped to the image).
pub const CROP: usize = 64;
/// The folder of the output directory that holds the cached references unless the study names another.
pub const CACHE_DIR: &str = "cache";
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
    /// The names of the values of [`Variant::x`] when they are unrelated cases, not a swept setting (x = 1 is the
    /// first name): charts draw a bar per case and series instead of curves, and labels name the case. Empty for a
    /// sweep.
    pub categories: Vec<String>,
}

impl Kind {
    /// How a value of [`Variant::x`] is written in labels: its category's name, or the number.
    pub fn x_name(&self, x: f64) -> String {
        let index = x - 1.0;
        if index >= 0.0 && index.fract() == 0.0 {
            if let Some(name) = self.categories.get(index as usize) {
                return name.clone();
            }
        }
        charts::x_label(x)
    }
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
    /// Where references are cached (default: [`CACHE_DIR`] in `out_dir`; see [`StudyConfig::cache`]).
    pub cache_dir: Option<PathBuf>,
    /// Small sweeps and a tiny image (what CI runs).
    pub quick: bool,
    /// Seeds per variant.
    pub seeds: u32,
    /// Samples per pixel of the references of kinds without a budget of their own ([`Budget::reference_spp`]:
    /// every kind of a full run has one; `--quick` runs have none).
    pub reference_spp: u32,
    /// Samples per pixel of every reference, over the kinds' budgets and `reference_spp` (an explicit
    /// `--reference-spp`).
    pub reference_spp_override: Option<u32>,
    /// Film resolution override (default: the scene's, or [`QUICK_RESOLUTION`] with `quick`).
    pub resolution: Option<[u32; 2]>,
    /// Worker threads.
    pub threads: usize,
    /// Progress bars on stderr.
    pub progress: bool,
    /// Side of the window of `<kind>-crops.png`, pixels (centred on the hair: [`super::figures::hair_window`]).
    pub crop: usize,
}

/// The film of `--quick` unless `--res` says otherwise.
pub const QUICK_RESOLUTION: [u32; 2] = [32, 24];

impl StudyConfig {
    /// The defaults of `cuticle study <kind>`: 3 seeds, references at 256 spp (64 with `quick`) where a kind has no
    /// budget of its own, 2 threads (the command line asks for one per core).
    pub fn new(out_dir: impl Into<PathBuf>, quick: bool) -> Self {
        StudyConfig {
            out_dir: out_dir.into(),
            cache_dir: None,
            quick,
            seeds: 3,
            reference_spp: if quick { 64 } else { 256 },
            reference_spp_override: None,
            resolution: None,
            threads: 2,
            progress: false,
            crop: CROP,
        }
    }

    /// Where references are cached: `cache_dir`, or [`CACHE_DIR`] in the output directory.
    pub fn cache(&self) -> PathBuf {
        self.cache_dir
            .clone()
            .unwrap_or_else(|| self.out_dir.join(CACHE_DIR))
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
    /// Files written, in order: the CSVs, charts (PNG then SVG), crops, differences and read-outs (not the cached
    /// references).
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

#[cfg(test)]
mod tests {
    use super::run::set_key;
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
