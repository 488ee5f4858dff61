//! Trace throughput benchmark (`cuticle bench trace SCENE`): for round and flat curves, BVH build time, primary-ray
//! and shadow-ray throughput through the Embree tracer, Embree's memory and the process's peak memory.
//!
//! Method: the scene's camera shoots one ray through each pixel centre of its image. Every
//! primary hit spawns one shadow ray from the hit point towards a distant light, a transmittance query that ignores
//! the strand it starts on (so no origin offset is needed). Each measurement is repeated (3 times by default) after
//! one untimed warm-up run, and reported as median (min–max). Queries run on a local rayon pool of `threads`
//! threads, and the Embree device is configured with the same thread count, so BVH builds use it too. Ray
//! generation and scene loading are not timed. Every throughput is printed beside a correctness figure (hit count,
//! mean transmittance) so that runs doing different work are not compared.

pub mod frame;
pub mod shadows;

use std::fmt;
use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use crate::accel::embree::EmbreeTracer;
use crate::accel::embree::{Cutoff, Device, EmbreeError};
use crate::accel::{CurveKind, Hit, Tracer};
use crate::hair::Strands;
use crate::measure::{peak_rss_bytes, Timing};
use crate::ray::Ray;
use crate::render::camera::Camera;
use crate::scene::{LightConfig, Scene};

/// Why a benchmark could not run.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// Embree could not build the scene.
    #[error(transparent)]
    Embree(#[from] EmbreeError),
    /// The rayon thread pool could not be created.
    #[error("bench: could not create a pool of {threads} threads: {source}")]
    ThreadPool {
        /// The requested thread count.
        threads: usize,
        /// Rayon's error.
        source: rayon::ThreadPoolBuildError,
    },
}

/// What to measure.
#[derive(Debug, Clone, PartialEq)]
pub struct TraceConfig {
    /// Threads for queries (rayon) and BVH builds (Embree); 0 = all cores.
    pub threads: usize,
    /// The camera: one primary ray through each pixel centre of its image.
    pub camera: Camera,
    /// Direction from a hit point towards the distant light (normalised on use).
    pub to_light: Vec3,
    /// Timed repetitions (after one warm-up run); the median is reported.
    pub repetitions: usize,
    /// Curve types to measure.
    pub kinds: Vec<CurveKind>,
    /// Replaces every strand's opacity (as a scene may); `None` keeps the model's. Opacity sets how far shadow
    /// rays travel before they go dark, so shadow throughput depends on it.
    pub opacity: Option<f32>,
}

impl TraceConfig {
    /// Rays from `camera` on `threads` threads, light towards (1, 1, −1), 3 repetitions, round and flat curves.
    pub fn new(camera: Camera, threads: usize) -> Self {
        TraceConfig {
            threads,
            camera,
            to_light: Vec3::new(1.0, 1.0, -1.0),
            repetitions: 3,
            kinds: vec![CurveKind::Round, CurveKind::Flat],
            opacity: None,
        }
    }
}

/// Timed ray queries.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Throughput {
    /// Rays per repetition.
    pub rays: usize,
    /// Wall time per repetition.
    pub seconds: Timing,
}

impl Throughput {
    /// Million rays per second at the median time.
    pub fn mrays_per_second(&self) -> f64 {
        self.rays as f64 / self.seconds.median / 1e6
    }
}

/// Results for one curve type.
#[derive(Debug, Clone, PartialEq)]
pub struct KindReport {
    /// Curve type.
    pub kind: CurveKind,
    /// Geometry creation + BVH build ([`EmbreeTracer::build_seconds`]).
    pub build: Timing,
    /// Bytes Embree holds for the built scene (BVH and curve buffers), from its memory monitor.
    pub embree_bytes: usize,
    /// Primary (closest-hit) rays.
    pub primary: Throughput,
    /// Primary rays that hit a strand (correctness figure).
    pub primary_hits: usize,
    /// Shadow (transmittance) rays, one per primary hit.
    pub shadow: Throughput,
    /// Mean transmittance of the shadow rays (correctness figure).
    pub mean_transmittance: f64,
    /// Shadow rays stopped because the transmittance fell below the cutoff.
    pub shadow_dark: usize,
    /// Shadow rays stopped because they crossed more strands than the filter can remember (biased dark).
    pub shadow_seen_list_full: usize,
}

/// The whole benchmark: configuration, per-curve-type results and memory.
#[derive(Debug, Clone, PartialEq)]
pub struct TraceReport {
    /// Strands in the model.
    pub strands: usize,
    /// Curve segments (Embree primitives).
    pub segments: usize,
    /// Query and build threads used.
    pub threads: usize,
    /// Timed repetitions.
    pub repetitions: usize,
    /// The camera used.
    pub camera: Camera,
    /// Normalised direction towards the light.
    pub to_light: Vec3,
    /// Embree version (major, minor, patch).
    pub embree_version: (u32, u32, u32),
    /// Mean strand opacity traced with.
    pub mean_opacity: f32,
    /// The opacity override, if the configuration set one.
    pub opacity_override: Option<f32>,
    /// One entry per curve type measured.
    pub kinds: Vec<KindReport>,
    /// Peak resident memory of the process (`VmHWM`), bytes, if the platform reports it.
    pub peak_rss_bytes: Option<u64>,
}

