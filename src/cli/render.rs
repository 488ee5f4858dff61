//! `cuticle render` and `cuticle merge`.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};

use cuticle::accel::{Backend, CurveKind};
use cuticle::farm::{FarmError, Interrupted};
use cuticle::job::{AutoPlan, Job, Part, Request};
use cuticle::quality::delivered::{delivered, delivered_denoised};
use cuticle::quality::{Fixed, QualityMode};
use cuticle::render::{
    self, LightSelection, MultipleScattering, Reconstruction, RenderStats, Shading, ShadowMode,
    TransmittanceMode,
};
use cuticle::scene::Overrides;

use super::{load_scene, parse_resolution, scene_name};

#[derive(clap::Args)]
pub struct RenderArgs {
    /// Scene file (TOML), or a USD stage (`.usda`, `.usdc`, `.usdz`, `.usd`) rendered with defaults: its curves,
    /// meshes, camera and lights. Without it, the built-in default scene (a procedural fur ball).
    scene: Option<PathBuf>,
    /// Output image: `.exr` (beauty + AOVs, plus a `.png` preview beside it) or `.png` (preview only).
    #[arg(short, long, default_value = "cuticle.exr")]
    output: PathBuf,
    /// Camera samples per pixel (overrides film.spp).
    #[arg(long)]
    spp: Option<u32>,
    /// Resolution WxH, e.g. 1280x720 (overrides film.resolution).
    #[arg(long, value_parser = parse_resolution)]
    res: Option<[u32; 2]>,
    /// Worker threads (default: all cores). The image does not depend on it.
    #[arg(long)]
    threads: Option<usize>,
    /// Strand geometry, round or flat (overrides hair.curves).
    #[arg(long, value_parser = scene_name::<CurveKind>)]
    curves: Option<CurveKind>,
    /// Strand tracer: embree or bvh, the pure-Rust BVH (overrides hair.backend).
    #[arg(long, value_parser = scene_name::<Backend>)]
    backend: Option<Backend>,
    /// Seed of the sample streams (overrides film.seed).
    #[arg(long)]
    seed: Option<u32>,
    /// AOV layers the EXR holds beside the beauty: all, none, or a comma-separated list such as depth,albedo
    /// (overrides film.aovs).
    #[arg(long, value_name = "LAYERS", value_parser = parse_aovs)]
    aovs: Option<AovList>,
    /// Self-shadowing: raytraced, deep-opacity or none (overrides shadows.mode).
    #[arg(long, value_parser = scene_name::<ShadowMode>)]
    shadows: Option<ShadowMode>,
    /// How light samples see semi-transparent strands: stochastic or exact (overrides shadows.transmittance).
    #[arg(long, value_parser = scene_name::<TransmittanceMode>)]
    transmittance: Option<TransmittanceMode>,
    /// Light samples per light at the first shading point (overrides integrator.light_samples).
    #[arg(long)]
    light_samples: Option<u32>,
    /// Material samples at the first shading point (overrides integrator.material_samples).
    #[arg(long)]
    material_samples: Option<u32>,
    /// Indirect bounces, 0 = direct light only (overrides integrator.path_length).
    #[arg(long)]
    path_length: Option<u32>,
    /// all: every light gets its own light samples; one: each light sample goes to one light chosen by power (an
    /// environment by its irradiance) (overrides integrator.lights).
    #[arg(long, value_parser = scene_name::<LightSelection>)]
    lights: Option<LightSelection>,
    /// lanes: the wavefront integrator (eight paths at a time, shaded in f32x8 lanes); scalar: the scalar path
    /// tracer, the reference; the same image either way (overrides integrator.shading).
    #[arg(long, value_parser = scene_name::<Shading>)]
    shading: Option<Shading>,
    /// splat: each sample counts in every pixel its filter reaches (less noise at the same spp); importance: each
    /// counts in its own pixel, its offset drawn from the filter; the same converged image (overrides
    /// film.reconstruction).
    #[arg(long, value_parser = scene_name::<Reconstruction>)]
    reconstruction: Option<Reconstruction>,
    /// path: light between fibres by path tracing (integrator.path_length bounces); dual: by dual scattering,
    /// Chiang's model only, paths end at the first shading point (overrides integrator.multiple_scattering).
    #[arg(long, value_parser = scene_name::<MultipleScattering>)]
    multiple_scattering: Option<MultipleScattering>,
    /// Refuse the frame before building it when its estimated memory exceeds this size (e.g. 4G, 512M; default:
    /// 3/4 of physical memory).
    #[arg(long, value_name = "SIZE", value_parser = render::budget::parse_size)]
    max_memory: Option<u64>,
    /// Also write every deep opacity map (z0 and per-layer transmittance) as an EXR into this directory.
    #[arg(long, value_name = "DIR")]
    dump_shadow_maps: Option<PathBuf>,
    /// Denoise the frame with Intel Open Image Denoise: `denoised.R/G/B` beside the beauty in the EXR, and the PNG
    /// preview made from them. Guide: color (the default: the colour alone), albedo or albedo-prefiltered (the
    /// albedo AOV). Whole frames only (`cuticle merge --denoise` for tiles).
    #[arg(long, value_name = "GUIDE", num_args = 0..=1, default_missing_value = "color",
          value_parser = scene_name::<cuticle::image::denoise::Guide>)]
    denoise: Option<cuticle::image::denoise::Guide>,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
    /// With --quality auto: print the reasons and numbers behind every decision.
    #[arg(short, long)]
    verbose: bool,
    /// Render only the pixels x0..x1 × y0..y1 of the frame (EXR data window; same pixels as the full render).
    #[arg(long, value_name = "X0,Y0,X1,Y1", value_parser = render::tiles::Region::parse, conflicts_with = "tile")]
    crop: Option<render::Region>,
    /// Render part I (from 0) of N of the frame: a band of whole rows (see `cuticle merge`).
    #[arg(long, value_name = "I/N", value_parser = render::tiles::parse_part)]
    tile: Option<(u32, u32)>,
    /// Render frames A..B (inclusive) of the camera's turntable (camera.orbit_degrees_per_frame), one
    /// `name.####.exr` each.
    #[arg(long, value_name = "A..B", value_parser = cuticle::farm::parse_frames)]
    frames: Option<std::ops::RangeInclusive<i32>>,
    /// fixed (the scene's settings) or auto: choose curves, shadows, path length and samples for --target and say
    /// why (overrides quality.mode; options given here stay fixed).
    #[arg(long)]
    quality: Option<QualityMode>,
    /// Error target of --quality auto: relative RMSE of the beauty against a converged image (overrides
    /// quality.target).
    #[arg(long)]
    target: Option<f32>,
}

