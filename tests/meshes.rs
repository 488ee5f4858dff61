//! The mesh tracer on both backends: watertightness on closed meshes (rays aimed exactly at vertices and edge
//! midpoints from inside never escape; a Möller–Trumbore test on the same rays shows what the check catches),
//! Embree against the Rust BVH on random rays, the open interval (tnear, tfar), degenerate triangles, a ray through
//! a shared edge, several meshes, and invalid rays (which would abort the process inside Debian's libembree3 if
//! they reached it).

use std::collections::HashMap;

use cuticle::accel::mesh::{MeshHit, MeshTracer, MeshTracerError};
use cuticle::accel::Backend;
use cuticle::geometry::triangle_hit;
use cuticle::mesh::TriangleMesh;
use cuticle::ray::{InvalidRay, Ray};
use cuticle::util::hash::SplitMix64;
use glam::Vec3;

const BACKENDS: [Backend; 2] = [Backend::Embree, Backend::Bvh];

/// Random rays of the agreement test: the brief's 100 000 and a margin.
const AGREEMENT_RAYS: usize = 120_000;

/// Fraction of random rays on which the backends must agree: they differ only where rounding decides which of two
/// triangles sharing an edge a ray meets, or whether a grazing ray meets one.
const AGREEMENT: f64 = 0.999;

/// Relative difference of t allowed where both backends hit the same triangle: two single-precision tests of one
/// triangle differ by a few ulps.
const T_RELATIVE: f32 = 1e-4;

/// Difference of barycentrics allowed where both hit the same triangle (a few ulps of coordinates of order 1).
const UV_TOLERANCE: f32 = 1e-4;

fn mesh(name: &str, positions: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> TriangleMesh {
    TriangleMesh {
        name: name.into(),
        positions,
        triangles,
        corner_albedo: None,
        albedo: Vec3::splat(0.5),
        vertex_normals: None,
        texture: None,
    }
}

/// A closed icosphere: the icosahedron with each triangle split into four `levels` times, every new point pushed
/// onto the sphere. Points are shared between triangles (one per edge midpoint), triangles wound outward.
fn icosphere(levels: u32, center: Vec3, radius: f32) -> TriangleMesh {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut points: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut midpoints: HashMap<(u32, u32), u32> = HashMap::new();
        let mut midpoint = |a: u32, b: u32, points: &mut Vec<Vec3>| {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                points.push((points[a as usize] + points[b as usize]).normalize());
                points.len() as u32 - 1
            })
        };
        triangles = triangles
            .iter()
            .flat_map(|&[a, b, c]| {
                let ab = midpoint(a, b, &mut points);
                let bc = midpoint(b, c, &mut points);
                let ca = midpoint(c, a, &mut points);
                [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
            })
            .collect();
    }
    let positions = points.iter().map(|&p| center + radius * p).collect();
    mesh("icosphere", positions, triangles)
}

/// The cube [−1, 1]³ as 12 triangles over its 8 corners, wound outward.
fn cube() -> TriangleMesh {
    let positions = (0..8)
        .map(|i| {
            Vec3::new(
                if i & 1 == 0 { -1.0 } else { 1.0 },
                if i & 2 == 0 { -1.0 } else { 1.0 },
                if i & 4 == 0 { -1.0 } else { 1.0 },
            )
        })
        .collect();
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let triangles = quads
        .iter()
        .flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]])
        .collect();
    mesh("cube", positions, triangles)
}

/// Every distinct edge of a mesh, as point indices.
fn edges(mesh: &TriangleMesh) -> Vec<(u32, u32)> {
    let mut edges: Vec<(u32, u32)> = mesh
        .triangles
        .iter()
        .flat_map(|&[a, b, c]| [(a, b), (b, c), (c, a)])
        .map(|(a, b)| (a.min(b), a.max(b)))
        .collect();
    edges.sort_unstable();
    edges.dedup();
    edges
}

/// The rays from `inside` aimed exactly at each point and each edge's midpoint, rounded as f32 rounds them.
fn aimed_rays(mesh: &TriangleMesh, inside: Vec3) -> Vec<Ray> {
    let targets = mesh.positions.iter().copied().chain(
        edges(mesh)
            .into_iter()
            .map(|(a, b)| 0.5 * (mesh.positions[a as usize] + mesh.positions[b as usize])),
    );
    targets.map(|p| Ray::new(inside, p - inside)).collect()
}