impl fmt::Display for TraceReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (major, minor, patch) = self.embree_version;
        let c = &self.camera;
        writeln!(
            f,
            "trace benchmark: {} strands, {} segments; embree {major}.{minor}.{patch}; {} threads; debug assertions {}",
            self.strands,
            self.segments,
            self.threads,
            if cfg!(debug_assertions) { "on" } else { "off" },
        )?;
        writeln!(
            f,
            "camera at ({:.3}, {:.3}, {:.3}) looking along ({:.3}, {:.3}, {:.3}), {}x{} rays; light direction ({:.3}, {:.3}, {:.3}); \
             strand opacity {}; median (min-max) of {} runs after 1 warm-up",
            c.position.x,
            c.position.y,
            c.position.z,
            c.forward.x,
            c.forward.y,
            c.forward.z,
            c.resolution().0,
            c.resolution().1,
            self.to_light.x,
            self.to_light.y,
            self.to_light.z,
            match self.opacity_override {
                Some(a) => format!("{a} (override)"),
                None => format!("{:.3} (model mean)", self.mean_opacity),
            },
            self.repetitions
        )?;
        writeln!(
            f,
            "{:<6} {:>22} {:>9} {:>22} {:>9} {:>22} {:>9} {:>7} {:>12}",
            "curve",
            "build s",
            "embree MB",
            "primary Mrays/s",
            "hits",
            "shadow Mrays/s",
            "rays",
            "mean T",
            "dark/full"
        )?;
        for k in &self.kinds {
            let rate = |t: &Throughput| {
                let r = |s: f64| t.rays as f64 / s / 1e6;
                format!(
                    "{:.3} ({:.3}-{:.3})",
                    r(t.seconds.median),
                    r(t.seconds.max),
                    r(t.seconds.min)
                )
            };
            writeln!(
                f,
                "{:<6} {:>22} {:>9.1} {:>22} {:>9} {:>22} {:>9} {:>7.4} {:>12}",
                format!("{:?}", k.kind).to_lowercase(),
                format!(
                    "{:.3} ({:.3}-{:.3})",
                    k.build.median, k.build.min, k.build.max
                ),
                k.embree_bytes as f64 / 1e6,
                rate(&k.primary),
                format!("{}/{}", k.primary_hits, k.primary.rays),
                rate(&k.shadow),
                k.shadow.rays,
                k.mean_transmittance,
                format!("{}/{}", k.shadow_dark, k.shadow_seen_list_full),
            )?;
        }
        // One line per measurement for scripts: `<ray kind> <curves> <backend> <value> <unit>`.
        for k in &self.kinds {
            let kind = format!("{:?}", k.kind).to_lowercase();
            writeln!(f, "build {kind} embree {:.4} s", k.build.median)?;
            for (what, t) in [("camera", &k.primary), ("shadow-exact", &k.shadow)] {
                writeln!(
                    f,
                    "{what} {kind} embree {:.4} Mrays/s",
                    t.mrays_per_second()
                )?;
            }
        }
        match self.peak_rss_bytes {
            Some(b) => write!(f, "peak memory (VmHWM): {:.1} MB", b as f64 / 1e6),
            None => write!(f, "peak memory: not reported by this platform"),
        }
    }
}

/// Sums over shadow-ray results.
#[derive(Debug, Clone, Copy, Default)]
struct ShadowTally {
    transmittance: f64,
    dark: usize,
    seen_list_full: usize,
}

impl ShadowTally {
    fn add(mut self, other: Self) -> Self {
        self.transmittance += other.transmittance;
        self.dark += other.dark;
        self.seen_list_full += other.seen_list_full;
        self
    }
}

/// Runs the trace benchmark on the hair of `scene`, seen by its camera at `resolution`, with shadow rays towards its
/// first distant light (if it has one) through strands of the scene's opacity.
pub fn trace_scene(
    scene: &Scene,
    threads: usize,
    resolution: [u32; 2],
) -> Result<TraceReport, TraceSceneError> {
    let strands = scene.hair_spec().load()?;
    let [w, h] = resolution;
    let camera = Camera::from_config(&scene.camera, strands.bounds(), w, h);
    let mut config = TraceConfig::new(camera, threads);
    if let Some(LightConfig::Distant { direction, .. }) = scene.lights.first() {
        config.to_light = -Vec3::from(*direction);
    }
    config.opacity = scene.hair.opacity;
    Ok(trace(&strands, &config)?)
}

