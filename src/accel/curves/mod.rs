//! Ray–curve intersection in pure Rust, for the BVH backend (issue 13): the same swept surfaces Embree intersects,
//! so both backends hit the same strands.
//!
//! - [`round`]: Embree's `ROUND_BSPLINE` — a sphere of varying radius swept along a cubic B-spline segment.
//! - [`flat`]: Embree's `FLAT_BSPLINE` — a ribbon of the segment's width that always faces the ray.
//!
//! A segment is given as its four control points (x, y, z, radius), exactly as `hair::Strands::control_points`
//! holds them and as Embree receives them; results use the conventions of [`crate::accel::Hit`].

pub mod flat;
pub mod round;

use glam::Vec3;

/// A ray–segment intersection, in the conventions of [`crate::accel::Hit`] (without strand and segment ids).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurveHit {
    /// Ray parameter of the hit.
    pub t: f32,
    /// Curve parameter along the segment, in [0, 1].
    pub u: f32,
    /// Across the curve: 0 for round curves, in [−1, 1] across a flat ribbon.
    pub v: f32,
    /// Geometric normal, not normalised: round curves, outward from the tube axis; flat curves, the curve tangent.
    pub ng: Vec3,
}