/// Möller & Trumbore 1997 as it is usually written, two-sided, for comparison: not watertight, since each triangle
/// computes its edge tests from its own first corner and edge vectors, rounded differently for two triangles that
/// share an edge.
fn moller_trumbore(ray: &Ray, [a, b, c]: [Vec3; 3]) -> Option<f32> {
    let (e1, e2) = (b - a, c - a);
    let p = ray.dir.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 {
        return None;
    }
    let inv = 1.0 / det;
    let s = ray.origin - a;
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = ray.dir.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(q) * inv;
    (t > ray.tnear && t < ray.tfar).then_some(t)
}

/// The closed meshes and the interior points the watertightness test shoots from.
fn closed_meshes() -> Vec<(TriangleMesh, Vec<Vec3>)> {
    let inside = |r: f32| {
        vec![
            Vec3::ZERO,
            Vec3::new(0.1, -0.2, 0.3) * r,
            Vec3::new(-0.37, 0.21, 0.05) * r,
            Vec3::new(0.013, 0.6, -0.29) * r,
        ]
    };
    vec![
        (icosphere(3, Vec3::ZERO, 1.0), inside(1.0)),
        (
            icosphere(4, Vec3::new(0.3, -0.1, 0.7), 2.5),
            inside(2.5)
                .into_iter()
                .map(|p| p + Vec3::new(0.3, -0.1, 0.7))
                .collect(),
        ),
        (cube(), inside(1.0)),
    ]
}

/// Largest share of the rays aimed exactly at a vertex that may escape through Embree. Its robust mode tests a
/// triangle's edges with Plücker coordinates computed in 3-D: two triangles sharing an edge compute the same value
/// with opposite signs (no ray escapes through an edge, checked below), but the rounded signs of the edges around
/// a vertex need not be consistent with one another, so a ray through the vertex can be outside every triangle
/// around it. Measured on these meshes (Embree 3.13.5, AVX2): 38 of 12 848 vertex rays; Embree's default
/// (Möller–Trumbore) mode let 3 231 of the 51 320 rays through, edges and vertices alike.
const EMBREE_VERTEX_LEAKS: f64 = 0.01;

#[test]
fn rays_from_inside_a_closed_mesh_never_escape() {
    let (mut vertex_rays, mut edge_rays) = (0usize, 0usize);
    let (mut embree_vertex_escapes, mut moller_escapes) = (0usize, 0usize);
    for (mesh, insides) in closed_meshes() {
        let corners: Vec<[Vec3; 3]> = (0..mesh.triangles.len() as u32)
            .map(|t| mesh.corners(t))
            .collect();
        let [embree, bvh] =
            BACKENDS.map(|b| MeshTracer::build(std::slice::from_ref(&mesh), b).unwrap());
        for &inside in &insides {
            for (k, ray) in aimed_rays(&mesh, inside).into_iter().enumerate() {
                let at_vertex = k < mesh.positions.len();
                if at_vertex {
                    vertex_rays += 1;
                } else {
                    edge_rays += 1;
                }
                let what = |backend: Backend| {
                    format!(
                        "{}, {backend:?}: the ray from {inside} along {} (at a {}) escapes",
                        mesh.name,
                        ray.dir,
                        if at_vertex {
                            "vertex"
                        } else {
                            "an edge's midpoint"
                        }
                    )
                };
                // The Rust backend: never.
                assert!(
                    bvh.intersect(&ray).unwrap().is_some(),
                    "{}",
                    what(Backend::Bvh)
                );
                assert!(bvh.occluded(&ray).unwrap(), "{}", what(Backend::Bvh));
                // Embree: never through an edge; through a vertex, rarely (see EMBREE_VERTEX_LEAKS).
                let (hit, occluded) = (
                    embree.intersect(&ray).unwrap(),
                    embree.occluded(&ray).unwrap(),
                );
                assert_eq!(
                    hit.is_some(),
                    occluded,
                    "{}: closest and any hit disagree",
                    what(Backend::Embree)
                );
                if hit.is_none() {
                    assert!(at_vertex, "{}", what(Backend::Embree));
                    embree_vertex_escapes += 1;
                }
                // The same rays, brute force over the triangles: the watertight test, and Möller–Trumbore.
                assert!(corners
                    .iter()
                    .any(|&c| triangle_hit(ray.origin, ray.dir, c, ray.tnear, ray.tfar).is_some()));
                if !corners.iter().any(|&c| moller_trumbore(&ray, c).is_some()) {
                    moller_escapes += 1;
                }
            }
        }
    }
    println!(
        "{vertex_rays} rays aimed at vertices and {edge_rays} at edge midpoints: the Rust BVH lets none escape, \
         Embree {embree_vertex_escapes} (at vertices), Möller–Trumbore by brute force {moller_escapes}"
    );
    assert!(
        vertex_rays > 10_000 && edge_rays > 30_000,
        "{vertex_rays} {edge_rays}"
    );
    assert!(
        (embree_vertex_escapes as f64) <= EMBREE_VERTEX_LEAKS * vertex_rays as f64,
        "embree: {embree_vertex_escapes} of {vertex_rays} vertex rays escape"
    );
    // The rays find cracks where a test has them: Möller–Trumbore's.
    assert!(moller_escapes > 0, "Möller–Trumbore lets no ray through");
}

