//! Ray–primitive hits, written once for every caller: the plane, the parallelogram (the [`crate::shape::Quad`]s
//! and quad lights), the disk and the sphere (disk and sphere lights).
//!
//! A ray is the line o + t·d. The plane, parallelogram and disk accept any non-zero `d` (t is then in units of |d|);
//! the sphere needs a unit `d`. Every surface is two-sided here: which side faces the ray, and what that side does,
//! is the caller's business.
//!
//! Each hit takes the interval of t it accepts as a [`RangeBounds`]: `t_min..=t_max` (closed; the area lights) or
//! [`open`]`(t_min, t_max)` (open; the shapes, so that a tie with an earlier hit keeps the earlier one). A ray that
//! starts on a surface meets it at t = 0 (up to rounding); callers keep it out with their interval.

use std::ops::{Bound, RangeBounds};

use glam::Vec3;

/// The open interval (t_min, t_max), for the hits below.
#[inline]
pub fn open(t_min: f32, t_max: f32) -> (Bound<f32>, Bound<f32>) {
    (Bound::Excluded(t_min), Bound::Excluded(t_max))
}

/// The t at which o + t·d meets the plane through `point` with normal `n` (any non-zero length): t = n·(point − o) /
/// n·d. `None` if the ray is parallel to the plane (or lies in it), or t is not finite.
#[inline]
pub fn plane_hit(o: Vec3, d: Vec3, point: Vec3, n: Vec3) -> Option<f32> {
    let denom = n.dot(d);
    let t = n.dot(point - o) / denom;
    (denom != 0.0 && t.is_finite()).then_some(t)
}

/// The parallelogram corner + a·edge_u + b·edge_v, a, b ∈ [0, 1], with the derived data its hit test needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Parallelogram {
    corner: Vec3,
    edge_u: Vec3,
    edge_v: Vec3,
    /// Unit normal, (edge_u × edge_v) / |edge_u × edge_v|.
    normal: Vec3,
    /// Dual basis: a = (q − corner)·dual_u, b = (q − corner)·dual_v for q in the plane.
    dual_u: Vec3,
    dual_v: Vec3,
    /// Area |edge_u × edge_v|.
    area: f32,
}

impl Parallelogram {
    /// The parallelogram from `corner` spanned by `edge_u` and `edge_v`. `None` unless all three are finite and the
    /// edges span a finite, non-zero area large enough for the dual basis to be finite (|edge_u × edge_v| ≳ 5e-20:
    /// anything smaller could never be hit).
    pub fn new(corner: Vec3, edge_u: Vec3, edge_v: Vec3) -> Option<Parallelogram> {
        let cross = edge_u.cross(edge_v);
        let area = cross.length();
        // With c = edge_u × edge_v: (edge_v × c)·edge_u = (c × edge_u)·edge_v = |c|², and each is 0 on the other edge.
        let inv_area2 = 1.0 / (area * area);
        let p = Parallelogram {
            corner,
            edge_u,
            edge_v,
            normal: cross / area,
            dual_u: edge_v.cross(cross) * inv_area2,
            dual_v: cross.cross(edge_u) * inv_area2,
            area,
        };
        let finite = [corner, edge_u, edge_v, p.normal, p.dual_u, p.dual_v]
            .iter()
            .all(|v| v.is_finite());
        (area > 0.0 && area.is_finite() && finite).then_some(p)
    }

    /// The corner.
    pub fn corner(&self) -> Vec3 {
        self.corner
    }

    /// The first edge from the corner.
    pub fn edge_u(&self) -> Vec3 {
        self.edge_u
    }

    /// The second edge from the corner.
    pub fn edge_v(&self) -> Vec3 {
        self.edge_v
    }

    /// The unit normal, along edge_u × edge_v.
    pub fn normal(&self) -> Vec3 {
        self.normal
    }

    /// The area |edge_u × edge_v|.
    pub fn area(&self) -> f32 {
        self.area
    }

    /// The point corner + a·edge_u + b·edge_v.
    #[inline]
    pub fn point(&self, a: f32, b: f32) -> Vec3 {
        self.corner + a * self.edge_u + b * self.edge_v
    }

    /// The t in `range` at which o + t·d meets the parallelogram (edges included), from either side.
    #[inline]
    pub fn hit(&self, o: Vec3, d: Vec3, range: impl RangeBounds<f32>) -> Option<f32> {
        let t = plane_hit(o, d, self.corner, self.normal)?;
        if !range.contains(&t) {
            return None;
        }
        let rel = o + t * d - self.corner;
        let (a, b) = (rel.dot(self.dual_u), rel.dot(self.dual_v));
        ((0.0..=1.0).contains(&a) && (0.0..=1.0).contains(&b)).then_some(t)
    }
}

