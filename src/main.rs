//! The `cuticle` command line: render a scene, describe a hair file, benchmark tracing.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use serde::de::DeserializeOwned;

use cuticle::accel::{Backend, CurveKind};
use cuticle::hair;
use cuticle::render::{self, thread_pool, Frame, LightSelection, ShadowMode, TransmittanceMode};
use cuticle::scene::{Overrides, Scene};

/// cuticle: a physically based hair renderer (Embree curves, thesis hair BSDFs, OpenImageIO output).
#[derive(Parser)]
#[command(version, about, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene to an EXR (beauty + AOVs) and a PNG preview beside it.
    Render(RenderArgs),
    /// Assemble the tiles of `render --tile`/`--crop` into one frame (EXR + PNG preview), checking they are of one
    /// job and cover every pixel exactly once.
    Merge(MergeArgs),
    /// Describe a hair file: strands, points, bounds, thickness statistics, format.
    Info {
        /// A `.hair` or `.tfx` file.
        file: PathBuf,
    },
    /// Plot a fibre model's lobes (like the thesis' figure 4) and its sampled-vs-analytic pdf histograms as PNGs.
    PlotBsdf(PlotArgs),
    /// Chart one column of a CSV table against another (PNG and SVG), one curve per value of a column.
    PlotCsv(PlotCsvArgs),
    /// Benchmarks (not tests): print throughput figures.
    #[command(subcommand)]
    Bench(BenchCommand),
    /// Studies: measured comparisons written to a directory (CSV tables, charts, crops).
    #[command(subcommand)]
    Study(StudyCommand),
}

#[derive(clap::Args)]
struct RenderArgs {
    /// Scene file (TOML). Without it, the built-in default scene (a procedural fur ball).
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
    /// Light samples for every light (all), or each for one light chosen by its weight, power with an environment counted by its irradiance (one) (overrides
    /// integrator.lights).
    #[arg(long, value_parser = scene_name::<LightSelection>)]
    lights: Option<LightSelection>,
    /// Refuse the frame before building it when its estimated memory exceeds this size (e.g. 4G, 512M; default:
    /// 3/4 of physical memory).
    #[arg(long, value_name = "SIZE", value_parser = render::budget::parse_size)]
    max_memory: Option<u64>,
    /// Also write every deep opacity map (z0 and per-layer transmittance) as an EXR into this directory.
    #[arg(long, value_name = "DIR")]
    dump_shadow_maps: Option<PathBuf>,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
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
    /// fixed (the scene's settings) or auto: choose curves, shadows, path length and spp for --target and print
    /// why (overrides quality.mode; options given here stay fixed).
    #[arg(long)]
    quality: Option<cuticle::quality::QualityMode>,
    /// Error target of --quality auto: relative RMSE of the beauty against a converged image (overrides
    /// quality.target).
    #[arg(long)]
    target: Option<f32>,
}

/// `cuticle merge`: tiles into one frame.
#[derive(clap::Args)]
struct MergeArgs {
    /// The merged frame (`.exr`; a `.png` preview is written beside it).
    output: PathBuf,
    /// The tile EXRs of `cuticle render --tile` or `--crop`, covering the frame exactly once.
    #[arg(required = true)]
    tiles: Vec<PathBuf>,
}

#[derive(clap::Args)]
struct PlotArgs {
    /// Take the `[material]` of this scene file (parameters included) instead of a model's defaults.
    scene: Option<PathBuf>,
    /// The model, with the papers' default parameters (ignored when a scene is given).
    #[arg(long, value_enum, default_value = "ishair")]
    material: MaterialName,
    /// Directory for the PNGs (created if needed).
    #[arg(short, long, default_value = "plots")]
    out: PathBuf,
    /// View direction's longitudinal angle θo, degrees.
    #[arg(long, default_value_t = 30.0, allow_hyphen_values = true)]
    theta_o: f32,
    /// θi of the azimuthal plot, degrees.
    #[arg(long, default_value_t = -30.0, allow_hyphen_values = true)]
    theta_i: f32,
    /// Relative azimuth φ of the longitudinal plot, degrees (180 shows TT).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    phi: f32,
    /// Directions drawn for the histogram.
    #[arg(long, default_value_t = 1_000_000)]
    samples: usize,
    /// Offset h = sin γo across the fibre, in [-1, 1], for models that depend on it (chiang); 0 = the centre.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    h: f32,
}

