//! Ray–curve intersection in pure Rust, for the BVH backend: the same swept surfaces Embree intersects,
//! so both backends hit the same strands.
//!
//! - [`round`]: Embree's `ROUND_BSPLINE` — a sphere of varying radius swept along a cubic B-spline segment.
//! - [`flat`]: Embree's `FLAT_BSPLINE` — a ribbon of the segment's width that always faces the ray.
//!
//! A segment is given as its four control points (x, y, z, radius), exactly as `hair::Strands::control_points`
//! holds them and as Embree receives them; results use the conventions of [`crate::accel::Hit`].

pub mod flat;
pub mod round;

use glam::{Vec2, Vec3, Vec4};

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

/// The Bézier control points of the uniform cubic B-spline segment v₀…v₃ (the same curve):
/// b₀ = (v₀ + 4v₁ + v₂)/6, b₁ = (2v₁ + v₂)/3, b₂ = (v₁ + 2v₂)/3, b₃ = (v₁ + 4v₂ + v₃)/6. Their convex hull holds
/// the curve and is tighter than the B-spline control points' own hull, so both intersectors cull rays with it.
fn bezier_points([v0, v1, v2, v3]: [Vec3; 4]) -> [Vec3; 4] {
    [
        (v0 + 4.0 * v1 + v2) * (1.0 / 6.0),
        (2.0 * v1 + v2) * (1.0 / 3.0),
        (v1 + 2.0 * v2) * (1.0 / 3.0),
        (v1 + 4.0 * v2 + v3) * (1.0 / 6.0),
    ]
}

/// True when the origin is farther than `radius` from the rectangle along the chord q₀q₃ of the 2-D points `q`
/// that holds their convex hull: some line across or along the chord separates the origin from every qᵢ by more
/// than `radius`. Seen along a ray, with `q` the projected Bézier points of a segment, it proves the ray passes
/// farther than `radius` from the curve. Four dot products a point, no division: for thin, gently curved segments
/// it rejects nearly all the rays that pass the exact hull test would (measured by the intersectors' tests), and
/// costs less on the rays it lets through. Hand-written because it is the hot path: most ray–segment tests the BVH
/// asks for are near misses that stop here. A NaN radius never counts as far; NaN points may (`min`/`max` skip
/// them), but a segment with a NaN control point is never hit.
fn origin_far_from_chord_box(q: [Vec2; 4], radius: f32) -> bool {
    let chord = q[3] - q[0];
    let normal = chord.perp();
    let reach = radius * chord.length();
    let across = q.map(|p| p.dot(normal));
    let along = q.map(|p| p.dot(chord));
    let min = |v: [f32; 4]| v[0].min(v[1]).min(v[2].min(v[3]));
    let max = |v: [f32; 4]| v[0].max(v[1]).max(v[2].max(v[3]));
    min(across) > reach || max(across) < -reach || min(along) > reach || max(along) < -reach
}