/// Uniform in [lo, hi) per axis.
fn point_in(rng: &mut SplitMix64, lo: Vec3, hi: Vec3) -> Vec3 {
    let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
    lo + u * (hi - lo)
}

/// A uniform unit vector (rejection from the ball's shell 0.1–1).
fn unit_vector(rng: &mut SplitMix64) -> Vec3 {
    loop {
        let p = point_in(rng, Vec3::NEG_ONE, Vec3::ONE);
        let l = p.length();
        if (0.1..=1.0).contains(&l) {
            return p / l;
        }
    }
}

/// `count` random triangles of sizes 0.01–0.5 in the box [−2, 2]³, each with its own three points.
fn soup(count: usize, seed: u64) -> TriangleMesh {
    let mut rng = SplitMix64::new(seed, 0);
    let mut positions = Vec::with_capacity(3 * count);
    for _ in 0..count {
        let a = point_in(&mut rng, Vec3::splat(-2.0), Vec3::splat(2.0));
        let size = 0.01 + 0.49 * rng.next_f32();
        positions.push(a);
        positions.push(a + size * unit_vector(&mut rng));
        positions.push(a + size * unit_vector(&mut rng));
    }
    let triangles = (0..count as u32)
        .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
        .collect();
    mesh("soup", positions, triangles)
}

/// Random rays through [−3, 3]³: from outside and inside, a quarter with a finite interval.
fn random_rays(n: usize, seed: u64) -> Vec<Ray> {
    let mut rng = SplitMix64::new(seed, 1);
    (0..n)
        .map(|i| {
            let origin = point_in(&mut rng, Vec3::splat(-3.0), Vec3::splat(3.0));
            let dir = unit_vector(&mut rng) * (0.5 + rng.next_f32());
            if i % 4 == 0 {
                let tnear = rng.next_f32();
                Ray::segment(origin, dir, tnear, tnear + 4.0 * rng.next_f32() + 1e-3)
            } else {
                Ray::new(origin, dir)
            }
        })
        .collect()
}

/// Whether two closest hits agree: both miss, or the same triangle at the same t and (u, v) within tolerance.
fn agree(a: Option<MeshHit>, b: Option<MeshHit>) -> bool {
    match (a, b) {
        (None, None) => true,
        (Some(a), Some(b)) => {
            (a.mesh, a.triangle) == (b.mesh, b.triangle)
                && (a.t - b.t).abs() <= T_RELATIVE * a.t.abs().max(b.t.abs())
                && (a.u - b.u).abs() <= UV_TOLERANCE
                && (a.v - b.v).abs() <= UV_TOLERANCE
        }
        _ => false,
    }
}