#[derive(clap::Args)]
struct PlotCsvArgs {
    /// The CSV table (a header line, then rows).
    file: PathBuf,
    /// The horizontal column.
    #[arg(long)]
    x: String,
    /// The vertical column. Rows where x or y is empty or not a number are left out.
    #[arg(long)]
    y: String,
    /// One curve per value of this column.
    #[arg(long)]
    by: Option<String>,
    /// Label each point with this column's value.
    #[arg(long)]
    point_label: Option<String>,
    /// Log10 horizontal axis.
    #[arg(long)]
    log_x: bool,
    /// Log10 vertical axis.
    #[arg(long)]
    log_y: bool,
    /// The chart title.
    #[arg(long, default_value = "")]
    title: String,
    /// The horizontal axis title (default: the column name).
    #[arg(long)]
    x_label: Option<String>,
    /// The vertical axis title (default: the column name).
    #[arg(long)]
    y_label: Option<String>,
    /// Directory for `<stem>.png` and `<stem>.svg` (created if needed).
    #[arg(short, long, default_value = ".")]
    out: PathBuf,
    /// File name of the chart, without extension (default: the table's).
    #[arg(long)]
    stem: Option<String>,
    /// Chart size WxH, pixels.
    #[arg(long, value_parser = parse_resolution, default_value = "960x640")]
    size: [u32; 2],
}

/// Model names for `plot-bsdf --material`.
#[derive(Clone, Copy, clap::ValueEnum)]
enum MaterialName {
    /// Kajiya & Kay 1989.
    KajiyaKay,
    /// Hery & Ramamoorthi 2012 (thesis §4.2).
    Marschner,
    /// Ou et al. 2012 (thesis §4.3).
    Ishair,
    /// Chiang et al. 2016 (issue 14), at offset `--h`.
    Chiang,
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Wall time of a whole frame (default: furball-512, `scenes/furball.toml`), rays/s and peak memory.
    Frame(TimedRenderArgs),
    /// The renderer's rays/s against its tracer alone on the same rays (issue 15 target 3): records every tracer
    /// query of one frame, traces them again without shading, prints both rates and their ratio.
    Replay(TimedRenderArgs),
    /// Shadow cost of ray-traced shadows and of deep opacity maps on one scene (default: the built-in scene; the
    /// issue-6 configuration is `scenes/furball-shadows.toml`), and the difference between their images.
    Shadows(TimedRenderArgs),
    /// Embree against the pure-Rust BVH on identical rays: Mrays/s per ray type (camera, secondary, shadow exact
    /// and stochastic), build time and bytes per segment, for round and flat curves.
    Trace {
        /// Scene whose hair model is traced (default: the built-in default scene).
        scene: Option<PathBuf>,
        /// Worker threads; a list measures each, e.g. `--threads 1,2`.
        #[arg(long, value_delimiter = ',', default_value = "2")]
        threads: Vec<usize>,
        /// Backends to measure, e.g. `--backend bvh` (default: embree,bvh).
        #[arg(long, value_delimiter = ',', value_parser = scene_name::<Backend>, default_value = "embree,bvh")]
        backend: Vec<Backend>,
        /// Curve types to measure (default: round,flat).
        #[arg(long, value_delimiter = ',', value_parser = scene_name::<CurveKind>, default_value = "round,flat")]
        curves: Vec<CurveKind>,
        /// Camera rays: one per pixel of a WxH image through the scene's camera.
        #[arg(long, value_parser = parse_resolution, default_value = "512x512")]
        res: [u32; 2],
        /// Timed repetitions after one warm-up.
        #[arg(long, default_value_t = 3)]
        repetitions: usize,
    },
    /// Build time, bytes per segment and peak memory of each backend on procedural grooms of 16-point strands
    /// (`scenes/groom-1m.toml`'s fur ball), e.g. `--strands 100000,1000000`.
    Build {
        /// Strand counts, one groom each.
        #[arg(long, value_delimiter = ',', default_value = "100000,1000000")]
        strands: Vec<u32>,
        /// Backends to measure (default: embree,bvh).
        #[arg(long, value_delimiter = ',', value_parser = scene_name::<Backend>, default_value = "embree,bvh")]
        backend: Vec<Backend>,
        /// Curve types to measure (default: round,flat).
        #[arg(long, value_delimiter = ',', value_parser = scene_name::<CurveKind>, default_value = "round,flat")]
        curves: Vec<CurveKind>,
        /// Embree build qualities to measure, e.g. `--embree-quality low,medium` (the renderer uses medium).
        #[arg(long, value_delimiter = ',', value_parser = cuticle::bench::build::parse_quality, default_value = "medium")]
        embree_quality: Vec<cuticle::accel::embree::BuildQuality>,
        /// Embree leaf layouts to measure, e.g. `--embree-layout fast,compact` (RTC_SCENE_FLAG_COMPACT).
        #[arg(long, value_delimiter = ',', value_parser = cuticle::bench::build::parse_layout, default_value = "fast,compact")]
        embree_layout: Vec<cuticle::accel::embree::Layout>,
        /// Threads of the rayon pool (the Rust BVH build; Embree's builder uses every core).
        #[arg(long, default_value_t = 2)]
        threads: usize,
    },
}

