//! Where the tube can be on each of a segment's pieces: the curve sampled at the piece boundaries in f32 lanes
//! ([`SamplePoints`]) and each piece's conservative bounds ([`PieceBounds`]), which the subdivision search prunes
//! with; the geometry the search reads, apart from the search itself.

use glam::{Vec3, Vec4};

use super::cylinder::Interval;
use super::search::lerp;
use super::{BSpline, MAX_POINTS, MIN_RCP_INPUT, ULP};

/// One level's sample points P(uᵢ) and scaled derivatives P′(uᵢ)·dscale, uᵢ = lerp(u0, u1, i/n), as structure of
/// arrays (one lane per point) so that the compiler evaluates and bounds all pieces at once, in SIMD. Every lane
/// repeats the scalar arithmetic of [`BSpline::eval`], [`BSpline::eval_du`],
/// [`sqr_point_to_line_distance`](super::cylinder::sqr_point_to_line_distance) and
/// [`intersect_cylinder`](super::cylinder::intersect_cylinder) operation for operation, so the results are bit for
/// bit those of the scalar code. Hand-written because the profile shows it hot: the subdivision levels are ~90 % of a
/// hit call.
pub(super) struct SamplePoints {
    pub(super) p: [Lanes; 4],
    pub(super) dp: [Lanes; 4],
}

/// One f32 per sample point (8: Embree's AVX width; the last lane is unused with 7 pieces).
pub(super) type Lanes = [f32; MAX_POINTS];

impl SamplePoints {
    pub(super) fn new(curve: &BSpline, u0: f32, u1: f32, n: usize, dscale: f32) -> SamplePoints {
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

    pub(super) fn p(&self, i: usize) -> Vec4 {
        Vec4::new(self.p[0][i], self.p[1][i], self.p[2][i], self.p[3][i])
    }

    pub(super) fn dp(&self, i: usize) -> Vec4 {
        Vec4::new(self.dp[0][i], self.dp[1][i], self.dp[2][i], self.dp[3][i])
    }

    /// Bounds of every piece (lane i: the piece from point i to i + 1, i < n): the ray interval `ray` clipped by the
    /// piece's outer cylinder ([`intersect_cylinder`](super::cylinder::intersect_cylinder) with the outer radius) and
    /// its two cap planes ([`half_space`](super::cylinder::half_space)), and whether it is empty. Same operations as
    /// the scalar code in [`Search::check_bounds`](super::search::Search::check_bounds), so the same bits.
    pub(super) fn bounds(&self, dir: Vec3, n: usize, ray: Interval) -> PieceBounds {
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

/// What [`SamplePoints::bounds`] finds for each piece i (lane i): the values
/// [`Search::level`](super::search::Search::level) would compute for it one piece at a time.
pub(super) struct PieceBounds {
    /// Bit i: the ray interval clipped by the piece's outer cylinder and cap planes is not empty.
    pub(super) keep: u8,
    /// That interval (meaningful for kept pieces).
    pub(super) lower: Lanes,
    pub(super) upper: Lanes,
    /// Axis parameters of the outer cylinder's entry and exit ([`CylinderHit::u`](super::cylinder::CylinderHit::u)).
    pub(super) axis_u: [Lanes; 2],
    /// How far the Bézier handles stray from the chord.
    pub(super) stray: Lanes,
}