#[test]
fn embree_and_the_rust_bvh_agree_on_random_rays() {
    let meshes = [icosphere(4, Vec3::new(0.2, 0.1, -0.3), 1.2), soup(3000, 7)];
    let [embree, bvh] = BACKENDS.map(|b| MeshTracer::build(&meshes, b).unwrap());
    let rays = random_rays(AGREEMENT_RAYS, 11);
    let (mut closest, mut occluded, mut hits) = (0usize, 0usize, 0usize);
    let mut first_disagreement = None;
    for ray in &rays {
        let (e, b) = (embree.intersect(ray).unwrap(), bvh.intersect(ray).unwrap());
        if agree(e, b) {
            closest += 1;
        } else if first_disagreement.is_none() {
            first_disagreement = Some((*ray, e, b));
        }
        hits += usize::from(e.is_some());
        let (oe, ob) = (embree.occluded(ray).unwrap(), bvh.occluded(ray).unwrap());
        occluded += usize::from(oe == ob);
        // An occlusion query answers what the closest-hit query found.
        assert_eq!(ob, b.is_some(), "bvh: occluded against closest on {ray:?}");
    }
    let n = rays.len() as f64;
    let (closest_share, occluded_share) = (closest as f64 / n, occluded as f64 / n);
    println!(
        "{} rays, {hits} hitting: closest hits agree on {closest} ({:.5}), occlusion on {occluded} ({:.5}); first \
         disagreement: {first_disagreement:?}",
        rays.len(),
        closest_share,
        occluded_share
    );
    // Guard against a vacuous test: a good share of the rays must hit.
    assert!(hits > rays.len() / 4, "only {hits} rays hit");
    assert!(
        closest_share >= AGREEMENT,
        "closest hits agree on {closest_share}; first disagreement {first_disagreement:?}"
    );
    assert!(
        occluded_share >= AGREEMENT,
        "occlusion agrees on {occluded_share}"
    );
}

