//! Non-hair geometry: quads (a ground plane, a wall), boxes of quads (the Cornell box of §6.3, figure 22) and
//! triangle meshes (a head under a groom, read from USD), all with a two-sided Lambert material.
//!
//! A scene holds a handful of quads, so they are intersected by brute force in Rust whichever strand tracer runs.
//! Meshes hold up to millions of triangles: they are traced by the frame's backend ([`MeshTracer`]: Embree's
//! triangles or the pure-Rust BVH), in a structure of their own beside the strands'. **Decision**: meshes are not
//! put in the strands' structure. The strands' queries (stochastic presence, transmittance, strand counts) stay as
//! they are, and a mesh is opaque, so the integrator asks the shapes first and the strands only up to the shape's
//! hit; the cost is one more traversal per ray in scenes with meshes, none in scenes without.
//!
//! **Roots on the scalp.** A strand's rays see the mesh it grows from like any other shape. The hits are exact
//! (watertight triangles, exact curves), and a fibre's visible shading points lie on or outside the skin, so the
//! rays towards a light above the skin never meet the scalp: no acne where hair meets skin. Measured in
//! `tests/groom.rs` (1 200 strands rooted on a 352-triangle head, sun overhead, hair transparent to shadows): every
//! hair pixel's shadow rays reach the sun (`shadow.Y` 1). Ignoring the mesh within a few fibre radii of a hair
//! ray's origin, as a clearance against acne, changed nothing there (1 with 4 radii and with none) and would let
//! light from below through the skin at the roots, so there is none.

use std::sync::Arc;

use glam::Vec3;

use crate::accel::mesh::{MeshTracer, MeshTracerError};
use crate::accel::Backend;
use crate::geometry::{self, Parallelogram};
use crate::mesh::TriangleMesh;
use crate::ray::Ray;

/// A parallelogram `corner + s·edge_u + t·edge_v`, s, t ∈ [0, 1], with a Lambert albedo.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Quad {
    /// One corner.
    pub corner: Vec3,
    /// First edge from the corner.
    pub edge_u: Vec3,
    /// Second edge from the corner.
    pub edge_v: Vec3,
    /// Lambert albedo, linear RGB in [0, 1].
    pub albedo: Vec3,
    /// The surface built by [`Quad::new`], which the hits use (not the fields above); its unit normal lies along
    /// edge_u × edge_v (the material is two-sided; the normal only fixes a convention).
    surface: Parallelogram,
}

impl Quad {
    /// A quad from a corner and two edges; `None` if the edges are parallel or not finite (see
    /// [`Parallelogram::new`]).
    pub fn new(corner: Vec3, edge_u: Vec3, edge_v: Vec3, albedo: Vec3) -> Option<Quad> {
        Some(Quad {
            corner,
            edge_u,
            edge_v,
            albedo,
            surface: Parallelogram::new(corner, edge_u, edge_v)?,
        })
    }

    /// The unit normal along edge_u × edge_v.
    pub fn normal(&self) -> Vec3 {
        self.surface.normal()
    }

    /// The ray parameter of the hit inside `(ray.tnear, tfar)`, if any.
    #[inline]
    pub fn intersect(&self, ray: &Ray, tfar: f32) -> Option<f32> {
        self.surface
            .hit(ray.origin, ray.dir, geometry::open(ray.tnear, tfar))
    }
}

/// The closest hit of a ray with the scene's shapes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShapeHit {
    /// Ray parameter.
    pub t: f32,
    /// Unit shading normal: the quad's or triangle's own, or a smooth mesh's interpolated one, on the side of
    /// `geometric` (either side may face the ray).
    pub normal: Vec3,
    /// Unit normal of the quad or triangle hit: which side of the surface the ray is on.
    pub geometric: Vec3,
    /// Lambert albedo.
    pub albedo: Vec3,
}

/// Every non-hair shape of a scene.
#[derive(Debug, Clone, Default)]
pub struct Shapes {
    quads: Vec<Quad>,
    /// Triangle meshes, in the order added (shared by the frames made of one frame's shapes).
    meshes: Arc<Vec<TriangleMesh>>,
    /// The meshes' tracer, built by [`Shapes::trace`] once every mesh is in.
    tracer: Option<Arc<MeshTracer>>,
}

impl Shapes {
    /// No shapes.
    pub fn new() -> Shapes {
        Shapes::default()
    }