/// A benchmark that renders a scene several times.
#[derive(clap::Args)]
struct TimedRenderArgs {
    /// Scene to render (default: the built-in default scene).
    scene: Option<PathBuf>,
    /// Worker threads.
    #[arg(long, default_value_t = 2)]
    threads: usize,
    /// Timed renders (per variant) after one warm-up.
    #[arg(long, default_value_t = 2)]
    repetitions: usize,
    /// Strand tracer: embree or bvh (overrides hair.backend).
    #[arg(long, value_parser = scene_name::<Backend>)]
    backend: Option<Backend>,
}

impl TimedRenderArgs {
    /// The scene, after checking the thread count.
    fn scene(&self) -> Result<Scene> {
        if self.threads == 0 {
            bail!("--threads must be at least 1");
        }
        let overrides = Overrides {
            backend: self.backend,
            ..Overrides::default()
        };
        Ok(load_scene(self.scene.as_deref())?.apply(&overrides)?)
    }
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

fn parse_resolution(s: &str) -> Result<[u32; 2], String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("expected WxH, e.g. 640x480, got `{s}`"))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<u32>()
            .map_err(|_| format!("expected WxH, e.g. 640x480, got `{s}`"))
    };
    let (w, h) = (parse(w)?, parse(h)?);
    if w == 0 || h == 0 {
        return Err(format!("resolution must be at least 1x1, got `{s}`"));
    }
    Ok([w, h])
}

/// Parses a value the way the scene file spells it (`deep-opacity`, `flat`, ...), so the command line and the
/// TOML accept the same names and the library's types need no command-line derive.
fn scene_name<T: DeserializeOwned>(s: &str) -> Result<T, String> {
    T::deserialize(serde::de::value::StrDeserializer::<serde::de::value::Error>::new(s))
        .map_err(|e| e.to_string())
}

fn load_scene(path: Option<&Path>) -> Result<Scene> {
    Ok(match path {
        Some(p) => Scene::load(p)?,
        None => Scene::default_scene(),
    })
}

