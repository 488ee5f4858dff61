//! Ray–tube intersection matching Embree's `ROUND_BSPLINE` curves, so that the Rust BVH and Embree report the
//! same hits (issue 13).
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
//! against 100 % and 99.995 % with the AVX one (1 Dec 2026).
//!
//! **Speed.** Each level evaluates its 8 sample points and bounds its 7 pieces as structure of arrays
//! (`SamplePoints`, autovectorised, the same arithmetic as the scalar code: the unit tests check the bits), so
//! only the 1–2 pieces the ray really crosses go through the scalar inner-cylinder and Newton code.
//! `benches/curves.rs` (fur-ball-like segments, 1 Dec 2026, 2-core VM): ~880 ns and ~6 000 instructions per hit,
//! ~65 ns and ~350 instructions per near miss (before: 1 760 ns / 13 100 and 255 ns / 2 500).
//!
//! **Normal.** Embree's convention: Ng = (P′ × R̂) × (P′ + r′R̂) with R̂ the unit vector from the axis to the hit,
//! i.e. outward from the axis (tilted by the taper), not normalised (|Ng| ≈ |P′|²). `v` is 0.
//!
//! All in f32, no allocation: the subdivision stack is a fixed array.

use std::cmp::Ordering;

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

/// One level's sample points P(uᵢ) and scaled derivatives P′(uᵢ)·dscale, uᵢ = lerp(u0, u1, i/n), as structure of
/// arrays (one lane per point) so that the compiler evaluates and bounds all pieces at once, in SIMD. Every lane
/// repeats the scalar arithmetic of [`BSpline::eval`], [`BSpline::eval_du`], [`sqr_point_to_line_distance`] and
/// [`intersect_cylinder`] operation for operation, so the results are bit for bit those of the scalar code.
/// Hand-written because the profile shows it hot: the subdivision levels are ~90 % of a hit call.
struct SamplePoints {
    p: [Lanes; 4],
    dp: [Lanes; 4],
}

/// One f32 per sample point (8: Embree's AVX width; the last lane is unused with 7 pieces).
type Lanes = [f32; MAX_POINTS];

impl SamplePoints {
    fn new(curve: &BSpline, u0: f32, u1: f32, n: usize, dscale: f32) -> SamplePoints {
        let inv_n = 1.0 / n as f32;
        let u: Lanes = std::array::from_fn(|i| lerp(u0, u1, i as f32 * inv_n));
        // The basis and its derivative at every uᵢ (BSpline::eval and eval_du, same operations).
        let mut b = [[0.0f32; MAX_POINTS]; 4];
        let mut db = [[0.0f32; MAX_POINTS]; 4];
        for i in 0..MAX_POINTS {
            let (t, s) = (u[i], 1.0 - u[i]);
            let n0 = s * s * s;
            let n1 = (4.0 * (s * s * s) + t * t * t) + (12.0 * ((s * t) * s) + 6.0 * ((t * s) * t));
            let n2 = (4.0 * (t * t * t) + s * s * s) + (12.0 * ((t * s) * t) + 6.0 * ((s * t) * s));
            let n3 = t * t * t;
            let k = 1.0 / 6.0;
            b[0][i] = k * n0;
            b[1][i] = k * n1;
            b[2][i] = k * n2;
            b[3][i] = k * n3;
            db[0][i] = 0.5 * (-s * s);
            db[1][i] = 0.5 * (-t * t - 4.0 * (t * s));
            db[2][i] = 0.5 * (s * s + 4.0 * (s * t));
            db[3][i] = 0.5 * (t * t);
        }
        let [v0, v1, v2, v3] = curve.0.map(|v| v.to_array());
        let mut p = [[0.0f32; MAX_POINTS]; 4];
        let mut dp = [[0.0f32; MAX_POINTS]; 4];
        for c in 0..4 {
            for i in 0..MAX_POINTS {
                // BSpline::combine: b₀v₀ + (b₁v₁ + (b₂v₂ + b₃v₃)).
                p[c][i] = b[0][i] * v0[c] + (b[1][i] * v1[c] + (b[2][i] * v2[c] + b[3][i] * v3[c]));
                dp[c][i] = (db[0][i] * v0[c]
                    + (db[1][i] * v1[c] + (db[2][i] * v2[c] + db[3][i] * v3[c])))
                    * dscale;
            }
        }
        SamplePoints { p, dp }
    }

    fn p(&self, i: usize) -> Vec4 {
        Vec4::new(self.p[0][i], self.p[1][i], self.p[2][i], self.p[3][i])
    }

    fn dp(&self, i: usize) -> Vec4 {
        Vec4::new(self.dp[0][i], self.dp[1][i], self.dp[2][i], self.dp[3][i])
    }

