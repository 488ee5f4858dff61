//! `cuticle study`: thin wrappers over `cuticle::study` (the logic and its docs live there).

use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::Subcommand;

use cuticle::accel::{Backend, CurveKind};
use cuticle::study::SceneFile;

use super::{parse_resolution, scene_name, threads};

#[derive(Subcommand)]
pub enum StudyCommand {
    /// Shadow modes against a converged ray-traced reference: error vs time, map memory, crops.
    Shadows(StudyShadowsArgs),
    /// The same frame on Embree and on the pure-Rust BVH: time, error against a reference, image difference.
    Backends(StudyBackendsArgs),
    /// Light samples against material samples, per model (thesis table 3, figure 17).
    Samples(StudyKindArgs),
    /// Importance against uniform BSDF sampling, at equal samples and equal time.
    Sampling(StudyKindArgs),
    /// ISHair's uniform against energy-based lobe selection.
    Lobes(StudyKindArgs),
    /// The published (biased) against the exact Hery & Ramamoorthi sampler.
    Hery(StudyKindArgs),
    /// Marschner and ISHair against a chiang reference.
    Models(StudyKindArgs),
    /// Round tubes against flat ribbons per model and film width.
    Curves(StudyKindArgs),
    /// Dual scattering (both forms) against path tracing at 1 to 30 bounces (chiang; blond, brown and black),
    /// against path tracing converged in path length: error against time and each method's bias at convergence.
    /// Not part of `all`.
    MultipleScattering(StudyKindArgs),
    /// Adversarial cases per method: stress.csv, stress.md, bar charts per case (NaN/Inf, fireflies, error;
    /// failures named).
    Stress(StudyKindArgs),
    /// Every kind above, and one Markdown report (report.md) with the charts.
    All(StudyKindArgs),
    /// `--quality auto` against every fixed configuration and the shipped settings, per error target.
    Auto(StudyAutoArgs),
    /// Error against a converged reference versus time with and without the denoiser (RMSE, SSIM, detail kept
    /// around the hair), over samples per pixel: denoise.csv, denoise.md.
    Denoise(StudyDenoiseArgs),
    /// Frame-to-frame flicker beside each frame's error, on a still camera and a turntable: shadowing and
    /// transmittance modes, denoised or not, a seed per frame or one seed.
    Temporal(StudyTemporalArgs),
    /// Writes a seeded set of random test scenes (grooms, strand widths on screen, models, absorption, lights) on
    /// which no constant is tuned: the held-out set `study auto` is judged on.
    Scenes(StudyScenesArgs),
}

#[derive(clap::Args)]
pub struct StudyDenoiseArgs {
    /// Scene files (TOML). Without any, the built-in default scene (a procedural fur ball).
    scenes: Vec<PathBuf>,
    /// Output directory: denoise.csv, denoise.md; references cached in OUT/cache.
    #[arg(short, long, default_value = "study")]
    out: PathBuf,
    /// Film resolution WxH.
    #[arg(long, value_parser = parse_resolution, default_value = "128x96")]
    res: [u32; 2],
    /// Samples per pixel swept (default: 1,2,4,...,128; with --quick 1,4,16).
    #[arg(long, value_delimiter = ',')]
    spp: Option<Vec<u32>>,
    /// Samples per pixel of the references.
    #[arg(long, default_value_t = 1024)]
    reference_spp: u32,
    /// Three spp points.
    #[arg(long)]
    quick: bool,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
}

#[derive(clap::Args)]
pub struct StudyTemporalArgs {
    /// Scene files (TOML), one per fibre model to compare. Without any, the built-in default scene.
    scenes: Vec<PathBuf>,
    /// Output directory: temporal.csv, temporal.md; references cached in OUT/cache.
    #[arg(short, long, default_value = "study")]
    out: PathBuf,
    /// Film resolution WxH.
    #[arg(long, value_parser = parse_resolution, default_value = "160x120")]
    res: [u32; 2],
    /// Frames per sequence.
    #[arg(long, default_value_t = 6)]
    frames: u32,
    /// Degrees the turntable turns per frame.
    #[arg(long, default_value_t = 2.0)]
    orbit: f32,
    /// Samples per pixel swept.
    #[arg(long, value_delimiter = ',', default_value = "4,16,64")]
    spp: Vec<u32>,
    /// Samples per pixel of the references (one per turntable frame).
    #[arg(long, default_value_t = 512)]
    reference_spp: u32,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
}

