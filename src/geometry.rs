//! Ray–primitive hits, written once for every caller: the plane, the parallelogram (the [`crate::shape::Quad`]s
//! and quad lights), the disk and the sphere (disk and sphere lights), and the watertight triangle (the meshes of
//! `accel::mesh`'s Rust backend).
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

/// Where a ray meets a triangle: the distance and the barycentrics of the hit point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriangleHit {
    /// Ray parameter of the hit, in units of |d|.
    pub t: f32,
    /// Barycentric weight of the second corner `b`.
    pub u: f32,
    /// Barycentric weight of the third corner `c`; the point is a + u (b − a) + v (c − a) (Embree's convention).
    pub v: f32,
}

/// γₙ = nε / (1 − nε) with ε = 2⁻²⁴: the relative error bound of n rounded operations (pbrt-v4 eq. 6.11).
#[inline]
fn gamma(n: f32) -> f32 {
    let e = 0.5 * f32::EPSILON;
    n * e / (1.0 - n * e)
}

/// The hit in the open interval (`t_min`, `t_max`) of the ray o + t·d (any non-zero `d`) with the triangle
/// (`a`, `b`, `c`), from either side: Woop, Benthin & Wald 2013, "Watertight Ray/Triangle Intersection" (JCGT
/// 2(1)), with pbrt-v4's conservative bound on t (§6.5.3).
///
/// The test moves the ray to the origin and shears space so that the ray becomes the +z axis; whether the axis
/// passes inside the triangle is then the sign of three 2-D edge functions. Every corner is transformed
/// identically whichever triangle it belongs to, and an edge function depends only on its edge's two corners, so
/// two triangles sharing an edge see the same edge function (with opposite signs): a ray through the edge hits at
/// least one of them (no cracks) and, since an edge function of exactly 0 counts as inside, may hit both. A
/// degenerate triangle ([`triangle_is_degenerate`]) is never hit.
#[inline]
pub fn triangle_hit(
    o: Vec3,
    d: Vec3,
    [a, b, c]: [Vec3; 3],
    t_min: f32,
    t_max: f32,
) -> Option<TriangleHit> {
    if triangle_is_degenerate([a, b, c]) {
        return None;
    }
    // Translate: the ray starts at the origin.
    let (a, b, c) = (a - o, b - o, c - o);
    // Permute: the direction's largest component becomes z (so the shear below divides by the largest |dᵢ|),
    // keeping the axes' cyclic order so that the edge functions' signs keep their meaning.
    let kz = d.abs().max_position();
    let (kx, ky) = ((kz + 1) % 3, (kz + 2) % 3);
    let permute = |p: Vec3| Vec3::new(p[kx], p[ky], p[kz]);
    let (d, a, b, c) = (permute(d), permute(a), permute(b), permute(c));
    // Shear (WBW13 eq. 2): x' = x − (dx/dz) z, y' = y − (dy/dz) z, so that d becomes (0, 0, dz). z is scaled by 1/dz
    // only after the edge functions, which read x' and y' alone.
    let (sx, sy, sz) = (-d.x / d.z, -d.y / d.z, 1.0 / d.z);
    let shear = |p: Vec3| Vec3::new(p.x + sx * p.z, p.y + sy * p.z, p.z);
    let (a, b, c) = (shear(a), shear(b), shear(c));
    // 2-D edge functions (WBW13 eq. 3): e_a = b × c, e_b = c × a, e_c = a × b in the sheared xy plane; each is
    // twice the signed area that the ray's axis and one edge span, i.e. the unnormalised barycentric weight of the
    // opposite corner.
    let edge = |p: Vec3, q: Vec3| difference_of_products(p.x, q.y, p.y, q.x);
    let (mut e_a, mut e_b, mut e_c) = (edge(b, c), edge(c, a), edge(a, b));
    // An edge function of exactly 0 in f32 may have its sign decided by rounding: recompute it in f64, where the
    // product of two f32s is exact (WBW13 §3.1), so that the neighbours across the edge agree on its sign.
    if e_a == 0.0 || e_b == 0.0 || e_c == 0.0 {
        let edge64 = |p: Vec3, q: Vec3| {
            (f64::from(p.x) * f64::from(q.y) - f64::from(p.y) * f64::from(q.x)) as f32
        };
        (e_a, e_b, e_c) = (edge64(b, c), edge64(c, a), edge64(a, b));
    }
    // The axis passes inside (or on the boundary) when no two edge functions have opposite signs: two-sided, so
    // both all-non-negative and all-non-positive count (WBW13 §3, no back-face culling).
    let negative = e_a < 0.0 || e_b < 0.0 || e_c < 0.0;
    let positive = e_a > 0.0 || e_b > 0.0 || e_c > 0.0;
    if negative && positive {
        return None;
    }
    // The determinant: twice the sheared triangle's signed area. 0 when the ray lies in the triangle's plane.
    let det = e_a + e_b + e_c;
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    // Scaled hit distance (WBW13 eq. 5): t · det = Σ eᵢ zᵢ / dz, compared against the interval times det so that
    // nothing is divided before the hit is known to be in range.
    let (za, zb, zc) = (a.z * sz, b.z * sz, c.z * sz);
    let t_scaled = e_a * za + e_b * zb + e_c * zc;
    let inside = if det < 0.0 {
        t_scaled < t_min * det && t_scaled > t_max * det
    } else {
        t_scaled > t_min * det && t_scaled < t_max * det
    };
    if !inside {
        return None;
    }
    let inv_det = 1.0 / det;
    let t = t_scaled * inv_det;
    // The conservative lower bound on t (pbrt-v4 §6.5.3): bounding the rounding error of z, x, y, the edge
    // functions and t itself keeps a hit whose true distance is ≤ 0 from being reported at a small positive t, the
    // self-intersection of a ray leaving the triangle.
    let max_z = za.abs().max(zb.abs()).max(zc.abs());
    let max_x = a.x.abs().max(b.x.abs()).max(c.x.abs());
    let max_y = a.y.abs().max(b.y.abs()).max(c.y.abs());
    let delta_z = gamma(3.0) * max_z;
    let delta_x = gamma(5.0) * (max_x + max_z);
    let delta_y = gamma(5.0) * (max_y + max_z);
    let delta_e = 2.0 * (gamma(2.0) * max_x * max_y + delta_y * max_x + delta_x * max_y);
    let max_e = e_a.abs().max(e_b.abs()).max(e_c.abs());
    let delta_t =
        3.0 * (gamma(3.0) * max_e * max_z + delta_e * max_z + delta_z * max_e) * inv_det.abs();
    if t <= delta_t || !(t > t_min && t < t_max) {
        return None;
    }
    // Barycentrics: the edge functions over their sum; the weights of b and c are Embree's (u, v).
    Some(TriangleHit {
        t,
        u: e_b * inv_det,
        v: e_c * inv_det,
    })
}

