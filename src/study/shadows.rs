//! `cuticle study shadows SCENE -o DIR`: how good and how fast are deep opacity maps (`shadows = "deep-opacity"`)
//! against ray-traced shadows, on one scene (issue 6)?
//!
//! # What is rendered
//!
//! The scene's hair, lights, material and integrator settings are kept; only the shadow mode, its settings, the
//! samples per pixel and (optionally) the film resolution change. On one Embree BVH and one thread pool:
//!
//! 1. **Reference**: ray-traced shadows with **exact** transmittance (∏(1 − opacity) along each shadow ray, smoother
//!    than the stochastic mode and converging to the same value), at `reference_spp` samples per pixel, with a
//!    seed different from the variants' (the scene's seed + [`REFERENCE_SEED_OFFSET`]), so a variant does not share
//!    its first samples with the reference. Cached as `reference-<hash>.exr` in the cache directory (default: the
//!    output directory), where the hash ([`super::cache::Fnv1a`]) covers the scene file's text (parsed, without its
//!    `[shadows]` table, which the reference overrides), its directory, the film resolution, spp and seed actually
//!    used and a format version. It does **not** cover the hair or map files nor the renderer's code: delete the
//!    file after changing them.
//! 2. **No shadows** (`shadows = "none"`) at `dom_spp`: the time of shading without any visibility, and the error
//!    of ignoring self-shadowing.
//! 3. **Ray traced** (`shadows = "raytraced"`, the scene's own `transmittance`) at each of `rt_spp`.
//! 4. **Deep opacity maps** at `dom_spp`: over `layers` at resolution `layer_resolution`, and over `resolutions` at
//!    `resolution_layers` layers (a setting in both series is rendered once). The other map settings are the
//!    scene's `[shadows.deep_opacity]`. In this mode the integrator uses light samples only (see
//!    [`crate::render::settings`]), so a DOM variant's error is the maps' bias plus light-sampling noise at `dom_spp`.
//!
//! # What is measured, per variant ([`Row`])
//!
//! - `build_s`: building the shadow maps ([`RenderStats::shadow_build_seconds`], 0 without maps); `render_s`: the
//!   pixel loop ([`RenderStats::seconds`]); `total_s` = their sum. Hair loading and the BVH build are shared and not
//!   counted. One run each, wall clock: on a shared machine expect ±10 % noise.
//! - `rmse`, `relmse`, `rmse_shadowed`, `relmse_shadowed`: [`super::metrics`] against the reference, over the whole
//!   image and over the pixels the reference sees shadowed (`shadow.Y` < ½, alpha > 0). The reference has noise of
//!   its own (at 256 spp, about a quarter of a 16-spp image's RMSE): errors below it are not resolved.
//! - `map_mb`: memory held by the shadow maps ([`RenderStats::shadow_map_bytes`], 10⁶ bytes).
//! - `vmhwm_mb`: the process's peak resident memory (Linux `VmHWM`) read after the variant. It is process-wide
//!   and never decreases, so it is the peak over this variant *and everything rendered before it*, reference
//!   included; only an increase over the previous row can be blamed on this variant. Use `map_mb` to compare.
//!
//! # What is written into the output directory
//!
//! - `shadows.csv`: one row per variant, columns
//!   `mode,spp,layers,resolution,build_s,render_s,total_s,rmse,relmse,rmse_shadowed,relmse_shadowed,map_mb,vmhwm_mb`
//!   (`layers` and `resolution` empty for non-map modes);
//! - `shadows-error-time.png` and `.svg`: RMSE against total time, log–log, a series for ray tracing over spp, one for the
//!   maps over layers, one over resolution, and the no-shadow point;
//! - `shadows-crops.png`: the `crop × crop` window (default 128, smaller for small images) holding the most
//!   shadowed reference pixels, from the reference, then every variant, one row per series, at one exposure set
//!   from the reference crop; top left, the whole reference with the window outlined;
//! - `reference-<hash>.exr` (unless a cache directory is given): the reference, every AOV.

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::Vec3;
use plotters::style::RGBColor;
use serde::Serialize;

use super::cache::write_text;
use super::figures::{self, ChartSeries, Panel, Point};
use super::StudyError;
use crate::accel::Backend;
use crate::image::{self, Image};
use crate::measure::metrics::{self, Errors};
use crate::measure::peak_rss_bytes;
use crate::plot::{self, hex, Figure};
use crate::render::{thread_pool, Frame, Options, RenderStats};
use crate::scene::{Overrides, Scene, ShadowMode, TransmittanceMode};

