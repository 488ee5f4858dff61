//! Area lights: a quad (parallelogram), a disk or a sphere of uniform radiance.
//!
//! Parameters (scene units; radiance RGB, W m⁻² sr⁻¹, ≥ 0):
//! - `Quad { corner, edge_u, edge_v }`: the points corner + a·edge_u + b·edge_v, a, b ∈ [0, 1]; normal
//!   n = normalize(edge_u × edge_v) (edges must not be parallel).
//! - `Disk { center, normal, radius }`: radius > 0, `normal` of any non-zero length.
//! - `Sphere { center, radius }`: radius > 0, normal pointing outwards.
//!
//! A quad or disk emits on the side its normal points to unless `two_sided`; a sphere emits outwards (and, if
//! `two_sided`, inwards too — only a point inside it sees that).
//!
//! Sampling (pbrt-v3 §14.2.2): quads and disks are sampled uniformly by area, and the area density 1/A is
//! turned into a density per unit solid angle at the shading point p:
//!
//! p_ω = dist² / (|cos θ_light| · A),
//!
//! with θ_light between the light's normal and the direction back to p. A sphere seen from outside is sampled
//! uniformly inside the cone of directions it subtends (sin²θ_max = r²/d²), which is exact and has much lower
//! variance than area sampling; from inside (or on) the sphere every surface point is visible, so it falls back
//! to uniform area sampling. [`AreaLight::pdf_li`] is the exact density of [`AreaLight::sample_li`] for the
//! direction given (found by intersecting the ray from p along it with the light), and 0 where the sampler cannot
//! produce the direction. The ray–surface hits themselves are [`crate::geometry`]'s, shared with the shapes.

use std::f32::consts::PI;

use glam::Vec3;

use super::cone::Cone;
use super::{check, check_color, check_direction, clamp_u, unit, LightError, LightSample};
use crate::ray::Ray;
use crate::util::color::luminance;
use crate::util::sampling::uniform_sphere;

use crate::geometry::{Disk, Parallelogram, Sphere};

/// The geometry of an [`AreaLight`] (world space).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// The parallelogram corner + a·edge_u + b·edge_v, a, b ∈ [0, 1]; front side along edge_u × edge_v.
    Quad {
        /// One corner.
        corner: Vec3,
        /// The first edge from `corner`.
        edge_u: Vec3,
        /// The second edge from `corner`.
        edge_v: Vec3,
    },
    /// A disk; front side along `normal`.
    Disk {
        /// Centre.
        center: Vec3,
        /// Normal of the front side (any non-zero length).
        normal: Vec3,
        /// Radius, > 0.
        radius: f32,
    },
    /// A sphere; front side outwards.
    Sphere {
        /// Centre.
        center: Vec3,
        /// Radius, > 0.
        radius: f32,
    },
}

impl Shape {
    /// The centre: of the parallelogram, the disk or the sphere.
    pub fn center(&self) -> Vec3 {
        match *self {
            Shape::Quad {
                corner,
                edge_u,
                edge_v,
            } => corner + 0.5 * (edge_u + edge_v),
            Shape::Disk { center, .. } | Shape::Sphere { center, .. } => center,
        }
    }
}

/// An emitter of uniform radiance (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct AreaLight {
    shape: Shape,
    geometry: Geometry,
    radiance: Vec3,
    two_sided: bool,
    /// Surface area A.
    area: f32,
}

/// Derived geometry, computed once in [`AreaLight::new`].
#[derive(Debug, Clone, Copy, PartialEq)]
enum Geometry {
    Quad(Parallelogram),
    Disk {
        disk: Disk,
        /// Two unit tangents completing the disk's normal to an orthonormal frame.
        t: Vec3,
        b: Vec3,
    },
    Sphere(Sphere),
}

/// Checks a position: every component finite.
fn check_point(light: &'static str, key: &'static str, v: Vec3) -> Result<(), LightError> {
    let bad = v
        .to_array()
        .into_iter()
        .find(|x| !x.is_finite())
        .unwrap_or(0.0);
    check(light, key, bad, "finite", v.is_finite())
}