fn render_command(args: RenderArgs) -> Result<()> {
    if args.spp == Some(0) {
        bail!("--spp must be at least 1");
    }
    let overrides = Overrides {
        spp: args.spp,
        resolution: args.res,
        seed: args.seed,
        aovs: args.aovs.map(|a| a.0),
        curves: args.curves,
        backend: args.backend,
        shadows: args.shadows,
        transmittance: args.transmittance,
        light_samples: args.light_samples,
        material_samples: args.material_samples,
        path_length: args.path_length,
        lights: args.lights,
        quality: args.quality,
        target: args.target,
    };
    let scene = load_scene(args.scene.as_deref())?.apply(&overrides)?;
    let description = format!("{scene:?}");
    let frames: Vec<Option<i32>> = match &args.frames {
        Some(r) => r.clone().map(Some).collect(),
        None => vec![None],
    };
    // Every output path is checked before anything is loaded or rendered.
    let exr_output = match args.output.extension().and_then(|e| e.to_str()) {
        Some(e) if e.eq_ignore_ascii_case("exr") => true,
        Some(e) if e.eq_ignore_ascii_case("png") => false,
        _ => bail!("{}: output must end in .exr or .png", args.output.display()),
    };
    for &f in &frames {
        let path = cuticle::farm::frame_path(&args.output, f);
        cuticle::image::check_output(&path)?;
        if exr_output {
            cuticle::image::check_output(&path.with_extension("png"))?;
        }
    }
    if let Some(dir) = &args.dump_shadow_maps {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create the shadow-map directory {}", dir.display()))?;
        cuticle::image::check_output(&dir.join("map.exr"))?;
    }
    let cancel = cuticle::farm::catch_signals().context("cannot catch sigint/sigterm")?;

    let threads = args
        .threads
        .map(render::budget::check_threads)
        .transpose()
        .map_err(anyhow::Error::msg)?;
    let pool = thread_pool(threads)?;
    let spec = scene.resolve()?;
    let (limit, limit_source) = match args.max_memory {
        Some(bytes) => (bytes, "--max-memory".to_owned()),
        None => render::budget::default_limit(),
    };
    let auto =
        (scene.quality.mode == cuticle::quality::QualityMode::Auto).then_some(&scene.quality);
    // What the command line fixes, auto keeps.
    let fixed = cuticle::quality::Fixed {
        curves: args.curves.is_some(),
        shadows: args.shadows.is_some(),
        path_length: args.path_length.is_some(),
        samples: args.light_samples.is_some() || args.material_samples.is_some(),
        spp: args.spp.is_some(),
    };
    let mut decisions = Vec::new();
    let frame = pool.install(|| {
        // Auto samples adaptively unless --spp fixes the count: its memory is checked for that.
        Frame::load_adjusted(
            spec,
            limit,
            &limit_source,
            auto.is_some() && !fixed.spp,
            |strands, spec| {
                if auto.is_some() && !fixed.curves {
                    let s = &spec.settings;
                    let (kind, d) = cuticle::quality::plan_curves(
                        strands,
                        &spec.material,
                        &s.camera,
                        s.film.resolution,
                    );
                    spec.curves = kind;
                    decisions.push(d);
                }
            },
        )
    })?;
    // The frame is built: load OpenImageIO in the background while it renders. Not earlier: `dlopen` holds the
    // loader's lock for the whole load (OpenImageIO pulls in some sixty libraries, ~0.1 s), and creating threads
    // needs that lock, so Embree's device and build (TBB starting its workers) waited for it. Measured on the peer
    // scene (`hyperfine -w 1 -r 6`, whole process, 2 threads): 5.95 ± 0.05 s preloading before the hair loads,
    // 5.86 ± 0.04 s from here; device creation went from 0.14 s to 0.000 s.
    cuticle::image::preload();
    let planned = auto
        .map(|q| pool.install(|| cuticle::quality::plan_frame(&frame, &frame.settings, q, fixed)));
    if let (Some(p), Some(q)) = (&planned, auto) {
        for d in decisions.iter().chain(&p.decisions) {
            eprintln!("auto: {d}");
        }
        eprintln!(
            "auto: pilots took {:.2} s ({:.2} CPU s predicted from their rays); predicted render {:.1} s at {} spp, noise {:.4} (target {})",
            p.pilot.pilot_seconds,
            p.pilot.pilot_predicted_seconds,
            p.pilot.predicted_seconds,
            p.pilot.spp,
            p.pilot.predicted_noise,
            q.target
        );
    }
    let pilot_seconds = planned.as_ref().map(|p| p.pilot.pilot_seconds);
    let (settings, planned_maps) = match planned {
        Some(p) => (p.settings, p.maps.map(|m| (m, p.maps_seconds))),
        None => (frame.settings.clone(), None),
    };
    let settings = &settings;
    let [width, height] = settings.film.resolution;
    settings
        .camera
        .camera(frame.strands.bounds(), width, height)
        .map_err(|m| anyhow::anyhow!("{}: {m}", scene.source.display()))?;
    let dropped_before = render::film::dropped_samples();
    let region = match (args.crop, args.tile) {
        (Some(crop), _) => {
            crop.check_inside(width, height)
                .map_err(anyhow::Error::msg)?;
            crop
        }
        (None, Some((i, n))) => {
            render::Region::band(i, n, width, height).map_err(anyhow::Error::msg)?
        }
        (None, None) => render::Region::full(width, height),
    };
    // Deep opacity maps are built once: for the render (in deep-opacity mode) and for --dump-shadow-maps alike.
    let deep_opacity = settings.shadows.mode == ShadowMode::DeepOpacity;
    let start = Instant::now();
    let (maps, maps_seconds) = match planned_maps {
        Some((m, s)) => (Some(m), s),
        None => {
            let maps = (deep_opacity || args.dump_shadow_maps.is_some())
                .then(|| pool.install(|| frame.shadow_maps(settings)));
            (maps, start.elapsed().as_secs_f64())
        }
    };
    let options = render::Options {
        progress: !args.quiet,
    };
    let mut stats = render::RenderStats::default();
    for (k, &f) in frames.iter().enumerate() {
        let mut settings = settings.clone();
        settings.camera.frame = f.unwrap_or(0);
        let path = cuticle::farm::frame_path(&args.output, f);
        if !args.quiet {
            eprintln!("rendering {}", path.display());
        }
        let r = pool.install(|| {
            frame.render_region(
                &settings,
                maps.as_ref(),
                maps_seconds,
                options,
                region,
                Some(&cancel),
            )
        });
        stats = r.stats;
        let job = cuticle::farm::job_hash(&description, settings.camera.frame);
        let info = cuticle::farm::render_info(
            region,
            width,
            height,
            &job,
            settings.camera.frame,
            r.tiles_done,
            r.tiles_total,
        );
        if !r.is_complete() {
            let signal = cancel.load(std::sync::atomic::Ordering::Relaxed) as i32;
            let partial = (r.tiles_done > 0).then(|| cuticle::farm::partial_path(&path));
            if let Some(p) = &partial {
                let mut outputs = cuticle::image::Outputs::new();
                outputs.exr(p, &r.image, &info)?;
                outputs.commit()?;
            }
            let i = cuticle::farm::Interrupted { signal, partial };
            return Err(cuticle::farm::FarmError::Interrupted(i).into());
        }
        let mut outputs = cuticle::image::Outputs::new();
        if let (Some(dir), Some(maps), 0) = (&args.dump_shadow_maps, &maps, k) {
            for (name, map) in maps.maps() {
                outputs.exr(
                    &dir.join(format!("{name}.exr")),
                    &map.to_image(),
                    &Default::default(),
                )?;
            }
        }
        if exr_output {
            outputs.exr_with_preview(&path, &path.with_extension("png"), &r.image, &info)?;
        } else {
            outputs.png_preview(&path, &r.image)?;
        }
        for p in outputs.commit()? {
            eprintln!("wrote {}", p.display());
        }
    }
    eprintln!(
        "{} strands ({:?} curves, {:?} backend), {width}x{height}, {}, {} threads: load {:.2} s, build {:.2} s, render {:.2} s \
         ({:.2} Mrays/s: {} camera, {} shadow, {} material rays)",
        frame.strands.strand_count(),
        frame.curves,
        frame.backend,
        match settings.adaptive {
            // Each pixel traces its samples' camera rays and, for the centre AOVs, one centre ray.
            Some(a) => {
                let pixels = u64::from(region.width()) * u64::from(region.height());
                let centre = if settings.film.traces_centre_ray() { pixels } else { 0 };
                let mean = stats.rays.camera.saturating_sub(centre) as f64 / pixels.max(1) as f64;
                format!("adaptive {}..{} spp (mean {mean:.1})", a.min, a.max)
            }
            None => format!("{} spp", settings.film.spp),
        },
        pool.current_num_threads(),
        frame.load_seconds,
        frame.build_seconds(),
        stats.seconds,
        stats.rays.total() as f64 / stats.seconds / 1e6,
        stats.rays.camera,
        stats.rays.shadow,
        stats.rays.material,
    );
    if let Some(p) = pilot_seconds {
        eprintln!(
            "auto: the pilots took {:.0} % of pilots + render ({p:.2} s of {:.2} s)",
            100.0 * p / (p + stats.seconds).max(1e-9),
            p + stats.seconds
        );
    }
    if deep_opacity {
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
    Ok(())
}

fn merge_command(args: &MergeArgs) -> Result<()> {
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
    let merged = cuticle::farm::merge(&args.tiles)?;
    let mut outputs = cuticle::image::Outputs::new();
    outputs.exr_with_preview(&args.output, &preview, &merged.image, &merged.info)?;
    for p in outputs.commit()? {
        eprintln!("wrote {}", p.display());
    }
    Ok(())
}

fn info_command(file: &Path) -> Result<()> {
    let model = hair::load(file)?;
    println!("file:         {}", file.display());
    println!("{}", model.summary());
    Ok(())
}

fn plot_command(args: PlotArgs) -> Result<()> {
    use cuticle::scene::MaterialConfig;
    let config = match &args.scene {
        Some(path) => Scene::load(path)?.material,
        None => {
            let name = match args.material {
                MaterialName::KajiyaKay => "kajiya-kay",
                MaterialName::Marschner => "marschner",
                MaterialName::Ishair => "ishair",
                MaterialName::Chiang => "chiang",
            };
            MaterialConfig::named(name).context("building the default material")?
        }
    };
    if !(args.h.is_finite() && args.h.abs() <= 1.0) {
        bail!("--h must be in [-1, 1], got {}", args.h);
    }
    let material = config.build().map_err(anyhow::Error::msg)?;
    let options = cuticle::plot::bsdf::PlotOptions {
        theta_o_deg: args.theta_o,
        theta_i_deg: args.theta_i,
        phi_deg: args.phi,
        samples: args.samples,
        ..Default::default()
    };
    let paths =
        cuticle::plot::bsdf::write_plots(&material.at(args.h), material.name, &args.out, &options)?;
    for p in paths {
        println!("wrote {}", p.display());
    }
    Ok(())
}

fn plot_csv_command(args: PlotCsvArgs) -> Result<()> {
    let text = std::fs::read_to_string(&args.file)
        .with_context(|| format!("cannot read {}", args.file.display()))?;
    let spec = cuticle::plot::CsvChart {
        x: args.x,
        y: args.y,
        by: args.by,
        point_label: args.point_label,
        log_x: args.log_x,
        log_y: args.log_y,
        title: args.title,
        x_label: args.x_label,
        y_label: args.y_label,
    };
    let chart = spec
        .line_chart(&text)
        .with_context(|| format!("{}", args.file.display()))?;
    let [w, h] = args.size;
    let figure = cuticle::plot::render(&chart, "csv", (w as usize, h as usize))?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let stem = match args.stem {
        Some(stem) => stem,
        None => args
            .file
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "chart".to_owned()),
    };
    for path in cuticle::plot::write_figure(&figure, &args.out, &stem)? {
        println!("wrote {}", path.display());
    }
    Ok(())
}