/// Added to the scene's seed for the reference render.
pub const REFERENCE_SEED_OFFSET: u32 = 0x0001_0001;
/// Bumped when the reference's recipe changes, so old cached files are not reused.
const REFERENCE_FORMAT: &str = "cuticle study shadows reference v1";

/// What the study renders and where it writes (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct ShadowStudyConfig {
    /// Output directory (created if needed).
    pub out_dir: PathBuf,
    /// Where the reference is cached (default: `out_dir`).
    pub cache_dir: Option<PathBuf>,
    /// Samples per pixel of the reference.
    pub reference_spp: u32,
    /// Samples per pixel of the ray-traced variants.
    pub rt_spp: Vec<u32>,
    /// Layer counts of the first map series.
    pub layers: Vec<u32>,
    /// Map resolution of the layer series.
    pub layer_resolution: u32,
    /// Map resolutions of the second map series.
    pub resolutions: Vec<u32>,
    /// Layers of the resolution series.
    pub resolution_layers: u32,
    /// Samples per pixel of the map variants and of the no-shadow variant.
    pub dom_spp: u32,
    /// Film resolution override (default: the scene's).
    pub film_resolution: Option<[u32; 2]>,
    /// Worker threads.
    pub threads: usize,
    /// Side of the crop window, pixels (clamped to the image).
    pub crop: usize,
    /// One line per variant (and a progress bar for the reference) on stderr.
    pub progress: bool,
    /// Strand tracer (default: the scene's). The cached reference does not depend on it (both backends converge
    /// to the same image).
    pub backend: Option<Backend>,
}

impl ShadowStudyConfig {
    /// The defaults of `cuticle study shadows`, writing into `out_dir`.
    pub fn new(out_dir: impl Into<PathBuf>) -> Self {
        ShadowStudyConfig {
            out_dir: out_dir.into(),
            cache_dir: None,
            reference_spp: 256,
            rt_spp: vec![1, 4, 16, 64],
            layers: vec![4, 8, 16, 32, 64],
            layer_resolution: 1024,
            resolutions: vec![256, 512, 1024, 2048, 4096],
            resolution_layers: 16,
            dom_spp: 16,
            film_resolution: None,
            threads: 2,
            crop: 128,
            progress: false,
            backend: None,
        }
    }
}

/// One rendering of the scene: a shadow mode and its settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Variant {
    /// The shadow mode.
    pub mode: ShadowMode,
    /// Samples per pixel.
    pub spp: u32,
    /// Map layers (0 unless deep-opacity).
    pub layers: u32,
    /// Map resolution (0 unless deep-opacity).
    pub resolution: u32,
}

impl Variant {
    /// The mode as written in scenes.
    pub fn mode_name(&self) -> &'static str {
        match self.mode {
            ShadowMode::Raytraced => "raytraced",
            ShadowMode::DeepOpacity => "deep-opacity",
            ShadowMode::None => "none",
        }
    }

    /// A short label for progress lines and crops, e.g. `RT 16 SPP`, `DOM 8L 1024`.
    pub fn label(&self) -> String {
        match self.mode {
            ShadowMode::Raytraced => format!("RT {} SPP", self.spp),
            ShadowMode::DeepOpacity => format!("DOM {}L {}", self.layers, self.resolution),
            ShadowMode::None => "NO SHADOWS".to_owned(),
        }
    }

    /// The scene rendered for this variant.
    fn scene(&self, base: &Scene) -> Result<Scene, StudyError> {
        let mut scene = base.clone();
        scene.film.spp = self.spp;
        scene.shadows.mode = self.mode;
        if self.mode == ShadowMode::DeepOpacity {
            scene.shadows.deep_opacity.layers = self.layers;
            scene.shadows.deep_opacity.resolution = self.resolution;
        }
        Ok(scene.revalidate()?)
    }
}

/// What was measured for one variant (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Row {
    /// What was rendered.
    pub variant: Variant,
    /// Shadow-map build, seconds.
    pub build_s: f64,
    /// Pixel loop, seconds.
    pub render_s: f64,
    /// Errors against the reference.
    pub errors: Errors,
    /// Bytes held by the shadow maps.
    pub map_bytes: usize,
    /// The process's peak resident memory so far, bytes (if the platform reports it).
    pub vmhwm_bytes: Option<u64>,
}

impl Row {
    /// Build plus render, seconds.
    pub fn total_s(&self) -> f64 {
        self.build_s + self.render_s
    }
}

