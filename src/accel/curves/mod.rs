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

use glam::{Vec2, Vec3};

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

/// True when the origin is farther than `radius` from the convex hull of the 2-D points `q` (a ray, seen along
/// its direction, against a projected hull). The hull's distance exceeds `radius` when the origin lies in none
/// of the four triangles q_i q_j q_k (whose union is the hull) and is farther than `radius` from each of the six
/// segments q_i q_j (the hull's edges are among them). NaNs never count as far. Hand-written because it is the hot
/// path: most ray–segment tests the BVH asks for are near misses that stop here.
fn origin_far_from_hull(q: [Vec2; 4], radius: f32) -> bool {
    // First the cheap test of a thin, gently curved segment: the origin outside the rectangle along the chord
    // q₀q₃ that holds the hull, widened by `radius` (a separating line across or along the chord).
    let chord = q[3] - q[0];
    let normal = chord.perp();
    let reach = radius * chord.length();
    let across = q.map(|p| p.dot(normal));
    let along = q.map(|p| p.dot(chord));
    let min = |v: [f32; 4]| v[0].min(v[1]).min(v[2].min(v[3]));
    let max = |v: [f32; 4]| v[0].max(v[1]).max(v[2].max(v[3]));
    if min(across) > reach || max(across) < -reach || min(along) > reach || max(along) < -reach {
        return true;
    }
    let r2 = radius * radius;
    const PAIRS: [(usize, usize); 6] = [(0, 1), (1, 2), (2, 3), (0, 3), (0, 2), (1, 3)];
    for (i, j) in PAIRS {
        // Nearest point of the segment q_i q_j to the origin.
        let e = q[j] - q[i];
        let ee = e.dot(e);
        let s = if ee > 0.0 {
            (-q[i].dot(e) / ee).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let p = q[i] + s * e;
        let d2 = p.dot(p);
        if d2 <= r2 || d2.is_nan() {
            return false;
        }
    }
    const TRIANGLES: [(usize, usize, usize); 4] = [(0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)];
    for (i, j, k) in TRIANGLES {
        // The origin is inside when it is on the same side of all three edges (a + b + c is twice the signed
        // area: a degenerate triangle is a segment, which the distances above cover).
        let (a, b, c) = (
            q[i].perp_dot(q[j]),
            q[j].perp_dot(q[k]),
            q[k].perp_dot(q[i]),
        );
        let area2 = a + b + c;
        if (a >= 0.0 && b >= 0.0 && c >= 0.0 && area2 > 0.0)
            || (a <= 0.0 && b <= 0.0 && c <= 0.0 && area2 < 0.0)
        {
            return false;
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn origin_far_from_hull_measures_the_distance_to_the_hull() {
        // A unit square's corners, shifted so the origin is 0.5 to the left of its left edge (x = 0.5).
        let square =
            [(0.5, -0.5), (1.5, -0.5), (1.5, 0.5), (0.5, 0.5)].map(|(x, y)| Vec2::new(x, y));
        assert!(origin_far_from_hull(square, 0.49));
        assert!(!origin_far_from_hull(square, 0.51));
        // Points in any order, and the origin inside: never far.
        let shuffled = [square[2], square[0], square[3], square[1]];
        assert!(origin_far_from_hull(shuffled, 0.49));
        let around = square.map(|p| p - Vec2::new(1.0, 0.0));
        assert!(!origin_far_from_hull(around, 0.0));
        // Nearest to a corner: distance √(0.5² + 0.5²) ≈ 0.7071.
        let corner = square.map(|p| p + Vec2::new(0.0, 1.0));
        assert!(origin_far_from_hull(corner, 0.70));
        assert!(!origin_far_from_hull(corner, 0.71));
        // Collinear points (a straight segment's hull is a line segment), and NaN.
        let line = [1.0, 2.0, 3.0, 4.0].map(|x| Vec2::new(x, 0.0));
        assert!(origin_far_from_hull(line, 0.99));
        assert!(!origin_far_from_hull(line, 1.01));
        assert!(!origin_far_from_hull([Vec2::NAN; 4], 0.1));
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