    /// Adds a quad.
    pub fn push(&mut self, quad: Quad) {
        self.quads.push(quad);
    }

    /// Adds a triangle mesh (checked by its reader: [`TriangleMesh::validate`]). It is traced once
    /// [`Shapes::trace`] has built the meshes' structure; a mesh added later drops the structure built before.
    pub fn push_mesh(&mut self, mesh: TriangleMesh) {
        Arc::make_mut(&mut self.meshes).push(mesh);
        self.tracer = None;
    }

    /// Builds the meshes' tracer with `backend` (nothing to build without meshes). [`crate::render::Frame`]
    /// calls it with the strands' backend, so `--backend bvh` traces every primitive of the scene in Rust.
    pub fn trace(&mut self, backend: Backend) -> Result<(), MeshTracerError> {
        self.tracer = if self.meshes.is_empty() {
            None
        } else {
            Some(Arc::new(MeshTracer::build(&self.meshes, backend)?))
        };
        Ok(())
    }

    /// Adds the six faces of the axis-aligned box [`min`, `max`], leaving out the faces named in `open`
    /// (`"+x"`, `"-x"`, `"+y"`, `"-y"`, `"+z"`, `"-z"`: e.g. `["+z"]` opens a Cornell box towards a camera on +z).
    pub fn push_box(&mut self, min: Vec3, max: Vec3, albedo: Vec3, open: &[&str]) {
        let e = max - min;
        let (x, y, z) = (Vec3::X * e.x, Vec3::Y * e.y, Vec3::Z * e.z);
        let faces = [
            ("-x", min, y, z),
            ("+x", min + x, z, y),
            ("-y", min, z, x),
            ("+y", min + y, x, z),
            ("-z", min, x, y),
            ("+z", min + z, y, x),
        ];
        for (name, corner, a, b) in faces {
            if !open.contains(&name) {
                if let Some(q) = Quad::new(corner, a, b, albedo) {
                    self.quads.push(q);
                }
            }
        }
    }

    /// Whether there are no shapes.
    pub fn is_empty(&self) -> bool {
        self.quads.is_empty() && self.meshes.is_empty()
    }

    /// The quads, in the order added.
    pub fn quads(&self) -> &[Quad] {
        &self.quads
    }

    /// The meshes, in the order added.
    pub fn meshes(&self) -> &[TriangleMesh] {
        &self.meshes
    }

    /// The meshes' tracer, once built.
    pub fn mesh_tracer(&self) -> Option<&MeshTracer> {
        self.tracer.as_deref()
    }

