//! Frame replay (`cuticle bench replay SCENE`): how close the renderer comes to what its tracer
//! alone can trace on the same rays.
//!
//! Method: the frame is loaded and rendered once untimed (warm-up). One more render runs with the tracer wrapped in a
//! recorder that keeps every query the integrator makes (which query, origin, direction, tnear, tfar, ignored strand,
//! key) in memory, in the order the threads issued them (about 48 bytes a ray: 190 MB for the 256² peer frame, 750 MB
//! at 512²). The recorded rays are traced once untimed through the bare tracer with the same queries, in chunks of
//! [`CHUNK`] consecutive rays on the same pool; then `repetitions` times a timed render and a timed replay take turns
//! (the VM's load changes within a minute), medians reported. Renderer rays/s = recorded queries / median render
//! time; tracer rays/s = the same count / median replay time; their ratio is target 3's figure (≥ 0.8 wanted).

use std::fmt;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use rayon::prelude::*;

use crate::accel::{Hit, Tracer};
use crate::measure::Timing;
use crate::ray::{InvalidRay, Ray};
use crate::render::{thread_pool, Frame, Request};
use crate::scene::Scene;

use super::frame::FrameBenchError;

/// Consecutive recorded rays traced by one rayon task in the replay: large enough that scheduling costs nothing,
/// small enough that both threads stay busy to the end.
const CHUNK: usize = 4096;

/// The tracer query a recorded ray was traced with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Query {
    /// [`Tracer::intersect`] (camera rays).
    Intersect,
    /// [`Tracer::intersect_stochastic`] (material samples and path continuations).
    IntersectStochastic,
    /// [`Tracer::occluded_stochastic`] (light samples, stochastic transmittance).
    OccludedStochastic,
    /// [`Tracer::transmittance`] (light samples, exact transmittance).
    Transmittance,
    /// [`Tracer::strands_crossed`] (light samples under dual scattering; the limit is recorded as the key).
    StrandsCrossed,
}

/// One tracer query of a frame.
#[derive(Debug, Clone, Copy)]
pub struct TracedRay {
    /// The ray: origin, direction, tnear, tfar.
    pub ray: Ray,
    /// The strand the query ignores.
    pub ignore_strand: Option<u32>,
    /// The ray's key for the stochastic presence test (0 for the other queries).
    pub key: u64,
    /// Which query.
    pub query: Query,
    /// The rayon worker that issued it (0 outside a pool), so that each thread's queries can be taken in the
    /// order that thread issued them.
    pub thread: u16,
}

impl TracedRay {
    /// Traces the ray again through `tracer` with its own query; whether it hit (or was occluded), so the work
    /// cannot be optimised away and the replay can be checked against the frame.
    #[inline]
    pub fn trace(&self, tracer: &dyn Tracer) -> bool {
        let (ray, ignore, key) = (&self.ray, self.ignore_strand, self.key);
        match self.query {
            Query::Intersect => matches!(tracer.intersect(ray), Ok(Some(_))),
            Query::IntersectStochastic => {
                matches!(tracer.intersect_stochastic(ray, ignore, key), Ok(Some(_)))
            }
            Query::OccludedStochastic => {
                matches!(tracer.occluded_stochastic(ray, ignore, key), Ok(true))
            }
            Query::Transmittance => matches!(tracer.transmittance(ray, ignore), Ok(t) if t < 1.0),
            Query::StrandsCrossed => {
                matches!(tracer.strands_crossed(ray, ignore, key as u32), Ok(n) if n > 0)
            }
        }
    }
}

/// A tracer that forwards every query to `inner` and, while its log is recording, records it.
struct Recorder {
    inner: Arc<dyn Tracer + Send>,
    log: Arc<Log>,
}

/// The rays a [`Recorder`] has recorded, and whether it still records. Once recording stops the recorder only
/// forwards: one relaxed load of a flag no thread writes, a few ns against the µs a hair ray takes.
struct Log {
    recording: AtomicBool,
    rays: Mutex<Vec<TracedRay>>,
}

