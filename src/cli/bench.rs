//! `cuticle bench`: benchmarks, not tests; they print throughput figures.

use std::path::PathBuf;

use anyhow::Result;
use clap::Subcommand;

use cuticle::accel::{Backend, CurveKind};
use cuticle::scene::{Overrides, Scene, Shading};

use super::{load_scene, parse_resolution, scene_name, threads};

#[derive(Subcommand)]
pub enum BenchCommand {
    /// Wall time of a whole frame (default: the built-in scene), rays/s and peak memory.
    Frame(TimedRenderArgs),
    /// The renderer's rays/s against its tracer alone on the same rays: records every tracer query of one frame,
    /// traces them again without shading, prints both rates and their ratio. With `--packets`, traces the recorded
    /// queries one by one against Embree's packet queries instead.
    Replay(ReplayArgs),
    /// Shadow cost of ray-traced shadows and of deep opacity maps on one scene (default: the built-in scene), and
    /// the difference between their images.
    Shadows(TimedRenderArgs),
    /// Embree against the pure-Rust BVH on identical rays: Mrays/s per ray type (camera, secondary, shadow exact
    /// and stochastic), build time and bytes per segment, for round and flat curves.
    Trace {
        /// Scene whose hair model is traced (default: the built-in default scene).
        scene: Option<PathBuf>,
        /// Worker threads; a list measures each, e.g. `--threads 1,2` (default: all cores).
        #[arg(long, value_delimiter = ',')]
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
    /// (`scenes/groom-1m.toml`'s fur ball), e.g. `--strands 100000,1000000` (10⁶ strands take minutes and ~6 GB).
    Build {
        /// Strand counts, one groom each.
        #[arg(long, value_delimiter = ',', default_value = "100000")]
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
        /// Threads of the rayon pool for the Rust BVH build (default: all cores; Embree's builder uses every core).
        #[arg(long)]
        threads: Option<usize>,
    },
}

/// A benchmark that renders a scene several times.
#[derive(clap::Args)]
pub struct TimedRenderArgs {
    /// Scene to render (default: the built-in default scene).
    scene: Option<PathBuf>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Timed renders (per variant) after one warm-up.
    #[arg(long, default_value_t = 2)]
    repetitions: usize,
    /// Strand tracer: embree or bvh (overrides hair.backend).
    #[arg(long, value_parser = scene_name::<Backend>)]
    backend: Option<Backend>,
    /// Resolution WxH (overrides film.resolution).
    #[arg(long, value_parser = parse_resolution)]
    res: Option<[u32; 2]>,
    /// Camera samples per pixel (overrides film.spp).
    #[arg(long)]
    spp: Option<u32>,
    /// lanes (the wavefront integrator) or scalar (overrides integrator.shading).
    #[arg(long, value_parser = scene_name::<Shading>)]
    shading: Option<Shading>,
}

/// `bench replay`'s options.
#[derive(clap::Args)]
pub struct ReplayArgs {
    #[command(flatten)]
    timed: TimedRenderArgs,
    /// Packet widths, e.g. `--packets 8,16`: trace the recorded camera, material and shadow queries one by one and
    /// grouped as the renderer's batches issue them, in Embree packets of each width, and print rays/s, their ratio
    /// and the agreement of the hits per query kind (Embree only).
    #[arg(long, value_delimiter = ',', value_parser = parse_packet_width)]
    packets: Vec<usize>,
}

/// A packet width `--packets` accepts: 8 or 16.
fn parse_packet_width(text: &str) -> Result<usize, String> {
    match text.trim().parse::<usize>() {
        Ok(w) if cuticle::accel::embree::PACKET_WIDTHS.contains(&w) => Ok(w),
        _ => Err(format!("packet width must be 8 or 16, got {text:?}")),
    }
}

impl TimedRenderArgs {
    /// The scene with the overrides, and the thread count.
    fn scene(&self) -> Result<(Scene, usize)> {
        if self.spp == Some(0) {
            anyhow::bail!("--spp must be at least 1");
        }
        let overrides = Overrides {
            backend: self.backend,
            resolution: self.res,
            spp: self.spp,
            shading: self.shading,
            ..Overrides::default()
        };
        let scene = load_scene(self.scene.as_deref())?.apply(&overrides)?;
        Ok((scene, threads(self.threads)?))
    }
}

pub fn bench_command(command: BenchCommand) -> Result<()> {
    match command {
        BenchCommand::Frame(args) => {
            let (scene, threads) = args.scene()?;
            let report = cuticle::bench::frame::frame(&scene, threads, args.repetitions)?;
            println!("{report}");
        }
        BenchCommand::Replay(ReplayArgs { timed, packets }) => {
            let (scene, threads) = timed.scene()?;
            if packets.is_empty() {
                let report = cuticle::bench::replay::replay(&scene, threads, timed.repetitions)?;
                println!("{report}");
            } else {
                let report =
                    cuticle::bench::packets::packets(&scene, threads, timed.repetitions, &packets)?;
                println!("{report}");
            }
        }
        BenchCommand::Shadows(args) => {
            let (scene, threads) = args.scene()?;
            let report = cuticle::bench::shadows::shadows(&scene, threads, args.repetitions)?;
            println!("{report}");
        }
        BenchCommand::Trace {
            scene,
            threads: counts,
            backend,
            curves,
            res,
            repetitions,
        } => {
            let counts = if counts.is_empty() {
                vec![threads(None)?]
            } else {
                counts
                    .into_iter()
                    .map(|n| threads(Some(n)))
                    .collect::<Result<_>>()?
            };
            let scene = load_scene(scene.as_deref())?;
            let (strands, mut config) = cuticle::bench::scene_config(&scene, res)?;
            config.threads = counts;
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
            threads: count,
        } => {
            let config = cuticle::bench::build::BuildConfig {
                strands,
                backends: backend,
                kinds: curves,
                embree_qualities: embree_quality,
                embree_layouts: embree_layout,
                threads: threads(count)?,
            };
            println!("{}", cuticle::bench::build::build(&config)?);
        }
    }
    Ok(())
}