#[derive(clap::Args)]
pub struct StudyScenesArgs {
    /// How many scenes.
    #[arg(long, default_value_t = 24)]
    count: usize,
    /// Seed of the set; scene k is the same for any count.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Data folder whose real models (hair/) and maps (envmaps/) the scenes may use (default: $CUTICLE_DATA, or
    /// ../shared/data beside the working directory, when it exists; procedural grooms and constant skies only
    /// without one).
    #[arg(long)]
    data: Option<PathBuf>,
    /// Output directory: one TOML per scene and scenes.md, their index.
    #[arg(short, long, default_value = "scenes-generated")]
    out: PathBuf,
}

#[derive(clap::Args)]
pub struct StudyAutoArgs {
    /// Scene files (TOML). Without any, the built-in default scene (a procedural fur ball).
    scenes: Vec<PathBuf>,
    /// Output directory: auto.md, auto.csv, auto-fits-<scene>.csv (<scene>: the file's stem, or `default`).
    #[arg(short, long, default_value = "study")]
    out: PathBuf,
    /// Where the references' EXRs and the fits are cached (default: OUT/cache).
    #[arg(long)]
    cache_dir: Option<PathBuf>,
    /// Error targets (relative RMSE).
    #[arg(long, value_delimiter = ',', default_value = "0.1,0.05")]
    targets: Vec<f32>,
    /// Film resolution WxH.
    #[arg(long, value_parser = parse_resolution, default_value = "128x128")]
    res: [u32; 2],
    /// Samples per pixel of the references.
    #[arg(long, default_value_t = 512)]
    reference_spp: u32,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Auto alone against the yardstick (no fixed configurations): met or not, and its estimate of the error it
    /// delivered against the error measured; writes auto-held-out.md and .csv (for many scenes, such as the set
    /// of `study scenes`).
    #[arg(long)]
    auto_only: bool,
    /// With --auto-only: auto renders each frame denoised (`render --quality auto --denoise[=GUIDE]`), the target
    /// and the measurement applying to the denoised frame.
    #[arg(long, num_args = 0..=1, default_missing_value = "color", require_equals = true,
          value_parser = scene_name::<cuticle::image::denoise::Guide>)]
    denoise: Option<cuticle::image::denoise::Guide>,
}

#[derive(clap::Args)]
pub struct StudyKindArgs {
    /// Scene file (TOML). Without it, the built-in default scene (a procedural fur ball).
    scene: Option<PathBuf>,
    /// Output directory: <kind>.csv, <kind>-summary.csv, <kind>-error-time.png/.svg, <kind>-time.png/.svg,
    /// <kind>-crops.png, <kind>-readouts.txt (stress: bar charts stress-rmse and stress-time in place of the two
    /// charts, and stress.md; all: every kind's files and report.md); the references cached in OUT/cache.
    #[arg(short, long, default_value = "study")]
    out: PathBuf,
    /// Short sweeps on a 32x24 film (unless --res): what CI runs.
    #[arg(long)]
    quick: bool,
    /// Where the reference EXRs are cached (default: OUT/cache).
    #[arg(long)]
    cache_dir: Option<PathBuf>,
    /// Samples per pixel of every reference (default: 64 with --quick; else each kind's own: 16 for samples, 32
    /// for curves, 64 for the others).
    #[arg(long)]
    reference_spp: Option<u32>,
    /// Seeds per point.
    #[arg(long, default_value_t = 3)]
    seeds: u32,
    /// Film resolution WxH (default: the scene's film.resolution, 32x24 with --quick); full runs render each
    /// kind's centred window of it (96x96 for the spp sweeps, 12x12 for samples, 48x48 for stress).
    #[arg(long, value_parser = parse_resolution)]
    res: Option<[u32; 2]>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// No progress bars.
    #[arg(short, long)]
    quiet: bool,
}

