//! Ray intervals: inside the infinite cylinder about a piece's axis ([`intersect_cylinder`]), on one side of a
//! plane ([`half_space`]), and their intersection ([`Interval`]); the small geometry the bounds and the search
//! combine, apart from both.

use std::cmp::Ordering;

use glam::Vec3;

use super::{MIN_RCP_INPUT, ULP};

/// A closed interval of ray parameters; empty when `lower > upper`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Interval {
    pub(super) lower: f32,
    pub(super) upper: f32,
}

impl Interval {
    pub(super) const EMPTY: Interval = Interval {
        lower: f32::INFINITY,
        upper: f32::NEG_INFINITY,
    };
    pub(super) const ALL: Interval = Interval {
        lower: f32::NEG_INFINITY,
        upper: f32::INFINITY,
    };

    pub(super) fn intersect(self, other: Interval) -> Interval {
        Interval {
            lower: self.lower.max(other.lower),
            upper: self.upper.min(other.upper),
        }
    }

    pub(super) fn is_empty(self) -> bool {
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
pub(super) struct CylinderHit {
    pub(super) t: Interval,
    pub(super) u: [f32; 2],
    pub(super) ng: [Vec3; 2],
}

pub(super) fn intersect_cylinder(
    dir: Vec3,
    p0: Vec3,
    p1: Vec3,
    radius: f32,
) -> Option<CylinderHit> {
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
pub(super) fn half_space(dir: Vec3, p: Vec3, n: Vec3) -> Interval {
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
pub(super) fn sqr_point_to_line_distance(p: Vec3, d: Vec3) -> f32 {
    let n = p.cross(d);
    n.dot(n) * (1.0 / d.dot(d))
}
