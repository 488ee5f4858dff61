//! Ray–tube intersection matching Embree's `ROUND_BSPLINE` curves, so that the Rust BVH and Embree report the
//! same hits.
//!
//! **The surface.** A segment is the uniform cubic B-spline of four control points (x, y, z, r): centre line
//! P(u) and radius r(u), u ∈ [0, 1]. Embree's round curves are not the exact envelope of the swept spheres but the
//! sweep of the *circle* of radius r(u) in the plane normal to the curve at P(u): a point Q is on the surface when,
//! for some u ∈ [0, 1], with R = Q − P(u) and T = P′(u)/|P′(u)|,
//!
//! ```text
//!   f(u, t) = R·T = 0                      (Q lies in the normal plane at u)
//!   g(u, t) = sqrt(R·R − (R·T)²) − r(u) = 0 (at distance r(u) from the axis)
//! ```
//!
//! For a constant radius the two surfaces are the same; for a tapered one they differ by O(r·r′²/|P′|²), far below
//! a hair's radius. Matching Embree's definition matters more here than matching the ideal sweep.
//!
//! **Ends.** The surface stops at the normal planes of u = 0 and u = 1: a segment has no cap of its own. Two
//! consecutive segments of a strand share the end point, tangent and radius there (the B-spline is C¹, the
//! radius C²), so their circles meet in the same plane and the strand is closed along its length without a gap
//! or overlap. The strand's root and tip are open: a ray along the axis into the tip sees the tube's inside
//! wall, or nothing for a straight tube. This is what Embree 3.13 does; the test
//! `embree_agrees_on_open_ends` probes it.
//!
//! **The algorithm** is Embree's sweep intersector (Embree 3, `kernels/geometry/curve_intersector_sweep.h`,
//! `intersect_bezier_recursive_jacobian`; Cycles' `kernel/geom/curve_intersect.h`, `curve_intersect_recursive`,
//! carries a port of it), re-derived and rewritten here, because agreeing hit for hit means finding the same root
//! where there are several (front and back wall) and failing on the same grazing rays:
//!
//! 1. Move the ray origin to the point of the ray nearest the control points' centroid (t offset `dt`), so the
//!    numbers stay small. (Ours, not Embree's, which culls with the BVH's oriented boxes:) return no hit if the
//!    ray passes farther than 1.01 r_max from the box along the chord of the segment's Bézier control points,
//!    seen along the ray (`origin_far_from_chord_box` in `curves`): most calls the BVH makes are such near misses.
//! 2. Split [u0, u1] into [`PIECES`] pieces; each piece is the Bézier curve of its end points and end
//!    derivatives. Bound it by an *outer* cylinder around the chord (max radius plus the Bézier handles' distance
//!    from the chord) clipped by the two planes normal to the curve at the piece's ends, and an *inner* cylinder
//!    (min radius minus that distance) that the surface cannot enter.
//! 3. The ray interval inside the outer and outside the inner cylinder has a front part and a back part. Pieces
//!    whose part survives are split again, front to back, down to [`MAX_DEPTH`] levels (one more where the ray
//!    meets the inner cylinder at a glancing angle or misses it).
//! 4. At the last level, Newton iterations on (u, t) solve f = g = 0 from the piece's guess (front part: entry of
//!    the outer cylinder; back part: its exit), accepted when |f| and |g| are below their float error bounds and
//!    the root lies in [tnear, tfar] with u ∈ [0, 1]. Each accepted hit shortens tfar, so later pieces only
//!    report closer hits.
//!
//! Embree's SSE kernels split into 3 pieces and 3 levels, its AVX kernels (used on any AVX machine) into 7 pieces
//! and 2 levels; [`PIECES`] and [`MAX_DEPTH`] follow the AVX kernels, which agree better with the Embree of the
//! test machine: with the SSE setting the agreement tests measured 99.81 % (single segments) and 99.87 % (bundle),
//! against 100 % and 99.995 % with the AVX one.
//!
//! **Speed.** Each level evaluates its 8 sample points and bounds its 7 pieces as structure of arrays
//! (`SamplePoints`, autovectorised, the same arithmetic as the scalar code: the unit tests check the bits), so
//! only the 1–2 pieces the ray really crosses go through the scalar inner-cylinder and Newton code.
//! `benches/curves.rs` (fur-ball-like segments, 2-core VM): ~880 ns and ~6 000 instructions per hit,
//! ~65 ns and ~350 instructions per near miss (1 760 ns / 13 100 and 255 ns / 2 500 with every piece scalar).
//!
//! **Normal.** Embree's convention: Ng = (P′ × R̂) × (P′ + r′R̂) with R̂ the unit vector from the axis to the hit,
//! i.e. outward from the axis (tilted by the taper), not normalised (|Ng| ≈ |P′|²). `v` is 0.
//!
//! All in f32, no allocation: the subdivision stack is a fixed array.