/// Checks a radius: finite and > 0.
fn check_radius(light: &'static str, radius: f32) -> Result<(), LightError> {
    check(
        light,
        "radius",
        radius,
        "> 0 and finite",
        radius > 0.0 && radius.is_finite(),
    )
}

impl AreaLight {
    /// An emitter of `shape` with uniform `radiance` (RGB, finite, ≥ 0), on one side or, if `two_sided`, both.
    pub fn new(shape: Shape, radiance: Vec3, two_sided: bool) -> Result<AreaLight, LightError> {
        let (light, geometry, area) = match shape {
            Shape::Quad {
                corner,
                edge_u,
                edge_v,
            } => {
                check_point("quad", "corner", corner)?;
                check_point("quad", "edge_u", edge_u)?;
                check_point("quad", "edge_v", edge_v)?;
                let quad = Parallelogram::new(corner, edge_u, edge_v);
                check(
                    "quad",
                    "|edge_u x edge_v|",
                    edge_u.cross(edge_v).length(),
                    "> 0 and finite (edges not parallel)",
                    quad.is_some(),
                )?;
                let quad = quad.expect("checked just above");
                ("quad", Geometry::Quad(quad), quad.area())
            }
            Shape::Disk {
                center,
                normal,
                radius,
            } => {
                check_point("disk", "center", center)?;
                let n = check_direction("disk", "normal", normal)?;
                check_radius("disk", radius)?;
                let (t, b) = n.any_orthonormal_pair();
                let geometry = Geometry::Disk {
                    disk: Disk {
                        center,
                        normal: n,
                        radius,
                    },
                    t,
                    b,
                };
                ("disk", geometry, PI * radius * radius)
            }
            Shape::Sphere { center, radius } => {
                check_point("sphere", "center", center)?;
                check_radius("sphere", radius)?;
                (
                    "sphere",
                    Geometry::Sphere(Sphere { center, radius }),
                    4.0 * PI * radius * radius,
                )
            }
        };
        check_color(light, "radiance", radiance)?;
        check(
            light,
            "area",
            area,
            "finite",
            area.is_finite() && area > 0.0,
        )?;
        Ok(AreaLight {
            shape,
            geometry,
            radiance,
            two_sided,
            area,
        })
    }

    /// The shape, as given.
    pub fn shape(&self) -> Shape {
        self.shape
    }

    /// The emitted radiance L.
    pub fn radiance(&self) -> Vec3 {
        self.radiance
    }

    /// Whether quads and disks emit on both sides (spheres: also inwards).
    pub fn two_sided(&self) -> bool {
        self.two_sided
    }

    /// Surface area A.
    pub fn area(&self) -> f32 {
        self.area
    }

    /// Emitted power as luminance: π · A · luminance(L), doubled for two-sided quads and disks (a sphere's
    /// inside emission never leaves it).
    pub fn power(&self) -> f32 {
        let sides = match self.geometry {
            Geometry::Sphere(_) => 1.0,
            _ if self.two_sided => 2.0,
            _ => 1.0,
        };
        sides * PI * self.area * luminance(self.radiance)
    }

