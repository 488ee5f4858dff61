//! Trace throughput benchmark (`cuticle bench trace SCENE`): Embree against the pure-Rust BVH on identical rays, per
//! ray type, curve type and thread count — build time, memory per segment and Mrays/s.
//!
//! **The rays** are made once per curve type, by the first backend measured, and then replayed unchanged through
//! every backend, so both trace exactly the same work:
//! - `camera`: one closest-hit ray through each pixel centre of the scene's camera (coherent).
//! - `secondary`: incoherent rays that start on strands *inside* the fur, as a path's bounces do: from each camera
//!   hit a ray in a uniformly random direction finds a second hit (ignoring its own strand); from that second hit a
//!   new uniformly random direction is the benchmark ray. Traced as the renderer traces bounce rays:
//!   [`Tracer::intersect_stochastic`] ignoring the strand it starts on, strands present with their opacity; when
//!   every strand is opaque, starting past the strand's local tube instead
//!   ([`crate::hair::strands::tube_exit`]), as the renderer does.
//! - `shadow-exact`: from every camera hit and every inner (second) hit towards the distant light,
//!   [`Tracer::transmittance`] ignoring the strand the ray starts on (exact product over the strands crossed), or
//!   starting past its tube as the secondary rays do.
//! - `shadow-stochastic`: the same rays through [`Tracer::occluded_stochastic`] (any-hit with the stochastic
//!   presence test), the renderer's default shadow query.
//!
//! Directions come from a hash of the ray's index, so the rays do not depend on threads. **Timing**: each
//! measurement is repeated (3 times by default) after one untimed warm-up run and reported as median (min–max);
//! the backends take turns within each repetition (builds and ray types alike), so that the VM's slow spells fall
//! on both and the ratios between them hold.
//! Builds are timed by the tracers themselves ([`Tracer::build_seconds`]), on a rayon pool of the thread count
//! (the BVH) or an Embree device configured with it. Ray generation and scene loading are not timed. Every
//! throughput is printed beside a correctness figure (hits, mean transmittance, unoccluded fraction) that must
//! agree between backends: runs doing different work are not compared.
//!
//! **Memory** is [`Tracer::memory_bytes`]: Embree's memory monitor (its BVH and the curve buffers it copies) plus
//! the strand table, against the Rust BVH's nodes and indices plus its copy of the strands.

use std::fmt;
use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use super::BenchError;
use crate::accel::bvh_tracer::BvhTracer;
use crate::accel::embree::{Device, EmbreeTracer};
use crate::accel::{Backend, CurveKind, Tracer};
use crate::hair::Strands;
use crate::measure::{peak_rss_bytes, Timing};
use crate::ray::Ray;
use crate::render::camera::Camera;
use crate::scene::{LightConfig, Scene};
use crate::util::hash::{hash64, mix64, unit_f32};
use crate::util::sampling::uniform_sphere;

/// What to measure.
#[derive(Debug, Clone, PartialEq)]
pub struct TraceConfig {
    /// Thread counts to measure at (each ≥ 1), for queries (rayon) and builds.
    pub threads: Vec<usize>,
    /// Backends to measure; the first one makes the rays.
    pub backends: Vec<Backend>,
    /// The camera: one primary ray through each pixel centre of its image.
    pub camera: Camera,
    /// Direction from a hit point towards the distant light (normalised on use).
    pub to_light: Vec3,
    /// Timed repetitions (after one warm-up run); the median is reported.
    pub repetitions: usize,
    /// Curve types to measure.
    pub kinds: Vec<CurveKind>,
    /// Replaces every strand's opacity (as a scene may); `None` keeps the model's. Opacity sets how far shadow
    /// and secondary rays travel, so their throughput depends on it.
    pub opacity: Option<f32>,
}

impl TraceConfig {
    /// Rays from `camera` on `threads` threads through both backends, light towards (1, 1, −1), 3 repetitions,
    /// round and flat curves.
    pub fn new(camera: Camera, threads: usize) -> Self {
        TraceConfig {
            threads: vec![threads],
            backends: vec![Backend::Embree, Backend::Bvh],
            camera,
            to_light: Vec3::new(1.0, 1.0, -1.0),
            repetitions: 3,
            kinds: vec![CurveKind::Round, CurveKind::Flat],
            opacity: None,
        }
    }
}