/// [`origin_far_from_chord_box`] of the [`bezier_points`] of four 2-D B-spline control points given as lanes
/// (`x[i]`, `y[i]` is point i), all in SSE lanes: the Bézier points as four multiply-adds of constant columns, the
/// extents along and across the chord as lane minima and maxima. The same test up to rounding (a few ulps of the
/// coordinates, far inside the callers' margins; a test compares the two). Hand-written for the flat ribbon's step
/// 0, which most of the BVH's curve calls end in. (The round tube's step 0 projects its Bézier points in 3-D and
/// keeps the scalar test: projected into these lanes it mispredicted more, 5.79 M -> 6.62 M branches in the round
/// `bench trace` ray loops, estimated cycles 1.455 G -> 1.466 G.)
#[inline(always)]
fn origin_far_from_bezier_box(x: Vec4, y: Vec4, radius: f32) -> bool {
    // Columns of the B-spline → Bézier map (`bezier_points`): b = C₀ v₀ + C₁ v₁ + C₂ v₂ + C₃ v₃, lane j = b_j.
    const C0: Vec4 = Vec4::new(1.0 / 6.0, 0.0, 0.0, 0.0);
    const C1: Vec4 = Vec4::new(4.0 / 6.0, 2.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0);
    const C2: Vec4 = Vec4::new(1.0 / 6.0, 1.0 / 3.0, 2.0 / 3.0, 4.0 / 6.0);
    const C3: Vec4 = Vec4::new(0.0, 0.0, 0.0, 1.0 / 6.0);
    let bezier = |v: Vec4| {
        let [v0, v1, v2, v3] = v.to_array();
        C0 * v0 + C1 * v1 + C2 * v2 + C3 * v3
    };
    let (bx, by) = (bezier(x), bezier(y));
    let (cx, cy) = (bx.w - bx.x, by.w - by.x);
    let reach = radius * (cx * cx + cy * cy).sqrt();
    // Across the chord: dot with its perpendicular (−c_y, c_x); along it: dot with (c_x, c_y).
    let across = by * cx - bx * cy;
    let along = bx * cx + by * cy;
    // `||` (measured against `|`, one branch for the four tests: 1.053 G against 1.055 G estimated cycles).
    across.min_element() > reach
        || across.max_element() < -reach
        || along.min_element() > reach
        || along.max_element() < -reach
}