/// Whether a triangle has no surface to hit: a corner that is not finite, or (b − a) × (c − a) exactly zero (two
/// corners equal, or all three on a line as far as f32 can tell). Both mesh backends leave such triangles out.
#[inline]
pub fn triangle_is_degenerate([a, b, c]: [Vec3; 3]) -> bool {
    !(a.is_finite() && b.is_finite() && c.is_finite()) || (b - a).cross(c - a) == Vec3::ZERO
}

/// a·b − c·d with one rounding of the difference's error (Kahan's algorithm, as pbrt-v4's `DifferenceOfProducts`):
/// the edge functions of nearly parallel edges keep their sign.
#[inline]
fn difference_of_products(a: f32, b: f32, c: f32, d: f32) -> f32 {
    let cd = c * d;
    let dop = a.mul_add(b, -cd);
    let err = (-c).mul_add(d, cd);
    dop + err
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

    /// The triangle (0,0,0), (2,0,0), (0,2,0) in the plane z = 1, its normal along +z.
    fn triangle() -> [Vec3; 3] {
        [Vec3::Z, Vec3::new(2.0, 0.0, 1.0), Vec3::new(0.0, 2.0, 1.0)]
    }

    #[test]
    fn triangle_hits_report_t_and_embree_barycentrics_from_both_sides() {
        let tri = triangle();
        let [a, b, c] = tri;
        for (x, y) in [(0.5, 0.5), (0.1, 1.7), (1.9, 0.05), (0.0, 0.0), (1.0, 1.0)] {
            let target = Vec3::new(x, y, 1.0);
            for (o, d) in [
                (Vec3::new(x, y, -3.0), Vec3::Z),
                (Vec3::new(x, y, 5.0), -2.0 * Vec3::Z),
                (
                    Vec3::new(-1.0, 3.0, 4.0),
                    target - Vec3::new(-1.0, 3.0, 4.0),
                ),
            ] {
                let hit = triangle_hit(o, d, tri, 0.0, INF).unwrap_or_else(|| panic!("{o} {d}"));
                let p = a + hit.u * (b - a) + hit.v * (c - a);
                assert!((p - target).length() < 1e-5, "{o} {d}: {hit:?} -> {p}");
                assert!((o + hit.t * d - target).length() < 1e-5, "{o} {d}: {hit:?}");
                assert!(hit.u >= 0.0 && hit.v >= 0.0 && hit.u + hit.v <= 1.0 + 1e-6);
            }
        }
        // Outside each edge, and the plane behind the origin.
        for (x, y) in [(-0.01, 0.5), (0.5, -0.01), (1.01, 1.0), (3.0, 3.0)] {
            let o = Vec3::new(x, y, -3.0);
            assert_eq!(triangle_hit(o, Vec3::Z, tri, 0.0, INF), None, "{o}");
        }
        assert_eq!(
            triangle_hit(Vec3::new(0.5, 0.5, 3.0), Vec3::Z, tri, 0.0, INF),
            None
        );
        // In the triangle's plane: no hit.
        assert_eq!(
            triangle_hit(Vec3::new(-1.0, 0.5, 1.0), Vec3::X, tri, 0.0, INF),
            None
        );
    }

    #[test]
    fn triangle_hits_lie_in_the_open_interval() {
        let tri = triangle();
        let (o, d) = (Vec3::new(0.5, 0.5, -1.0), Vec3::Z);
        assert_eq!(triangle_hit(o, d, tri, 0.0, INF).map(|h| h.t), Some(2.0));
        assert_eq!(triangle_hit(o, d, tri, 0.0, 2.0), None);
        assert_eq!(triangle_hit(o, d, tri, 2.0, 3.0), None);
        assert_eq!(triangle_hit(o, d, tri, 0.0, 1.9), None);
        assert_eq!(triangle_hit(o, d, tri, 2.1, INF), None);
        assert!(triangle_hit(o, d, tri, 1.999, 2.001).is_some());
        // A ray leaving the triangle's surface does not meet it again just past its origin.
        let on = Vec3::new(0.3, 0.4, 1.0);
        assert_eq!(
            triangle_hit(on, Vec3::new(0.1, 0.2, 1.0), tri, 0.0, INF),
            None
        );
        assert_eq!(
            triangle_hit(on, Vec3::new(0.1, 0.2, -1.0), tri, 0.0, INF),
            None
        );
        // A NaN bound accepts nothing.
        assert_eq!(triangle_hit(o, d, tri, f32::NAN, INF), None);
        assert_eq!(triangle_hit(o, d, tri, 0.0, f32::NAN), None);
    }

    #[test]
    fn degenerate_triangles_are_never_hit() {
        let (p, q) = (Vec3::new(0.0, 0.0, 1.0), Vec3::new(2.0, 2.0, 1.0));
        let m = 0.5 * (p + q);
        for tri in [
            [p, q, m],
            [p, p, q],
            [p, p, p],
            [p, q, Vec3::NAN],
            [p, q, Vec3::INFINITY],
        ] {
            assert!(triangle_is_degenerate(tri), "{tri:?}");
            // Rays through the segment's points, across it and along it.
            for (o, d) in [
                (Vec3::new(1.0, 1.0, -1.0), Vec3::Z),
                (Vec3::new(0.5, 0.5, 0.0), Vec3::new(0.5, 0.5, 1.0)),
                (Vec3::new(-1.0, -1.0, 1.0), Vec3::new(1.0, 1.0, 0.0)),
            ] {
                assert_eq!(triangle_hit(o, d, tri, 0.0, INF), None, "{tri:?} {o} {d}");
            }
        }
        assert!(!triangle_is_degenerate(triangle()));
    }

    #[test]
    fn a_ray_through_a_shared_edge_or_vertex_hits_a_neighbour() {
        // The square [0, 2]² at z = 1 as two triangles sharing the diagonal (0,0)–(2,2), wound alike.
        let (p00, p20, p22, p02) = (
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(2.0, 0.0, 1.0),
            Vec3::new(2.0, 2.0, 1.0),
            Vec3::new(0.0, 2.0, 1.0),
        );
        let tris = [[p00, p20, p22], [p00, p22, p02]];
        let o = Vec3::new(0.3, -0.7, -2.5);
        for k in 0..=64 {
            let target = p00 + (k as f32 / 64.0) * (p22 - p00);
            let d = target - o;
            let hits = tris
                .iter()
                .filter(|&&tri| triangle_hit(o, d, tri, 0.0, INF).is_some())
                .count();
            assert!(hits >= 1, "edge point {target}: no hit");
        }
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
            assert_eq!(triangle_hit(o, d, triangle(), 0.0, INF), None, "{o} {d}");
        }
    }
}