    /// A direction from `p` towards the light (see the module docs for the strategy). `None` when the sampled point
    /// coincides with `p` or is seen edge-on (`p` in a quad's or disk's plane), when `p` is behind a one-sided quad
    /// or disk or inside (or on) a one-sided sphere, and when `p` is not finite.
    #[inline]
    pub fn sample_li(&self, p: Vec3, u: [f32; 2]) -> Option<LightSample> {
        if !p.is_finite() {
            return None;
        }
        let u = clamp_u(u);
        let q = match self.geometry {
            Geometry::Quad(quad) => quad.point(u[0], u[1]),
            Geometry::Disk { disk, t, b } => {
                // Uniform by area: r = R √u₀.
                let r = disk.radius * u[0].sqrt();
                let (sin_phi, cos_phi) = (std::f32::consts::TAU * u[1]).sin_cos();
                disk.center + r * (cos_phi * t + sin_phi * b)
            }
            Geometry::Sphere(Sphere { center, radius }) => {
                let oc = center - p;
                let d2 = oc.length_squared();
                let r2 = radius * radius;
                if d2 > r2 {
                    return self.sample_sphere_cone(p, oc, d2, r2, u);
                }
                center + radius * uniform_sphere(u[0], u[1])
            }
        };
        let to_q = q - p;
        let dist2 = to_q.length_squared();
        let dist = dist2.sqrt();
        let wi = to_q / dist;
        if !(dist2 > 0.0 && wi.is_finite()) {
            return None;
        }
        let cos_light = -self.normal_at(q).dot(wi);
        if !self.emits(cos_light) {
            return None;
        }
        // p_ω = dist² / (|cos θ_light| A).
        let pdf = dist2 / (cos_light.abs() * self.area);
        if !(pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        Some(LightSample {
            wi,
            radiance: self.radiance,
            pdf,
            distance: dist,
            delta: false,
        })
    }

    /// A sphere seen from outside (d² > r²): a direction uniform in the cone it subtends.
    #[inline]
    fn sample_sphere_cone(
        &self,
        p: Vec3,
        oc: Vec3,
        d2: f32,
        r2: f32,
        u: [f32; 2],
    ) -> Option<LightSample> {
        let cone = Cone::from_sin2(oc / d2.sqrt(), r2 / d2);
        let pdf = cone.pdf();
        if pdf <= 0.0 {
            return None;
        }
        let wi = cone.sample(u);
        let distance = match self.hit(p, wi, 0.0, f32::INFINITY) {
            Some(t) => t,
            // A direction on the rim may miss by rounding: take the tangent point's distance.
            None => oc.dot(wi).max(0.0),
        };
        Some(LightSample {
            wi,
            radiance: self.radiance,
            pdf,
            distance,
            delta: false,
        })
    }

    /// The density per unit solid angle with which [`AreaLight::sample_li`] at `p` draws `wi` (any non-zero
    /// length). 0 when the ray from `p` along `wi` misses the light or reaches a side that does not emit.
    #[inline]
    pub fn pdf_li(&self, p: Vec3, wi: Vec3) -> f32 {
        let Some(w) = unit(wi) else {
            return 0.0;
        };
        if !p.is_finite() {
            return 0.0;
        }
        if let Geometry::Sphere(Sphere { center, radius }) = self.geometry {
            let oc = center - p;
            let (d2, r2) = (oc.length_squared(), radius * radius);
            if d2 > r2 {
                let cone = Cone::from_sin2(oc / d2.sqrt(), r2 / d2);
                return if cone.contains(w) { cone.pdf() } else { 0.0 };
            }
        }
        let Some(t) = self.hit(p, w, 0.0, f32::INFINITY) else {
            return 0.0;
        };
        let cos_light = -self.normal_at(p + t * w).dot(w);
        if t <= 0.0 || !self.emits(cos_light) {
            return 0.0;
        }
        let pdf = t * t / (cos_light.abs() * self.area);
        if pdf.is_finite() {
            pdf
        } else {
            0.0
        }
    }

    /// The nearest hit of `ray` with the light in [tnear, tfar]: (t, radiance leaving the light towards the ray's
    /// origin). The emitter is opaque: a hit on a side that does not emit is reported with radiance 0.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<(f32, Vec3)> {
        let len = ray.dir.length();
        let w = unit(ray.dir)?;
        if !ray.origin.is_finite() {
            return None;
        }
        // Work with the unit direction: t_unit = t · |dir|.
        let t_unit = self.hit(ray.origin, w, ray.tnear * len, ray.tfar * len)?;
        let t = t_unit / len;
        if !(t >= ray.tnear && t <= ray.tfar) {
            return None;
        }
        let cos_light = -self.normal_at(ray.origin + t_unit * w).dot(w);
        let radiance = if self.emits(cos_light) {
            self.radiance
        } else {
            Vec3::ZERO
        };
        Some((t, radiance))
    }