/// The ray types measured (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RayType {
    /// Coherent closest-hit rays through the pixel centres.
    Camera,
    /// Incoherent closest-hit rays starting on strands inside the fur.
    Secondary,
    /// Exact transmittance towards the light.
    ShadowExact,
    /// Stochastic any-hit towards the light.
    ShadowStochastic,
}

impl RayType {
    /// Every ray type, in report order.
    pub const ALL: [RayType; 4] = [
        RayType::Camera,
        RayType::Secondary,
        RayType::ShadowExact,
        RayType::ShadowStochastic,
    ];

    /// The name in reports and script lines.
    pub fn name(self) -> &'static str {
        match self {
            RayType::Camera => "camera",
            RayType::Secondary => "secondary",
            RayType::ShadowExact => "shadow-exact",
            RayType::ShadowStochastic => "shadow-stochastic",
        }
    }

    /// What [`RayReport::figure`] is for this type.
    fn figure_name(self) -> &'static str {
        match self {
            RayType::Camera | RayType::Secondary => "hit fraction",
            RayType::ShadowExact => "mean transmittance",
            RayType::ShadowStochastic => "unoccluded fraction",
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

/// One ray type through one tracer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayReport {
    /// The ray type.
    pub ray: RayType,
    /// Its throughput.
    pub throughput: Throughput,
    /// Correctness figure: hit fraction (camera, secondary), mean transmittance (shadow-exact) or unoccluded
    /// fraction (shadow-stochastic). Equal work gives equal figures on every backend.
    pub figure: f64,
}

/// One (curve type, backend, thread count).
#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    /// Curve type.
    pub kind: CurveKind,
    /// Backend.
    pub backend: Backend,
    /// Threads for the build and the queries.
    pub threads: usize,
    /// Build time ([`Tracer::build_seconds`]).
    pub build: Timing,
    /// Memory the tracer holds ([`Tracer::memory_bytes`]).
    pub memory_bytes: usize,
    /// One entry per [`RayType::ALL`].
    pub rays: Vec<RayReport>,
}

/// The whole benchmark: configuration and one [`Measurement`] per (curve type, backend, thread count).
#[derive(Debug, Clone, PartialEq)]
pub struct TraceReport {
    /// Strands in the model.
    pub strands: usize,
    /// Curve segments.
    pub segments: usize,
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
    /// Every measurement, grouped by curve type, then thread count, then backend.
    pub measurements: Vec<Measurement>,
    /// Peak resident memory of the process (`VmHWM`), bytes, if the platform reports it.
    pub peak_rss_bytes: Option<u64>,
}

impl TraceReport {
    /// The measurement of (`kind`, `backend`, `threads`), if it was made.
    pub fn get(&self, kind: CurveKind, backend: Backend, threads: usize) -> Option<&Measurement> {
        self.measurements
            .iter()
            .find(|m| m.kind == kind && m.backend == backend && m.threads == threads)
    }
}

