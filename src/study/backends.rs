//! `cuticle study backends SCENE -o DIR`: the same frame on Embree and on the pure-Rust BVH (issue 13) — what each
//! costs, and whether they make the same image.
//!
//! # What is rendered
//!
//! For each curve type of `kinds`: a converged **reference** on Embree at `reference_spp` (seed offset by
//! [`super::shadows::REFERENCE_SEED_OFFSET`], cached as `reference-<hash>.exr` under a key of the scene text, the
//! curve type, resolution, spp and seed; not the hair file nor the code: delete it after changing them). Then each
//! backend at each of `spp`, with the scene's own seed, so both backends draw the same samples: their images
//! differ only where the tracers disagree (a few silhouette grazes per 10⁵ rays, see `accel::bvh_tracer`'s tests)
//! and where such a difference sends a path elsewhere.
//!
//! # What is measured, per (curves, backend, spp) ([`Row`])
//!
//! - `build_s`: the tracer's build ([`crate::accel::Tracer::build_seconds`]); `render_s`: the pixel loop; wall
//!   clock, one run each (±10 % on a shared machine; `bench trace` repeats).
//! - `rmse`, `relmse`: against the reference of the same curve type ([`crate::measure::metrics`]).
//! - `diff_rmse`: RMSE between the two backends' images at the same spp and seed — the backends' disagreement,
//!   to be read against `rmse` (the noise): far below it means the same image.
//! - `mean_r`, `mean_g`, `mean_b`: the image's per-channel means.
//!
//! # Written into the output directory
//!
//! `backends.csv` (columns [`CSV_HEADER`]), `backends-error-time.png`/`.svg` (RMSE against build + render time,
//! one series per backend and curve type, points labelled with spp), and `backends-diff-<curves>.png`: |Embree −
//! BVH| at the highest spp, scaled so that the reference's 99th percentile is white — structure in it (edges,
//! a region) would mean the backends trace differently; isolated pixels are paths sent elsewhere by one graze.

use std::path::{Path, PathBuf};

use glam::Vec3;
use serde::Serialize;

use super::cache::{scene_key, write_text};
use super::figures::{self, ChartSeries, Point};
use super::shadows::REFERENCE_SEED_OFFSET;
use super::StudyError;
use crate::accel::{Backend, CurveKind};
use crate::image::{self, Image};
use crate::measure::metrics;
use crate::plot::{self, hex};
use crate::render::{thread_pool, Frame, Options};
use crate::scene::{Overrides, Scene};

/// Bumped when the reference's recipe changes.
const REFERENCE_FORMAT: &str = "cuticle study backends reference v1";

/// CSV columns.
pub const CSV_HEADER: &str =
    "curves,backend,spp,build_s,render_s,total_s,rmse,relmse,diff_rmse,mean_r,mean_g,mean_b";

/// What the study renders and where it writes.
#[derive(Debug, Clone, PartialEq)]
pub struct BackendStudyConfig {
    /// Output directory (created if needed).
    pub out_dir: PathBuf,
    /// Where references are cached (default: `out_dir`).
    pub cache_dir: Option<PathBuf>,
    /// Samples per pixel of the references.
    pub reference_spp: u32,
    /// Samples per pixel of the compared renders.
    pub spp: Vec<u32>,
    /// Curve types.
    pub kinds: Vec<CurveKind>,
    /// Film resolution override.
    pub film_resolution: Option<[u32; 2]>,
    /// Worker threads.
    pub threads: usize,
    /// One line per render on stderr.
    pub progress: bool,
}

impl BackendStudyConfig {
    /// The defaults of `cuticle study backends`, writing into `out_dir`.
    pub fn new(out_dir: impl Into<PathBuf>) -> Self {
        BackendStudyConfig {
            out_dir: out_dir.into(),
            cache_dir: None,
            reference_spp: 256,
            spp: vec![1, 4, 16],
            kinds: vec![CurveKind::Round, CurveKind::Flat],
            film_resolution: None,
            threads: 2,
            progress: false,
        }
    }
}

/// One render.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// Curve type.
    pub curves: CurveKind,
    /// Backend.
    pub backend: Backend,
    /// Samples per pixel.
    pub spp: u32,
    /// Tracer build, seconds.
    pub build_s: f64,
    /// Pixel loop, seconds.
    pub render_s: f64,
    /// Against the reference.
    pub errors: metrics::Errors,
    /// RMSE between this image and the other backend's at the same spp (NaN when only one backend ran).
    pub diff_rmse: f64,
    /// Per-channel means.
    pub mean: [f64; 3],
}

/// What the study measured and wrote.
#[derive(Debug, Clone)]
pub struct BackendStudyReport {
    /// One row per render.
    pub rows: Vec<Row>,
    /// The CSV table.
    pub csv: PathBuf,
    /// The chart (PNG; an SVG beside it).
    pub chart: PathBuf,
    /// The difference images, one per curve type.
    pub diffs: Vec<PathBuf>,
}

