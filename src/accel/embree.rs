//! The Embree strand tracer: [`Strands`] as native Embree B-spline curves (round tubes or flat ribbons), behind the
//! [`Tracer`] trait.
//!
//! Everything Embree-specific (FFI, callbacks, the transparent-shadow filter) lives in [`crate::sys::embree`]; this
//! file only maps cuticle's strands and hits onto it, and hands the stochastic queries their presence test
//! ([`strand_present`] under the ray's key).

use std::sync::Arc;
use std::time::Instant;

use super::{strand_present, CurveKind, Hit, Tracer};
use crate::hair::Strands;
use crate::ray::{InvalidRay, Ray};
use crate::sys::embree::{
    CommittedScene, CurveBasis, CurveGeometry, Scene, StrandTable, Transmittance,
};

pub use crate::sys::embree::{BuildQuality, Cutoff, Device, EmbreeError, Layout, PACKET_WIDTHS};

/// BVH quality for hair: Embree's SAH build. On furball.hair (455k segments, Embree 3.13.5, 2 threads) `High`
/// built a BVH of the same size and traced camera and shadow rays no faster (differences within run-to-run
/// noise), so the cheaper default is kept.
const HAIR_BUILD_QUALITY: BuildQuality = BuildQuality::Medium;

/// Strands in an Embree scene as native curves. Queries may run from many threads at once.
#[derive(Debug)]
pub struct EmbreeTracer {
    device: Device,
    scene: CommittedScene,
    strands: Arc<StrandTable>,
    kind: CurveKind,
    /// Every strand has opacity 1, so the stochastic presence test always says present: a stochastic query that
    /// ignores no strand is a plain query, traced without the filter (which Embree would call for every candidate
    /// hit, and which costs traversal even when it accepts them all).
    all_opaque: bool,
    build_seconds: f64,
}

impl EmbreeTracer {
    /// Builds an Embree scene for `strands` with curves of type `kind`, on a new device.
    pub fn new(strands: &Strands, kind: CurveKind) -> Result<Self, EmbreeError> {
        Self::with_device(&Device::new()?, strands, kind)
    }

    /// Builds an Embree scene for `strands` with curves of type `kind` on an existing device (devices are costly:
    /// each has its own build thread pool).
    pub fn with_device(
        device: &Device,
        strands: &Strands,
        kind: CurveKind,
    ) -> Result<Self, EmbreeError> {
        Self::with_build(device, strands, kind, HAIR_BUILD_QUALITY, Layout::Fast)
    }