/// The outcome of [`run`].
#[derive(Debug, Clone)]
pub struct ShadowStudyReport {
    /// One row per variant, in the order rendered.
    pub rows: Vec<Row>,
    /// The reference (every AOV).
    pub reference: Image,
    /// Where the reference is cached.
    pub reference_path: PathBuf,
    /// The reference was read from the cache rather than rendered.
    pub reference_cached: bool,
    /// Pixel-loop time of the reference when it was rendered now, seconds.
    pub reference_seconds: Option<f64>,
    /// Pixels the reference sees shadowed.
    pub shadowed_pixels: usize,
    /// The crop window: (x0, y0, size).
    pub crop: (usize, usize, usize),
    /// The files written: the CSV, the chart, the crops.
    pub csv: PathBuf,
    /// The error-against-time chart.
    pub chart: PathBuf,
    /// The mosaic of crops.
    pub crops: PathBuf,
}

/// The variants of `config`, in rendering order, each once: no shadows, ray traced by spp, maps by layers, maps by
/// resolution.
pub fn variants(config: &ShadowStudyConfig) -> Vec<Variant> {
    let mut out = vec![Variant {
        mode: ShadowMode::None,
        spp: config.dom_spp,
        layers: 0,
        resolution: 0,
    }];
    out.extend(config.rt_spp.iter().map(|&spp| Variant {
        mode: ShadowMode::Raytraced,
        spp,
        layers: 0,
        resolution: 0,
    }));
    let dom = |layers, resolution| Variant {
        mode: ShadowMode::DeepOpacity,
        spp: config.dom_spp,
        layers,
        resolution,
    };
    out.extend(
        config
            .layers
            .iter()
            .map(|&l| dom(l, config.layer_resolution)),
    );
    out.extend(
        config
            .resolutions
            .iter()
            .map(|&r| dom(config.resolution_layers, r)),
    );
    let mut unique: Vec<Variant> = Vec::with_capacity(out.len());
    for v in out {
        if !unique.contains(&v) {
            unique.push(v);
        }
    }
    unique
}

/// The cache key of the reference of `scene` (already carrying the reference's spp, seed and resolution), whose
/// file held `text`. The scene's `[shadows]` table is left out (the reference sets its own mode and transmittance,
/// and map settings do not affect it), so changing map settings in the scene keeps the cached reference; the rest
/// of the text is hashed as parsed and re-serialised (sorted keys, no comments), so comments and layout do not
/// matter either.
fn reference_key(text: &str, scene: &Scene) -> u64 {
    super::cache::scene_key(
        REFERENCE_FORMAT,
        text,
        scene,
        &["shadows"],
        &format!(
            "resolution={:?};spp={};seed={};mode=raytraced;transmittance=exact",
            scene.film.resolution, scene.film.spp, scene.film.seed
        ),
    )
}

/// Checks the study's own settings.
fn check(config: &ShadowStudyConfig) -> Result<(), StudyError> {
    let bad = |m: String| Err(StudyError::Config(m));
    if config.rt_spp.is_empty() && config.layers.is_empty() && config.resolutions.is_empty() {
        return bad(
            "nothing to compare: --rt-spp, --layers and --resolutions are all empty".into(),
        );
    }
    let spp = [config.reference_spp, config.dom_spp]
        .into_iter()
        .chain(config.rt_spp.iter().copied());
    if let Some(s) = spp.into_iter().find(|&s| s == 0) {
        return bad(format!("samples per pixel must be at least 1, got {s}"));
    }
    if config.threads == 0 {
        return bad("--threads must be at least 1".into());
    }
    if config.crop == 0 {
        return bad("--crop must be at least 1 pixel".into());
    }
    Ok(())
}