/// Two triangles making the square [0, 2]² at height z, sharing the diagonal (0, 0)–(2, 2).
fn square(z: f32) -> TriangleMesh {
    mesh(
        "square",
        vec![
            Vec3::new(0.0, 0.0, z),
            Vec3::new(2.0, 0.0, z),
            Vec3::new(2.0, 2.0, z),
            Vec3::new(0.0, 2.0, z),
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    )
}

#[test]
fn hits_lie_in_the_open_interval() {
    let meshes = [square(1.0), square(2.0)];
    for backend in BACKENDS {
        let tracer = MeshTracer::build(&meshes, backend).unwrap();
        let o = Vec3::new(1.5, 0.5, 0.0);
        let at = |tnear: f32, tfar: f32| {
            let ray = Ray::segment(o, Vec3::Z, tnear, tfar);
            let hit = tracer.intersect(&ray).unwrap();
            assert_eq!(
                hit.is_some(),
                tracer.occluded(&ray).unwrap(),
                "{backend:?}: ({tnear}, {tfar})"
            );
            hit.map(|h| (h.mesh, h.t))
        };
        assert_eq!(at(0.0, f32::INFINITY), Some((0, 1.0)), "{backend:?}");
        assert_eq!(at(0.0, 1.0), None, "{backend:?}");
        assert_eq!(at(0.0, 1.0001), Some((0, 1.0)), "{backend:?}");
        // tnear at the first square: the second; between them: the second; at the second: nothing.
        assert_eq!(at(1.0, f32::INFINITY), Some((1, 2.0)), "{backend:?}");
        assert_eq!(at(0.9999, f32::INFINITY), Some((0, 1.0)), "{backend:?}");
        assert_eq!(at(1.5, 2.0), None, "{backend:?}");
        assert_eq!(at(2.0, 5.0), None, "{backend:?}");
        // The barycentrics of (1.5, 0.5) in triangle (0,0)-(2,0)-(2,2): a + u (b − a) + v (c − a).
        let hit = tracer.intersect(&Ray::new(o, Vec3::Z)).unwrap().unwrap();
        assert_eq!(hit.triangle, 0, "{backend:?}");
        assert!(
            (hit.u - 0.5).abs() < 1e-6 && (hit.v - 0.25).abs() < 1e-6,
            "{backend:?}: {hit:?}"
        );
    }
}

#[test]
fn degenerate_triangles_are_never_hit() {
    // Triangles 0–2 degenerate (a repeated point, three collinear points, all three equal), 3 a real one.
    let (p, q) = (Vec3::new(0.0, 0.0, 1.0), Vec3::new(2.0, 2.0, 1.0));
    let m = mesh(
        "degenerate",
        vec![
            p,
            q,
            0.5 * (p + q),
            Vec3::new(5.0, 0.0, 1.0),
            Vec3::new(6.0, 0.0, 1.0),
            Vec3::new(5.0, 1.0, 1.0),
        ],
        vec![[0, 0, 1], [0, 2, 1], [2, 2, 2], [3, 4, 5]],
    );
    for backend in BACKENDS {
        let tracer = MeshTracer::build(std::slice::from_ref(&m), backend).unwrap();
        for k in 0..=32 {
            let target = p + (k as f32 / 32.0) * (q - p);
            for o in [
                Vec3::new(0.3, 1.7, -1.0),
                target - Vec3::Z,
                Vec3::new(-1.0, -1.0, 1.0),
            ] {
                let ray = Ray::new(o, target - o);
                assert_eq!(
                    tracer.intersect(&ray).unwrap(),
                    None,
                    "{backend:?}: {ray:?}"
                );
                assert!(!tracer.occluded(&ray).unwrap(), "{backend:?}: {ray:?}");
            }
        }
        // The real triangle keeps its own index behind the degenerate ones.
        let hit = tracer
            .intersect(&Ray::new(Vec3::new(5.2, 0.2, 0.0), Vec3::Z))
            .unwrap()
            .unwrap();
        assert_eq!((hit.mesh, hit.triangle), (0, 3), "{backend:?}");
    }
}

#[test]
fn a_ray_through_a_shared_edge_hits_the_surface_once() {
    let meshes = [square(1.0)];
    for backend in BACKENDS {
        let tracer = MeshTracer::build(&meshes, backend).unwrap();
        for k in 1..64 {
            // Points of the shared diagonal, from an oblique origin.
            let target = Vec3::new(2.0, 2.0, 1.0) * (k as f32 / 64.0)
                + Vec3::new(0.0, 0.0, 1.0) * (1.0 - k as f32 / 64.0);
            let o = Vec3::new(-0.3, 1.1, -1.5);
            let ray = Ray::new(o, target - o);
            let hit = tracer
                .intersect(&ray)
                .unwrap()
                .unwrap_or_else(|| panic!("{backend:?}: {ray:?} goes through the edge"));
            assert!(
                hit.triangle < 2 && (hit.t - 1.0).abs() < 1e-5,
                "{backend:?}: {hit:?}"
            );
            // Continued from the hit, the ray meets nothing more: the neighbour at the same t is not a second hit.
            let past = Ray::segment(o, ray.dir, hit.t, f32::INFINITY);
            assert_eq!(
                tracer.intersect(&past).unwrap(),
                None,
                "{backend:?}: {past:?}"
            );
            assert!(!tracer.occluded(&past).unwrap(), "{backend:?}: {past:?}");
        }
    }
}

#[test]
fn several_meshes_report_their_own_index() {
    let meshes = [
        square(3.0),
        icosphere(1, Vec3::new(5.0, 0.0, 0.0), 0.5),
        cube(),
        icosphere(2, Vec3::new(0.0, 5.0, 0.0), 1.0),
    ];
    for backend in BACKENDS {
        let tracer = MeshTracer::build(&meshes, backend).unwrap();
        let cases = [
            // Down through the square onto the cube's top: the square is nearer.
            (Vec3::new(0.5, 0.5, 10.0), -Vec3::Z, 0, 7.0),
            // Up from below: the cube's bottom first.
            (Vec3::new(0.5, 0.5, -10.0), Vec3::Z, 2, 9.0),
            (Vec3::new(5.0, 0.0, -10.0), Vec3::Z, 1, 9.5),
            (Vec3::new(0.0, 5.0, 10.0), -Vec3::Z, 3, 9.0),
        ];
        for (o, d, mesh, t) in cases {
            let hit = tracer.intersect(&Ray::new(o, d)).unwrap().unwrap();
            assert_eq!(hit.mesh, mesh, "{backend:?}: {o} {d}");
            assert!(
                (hit.t - t).abs() < 0.02,
                "{backend:?}: {hit:?}, expected t {t}"
            );
            let [a, b, c] = meshes[mesh as usize].corners(hit.triangle);
            let p = a + hit.u * (b - a) + hit.v * (c - a);
            assert!(
                (p - (o + hit.t * d)).length() < 1e-4,
                "{backend:?}: {hit:?}"
            );
        }
        assert_eq!(tracer.backend(), backend);
        assert!(tracer.memory_bytes() > 0 && tracer.build_seconds() >= 0.0);
    }
}

#[test]
fn invalid_rays_are_errors() {
    let meshes = [cube()];
    let bad = [
        (
            Ray::new(Vec3::new(f32::NAN, 0.0, 0.0), Vec3::X),
            InvalidRay::NotFinite,
        ),
        (
            Ray::new(Vec3::ZERO, Vec3::new(0.0, f32::INFINITY, 0.0)),
            InvalidRay::NotFinite,
        ),
        (
            Ray::new(Vec3::new(2e19, 0.0, 0.0), -Vec3::X),
            InvalidRay::OriginTooFar,
        ),
        (Ray::new(Vec3::ZERO, Vec3::ZERO), InvalidRay::ZeroDirection),
        (
            Ray::segment(Vec3::ZERO, Vec3::X, -1.0, 1.0),
            InvalidRay::BadInterval,
        ),
        (
            Ray::segment(Vec3::ZERO, Vec3::X, 0.0, f32::NAN),
            InvalidRay::BadInterval,
        ),
        (
            Ray::segment(Vec3::ZERO, Vec3::X, 2.0, 2.0),
            InvalidRay::BadInterval,
        ),
    ];
    for backend in BACKENDS {
        let tracer = MeshTracer::build(&meshes, backend).unwrap();
        for (ray, why) in bad {
            assert_eq!(tracer.intersect(&ray), Err(why), "{backend:?}: {ray:?}");
            assert_eq!(tracer.occluded(&ray), Err(why), "{backend:?}: {ray:?}");
        }
    }
}

#[test]
fn invalid_meshes_are_build_errors() {
    let mut bad = cube();
    bad.triangles[3][1] = 8;
    for backend in BACKENDS {
        let e = MeshTracer::build(&[cube(), bad.clone()], backend).unwrap_err();
        assert!(matches!(e, MeshTracerError::Mesh { index: 1, .. }), "{e:?}");
        assert!(e.to_string().contains("triangle 3 names point 8"), "{e}");
        // No meshes: nothing to hit.
        let empty = MeshTracer::build(&[], backend).unwrap();
        assert_eq!(empty.intersect(&Ray::new(Vec3::ZERO, Vec3::X)), Ok(None));
        assert_eq!(empty.occluded(&Ray::new(Vec3::ZERO, Vec3::X)), Ok(false));
    }
}

#[test]
fn embree_reports_the_normal_of_the_winding() {
    use cuticle::sys::embree::{BuildQuality, Device, Scene, TriangleGeometry};
    let m = square(1.0);
    let device = Device::new().unwrap();
    for robust in [false, true] {
        let mut scene = if robust {
            Scene::robust(&device, BuildQuality::Medium)
        } else {
            Scene::new(&device, BuildQuality::Medium)
        }
        .unwrap();
        let points: Vec<[f32; 3]> = m.positions.iter().map(|p| p.to_array()).collect();
        let geometry = TriangleGeometry::new(&device, &points, &m.triangles).unwrap();
        assert_eq!(geometry.triangle_count(), 2);
        scene.attach_triangles(geometry).unwrap();
        let scene = scene.commit().unwrap();
        for d in [Vec3::Z, -Vec3::Z] {
            let o = Vec3::new(0.5, 1.5, 1.0) - 3.0 * d;
            let hit = scene.intersect1(&Ray::new(o, d)).unwrap().unwrap();
            // (b − a) × (c − a), whichever side the ray comes from: +z for the square's winding.
            assert_eq!(hit.prim_id, 1);
            assert!(
                (hit.ng.normalize() - m.normal(1)).length() < 1e-6,
                "robust {robust}: {hit:?}"
            );
        }
    }
    // Bad input never reaches Embree.
    assert!(TriangleGeometry::new(&device, &[[0.0; 3]; 3], &[[0, 1, 3]]).is_err());
    assert!(TriangleGeometry::new(&device, &[[f32::NAN, 0.0, 0.0]; 3], &[[0, 1, 2]]).is_err());
}