    /// [`EmbreeTracer::with_device`] with an explicit BVH build quality and leaf layout (for `bench build`).
    pub fn with_build(
        device: &Device,
        strands: &Strands,
        kind: CurveKind,
        quality: BuildQuality,
        layout: Layout,
    ) -> Result<Self, EmbreeError> {
        if !device.supports_filter_functions() {
            return Err(EmbreeError {
                code: crate::sys::embree::ErrorCode::InvalidOperation,
                message:
                    "this embree build has no filter functions, which transparent shadows need"
                        .into(),
            });
        }
        let start = Instant::now();
        let table = Arc::new(StrandTable::new(
            strands.segment_strand.clone(),
            strands.opacity.clone(),
        )?);
        let basis = match kind {
            CurveKind::Round => CurveBasis::RoundBSpline,
            CurveKind::Flat => CurveBasis::FlatBSpline,
        };
        let geometry = CurveGeometry::bspline(
            device,
            basis,
            &strands.control_points,
            &strands.segment_first,
            Arc::clone(&table),
        )?;
        let mut scene = Scene::with_layout(device, quality, layout)?;
        scene.attach(geometry)?;
        let scene = scene.commit()?;
        Ok(EmbreeTracer {
            device: device.clone(),
            scene,
            strands: table,
            kind,
            all_opaque: strands.all_opaque(),
            build_seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// The curve type the strands were built as.
    pub fn kind(&self) -> CurveKind {
        self.kind
    }

    /// The device the scene lives on (for its memory statistics).
    pub fn device(&self) -> &Device {
        &self.device
    }

    /// [`Tracer::transmittance`] with the detail of how the query ended (strands counted, cutoffs).
    pub fn transmittance_detail(
        &self,
        ray: &Ray,
        ignore_strand: Option<u32>,
    ) -> Result<Transmittance, InvalidRay> {
        self.scene.transmittance1(ray, ignore_strand)
    }
}

impl Tracer for EmbreeTracer {
    /// Wall time to create the geometry and build (commit) the BVH, in seconds; device creation excluded.
    fn build_seconds(&self) -> f64 {
        self.build_seconds
    }

    /// Embree's memory monitor for the device (BVH and the curve buffers Embree copied) plus the strand table kept
    /// in Rust for the filter. Exact when the device holds this scene alone, as [`EmbreeTracer::new`]'s does.
    fn memory_bytes(&self) -> usize {
        self.device.memory_bytes() + self.strands.bytes()
    }

    fn intersect(&self, ray: &Ray) -> Result<Option<Hit>, InvalidRay> {
        Ok(self.scene.intersect1(ray)?.map(|h| self.hit(h)))
    }

    fn intersect_stochastic(
        &self,
        ray: &Ray,
        ignore_strand: Option<u32>,
        key: u64,
    ) -> Result<Option<Hit>, InvalidRay> {
        if self.all_opaque && ignore_strand.is_none() {
            return self.intersect(ray);
        }
        Ok(self
            .scene
            .intersect1_stochastic(ray, ignore_strand, |strand, opacity| {
                strand_present(key, strand, opacity)
            })?
            .map(|h| self.hit(h)))
    }

    fn occluded_stochastic(
        &self,
        ray: &Ray,
        ignore_strand: Option<u32>,
        key: u64,
    ) -> Result<bool, InvalidRay> {
        if self.all_opaque && ignore_strand.is_none() {
            return self.scene.occluded1(ray);
        }
        self.scene
            .occluded1_stochastic(ray, ignore_strand, |strand, opacity| {
                strand_present(key, strand, opacity)
            })
    }

    fn transmittance(&self, ray: &Ray, ignore_strand: Option<u32>) -> Result<f32, InvalidRay> {
        Ok(self.scene.transmittance1(ray, ignore_strand)?.value)
    }

    fn strands_crossed(
        &self,
        ray: &Ray,
        ignore_strand: Option<u32>,
        limit: u32,
    ) -> Result<u32, InvalidRay> {
        self.scene.strands_crossed1(ray, ignore_strand, limit)
    }
}

/// Packet queries: [`Tracer::intersect`], [`Tracer::intersect_stochastic`] and [`Tracer::occluded_stochastic`] for
/// `W` = 8 or 16 rays at once, through Embree's `rtcIntersect8/16` and `rtcOccluded8/16`, for `bench replay
/// --packets`. Lane k traces `rays[k]` (none: the lane is masked off and its result left untouched) with
/// `ignore_strand[k]` and `keys[k]`, and gets what the single-ray query would report for it; an invalid ray gets
/// its error and never reaches Embree.
impl EmbreeTracer {
    /// [`Tracer::intersect`] of up to `W` rays.
    pub fn intersect_packet<const W: usize>(
        &self,
        rays: &[Option<Ray>; W],
        hits: &mut [Result<Option<Hit>, InvalidRay>; W],
    ) {
        let mut raw = [Ok(None); W];
        self.scene.intersect_packet(rays, &mut raw);
        self.hits_of(rays, &raw, hits);
    }

    /// [`Tracer::intersect_stochastic`] of up to `W` rays.
    pub fn intersect_stochastic_packet<const W: usize>(
        &self,
        rays: &[Option<Ray>; W],
        ignore_strand: &[Option<u32>; W],
        keys: &[u64; W],
        hits: &mut [Result<Option<Hit>, InvalidRay>; W],
    ) {
        let mut raw = [Ok(None); W];
        if self.all_opaque && ignore_strand.iter().all(Option::is_none) {
            self.scene.intersect_packet(rays, &mut raw);
        } else {
            self.scene.intersect_packet_stochastic(
                rays,
                ignore_strand,
                |lane, strand, opacity| strand_present(keys[lane], strand, opacity),
                &mut raw,
            );
        }
        self.hits_of(rays, &raw, hits);
    }

    /// [`Tracer::occluded_stochastic`] of up to `W` rays.
    pub fn occluded_stochastic_packet<const W: usize>(
        &self,
        rays: &[Option<Ray>; W],
        ignore_strand: &[Option<u32>; W],
        keys: &[u64; W],
        occluded: &mut [Result<bool, InvalidRay>; W],
    ) {
        if self.all_opaque && ignore_strand.iter().all(Option::is_none) {
            self.scene.occluded_packet(rays, occluded);
        } else {
            self.scene.occluded_packet_stochastic(
                rays,
                ignore_strand,
                |lane, strand, opacity| strand_present(keys[lane], strand, opacity),
                occluded,
            );
        }
    }

    /// The tracer hits of the lanes with a ray, from Embree's.
    fn hits_of<const W: usize>(
        &self,
        rays: &[Option<Ray>; W],
        raw: &[Result<Option<crate::sys::embree::RayHit>, InvalidRay>; W],
        hits: &mut [Result<Option<Hit>, InvalidRay>; W],
    ) {
        for k in (0..W).filter(|&k| rays[k].is_some()) {
            hits[k] = raw[k].map(|h| h.map(|h| self.hit(h)));
        }
    }
}

impl EmbreeTracer {
    /// A tracer hit from Embree's, with the strand looked up.
    fn hit(&self, hit: crate::sys::embree::RayHit) -> Hit {
        let strand = self
            .strands
            .strand_of(hit.prim_id)
            .expect("embree reported a segment outside the strand table it was built from");
        Hit {
            t: hit.t,
            segment: hit.prim_id,
            strand,
            u: hit.u,
            v: hit.v,
            ng: hit.ng,
        }
    }
}