/// The R, G, B values of every pixel of a render, row-major.
fn rgb_pixels(image: &Image) -> Result<Vec<Vec3>, StudyError> {
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
        .map(|p| Vec3::new(p[r], p[g], p[b]))
        .collect())
}

/// Per-channel means of R, G, B.
fn means(image: &Image) -> Result<[f64; 3], StudyError> {
    let pixels = rgb_pixels(image)?;
    let count = (image.width * image.height).max(1) as f64;
    Ok(std::array::from_fn(|c| {
        pixels.iter().map(|p| f64::from(p[c])).sum::<f64>() / count
    }))
}

/// |a − b| in RGB, scaled by `scale`, as an RGB image.
fn difference(a: &Image, b: &Image, scale: f32) -> Result<Image, StudyError> {
    let mut out = Image::new(a.width, a.height, vec!["R".into(), "G".into(), "B".into()]);
    for (k, (pa, pb)) in rgb_pixels(a)?.into_iter().zip(rgb_pixels(b)?).enumerate() {
        let d = (pa - pb).abs() * scale;
        for c in 0..3 {
            out.set(k % a.width, k / a.width, c, d[c]);
        }
    }
    Ok(out)
}

/// Runs the study on the scene file at `scene_path` (see the module docs).
pub fn run(
    scene_path: &Path,
    config: &BackendStudyConfig,
) -> Result<BackendStudyReport, StudyError> {
    if config.spp.is_empty() || config.kinds.is_empty() {
        return Err(StudyError::Config(
            "nothing to compare: --spp and --curves must not be empty".into(),
        ));
    }
    if let Some(s) = std::iter::once(config.reference_spp)
        .chain(config.spp.iter().copied())
        .find(|&s| s == 0)
    {
        return Err(StudyError::Config(format!(
            "samples per pixel must be at least 1, got {s}"
        )));
    }
    if config.threads == 0 {
        return Err(StudyError::Config("--threads must be at least 1".into()));
    }
    let (text, scene) = super::load_scene(scene_path, config.film_resolution)?;
    super::create_dir(&config.out_dir)?;
    let cache_dir = config.cache_dir.as_deref().unwrap_or(&config.out_dir);
    super::create_dir(cache_dir)?;
    let say = |line: String| {
        if config.progress {
            eprintln!("{line}");
        }
    };
    let pool = thread_pool(Some(config.threads))?;
    let strands = scene
        .hair_spec()
        .load()
        .map_err(crate::render::FrameError::from)?;
    let variant = |curves, backend, spp: u32, seed: u32| -> Result<Scene, StudyError> {
        Ok(scene.clone().apply(&Overrides {
            curves: Some(curves),
            backend: Some(backend),
            spp: Some(spp),
            seed: Some(seed),
            ..Overrides::default()
        })?)
    };
    let backends = [Backend::Embree, Backend::Bvh];
    let mut rows = Vec::new();
    let mut diffs = Vec::new();
    for &curves in &config.kinds {
        let reference_scene = variant(
            curves,
            Backend::Embree,
            config.reference_spp,
            scene.film.seed.wrapping_add(REFERENCE_SEED_OFFSET),
        )?;
        let key = scene_key(
            REFERENCE_FORMAT,
            &text,
            &reference_scene,
            &[],
            &format!(
                "curves={};resolution={:?};spp={};seed={}",
                curves.name(),
                reference_scene.film.resolution,
                reference_scene.film.spp,
                reference_scene.film.seed
            ),
        );
        let reference_path = cache_dir.join(format!("reference-{key:016x}.exr"));
        say(format!(
            "{} reference: {} spp on embree -> {}",
            curves.name(),
            config.reference_spp,
            reference_path.display()
        ));
        let mut frames = Vec::new();
        for backend in backends {
            let spec = variant(curves, backend, 1, scene.film.seed)?.resolve()?;
            frames.push(pool.install(|| Frame::build(strands.clone(), spec))?);
        }
        let (reference, _, _) =
            super::cached_reference(&reference_path, scene.film.resolution, || {
                let (image, stats) = pool.install(|| {
                    frames[0].render_with(
                        &reference_scene.render_settings(),
                        Options {
                            progress: config.progress,
                        },
                    )
                });
                (image, stats.seconds)
            })?;
        let mut last: Vec<Image> = Vec::new();
        for &spp in &config.spp {
            let settings =
                variant(curves, Backend::Embree, spp, scene.film.seed)?.render_settings();
            let mut images = Vec::new();
            for (frame, backend) in frames.iter().zip(backends) {
                let (image, stats) =
                    pool.install(|| frame.render_with(&settings, Options { progress: false }));
                let errors =
                    metrics::errors(&image, &reference, &vec![false; image.width * image.height])
                        .map_err(StudyError::Config)?;
                say(format!(
                    "{} {:<6} {spp:>4} spp: build {:.3} s, render {:.3} s, rmse {:.5}",
                    curves.name(),
                    backend.name(),
                    frame.build_seconds(),
                    stats.seconds,
                    errors.rmse
                ));
                rows.push(Row {
                    curves,
                    backend,
                    spp,
                    build_s: frame.build_seconds(),
                    render_s: stats.seconds,
                    errors,
                    diff_rmse: f64::NAN,
                    mean: means(&image)?,
                });
                images.push(image);
            }
            let no_mask = vec![false; images[0].width * images[0].height];
            let diff = metrics::errors(&images[1], &images[0], &no_mask)
                .map_err(StudyError::Config)?
                .rmse;
            let n = rows.len();
            rows[n - 1].diff_rmse = diff;
            rows[n - 2].diff_rmse = diff;
            last = images;
        }
        let path = config
            .out_dir
            .join(format!("backends-diff-{}.png", curves.name()));
        image::write(
            &path,
            &difference(
                &last[0],
                &last[1],
                1.0 / figures::p99_largest_channel(rgb_pixels(&reference)?)
                    .filter(|&w| w > 0.0)
                    .unwrap_or(1.0),
            )?,
        )?;
        diffs.push(path);
    }
    let csv = config.out_dir.join("backends.csv");
    write_text(&csv, &to_csv(&rows)?)?;
    let [chart, _] = plot::write_figure(
        &chart_figure(&scene, config, &rows)?,
        &config.out_dir,
        "backends-error-time",
    )?;
    say(format!(
        "wrote {}, {} and the difference images",
        csv.display(),
        chart.display()
    ));
    Ok(BackendStudyReport {
        rows,
        csv,
        chart,
        diffs,
    })
}