impl fmt::Display for TraceReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // One piece: the report's sections in the order they print, sharing the measurements' formatting.
        let (major, minor, patch) = self.embree_version;
        let c = &self.camera;
        writeln!(
            f,
            "trace benchmark: {} strands, {} segments; embree {major}.{minor}.{patch}; debug assertions {}",
            self.strands,
            self.segments,
            if cfg!(debug_assertions) { "on" } else { "off" },
        )?;
        writeln!(
            f,
            "camera at ({:.3}, {:.3}, {:.3}) looking along ({:.3}, {:.3}, {:.3}), {}x{} rays; light direction \
             ({:.3}, {:.3}, {:.3}); strand opacity {}; median (min-max) of {} runs after 1 warm-up",
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
        write!(
            f,
            "{:<6} {:<7} {:>3} {:>20} {:>8}",
            "curve", "backend", "thr", "build s", "B/seg"
        )?;
        for ray in RayType::ALL {
            write!(f, " {:>24}", format!("{} Mrays/s", ray.name()))?;
        }
        writeln!(f)?;
        let per_segment = |m: &Measurement| m.memory_bytes as f64 / self.segments.max(1) as f64;
        for m in &self.measurements {
            write!(
                f,
                "{:<6} {:<7} {:>3} {:>20} {:>8.1}",
                m.kind.name(),
                m.backend.name(),
                m.threads,
                format!(
                    "{:.3} ({:.3}-{:.3})",
                    m.build.median, m.build.min, m.build.max
                ),
                per_segment(m),
            )?;
            for r in &m.rays {
                let t = &r.throughput;
                let rate = |s: f64| t.rays as f64 / s / 1e6;
                write!(
                    f,
                    " {:>24}",
                    format!(
                        "{:.3} ({:.3}-{:.3})",
                        rate(t.seconds.median),
                        rate(t.seconds.max),
                        rate(t.seconds.min)
                    )
                )?;
            }
            writeln!(f)?;
        }
        // The work each ray type did: identical on every backend up to the rare silhouette disagreement.
        writeln!(
            f,
            "rays and correctness figures (equal work, equal figures):"
        )?;
        for m in &self.measurements {
            write!(
                f,
                "  {} {} {} threads:",
                m.kind.name(),
                m.backend.name(),
                m.threads
            )?;
            for r in &m.rays {
                write!(
                    f,
                    " {} {} rays, {} {:.4};",
                    r.ray.name(),
                    r.throughput.rays,
                    r.ray.figure_name(),
                    r.figure
                )?;
            }
            writeln!(f)?;
        }
        // Time per ray of the BVH relative to Embree's (> 1: the BVH is slower), where both were measured.
        for m in &self.measurements {
            if m.backend != Backend::Bvh {
                continue;
            }
            let Some(e) = self.get(m.kind, Backend::Embree, m.threads) else {
                continue;
            };
            write!(
                f,
                "bvh / embree time, {} {} threads: build {:.2}x, memory {:.2}x",
                m.kind.name(),
                m.threads,
                m.build.median / e.build.median,
                m.memory_bytes as f64 / e.memory_bytes.max(1) as f64
            )?;
            for (b, r) in m.rays.iter().zip(&e.rays) {
                write!(
                    f,
                    ", {} {:.2}x",
                    b.ray.name(),
                    r.throughput.mrays_per_second() / b.throughput.mrays_per_second()
                )?;
            }
            writeln!(f)?;
        }
        // The same figures again, one per line for scripts: `<measure> <curves> <backend> <value> <unit> <threads>`.
        writeln!(
            f,
            "the figures above, one per line for scripts (measure, curves, backend, value, unit, threads):"
        )?;
        for m in &self.measurements {
            let (kind, backend, threads) = (m.kind.name(), m.backend.name(), m.threads);
            writeln!(
                f,
                "build {kind} {backend} {:.4} s {threads}-threads",
                m.build.median
            )?;
            writeln!(
                f,
                "memory {kind} {backend} {:.1} B/segment {threads}-threads",
                per_segment(m)
            )?;
            for r in &m.rays {
                writeln!(
                    f,
                    "{} {kind} {backend} {:.4} Mrays/s {threads}-threads",
                    r.ray.name(),
                    r.throughput.mrays_per_second()
                )?;
            }
        }
        match self.peak_rss_bytes {
            Some(b) => write!(f, "peak memory (VmHWM): {:.1} MB", b as f64 / 1e6),
            None => write!(f, "peak memory: not reported by this platform"),
        }
    }
}

/// The strands of `scene` and a configuration for them: its camera at `resolution`, shadow rays towards its first
/// distant light (if it has one), the scene's opacity; both backends, both curve types, 1 thread (set the fields
/// to measure something else).
pub fn scene_config(
    scene: &Scene,
    resolution: [u32; 2],
) -> Result<(Strands, TraceConfig), crate::hair::HairError> {
    let strands = scene.hair_spec().load()?;
    let [w, h] = resolution;
    let camera = Camera::from_config(&scene.camera, strands.bounds(), w, h);
    let mut config = TraceConfig::new(camera, 1);
    if let Some(LightConfig::Distant { direction, .. }) = scene.lights.first() {
        config.to_light = -Vec3::from(*direction);
    }
    config.opacity = scene.hair.opacity;
    Ok((strands, config))
}

/// The rays every backend traces for one curve type.
struct Rays {
    camera: Vec<Ray>,
    /// (ray, strand it ignores, presence key).
    secondary: Vec<(Ray, Option<u32>, u64)>,
    /// (ray, strand it ignores, presence key).
    shadow: Vec<(Ray, Option<u32>, u64)>,
}

