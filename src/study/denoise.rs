//! `cuticle study denoise [SCENE...]`: error against a converged reference versus time, with and without the
//! denoiser ([`crate::image::denoise`]), over samples per pixel.
//!
//! Per scene: the frame is set up once; the reference is rendered at the study's reference spp as two halves with
//! seeds no sweep point uses (cached as `cache/denoise-<scene>-<hash>-{0,1}.exr`, the hash covering the scene text,
//! the film and the reference spp), their mean the reference. Then per spp, one render by filter importance sampling
//! (its seconds; as `render --denoise` renders) and one denoise of it (its seconds), and one render splatted without
//! the denoiser (method [`NOISY_SPLAT`]: the frame a user gets without `--denoise`) and that frame denoised with the
//! colour guide ([`DENOISED_SPLAT`]: it shows why `--denoise` does not splat), and for both noisy beauties, the
//! denoised splat and the beauty denoised with each guide ([`denoise::Guide`]):
//!
//! - **RMSE** of R, G, B against the reference, and **relative RMSE** (√ of the mean of (x − r)² / (r² + 0.01));
//! - **SSIM** ([`crate::measure::pixels::ssim`]);
//! - **detail kept** and **detail error** ([`crate::measure::pixels::detail`]) over the 64² window centred on the
//!   hair ([`super::figures::hair_window`]): the reference's fine structure that survives (a denoiser that smears
//!   strands scores low here even where its RMSE is small), and the error in that band (noise and smoothing both).
//!
//! Written: `denoise-crops-<scene>.png` (the hair window: the reference, then per spp the noisy frame beside it
//! denoised with the colour guide, one exposure for all), `denoise.csv` (one row per scene, spp and method) and
//! `denoise.md` (the table, and per scene and guide
//! the read-out: the fewest spp at which the denoised frame reaches both the SSIM and the detail error of the noisy
//! frame at the largest spp, importance-sampled and splatted, in what fraction of its time, and how much detail it
//! keeps there).

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use super::cache::{scene_key, write_text};
use super::figures;
use super::{cached_reference, create_dir, SceneFile, StudyError};
use crate::image::{denoise, Image};
use crate::measure::{metrics::REL_EPSILON, pixels};
use crate::render::{Frame, Request};

/// The method of the rows of frames rendered without the denoiser by the splatting film (the default without
/// `--denoise`); "noisy" rows are the filter-importance-sampled frames the denoiser takes.
pub const NOISY_SPLAT: &str = "noisy splat";
/// The method of the rows of the splatted frames denoised (colour guide).
pub const DENOISED_SPLAT: &str = "denoised splat";

/// Side of the window centred on the hair over which detail is measured, pixels.
pub const DETAIL_WINDOW: usize = 64;
/// Added to the scene's seed for the reference, so no sweep point shares its samples.
const REFERENCE_SEED_OFFSET: u32 = 0x0002_0003;

/// What `study denoise` renders.
#[derive(Debug, Clone)]
pub struct DenoiseStudyConfig {
    /// The scenes.
    pub scenes: Vec<SceneFile>,
    /// Film resolution.
    pub resolution: [u32; 2],
    /// The samples per pixel swept.
    pub spp: Vec<u32>,
    /// Samples per pixel of the references.
    pub reference_spp: u32,
    /// Output directory.
    pub out: PathBuf,
    /// Worker threads (the denoiser gets as many).
    pub threads: usize,
}

/// One measured image.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// The scene's name.
    pub scene: String,
    /// Samples per pixel of the render.
    pub spp: u32,
    /// `noisy`, or the denoiser's guide ([`denoise::Guide::name`]).
    pub method: &'static str,
    /// Render seconds (the pixel loop and any maps).
    pub render_seconds: f64,
    /// Denoising seconds (0 for the noisy image).
    pub denoise_seconds: f64,
    /// RMSE of R, G, B against the reference.
    pub rmse: f64,
    /// Relative RMSE against the reference.
    pub rel_rmse: f64,
    /// Mean SSIM against the reference.
    pub ssim: f64,
    /// The reference's detail kept over the hair window.
    pub detail: f64,
    /// The error in the detail band over the hair window.
    pub detail_error: f64,
}

impl Row {
    /// Render plus denoising seconds.
    pub fn seconds(&self) -> f64 {
        self.render_seconds + self.denoise_seconds
    }
}

/// What the study wrote.
#[derive(Debug)]
pub struct DenoiseReport {
    /// Every row.
    pub rows: Vec<Row>,
    /// The Markdown report.
    pub markdown: String,
    /// The files written.
    pub files: Vec<PathBuf>,
}