fn bench_command(command: BenchCommand) -> Result<()> {
    match command {
        BenchCommand::Frame(args) => {
            let scene = args.scene()?;
            let report = cuticle::bench::frame::frame(&scene, args.threads, args.repetitions)?;
            println!("{report}");
        }
        BenchCommand::Replay(args) => {
            let scene = args.scene()?;
            let report = cuticle::bench::replay::replay(&scene, args.threads, args.repetitions)?;
            println!("{report}");
        }
        BenchCommand::Shadows(args) => {
            let scene = args.scene()?;
            let report = cuticle::bench::shadows::shadows(&scene, args.threads, args.repetitions)?;
            println!("{report}");
        }
        BenchCommand::Trace {
            scene,
            threads,
            backend,
            curves,
            res,
            repetitions,
        } => {
            if threads.contains(&0) {
                bail!("--threads must be at least 1");
            }
            let scene = load_scene(scene.as_deref())?;
            let (strands, mut config) = cuticle::bench::scene_config(&scene, res)?;
            config.threads = threads;
            config.backends = backend;
            config.kinds = curves;
            config.repetitions = repetitions;
            let report = cuticle::bench::trace(&strands, &config)?;
            println!("{report}");
        }
        BenchCommand::Build {
            strands,
            backend,
            curves,
            embree_quality,
            embree_layout,
            threads,
        } => {
            if threads == 0 {
                bail!("--threads must be at least 1");
            }
            let config = cuticle::bench::build::BuildConfig {
                strands,
                backends: backend,
                kinds: curves,
                embree_qualities: embree_quality,
                embree_layouts: embree_layout,
                threads,
            };
            println!("{}", cuticle::bench::build::build(&config)?);
        }
    }
    Ok(())
}