/// Where a hit was: point, strand, segment and curve parameter.
#[derive(Clone, Copy)]
struct Start {
    p: Vec3,
    strand: u32,
    segment: u32,
    u: f32,
}

impl Start {
    fn of(ray: &Ray, hit: &crate::accel::Hit) -> Start {
        Start {
            p: ray.at(hit.t),
            strand: hit.strand,
            segment: hit.segment,
            u: hit.u,
        }
    }

    /// A ray leaving this hit along `dir` as the renderer spawns it: past the strand's local tube in `tube`'s
    /// strands (given when every strand is opaque) where the exit is defined, otherwise ignoring the strand.
    fn spawn(&self, tube: Option<&Strands>, dir: Vec3) -> (Ray, Option<u32>) {
        let exit = tube.and_then(|strands| strands.tube_exit_at(self.segment, self.u, self.p, dir));
        match exit {
            Some(t) => (Ray::segment(self.p, dir, t, f32::INFINITY), None),
            None => (Ray::new(self.p, dir), Some(self.strand)),
        }
    }
}

/// A direction uniform on the sphere for ray `index` of generation `generation`.
fn random_direction(index: usize, generation: u64) -> Vec3 {
    let h = hash64((index as u64) << 2 | generation);
    uniform_sphere(unit_f32(h), unit_f32(mix64(h)))
}

impl Rays {
    /// Camera rays, then the secondary and shadow rays derived from `tracer`'s hits (see the module docs).
    fn new(tracer: &dyn Tracer, strands: &Strands, camera: &Camera, to_light: Vec3) -> Rays {
        let camera = camera.pixel_centre_rays();
        // Checked once here, not per ray (it reads every strand's opacity).
        let tube = strands.all_opaque().then_some(strands);
        let first: Vec<Start> = camera
            .par_iter()
            .filter_map(|ray| {
                let hit = tracer.intersect(ray).expect("camera rays are valid")?;
                Some(Start::of(ray, &hit))
            })
            .collect();
        let inner: Vec<Start> = first
            .par_iter()
            .enumerate()
            .filter_map(|(i, s)| {
                let ray = Ray::new(s.p, random_direction(i, 0));
                let hit = tracer
                    .intersect_stochastic(&ray, Some(s.strand), hash64(i as u64))
                    .expect("rays from finite hit points are valid")?;
                Some(Start::of(&ray, &hit))
            })
            .collect();
        let secondary = inner
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let key = hash64(!(i as u64));
                let (ray, ignore) = s.spawn(tube, random_direction(i, 1));
                (ray, ignore, key)
            })
            .collect();
        let shadow = first
            .iter()
            .chain(&inner)
            .enumerate()
            .map(|(i, s)| {
                let (ray, ignore) = s.spawn(tube, to_light);
                (ray, ignore, hash64(i as u64 ^ 0x5ad0))
            })
            .collect();
        Rays {
            camera,
            secondary,
            shadow,
        }
    }

    /// How many rays of type `ray` there are.
    fn count(&self, ray: RayType) -> usize {
        match ray {
            RayType::Camera => self.camera.len(),
            RayType::Secondary => self.secondary.len(),
            RayType::ShadowExact | RayType::ShadowStochastic => self.shadow.len(),
        }
    }

    /// Traces every ray of type `ray` through `tracer` on the current pool; returns the sum of the correctness
    /// figure over the rays.
    fn trace(&self, tracer: &dyn Tracer, ray: RayType) -> f64 {
        const CHUNK: usize = 256;
        match ray {
            RayType::Camera => self
                .camera
                .par_iter()
                .with_min_len(CHUNK)
                .filter(|r| {
                    tracer
                        .intersect(r)
                        .expect("camera rays are valid")
                        .is_some()
                })
                .count() as f64,
            RayType::Secondary => self
                .secondary
                .par_iter()
                .with_min_len(CHUNK)
                .filter(|(r, strand, key)| {
                    tracer
                        .intersect_stochastic(r, *strand, *key)
                        .expect("secondary rays are valid")
                        .is_some()
                })
                .count() as f64,
            RayType::ShadowExact => self
                .shadow
                .par_iter()
                .with_min_len(CHUNK)
                .map(|(r, strand, _)| {
                    f64::from(
                        tracer
                            .transmittance(r, *strand)
                            .expect("shadow rays are valid"),
                    )
                })
                .sum(),
            RayType::ShadowStochastic => self
                .shadow
                .par_iter()
                .with_min_len(CHUNK)
                .filter(|(r, strand, key)| {
                    !tracer
                        .occluded_stochastic(r, *strand, *key)
                        .expect("shadow rays are valid")
                })
                .count() as f64,
        }
    }
}