impl Recorder {
    fn record(&self, ray: &Ray, ignore_strand: Option<u32>, key: u64, query: Query) {
        if !self.log.recording.load(Ordering::Relaxed) {
            return;
        }
        let thread = rayon::current_thread_index().map_or(0, |i| i as u16);
        let traced = TracedRay {
            ray: *ray,
            ignore_strand,
            key,
            query,
            thread,
        };
        self.log
            .rays
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .push(traced);
    }
}

impl Tracer for Recorder {
    fn build_seconds(&self) -> f64 {
        self.inner.build_seconds()
    }

    fn memory_bytes(&self) -> usize {
        self.inner.memory_bytes()
    }

    fn intersect(&self, ray: &Ray) -> Result<Option<Hit>, InvalidRay> {
        self.record(ray, None, 0, Query::Intersect);
        self.inner.intersect(ray)
    }

    fn transmittance(&self, ray: &Ray, ignore_strand: Option<u32>) -> Result<f32, InvalidRay> {
        self.record(ray, ignore_strand, 0, Query::Transmittance);
        self.inner.transmittance(ray, ignore_strand)
    }

    fn strands_crossed(
        &self,
        ray: &Ray,
        ignore_strand: Option<u32>,
        limit: u32,
    ) -> Result<u32, InvalidRay> {
        self.record(ray, ignore_strand, limit as u64, Query::StrandsCrossed);
        self.inner.strands_crossed(ray, ignore_strand, limit)
    }

    fn intersect_stochastic(
        &self,
        ray: &Ray,
        ignore_strand: Option<u32>,
        key: u64,
    ) -> Result<Option<Hit>, InvalidRay> {
        self.record(ray, ignore_strand, key, Query::IntersectStochastic);
        self.inner.intersect_stochastic(ray, ignore_strand, key)
    }

    fn occluded_stochastic(
        &self,
        ray: &Ray,
        ignore_strand: Option<u32>,
        key: u64,
    ) -> Result<bool, InvalidRay> {
        self.record(ray, ignore_strand, key, Query::OccludedStochastic);
        self.inner.occluded_stochastic(ray, ignore_strand, key)
    }
}

/// Stands in for the frame's tracer while the recorder is being put in place; never traces.
struct Unset;

impl Tracer for Unset {
    fn build_seconds(&self) -> f64 {
        0.0
    }
    fn memory_bytes(&self) -> usize {
        0
    }
    fn intersect(&self, _: &Ray) -> Result<Option<Hit>, InvalidRay> {
        unreachable!("the replay's placeholder tracer is never traced")
    }
    fn transmittance(&self, _: &Ray, _: Option<u32>) -> Result<f32, InvalidRay> {
        unreachable!("the replay's placeholder tracer is never traced")
    }
    fn strands_crossed(&self, _: &Ray, _: Option<u32>, _: u32) -> Result<u32, InvalidRay> {
        unreachable!("the replay's placeholder tracer is never traced")
    }
    fn intersect_stochastic(
        &self,
        _: &Ray,
        _: Option<u32>,
        _: u64,
    ) -> Result<Option<Hit>, InvalidRay> {
        unreachable!("the replay's placeholder tracer is never traced")
    }
    fn occluded_stochastic(&self, _: &Ray, _: Option<u32>, _: u64) -> Result<bool, InvalidRay> {
        unreachable!("the replay's placeholder tracer is never traced")
    }
}

/// Renders `frame` once with every tracer query recorded. Returns the bare tracer and the rays in the order they
/// were issued; the frame then traces through the same tracer again, through the recorder, no longer recording.
pub fn record(frame: &mut Frame) -> (Arc<dyn Tracer + Send>, Vec<TracedRay>) {
    let inner: Arc<dyn Tracer + Send> =
        Arc::from(std::mem::replace(&mut frame.tracer, Box::new(Unset)));
    let log = Arc::new(Log {
        recording: AtomicBool::new(true),
        rays: Mutex::new(Vec::new()),
    });
    frame.tracer = Box::new(Recorder {
        inner: Arc::clone(&inner),
        log: Arc::clone(&log),
    });
    frame.render(Request::new(&frame.settings));
    log.recording.store(false, Ordering::Relaxed);
    let rays = std::mem::take(
        &mut *log
            .rays
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner),
    );
    (inner, rays)
}