/// A disk.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Disk {
    /// Centre.
    pub center: Vec3,
    /// Unit normal.
    pub normal: Vec3,
    /// Radius, > 0.
    pub radius: f32,
}

impl Disk {
    /// The t in `range` at which o + t·d meets the disk (rim included), from either side.
    #[inline]
    pub fn hit(&self, o: Vec3, d: Vec3, range: impl RangeBounds<f32>) -> Option<f32> {
        let t = plane_hit(o, d, self.center, self.normal)?;
        let inside = (o + t * d - self.center).length_squared() <= self.radius * self.radius;
        (inside && range.contains(&t)).then_some(t)
    }
}

/// A sphere.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    /// Centre.
    pub center: Vec3,
    /// Radius, > 0.
    pub radius: f32,
}

impl Sphere {
    /// Both roots t₀ ≤ t₁ of |o + t·w − c|² = r² for unit `w`, or `None` if the line misses. The discriminant is
    /// computed from the perpendicular distance (r² − |f − (f·w)w|², f = o − c) and the roots in the stable form
    /// q = −b − sign(b)√Δ, t = q and c/q (Haines et al., Ray Tracing Gems ch. 7).
    #[inline]
    pub fn roots(&self, o: Vec3, w: Vec3) -> Option<(f32, f32)> {
        let f = o - self.center;
        let b = f.dot(w);
        let perp = f - b * w;
        let disc = self.radius * self.radius - perp.length_squared();
        // Also rejects NaN.
        if disc.is_nan() || disc < 0.0 {
            return None;
        }
        let c = (f.length() - self.radius) * (f.length() + self.radius);
        let q = -b - disc.sqrt().copysign(b);
        let (t0, t1) = if q != 0.0 { (q, c / q) } else { (0.0, 0.0) };
        let (t0, t1) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
        (t0.is_finite() && t1.is_finite()).then_some((t0, t1))
    }

    /// The nearest root in `range` of the ray o + t·w (`w` unit) with the sphere, from outside or inside.
    #[inline]
    pub fn hit(&self, o: Vec3, w: Vec3, range: impl RangeBounds<f32>) -> Option<f32> {
        let (t0, t1) = self.roots(o, w)?;
        [t0, t1].into_iter().find(|t| range.contains(t))
    }

    /// The outward unit normal at a point `q` on the sphere (zero at the centre).
    #[inline]
    pub fn normal_at(&self, q: Vec3) -> Vec3 {
        (q - self.center).normalize_or_zero()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const INF: f32 = f32::INFINITY;

    /// The square [0, 2]² in the plane y = 1; edge_u × edge_v = z × x = +y.
    fn square() -> Parallelogram {
        Parallelogram::new(Vec3::Y, 2.0 * Vec3::Z, 2.0 * Vec3::X).unwrap()
    }

    #[test]
    fn plane_hits_from_both_sides_and_not_along_it() {
        let (point, n) = (Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 3.0, 0.0));
        assert_eq!(plane_hit(Vec3::ZERO, Vec3::Y, point, n), Some(1.0));
        // Back face: from above, looking down.
        assert_eq!(
            plane_hit(Vec3::new(5.0, 3.0, -2.0), -Vec3::Y, point, n),
            Some(2.0)
        );
        // t in units of |d|, and behind the origin too (the caller's interval decides).
        assert_eq!(plane_hit(Vec3::ZERO, 4.0 * Vec3::Y, point, n), Some(0.25));
        assert_eq!(plane_hit(Vec3::ZERO, -Vec3::Y, point, n), Some(-1.0));
        // Parallel, in the plane, grazing so closely that t overflows: no hit.
        assert_eq!(plane_hit(Vec3::ZERO, Vec3::X, point, n), None);
        assert_eq!(plane_hit(point, Vec3::X, point, n), None);
        assert_eq!(
            plane_hit(Vec3::ZERO, Vec3::new(1.0, 1e-40, 0.0), point, n),
            None
        );
    }