/// Prints `wrote PATH` for every file in `files`, then where `cached` (the references) are cached.
fn print_written(files: &[PathBuf], cached: &str, cache: &Path) {
    for f in files {
        println!("wrote {}", f.display());
    }
    println!("{cached} cached in {}", cache.display());
}

/// The scene files named, or the built-in default scene without any.
fn scene_files(paths: &[PathBuf]) -> Result<Vec<SceneFile>> {
    if paths.is_empty() {
        return Ok(vec![SceneFile::default_scene()]);
    }
    Ok(paths
        .iter()
        .map(|p| SceneFile::read(p))
        .collect::<Result<_, _>>()?)
}

/// Runs `cuticle study <name>` for a framework kind (or `all`) and prints the read-outs.
fn study_kind(name: &str, a: StudyKindArgs) -> Result<()> {
    use cuticle::study::framework::{run_kind, StudyConfig};
    let scene = SceneFile::load(a.scene.as_deref())?;
    let config = StudyConfig {
        cache_dir: a.cache_dir,
        seeds: a.seeds,
        reference_spp_override: a.reference_spp,
        resolution: a.res,
        threads: threads(a.threads)?,
        progress: !a.quiet,
        ..StudyConfig::new(a.out, a.quick)
    };
    let files = if name == "all" {
        let report = cuticle::study::report::run_all(&scene, &config)?;
        for k in report.kinds.iter().chain([&report.stress.report]) {
            k.readouts
                .iter()
                .for_each(|l| println!("{}: {l}", k.kind.name));
        }
        print_skipped(&report.stress);
        report.files
    } else if name == "stress" {
        let report = cuticle::study::stress::run(&scene, &config)?;
        report.report.readouts.iter().for_each(|l| println!("{l}"));
        print_skipped(&report);
        report.report.files
    } else {
        let kind = cuticle::study::kinds::by_name(name, a.quick)
            .expect("a subcommand per kind")
            .map_err(|e| anyhow::anyhow!("study {name}: {e}"))?;
        let report = run_kind(&scene, &kind, &config)?;
        report.readouts.iter().for_each(|l| println!("{l}"));
        report.files
    };
    print_written(&files, "references", &config.cache());
    Ok(())
}

/// Prints the stress cases the scene cannot express, and why.
fn print_skipped(report: &cuticle::study::stress::StressReport) {
    report
        .skipped
        .iter()
        .for_each(|s| println!("stress: skipped {}: {}", s.case, s.reason));
}

/// The flags `study shadows` and `study backends` share.
#[derive(clap::Args)]
pub struct StudyWholeArgs {
    /// Scene file (TOML). Without it, the built-in default scene (a procedural fur ball).
    scene: Option<PathBuf>,
    /// Where the reference EXRs are cached (default: OUT/cache).
    #[arg(long)]
    cache_dir: Option<PathBuf>,
    /// Samples per pixel of the references.
    #[arg(long, default_value_t = 256)]
    reference_spp: u32,
    /// Film resolution WxH (default: the scene's film.resolution).
    #[arg(long, value_parser = parse_resolution)]
    res: Option<[u32; 2]>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Seeds per point.
    #[arg(long, default_value_t = 3)]
    seeds: u32,
    /// No progress bars.
    #[arg(short, long)]
    quiet: bool,
}