    /// Bounds of every piece (lane i: the piece from point i to i + 1, i < n): the ray interval `ray` clipped by
    /// the piece's outer cylinder ([`intersect_cylinder`] with the outer radius) and its two cap planes
    /// ([`half_space`]), and whether it is empty. Same operations as the scalar code in
    /// [`Search::check_bounds`], so the same bits.
    fn bounds(&self, dir: Vec3, n: usize, ray: Interval) -> PieceBounds {
        let [x, y, z, w] = &self.p;
        let [dx, dy, dz, dw] = &self.dp;
        let dd = dir.dot(dir);
        let mut keep = [false; MAX_POINTS];
        let mut b = PieceBounds {
            keep: 0,
            lower: [0.0; MAX_POINTS],
            upper: [0.0; MAX_POINTS],
            axis_u: [[0.0; MAX_POINTS]; 2],
            stray: [0.0; MAX_POINTS],
        };
        for i in 0..MAX_POINTS - 1 {
            let j = i + 1;
            // Handles' radii P1 = P0 + d0, P2 = P3 − d3.
            let w1 = w[i] + dw[i];
            let w2 = w[j] - dw[j];
            // Chord and the handles' squared distances from it (sqr_point_to_line_distance).
            let (cx, cy, cz) = (x[j] - x[i], y[j] - y[i], z[j] - z[i]);
            let cc = (cx * cx) + (cy * cy) + (cz * cz);
            let rcp_cc = 1.0 / cc;
            let n0x = dy[i] * cz - cy * dz[i];
            let n0y = dz[i] * cx - cz * dx[i];
            let n0z = dx[i] * cy - cx * dy[i];
            let n3x = dy[j] * cz - cy * dz[j];
            let n3y = dz[j] * cx - cz * dx[j];
            let n3z = dx[j] * cy - cx * dy[j];
            let s0 = ((n0x * n0x) + (n0y * n0y) + (n0z * n0z)) * rcp_cc;
            let s3 = ((n3x * n3x) + (n3y * n3y) + (n3z * n3z)) * rcp_cc;
            let stray = s0.max(s3).sqrt();
            let r = (w[i].max(w1).max(w2).max(w[j]) + stray) * (1.0 + 2.0 * ULP);
            // intersect_cylinder(dir, P0, P3, r).
            let rl = 1.0 / cc.sqrt();
            let (ax, ay, az) = (cx * rl, cy * rl, cz * rl);
            let (ox, oy, oz) = (-x[i], -y[i], -z[i]);
            let od = (dir.x * ox) + (dir.y * oy) + (dir.z * oz);
            let oo = (ox * ox) + (oy * oy) + (oz * oz);
            let a_d = (ax * dir.x) + (ay * dir.y) + (az * dir.z);
            let a_o = (ax * ox) + (ay * oy) + (az * oz);
            let qa = dd - a_d * a_d;
            let qb = 2.0 * (od - a_d * a_o);
            let qc = oo - a_o * a_o - r * r;
            let disc = qb * qb - 4.0 * qa * qc;
            let hit = disc >= 0.0;
            let parallel = qa.abs() < 16.0 * ULP * dd.abs().max(a_d * a_d);
            let q = disc.sqrt();
            let rcp_2a = 1.0 / (2.0 * qa);
            let (t0, t1) = ((-qb - q) * rcp_2a, (-qb + q) * rcp_2a);
            let (lower, upper) = if parallel {
                (f32::NEG_INFINITY, f32::INFINITY)
            } else {
                (t0, t1)
            };
            // The axis parameters of entry and exit (0 at P0, 1 at P3).
            let (axis_u0, axis_u1) = if parallel {
                (0.0, 0.0)
            } else {
                ((t0 * a_d + a_o) * rl, (t1 * a_d + a_o) * rl)
            };
            let hit = hit && (!parallel || qc <= 0.0);
            // Cap planes: half_space(dir, P0, d0) and half_space(dir, P3, −d3).
            let on0 = ((-x[i]) * dx[i] + (-y[i]) * dy[i]) + (-z[i]) * dz[i];
            let dn0 = (dir.x * dx[i] + dir.y * dy[i]) + dir.z * dz[i];
            let (n3x, n3y, n3z) = (-dx[j], -dy[j], -dz[j]);
            let on3 = ((-x[j]) * n3x + (-y[j]) * n3y) + (-z[j]) * n3z;
            let dn3 = (dir.x * n3x + dir.y * n3y) + dir.z * n3z;
            let plane = |on: f32, dn: f32| {
                let parallel = dn.abs() < MIN_RCP_INPUT;
                let t = -on * (1.0 / dn);
                (
                    if parallel || dn < 0.0 {
                        f32::NEG_INFINITY
                    } else {
                        t
                    },
                    if parallel || dn > 0.0 {
                        f32::INFINITY
                    } else {
                        t
                    },
                )
            };
            let (l0, u0) = plane(on0, dn0);
            let (l3, u3) = plane(on3, dn3);
            let lower = ray.lower.max(lower).max(l0).max(l3);
            let upper = ray.upper.min(upper).min(u0).min(u3);
            keep[i] = hit && lower <= upper;
            b.lower[i] = lower;
            b.upper[i] = upper;
            b.axis_u[0][i] = axis_u0;
            b.axis_u[1][i] = axis_u1;
            b.stray[i] = stray;
        }
        for (i, &k) in keep.iter().enumerate().take(n) {
            b.keep |= u8::from(k) << i;
        }
        b
    }
}

/// What [`SamplePoints::bounds`] finds for each piece i (lane i): the values [`Search::level`] would compute for
/// it one piece at a time.
struct PieceBounds {
    /// Bit i: the ray interval clipped by the piece's outer cylinder and cap planes is not empty.
    keep: u8,
    /// That interval (meaningful for kept pieces).
    lower: Lanes,
    upper: Lanes,
    /// Axis parameters of the outer cylinder's entry and exit ([`CylinderHit::u`]).
    axis_u: [Lanes; 2],
    /// How far the Bézier handles stray from the chord.
    stray: Lanes,
}

/// A closed interval of ray parameters; empty when `lower > upper`.
#[derive(Clone, Copy, Debug)]
struct Interval {
    lower: f32,
    upper: f32,
}

impl Interval {
    const EMPTY: Interval = Interval {
        lower: f32::INFINITY,
        upper: f32::NEG_INFINITY,
    };
    const ALL: Interval = Interval {
        lower: f32::NEG_INFINITY,
        upper: f32::INFINITY,
    };

    fn intersect(self, other: Interval) -> Interval {
        Interval {
            lower: self.lower.max(other.lower),
            upper: self.upper.min(other.upper),
        }
    }

    fn is_empty(self) -> bool {
        // NaN bounds count as empty, as with Embree's `lower <= upper` test.
        !matches!(
            self.lower.partial_cmp(&self.upper),
            Some(Ordering::Less | Ordering::Equal)
        )
    }
}

/// The ray (origin at 0, after step 1) against an infinite cylinder of radius `radius` around the line through
/// `p0` and `p1`: the interval inside it, the axis parameters (0 at p0, 1 at p1) of the entry and exit points, and
/// the entry and exit normals (from the axis to the point, length `radius`).
///
/// With the axis unit vector a, O = −p0 and d the ray direction, |O + t d|² − ((O + t d)·a)² = radius² is
/// A t² + B t + C = 0, A = d·d − (d·a)², B = 2 (O·d − (d·a)(O·a)), C = O·O − (O·a)² − radius².
struct CylinderHit {
    t: Interval,
    u: [f32; 2],
    ng: [Vec3; 2],
}