mod bounds;
mod cylinder;
mod search;
#[cfg(test)]
mod tests;

use search::Search;

use glam::{Vec2, Vec3, Vec4, Vec4Swizzles};

use super::CurveHit;

/// Pieces per subdivision level (Embree's AVX kernels: 8 lanes, 8 sample points, 7 pieces).
pub const PIECES: usize = 7;

/// Subdivision levels before the Newton iterations (Embree's AVX kernels: 2; one more in unstable regions).
pub const MAX_DEPTH: u32 = 2;

/// Newton iterations per start point (Embree: 5).
const NEWTON_ITERATIONS: usize = 5;

/// Machine epsilon of f32, Embree's `ulp`.
const ULP: f32 = f32::EPSILON;

/// Below this |n·d| a cap plane counts as parallel to the ray (Embree's `min_rcp_input`).
const MIN_RCP_INPUT: f32 = 1e-18;

/// Most sample points of one level (pieces + 1), the size of the fixed arrays.
const MAX_POINTS: usize = 8;

/// Subdivision stack entries: one per level below the first, plus the unstable extra level.
const STACK_SIZE: usize = 6;

/// The closest hit of the ray `org + t·dir`, t ∈ [`tnear`, `tfar`], with the round B-spline tube of the four
/// control points `cp` (x, y, z, radius), in Embree's conventions (module docs). `dir` need not be normalised.
pub fn intersect(
    org: Vec3,
    dir: Vec3,
    tnear: f32,
    tfar: f32,
    cp: [[f32; 4]; 4],
) -> Option<CurveHit> {
    intersect_with(org, dir, tnear, tfar, cp, PIECES, MAX_DEPTH, true, false)
}

/// Whether [`intersect`] would find a hit: the same search, ended at the first accepted root instead of going on
/// for a closer one (what shadow queries need; a root [`intersect`] accepts is accepted here too, and the first
/// one it finds is the same, so both answer alike).
pub fn occludes(org: Vec3, dir: Vec3, tnear: f32, tfar: f32, cp: [[f32; 4]; 4]) -> bool {
    intersect_with(org, dir, tnear, tfar, cp, PIECES, MAX_DEPTH, true, true).is_some()
}

/// [`intersect`] with `pieces` per level (at most 7) and `max_depth` levels: Embree's SSE kernels use (3, 3);
/// `early_reject: false` skips step 0 (the tests check that it changes nothing); `any` stops at the first hit.
#[allow(clippy::too_many_arguments)]
fn intersect_with(
    org: Vec3,
    dir: Vec3,
    tnear: f32,
    tfar: f32,
    cp: [[f32; 4]; 4],
    pieces: usize,
    max_depth: u32,
    early_reject: bool,
    any: bool,
) -> Option<CurveHit> {
    debug_assert!((1..MAX_POINTS).contains(&pieces));
    let v = cp.map(Vec4::from_array);
    // Step 1: the ray origin moves to `org + dt·dir`, the point nearest the control points' centroid.
    let center = 0.25 * (v[0] + v[1] + v[2] + v[3]);
    let dt = (center.xyz() - org).dot(dir) / dir.dot(dir);
    let reference = (org + dt * dir).extend(0.0);
    let curve = BSpline(v.map(|p| p - reference));
    let r_max = curve.max_radius();
    let p_err = 16.0 * ULP * curve.max_abs_coordinate();
    // Step 0: most calls are near misses (the BVH offers every segment whose box the ray crosses): reject those
    // that pass farther than REJECT_RADII radii from the box around the segment's chord and Bézier hull.
    if early_reject && far_from_curve(&curve, dir, REJECT_RADII * r_max.abs() + 64.0 * p_err) {
        return None;
    }
    let mut search = Search {
        curve,
        dir,
        dt,
        tnear,
        tfar,
        p_err,
        r_max,
        pieces,
        best: None,
        any,
    };
    search.run(max_depth);
    search.best
}