#[derive(clap::Args)]
pub struct StudyShadowsArgs {
    #[command(flatten)]
    common: StudyWholeArgs,
    /// Output directory: shadows.csv, shadows-summary.csv, shadows-error-time.png/.svg, shadows-time.png/.svg,
    /// shadows-crops.png, shadows-readouts.txt; the reference (ray traced, exact transmittance) cached in
    /// OUT/cache.
    #[arg(short, long, default_value = "study-shadows")]
    out: PathBuf,
    /// Samples per pixel of the ray-traced variants (stochastic and exact transmittance).
    #[arg(long, value_delimiter = ',', default_value = "1,4,16,64")]
    rt_spp: Vec<u32>,
    /// Layer counts of the deep-opacity series at --layer-resolution.
    #[arg(long, value_delimiter = ',', default_value = "4,8,16,32,64")]
    layers: Vec<u32>,
    /// Map resolution of the layer series.
    #[arg(long, default_value_t = 1024)]
    layer_resolution: u32,
    /// Map resolutions of the deep-opacity series at --resolution-layers.
    #[arg(long, value_delimiter = ',', default_value = "256,512,1024,2048,4096")]
    resolutions: Vec<u32>,
    /// Layers of the resolution series.
    #[arg(long, default_value_t = 16)]
    resolution_layers: u32,
    /// Samples per pixel of the deep-opacity and no-shadow variants.
    #[arg(long, default_value_t = 16)]
    dom_spp: u32,
    /// Side of the crop window of shadows-crops.png (centred on the hair), pixels.
    #[arg(long, default_value_t = 128)]
    crop: usize,
    /// Strand tracer of the variants: embree or bvh (overrides hair.backend; the reference keeps the scene's).
    #[arg(long, value_parser = scene_name::<Backend>)]
    backend: Option<Backend>,
}

#[derive(clap::Args)]
pub struct StudyBackendsArgs {
    #[command(flatten)]
    common: StudyWholeArgs,
    /// Output directory: backends.csv, backends-summary.csv, backends-error-time.png/.svg, backends-time.png/.svg,
    /// backends-crops.png, backends-differences.csv, backends-diff-*.png, backends-readouts.txt; the references
    /// (Embree) cached in OUT/cache.
    #[arg(short, long, default_value = "study-backends")]
    out: PathBuf,
    /// Samples per pixel of the compared renders.
    #[arg(long, value_delimiter = ',', default_value = "1,4,16")]
    spp: Vec<u32>,
    /// Curve types.
    #[arg(long, value_delimiter = ',', value_parser = scene_name::<CurveKind>, default_value = "round,flat")]
    curves: Vec<CurveKind>,
}

/// Runs the kind `build` makes (from a subcommand's own flags) on the whole film, references at
/// `--reference-spp`, and prints its read-outs.
fn study_whole(
    a: StudyWholeArgs,
    out: PathBuf,
    crop: Option<usize>,
    build: impl FnOnce(
        cuticle::study::framework::Budget,
    ) -> Result<cuticle::study::framework::Kind, String>,
) -> Result<()> {
    use cuticle::study::framework::{run_kind, Budget, StudyConfig};
    let kind = build(Budget {
        crop: None,
        reference_spp: Some(a.reference_spp),
    })
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    let defaults = StudyConfig::new(out, false);
    let config = StudyConfig {
        cache_dir: a.cache_dir,
        seeds: a.seeds,
        resolution: a.res,
        threads: threads(a.threads)?,
        progress: !a.quiet,
        crop: crop.unwrap_or(defaults.crop),
        ..defaults
    };
    let report = run_kind(&SceneFile::load(a.scene.as_deref())?, &kind, &config)?;
    report.readouts.iter().for_each(|l| println!("{l}"));
    print_written(&report.files, "references", &config.cache());
    Ok(())
}