fn intersect_cylinder(dir: Vec3, p0: Vec3, p1: Vec3, radius: f32) -> Option<CylinderHit> {
    let axis = p1 - p0;
    let rl = 1.0 / axis.length();
    let a = axis * rl;
    let o = -p0;
    let dd = dir.dot(dir);
    let od = dir.dot(o);
    let oo = o.dot(o);
    let dz = a.dot(dir);
    let oz = a.dot(o);
    let qa = dd - dz * dz;
    let qb = 2.0 * (od - dz * oz);
    let qc = oo - oz * oz - radius * radius;
    let disc = qb * qb - 4.0 * qa * qc;
    if disc.is_nan() || disc < 0.0 {
        return None;
    }
    // A ray (nearly) parallel to the axis: inside for all t, or never.
    let eps = 16.0 * ULP * dd.abs().max(dz * dz);
    if qa.abs() < eps {
        return (qc <= 0.0).then_some(CylinderHit {
            t: Interval::ALL,
            u: [0.0; 2],
            ng: [Vec3::ZERO; 2],
        });
    }
    let q = disc.sqrt();
    let rcp_2a = 1.0 / (2.0 * qa);
    let t = [(-qb - q) * rcp_2a, (-qb + q) * rcp_2a];
    let u = t.map(|t| (t * dz + oz) * rl);
    let ng = [0, 1].map(|k| t[k] * dir - (p0 + u[k] * axis));
    Some(CylinderHit {
        t: Interval {
            lower: t[0],
            upper: t[1],
        },
        u,
        ng,
    })
}

/// The ray interval on the side of the plane through `p` that normal `n` points into.
fn half_space(dir: Vec3, p: Vec3, n: Vec3) -> Interval {
    // (t d − p)·n ≥ 0  ⇔  t ≥ (p·n)/(d·n) when d·n > 0, t ≤ it when d·n < 0.
    let on = (-p).dot(n);
    let dn = dir.dot(n);
    let parallel = dn.abs() < MIN_RCP_INPUT;
    let t = -on * (1.0 / dn);
    Interval {
        lower: if parallel || dn < 0.0 {
            f32::NEG_INFINITY
        } else {
            t
        },
        upper: if parallel || dn > 0.0 {
            f32::INFINITY
        } else {
            t
        },
    }
}

/// Squared distance of the point `p` from the line through the origin along `d`: |p × d|² / |d|².
fn sqr_point_to_line_distance(p: Vec3, d: Vec3) -> f32 {
    let n = p.cross(d);
    n.dot(n) * (1.0 / d.dot(d))
}

/// Pieces of one level still to be refined: those in `valid` (bit i = piece i of [u0, u1]), front to back.
#[derive(Clone, Copy)]
struct StackEntry {
    valid: u8,
    tlower: [f32; MAX_POINTS],
    u0: f32,
    u1: f32,
    depth: u32,
}

/// The state of one ray–segment query: the curve in ray-relative coordinates and the closest hit so far.
struct Search {
    curve: BSpline,
    dir: Vec3,
    /// t of the moved ray origin on the original ray.
    dt: f32,
    tnear: f32,
    /// Shrinks to the closest accepted hit.
    tfar: f32,
    /// Error bound of a curve evaluation.
    p_err: f32,
    r_max: f32,
    pieces: usize,
    best: Option<CurveHit>,
    /// Stop at the first accepted hit.
    any: bool,
}

/// Index of the smallest `values[i]` among the bits of `mask` (the lowest index on ties); `mask` is not empty.
fn select_min(mask: u8, values: &[f32; MAX_POINTS]) -> usize {
    let mut best = usize::MAX;
    for i in 0..MAX_POINTS {
        if mask & (1 << i) != 0 && (best == usize::MAX || values[i] < values[best]) {
            best = i;
        }
    }
    best
}

impl Search {
    /// Steps 2–4 of the module docs over the whole segment, depth first, front to back.
    fn run(&mut self, max_depth: u32) {
        let mut stack = [StackEntry {
            valid: 0,
            tlower: [0.0; MAX_POINTS],
            u0: 0.0,
            u1: 0.0,
            depth: 0,
        }; STACK_SIZE];
        let mut len = 0;
        let mut next = Some((0.0, 1.0, 1));
        loop {
            if self.any && self.best.is_some() {
                return;
            }
            let (u0, u1, depth) = match next.take() {
                Some(piece) => piece,
                None => {
                    // Pop the front-most piece still worth refining from the top entry.
                    if len == 0 {
                        return;
                    }
                    len -= 1;
                    let entry = &mut stack[len];
                    let mut valid = entry.valid;
                    for i in 0..self.pieces {
                        if entry.tlower[i] + self.dt > self.tfar {
                            valid &= !(1 << i);
                        }
                    }
                    if valid == 0 {
                        continue;
                    }
                    let i = select_min(valid, &entry.tlower);
                    valid &= !(1 << i);
                    entry.valid = valid;
                    let (u0, u1, depth) = (entry.u0, entry.u1, entry.depth);
                    if valid != 0 {
                        len += 1;
                    }
                    let step = 1.0 / self.pieces as f32;
                    (
                        lerp(u0, u1, i as f32 * step),
                        lerp(u0, u1, (i + 1) as f32 * step),
                        depth,
                    )
                }
            };
            if let Some(entry) = self.level(u0, u1, depth, max_depth) {
                assert!(len < STACK_SIZE, "round curve: subdivision stack overflow");
                stack[len] = entry;
                len += 1;
            }
        }
    }