    #[test]
    fn parallelogram_hits_inside_and_on_its_edges_only() {
        let q = square();
        assert_eq!(q.normal(), Vec3::Y);
        assert_eq!(q.area(), 4.0);
        assert_eq!(q.point(0.5, 0.25), Vec3::new(0.5, 1.0, 1.0));
        let down = |x: f32, z: f32| (Vec3::new(x, 3.0, z), -Vec3::Y);
        for (x, z) in [(1.0, 1.0), (0.0, 0.0), (2.0, 2.0), (0.0, 2.0), (1.5, 0.0)] {
            let (o, d) = down(x, z);
            assert_eq!(q.hit(o, d, 0.0..=INF), Some(2.0), "({x}, {z})");
        }
        for (x, z) in [
            (-0.01, 1.0),
            (2.01, 1.0),
            (1.0, -0.01),
            (1.0, 2.01),
            (3.0, 3.0),
        ] {
            let (o, d) = down(x, z);
            assert_eq!(q.hit(o, d, 0.0..=INF), None, "({x}, {z})");
        }
        // Back face: from below.
        assert_eq!(
            q.hit(Vec3::new(1.0, 0.0, 1.0), Vec3::Y, 0.0..=INF),
            Some(1.0)
        );
        // Oblique, with a long direction: t in units of |d|.
        let (o, d) = (Vec3::new(-1.0, 3.0, 1.0), Vec3::new(2.0, -2.0, 0.0));
        assert_eq!(q.hit(o, d, 0.0..=INF), Some(1.0));
        // Grazing: parallel to the plane (above it, or in it) misses.
        assert_eq!(q.hit(Vec3::new(-1.0, 1.5, 1.0), Vec3::X, 0.0..=INF), None);
        assert_eq!(q.hit(Vec3::new(-1.0, 1.0, 1.0), Vec3::X, 0.0..=INF), None);
    }

