//! Ray tracing of strands behind one small trait, so that Embree and the pure-Rust BVH can be
//! swapped per render and timed on identical rays; [`mesh`] traces triangle meshes on the same two backends.

pub mod bvh;
pub mod bvh_tracer;
pub mod curves;
pub mod embree;
pub mod mesh;
#[cfg(test)]
mod testing;

use glam::Vec3;

use crate::ray::{InvalidRay, Ray};
use crate::util::hash::{mix64, unit_f32, GOLDEN_GAMMA};

/// How strands are intersected.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CurveKind {
    /// Round tubes (Embree `ROUND_BSPLINE`): exact swept spheres, both for camera and shadow rays.
    #[default]
    Round,
    /// Flat ribbons facing the ray (Embree `FLAT_BSPLINE`), like RenderMan's RiCurves in the thesis.
    Flat,
}

impl CurveKind {
    /// The scene-file name: `"round"` or `"flat"`.
    pub fn name(self) -> &'static str {
        match self {
            CurveKind::Round => "round",
            CurveKind::Flat => "flat",
        }
    }
}

/// Which implementation traces the strands: the two are timed against each other on identical work.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Backend {
    /// Intel Embree through `sys::embree` ([`embree::EmbreeTracer`]).
    #[default]
    Embree,
    /// The pure-Rust BVH ([`bvh_tracer::BvhTracer`]): [`bvh`] with the ray–curve tests of [`curves`].
    Bvh,
}

impl Backend {
    /// The scene-file name: `"embree"` or `"bvh"`.
    pub fn name(self) -> &'static str {
        match self {
            Backend::Embree => "embree",
            Backend::Bvh => "bvh",
        }
    }
}

/// The closest hit of a ray with a strand.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit.
    pub t: f32,
    /// Curve segment (Embree `primID`).
    pub segment: u32,
    /// Strand the segment belongs to.
    pub strand: u32,
    /// Curve parameter along the segment, in [0, 1].
    pub u: f32,
    /// Across the curve: 0 for round curves, in [−1, 1] across a flat ribbon.
    pub v: f32,
    /// Geometric normal as the tracer reports it, not normalised. Round curves: outward from the tube axis.
    /// Flat curves: the curve tangent (Embree's convention), not a surface normal.
    pub ng: Vec3,
}

/// A strand tracer. Implementations are shared between render threads.
pub trait Tracer: Sync {
    /// Wall time of building the acceleration structure, seconds (what the backends are compared on).
    fn build_seconds(&self) -> f64;

    /// Bytes the tracer holds for the strands: its hierarchy plus its own copy of the curves (control points,
    /// indices, strand table). What the backends are compared on per segment.
    fn memory_bytes(&self) -> usize;

    /// The closest strand hit along `ray` in `[tnear, tfar]`, if any.
    fn intersect(&self, ray: &Ray) -> Result<Option<Hit>, InvalidRay>;

    /// Fraction of light passing along `ray` through semi-transparent strands: ∏ (1 − opacity) over the distinct
    /// strands crossed, each strand counted once however many times the tracer reports it. `ignore_strand` is left
    /// out (the strand being shaded: its own scattering is the BSDF's job, not a shadow).
    fn transmittance(&self, ray: &Ray, ignore_strand: Option<u32>) -> Result<f32, InvalidRay>;

    /// The distinct strands `ray` crosses (of opacity above 0, each counted once however many times the tracer
    /// reports it), `ignore_strand` left out, counted up to `limit` (at most 64, the tracers' list of strands
    /// seen): how many fibres light passes on its way to a shading point, for dual scattering
    /// ([`crate::bsdf::dual`]).
    fn strands_crossed(
        &self,
        ray: &Ray,
        ignore_strand: Option<u32>,
        limit: u32,
    ) -> Result<u32, InvalidRay>;

    /// The closest hit among the strands *present* for the ray with this `key` (see [`strand_present`]): the
    /// semi-transparent hair of the thesis' shadows, made stochastic so that light and material samples see the
    /// same hair. `ignore_strand` is never hit.
    fn intersect_stochastic(
        &self,
        ray: &Ray,
        ignore_strand: Option<u32>,
        key: u64,
    ) -> Result<Option<Hit>, InvalidRay>;

    /// Whether a strand present for this `key` blocks `ray`. Its expectation over keys is
    /// 1 − [`Tracer::transmittance`]: an unbiased, cheaper (any-hit) estimate of the same shadow.
    fn occluded_stochastic(
        &self,
        ray: &Ray,
        ignore_strand: Option<u32>,
        key: u64,
    ) -> Result<bool, InvalidRay>;
}

/// Whether strand `strand` of opacity `opacity` is present for the ray identified by `key`: true with probability
/// `opacity` over keys, and always the same answer for the same (key, strand) — so a strand the tracer reports
/// twice (front and back of a tube, two segments at a joint) is decided once, and the result does not depend on
/// traversal order or thread. Opacity 1 is always present, 0 never.
///
/// The hash is SplitMix64's finaliser over the key mixed with the strand id; its top 24 bits give u ∈ [0, 1).
#[inline]
pub fn strand_present(key: u64, strand: u32, opacity: f32) -> bool {
    let u = unit_f32(mix64(key ^ u64::from(strand).wrapping_mul(GOLDEN_GAMMA)));
    u < opacity
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_the_scene_names() {
        #[derive(serde::Deserialize)]
        struct Key {
            curves: CurveKind,
            backend: Backend,
        }
        for curves in [CurveKind::Round, CurveKind::Flat] {
            for backend in [Backend::Embree, Backend::Bvh] {
                let text = format!(
                    "curves = \"{}\"\nbackend = \"{}\"",
                    curves.name(),
                    backend.name()
                );
                let key: Key = toml::from_str(&text).unwrap();
                assert_eq!((key.curves, key.backend), (curves, backend));
            }
        }
    }

    #[test]
    fn presence_frequency_matches_opacity() {
        for (opacity, strand) in [(0.0, 3), (0.1, 17), (0.5, 123_456), (0.9, 7), (1.0, 0)] {
            let n = 200_000u64;
            let hits = (0..n)
                .filter(|&k| strand_present(k.wrapping_mul(0x2545_f491_4f6c_dd1d), strand, opacity))
                .count() as f64;
            let p = f64::from(opacity);
            let sigma = (p * (1.0 - p) / n as f64).sqrt();
            let freq = hits / n as f64;
            assert!(
                (freq - p).abs() <= 4.0 * sigma + 1e-9,
                "opacity {opacity}: frequency {freq}"
            );
        }
    }

    #[test]
    fn strands_decide_independently() {
        // Two strands of opacity 1/2 on the same ray: both present a quarter of the time (product rule, which is
        // what makes E[visible] = ∏ (1 − aᵢ)).
        let n = 200_000u64;
        let both = (0..n)
            .filter(|&k| strand_present(k, 10, 0.5) && strand_present(k, 11, 0.5))
            .count() as f64
            / n as f64;
        assert!(
            (both - 0.25).abs() < 4.0 * (0.25f64 * 0.75 / n as f64).sqrt(),
            "{both}"
        );
    }
}