// `cuticle study`: thin wrappers over `cuticle::study` (the logic and its docs live there).

#[derive(Subcommand)]
enum StudyCommand {
    /// Shadow modes against a converged ray-traced reference: error vs time, map memory, crops (issue 6).
    Shadows(StudyShadowsArgs),
    /// The same frame on Embree and on the pure-Rust BVH: time, error against a reference, image difference
    /// (issue 13).
    Backends(StudyBackendsArgs),
    /// Light samples against material samples, per model (thesis table 3, figure 17; issue 17).
    Samples(StudyKindArgs),
    /// Importance against uniform BSDF sampling, at equal samples and equal time (issue 17).
    Sampling(StudyKindArgs),
    /// ISHair's uniform against energy-based lobe selection (issue 17).
    Lobes(StudyKindArgs),
    /// The published (biased) against the exact Hery & Ramamoorthi sampler (issue 17).
    Hery(StudyKindArgs),
    /// Marschner and ISHair against a chiang reference (issue 17).
    Models(StudyKindArgs),
    /// Round tubes against flat ribbons per model and film width (issue 17).
    Curves(StudyKindArgs),
    /// Adversarial cases per method: stress.csv, stress.md (NaN/Inf, fireflies, error; failures named).
    Stress(StudyKindArgs),
    /// Every kind above, and one Markdown report (report.md) with the charts (issue 17).
    All(StudyKindArgs),
    /// `--quality auto` against every fixed configuration and the shipped settings, per error target (issue 18).
    Auto(StudyAutoArgs),
}