/// `--aovs`: `all`, `none` (the beauty alone) or comma-separated layer names (checked with the scene, by
/// `film.aovs`' own validation).
fn parse_aovs(s: &str) -> Result<AovList, String> {
    match s.trim() {
        "" => Err("expected all, none or layer names such as depth,albedo".to_owned()),
        "none" => Ok(AovList(Vec::new())),
        list => Ok(AovList(
            list.split(',').map(|l| l.trim().to_owned()).collect(),
        )),
    }
}

/// The value of `--aovs` (one argument holding a list, so clap must not see a `Vec`).
#[derive(Clone, Debug)]
struct AovList(Vec<String>);

/// Longest line auto prints without `--verbose`.
const LINE: usize = 120;

pub fn render_command(args: RenderArgs) -> Result<()> {
    if args.spp == Some(0) {
        bail!("--spp must be at least 1");
    }
    let overrides = Overrides {
        spp: args.spp,
        resolution: args.res,
        seed: args.seed,
        aovs: args.aovs.map(|a| a.0),
        reconstruction: args.reconstruction,
        curves: args.curves,
        backend: args.backend,
        shadows: args.shadows,
        transmittance: args.transmittance,
        light_samples: args.light_samples,
        material_samples: args.material_samples,
        path_length: args.path_length,
        lights: args.lights,
        shading: args.shading,
        multiple_scattering: args.multiple_scattering,
        quality: args.quality,
        target: args.target,
    };
    let scene = load_scene(args.scene.as_deref())?.apply(&overrides)?;
    if args.target.is_some() && scene.quality.mode != QualityMode::Auto {
        eprintln!(
            "warning: --target is read only by --quality auto; this render uses the scene's fixed settings"
        );
    }
    let part = match (args.crop, args.tile) {
        (Some(crop), _) => Part::Crop(crop),
        (None, Some((index, count))) => Part::Tile { index, count },
        (None, None) => Part::Full,
    };
    let cancel = cuticle::farm::catch_signals()
        .map_err(|e| anyhow::anyhow!("cannot catch sigint/sigterm: {e}"))?;
    let request = Request {
        scene,
        fixed: Fixed::from_overrides(&overrides),
        threads: args.threads,
        max_memory: args.max_memory,
        part,
        frames: args.frames,
        output: Some(args.output),
        dump_shadow_maps: args.dump_shadow_maps,
        denoise: args.denoise,
        progress: !args.quiet,
    };
    let job = prepare_answering_signals(request, &cancel)?;
    if let Some(auto) = &job.auto {
        print_plan(auto, job.denoised.is_some(), args.verbose);
    }
    let dropped_before = render::film::dropped_samples();
    let mut last = None;
    for f in job.frames() {
        if !args.quiet {
            if let Some(path) = job.output_path(f) {
                eprintln!("rendering {}", path.display());
            }
        }
        let rendered = job.render(f, Some(&cancel))?;
        for p in job.write(&rendered)? {
            eprintln!("wrote {}", p.display());
        }
        if let Some(guide) = args.denoise {
            eprintln!(
                "denoised ({} guide) in {:.2} s",
                guide.name(),
                rendered.denoise_seconds
            );
        }
        if let Some(r) = &rendered.rounds {
            eprintln!("auto: denoised rounds {} spp", r.path());
            if let Some(w) = r.denoiser_warning() {
                eprintln!("warning: {w}");
            }
        }
        last = Some((rendered.stats, rendered.rounds));
    }
    let (stats, rounds) = last.unwrap_or_default();
    print_summary(&job, &stats, rounds.as_ref(), dropped_before);
    if args.verbose {
        if let (Some(e), Some(peak)) = (
            job.frame.memory_estimate,
            cuticle::measure::peak_rss_bytes(),
        ) {
            eprintln!(
                "memory: estimated {} ({}), peak {}",
                cuticle::util::input_file::human_bytes(e.total()),
                e.parts(),
                cuticle::util::input_file::human_bytes(peak)
            );
        }
    }
    Ok(())
}