/// Why [`trace_scene`] could not run.
#[derive(Debug, thiserror::Error)]
pub enum TraceSceneError {
    /// The hair could not be loaded.
    #[error(transparent)]
    Hair(#[from] crate::hair::HairError),
    /// Embree or the thread pool failed.
    #[error(transparent)]
    Bench(#[from] BenchError),
}

/// Runs the trace benchmark on `strands` (see the module docs for the method).
pub fn trace(strands: &Strands, config: &TraceConfig) -> Result<TraceReport, BenchError> {
    let overridden;
    let strands = match config.opacity {
        Some(opacity) => {
            let mut copy = strands.clone();
            copy.set_opacity(opacity);
            overridden = copy;
            &overridden
        }
        None => strands,
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(config.threads)
        .build()
        .map_err(|source| BenchError::ThreadPool {
            threads: config.threads,
            source,
        })?;
    let threads = pool.current_num_threads();
    let camera = config.camera;
    let to_light = config.to_light.normalize_or(Vec3::Y);
    let repetitions = config.repetitions.max(1);
    let primary_rays = camera.pixel_centre_rays();
    let mut embree_version = (0, 0, 0);
    let mut kinds = Vec::new();
    for &kind in &config.kinds {
        // One device per curve type, so its memory monitor counts this scene alone.
        let device = Device::with_config(&format!("threads={threads}"))?;
        embree_version = device.version();
        let mut build_seconds = Vec::new();
        let mut tracer = EmbreeTracer::with_device(&device, strands, kind)?;
        for _ in 0..repetitions {
            drop(tracer);
            tracer = EmbreeTracer::with_device(&device, strands, kind)?;
            build_seconds.push(tracer.build_seconds());
        }
        let embree_bytes = device.memory_bytes();

        // Warm-up run, which also finds the hits the shadow rays start from.
        let hits: Vec<(Ray, Hit)> = pool.install(|| {
            primary_rays
                .par_iter()
                .filter_map(|ray| {
                    let hit = tracer.intersect(ray).expect("camera rays are valid")?;
                    Some((*ray, hit))
                })
                .collect()
        });
        let primary = time(&pool, repetitions, || {
            primary_rays
                .par_iter()
                .with_min_len(256)
                .filter(|ray| {
                    tracer
                        .intersect(ray)
                        .expect("camera rays are valid")
                        .is_some()
                })
                .count()
        });
        let shadow_rays: Vec<(Ray, u32)> = hits
            .iter()
            .map(|(ray, hit)| (Ray::new(ray.at(hit.t), to_light), hit.strand))
            .collect();
        let trace_shadows = || {
            shadow_rays
                .par_iter()
                .with_min_len(256)
                .map(|(ray, strand)| {
                    let t = tracer
                        .transmittance_detail(ray, Some(*strand))
                        .expect("shadow rays start at finite hit points");
                    ShadowTally {
                        transmittance: f64::from(t.value),
                        dark: usize::from(t.cutoff == Some(Cutoff::Dark)),
                        seen_list_full: usize::from(t.cutoff == Some(Cutoff::SeenListFull)),
                    }
                })
                .reduce(ShadowTally::default, ShadowTally::add)
        };
        let tally = pool.install(trace_shadows);
        let shadow = time(&pool, repetitions, trace_shadows);
        kinds.push(KindReport {
            kind,
            build: Timing::from_samples(build_seconds),
            embree_bytes,
            primary: Throughput {
                rays: primary_rays.len(),
                seconds: primary,
            },
            primary_hits: hits.len(),
            shadow: Throughput {
                rays: shadow_rays.len(),
                seconds: shadow,
            },
            mean_transmittance: tally.transmittance / shadow_rays.len().max(1) as f64,
            shadow_dark: tally.dark,
            shadow_seen_list_full: tally.seen_list_full,
        });
    }
    Ok(TraceReport {
        strands: strands.strand_count(),
        segments: strands.segment_count(),
        threads,
        repetitions,
        camera,
        to_light,
        embree_version,
        mean_opacity: strands.opacity.iter().sum::<f32>() / strands.opacity.len().max(1) as f32,
        opacity_override: config.opacity,
        kinds,
        peak_rss_bytes: peak_rss_bytes(),
    })
}

/// Times `repetitions` runs of `work` inside `pool`.
fn time<R: Send>(
    pool: &rayon::ThreadPool,
    repetitions: usize,
    work: impl Fn() -> R + Sync + Send,
) -> Timing {
    let seconds = (0..repetitions)
        .map(|_| {
            let start = Instant::now();
            std::hint::black_box(pool.install(&work));
            start.elapsed().as_secs_f64()
        })
        .collect();
    Timing::from_samples(seconds)
}
