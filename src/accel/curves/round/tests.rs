//! Tests of the round-curve intersector against Embree and against brute-force references, apart because they
//! outweigh the intersector.

use super::*;
use crate::accel::embree::{Device, EmbreeTracer};
use crate::accel::testing::Rng;
use crate::accel::{CurveKind, Tracer};
use crate::hair::{HairModel, Strands};
use crate::ray::Ray;

/// Hit distances agree when |Δt| ≤ this · t.
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
fn closest(strands: &Strands, ray: &Ray, pieces: usize, max_depth: u32) -> Option<(u32, CurveHit)> {
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