/// The image's R, G, B as an image of those three channels, from channels `names`.
pub(super) fn rgb_of(image: &Image, names: [&str; 3]) -> Result<Image, StudyError> {
    let data = image
        .triples(names)
        .ok_or_else(|| StudyError::Config(format!("the image lacks one of {names:?}")))?;
    let mut out = Image::new(
        image.width,
        image.height,
        ["R", "G", "B"].map(String::from).to_vec(),
    );
    out.data = data;
    Ok(out)
}

/// RMSE and relative RMSE (√ of the mean of (x − r)² / (r² + 0.01)) of the values `image` against `reference`,
/// value by value (RGB triples, or images of R, G, B only).
pub(super) fn errors(image: &[f32], reference: &[f32]) -> (f64, f64) {
    let (mut se, mut rel, mut n) = (0.0, 0.0, 0.0);
    for (x, r) in image.iter().zip(reference) {
        let (x, r) = (f64::from(*x), f64::from(*r));
        se += (x - r).powi(2);
        rel += (x - r).powi(2) / (r * r + REL_EPSILON);
        n += 1.0;
    }
    let n = f64::max(n, 1.0);
    ((se / n).sqrt(), (rel / n).sqrt())
}

/// The row of image `x` (R, G, B) against `truth` and the reference's `halves`.
#[allow(clippy::too_many_arguments)]
fn measured(
    file: &SceneFile,
    spp: u32,
    method: &'static str,
    render_seconds: f64,
    denoise_seconds: f64,
    x: &Image,
    truth: &Image,
    halves: &[Image],
    window: (usize, usize, usize),
) -> Result<Row, StudyError> {
    let (rmse, rel_rmse) = errors(&x.data, &truth.data);
    let measure = |r: Result<f64, String>| r.map_err(StudyError::Config);
    let d = pixels::detail(x, [&halves[0], &halves[1]], window).map_err(StudyError::Config)?;
    Ok(Row {
        scene: file.name(),
        spp,
        method,
        render_seconds,
        denoise_seconds,
        rmse,
        rel_rmse,
        ssim: measure(pixels::ssim(x, truth))?,
        detail: d.kept,
        detail_error: d.error,
    })
}

/// What a study with the denoiser needs first: the denoiser (named as `study`'s error if missing), the output
/// directory and its `cache` (both created), and a pool of `threads` workers. Returns the cache and the pool.
pub(super) fn setup(
    study: &str,
    out: &std::path::Path,
    threads: usize,
) -> Result<(PathBuf, rayon::ThreadPool), StudyError> {
    denoise::available().map_err(|e| StudyError::Config(format!("{study}: {e}")))?;
    create_dir(out)?;
    let cache = out.join("cache");
    create_dir(&cache)?;
    Ok((cache, crate::render::thread_pool(Some(threads))?))
}