#[derive(clap::Args)]
struct StudyAutoArgs {
    /// Scene files (TOML).
    #[arg(required = true)]
    scenes: Vec<PathBuf>,
    /// Output directory: auto.md, auto.csv, auto-fits-<scene>.csv, the cached references.
    #[arg(short, long, default_value = "study")]
    out: PathBuf,
    /// Error targets (relative RMSE).
    #[arg(long, value_delimiter = ',', default_value = "0.1,0.05")]
    targets: Vec<f32>,
    /// Film resolution WxH.
    #[arg(long, value_parser = parse_resolution, default_value = "128x128")]
    res: [u32; 2],
    /// Samples per pixel of the references.
    #[arg(long, default_value_t = 512)]
    reference_spp: u32,
    /// Worker threads.
    #[arg(long, default_value_t = 2)]
    threads: usize,
}

#[derive(clap::Args)]
struct StudyKindArgs {
    /// Scene file (TOML).
    scene: PathBuf,
    /// Output directory: <kind>.csv, <kind>-summary.csv, <kind>-error-time.png/.svg, <kind>-time.png/.svg,
    /// <kind>-readouts.txt, the cached references (and report.md for all).
    #[arg(short, long, default_value = "study")]
    out: PathBuf,
    /// Short sweeps on a 32x24 film (unless --res): what CI runs.
    #[arg(long)]
    quick: bool,
    /// Where the reference EXRs are cached (default: the output directory).
    #[arg(long)]
    cache_dir: Option<PathBuf>,
    /// Samples per pixel of the references (default 256, 64 with --quick).
    #[arg(long)]
    reference_spp: Option<u32>,
    /// Seeds per point.
    #[arg(long, default_value_t = 3)]
    seeds: u32,
    /// Film resolution WxH (overrides film.resolution).
    #[arg(long, value_parser = parse_resolution)]
    res: Option<[u32; 2]>,
    /// Worker threads.
    #[arg(long, default_value_t = 2)]
    threads: usize,
    /// No progress bars.
    #[arg(short, long)]
    quiet: bool,
}

/// Runs `cuticle study <name>` for a framework kind (or `all`) and prints the read-outs.
fn study_kind(name: &str, a: StudyKindArgs) -> Result<()> {
    use cuticle::study::framework::{run_kind, StudyConfig};
    let defaults = StudyConfig::new(a.out, a.quick);
    let config = StudyConfig {
        cache_dir: a.cache_dir,
        seeds: a.seeds,
        reference_spp: a.reference_spp.unwrap_or(defaults.reference_spp),
        resolution: a.res,
        threads: a.threads,
        progress: !a.quiet,
        ..defaults
    };
    if name == "all" {
        let report = cuticle::study::report::run_all(&a.scene, &config)?;
        println!("wrote {}", report.markdown.display());
        for k in &report.kinds {
            k.readouts
                .iter()
                .for_each(|l| println!("{}: {l}", k.kind.name));
        }
    } else if name == "stress" {
        let report = cuticle::study::stress::run(&a.scene, &config)?;
        println!("wrote {}", report.markdown.display());
        report
            .skipped
            .iter()
            .for_each(|s| println!("skipped {}: {}", s.case, s.reason));
        report.failures.iter().for_each(|l| println!("{l}"));
    } else {
        let kind = cuticle::study::kinds::by_name(name, a.quick)
            .expect("a subcommand per kind")
            .map_err(|e| anyhow::anyhow!("study {name}: {e}"))?;
        let report = run_kind(&a.scene, &kind, &config)?;
        report.readouts.iter().for_each(|l| println!("{l}"));
    }
    Ok(())
}