    /// Whether the side seen at cos θ_light (normal · direction back to the viewer) emits.
    #[inline]
    fn emits(&self, cos_light: f32) -> bool {
        cos_light > 0.0 || (self.two_sided && cos_light < 0.0)
    }

    /// The unit normal at a point `q` of the light (outwards for a sphere).
    #[inline]
    fn normal_at(&self, q: Vec3) -> Vec3 {
        match self.geometry {
            Geometry::Quad(quad) => quad.normal(),
            Geometry::Disk { disk, .. } => disk.normal,
            Geometry::Sphere(sphere) => sphere.normal_at(q),
        }
    }

    /// The nearest t ∈ [t_min, t_max] at which o + t·w (w unit) meets the light's surface.
    #[inline]
    fn hit(&self, o: Vec3, w: Vec3, t_min: f32, t_max: f32) -> Option<f32> {
        match self.geometry {
            Geometry::Quad(quad) => quad.hit(o, w, t_min..=t_max),
            Geometry::Disk { disk, .. } => disk.hit(o, w, t_min..=t_max),
            Geometry::Sphere(sphere) => sphere.hit(o, w, t_min..=t_max),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light::Light;
    use glam::DVec3;
    use rand::Rng;
    use rand_pcg::Pcg32;

    /// Samples of each irradiance estimate: the area-sampled quad has a relative standard deviation per sample
    /// of ≈ 0.5, so 200 000 give a standard error ≈ 0.1 %, well inside the 1 % tolerance.
    const IRRADIANCE_SAMPLES: usize = 200_000;
    /// Tolerance of the irradiance estimates against the closed forms.
    const IRRADIANCE_TOLERANCE: f64 = 0.01;
    /// Quadrature grid (cos θ × φ) of the pdf integrals, per region: the rim cells, where the midpoint rule errs,
    /// are ≈ 1/N of the cap's cells, so the error is well below the 1 % tolerance.
    const PDF_GRID: usize = 800;
    /// Tolerance of ∫ pdf dω = 1.
    const PDF_TOLERANCE: f64 = 0.01;

    fn light(shape: Shape, two_sided: bool) -> Light {
        Light::Area(AreaLight::new(shape, Vec3::splat(1.5), two_sided).unwrap())
    }

    /// The mean and standard error of L · max(0, n·ωi) / pdf over `IRRADIANCE_SAMPLES` light samples at `p`.
    fn irradiance_estimate(l: &Light, p: Vec3, n: Vec3, seed: u64) -> (f64, f64) {
        let mut rng = Pcg32::new(seed, 17);
        let (mut sum, mut sum2) = (0.0f64, 0.0f64);
        for _ in 0..IRRADIANCE_SAMPLES {
            let x = match l.sample_li(p, rng.random()) {
                Some(s) => {
                    assert!(
                        (s.pdf - l.pdf_li(p, s.wi)).abs() <= 1e-3 * s.pdf,
                        "pdf {} vs pdf_li {}",
                        s.pdf,
                        l.pdf_li(p, s.wi)
                    );
                    (s.radiance.x * n.dot(s.wi).max(0.0) / s.pdf) as f64
                }
                None => 0.0,
            };
            sum += x;
            sum2 += x * x;
        }
        let n_f = IRRADIANCE_SAMPLES as f64;
        let mean = sum / n_f;
        (mean, ((sum2 / n_f - mean * mean).max(0.0) / n_f).sqrt())
    }

    fn assert_irradiance(name: &str, estimate: (f64, f64), reference: f64) {
        let (mean, se) = estimate;
        let rel = (mean - reference).abs() / reference;
        assert!(rel < IRRADIANCE_TOLERANCE, "{name}: {mean} vs {reference}");
        assert!(
            (mean - reference).abs() < 3.0 * se,
            "{name}: {mean} ± {se} vs {reference}"
        );
    }

    /// The irradiance from a Lambertian polygon of radiance `l` at `p` with normal `n` (Lambert 1760; e.g. Arvo
    /// 1995 eq. 2): E = L/2 Σ_k γ_k n·(a_k × b_k)/|a_k × b_k|, a_k, b_k unit vectors to consecutive vertices and
    /// γ_k the angle between them. The polygon must lie above the tangent plane.
    fn polygon_irradiance(vertices: &[DVec3], p: DVec3, n: DVec3, l: f64) -> f64 {
        let mut sum = 0.0;
        for k in 0..vertices.len() {
            let a = (vertices[k] - p).normalize();
            let b = (vertices[(k + 1) % vertices.len()] - p).normalize();
            let gamma = a.dot(b).clamp(-1.0, 1.0).acos();
            sum += gamma * n.dot(a.cross(b).normalize());
        }
        0.5 * l * sum.abs()
    }

    #[test]
    fn disk_on_axis_irradiance() {
        let (r, h) = (0.5f32, 0.7f32);
        let axis = Vec3::new(1.0, 2.0, 0.5).normalize();
        let p = Vec3::new(0.1, 0.8, -0.2);
        let l = light(
            Shape::Disk {
                center: p + h * axis,
                normal: -axis,
                radius: r,
            },
            false,
        );
        let reference = std::f64::consts::PI * 1.5 * (r * r) as f64 / (r * r + h * h) as f64;
        assert_irradiance("disk", irradiance_estimate(&l, p, axis, 1), reference);
    }

    #[test]
    fn sphere_irradiance_facing_centre() {
        let (r, d) = (0.6f32, 2.0f32);
        let axis = Vec3::new(-0.4, 0.3, 1.0).normalize();
        let p = Vec3::new(3.0, -1.0, 0.5);
        let l = light(
            Shape::Sphere {
                center: p + d * axis,
                radius: r,
            },
            false,
        );
        let reference = std::f64::consts::PI * 1.5 * ((r / d) as f64).powi(2);
        assert_irradiance("sphere", irradiance_estimate(&l, p, axis, 2), reference);
    }

    #[test]
    fn quad_irradiance_matches_polygon_formula() {
        let (corner, edge_u, edge_v) = (
            Vec3::new(-0.3, 1.0, -0.2),
            Vec3::new(1.0, 0.1, 0.0),
            Vec3::new(0.0, 0.2, 0.8),
        );
        // n = edge_u × edge_v points down (−y), towards p: the front side.
        let l = light(
            Shape::Quad {
                corner,
                edge_u,
                edge_v,
            },
            false,
        );
        let p = Vec3::new(0.2, 0.0, 0.1);
        let n = Vec3::new(0.3, 1.0, -0.2).normalize();
        let vertices = [
            corner,
            corner + edge_u,
            corner + edge_u + edge_v,
            corner + edge_v,
        ]
        .map(|v| v.as_dvec3());
        for v in vertices {
            assert!(
                n.as_dvec3().dot(v - p.as_dvec3()) > 0.0,
                "vertex below the tangent plane"
            );
        }
        let reference = polygon_irradiance(&vertices, p.as_dvec3(), n.as_dvec3(), 1.5);
        assert_irradiance("quad", irradiance_estimate(&l, p, n, 3), reference);
        // A one-sided quad seen from behind: nothing to sample, no pdf, a hit of radiance 0.
        let behind = Vec3::new(0.2, 2.0, 0.1);
        assert!(l.sample_li(behind, [0.5, 0.5]).is_none());
        let down = Vec3::new(0.0, -1.0, 0.1);
        assert_eq!(l.pdf_li(behind, down), 0.0);
        let (t, radiance) = l.intersect(&Ray::new(behind, down)).unwrap();
        assert!(t > 0.0 && radiance == Vec3::ZERO);
        // Two-sided: the same irradiance from behind as from the mirrored point in front.
        let two = light(
            Shape::Quad {
                corner,
                edge_u,
                edge_v,
            },
            true,
        );
        let up = Vec3::new(0.0, 1.0, 0.0);
        let (e_front, _) = irradiance_estimate(&two, Vec3::new(0.2, 0.0, 0.1), up, 4);
        assert!(e_front > 0.0);
        let (e_back, se) = irradiance_estimate(&two, behind, -up, 5);
        let reference = polygon_irradiance(&vertices, behind.as_dvec3(), -up.as_dvec3(), 1.5);
        assert!(
            (e_back - reference).abs() < 3.0 * se
                && (e_back / reference - 1.0).abs() < IRRADIANCE_TOLERANCE
        );
    }

    /// ∫ pdf_li(p, ω) dω by the midpoint rule in (cos θ, φ) around `axis`: `PDF_GRID²` cells on the cap cos θ ≥
    /// `cos_cap` and as many on the rest of the sphere. Returns (cap integral, rest integral).
    fn pdf_integral(l: &Light, p: Vec3, axis: Vec3, cos_cap: f64) -> (f64, f64) {
        let (t, b) = axis.any_orthonormal_pair();
        let region = |lo: f64, hi: f64| {
            let n = PDF_GRID;
            let mut sum = 0.0f64;
            for i in 0..n {
                let cos_t = lo + (hi - lo) * (i as f64 + 0.5) / n as f64;
                let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
                for j in 0..n {
                    let phi = std::f64::consts::TAU * (j as f64 + 0.5) / n as f64;
                    let w = (sin_t * phi.cos()) as f32 * t
                        + (sin_t * phi.sin()) as f32 * b
                        + cos_t as f32 * axis;
                    let pdf = l.pdf_li(p, w);
                    assert!(pdf.is_finite() && pdf >= 0.0);
                    sum += pdf as f64;
                }
            }
            sum * (hi - lo) * std::f64::consts::TAU / (n * n) as f64
        };
        (region(cos_cap, 1.0), region(-1.0, cos_cap))
    }

    /// The cosine of a cap around `axis` (seen from `p`) containing every point of `points`, padded by 5 %.
    fn cap_around(p: Vec3, axis: Vec3, points: impl IntoIterator<Item = Vec3>) -> f64 {
        let max_angle = points
            .into_iter()
            .map(|q| {
                ((q - p).normalize().dot(axis) as f64)
                    .clamp(-1.0, 1.0)
                    .acos()
            })
            .fold(0.0f64, f64::max);
        (max_angle * 1.05 + 0.01).min(std::f64::consts::PI).cos()
    }

    #[test]
    fn pdf_li_integrates_to_one_and_matches_samples() {
        // One piece: the same three shapes go through the integral and the sample histogram.
        let quad = Shape::Quad {
            corner: Vec3::new(-0.3, 1.0, -0.2),
            edge_u: Vec3::new(1.0, 0.1, 0.0),
            edge_v: Vec3::new(0.0, 0.2, 0.8),
        };
        let quad_points = [
            Vec3::new(-0.3, 1.0, -0.2),
            Vec3::new(0.7, 1.1, -0.2),
            Vec3::new(0.7, 1.3, 0.6),
            Vec3::new(-0.3, 1.2, 0.6),
        ];
        let disk_center = Vec3::new(0.5, 0.2, 1.0);
        let disk_normal = Vec3::new(0.2, -0.3, -1.0).normalize();
        let disk = Shape::Disk {
            center: disk_center,
            normal: disk_normal,
            radius: 0.4,
        };
        let (dt, db) = disk_normal.any_orthonormal_pair();
        let rim: Vec<Vec3> = (0..360)
            .map(|k| {
                let a = (k as f32).to_radians();
                disk_center + 0.4 * (a.cos() * dt + a.sin() * db)
            })
            .collect();
        let sphere = Shape::Sphere {
            center: Vec3::new(0.3, 0.4, 2.0),
            radius: 0.5,
        };
        let p = Vec3::new(0.2, 0.0, 0.1);
        let cases: Vec<(&str, Light, Vec3, Vec3, f64)> = vec![
            {
                let axis = (Vec3::new(0.2, 1.15, 0.2) - p).normalize();
                (
                    "quad, front",
                    light(quad, false),
                    p,
                    axis,
                    cap_around(p, axis, quad_points),
                )
            },
            {
                let q = Vec3::new(0.6, 2.5, 0.0);
                let axis = (Vec3::new(0.2, 1.15, 0.2) - q).normalize();
                (
                    "quad two-sided, back",
                    light(quad, true),
                    q,
                    axis,
                    cap_around(q, axis, quad_points),
                )
            },
            {
                let axis = (disk_center - p).normalize();
                (
                    "disk",
                    light(disk, false),
                    p,
                    axis,
                    cap_around(p, axis, rim.iter().copied()),
                )
            },
            {
                let axis = (Vec3::new(0.3, 0.4, 2.0) - p).normalize();
                let d = (Vec3::new(0.3, 0.4, 2.0) - p).length() as f64;
                let cos_cap = (0.5f64 / d).asin().mul_add(1.05, 0.01).cos();
                ("sphere, outside", light(sphere, false), p, axis, cos_cap)
            },
            (
                "sphere two-sided, inside",
                light(sphere, true),
                Vec3::new(0.4, 0.3, 2.2),
                Vec3::Y,
                -1.0,
            ),
        ];
        let mut rng = Pcg32::new(21, 5);
        for (name, l, p, axis, cos_cap) in cases {
            let (cap, rest) = pdf_integral(&l, p, axis, cos_cap);
            assert!(
                (cap + rest - 1.0).abs() < PDF_TOLERANCE,
                "{name}: ∫ pdf = {cap} + {rest}"
            );
            assert_eq!(rest, 0.0, "{name}: pdf outside the light's cap");
            for _ in 0..10_000 {
                let s = l.sample_li(p, rng.random()).unwrap();
                let pdf = l.pdf_li(p, s.wi);
                assert!(
                    (s.pdf - pdf).abs() <= 1e-3 * s.pdf,
                    "{name}: sample pdf {} vs pdf_li {pdf} at {}",
                    s.pdf,
                    s.wi
                );
                assert!((s.wi.length() - 1.0).abs() < 1e-5 && s.distance > 0.0 && !s.delta);
                // The shadow ray's end is on the light.
                let (t, radiance) = l
                    .intersect(&Ray::new(p, s.wi))
                    .expect("sampled direction misses");
                assert!(
                    (t - s.distance).abs() <= 1e-3 * s.distance,
                    "{name}: hit at {t}, sample at {}",
                    s.distance
                );
                assert_eq!(radiance, s.radiance);
            }
        }
    }

    #[test]
    fn intersect_honours_the_ray_interval_and_picks_the_right_root() {
        let sphere = light(
            Shape::Sphere {
                center: Vec3::new(0.0, 0.0, 5.0),
                radius: 1.0,
            },
            false,
        );
        // dir of length 2: t is in units of dir.
        let (t, l) = sphere
            .intersect(&Ray::new(Vec3::ZERO, Vec3::new(0.0, 0.0, 2.0)))
            .unwrap();
        assert!((t - 2.0).abs() < 1e-5 && l == Vec3::splat(1.5));
        assert!(sphere
            .intersect(&Ray::segment(Vec3::ZERO, Vec3::Z, 0.0, 3.9))
            .is_none());
        // Starting past the near root gives the far root, seen from inside: radiance 0 for a one-sided sphere.
        let (t, l) = sphere
            .intersect(&Ray::segment(Vec3::ZERO, Vec3::Z, 4.5, 100.0))
            .unwrap();
        assert!((t - 6.0).abs() < 1e-5 && l == Vec3::ZERO);
        assert!(sphere.intersect(&Ray::new(Vec3::ZERO, Vec3::X)).is_none());
        let disk = light(
            Shape::Disk {
                center: Vec3::new(0.0, 2.0, 0.0),
                normal: -Vec3::Y,
                radius: 1.0,
            },
            false,
        );
        let (t, l) = disk
            .intersect(&Ray::new(Vec3::new(0.5, 0.0, 0.5), Vec3::Y))
            .unwrap();
        assert!((t - 2.0).abs() < 1e-6 && l == Vec3::splat(1.5));
        assert!(disk
            .intersect(&Ray::new(Vec3::new(0.8, 0.0, 0.8), Vec3::Y))
            .is_none());
        assert!(disk.intersect(&Ray::new(Vec3::ZERO, -Vec3::Y)).is_none());
    }

    #[test]
    fn power_counts_area_and_sides() {
        let disk = AreaLight::new(
            Shape::Disk {
                center: Vec3::ZERO,
                normal: Vec3::Y,
                radius: 2.0,
            },
            Vec3::ONE,
            true,
        )
        .unwrap();
        assert!((disk.power() - 2.0 * PI * PI * 4.0).abs() < 1e-3);
        let sphere = AreaLight::new(
            Shape::Sphere {
                center: Vec3::ZERO,
                radius: 1.0,
            },
            Vec3::ONE,
            true,
        )
        .unwrap();
        assert!((Light::Area(sphere).power(1.0) - 4.0 * PI * PI).abs() < 1e-3);
    }

    #[test]
    fn degenerate_inputs_stay_finite() {
        let shapes = [
            Shape::Quad {
                corner: Vec3::ZERO,
                edge_u: Vec3::X,
                edge_v: Vec3::Z,
            },
            Shape::Disk {
                center: Vec3::ZERO,
                normal: Vec3::Y,
                radius: 1.0,
            },
            Shape::Sphere {
                center: Vec3::ZERO,
                radius: 1.0,
            },
        ];
        let points = [
            Vec3::ZERO,               // On the quad's corner, the disk's centre, the sphere's centre.
            Vec3::new(0.5, 0.0, 0.5), // On the quad and disk.
            Vec3::new(1.0, 0.0, 0.0), // On the quad's edge, the disk's rim, the sphere's surface.
            Vec3::new(0.0, 1.0, 0.0), // On the sphere; above the quad and disk.
            Vec3::new(0.3, 1e-30, 0.2), // A hair above the plane.
            Vec3::new(1e30, 1.0, 0.0),
            Vec3::NAN,
            Vec3::INFINITY,
        ];
        let directions = [
            Vec3::X,
            Vec3::Z,
            -Vec3::Y,
            Vec3::ZERO,
            Vec3::NAN,
            Vec3::new(1.0, 1e-30, 0.0),
            Vec3::splat(1e30),
        ];
        let us = [
            [0.0, 0.0],
            [1.0, 1.0],
            [0.5, 0.5],
            [f32::NAN, 0.3],
            [-1.0, 2.0],
        ];
        for shape in shapes {
            for two_sided in [false, true] {
                let l = light(shape, two_sided);
                for p in points {
                    for u in us {
                        if let Some(s) = l.sample_li(p, u) {
                            assert!(
                                s.wi.is_finite() && s.radiance.is_finite(),
                                "{shape:?} at {p}, u {u:?}: {s:?}"
                            );
                            assert!(
                                s.pdf > 0.0 && s.pdf.is_finite() && s.distance.is_finite(),
                                "{shape:?} at {p}: {s:?}"
                            );
                        }
                    }
                    for d in directions {
                        let pdf = l.pdf_li(p, d);
                        assert!(
                            pdf.is_finite() && pdf >= 0.0,
                            "{shape:?} at {p}, wi {d}: pdf {pdf}"
                        );
                        for ray in [
                            Ray::new(p, d),
                            Ray::segment(p, d, 0.5, 0.25),
                            Ray::segment(p, d, f32::NAN, 1.0),
                        ] {
                            if let Some((t, radiance)) = l.intersect(&ray) {
                                assert!(t.is_finite() && radiance.is_finite(), "{shape:?} {ray:?}");
                            }
                        }
                    }
                }
            }
        }
        assert!(AreaLight::new(
            Shape::Quad {
                corner: Vec3::ZERO,
                edge_u: Vec3::X,
                edge_v: 2.0 * Vec3::X
            },
            Vec3::ONE,
            false
        )
        .unwrap_err()
        .to_string()
        .contains("edges not parallel"));
    }
}