/// Runs the study (see the module docs).
pub fn run(config: &DenoiseStudyConfig) -> Result<DenoiseReport, StudyError> {
    if config.spp.is_empty() || config.spp.contains(&0) || config.reference_spp == 0 {
        return Err(StudyError::Config(
            "study denoise: spp and the reference's spp must be positive".to_owned(),
        ));
    }
    let (cache, pool) = setup("study denoise", &config.out, config.threads)?;
    let mut rows = Vec::new();
    let mut crop_files = Vec::new();
    // Per scene: its reference's two halves, then each spp.
    let steps = (config.scenes.len() * (2 + config.spp.len())) as u64;
    let progress = super::steps_bar(steps, "study denoise");
    for file in &config.scenes {
        progress.set_message(file.name());
        let scene = file.scene(Some(config.resolution))?;
        let frame = pool.install(|| Frame::load(scene.resolve()?).map_err(StudyError::from))?;
        // A frame of `settings` and the wall time of its render.
        let render = |settings: &crate::render::RenderSettings| {
            let start = Instant::now();
            let image = pool.install(|| frame.render(Request::new(settings)).image);
            (image, start.elapsed().as_secs_f64())
        };
        let mut settings = scene.render_settings();
        // The guide must be in the film.
        settings.film.aovs = vec![crate::render::settings::ALL_AOVS.to_owned()];
        // Frames by filter importance sampling, as `render --denoise` renders them (Open Image Denoise cannot
        // remove a splat's noise, shared by neighbouring pixels): the noisy and denoised rows are of one frame.
        settings.film.reconstruction = crate::render::Reconstruction::Importance;
        let key = scene_key(
            "cuticle study denoise reference v1",
            &file.text,
            file,
            &[],
            &format!(
                "{}x{} {} spp",
                config.resolution[0], config.resolution[1], config.reference_spp
            ),
        );
        // Two halves of the reference's samples with seeds of their own: their mean is the reference, and their
        // detail, correlated only where it is the scene's, measures what a render keeps of it.
        let (mut halves, mut window) = (Vec::new(), (0, 0, DETAIL_WINDOW));
        for half in 0..2u32 {
            let path = cache.join(format!("denoise-{}-{key:016x}-{half}.exr", file.name()));
            let (image, _, _) = cached_reference(&path, config.resolution, || {
                let mut s = settings.clone();
                s.film.spp = config.reference_spp.div_ceil(2);
                s.film.seed = s.film.seed.wrapping_add(REFERENCE_SEED_OFFSET + half);
                s.adaptive = None;
                render(&s)
            })?;
            progress.inc(1);
            if half == 0 {
                window = super::figures::hair_window(&image, DETAIL_WINDOW);
            }
            halves.push(rgb_of(&image, ["R", "G", "B"])?);
        }
        let mut truth = halves[0].clone();
        for (t, b) in truth.data.iter_mut().zip(&halves[1].data) {
            *t = 0.5 * (*t + b);
        }
        // The crops of the hair window: reference, then per spp the noisy and the colour-guided denoised frame.
        let (cx, cy, cs) = window;
        let reference_crop = figures::crop(&truth, cx, cy, cs).map_err(StudyError::Config)?;
        let mut crop_rows = vec![vec![
            figures::Panel {
                label: "WHOLE IMAGE".into(),
                rgb: figures::overview(&truth, cx, cy, cs, cs),
            },
            figures::Panel {
                label: format!("REFERENCE {} SPP", config.reference_spp),
                rgb: reference_crop.clone(),
            },
        ]];
        for &spp in &config.spp {
            let mut s = settings.clone();
            s.film.spp = spp;
            s.adaptive = None;
            let (mut image, render_seconds) = render(&s);
            let x = rgb_of(&image, ["R", "G", "B"])?;
            rows.push(measured(
                file,
                spp,
                "noisy",
                render_seconds,
                0.0,
                &x,
                &truth,
                &halves,
                window,
            )?);
            let noisy_crop = figures::crop(&x, cx, cy, cs).map_err(StudyError::Config)?;
            for guide in denoise::Guide::ALL {
                let start = Instant::now();
                denoise::add_denoised(&mut image, guide, config.threads)
                    .map_err(|e| StudyError::Config(format!("study denoise: {e}")))?;
                let seconds = start.elapsed().as_secs_f64();
                let x = rgb_of(&image, denoise::CHANNELS)?;
                if guide == denoise::Guide::Color {
                    crop_rows.push(vec![
                        figures::Panel {
                            label: format!("NOISY {spp} SPP"),
                            rgb: noisy_crop.clone(),
                        },
                        figures::Panel {
                            label: format!("DENOISED {spp} SPP"),
                            rgb: figures::crop(&x, cx, cy, cs).map_err(StudyError::Config)?,
                        },
                    ]);
                }
                rows.push(measured(
                    file,
                    spp,
                    guide.name(),
                    render_seconds,
                    seconds,
                    &x,
                    &truth,
                    &halves,
                    window,
                )?);
            }
            // The frame a user gets without the denoiser: splatted (the film's default), at the same spp.
            let mut s = s.clone();
            s.film.reconstruction = crate::render::Reconstruction::Splat;
            let (mut image, render_seconds) = render(&s);
            rows.push(measured(
                file,
                spp,
                NOISY_SPLAT,
                render_seconds,
                0.0,
                &rgb_of(&image, ["R", "G", "B"])?,
                &truth,
                &halves,
                window,
            )?);
            let start = Instant::now();
            denoise::add_denoised(&mut image, denoise::Guide::Color, config.threads)
                .map_err(|e| StudyError::Config(format!("study denoise: {e}")))?;
            rows.push(measured(
                file,
                spp,
                DENOISED_SPLAT,
                render_seconds,
                start.elapsed().as_secs_f64(),
                &rgb_of(&image, denoise::CHANNELS)?,
                &truth,
                &halves,
                window,
            )?);
            progress.inc(1);
        }
        let crops = figures::mosaic(
            &format!(
                "{}: the hair window, noisy and denoised (colour guide)",
                file.name()
            ),
            &crop_rows,
            cs,
            figures::exposure(&reference_crop),
        )?;
        let path = config
            .out
            .join(format!("denoise-crops-{}.png", file.name()));
        crate::image::write(&path, &crops)?;
        crop_files.push(path);
    }
    progress.finish_and_clear();
    let csv = csv_of(&rows)?;
    let md = markdown(&rows, config);
    let (csv_path, md_path) = (
        config.out.join("denoise.csv"),
        config.out.join("denoise.md"),
    );
    write_text(&csv_path, &csv)?;
    write_text(&md_path, &md)?;
    Ok(DenoiseReport {
        rows,
        markdown: md,
        files: [vec![csv_path, md_path], crop_files].concat(),
    })
}