    /// One subdivision level over [u0, u1]: bounds every piece, runs Newton on the pieces at the last level and
    /// returns those to refine.
    fn level(&mut self, u0: f32, u1: f32, depth: u32, max_depth: u32) -> Option<StackEntry> {
        let n = self.pieces;
        // Each piece as a Bézier curve: end points P0, P3 and handles P1 = P0 + P0′ h, P2 = P3 − P3′ h, where
        // h = (u1 − u0)/(3n) converts the B-spline derivative to the piece's Bézier handles.
        let dscale = (u1 - u0) * (1.0 / (3.0 * n as f32));
        let points = SamplePoints::new(&self.curve, u0, u1, n, dscale);
        let p: [Vec4; MAX_POINTS] = std::array::from_fn(|i| points.p(i));
        let dp: [Vec4; MAX_POINTS] = std::array::from_fn(|i| points.dp(i));
        let ray = Interval {
            lower: self.tnear - self.dt,
            upper: self.tfar - self.dt,
        };
        let bounds = points.bounds(self.dir, n, ray);
        let mut tp0 = [Interval::EMPTY; MAX_POINTS];
        let mut tp1 = [Interval::EMPTY; MAX_POINTS];
        let mut u_start = [[0.0f32; 2]; MAX_POINTS];
        let (mut newton0, mut newton1, mut refine0, mut refine1) = (0u8, 0u8, 0u8, 0u8);
        for i in 0..n {
            if cfg!(test) {
                self.check_bounds(&p, &dp, i, ray, &bounds);
            }
            if bounds.keep & (1 << i) == 0 {
                continue;
            }
            let (p0, p3, d0, d3) = (p[i], p[i + 1], dp[i], dp[i + 1]);
            let (p1, p2) = (p0 + d0, p3 - d3);
            // Bounding cylinders around the chord P0P3: the radius range widened by how far the handles stray.
            // The outer one, clipped by the ray extent and by the planes normal to the curve at the piece's ends,
            // is in `bounds`.
            let r_inner = ((p0.w.min(p1.w).min(p2.w).min(p3.w) - bounds.stray[i])
                * (1.0 - 2.0 * ULP))
                .max(0.0);
            let tp = Interval {
                lower: bounds.lower[i],
                upper: bounds.upper[i],
            };
            // Start parameters from the cylinder's axis parameter, as Embree maps it (over n + 1, not n).
            u_start[i] = [0, 1].map(|k| {
                let u = bounds.axis_u[k][i];
                lerp(u0, u1, (i as f32 + u.clamp(0.0, 1.0)) / (n + 1) as f32)
            });
            let inner = intersect_cylinder(self.dir, p0.xyz(), p3.xyz(), r_inner);
            let inner_t = inner.as_ref().map_or(Interval::EMPTY, |c| c.t);
            if self.any {
                if let Some(t) = self.inside_core(p0, p1, p2, p3, bounds.stray[i], ray) {
                    self.best = Some(CurveHit {
                        t: t + self.dt,
                        u: u_start[i][0],
                        v: 0.0,
                        ng: Vec3::ZERO,
                    });
                    return None;
                }
            }
            // Unstable where the ray misses the inner cylinder or meets it at a glancing angle (|d·Ng| < 0.3,
            // with Embree's unnormalised d and Ng): one more level there.
            let term_depth = |k: usize| {
                let unstable = inner
                    .as_ref()
                    .is_none_or(|c| self.dir.dot(c.ng[k]).abs() < 0.3);
                if unstable {
                    max_depth + 1
                } else {
                    max_depth
                }
            };
            // Front part: before the inner cylinder; back part: after it.
            let front = Interval {
                lower: tp.lower,
                upper: tp.upper.min(inner_t.lower),
            };
            // Closest-hit shortcut, for a front part that would be refined: a ray that reaches the piece's core at
            // t_core crossed the wall before it, in the front part (`inside_core`). Newton from the front part's
            // start, as at the last level; a root at or before t_core is that crossing, found without refining.
            // Otherwise the piece is refined as usual.
            if !self.any && !front.is_empty() && depth < term_depth(0) {
                if let Some(t_core) = self.inside_core(p0, p1, p2, p3, bounds.stray[i], ray) {
                    if let Some(hit) = self.solve(u_start[i][0], front.lower) {
                        if hit.t - self.dt <= t_core {
                            self.best = Some(hit);
                            self.tfar = hit.t;
                            continue;
                        }
                    }
                }
            }
            let back = Interval {
                lower: tp.lower.max(inner_t.upper),
                upper: tp.upper,
            };
            tp0[i] = front;
            tp1[i] = back;
            for (part, k, newton, refine) in [
                (front, 0, &mut newton0, &mut refine0),
                (back, 1, &mut newton1, &mut refine1),
            ] {
                if part.is_empty() {
                    continue;
                }
                if depth < term_depth(k) {
                    *refine |= 1 << i;
                } else {
                    *newton |= 1 << i;
                }
            }
        }
        let lower0 = tp0.map(|t| t.lower);
        let lower1 = tp1.map(|t| t.lower);
        // Newton from the front parts, front to back; each hit shortens tfar.
        while newton0 != 0 {
            let i = select_min(newton0, &lower0);
            newton0 &= !(1 << i);
            self.newton(u_start[i][0], tp0[i].lower);
            newton0 &= self.within_tfar(&lower0);
        }
        newton1 &= self.within_tfar(&lower1);
        // Then from the back parts, starting at the exit of the outer cylinder.
        while newton1 != 0 {
            let i = select_min(newton1, &lower1);
            newton1 &= !(1 << i);
            self.newton(u_start[i][1], tp1[i].upper);
            newton1 &= self.within_tfar(&lower1);
        }
        let refine0 = refine0 & self.within_tfar(&lower0);
        let refine1 = refine1 & self.within_tfar(&lower1);
        let valid = refine0 | refine1;
        (valid != 0).then(|| {
            let mut tlower = [0.0; MAX_POINTS];
            for i in 0..n {
                tlower[i] = if refine0 & (1 << i) != 0 {
                    lower0[i]
                } else {
                    lower1[i]
                };
            }
            StackEntry {
                valid,
                tlower,
                u0,
                u1,
                depth: depth + 1,
            }
        })
    }

    /// The scalar bounds of piece `i` (outer cylinder, cap planes, ray extent), one piece at a time: the unit
    /// tests assert that [`SamplePoints::bounds`] found them bit for bit.
    fn check_bounds(
        &self,
        p: &[Vec4; MAX_POINTS],
        dp: &[Vec4; MAX_POINTS],
        i: usize,
        ray: Interval,
        bounds: &PieceBounds,
    ) {
        let keep = bounds.keep & (1 << i) != 0;
        let (p0, p3, d0, d3) = (p[i], p[i + 1], dp[i], dp[i + 1]);
        let (p1, p2) = (p0 + d0, p3 - d3);
        let chord = (p3 - p0).xyz();
        let stray = sqr_point_to_line_distance(d0.xyz(), chord)
            .max(sqr_point_to_line_distance(d3.xyz(), chord))
            .sqrt();
        let r_outer = (p0.w.max(p1.w).max(p2.w).max(p3.w) + stray) * (1.0 + 2.0 * ULP);
        let Some(outer) = intersect_cylinder(self.dir, p0.xyz(), p3.xyz(), r_outer) else {
            assert!(
                !keep,
                "SamplePoints::bounds kept piece {i} without outer cylinder"
            );
            return;
        };
        let tp = ray
            .intersect(outer.t)
            .intersect(half_space(self.dir, p0.xyz(), d0.xyz()))
            .intersect(half_space(self.dir, p3.xyz(), -d3.xyz()));
        assert_eq!(keep, !tp.is_empty(), "SamplePoints::bounds on piece {i}");
        if keep {
            let bits = |v: [f32; 5]| v.map(f32::to_bits);
            assert_eq!(
                bits([tp.lower, tp.upper, outer.u[0], outer.u[1], stray]),
                bits([
                    bounds.lower[i],
                    bounds.upper[i],
                    bounds.axis_u[0][i],
                    bounds.axis_u[1][i],
                    bounds.stray[i]
                ]),
                "SamplePoints::bounds on piece {i}"
            );
        }
    }