/// [`Job::prepare`] on a thread of its own, while this one answers SIGINT/SIGTERM within 50 ms: loading, the
/// tracer's build and the maps' builds take seconds to minutes on large grooms (20 s for 6·10⁵ strands) and read
/// no cancel flag, so the first Ctrl-C was answered only after them. Nothing is written before the job is
/// prepared, so stopping then leaves nothing behind; the process ends with the build still running on its thread.
fn prepare_answering_signals(
    request: Request,
    cancel: &std::sync::atomic::AtomicUsize,
) -> Result<Job> {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::Builder::new()
        .name("prepare".to_owned())
        .spawn(move || {
            let _ = tx.send(Job::prepare(request));
        })
        .context("cannot start the thread that prepares the job")?;
    loop {
        match rx.recv_timeout(std::time::Duration::from_millis(50)) {
            Ok(job) => return Ok(job?),
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
                if let Some(i) = Interrupted::caught(cancel) {
                    return Err(FarmError::Interrupted(i).into());
                }
            }
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
                bail!("the thread that prepares the job ended without a result")
            }
        }
    }
}

/// Auto's decisions, one line each (with `verbose`, the reasons under them), its prediction, and a warning when
/// the settings the user fixed cannot meet the target.
fn print_plan(auto: &AutoPlan, denoised: bool, verbose: bool) {
    for d in &auto.decisions {
        let line = format!("auto: {} = {}", d.key, d.value);
        eprintln!("{}", shorten(&line, LINE));
        if verbose {
            eprintln!("      {}", d.reason);
        }
    }
    let p = &auto.pilot;
    if denoised {
        eprintln!(
            "auto: pilots {:.2} s; undenoised, about {} spp and {:.1} s would meet target {}",
            p.pilot_seconds, p.spp, p.predicted_seconds, auto.target
        );
    } else {
        eprintln!(
            "auto: pilots {:.2} s; predicted render {:.1} s, noise {:.4} for target {}",
            p.pilot_seconds, p.predicted_seconds, p.predicted_noise, auto.target
        );
    }
    if let Some(why) = auto.shortfall() {
        eprintln!("warning: {why}");
    }
}

/// The share of an environment map's magnitude in negative texels (read as 0) above which a render says so.
const NEGATIVE_SHARE_REPORTED: f64 = 1e-4;