/// The result of [`replay`].
#[derive(Debug, Clone)]
pub struct ReplayReport {
    /// Scene source.
    pub scene: String,
    /// Resolution and samples per pixel.
    pub resolution: [u32; 2],
    /// Camera samples per pixel.
    pub spp: u32,
    /// Threads used.
    pub threads: usize,
    /// The strand tracer.
    pub backend: crate::accel::Backend,
    /// Tracer queries of one frame, by query: intersect, intersect stochastic, occluded stochastic,
    /// transmittance.
    pub queries: [u64; 4],
    /// Queries that hit (or were occluded) in the recorded render's replay.
    pub hits: u64,
    /// Pixel loop wall time of the frame.
    pub render: Timing,
    /// Wall time of tracing the recorded rays alone.
    pub replay: Timing,
}

impl ReplayReport {
    /// All recorded queries.
    pub fn rays(&self) -> u64 {
        self.queries.iter().sum()
    }
}

impl fmt::Display for ReplayReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [w, h] = self.resolution;
        let n = self.rays() as f64;
        let [i, is, os, t] = self.queries;
        writeln!(
            f,
            "frame replay: {} ({w}x{h}, {} spp); {} backend; {} threads; median (min-max) after 1 warm-up",
            self.scene, self.spp, self.backend.name(), self.threads
        )?;
        writeln!(
            f,
            "queries per frame: {i} intersect, {is} intersect-stochastic, {os} occluded-stochastic, {t} transmittance = {} ({} hit)",
            self.rays(),
            self.hits
        )?;
        writeln!(
            f,
            "render {:.3} s ({:.3}-{:.3}), tracer alone {:.3} s ({:.3}-{:.3})",
            self.render.median,
            self.render.min,
            self.render.max,
            self.replay.median,
            self.replay.min,
            self.replay.max
        )?;
        let (renderer, tracer) = (n / self.render.median, n / self.replay.median);
        writeln!(f, "replay renderer_rays_per_s {renderer:.0}")?;
        writeln!(f, "replay tracer_rays_per_s {tracer:.0}")?;
        write!(f, "replay ratio {:.3}", renderer / tracer)
    }
}

/// Renders `scene` and replays its rays as described in the module docs.
pub fn replay(
    scene: &Scene,
    threads: usize,
    repetitions: usize,
) -> Result<ReplayReport, FrameBenchError> {
    let pool = thread_pool(Some(threads))?;
    let mut frame = Frame::load(scene.resolve()?)?;
    let repetitions = repetitions.max(1);
    // Warm-up render, then the recording render, then render and replay take turns, so that the VM's slow
    // spells fall on both.
    pool.install(|| frame.render(Request::new(&frame.settings)));
    let (tracer, rays) = pool.install(|| record(&mut frame));
    let bare: &dyn Tracer = tracer.as_ref();
    let trace_all = || -> u64 {
        pool.install(|| {
            rays.par_chunks(CHUNK)
                .map(|chunk| chunk.iter().filter(|r| r.trace(bare)).count() as u64)
                .sum()
        })
    };
    let hits = trace_all();
    let (mut render, mut replay) = (Vec::new(), Vec::new());
    for _ in 0..repetitions {
        let t = Instant::now();
        pool.install(|| frame.render(Request::new(&frame.settings)));
        render.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        std::hint::black_box(trace_all());
        replay.push(t.elapsed().as_secs_f64());
    }
    let (render, replay) = (Timing::from_samples(render), Timing::from_samples(replay));
    let mut queries = [0u64; 4];
    for r in &rays {
        queries[r.query as usize] += 1;
    }
    Ok(ReplayReport {
        scene: scene.source.display().to_string(),
        resolution: scene.film.resolution,
        spp: scene.film.spp,
        threads: pool.current_num_threads(),
        backend: frame.backend,
        queries,
        hits,
        render,
        replay,
    })
}