/// Builds the tracer of `backend` on `threads` threads.
fn build(
    backend: Backend,
    strands: &Strands,
    kind: CurveKind,
    threads: usize,
    pool: &rayon::ThreadPool,
) -> Result<Box<dyn Tracer + Send>, BenchError> {
    Ok(match backend {
        // A device of its own, so its memory monitor counts this scene alone, with the same build threads.
        Backend::Embree => Box::new(EmbreeTracer::with_device(
            &Device::with_config(&format!("threads={threads}"))?,
            strands,
            kind,
        )?),
        Backend::Bvh => Box::new(pool.install(|| BvhTracer::new(strands, kind))),
    })
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
    let camera = config.camera;
    let to_light = config.to_light.normalize_or(Vec3::Y);
    let repetitions = config.repetitions.max(1);
    let embree_version = Device::new()?.version();
    let mut measurements = Vec::new();
    for &kind in &config.kinds {
        let mut rays = None;
        for &threads in &config.threads {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .map_err(|source| BenchError::ThreadPool { threads, source })?;
            // Every backend's tracer lives through the whole measurement, and each repetition times the backends
            // one after the other: a slow spell of this noisy VM then slows both alike instead of one backend's
            // whole series, so the ratios hold (runs of one backend after the other's give ratios that move by
            // up to 2x between runs).
            let mut tracers = Vec::new();
            let mut build_seconds = vec![Vec::new(); config.backends.len()];
            for _ in 0..repetitions {
                tracers.clear();
                for (b, &backend) in config.backends.iter().enumerate() {
                    let tracer = build(backend, strands, kind, threads, &pool)?;
                    build_seconds[b].push(tracer.build_seconds());
                    tracers.push(tracer);
                }
            }
            let rays = rays.get_or_insert_with(|| {
                pool.install(|| Rays::new(&*tracers[0], strands, &camera, to_light))
            });
            let mut reports: Vec<Vec<RayReport>> = vec![Vec::new(); tracers.len()];
            for &ray in &RayType::ALL {
                let count = rays.count(ray);
                // The warm-up run gives the correctness figure.
                let figures: Vec<f64> = tracers
                    .iter()
                    .map(|t| pool.install(|| rays.trace(&**t, ray)))
                    .collect();
                let mut seconds = vec![Vec::new(); tracers.len()];
                for _ in 0..repetitions {
                    for (b, tracer) in tracers.iter().enumerate() {
                        let start = Instant::now();
                        std::hint::black_box(pool.install(|| rays.trace(&**tracer, ray)));
                        seconds[b].push(start.elapsed().as_secs_f64());
                    }
                }
                for (b, samples) in seconds.into_iter().enumerate() {
                    reports[b].push(RayReport {
                        ray,
                        throughput: Throughput {
                            rays: count,
                            seconds: Timing::from_samples(samples),
                        },
                        figure: figures[b] / count.max(1) as f64,
                    });
                }
            }
            for (b, ray_reports) in reports.into_iter().enumerate() {
                measurements.push(Measurement {
                    kind,
                    backend: config.backends[b],
                    threads,
                    build: Timing::from_samples(std::mem::take(&mut build_seconds[b])),
                    memory_bytes: tracers[b].memory_bytes(),
                    rays: ray_reports,
                });
            }
        }
    }
    Ok(TraceReport {
        strands: strands.strand_count(),
        segments: strands.segment_count(),
        repetitions,
        camera,
        to_light,
        embree_version,
        mean_opacity: strands.opacity.iter().sum::<f32>() / strands.opacity.len().max(1) as f32,
        opacity_override: config.opacity,
        measurements,
        peak_rss_bytes: peak_rss_bytes(),
    })
}