/// The summary line of the last frame, auto's and the maps' shares, and warnings of samples or rays refused.
fn print_summary(
    job: &Job,
    stats: &RenderStats,
    rounds: Option<&cuticle::quality::denoised::Rounds>,
    dropped_before: u64,
) {
    eprintln!("{}", job.summary(stats));
    if job.frame.zero_length_strands > 0 {
        eprintln!(
            "warning: {} strands of zero length (every point at one place) were left out",
            job.frame.zero_length_strands
        );
    }
    for light in &job.frame.lights {
        if let cuticle::light::Light::Environment(env) = light {
            // Lossy compression leaves tiny negatives (the shipped maps: 3 to 8,980 values, at most 3e-7 of the
            // map's magnitude); only a share that could change the image is reported.
            let share = env.negative_share();
            if share > NEGATIVE_SHARE_REPORTED {
                eprintln!(
                    "warning: the environment map had {} negative texel values, read as 0: {:.2} % of its \
                     magnitude (a damaged map?)",
                    env.clamped_texels(),
                    100.0 * share
                );
            }
        }
    }
    if let Some(auto) = &job.auto {
        let p = auto.pilot.pilot_seconds;
        eprintln!(
            "auto: the pilots took {:.0} % of pilots + render ({p:.2} s of {:.2} s)",
            100.0 * p / (p + stats.seconds).max(1e-9),
            p + stats.seconds
        );
        let delivered = match rounds {
            Some(r) => delivered_denoised(&auto.pilot, auto.target, r),
            None => delivered(&auto.pilot, auto.target, stats.noise.as_ref()),
        };
        eprintln!("{}", delivered.line());
        if let Some(why) = delivered.shortfall() {
            eprintln!("warning: {why}");
        }
    }
    if job.uses_maps() {
        eprintln!(
            "deep opacity maps: built in {:.3} s, {:.1} MB, {} lookups",
            stats.shadow_build_seconds,
            stats.shadow_map_bytes as f64 / 1e6,
            stats.rays.map_lookups
        );
    }
    let dropped = render::film::dropped_samples() - dropped_before;
    if dropped > 0 {
        eprintln!(
            "warning: {dropped} camera samples were not finite and were left out of their pixels (a bug: please \
             report)"
        );
    }
    if stats.rays.rejected > 0 {
        eprintln!(
            "warning: {} invalid rays were rejected before tracing (a bug: please report)",
            stats.rays.rejected
        );
    }
}

/// `line` cut to `max` characters, with an ellipsis where it was cut.
fn shorten(line: &str, max: usize) -> String {
    if line.chars().count() <= max {
        return line.to_owned();
    }
    let mut s: String = line.chars().take(max - 1).collect();
    s.push('…');
    s
}

/// `cuticle merge`: tiles into one frame.
#[derive(clap::Args)]
pub struct MergeArgs {
    /// The merged frame (`.exr`; a `.png` preview is written beside it).
    #[arg(short, long)]
    output: PathBuf,
    /// The tile EXRs of `cuticle render --tile` or `--crop`, covering the frame exactly once.
    #[arg(required = true)]
    tiles: Vec<PathBuf>,
    /// Denoise the merged frame (as `render --denoise[=GUIDE]` does a whole frame).
    #[arg(long, value_name = "GUIDE", num_args = 0..=1, default_missing_value = "color",
          value_parser = scene_name::<cuticle::image::denoise::Guide>)]
    denoise: Option<cuticle::image::denoise::Guide>,
}

pub fn merge_command(args: &MergeArgs) -> Result<()> {
    if !args
        .output
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"))
    {
        bail!(
            "{}: the merged frame must end in .exr",
            args.output.display()
        );
    }
    let preview = args.output.with_extension("png");
    cuticle::image::check_output(&args.output)?;
    cuticle::image::check_output(&preview)?;
    // SIGINT/SIGTERM set a flag, read after the tiles are read and before the frame is put in place: an
    // interrupted merge leaves no temporary file (the staged ones are removed as `outputs` drops) and the old frame
    // as it was. A second signal ends the process at once.
    let cancel = cuticle::farm::catch_signals()
        .map_err(|e| anyhow::anyhow!("cannot catch sigint/sigterm: {e}"))?;
    if args.denoise.is_some() {
        cuticle::image::denoise::available().map_err(|e| anyhow::anyhow!("--denoise: {e}"))?;
    }
    let mut merged = cuticle::farm::merge(&args.tiles)?;
    if args.denoise.is_some() && merged.splatted() {
        bail!(
            "--denoise: the tiles were rendered with film.reconstruction = \"splat\", whose noise is shared by \
             neighbouring pixels and which Open Image Denoise cannot remove; render them with --reconstruction \
             importance to denoise the merged frame"
        );
    }
    if let Some(guide) = args.denoise {
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
        cuticle::image::denoise::add_denoised(&mut merged.image, guide, threads)
            .map_err(|e| anyhow::anyhow!("--denoise: {e}"))?;
    }
    if let Some(i) = Interrupted::caught(&cancel) {
        return Err(FarmError::Interrupted(i).into());
    }
    let mut outputs = cuticle::image::Outputs::new();
    outputs.exr_with_preview(&args.output, &preview, &merged.image, &merged.info)?;
    if let Some(i) = Interrupted::caught(&cancel) {
        return Err(FarmError::Interrupted(i).into());
    }
    for p in outputs.commit()? {
        eprintln!("wrote {}", p.display());
    }
    Ok(())
}