/// The rays of the early-reject tests of both intersectors: 300 hair-like random segments (unit-scale, gently
/// curved, radius 10⁻³–3·10⁻²), each with 200 rays, the even ones through the segment's box widened by its radius
/// (what the BVH offers), the odd ones aimed within 3 radii of the curve; every 7th starts at tnear 1. Calls
/// `f(control points, origin, direction, tnear, through the box)`.
#[cfg(test)]
fn near_rays(seed: u64, mut f: impl FnMut([[f32; 4]; 4], Vec3, Vec3, f32, bool)) {
    use crate::accel::testing::Rng;
    let mut rng = Rng::new(seed);
    for _ in 0..300 {
        let mut cp = [[0.0f32; 4]; 4];
        let mut p = Vec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), 0.0);
        let mut heading = rng.unit_vector();
        let r = rng.range(1e-3, 3e-2);
        for c in &mut cp {
            *c = [p.x, p.y, p.z, r * rng.range(0.5, 1.0)];
            heading = (heading + 0.3 * rng.unit_vector()).normalize();
            p += rng.range(0.2, 1.0) * heading;
        }
        let lo = cp
            .iter()
            .fold(Vec3::INFINITY, |m, c| m.min(Vec3::from_slice(c)));
        let hi = cp
            .iter()
            .fold(Vec3::NEG_INFINITY, |m, c| m.max(Vec3::from_slice(c)));
        for k in 0..200 {
            let through_box = k % 2 == 0;
            let target = if through_box {
                lo - r
                    + Vec3::new(
                        rng.range(0.0, 1.0),
                        rng.range(0.0, 1.0),
                        rng.range(0.0, 1.0),
                    ) * (hi - lo + Vec3::splat(2.0 * r))
            } else {
                let b = crate::hair::strands::bspline_basis(rng.range(-0.02, 1.02));
                let c: glam::Vec4 = (0..4).map(|i| b[i] * glam::Vec4::from_array(cp[i])).sum();
                c.truncate() + rng.range(0.0, 3.0 * c.w) * rng.unit_vector()
            };
            let dir = rng.unit_vector() * rng.range(0.5, 2.0);
            let org = target - rng.range(1.0, 4.0) * dir;
            let tnear = if k % 7 == 0 { 1.0 } else { 0.0 };
            f(cp, org, dir, tnear, through_box);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn origin_far_from_chord_box_measures_the_distance_to_the_box() {
        // A unit square's corners, chord q₀q₃ along its left edge, 0.5 to the right of the origin.
        let square =
            [(0.5, -0.5), (1.5, -0.5), (1.5, 0.5), (0.5, 0.5)].map(|(x, y)| Vec2::new(x, y));
        assert!(origin_far_from_chord_box(square, 0.49));
        assert!(!origin_far_from_chord_box(square, 0.51));
        // Past the end of the chord (along it), and behind it.
        let above = square.map(|p| p - Vec2::new(1.0, 1.0));
        assert!(origin_far_from_chord_box(above, 0.49));
        assert!(!origin_far_from_chord_box(above, 0.51));
        let left = square.map(|p| p - Vec2::new(2.0, 0.0));
        assert!(origin_far_from_chord_box(left, 0.49));
        assert!(!origin_far_from_chord_box(left, 0.51));
        // Inside: never far. Collinear points (a straight segment), and a NaN radius.
        let around = square.map(|p| p - Vec2::new(1.0, 0.0));
        assert!(!origin_far_from_chord_box(around, 0.0));
        let line = [1.0, 2.0, 3.0, 4.0].map(|x| Vec2::new(x, 0.0));
        assert!(origin_far_from_chord_box(line, 0.99));
        assert!(!origin_far_from_chord_box(line, 1.01));
        let beside = [1.0, 2.0, 3.0, 4.0].map(|y| Vec2::new(0.3, y - 2.5));
        assert!(origin_far_from_chord_box(beside, 0.29));
        assert!(!origin_far_from_chord_box(beside, 0.31));
        assert!(!origin_far_from_chord_box(square, f32::NAN));
    }

    /// The lane version decides as the scalar one, but within 10⁻⁴ of the boundary (rounding): random curves
    /// around the origin at random scales and radii.
    #[test]
    fn bezier_box_in_lanes_decides_as_the_scalar_test() {
        let mut rng = crate::accel::testing::Rng::new(7);
        let (mut far, mut near) = (0, 0);
        for _ in 0..20_000 {
            let scale = [1e-3, 1.0, 1e3][(rng.next_u64() % 3) as usize];
            let v: [Vec2; 4] = std::array::from_fn(|_| {
                Vec2::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)) * scale
            });
            let radius = rng.range(0.0, 0.5) * scale;
            let scalar = |r: f32| {
                origin_far_from_chord_box(
                    bezier_points(v.map(|p| p.extend(0.0))).map(|p| p.truncate()),
                    r,
                )
            };
            let lanes = origin_far_from_bezier_box(
                Vec4::from_array(v.map(|p| p.x)),
                Vec4::from_array(v.map(|p| p.y)),
                radius,
            );
            if scalar(radius * (1.0 + 1e-4)) {
                assert!(
                    lanes,
                    "{v:?} radius {radius}: far by the scalar test, not in lanes"
                );
                far += 1;
            }
            if !scalar(radius * (1.0 - 1e-4)) {
                assert!(
                    !lanes,
                    "{v:?} radius {radius}: near by the scalar test, far in lanes"
                );
                near += 1;
            }
        }
        assert!(
            far > 1000 && near > 1000,
            "far {far}, near {near}: a vacuous test"
        );
    }

    #[test]
    fn bezier_points_give_the_same_curve() {
        // Bézier at s ∈ {0, 1/2, 1} against the B-spline basis at the same parameter.
        let v = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 2.0, 0.5),
            Vec3::new(2.0, 1.0, -1.0),
            Vec3::new(4.0, 3.0, 2.0),
        ];
        let b = bezier_points(v);
        for s in [0.0f32, 0.5, 1.0] {
            let t = 1.0 - s;
            let bezier = t * t * t * b[0]
                + 3.0 * t * t * s * b[1]
                + 3.0 * t * s * s * b[2]
                + s * s * s * b[3];
            let w = crate::hair::strands::bspline_basis(s);
            let bspline = w[0] * v[0] + w[1] * v[1] + w[2] * v[2] + w[3] * v[3];
            assert!(
                (bezier - bspline).length() < 1e-5,
                "s = {s}: {bezier} vs {bspline}"
            );
        }
    }
}