/// `denoise.csv`: one record per row (the csv crate quotes a scene name that needs it).
fn csv_of(rows: &[Row]) -> Result<String, csv::Error> {
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record([
        "scene",
        "spp",
        "method",
        "render_s",
        "denoise_s",
        "seconds",
        "rmse",
        "rel_rmse",
        "ssim",
        "detail_kept",
        "detail_error",
    ])?;
    for r in rows {
        w.write_record([
            r.scene.clone(),
            r.spp.to_string(),
            r.method.to_owned(),
            format!("{:.4}", r.render_seconds),
            format!("{:.4}", r.denoise_seconds),
            format!("{:.4}", r.seconds()),
            format!("{:.6}", r.rmse),
            format!("{:.6}", r.rel_rmse),
            format!("{:.5}", r.ssim),
            format!("{:.4}", r.detail),
            format!("{:.4}", r.detail_error),
        ])?;
    }
    super::framework::finish_csv(w)
}

/// The table and, per scene and guide, the read-out: the fewest spp at which the denoised frame reaches both the SSIM
/// and the detail error of the noisy frame at the largest spp, the time ratio, and the detail kept there.
fn markdown(rows: &[Row], config: &DenoiseStudyConfig) -> String {
    let mut md = format!(
        "# study denoise\n\n{}x{}, reference {} spp, {} threads. Time: render + denoise, seconds.\n\n\
         | scene | spp | method | s | RMSE | rel. RMSE | SSIM | detail kept | detail error |\n\
         |---|---:|---|---:|---:|---:|---:|---:|---:|\n",
        config.resolution[0], config.resolution[1], config.reference_spp, config.threads
    );
    for r in rows {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.2} | {:.4} | {:.4} | {:.4} | {:.3} | {:.3} |",
            r.scene,
            r.spp,
            r.method,
            r.seconds(),
            r.rmse,
            r.rel_rmse,
            r.ssim,
            r.detail,
            r.detail_error
        );
    }
    md.push('\n');
    let mut scenes: Vec<&str> = rows.iter().map(|r| r.scene.as_str()).collect();
    scenes.dedup();
    for scene in scenes {
        let of = |m: &str| -> Vec<&Row> {
            rows.iter()
                .filter(|r| r.scene == scene && r.method == m)
                .collect()
        };
        for baseline in ["noisy", NOISY_SPLAT] {
            let noisy = of(baseline);
            let Some(best) = noisy.iter().max_by_key(|r| r.spp) else {
                continue;
            };
            for guide in denoise::Guide::ALL {
                let name = guide.name();
                // The target's form: the fewest spp whose denoised frame is at least as good as the noisy frame at
                // the most spp in SSIM and in the detail band's error.
                let reached = of(name)
                    .into_iter()
                    .find(|r| r.ssim >= best.ssim && r.detail_error <= best.detail_error);
                match reached {
                    Some(d) => {
                        let _ = writeln!(
                            md,
                            "- {scene}, {name}: at {} spp reaches the {baseline} frame's SSIM ({:.4}) and detail error \
                             ({:.3}) at {} spp in 1/{:.1} of its time ({:.2} s against {:.2} s); detail kept {:.2}.",
                            d.spp,
                            best.ssim,
                            best.detail_error,
                            best.spp,
                            best.seconds() / d.seconds().max(1e-9),
                            d.seconds(),
                            best.seconds(),
                            d.detail
                        );
                    }
                    None => {
                        let _ = writeln!(
                            md,
                            "- {scene}, {name}: does not reach the {baseline} frame's SSIM ({:.4}) and detail error \
                             ({:.3}) at {} spp in the spp swept.",
                            best.ssim, best.detail_error, best.spp
                        );
                    }
                }
            }
        }
    }
    md
}

/// The default spp sweep (`quick`: three points).
pub fn default_spp(quick: bool) -> Vec<u32> {
    if quick {
        vec![1, 4, 16]
    } else {
        vec![1, 2, 4, 8, 16, 32, 64, 128]
    }
}