/// Runs the study on the scene file at `scene_path` (see the module docs).
pub fn run(scene_path: &Path, config: &ShadowStudyConfig) -> Result<ShadowStudyReport, StudyError> {
    check(config)?;
    let (text, scene) = super::load_scene(scene_path, config.film_resolution)?;
    let scene = match config.backend {
        Some(backend) => scene.apply(&Overrides {
            backend: Some(backend),
            ..Overrides::default()
        })?,
        None => scene,
    };
    let variants = variants(config);
    // Every variant's settings are checked before anything is rendered.
    let scenes = variants
        .iter()
        .map(|v| v.scene(&scene))
        .collect::<Result<Vec<_>, _>>()?;
    let mut reference_scene = scene.clone();
    reference_scene.film.spp = config.reference_spp;
    reference_scene.film.seed = scene.film.seed.wrapping_add(REFERENCE_SEED_OFFSET);
    reference_scene.shadows.mode = ShadowMode::Raytraced;
    reference_scene.shadows.transmittance = TransmittanceMode::Exact;
    let reference_scene = reference_scene.revalidate()?;

    super::create_dir(&config.out_dir)?;
    let cache_dir = config.cache_dir.as_deref().unwrap_or(&config.out_dir);
    super::create_dir(cache_dir)?;

    let say = |line: String| {
        if config.progress {
            eprintln!("{line}");
        }
    };
    let pool = thread_pool(Some(config.threads))?;
    let frame = Frame::load(scene.resolve()?)?;
    let render_scene = |s: &Scene, progress: bool| -> (Image, RenderStats) {
        pool.install(|| frame.render_with(&s.render_settings(), Options { progress }))
    };

    // The reference.
    let key = reference_key(&text, &reference_scene);
    let reference_path = cache_dir.join(format!("reference-{key:016x}.exr"));
    let [width, height] = scene.film.resolution;
    if reference_path.is_file() {
        say(format!("reference: reusing {}", reference_path.display()));
    } else {
        say(format!(
            "reference: ray traced, exact transmittance, {} spp, {width}x{height} -> {}",
            config.reference_spp,
            reference_path.display()
        ));
    }
    let (reference, reference_cached, reference_seconds) =
        super::cached_reference(&reference_path, scene.film.resolution, || {
            let start = Instant::now();
            let (image, stats) = render_scene(&reference_scene, config.progress);
            say(format!(
                "reference: {:.2} s ({:.2} s with writing)",
                stats.seconds,
                start.elapsed().as_secs_f64()
            ));
            (image, stats.seconds)
        })?;
    let mask = metrics::shadowed_mask(&reference).map_err(StudyError::Config)?;
    let shadowed_pixels = mask.iter().filter(|&&m| m).count();
    let crop_window =
        metrics::densest_window(&mask, reference.width, reference.height, config.crop);
    let (cx, cy, cs) = crop_window;
    say(format!(
        "reference: {shadowed_pixels} shadowed pixels of {}; crop {cs}x{cs} at ({cx}, {cy})",
        mask.len()
    ));
    let reference_crop = figures::crop(&reference, cx, cy, cs).map_err(StudyError::Config)?;

    // The variants.
    let mut rows = Vec::with_capacity(variants.len());
    let mut crops = Vec::with_capacity(variants.len());
    for (i, (variant, vscene)) in variants.iter().zip(&scenes).enumerate() {
        let (image, stats) = render_scene(vscene, false);
        let errors = metrics::errors(&image, &reference, &mask).map_err(StudyError::Config)?;
        crops.push(figures::crop(&image, cx, cy, cs).map_err(StudyError::Config)?);
        let row = Row {
            variant: *variant,
            build_s: stats.shadow_build_seconds,
            render_s: stats.seconds,
            errors,
            map_bytes: stats.shadow_map_bytes,
            vmhwm_bytes: peak_rss_bytes(),
        };
        say(format!(
            "[{}/{}] {:<14} {:>3} spp: build {:.3} s, render {:.3} s, rmse {:.5} (shadowed {:.5}), maps {:.1} MB",
            i + 1,
            variants.len(),
            variant.label(),
            variant.spp,
            row.build_s,
            row.render_s,
            errors.rmse,
            errors.rmse_shadowed,
            row.map_bytes as f64 / 1e6
        ));
        rows.push(row);
    }

    let csv = config.out_dir.join("shadows.csv");
    write_text(&csv, &to_csv(&rows)?)?;
    let [chart, _] = plot::write_figure(
        &chart_figure(&scene, config, &rows)?,
        &config.out_dir,
        "shadows-error-time",
    )?;
    let crops_path = config.out_dir.join("shadows-crops.png");
    image::write(
        &crops_path,
        &crops_image(
            &reference,
            reference_crop,
            crop_window,
            config,
            &variants,
            &crops,
        )?,
    )?;
    say(format!(
        "wrote {}, {} and {}",
        csv.display(),
        chart.display(),
        crops_path.display()
    ));
    Ok(ShadowStudyReport {
        rows,
        reference,
        reference_path,
        reference_cached,
        reference_seconds,
        shadowed_pixels,
        crop: crop_window,
        csv,
        chart,
        crops: crops_path,
    })
}