/// Step 0's reject distance, in radii. An accepted hit lies within r(u) ≤ r_max of the axis up to the Newton
/// tolerances (|f|, |g| below bounds of a few float ulps of the coordinates, covered by the 64 p_err added to the
/// distance) and the last Newton step, of the order of those tolerances. Embree's own leaf boxes bound the tube by
/// r_max too. 1 % over one radius: on the fur ball (`bench trace`, 256², round) step 0 then rejects 50 % of the
/// calls instead of 16 % with two radii, with every hit the same (577 249 shadow-ray hits either way), and the
/// agreement tests count the same disagreements with Embree.
const REJECT_RADII: f32 = 1.01;

/// True when the ray through the origin along `dir` passes farther than `radius` from the segment's centre line:
/// projected along `dir` onto the plane normal to it, the ray is the origin, and the curve lies in the hull of
/// the projected Bézier control points ([`super::bezier_points`]), so [`super::origin_far_from_chord_box`] proves it.
fn far_from_curve(curve: &BSpline, dir: Vec3, radius: f32) -> bool {
    let b = super::bezier_points(curve.0.map(|v| v.xyz()));
    // An orthonormal pair (ex, ey) normal to dir: ex from the larger of two vectors normal to dir, ey = d × ex.
    let ex0 = Vec3::new(0.0, dir.z, -dir.y);
    let ex1 = Vec3::new(-dir.z, 0.0, dir.x);
    let ex = if ex0.length_squared() > ex1.length_squared() {
        ex0
    } else {
        ex1
    };
    let ey = dir.cross(ex);
    let (ex, ey) = (ex * ex.length_recip(), ey * ey.length_recip());
    super::origin_far_from_chord_box(b.map(|p| Vec2::new(p.dot(ex), p.dot(ey))), radius)
}

/// A cubic uniform B-spline segment with radius in `w`, evaluated in Embree's grouping of the basis.
#[derive(Clone, Copy)]
struct BSpline([Vec4; 4]);

impl BSpline {
    fn combine(&self, b: [f32; 4]) -> Vec4 {
        let [v0, v1, v2, v3] = self.0;
        b[0] * v0 + (b[1] * v1 + (b[2] * v2 + b[3] * v3))
    }

    /// P(u) = Σ Bᵢ(u) vᵢ with the uniform cubic basis (s = 1 − u):
    /// B = (s³, 4s³ + u³ + 12s²u + 6su², 4u³ + s³ + 12su² + 6s²u, u³) / 6.
    fn eval(&self, u: f32) -> Vec4 {
        let (t, s) = (u, 1.0 - u);
        let n0 = s * s * s;
        let n1 = (4.0 * (s * s * s) + t * t * t) + (12.0 * ((s * t) * s) + 6.0 * ((t * s) * t));
        let n2 = (4.0 * (t * t * t) + s * s * s) + (12.0 * ((t * s) * t) + 6.0 * ((s * t) * s));
        let n3 = t * t * t;
        let k = 1.0 / 6.0;
        self.combine([k * n0, k * n1, k * n2, k * n3])
    }

    /// P′(u): B′ = (−s², −u² − 4us, s² + 4su, u²) / 2.
    fn eval_du(&self, u: f32) -> Vec4 {
        let (t, s) = (u, 1.0 - u);
        self.combine([
            0.5 * (-s * s),
            0.5 * (-t * t - 4.0 * (t * s)),
            0.5 * (s * s + 4.0 * (s * t)),
            0.5 * (t * t),
        ])
    }

    /// P″(u): B″ = (s, u − 2s, s − 2u, u).
    fn eval_dudu(&self, u: f32) -> Vec4 {
        let (t, s) = (u, 1.0 - u);
        self.combine([s, t - 2.0 * s, s - 2.0 * t, t])
    }

    /// Largest |x|, |y|, |z| of the control points: float errors of evaluations scale with it.
    fn max_abs_coordinate(&self) -> f32 {
        self.0
            .iter()
            .fold(0.0f32, |m, p| m.max(p.xyz().abs().max_element()))
    }

    /// Largest control-point radius (Embree's `bounds().upper.w`).
    fn max_radius(&self) -> f32 {
        self.0.iter().fold(f32::NEG_INFINITY, |m, p| m.max(p.w))
    }
}