pub fn study_command(command: StudyCommand) -> Result<()> {
    match command {
        StudyCommand::Samples(a) => study_kind("samples", a)?,
        StudyCommand::Sampling(a) => study_kind("sampling", a)?,
        StudyCommand::Lobes(a) => study_kind("lobes", a)?,
        StudyCommand::Hery(a) => study_kind("hery", a)?,
        StudyCommand::Models(a) => study_kind("models", a)?,
        StudyCommand::MultipleScattering(a) => study_kind("multiple-scattering", a)?,
        StudyCommand::Curves(a) => study_kind("curves", a)?,
        StudyCommand::All(a) => study_kind("all", a)?,
        StudyCommand::Scenes(a) => write_scenes(&a)?,
        StudyCommand::Denoise(a) => {
            let scenes = scene_files(&a.scenes)?;
            let config = cuticle::study::denoise::DenoiseStudyConfig {
                scenes,
                resolution: a.res,
                spp: a
                    .spp
                    .unwrap_or_else(|| cuticle::study::denoise::default_spp(a.quick)),
                reference_spp: a.reference_spp,
                threads: threads(a.threads)?,
                out: a.out,
            };
            let report = cuticle::study::denoise::run(&config)?;
            print!("{}", report.markdown);
            print_written(&report.files, "references", &config.out.join("cache"));
        }
        StudyCommand::Temporal(a) => {
            let config = cuticle::study::temporal::TemporalStudyConfig {
                scenes: scene_files(&a.scenes)?,
                resolution: a.res,
                frames: a.frames,
                orbit_degrees: a.orbit,
                spp: a.spp,
                reference_spp: a.reference_spp,
                out: a.out,
                threads: threads(a.threads)?,
            };
            let report = cuticle::study::temporal::run(&config)?;
            print!("{}", report.markdown);
            print_written(&report.files, "references", &config.out.join("cache"));
        }
        StudyCommand::Auto(a) => {
            let scenes = scene_files(&a.scenes)?;
            let config = cuticle::study::auto::AutoStudyConfig {
                scenes,
                targets: a.targets,
                resolution: a.res,
                reference_spp: a.reference_spp,
                out: a.out,
                cache_dir: a.cache_dir,
                threads: threads(a.threads)?,
                denoise: a.denoise,
            };
            if a.denoise.is_some() && !a.auto_only {
                anyhow::bail!("study auto --denoise measures auto alone: add --auto-only");
            }
            let report = if a.auto_only {
                cuticle::study::auto::run_auto_only(&config)?
            } else {
                cuticle::study::auto::run(&config)?
            };
            print!("{}", report.markdown);
            print_written(&report.files, "references and fits", &report.cache_dir);
        }
        StudyCommand::Stress(a) => study_kind("stress", a)?,
        StudyCommand::Shadows(a) => {
            let sweep = cuticle::study::kinds::ShadowsSweep {
                rt_spp: a.rt_spp,
                layers: a.layers,
                layer_resolution: a.layer_resolution,
                resolutions: a.resolutions,
                resolution_layers: a.resolution_layers,
                dom_spp: a.dom_spp,
                backend: a.backend.map(|b| b.name().to_owned()),
            };
            study_whole(a.common, a.out, Some(a.crop), |budget| {
                cuticle::study::kinds::shadows_with(&sweep, budget)
            })?;
        }
        StudyCommand::Backends(a) => {
            let sweep = cuticle::study::kinds::BackendsSweep {
                spp: a.spp,
                curves: a.curves.iter().map(|c| c.name().to_owned()).collect(),
            };
            study_whole(a.common, a.out, None, |budget| {
                cuticle::study::kinds::backends_with(&sweep, budget)
            })?;
        }
    }
    Ok(())
}

/// `cuticle study scenes`: the generated set into `a.out`, with its index.
fn write_scenes(a: &StudyScenesArgs) -> Result<()> {
    use cuticle::study::cache::write_text;
    use cuticle::study::generated::{generate, DataFiles};
    let data_dir = a.data.clone().or_else(|| {
        let dir = std::env::var_os("CUTICLE_DATA")
            .map_or_else(|| PathBuf::from("../shared/data"), PathBuf::from);
        dir.is_dir().then_some(dir)
    });
    let data = data_dir.as_deref().map(DataFiles::scan).unwrap_or_default();
    std::fs::create_dir_all(&a.out)
        .map_err(|e| anyhow::anyhow!("{}: cannot create the folder: {e}", a.out.display()))?;
    let scenes = generate(a.seed, a.count, &data);
    let mut index = format!(
        "# Generated scenes, seed {}\n\n`cuticle study scenes --seed {} --count {}`: held out, no constant is tuned on \
         them.\n\n| scene | what was drawn |\n|---|---|\n",
        a.seed, a.seed, a.count
    );
    for s in &scenes {
        let path = a.out.join(format!("{}.toml", s.name));
        write_text(&path, &s.toml)?;
        println!("wrote {}", path.display());
        index.push_str(&format!("| {} | {} |\n", s.name, s.summary));
    }
    let path = a.out.join("scenes.md");
    write_text(&path, &index)?;
    println!("wrote {}", path.display());
    Ok(())
}
