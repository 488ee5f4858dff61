//! One frame set up for rendering, the same way for every caller (the `render` command, every benchmark, every
//! study, the tests): the hair loaded and converted to strands, its acceleration structure built, the material,
//! lights and shapes built — each exactly once — and the [`RenderSettings`] a render runs with.
//!
//! A [`FrameSpec`] says what to build (a scene resolves into one: [`crate::scene::Scene::resolve`]);
//! [`Frame::load`] builds it. One frame can then be rendered under several settings (a benchmark's repetitions, a
//! study's variants) without reloading anything.

use glam::Vec3;
use std::sync::Arc;
use std::time::Instant;

use crate::accel::bvh_tracer::BvhTracer;
use crate::accel::embree::EmbreeError;
use crate::accel::embree::EmbreeTracer;
use crate::accel::{Backend, CurveKind, Tracer};
use crate::bsdf::Material;
use crate::hair::{HairError, HairSpec, Strands};
use crate::light::Light;
use crate::shadow::ShadowMaps;
use crate::shape::Shapes;

use super::settings::{RenderSettings, ShadowMode};
use super::{Region, RegionRender, Request};

/// What a frame is made of, before anything heavy is built.
#[derive(Debug)]
pub struct FrameSpec {
    /// The hair model and its adjustments.
    pub hair: HairSpec,
    /// Round tubes or flat ribbons.
    pub curves: CurveKind,
    /// Embree or the pure-Rust BVH.
    pub backend: Backend,
    /// The fibre material.
    pub material: Material,
    /// Every light, environment last.
    pub lights: Vec<Light>,
    /// Non-hair geometry.
    pub shapes: Shapes,
    /// The settings [`Frame::render`] uses.
    pub settings: RenderSettings,
}