    #[test]
    fn parallelogram_that_is_not_a_rectangle() {
        // A sheared parallelogram in the plane z = 0: the points (x, y) with 0 ≤ y ≤ 1 and y ≤ x ≤ y + 1.
        let q = Parallelogram::new(Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0)).unwrap();
        assert_eq!(q.normal(), Vec3::Z);
        let hit = |x: f32, y: f32| q.hit(Vec3::new(x, y, -1.0), Vec3::Z, 0.0..=INF);
        assert_eq!(hit(1.5, 0.75), Some(1.0));
        assert_eq!(hit(0.25, 0.5), None);
        assert_eq!(hit(1.75, 0.5), None);
    }

    #[test]
    fn range_is_open_or_closed_as_asked() {
        let q = square();
        let (o, d) = (Vec3::new(1.0, 3.0, 1.0), -Vec3::Y);
        assert_eq!(q.hit(o, d, 0.0..=2.0), Some(2.0));
        assert_eq!(q.hit(o, d, open(0.0, 2.0)), None);
        assert_eq!(q.hit(o, d, open(0.0, 2.5)), Some(2.0));
        assert_eq!(q.hit(o, d, 2.0..=3.0), Some(2.0));
        assert_eq!(q.hit(o, d, open(2.0, 3.0)), None);
        assert_eq!(q.hit(o, d, 0.0..=1.9), None);
        // A NaN bound accepts nothing.
        assert_eq!(q.hit(o, d, f32::NAN..=INF), None);
        assert_eq!(q.hit(o, d, open(0.0, f32::NAN)), None);
        // Behind the origin.
        assert_eq!(q.hit(o, Vec3::Y, 0.0..=INF), None);
    }

    #[test]
    fn rays_starting_on_a_surface_meet_it_at_zero() {
        let q = square();
        let o = Vec3::new(1.0, 1.0, 1.0);
        assert_eq!(q.hit(o, Vec3::Y, 0.0..=INF), Some(0.0));
        assert_eq!(q.hit(o, Vec3::Y, open(0.0, INF)), None);
        let disk = Disk {
            center: Vec3::ZERO,
            normal: Vec3::Z,
            radius: 1.0,
        };
        assert_eq!(disk.hit(Vec3::X * 0.5, Vec3::Z, 0.0..=INF), Some(0.0));
        assert_eq!(disk.hit(Vec3::X * 0.5, Vec3::Z, open(0.0, INF)), None);
        // On a sphere, leaving it: the root at 0 only.
        let s = Sphere {
            center: Vec3::ZERO,
            radius: 1.0,
        };
        assert_eq!(s.roots(Vec3::X, Vec3::X), Some((-2.0, 0.0)));
        assert_eq!(s.hit(Vec3::X, Vec3::X, 0.0..=INF), Some(0.0));
        assert_eq!(s.hit(Vec3::X, Vec3::X, open(0.0, INF)), None);
        // Entering it: the far side.
        assert_eq!(s.hit(Vec3::X, -Vec3::X, open(0.0, INF)), Some(2.0));
    }

    #[test]
    fn degenerate_parallelograms_are_refused() {
        assert!(Parallelogram::new(Vec3::ZERO, Vec3::X, 2.0 * Vec3::X).is_none());
        assert!(Parallelogram::new(Vec3::NAN, Vec3::X, Vec3::Y).is_none());
        assert!(Parallelogram::new(Vec3::ZERO, Vec3::INFINITY, Vec3::Y).is_none());
        assert!(Parallelogram::new(Vec3::ZERO, 1e30 * Vec3::X, 1e30 * Vec3::Y).is_none());
        // Too small for its dual basis to be finite, and then it could never be hit.
        assert!(Parallelogram::new(Vec3::ZERO, 1e-10 * Vec3::X, 1e-10 * Vec3::Y).is_none());
        assert!(Parallelogram::new(Vec3::ZERO, 1e-9 * Vec3::X, 1e-9 * Vec3::Y).is_some());
    }

    #[test]
    fn disk_hits_inside_its_rim_from_both_sides() {
        let disk = Disk {
            center: Vec3::new(0.0, 2.0, 0.0),
            normal: -Vec3::Y,
            radius: 1.0,
        };
        assert_eq!(
            disk.hit(Vec3::new(0.5, 0.0, 0.5), Vec3::Y, 0.0..=INF),
            Some(2.0)
        );
        assert_eq!(
            disk.hit(Vec3::new(0.5, 4.0, 0.5), -Vec3::Y, 0.0..=INF),
            Some(2.0)
        );
        // On the rim; just outside it.
        assert_eq!(
            disk.hit(Vec3::new(0.6, 0.0, 0.8), Vec3::Y, 0.0..=INF),
            Some(2.0)
        );
        assert_eq!(disk.hit(Vec3::new(0.8, 0.0, 0.8), Vec3::Y, 0.0..=INF), None);
        // Grazing, behind, out of range.
        assert_eq!(
            disk.hit(Vec3::new(0.0, 2.0, -2.0), Vec3::Z, 0.0..=INF),
            None
        );
        assert_eq!(disk.hit(Vec3::ZERO, -Vec3::Y, 0.0..=INF), None);
        assert_eq!(disk.hit(Vec3::ZERO, Vec3::Y, open(0.0, 2.0)), None);
    }

    #[test]
    fn sphere_hits_the_nearest_root_in_range() {
        let s = Sphere {
            center: Vec3::new(0.0, 0.0, 5.0),
            radius: 1.0,
        };
        assert_eq!(s.roots(Vec3::ZERO, Vec3::Z), Some((4.0, 6.0)));
        assert_eq!(s.hit(Vec3::ZERO, Vec3::Z, 0.0..=INF), Some(4.0));
        // Past the near root: the far one, seen from inside.
        assert_eq!(s.hit(Vec3::ZERO, Vec3::Z, 4.5..=INF), Some(6.0));
        assert_eq!(s.hit(Vec3::ZERO, Vec3::Z, 0.0..=3.9), None);
        assert_eq!(s.hit(Vec3::ZERO, Vec3::Z, open(4.0, 6.0)), None);
        // From inside: one root behind, one ahead.
        let inside = Vec3::new(0.0, 0.0, 5.5);
        assert_eq!(s.roots(inside, Vec3::Z), Some((-1.5, 0.5)));
        assert_eq!(s.hit(inside, Vec3::Z, 0.0..=INF), Some(0.5));
        // Behind the origin, and a clear miss.
        assert_eq!(s.hit(Vec3::ZERO, -Vec3::Z, 0.0..=INF), None);
        assert_eq!(s.roots(Vec3::ZERO, Vec3::X), None);
        // Grazing: tangent to the sphere, a double root at the tangent point; just past it, a miss.
        let (t0, t1) = s.roots(Vec3::new(1.0, 0.0, 0.0), Vec3::Z).unwrap();
        assert!(
            (t0 - 5.0).abs() < 1e-6 && (t1 - 5.0).abs() < 1e-6,
            "{t0} {t1}"
        );
        assert_eq!(s.roots(Vec3::new(1.0001, 0.0, 0.0), Vec3::Z), None);
        assert_eq!(s.normal_at(Vec3::new(0.0, 1.0, 5.0)), Vec3::Y);
        assert_eq!(s.normal_at(s.center), Vec3::ZERO);
    }

    #[test]
    fn non_finite_rays_never_hit() {
        let q = square();
        let disk = Disk {
            center: Vec3::ZERO,
            normal: Vec3::Y,
            radius: 1.0,
        };
        let s = Sphere {
            center: Vec3::ZERO,
            radius: 1.0,
        };
        for (o, d) in [
            (Vec3::NAN, -Vec3::Y),
            (Vec3::new(1.0, 3.0, 1.0), Vec3::NAN),
            (Vec3::new(1.0, 3.0, 1.0), Vec3::ZERO),
            (Vec3::INFINITY, -Vec3::Y),
        ] {
            assert_eq!(q.hit(o, d, 0.0..=INF), None, "{o} {d}");
            assert_eq!(disk.hit(o, d, 0.0..=INF), None, "{o} {d}");
            assert_eq!(s.hit(o, d, 0.0..=INF), None, "{o} {d}");
        }
    }
}