    /// The any-hit shortcut: the first t in `ray` at which the ray is inside the *core* of the Bézier piece
    /// `p0…p3` (x, y, z, r), if it gets there. The core is a cylinder around the chord p0p3, between the planes
    /// normal to the curve at the piece's ends, that the tube's wall cannot enter: a wall point is X = P(u) + r(u) n
    /// with n ⊥ P′(u), P(u) is within `stray` of the chord line, r(u) ≥ r_min (the least radius control value),
    /// and n's component across the line is at least cos θ, θ the largest angle between the chord and the curve's
    /// tangent (the tangent is a positive combination of the hodograph's control vectors p1 − p0, p2 − p1,
    /// p3 − p2, so θ is at most theirs). So the wall keeps r_min cos θ − stray from the line, and the core has that
    /// radius less the evaluation error. When stray is below it too, the axis runs inside the core, so the whole
    /// core is inside the tube; a ray that reaches it from outside crossed the tube's wall before — this
    /// segment's, or a neighbour's of the same strand through the shared end plane, or none when it came in
    /// through the strand's open root or tip (where Embree may see a miss). Shadow queries only ask whether
    /// a strand is hit, so they stop here, without refining or Newton.
    fn inside_core(
        &self,
        p0: Vec4,
        p1: Vec4,
        p2: Vec4,
        p3: Vec4,
        stray: f32,
        ray: Interval,
    ) -> Option<f32> {
        let chord = (p3 - p0).xyz();
        let chord_len = chord.length();
        let cos_theta = [p1 - p0, p2 - p1, p3 - p2]
            .map(|v| v.xyz().dot(chord) / (v.xyz().length() * chord_len))
            .into_iter()
            .fold(1.0f32, f32::min);
        let r_min = p0.w.min(p1.w).min(p2.w).min(p3.w);
        let radius = r_min * cos_theta - stray - 4.0 * self.p_err;
        // NaN (a degenerate chord or handle) fails the test too.
        if !(cos_theta > 0.0 && stray < radius) {
            return None;
        }
        let core = intersect_cylinder(self.dir, p0.xyz(), p3.xyz(), radius)?;
        let inside = ray
            .intersect(core.t)
            .intersect(half_space(self.dir, p0.xyz(), (p1 - p0).xyz()))
            .intersect(half_space(self.dir, p3.xyz(), (p3 - p2).xyz() * -1.0));
        (!inside.is_empty()).then_some(inside.lower)
    }

    /// The pieces whose part starts no later than the closest hit so far.
    fn within_tfar(&self, lower: &[f32; MAX_POINTS]) -> u8 {
        let mut mask = 0;
        for (i, &l) in lower.iter().enumerate() {
            if l + self.dt <= self.tfar {
                mask |= 1 << i;
            }
        }
        mask
    }

    /// Newton iterations on (u, t) for f = g = 0 (module docs) from (`u`, `t`), t relative to the moved origin.
    /// Records the hit and shortens tfar when a root in range is found.
    fn newton(&mut self, u: f32, t: f32) {
        if self.any && self.best.is_some() {
            return;
        }
        if let Some(hit) = self.solve(u, t) {
            self.best = Some(hit);
            self.tfar = hit.t;
        }
    }

    /// The Newton iterations of [`Search::newton`] without recording: the root they converge to from (`u`, `t`),
    /// if it lies in [tnear, tfar] with u ∈ [0, 1].
    fn solve(&self, mut u: f32, mut t: f32) -> Option<CurveHit> {
        let dir = self.dir;
        let dir_len = dir.length();
        for _ in 0..NEWTON_ITERATIONS {
            // Q(t) = t d (the origin is 0), R = Q − P(u).
            let q = t * dir;
            let q_err = 16.0 * ULP * dir_len * t;
            let (p, dpdu, ddpdu) = (
                self.curve.eval(u),
                self.curve.eval_du(u),
                self.curve.eval_dudu(u),
            );
            let r = q - p.xyz();
            let len_r = r.length();
            let r_err = q_err.max(self.p_err);
            let (drdu, drdt) = (-dpdu.xyz(), dir);
            // T = P′/|P′| and dT/du = (P″ |P′|² − P′ (P′·P″)) / |P′|³.
            let (d1, d2) = (dpdu.xyz(), ddpdu.xyz());
            let tangent = d1.normalize();
            let d11 = d1.dot(d1);
            let dtdu = (d2 * d11 - d1 * d1.dot(d2)) * (d11 * d11.sqrt()).recip();
            let cos_err = self.p_err / d1.length();
            // f = R·T, with its float error bound (Embree's estimate).
            let f = r.dot(tangent);
            let f_err = len_r * self.p_err + r_err + cos_err * (1.0 + len_r);
            let dfdu = drdu.dot(tangent) + r.dot(dtdu);
            let dfdt = drdt.dot(tangent);
            // K = |R|² − f² is the squared distance from the axis; g = sqrt(K) − r(u).
            let k = r.dot(r) - f * f;
            let dkdu = r.dot(drdu) - f * dfdu;
            let dkdt = r.dot(drdt) - f * dfdt;
            let rsqrt_k = 1.0 / k.sqrt();
            let g = k.sqrt() - p.w;
            let g_err = r_err + f_err + 16.0 * ULP * self.r_max;
            let dgdu = dkdu * rsqrt_k - dpdu.w;
            let dgdt = dkdt * rsqrt_k;
            // Newton step: J (Δu, Δt) = (f, g), J = [[∂f/∂u, ∂f/∂t], [∂g/∂u, ∂g/∂t]].
            let det = dfdu * dgdt - dfdt * dgdu;
            let rcp_det = 1.0 / det;
            let du = (dgdt * f - dfdt * g) * rcp_det;
            let dtt = (-dgdu * f + dfdu * g) * rcp_det;
            u -= du;
            t -= dtt;
            if f.abs() < f_err && g.abs() < g_err {
                let t_hit = t + self.dt;
                // Written so that NaNs are rejected.
                if !((self.tnear..=self.tfar).contains(&t_hit) && (0.0..=1.0).contains(&u)) {
                    return None;
                }
                // Ng = (P′ × R̂) × (P′ + r′ R̂): outward, tilted by the taper.
                let r_hat = (q - p.xyz()).normalize();
                let along = d1 + dpdu.w * r_hat;
                let around = d1.cross(r_hat);
                return Some(CurveHit {
                    t: t_hit,
                    u,
                    v: 0.0,
                    ng: around.cross(along),
                });
            }
        }
        None
    }
}