/// The CSV header (see the module docs for the columns).
pub const CSV_HEADER: &str = "mode,spp,layers,resolution,build_s,render_s,total_s,rmse,relmse,rmse_shadowed,relmse_shadowed,map_mb,vmhwm_mb";

/// One line of `shadows.csv`, in [`CSV_HEADER`] order (the field names are the header). Times and memory are
/// written with fixed decimals, errors in scientific notation with 7 significant digits; `layers` and
/// `resolution` are empty for non-map modes, `vmhwm_mb` where the platform does not report it.
#[derive(Debug, Serialize)]
struct CsvRow {
    mode: &'static str,
    spp: u32,
    layers: Option<u32>,
    resolution: Option<u32>,
    build_s: String,
    render_s: String,
    total_s: String,
    rmse: String,
    relmse: String,
    rmse_shadowed: String,
    relmse_shadowed: String,
    map_mb: String,
    vmhwm_mb: Option<String>,
}

impl CsvRow {
    fn new(r: &Row) -> CsvRow {
        let v = &r.variant;
        let maps = v.mode == ShadowMode::DeepOpacity;
        let e = &r.errors;
        let sci = |x: f64| format!("{x:.6e}");
        CsvRow {
            mode: v.mode_name(),
            spp: v.spp,
            layers: maps.then_some(v.layers),
            resolution: maps.then_some(v.resolution),
            build_s: format!("{:.4}", r.build_s),
            render_s: format!("{:.4}", r.render_s),
            total_s: format!("{:.4}", r.total_s()),
            rmse: sci(e.rmse),
            relmse: sci(e.relmse),
            rmse_shadowed: sci(e.rmse_shadowed),
            relmse_shadowed: sci(e.relmse_shadowed),
            map_mb: format!("{:.3}", r.map_bytes as f64 / 1e6),
            vmhwm_mb: r.vmhwm_bytes.map(|b| format!("{:.1}", b as f64 / 1e6)),
        }
    }
}

/// The rows as CSV text, with [`CSV_HEADER`] (written by the `csv` crate from [`CsvRow`]s).
pub fn to_csv(rows: &[Row]) -> Result<String, csv::Error> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    if rows.is_empty() {
        // `serialize` writes the header with the first row.
        writer.write_record(CSV_HEADER.split(','))?;
    }
    for r in rows {
        writer.serialize(CsvRow::new(r))?;
    }
    let bytes = writer.into_inner().map_err(|e| e.into_error())?;
    String::from_utf8(bytes)
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, e).into())
}

/// Series colours (Okabe & Ito).
fn colors() -> [RGBColor; 4] {
    [hex(0x0072b2), hex(0xd55e00), hex(0x009e73), hex(0x555555)]
}

/// The rows of each series, in the order of the configured lists: ray traced, maps by layers, maps by resolution,
/// no shadows.
fn series_rows<'a>(config: &ShadowStudyConfig, rows: &'a [Row]) -> [Vec<&'a Row>; 4] {
    let find = |pred: &dyn Fn(&Variant) -> bool| rows.iter().find(|r| pred(&r.variant));
    let dom = ShadowMode::DeepOpacity;
    [
        config
            .rt_spp
            .iter()
            .filter_map(|&s| find(&|v| v.mode == ShadowMode::Raytraced && v.spp == s))
            .collect(),
        config
            .layers
            .iter()
            .filter_map(|&l| {
                find(&|v| v.mode == dom && v.layers == l && v.resolution == config.layer_resolution)
            })
            .collect(),
        config
            .resolutions
            .iter()
            .filter_map(|&r| {
                find(&|v| {
                    v.mode == dom && v.resolution == r && v.layers == config.resolution_layers
                })
            })
            .collect(),
        rows.iter()
            .filter(|r| r.variant.mode == ShadowMode::None)
            .collect(),
    ]
}

