//! Ray tracing of strands behind one small trait, so that Embree and (later, issue 7) a pure-Rust BVH can be
//! swapped per render and timed on identical rays.

pub mod embree;

use glam::Vec3;

use crate::ray::{InvalidRay, Ray};

/// How strands are intersected.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum CurveKind {
    /// Round tubes (Embree `ROUND_BSPLINE`): exact swept spheres, both for camera and shadow rays.
    #[default]
    Round,
    /// Flat ribbons facing the ray (Embree `FLAT_BSPLINE`), like RenderMan's RiCurves in the thesis.
    Flat,
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
    /// The closest strand hit along `ray` in `[tnear, tfar]`, if any.
    fn intersect(&self, ray: &Ray) -> Result<Option<Hit>, InvalidRay>;

    /// Fraction of light passing along `ray` through semi-transparent strands: ∏ (1 − opacity) over the distinct
    /// strands crossed, each strand counted once however many times the tracer reports it. `ignore_strand` is left
    /// out (the strand being shaded: its own scattering is the BSDF's job, not a shadow).
    fn transmittance(&self, ray: &Ray, ignore_strand: Option<u32>) -> Result<f32, InvalidRay>;
}