fn lerp(a: f32, b: f32, s: f32) -> f32 {
    (1.0 - s) * a + s * b
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::embree::{Device, EmbreeTracer};
    use crate::accel::testing::Rng;
    use crate::accel::{CurveKind, Tracer};
    use crate::hair::{HairModel, Strands};
    use crate::ray::Ray;

    /// Hit distances agree when |Δt| ≤ this · t (issue 13).
    const T_RELATIVE: f32 = 1e-3;

    /// A hit whose |cos| between ray and normal is below this counts as grazing the silhouette, where two
    /// correct float implementations may decide hit or miss differently.
    const GRAZING_COS: f32 = 0.1;

    /// Straight, evenly spaced control points along y with radius `r`: the B-spline is the segment
    /// y ∈ [−0.5, 0.5] itself, u = y + 0.5, a cylinder of radius r.
    fn straight(r: f32) -> [[f32; 4]; 4] {
        [-1.5, -0.5, 0.5, 1.5].map(|y| [0.0, y, 0.0, r])
    }

    #[test]
    fn perpendicular_ray_through_a_straight_tube_hits_at_d_minus_r() {
        let r = 0.05;
        for x in [0.0, 0.3 * r, 0.6 * r, 0.95 * r] {
            for scale in [1.0, 2.0, 0.25] {
                let org = Vec3::new(x, 0.3, 5.0);
                let hit = intersect(org, scale * Vec3::NEG_Z, 0.0, f32::INFINITY, straight(r))
                    .unwrap_or_else(|| panic!("x = {x}, scale {scale}: missed"));
                let z = (r * r - x * x).sqrt();
                let expected = (5.0 - z) / scale;
                assert!(
                    (hit.t - expected).abs() <= 1e-6 * 5.0 / scale,
                    "x = {x}, scale {scale}: t = {}, expected {expected}",
                    hit.t
                );
                assert!((hit.u - 0.8).abs() < 1e-5, "u = {}", hit.u);
                assert_eq!(hit.v, 0.0);
                let n = hit.ng.normalize();
                assert!(
                    (n - Vec3::new(x, 0.0, z) / r).length() < 1e-3,
                    "x = {x}: ng = {}",
                    hit.ng
                );
            }
        }
        // Beside the tube, beyond tfar, and before tnear (the ray starting past the tube): misses.
        let cp = straight(r);
        let (org, dir) = (Vec3::new(0.0, 0.3, 5.0), Vec3::NEG_Z);
        assert_eq!(
            intersect(Vec3::new(1.05 * r, 0.3, 5.0), dir, 0.0, 10.0, cp),
            None
        );
        assert_eq!(intersect(org, dir, 0.0, 4.9, cp), None);
        // From inside the tube (tnear past the front wall), the back wall: t = d + r.
        let back = intersect(org, dir, 4.96, 10.0, cp).expect("back wall");
        assert!((back.t - 5.05).abs() < 1e-5, "{back:?}");
        assert!(
            back.ng.z < 0.0,
            "back wall normal points away from the axis: {back:?}"
        );
        // Past the segment's end planes (u outside [0, 1]): no hit.
        assert_eq!(
            intersect(Vec3::new(0.0, 0.6, 5.0), dir, 0.0, 10.0, cp),
            None
        );
        assert_eq!(
            intersect(Vec3::new(0.0, -0.6, 5.0), dir, 0.0, 10.0, cp),
            None
        );
    }

    #[test]
    fn ray_normal_to_the_plane_of_a_curved_tapered_segment_hits_at_d_minus_r() {
        // A planar curve in z = 0 with varying radius. A ray along −z through P(u₀) lies in the normal plane at
        // u₀ (the tangent is in the xy plane), so it meets the circle of radius r(u₀) at t = d − r(u₀), u = u₀.
        let cp = [
            [0.0, 0.0, 0.0, 0.05],
            [1.0, 1.0, 0.0, 0.08],
            [2.0, 0.5, 0.0, 0.03],
            [3.0, 2.0, 0.0, 0.05],
        ];
        let curve = BSpline(cp.map(Vec4::from_array));
        for u0 in [0.05, 0.37, 0.5, 0.81, 0.97] {
            let p = curve.eval(u0);
            let d = 3.0;
            let hit = intersect(p.xyz() + d * Vec3::Z, Vec3::NEG_Z, 0.0, 100.0, cp)
                .unwrap_or_else(|| panic!("u0 = {u0}: missed"));
            assert!(
                (hit.t - (d - p.w)).abs() < 1e-5,
                "u0 = {u0}: t = {}, expected {}",
                hit.t,
                d - p.w
            );
            assert!((hit.u - u0).abs() < 1e-4, "u0 = {u0}: u = {}", hit.u);
            // Outward: the hit lies above the axis, so Ng points up (+z), up to the taper's tilt along P′.
            let n = hit.ng.normalize();
            assert!(n.z > 0.95, "u0 = {u0}: ng = {}", hit.ng);
        }
    }

    /// One strand of one segment with these control points.
    fn single_segment(cp: [[f32; 4]; 4]) -> Strands {
        Strands {
            control_points: cp.to_vec(),
            strand_offsets: vec![0, 4],
            segment_first: vec![0],
            segment_strand: vec![0],
            opacity: vec![1.0],
            color: vec![[0.5; 3]],
        }
    }

    /// The closest hit over every segment of `strands`, by brute force, with its segment.
    fn closest(
        strands: &Strands,
        ray: &Ray,
        pieces: usize,
        max_depth: u32,
    ) -> Option<(u32, CurveHit)> {
        let mut best: Option<(u32, CurveHit)> = None;
        for (s, &first) in strands.segment_first.iter().enumerate() {
            let first = first as usize;
            let cp = [0, 1, 2, 3].map(|k| strands.control_points[first + k]);
            let tfar = best.map_or(ray.tfar, |(_, h)| h.t);
            if let Some(h) = intersect_with(
                ray.origin, ray.dir, ray.tnear, tfar, cp, pieces, max_depth, true, false,
            ) {
                best = Some((s as u32, h));
            }
        }
        best
    }

    /// How the Rust intersector and Embree agree on a set of rays.
    #[derive(Debug, Default)]
    struct Agreement {
        rays: usize,
        both_hit: usize,
        both_miss: usize,
        only_embree: usize,
        only_ours: usize,
        /// Both hit, but |Δt| > T_RELATIVE · t (e.g. front wall against back wall).
        t_differs: usize,
        /// Both hit at the same t, on different segments away from a shared joint.
        segment_differs: usize,
        /// Disagreements on hits grazing the silhouette (|cos| < GRAZING_COS).
        grazing: usize,
        worst_t: f32,
        worst_u: f32,
        worst_ng_cos: f32,
        examples: Vec<String>,
    }

    impl Agreement {
        fn disagreements(&self) -> usize {
            self.only_embree + self.only_ours + self.t_differs + self.segment_differs
        }
        fn fraction(&self) -> f64 {
            1.0 - self.disagreements() as f64 / self.rays as f64
        }
    }

    fn grazing(ray: &Ray, ng: Vec3) -> bool {
        ray.dir.normalize().dot(ng.normalize()).abs() < GRAZING_COS
    }

    fn compare(
        agreement: &mut Agreement,
        tracer: &EmbreeTracer,
        strands: &Strands,
        ray: &Ray,
        pieces: usize,
        max_depth: u32,
    ) {
        agreement.rays += 1;
        let embree = tracer.intersect(ray).unwrap();
        let ours = closest(strands, ray, pieces, max_depth);
        let note = |a: &mut Agreement, what: &str| {
            if a.examples.len() < 8 {
                a.examples.push(format!(
                    "{what}: ray {ray:?}\n    embree {embree:?}\n    ours   {ours:?}"
                ));
            }
        };
        match (embree, ours) {
            (None, None) => agreement.both_miss += 1,
            (Some(e), None) => {
                agreement.only_embree += 1;
                agreement.grazing += usize::from(grazing(ray, e.ng));
                note(agreement, "only embree");
            }
            (None, Some((_, o))) => {
                agreement.only_ours += 1;
                agreement.grazing += usize::from(grazing(ray, o.ng));
                note(agreement, "only ours");
            }
            (Some(e), Some((segment, o))) => {
                agreement.both_hit += 1;
                let dt = (e.t - o.t).abs();
                if dt > T_RELATIVE * e.t {
                    agreement.t_differs += 1;
                    agreement.grazing += usize::from(grazing(ray, e.ng) || grazing(ray, o.ng));
                    note(agreement, "t differs");
                    return;
                }
                let at_joint = |u: f32| !(1e-3..=1.0 - 1e-3).contains(&u);
                if e.segment != segment {
                    if !(at_joint(e.u) && at_joint(o.u)) {
                        agreement.segment_differs += 1;
                        note(agreement, "segment differs");
                    }
                    return;
                }
                agreement.worst_t = agreement.worst_t.max(dt / e.t);
                agreement.worst_u = agreement.worst_u.max((e.u - o.u).abs());
                let cos = e.ng.normalize().dot(o.ng.normalize());
                agreement.worst_ng_cos = if agreement.worst_ng_cos == 0.0 {
                    cos
                } else {
                    agreement.worst_ng_cos.min(cos)
                };
            }
        }
    }

    /// A ray from 2–6 units away towards a random point within 1.5 radii of a random point of the curve, with a
    /// direction of random length (t is in units of `dir`).
    fn ray_at(rng: &mut Rng, cp: [[f32; 4]; 4]) -> Ray {
        let curve = BSpline(cp.map(Vec4::from_array));
        let p = curve.eval(rng.range(-0.05, 1.05));
        let target = p.xyz() + rng.range(0.0, 1.5 * p.w.abs()) * rng.unit_vector();
        let origin = target + rng.range(2.0, 6.0) * rng.unit_vector();
        Ray::new(origin, (target - origin).normalize() * rng.range(0.5, 2.0))
    }

    /// Random segments: a random walk of control points (steps 0.2–1 long), radii 0.01–0.1.
    fn random_segment(rng: &mut Rng) -> [[f32; 4]; 4] {
        let mut p = Vec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        );
        let mut cp = [[0.0; 4]; 4];
        for c in &mut cp {
            *c = [p.x, p.y, p.z, rng.range(0.01, 0.1)];
            p += rng.range(0.2, 1.0) * rng.unit_vector();
        }
        cp
    }

    fn single_segment_agreement(pieces: usize, max_depth: u32) -> Agreement {
        let device = Device::new().unwrap();
        let mut rng = Rng::new(13);
        let mut agreement = Agreement::default();
        for _ in 0..200 {
            let cp = random_segment(&mut rng);
            let strands = single_segment(cp);
            let tracer = EmbreeTracer::with_device(&device, &strands, CurveKind::Round).unwrap();
            for _ in 0..100 {
                let ray = ray_at(&mut rng, cp);
                compare(&mut agreement, &tracer, &strands, &ray, pieces, max_depth);
            }
        }
        agreement
    }

    /// Wavy strands in a 2-unit box, 7 points (6 segments) each, radius 0.02–0.05 from the file.
    fn random_bundle(rng: &mut Rng, strand_count: usize) -> Strands {
        let mut model = HairModel {
            radius_from_file: true,
            strand_offsets: vec![0],
            ..Default::default()
        };
        for _ in 0..strand_count {
            let mut p = Vec3::new(rng.range(-1.0, 1.0), -1.0, rng.range(-1.0, 1.0));
            let radius = rng.range(0.02, 0.05);
            for _ in 0..7 {
                model.points.push(p);
                model.radius.push(radius);
                model.transparency.push(0.0);
                model.color.push([0.5; 3]);
                p += Vec3::new(rng.range(-0.15, 0.15), 0.33, rng.range(-0.15, 0.15));
            }
            model.strand_offsets.push(model.points.len() as u32);
        }
        Strands::from_model(&model)
    }

    fn bundle_agreement(pieces: usize, max_depth: u32) -> Agreement {
        let mut rng = Rng::new(7);
        let strands = random_bundle(&mut rng, 40);
        let tracer = EmbreeTracer::new(&strands, CurveKind::Round).unwrap();
        let mut agreement = Agreement::default();
        for _ in 0..10_000 {
            let s = (rng.next_u64() % strands.segment_count() as u64) as usize;
            let first = strands.segment_first[s] as usize;
            let cp = [0, 1, 2, 3].map(|k| strands.control_points[first + k]);
            let ray = ray_at(&mut rng, cp);
            compare(&mut agreement, &tracer, &strands, &ray, pieces, max_depth);
            // A secondary ray from the hit, as shading spawns them: into or out of the tube, tnear just past
            // the surface, so exits through the back wall and neighbouring strands are compared too.
            if let Some(hit) = tracer.intersect(&ray).unwrap() {
                let secondary = Ray::segment(ray.at(hit.t), rng.unit_vector(), 1e-3, f32::INFINITY);
                compare(
                    &mut agreement,
                    &tracer,
                    &strands,
                    &secondary,
                    pieces,
                    max_depth,
                );
            }
        }
        agreement
    }

    #[test]
    fn early_reject_changes_no_result() {
        // Rays through the bounding box of hair-like segments (what the BVH offers), and rays aimed within 3 radii
        // of the curve (the band around the reject distance): the same result with and without step 0, and step 0
        // must reject most of the box rays, or it is not worth its cost.
        let (mut box_rays, mut rejected, mut hits, mut explained) = (0, 0, 0, 0);
        super::super::near_rays(0x5eed, |cp, org, dir, tnear, through_box| {
            box_rays += usize::from(through_box);
            let search = |early, any| {
                intersect_with(
                    org,
                    dir,
                    tnear,
                    f32::INFINITY,
                    cp,
                    PIECES,
                    MAX_DEPTH,
                    early,
                    any,
                )
            };
            let (with, without) = (search(true, false), search(false, false));
            // The any-hit search answers alike (and, ending at the first root, at no larger t), except where its
            // shortcut is told apart from the wall crossing: a ray that starts inside the tube or enters it
            // through an open end of this lone segment (module docs of `level`'s shortcut).
            let any = search(true, true);
            let differs = match (any, with) {
                (Some(a), Some(w)) => a.t < w.t,
                (a, w) => a.is_some() != w.is_some(),
            };
            if differs {
                assert!(
                    enters_through_an_end_or_starts_inside(cp, org, dir, tnear),
                    "cp {cp:?}, org {org}, dir {dir}, tnear {tnear}: any-hit {any:?}, closest {with:?}"
                );
                explained += 1;
            }
            assert_eq!(
                with, without,
                "cp {cp:?}, org {org}, dir {dir}, tnear {tnear}"
            );
            hits += usize::from(with.is_some());
            if through_box && with.is_none() {
                let v = cp.map(Vec4::from_array);
                let center = 0.25 * (v[0] + v[1] + v[2] + v[3]);
                let shifted = BSpline(v.map(|p| {
                    p - (org + (center.xyz() - org).dot(dir) / dir.dot(dir) * dir).extend(0.0)
                }));
                rejected += usize::from(far_from_curve(
                    &shifted,
                    dir,
                    REJECT_RADII * shifted.max_radius(),
                ));
            }
        });
        assert!(hits > 10_000, "too few hits to test: {hits}");
        // Every difference was explained above; this only catches a shortcut that fires far too often (the test's
        // rays start inside a tube or aim at a lone segment's ends far more often than rays in hair do).
        assert!(explained * 20 < hits, "{explained} any-hit differences");
        assert!(
            rejected * 10 > box_rays * 7,
            "step 0 rejects only {rejected} of {box_rays} box rays"
        );
    }

    /// Whether the ray from `org + tnear·dir` starts inside the tube of `cp`, or crosses one of its end discs
    /// (the circles of radius r in the normal planes at u = 0 and 1) at t ≥ tnear: by dense sampling of u, for the
    /// test above.
    fn enters_through_an_end_or_starts_inside(
        cp: [[f32; 4]; 4],
        org: Vec3,
        dir: Vec3,
        tnear: f32,
    ) -> bool {
        let curve = BSpline(cp.map(Vec4::from_array));
        let tolerance = 1.0 + 1e-3;
        let through_end = [0.0, 1.0].into_iter().any(|u| {
            let (p, n) = (curve.eval(u), curve.eval_du(u).xyz());
            let t = (p.xyz() - org).dot(n) / dir.dot(n);
            t >= tnear && (org + t * dir - p.xyz()).length() <= p.w * tolerance
        });
        let start = org + tnear * dir;
        const STEPS: usize = 4096;
        let starts_inside = (0..STEPS).any(|k| {
            let (u0, u1) = (k as f32 / STEPS as f32, (k + 1) as f32 / STEPS as f32);
            let f = |u: f32| (start - curve.eval(u).xyz()).dot(curve.eval_du(u).xyz());
            let p = curve.eval(u0);
            f(u0).signum() != f(u1).signum() && (start - p.xyz()).length() <= p.w * tolerance
        });
        through_end || starts_inside
    }

    #[test]
    fn embree_agrees_on_random_single_segments() {
        let a = single_segment_agreement(PIECES, MAX_DEPTH);
        assert!(a.both_hit > a.rays / 3, "too few hits to test: {a:?}");
        assert!(a.fraction() >= 0.999, "{a:?}");
    }

    #[test]
    fn embree_agrees_on_a_random_bundle() {
        let a = bundle_agreement(PIECES, MAX_DEPTH);
        assert!(a.both_hit > a.rays / 3, "too few hits to test: {a:?}");
        assert!(a.fraction() >= 0.999, "{a:?}");
    }
}