/// One line of `backends.csv` ([`CSV_HEADER`]).
#[derive(Debug, Serialize)]
struct CsvRow {
    curves: &'static str,
    backend: &'static str,
    spp: u32,
    build_s: String,
    render_s: String,
    total_s: String,
    rmse: String,
    relmse: String,
    diff_rmse: String,
    mean_r: String,
    mean_g: String,
    mean_b: String,
}

/// The CSV table of `rows`.
pub fn to_csv(rows: &[Row]) -> Result<String, csv::Error> {
    let mut w = csv::Writer::from_writer(Vec::new());
    let sci = |x: f64| format!("{x:.6e}");
    for r in rows {
        w.serialize(CsvRow {
            curves: r.curves.name(),
            backend: r.backend.name(),
            spp: r.spp,
            build_s: format!("{:.4}", r.build_s),
            render_s: format!("{:.4}", r.render_s),
            total_s: format!("{:.4}", r.build_s + r.render_s),
            rmse: sci(r.errors.rmse),
            relmse: sci(r.errors.relmse),
            diff_rmse: sci(r.diff_rmse),
            mean_r: sci(r.mean[0]),
            mean_g: sci(r.mean[1]),
            mean_b: sci(r.mean[2]),
        })?;
    }
    let bytes = w
        .into_inner()
        .map_err(|e| csv::Error::from(e.into_error()))?;
    Ok(String::from_utf8(bytes).expect("the csv writer writes utf-8"))
}

fn chart_figure(
    scene: &Scene,
    config: &BackendStudyConfig,
    rows: &[Row],
) -> Result<crate::plot::Figure, StudyError> {
    let colors = [hex(0x0072b2), hex(0xd55e00), hex(0x56b4e9), hex(0xe69f00)];
    let mut series = Vec::new();
    for (i, &curves) in config.kinds.iter().enumerate() {
        for (j, backend) in [Backend::Embree, Backend::Bvh].into_iter().enumerate() {
            series.push(ChartSeries {
                label: format!("{} {}", backend.name(), curves.name()),
                color: colors[(2 * i + j) % colors.len()],
                points: rows
                    .iter()
                    .filter(|r| r.curves == curves && r.backend == backend)
                    .map(|r| Point {
                        x: r.build_s + r.render_s,
                        y: r.errors.rmse,
                        label: r.spp.to_string(),
                    })
                    .collect(),
            });
        }
    }
    Ok(figures::scene_error_time_chart(
        scene,
        "Embree vs Rust BVH, ",
        config.reference_spp,
        &series,
    )?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_rows_keep_their_format() {
        let row = Row {
            curves: CurveKind::Flat,
            backend: Backend::Bvh,
            spp: 4,
            build_s: 0.25,
            render_s: 1.5,
            errors: metrics::Errors {
                rmse: 0.01,
                relmse: 0.002,
                ..Default::default()
            },
            diff_rmse: 1e-4,
            mean: [0.1, 0.2, 0.3],
        };
        let text = to_csv(&[row]).unwrap();
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some(CSV_HEADER));
        assert_eq!(
            lines.next(),
            Some("flat,bvh,4,0.2500,1.5000,1.7500,1.000000e-2,2.000000e-3,1.000000e-4,1.000000e-1,2.000000e-1,3.000000e-1")
        );
    }
}