/// Why a frame could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    /// The hair model could not be read or generated.
    #[error(transparent)]
    Hair(#[from] HairError),
    /// Embree refused the strands.
    #[error(transparent)]
    Tracer(#[from] EmbreeError),
    /// The frame's memory estimate exceeds the limit (nothing was allocated).
    #[error(transparent)]
    Budget(#[from] super::budget::BudgetError),
    /// The meshes' tracer could not be built.
    #[error(transparent)]
    Meshes(#[from] crate::accel::mesh::MeshTracerError),
}

/// The tracer of `backend` over `strands` as `curves`.
fn tracer_of(
    strands: &Strands,
    backend: Backend,
    curves: CurveKind,
) -> Result<Box<dyn Tracer + Send>, FrameError> {
    Ok(match backend {
        Backend::Embree => Box::new(EmbreeTracer::new(strands, curves)?),
        Backend::Bvh => Box::new(BvhTracer::new(strands, curves)),
    })
}

/// A frame ready to render.
pub struct Frame {
    /// The strands, as every tracer and the shadow maps see them: the tracer was built from them and
    /// [`Frame::hair_bounds`] measured them, so they are not to be changed once the frame is built. Shared with
    /// the frames [`Frame::with_curves`] makes of them.
    pub strands: Arc<Strands>,
    /// The hair's acceleration structure, built by [`Frame::backend`].
    pub tracer: Box<dyn Tracer + Send>,
    /// Round tubes or flat ribbons.
    pub curves: CurveKind,
    /// Which implementation traces the strands.
    pub backend: Backend,
    /// The fibre material.
    pub material: Material,
    /// Every light, environment last.
    pub lights: Vec<Light>,
    /// Non-hair geometry.
    pub shapes: Shapes,
    /// The scene's own settings (a [`Request`] may render others).
    pub settings: RenderSettings,
    /// Wall time of reading or generating the hair and converting it to strands, seconds.
    pub load_seconds: f64,
    /// The memory estimate the frame was admitted by ([`Frame::load_adjusted`]; `None` when built otherwise).
    pub memory_estimate: Option<super::budget::MemoryEstimate>,
    /// The memory limit the frame was admitted under, bytes (`None` when built otherwise): what `--quality auto`
    /// may add to [`Frame::memory_estimate`] for its comparisons ([`Frame::memory_headroom`]).
    pub memory_limit: Option<u64>,
    /// Strands of the model left out for zero length ([`crate::hair::HairModel::drop_zero_length`]).
    pub zero_length_strands: usize,
    /// The strands' bounding box, measured once: every render needs it (camera framing, scene radius), and on the
    /// fur ball each pass over the control points was ~3 % of a 64², 4-spp render's instructions.
    hair_bounds: (Vec3, Vec3),
}

impl Frame {
    /// Loads the hair of `spec` and builds the frame, after checking its memory estimate against the default
    /// limit ([`super::budget::default_limit`]) for the current rayon pool: the benchmarks and studies refuse a
    /// frame the machine cannot hold as `render` does.
    pub fn load(spec: FrameSpec) -> Result<Frame, FrameError> {
        let (limit, source) = super::budget::default_limit();
        Frame::load_within(spec, limit, &source)
    }

    /// [`Frame::load`] with the memory limit `limit` (bytes), named `limit_source` in the refusal.
    pub fn load_within(
        spec: FrameSpec,
        limit: u64,
        limit_source: &str,
    ) -> Result<Frame, FrameError> {
        Frame::load_adjusted(spec, limit, limit_source, false, |_, _| {})
    }

    /// [`Frame::load_within`], with `adjust` changing the spec once the strands are loaded and before anything is
    /// built from them (`--quality auto` chooses the curve kind from the strands' width on screen there);
    /// `adaptive`: the frame will sample adaptively though its settings do not say so yet (`--quality auto` sets
    /// them after loading), so its memory is checked with adaptive sampling's per-pixel state.
    pub fn load_adjusted(
        mut spec: FrameSpec,
        limit: u64,
        limit_source: &str,
        adaptive: bool,
        adjust: impl FnOnce(&Strands, &mut FrameSpec),
    ) -> Result<Frame, FrameError> {
        let estimate =
            super::budget::estimate_frame(&spec, rayon::current_num_threads(), adaptive)?;
        estimate.check(limit, limit_source)?;
        let start = Instant::now();
        let (strands, zero_length_strands) = spec.hair.load_counting()?;
        let load_seconds = start.elapsed().as_secs_f64();
        // A USD stage's size does not bound its strands (instancing): checked again with the counts read, before
        // the tracer, the frame's largest part, is built.
        let estimate = if matches!(spec.hair.source, crate::hair::HairSource::Usd { .. }) {
            let counts = (
                strands.strand_count() as u64,
                strands.control_points.len() as u64,
            );
            let read = super::budget::estimate_frame_of(
                &spec,
                counts,
                rayon::current_num_threads(),
                adaptive,
            );
            read.check(limit, limit_source)?;
            read
        } else {
            estimate
        };
        adjust(&strands, &mut spec);
        let mut frame = Frame::build(strands, spec)?;
        frame.load_seconds = load_seconds;
        frame.memory_estimate = Some(estimate);
        frame.memory_limit = Some(limit);
        frame.zero_length_strands = zero_length_strands;
        Ok(frame)
    }

    /// Builds the frame around strands already in memory (`spec.hair` is not read).
    pub fn build(strands: Strands, mut spec: FrameSpec) -> Result<Frame, FrameError> {
        let tracer = tracer_of(&strands, spec.backend, spec.curves)?;
        spec.shapes.trace(spec.backend)?;
        let hair_bounds = strands.bounds();
        Ok(Frame {
            strands: Arc::new(strands),
            hair_bounds,
            tracer,
            curves: spec.curves,
            backend: spec.backend,
            material: spec.material,
            lights: spec.lights,
            shapes: spec.shapes,
            settings: spec.settings,
            load_seconds: 0.0,
            memory_estimate: None,
            memory_limit: None,
            zero_length_strands: 0,
        })
    }

    /// The same frame traced as `curves`: the strands are shared, only a tracer is built (`--quality auto`
    /// measures ribbons against tubes on the same samples with it).
    pub fn with_curves(&self, curves: CurveKind) -> Result<Frame, FrameError> {
        Ok(Frame {
            strands: Arc::clone(&self.strands),
            hair_bounds: self.hair_bounds,
            tracer: tracer_of(&self.strands, self.backend, curves)?,
            curves,
            backend: self.backend,
            material: self.material.clone(),
            lights: self.lights.clone(),
            shapes: self.shapes.clone(),
            settings: self.settings.clone(),
            load_seconds: 0.0,
            memory_estimate: self.memory_estimate,
            memory_limit: self.memory_limit,
            zero_length_strands: self.zero_length_strands,
        })
    }

    /// The strands' bounding box ([`Strands::bounds`], taken when the frame was built).
    pub fn hair_bounds(&self) -> (Vec3, Vec3) {
        self.hair_bounds
    }

    /// Radius of a sphere around the hair and the shapes (sizes infinite lights' power and ray offsets).
    pub fn radius(&self) -> f32 {
        let (mut lo, mut hi) = self.hair_bounds;
        if let Some((a, b)) = self.shapes.bounds() {
            (lo, hi) = (lo.min(a), hi.max(b));
        }
        let r = 0.5 * (hi - lo).length();
        if r.is_finite() && r > 0.0 {
            r
        } else {
            1.0
        }
    }

    /// Wall time of building the acceleration structure, seconds.
    pub fn build_seconds(&self) -> f64 {
        self.tracer.build_seconds()
    }

    /// Bytes `--quality auto` may hold beside what the frame was admitted with (the maps it builds, a second
    /// tracer for a comparison): the memory limit less the admitted estimate without its maps, which auto decides
    /// itself. `None` when the frame was built without an estimate (tests, benchmarks).
    pub fn memory_headroom(&self) -> Option<u64> {
        let (estimate, limit) = (self.memory_estimate?, self.memory_limit?);
        Some(limit.saturating_sub(estimate.total() - estimate.shadow_maps))
    }

    /// Whether `bytes` more fit [`Frame::memory_headroom`] (always, when it is unknown).
    pub fn fits(&self, bytes: u64) -> bool {
        self.memory_headroom().is_none_or(|room| bytes <= room)
    }

    /// Bytes of the deep opacity maps `settings` build for this frame's lights ([`super::budget::map_bytes`]).
    pub fn map_bytes(&self, settings: &RenderSettings) -> u64 {
        super::budget::map_bytes(settings, super::budget::map_count(&self.lights, settings))
    }

    /// Bytes of a tracer over this frame's strands as `curves`, at its build peak.
    pub fn tracer_bytes(&self, curves: CurveKind) -> u64 {
        super::budget::accel_bytes(self.strands.segment_count() as u64, self.backend, curves)
    }

    /// Builds the deep opacity maps of every light with `settings.shadows.deep_opacity`, on the current rayon pool.
    pub fn shadow_maps(&self, settings: &RenderSettings) -> ShadowMaps {
        ShadowMaps::build(
            &self.strands,
            &self.lights,
            &settings.shadows.deep_opacity,
            settings.integrator.dual(),
        )
    }

    /// Renders `request` on the current rayon pool: its settings, its region (the whole film by default), its
    /// maps or, in deep-opacity mode without them, maps built first (their build time is reported apart from the
    /// pixel loop's, in [`super::RenderStats::shadow_build_seconds`]).
    pub fn render(&self, request: Request<'_>) -> RegionRender {
        let settings = request.settings;
        let [width, height] = settings.film.resolution;
        let region = request.region.unwrap_or(Region::full(width, height));
        assert!(
            region.check_inside(width, height).is_ok() && region.width() > 0 && region.height() > 0,
            "region {region:?} is not inside the {width}x{height} frame"
        );
        let deep_opacity = settings.shadows.mode == ShadowMode::DeepOpacity;
        let start = Instant::now();
        let built = (deep_opacity && request.maps.is_none()).then(|| self.shadow_maps(settings));
        let (maps, maps_seconds) = match (request.maps, &built) {
            (Some((m, seconds)), _) => (Some(m), seconds),
            (None, Some(m)) => (Some(m), start.elapsed().as_secs_f64()),
            (None, None) => (None, 0.0),
        };
        let maps = maps.filter(|_| deep_opacity);
        let mut r = super::driver::render_tiles(
            self,
            settings,
            maps,
            request.progress,
            region,
            request.cancel,
            request.tile_side,
            request.sampling,
        );
        if let Some(m) = maps {
            r.stats.shadow_build_seconds = maps_seconds;
            r.stats.shadow_map_bytes = m.bytes();
        }
        r
    }
}

/// Why a worker pool could not be started.
#[derive(Debug, thiserror::Error)]
pub enum ThreadPoolError {
    /// Zero threads were asked for.
    #[error("--threads must be at least 1")]
    Zero,
    /// The operating system refused.
    #[error("cannot start {threads} worker threads: {source}")]
    Build {
        /// Threads asked for.
        threads: usize,
        /// Rayon's error.
        source: rayon::ThreadPoolBuildError,
    },
}

/// A rayon pool of `threads` workers (`None`: one per core). Every render runs inside one (`pool.install`).
pub fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool, ThreadPoolError> {
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        if n == 0 {
            return Err(ThreadPoolError::Zero);
        }
        builder = builder.num_threads(n);
    }
    builder.build().map_err(|source| ThreadPoolError::Build {
        threads: threads.unwrap_or(0),
        source,
    })
}