fn chart_figure(
    scene: &Scene,
    config: &ShadowStudyConfig,
    rows: &[Row],
) -> Result<Figure, StudyError> {
    let [rt, layers, res, none] = series_rows(config, rows);
    let [c0, c1, c2, c3] = colors();
    let points = |rows: &[&Row], label: &dyn Fn(&Variant) -> String| -> Vec<Point> {
        rows.iter()
            .map(|r| Point {
                x: r.total_s(),
                y: r.errors.rmse,
                label: label(&r.variant),
            })
            .collect()
    };
    let series = vec![
        ChartSeries {
            label: "ray traced (spp)".into(),
            color: c0,
            points: points(&rt, &|v| v.spp.to_string()),
        },
        ChartSeries {
            label: format!(
                "DOM layers (resolution {}, {} spp)",
                config.layer_resolution, config.dom_spp
            ),
            color: c1,
            points: points(&layers, &|v| format!("{}L", v.layers)),
        },
        ChartSeries {
            label: format!("DOM resolution ({} layers)", config.resolution_layers),
            color: c2,
            points: points(&res, &|v| v.resolution.to_string()),
        },
        ChartSeries {
            label: "no shadows".into(),
            color: c3,
            points: points(&none, &|_| String::new()),
        },
    ];
    Ok(figures::scene_error_time_chart(
        scene,
        "",
        config.reference_spp,
        &series,
    )?)
}

fn crops_image(
    reference: &Image,
    reference_crop: Vec<Vec3>,
    (cx, cy, cs): (usize, usize, usize),
    config: &ShadowStudyConfig,
    variants: &[Variant],
    crops: &[Vec<Vec3>],
) -> Result<Image, StudyError> {
    // One exposure for every panel: the reference crop's 99th percentile (largest channel) maps to 0.9.
    let p99 = figures::p99_largest_channel(reference_crop.iter().copied()).unwrap_or(1.0);
    let exposure = if p99 > 0.0 {
        (0.9 / p99).clamp(0.125, 64.0)
    } else {
        1.0
    };
    let reference_panel = || Panel {
        label: format!("REFERENCE {}", config.reference_spp),
        rgb: reference_crop.clone(),
    };
    let panel = |want: Variant| {
        variants.iter().position(|v| *v == want).map(|i| Panel {
            label: want.label(),
            rgb: crops[i].clone(),
        })
    };
    let dom = |layers, resolution| Variant {
        mode: ShadowMode::DeepOpacity,
        spp: config.dom_spp,
        layers,
        resolution,
    };
    let overview = Panel {
        label: "WHOLE IMAGE".into(),
        rgb: figures::overview(reference, cx, cy, cs, cs),
    };
    let mut row0 = vec![overview, reference_panel()];
    row0.extend(panel(Variant {
        mode: ShadowMode::None,
        spp: config.dom_spp,
        layers: 0,
        resolution: 0,
    }));
    row0.extend(config.rt_spp.iter().filter_map(|&spp| {
        panel(Variant {
            mode: ShadowMode::Raytraced,
            spp,
            layers: 0,
            resolution: 0,
        })
    }));
    let mut row1 = vec![reference_panel()];
    row1.extend(
        config
            .layers
            .iter()
            .filter_map(|&l| panel(dom(l, config.layer_resolution))),
    );
    let mut row2 = vec![reference_panel()];
    row2.extend(
        config
            .resolutions
            .iter()
            .filter_map(|&r| panel(dom(config.resolution_layers, r))),
    );
    Ok(figures::mosaic(
        &format!("crop {cs}×{cs} at ({cx}, {cy}), exposure ×{exposure:.2}"),
        &[row0, row1, row2],
        cs,
        exposure,
    )?)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The table is the one written by hand before the `csv` crate (same header, decimals and empty fields), byte
    /// for byte; NaN errors (no shadowed pixel) are written as `NaN`.
    #[test]
    fn csv_rows_keep_their_format() {
        let row = |mode, layers, resolution, vmhwm_bytes| Row {
            variant: Variant {
                mode,
                spp: 16,
                layers,
                resolution,
            },
            build_s: 0.5,
            render_s: 1.25,
            errors: Errors {
                rmse: 0.012_345_678,
                relmse: 3.0,
                rmse_shadowed: f64::NAN,
                relmse_shadowed: 1e-9,
            },
            map_bytes: 20_972_000,
            vmhwm_bytes,
        };
        let rows = [
            row(ShadowMode::DeepOpacity, 8, 1024, Some(240_700_000)),
            row(ShadowMode::Raytraced, 0, 0, None),
        ];
        assert_eq!(
            to_csv(&rows).unwrap(),
            format!(
                "{CSV_HEADER}\n\
                 deep-opacity,16,8,1024,0.5000,1.2500,1.7500,1.234568e-2,3.000000e0,NaN,1.000000e-9,20.972,240.7\n\
                 raytraced,16,,,0.5000,1.2500,1.7500,1.234568e-2,3.000000e0,NaN,1.000000e-9,20.972,\n"
            )
        );
        assert_eq!(to_csv(&[]).unwrap(), format!("{CSV_HEADER}\n"));
    }
}