    /// The box around every quad and mesh; `None` without shapes.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let quad_points = self.quads.iter().flat_map(|q| {
            [
                q.corner,
                q.corner + q.edge_u,
                q.corner + q.edge_v,
                q.corner + q.edge_u + q.edge_v,
            ]
        });
        let mesh_corners = self.meshes.iter().flat_map(|m| {
            let (lo, hi) = m.bounds();
            [lo, hi]
        });
        quad_points
            .chain(mesh_corners)
            .fold(None, |b: Option<(Vec3, Vec3)>, p| {
                Some(b.map_or((p, p), |(lo, hi)| (lo.min(p), hi.max(p))))
            })
    }

    /// Bytes the meshes and their tracer hold (the quads are a few dozen bytes each).
    pub fn memory_bytes(&self) -> usize {
        self.meshes.iter().map(|m| m.bytes()).sum::<usize>()
            + self.tracer.as_ref().map_or(0, |t| t.memory_bytes())
    }

    /// The closest hit with t in `(ray.tnear, tfar)`.
    #[inline]
    pub fn intersect(&self, ray: &Ray, tfar: f32) -> Option<ShapeHit> {
        let mut best: Option<ShapeHit> = None;
        let mut tmax = tfar;
        for q in &self.quads {
            if let Some(t) = q.intersect(ray, tmax) {
                tmax = t;
                best = Some(ShapeHit {
                    t,
                    normal: q.normal(),
                    geometric: q.normal(),
                    albedo: q.albedo,
                });
            }
        }
        if let Some(tracer) = &self.tracer {
            // A ray the tracer refuses (it passed the strands' checks with another tfar) finds no triangle.
            let segment = Ray::segment(ray.origin, ray.dir, ray.tnear, tmax);
            if let Ok(Some(h)) = tracer.intersect(&segment) {
                let mesh = &self.meshes[h.mesh as usize];
                let geometric = mesh.normal(h.triangle);
                best = Some(ShapeHit {
                    t: h.t,
                    normal: mesh.shading_normal(h.triangle, h.u, h.v, geometric),
                    geometric,
                    albedo: mesh.albedo_at(h.triangle, h.u, h.v),
                });
            }
        }
        best
    }

    /// Whether any shape blocks the ray before `tfar`.
    #[inline]
    pub fn occluded(&self, ray: &Ray, tfar: f32) -> bool {
        self.quads.iter().any(|q| q.intersect(ray, tfar).is_some())
            || self.tracer.as_ref().is_some_and(|tracer| {
                tracer
                    .occluded(&Ray::segment(ray.origin, ray.dir, ray.tnear, tfar))
                    .unwrap_or(false)
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_floor() -> Quad {
        // The square [0, 1]² in the plane y = 0, normal +y... edge_u × edge_v = z × x = +y.
        Quad::new(Vec3::ZERO, Vec3::Z, Vec3::X, Vec3::splat(0.5)).unwrap()
    }

    #[test]
    fn quad_hit_distance_and_bounds() {
        let q = unit_floor();
        assert_eq!(q.normal(), Vec3::Y);
        let down = |x: f32, z: f32| Ray::new(Vec3::new(x, 2.0, z), Vec3::NEG_Y);
        assert_eq!(q.intersect(&down(0.5, 0.5), f32::INFINITY), Some(2.0));
        assert_eq!(q.intersect(&down(1.01, 0.5), f32::INFINITY), None);
        assert_eq!(q.intersect(&down(0.5, -0.01), f32::INFINITY), None);
        // From below too (two-sided), and not beyond tfar.
        let up = Ray::new(Vec3::new(0.2, -1.0, 0.7), Vec3::Y);
        assert_eq!(q.intersect(&up, f32::INFINITY), Some(1.0));
        assert_eq!(q.intersect(&up, 0.99), None);
        // Parallel rays miss.
        assert_eq!(
            q.intersect(&Ray::new(Vec3::new(0.5, 0.0, -1.0), Vec3::Z), f32::INFINITY),
            None
        );
    }

    #[test]
    fn degenerate_quads_are_refused() {
        assert!(Quad::new(Vec3::ZERO, Vec3::X, Vec3::X * 2.0, Vec3::ONE).is_none());
        assert!(Quad::new(Vec3::NAN, Vec3::X, Vec3::Y, Vec3::ONE).is_none());
    }

    #[test]
    fn a_box_is_closed_except_where_opened() {
        let mut shapes = Shapes::new();
        shapes.push_box(Vec3::splat(-1.0), Vec3::splat(1.0), Vec3::ONE, &["+z"]);
        assert_eq!(shapes.quads().len(), 5);
        // From the centre every direction except through the open +z face hits a wall at distance ≥ 1.
        for dir in [Vec3::X, Vec3::NEG_X, Vec3::Y, Vec3::NEG_Y, Vec3::NEG_Z] {
            let hit = shapes
                .intersect(&Ray::new(Vec3::ZERO, dir), f32::INFINITY)
                .unwrap();
            assert!((hit.t - 1.0).abs() < 1e-6, "{dir}: {}", hit.t);
            assert!(hit.normal.dot(dir).abs() > 0.999);
        }
        assert!(shapes
            .intersect(&Ray::new(Vec3::ZERO, Vec3::Z), f32::INFINITY)
            .is_none());
        assert!(shapes.occluded(
            &Ray::new(Vec3::ZERO, Vec3::new(0.3, 0.2, -1.0).normalize()),
            10.0
        ));
        assert!(!shapes.occluded(&Ray::new(Vec3::ZERO, Vec3::X), 0.5));
    }

    #[test]
    fn closest_of_several() {
        let mut shapes = Shapes::new();
        for y in [-3.0, -1.0, -2.0] {
            shapes.push(
                Quad::new(
                    Vec3::new(-5.0, y, -5.0),
                    Vec3::Z * 10.0,
                    Vec3::X * 10.0,
                    Vec3::ONE,
                )
                .unwrap(),
            );
        }
        let hit = shapes
            .intersect(&Ray::new(Vec3::ZERO, Vec3::NEG_Y), f32::INFINITY)
            .unwrap();
        assert_eq!(hit.t, 1.0);
    }
}