/// The flags `study shadows` and `study backends` share.
#[derive(clap::Args)]
struct StudyWholeArgs {
    /// Scene file (TOML).
    scene: PathBuf,
    /// Where the reference EXRs are cached (default: the output directory).
    #[arg(long)]
    cache_dir: Option<PathBuf>,
    /// Samples per pixel of the references.
    #[arg(long, default_value_t = 256)]
    reference_spp: u32,
    /// Film resolution WxH (overrides film.resolution).
    #[arg(long, value_parser = parse_resolution)]
    res: Option<[u32; 2]>,
    /// Worker threads.
    #[arg(long, default_value_t = 2)]
    threads: usize,
    /// Seeds per point.
    #[arg(long, default_value_t = 3)]
    seeds: u32,
    /// No progress bars.
    #[arg(short, long)]
    quiet: bool,
}

#[derive(clap::Args)]
struct StudyShadowsArgs {
    #[command(flatten)]
    common: StudyWholeArgs,
    /// Output directory: the files of every study kind (shadows.csv, shadows-summary.csv, shadows-error-time.png,
    /// shadows-crops.png, ...), the cached reference (ray traced, exact transmittance).
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
    /// Side of the crop window, pixels.
    #[arg(long, default_value_t = 128)]
    crop: usize,
    /// Strand tracer of the variants: embree or bvh (overrides hair.backend; the reference keeps the scene's).
    #[arg(long, value_parser = scene_name::<Backend>)]
    backend: Option<Backend>,
}

#[derive(clap::Args)]
struct StudyBackendsArgs {
    #[command(flatten)]
    common: StudyWholeArgs,
    /// Output directory: the files of every study kind (backends.csv, backends-error-time.png, ...),
    /// backends-differences.csv, backends-diff-*.png, the cached references (Embree).
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
        threads: a.threads,
        progress: !a.quiet,
        crop: crop.unwrap_or(defaults.crop),
        ..defaults
    };
    let report = run_kind(&a.scene, &kind, &config)?;
    report.readouts.iter().for_each(|l| println!("{l}"));
    Ok(())
}

fn study_command(command: StudyCommand) -> Result<()> {
    match command {
        StudyCommand::Samples(a) => study_kind("samples", a)?,
        StudyCommand::Sampling(a) => study_kind("sampling", a)?,
        StudyCommand::Lobes(a) => study_kind("lobes", a)?,
        StudyCommand::Hery(a) => study_kind("hery", a)?,
        StudyCommand::Models(a) => study_kind("models", a)?,
        StudyCommand::Curves(a) => study_kind("curves", a)?,
        StudyCommand::All(a) => study_kind("all", a)?,
        StudyCommand::Auto(a) => {
            let md = cuticle::study::auto::run(&cuticle::study::auto::AutoStudyConfig {
                scenes: a.scenes,
                targets: a.targets,
                resolution: a.res,
                reference_spp: a.reference_spp,
                out: a.out,
                threads: a.threads,
            })?;
            print!("{md}");
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

fn run() -> Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Render(args) => render_command(args),
        Command::Merge(args) => merge_command(&args),
        Command::Info { file } => info_command(&file),
        Command::PlotBsdf(args) => plot_command(args),
        Command::PlotCsv(args) => plot_csv_command(args),
        Command::Bench(b) => bench_command(b),
        Command::Study(s) => study_command(s),
    }
}

/// The CPU features of the build target (`.cargo/config.toml`: x86-64-v3) that this CPU lacks; empty elsewhere.
fn missing_cpu_features() -> Vec<&'static str> {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
    {
        let mut missing = Vec::new();
        if !std::arch::is_x86_feature_detected!("avx2") {
            missing.push("avx2");
        }
        if !std::arch::is_x86_feature_detected!("fma") {
            missing.push("fma");
        }
        if !std::arch::is_x86_feature_detected!("bmi2") {
            missing.push("bmi2");
        }
        missing
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
    Vec::new()
}

fn main() -> ExitCode {
    let missing = missing_cpu_features();
    if !missing.is_empty() {
        eprintln!(
            "cuticle: error: this build targets x86-64-v3 and this CPU lacks {}; rebuild for it with \
             RUSTFLAGS=\"-C target-cpu=x86-64\" cargo build --release",
            missing.join(", ")
        );
        return ExitCode::from(2);
    }
    let result = run();
    // No exit while OpenImageIO is still being loaded in the background (image::finish_preload says why).
    cuticle::image::finish_preload();
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!(
                "cuticle: error: {}",
                cuticle::util::report::chain(e.as_ref())
            );
            match e.downcast_ref::<cuticle::farm::FarmError>() {
                Some(cuticle::farm::FarmError::Interrupted(i)) => ExitCode::from(i.exit_code()),
                _ => ExitCode::from(2),
            }
        }
    }
}
