//! Whole-frame benchmark (`cuticle bench frame SCENE`): the time a user waits for a render, and what it traced.
//!
//! Method: the scene's hair is loaded and its BVH built once (both timed, reported separately); then the frame is
//! rendered `repetitions` times after one untimed warm-up, on a local rayon pool of `threads` threads, and the
//! median wall time of the pixel loop is reported with the rays traced per second (camera, shadow and material
//! rays) and the process's peak memory. No image is written. The reference configuration is
//! `scenes/furball.toml` (furball-512) at 2 threads.

use std::fmt;
use std::time::Instant;

use crate::measure::{peak_rss_bytes, Timing};
use crate::render::integrator::RayCounts;
use crate::render::{thread_pool, Frame, FrameError, Request, ThreadPoolError};
use crate::scene::Scene;

/// The result of [`frame`].
#[derive(Debug, Clone)]
pub struct FrameReport {
    /// Scene source, for the header.
    pub scene: String,
    /// Strands rendered.
    pub strands: usize,
    /// Resolution.
    pub resolution: [u32; 2],
    /// Camera samples per pixel.
    pub spp: u32,
    /// Indirect bounces.
    pub path_length: u32,
    /// Material model name.
    pub material: &'static str,
    /// Threads used.
    pub threads: usize,
    /// The strand tracer.
    pub backend: crate::accel::Backend,
    /// Hair load (file or procedural) and conversion to strands, seconds.
    pub load_seconds: f64,
    /// Embree geometry + BVH build, seconds.
    pub build_seconds: f64,
    /// Pixel loop wall time over the repetitions.
    pub render: Timing,
    /// Rays of one render.
    pub rays: RayCounts,
    /// Timed repetitions.
    pub repetitions: usize,
    /// Peak resident memory, bytes.
    pub peak_rss_bytes: Option<u64>,
}

impl fmt::Display for FrameReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [w, h] = self.resolution;
        writeln!(
            f,
            "frame benchmark: {} ({} strands, {w}x{h}, {} spp, path length {}, {}); {} backend; {} threads; median (min-max) of {} runs after 1 warm-up",
            self.scene, self.strands, self.spp, self.path_length, self.material, self.backend.name(), self.threads, self.repetitions
        )?;
        writeln!(
            f,
            "load {:.3} s, build {:.3} s, render {:.3} s ({:.3}-{:.3})",
            self.load_seconds,
            self.build_seconds,
            self.render.median,
            self.render.min,
            self.render.max
        )?;
        let r = &self.rays;
        writeln!(
            f,
            "rays per frame: {} camera, {} shadow, {} material = {} ({:.3} Mrays/s)",
            r.camera,
            r.shadow,
            r.material,
            r.total(),
            r.total() as f64 / self.render.median / 1e6
        )?;
        match self.peak_rss_bytes {
            Some(b) => write!(f, "peak memory (VmHWM): {:.1} MB", b as f64 / 1e6),
            None => write!(f, "peak memory: not reported by this platform"),
        }
    }
}

/// Why a whole-frame benchmark could not run.
#[derive(Debug, thiserror::Error)]
pub enum FrameBenchError {
    /// The scene is invalid or its lights could not be built (e.g. a missing environment map).
    #[error(transparent)]
    Scene(#[from] crate::scene::SceneError),
    /// The hair could not be loaded or Embree refused it.
    #[error(transparent)]
    Frame(#[from] FrameError),
    /// The worker threads could not be started.
    #[error(transparent)]
    ThreadPool(#[from] ThreadPoolError),
    /// Embree could not build a benchmark's own tracer.
    #[error(transparent)]
    Embree(#[from] crate::accel::embree::EmbreeError),
}

/// Renders `scene` as described in the module docs.
pub fn frame(
    scene: &Scene,
    threads: usize,
    repetitions: usize,
) -> Result<FrameReport, FrameBenchError> {
    let pool = thread_pool(Some(threads))?;
    let frame = Frame::load(scene.resolve()?)?;
    let run = || pool.install(|| frame.render(Request::new(&frame.settings)));
    let warm = run().stats;
    let seconds: Vec<f64> = (0..repetitions.max(1))
        .map(|_| {
            let t = Instant::now();
            run();
            t.elapsed().as_secs_f64()
        })
        .collect();
    Ok(FrameReport {
        scene: scene.source.display().to_string(),
        strands: frame.strands.strand_count(),
        resolution: scene.film.resolution,
        spp: scene.film.spp,
        path_length: scene.integrator.path_length,
        material: frame.material.name,
        threads: pool.current_num_threads(),
        backend: frame.backend,
        load_seconds: frame.load_seconds,
        build_seconds: frame.build_seconds(),
        render: Timing::from_samples(seconds),
        rays: warm.rays,
        repetitions: repetitions.max(1),
        peak_rss_bytes: peak_rss_bytes(),
    })
}
