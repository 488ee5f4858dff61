//! Tests of the flat-curve (ribbon) intersector against Embree and against its own tessellation, apart because
//! they outweigh the intersector.

use super::*;
use crate::accel::embree::{Device, EmbreeTracer};
use crate::accel::testing::Rng;
use crate::accel::{CurveKind, Tracer};
use crate::hair::{HairModel, Strands};
use crate::ray::Ray;

/// Four equally spaced collinear control points `a + k·h` (k = 0..3) of radius `r`: the B-spline is the
/// straight segment P(u) = a + (1 + u)·h, so the ray-facing ribbon is flat and every quad lies in one plane.
fn straight(a: Vec3, h: Vec3, r: f32) -> [[f32; 4]; 4] {
    std::array::from_fn(|k| {
        let p = a + k as f32 * h;
        [p.x, p.y, p.z, r]
    })
}

#[test]
fn perpendicular_rays_hit_the_ribbon_through_the_axis() {
    // Axis from (0, −1, 0) to (0, 1, 0) (a = (0, −3, 0), h = (0, 2, 0)), radius 0.05.
    let (r, h) = (0.05, Vec3::new(0.0, 2.0, 0.0));
    let cp = straight(Vec3::new(0.0, -3.0, 0.0), h, r);
    for (x, y) in [
        (0.0, 0.3),
        (0.6 * r, -0.7),
        (-0.9 * r, 0.55),
        (0.3 * r, 0.0),
    ] {
        let hit = intersect(Vec3::new(x, y, 5.0), Vec3::NEG_Z, 0.0, f32::INFINITY, cp)
            .unwrap_or_else(|| panic!("ray at ({x}, {y}) missed"));
        // The ribbon faces the ray: it is the plane z = 0, hit at t = 5, u = (y + 1)/2, |v| = |x|/r.
        assert!((hit.t - 5.0).abs() < 1e-5, "({x}, {y}): {hit:?}");
        assert!(
            (hit.u - (y + 1.0) / 2.0).abs() < 1e-5,
            "({x}, {y}): {hit:?}"
        );
        assert!(
            (hit.v.abs() - x.abs() / r).abs() < 1e-4,
            "({x}, {y}): {hit:?}"
        );
        // Ng is dP/du = h, not normalised.
        assert!((hit.ng - h).length() < 1e-5, "({x}, {y}): {hit:?}");
        // v changes sign across the axis.
        if x != 0.0 {
            let other =
                intersect(Vec3::new(-x, y, 5.0), Vec3::NEG_Z, 0.0, f32::INFINITY, cp).unwrap();
            assert!((other.v + hit.v).abs() < 1e-4, "{hit:?} vs {other:?}");
        }
        // A direction three times as long: t in units of dir.
        let long = intersect(
            Vec3::new(x, y, 5.0),
            3.0 * Vec3::NEG_Z,
            0.0,
            f32::INFINITY,
            cp,
        )
        .unwrap();
        assert!((3.0 * long.t - 5.0).abs() < 1e-5, "{long:?}");
    }
    let miss = |o: Vec3, tnear: f32, tfar: f32| intersect(o, Vec3::NEG_Z, tnear, tfar, cp);
    assert_eq!(
        miss(Vec3::new(1.2 * r, 0.3, 5.0), 0.0, f32::INFINITY),
        None,
        "beside the ribbon"
    );
    assert_eq!(
        miss(Vec3::new(0.0, 1.2, 5.0), 0.0, f32::INFINITY),
        None,
        "past the segment's end"
    );
    assert_eq!(
        miss(Vec3::new(0.0, 0.3, 5.0), 0.0, 4.9),
        None,
        "before tfar"
    );
    assert_eq!(
        miss(Vec3::new(0.0, 0.3, 5.0), 5.1, 9.0),
        None,
        "after tnear"
    );
    assert_eq!(
        intersect(Vec3::new(0.0, 0.3, 5.0), Vec3::Z, 0.0, f32::INFINITY, cp),
        None,
        "ribbon behind the ray"
    );
}

#[test]
fn oblique_ray_hits_at_the_lines_closest_approach() {
    // Axis along (1, 1, 0)/√2 through the origin; the ray crosses it at 0.4 r from the axis, at 50° to it.
    let r = 0.04;
    let axis = Vec3::new(1.0, 1.0, 0.0).normalize();
    let cp = straight(-1.5 * axis, axis, r); // P(u) = (u − 0.5)·axis
    let side = axis.cross(Vec3::Z); // perpendicular to the axis, in the plane z = 0
    let closest = 0.1 * axis + 0.4 * r * Vec3::Z; // 0.4 r above the axis point at u = 0.6
                                                  // The ray runs in the plane z = 0.4 r, so its closest approach to
                                                  // the axis (the common perpendicular is ẑ) is `closest`; the
                                                  // ray-facing ribbon there spans the axis and ẑ.
    let dir = side * 50f32.to_radians().sin() - axis * 50f32.to_radians().cos();
    let org = closest - 3.0 * dir;
    let hit = intersect(org, dir, 0.0, f32::INFINITY, cp).expect("oblique ray missed");
    // Distance between the lines is 0.4 r (along z, perpendicular to both), reached at t = 3.
    assert!((hit.t - 3.0).abs() < 1e-4, "{hit:?}");
    assert!((hit.u - 0.6).abs() < 1e-4, "{hit:?}");
    assert!((hit.v.abs() - 0.4).abs() < 1e-3, "{hit:?}");
    assert!((hit.ng - axis).length() < 1e-5, "{hit:?}");
}

#[test]
fn hits_within_two_radii_of_the_origin_are_ignored() {
    // Embree's self-intersection avoidance: t must exceed 2 r / |dir|.
    let r = 0.05;
    let cp = straight(Vec3::new(0.0, -3.0, 0.0), Vec3::new(0.0, 2.0, 0.0), r);
    let at = |z: f32, len: f32| {
        intersect(
            Vec3::new(0.0, 0.2, z),
            len * Vec3::NEG_Z,
            0.0,
            f32::INFINITY,
            cp,
        )
    };
    assert_eq!(at(1.9 * r, 1.0), None);
    assert_eq!(
        at(1.9 * r, 0.5),
        None,
        "the cut-off is a distance, whatever |dir|"
    );
    assert!((at(2.1 * r, 1.0).unwrap().t - 2.1 * r).abs() < 1e-6);
    assert!((at(2.1 * r, 0.5).unwrap().t - 4.2 * r).abs() < 1e-6);
}

#[test]
fn degenerate_segments_are_missed_like_embree_misses_them() {
    // Coincident control points (a point, not a curve) and zero radius (a ribbon of no width): no hit, no NaN,
    // and Embree misses them too.
    let device = Device::new().expect("embree device");
    let point = [[0.1, 0.2, 0.0, 0.05]; 4];
    let thin = straight(Vec3::new(0.0, -3.0, 0.0), Vec3::new(0.0, 2.0, 0.0), 0.0);
    for (name, cp) in [("coincident points", point), ("zero radius", thin)] {
        let strands = one_segment(cp);
        let tracer = EmbreeTracer::with_device(&device, &strands, CurveKind::Flat).expect(name);
        for (x, y) in [(0.1, 0.2), (0.0, 0.3), (0.12, 0.2), (0.0, 0.0)] {
            let ray = Ray::new(Vec3::new(x, y, 5.0), Vec3::NEG_Z);
            assert_eq!(ours(&strands, &ray), None, "{name}: {ray:?}");
            assert_eq!(embree(&tracer, &ray), None, "{name}: embree, {ray:?}");
        }
    }
}

// ---- Agreement with Embree ------------------------------------------------------------------------------

/// A hit as both backends report it: (t, segment, u, v, Ng).
type Reported = Option<(f32, u32, f32, f32, Vec3)>;

/// The closest hit over every segment of `strands`, by [`intersect`] (brute force).
fn ours(strands: &Strands, ray: &Ray) -> Reported {
    ours_tessellated(strands, ray, TESSELLATION_RATE)
}

/// [`ours`] with `rate` quads per segment.
fn ours_tessellated(strands: &Strands, ray: &Ray, rate: usize) -> Reported {
    let mut best: Reported = None;
    for (segment, &first) in strands.segment_first.iter().enumerate() {
        let f = first as usize;
        let cp = [
            strands.control_points[f],
            strands.control_points[f + 1],
            strands.control_points[f + 2],
            strands.control_points[f + 3],
        ];
        if let Some(h) = intersect_tessellated(
            &RibbonRay::new(ray.origin, ray.dir),
            ray.tnear,
            ray.tfar,
            cp,
            rate,
            true,
            false,
        ) {
            if best.is_none_or(|b| h.t < b.0) {
                best = Some((h.t, segment as u32, h.u, h.v, h.ng));
            }
        }
    }
    best
}

fn embree(tracer: &EmbreeTracer, ray: &Ray) -> Reported {
    tracer
        .intersect(ray)
        .expect("valid ray")
        .map(|h| (h.t, h.segment, h.u, h.v, h.ng))
}

/// Tallies of one comparison, with the worst case of each kind and the ray that produced it.
#[derive(Default)]
struct Agreement {
    rays: usize,
    hits: usize,
    /// Rays one backend hits and the other misses.
    hit_miss: usize,
    /// Both hit, but |Δt| > 1e-3·t.
    far_t: usize,
    /// Both hit, at a different segment.
    other_segment: usize,
    worst_t: (f32, Option<Ray>),
    worst_u: (f32, Option<Ray>),
    worst_v: (f32, Option<Ray>),
    /// Largest |ΔNg| / |Ng|.
    worst_ng: (f32, Option<Ray>),
    examples: Vec<String>,
}

impl Agreement {
    fn add(&mut self, ray: &Ray, ours: Reported, embree: Reported) {
        self.rays += 1;
        let worst = |w: &mut (f32, Option<Ray>), d: f32| {
            if d > w.0 {
                *w = (d, Some(*ray));
            }
        };
        match (ours, embree) {
            (None, None) => {}
            (Some(o), Some(e)) => {
                self.hits += 1;
                let dt = (o.0 - e.0).abs() / e.0;
                worst(&mut self.worst_t, dt);
                if dt > 1e-3 {
                    self.far_t += 1;
                }
                if o.1 != e.1 {
                    self.other_segment += 1;
                    if self.examples.len() < 5 {
                        self.examples
                            .push(format!("segment: ours {o:?}, embree {e:?}, {ray:?}"));
                    }
                    return;
                }
                worst(&mut self.worst_u, (o.2 - e.2).abs());
                worst(&mut self.worst_v, (o.3 - e.3).abs());
                worst(&mut self.worst_ng, (o.4 - e.4).length() / e.4.length());
            }
            (o, e) => {
                self.hit_miss += 1;
                if self.examples.len() < 5 {
                    self.examples
                        .push(format!("hit/miss: ours {o:?}, embree {e:?}, {ray:?}"));
                }
            }
        }
    }

    /// Asserts the agreement required (≥ 99.9 % of rays agree on hit/miss; of the hits, ≥ 99.9 % within 1e-3·t on
    /// the same segment), and the t, u, v (sign included) and Ng agreement measured. A failure shows the first
    /// disagreements.
    fn check(&self, name: &str) {
        let pct = |n: usize, of: usize| 100.0 * n as f64 / of.max(1) as f64;
        let examples = self.examples.join("\n");
        assert!(
            self.hits * 10 > self.rays,
            "{name}: too few hits to compare"
        );
        assert!(
            pct(self.hit_miss, self.rays) <= 0.1,
            "{name}: hit/miss on {} of {} rays, e.g.\n{examples}",
            self.hit_miss,
            self.rays
        );
        assert!(
            pct(self.far_t, self.hits) <= 0.1,
            "{name}: |dt| > 1e-3 t on {} of {} hits",
            self.far_t,
            self.hits
        );
        assert!(
            pct(self.other_segment, self.hits) <= 0.1,
            "{name}: other segment on {} of {} hits, e.g.\n{examples}",
            self.other_segment,
            self.hits
        );
        // Where they agree, they agree to float noise (Embree's approximate reciprocals and square roots,
        // FMAs): measured worst |dt|/t 3.3e-6, |du| 1.5e-5, |dv| 6.7e-5, |dNg|/|Ng| 1.1e-4 over all tests.
        assert!(
            self.worst_t.0 <= 2e-5,
            "{name}: worst |dt|/t {:?}",
            self.worst_t
        );
        assert!(
            self.worst_u.0 <= 2e-4,
            "{name}: worst |du| {:?}",
            self.worst_u
        );
        assert!(
            self.worst_v.0 <= 2e-4,
            "{name}: worst |dv| {:?}",
            self.worst_v
        );
        assert!(
            self.worst_ng.0 <= 5e-4,
            "{name}: worst |dNg|/|Ng| {:?}",
            self.worst_ng
        );
    }
}

/// A single-segment `Strands` (one strand, no phantom points: the four control points as given).
fn one_segment(cp: [[f32; 4]; 4]) -> Strands {
    Strands {
        control_points: cp.to_vec(),
        strand_offsets: vec![0, 4],
        segment_first: vec![0],
        segment_strand: vec![0],
        opacity: vec![1.0],
        color: vec![[0.5; 3]],
    }
}

/// A random ray aimed within 1.5 radii of a random point of segment 0..n of `strands` (so silhouettes are
/// well sampled), from 1–4 units away, with |dir| in [0.5, 2]; one ray in five ends near the curve (finite
/// tfar), one in five starts near it (tnear > 0).
fn ray_near_curve(rng: &mut Rng, strands: &Strands) -> Ray {
    let segment = (rng.next_u64() % strands.segment_count() as u64) as u32;
    let p = strands.eval(segment, rng.range(0.0, 1.0));
    let target = p.position + rng.unit_vector() * rng.range(0.0, 1.5) * p.radius;
    let dir = rng.unit_vector();
    let distance = rng.range(1.0, 4.0);
    let len = rng.range(0.5, 2.0);
    let (mut tnear, mut tfar) = (0.0, f32::INFINITY);
    match rng.next_u64() % 5 {
        0 => tfar = rng.range(0.5, 1.5) * distance / len,
        1 => tnear = rng.range(0.5, 1.5) * distance / len,
        _ => {}
    }
    Ray::segment(target - distance * dir, len * dir, tnear, tfar)
}

/// Our intersector at `rate` quads per segment against Embree's flat curves on 300 random single segments,
/// 300 rays each. "Hair-like": control points a short walk apart, gently turning, radii 0.005–0.03; "wild":
/// anywhere in a unit box (loops, cusps, tight bends), radii 0.01–0.1.
fn single_segments(device: &Device, seed: u64, wild: bool, rate: usize) -> Agreement {
    let mut rng = Rng::new(seed);
    let mut agreement = Agreement::default();
    for _ in 0..300 {
        let mut cp = [[0.0f32; 4]; 4];
        let mut p = Vec3::ZERO;
        let mut heading = rng.unit_vector();
        for c in &mut cp {
            if wild {
                p = Vec3::new(
                    rng.range(-0.5, 0.5),
                    rng.range(-0.5, 0.5),
                    rng.range(-0.5, 0.5),
                );
            } else {
                heading = (heading + 0.4 * rng.unit_vector()).normalize();
                p += rng.range(0.2, 0.4) * heading;
            }
            let r = if wild {
                rng.range(0.01, 0.1)
            } else {
                rng.range(0.005, 0.03)
            };
            *c = [p.x, p.y, p.z, r];
        }
        let strands = one_segment(cp);
        let tracer = EmbreeTracer::with_device(device, &strands, CurveKind::Flat)
            .expect("embree flat curves");
        for _ in 0..300 {
            let ray = ray_near_curve(&mut rng, &strands);
            agreement.add(
                &ray,
                ours_tessellated(&strands, &ray, rate),
                embree(&tracer, &ray),
            );
        }
    }
    agreement
}

#[test]
fn early_reject_changes_no_result() {
    // Rays through the bounding box of hair-like segments (what the BVH offers) and rays aimed within 3 radii
    // of the curve: the same result, bit for bit, with and without step 0; and step 0 must reject most box
    // rays, or it is not worth its cost.
    let (mut box_rays, mut box_misses, mut rejected, mut hits) = (0, 0, 0, 0);
    super::super::near_rays(0x5eed_f1a7, |cp, org, dir, tnear, through_box| {
        box_rays += usize::from(through_box);
        let run = |reject, any| {
            intersect_tessellated(
                &RibbonRay::new(org, dir),
                tnear,
                f32::INFINITY,
                cp,
                TESSELLATION_RATE,
                reject,
                any,
            )
        };
        let (with, without) = (run(true, false), run(false, false));
        assert_eq!(
            with, without,
            "cp {cp:?}, org {org}, dir {dir}, tnear {tnear}"
        );
        // The any-hit search answers alike, at no smaller t than the closest hit.
        let any = run(true, true);
        assert_eq!(
            any.is_some(),
            with.is_some(),
            "cp {cp:?}, org {org}, dir {dir}"
        );
        if let (Some(a), Some(w)) = (any, with) {
            assert!(a.t >= w.t, "cp {cp:?}, org {org}, dir {dir}");
        }
        hits += usize::from(with.is_some());
        if through_box && with.is_none() {
            box_misses += 1;
            // Step 0 as intersect_tessellated runs it.
            let (rx, ry, _, _) = ray_space(dir);
            let q = cp.map(|c| {
                let p = Vec3::from_slice(&c) - org;
                (rx.dot(p), ry.dot(p))
            });
            let r_max = cp.iter().fold(0.0f32, |m, c| m.max(c[3]));
            rejected += usize::from(origin_far_from_bezier_box(
                Vec4::from_array(q.map(|p| p.0)),
                Vec4::from_array(q.map(|p| p.1)),
                REJECT_RADII * r_max,
            ));
        }
    });
    assert!(hits > 10_000, "too few hits to test: {hits}");
    assert!(
        rejected * 10 > box_misses * 8,
        "step 0 rejects only {rejected} of {box_misses} missing box rays"
    );
}

#[test]
fn four_lanes_give_the_one_by_one_quads_hits_bit_for_bit() {
    // quads4 is the one-quad loop at Embree's rate in SSE lanes: every ray of the early-reject set (box rays
    // and rays aimed at the curve), closest and any hit, must give the same (t, u, v′) bits, or None alike;
    // so must the whole intersector (its ray space computed four points at a time).
    let (mut compared, mut hits) = (0, 0);
    super::super::near_rays(0x4a9e_5e75, |cp, org, dir, tnear, _| {
        let ray = RibbonRay::new(org, dir);
        let (rx, ry, rz) = ray.rows;
        let q = cp.map(|c| {
            let p = Vec3::new(c[0], c[1], c[2]) - org;
            Vec4::new(rx.dot(p), ry.dot(p), rz.dot(p), c[3])
        });
        let extent = q
            .iter()
            .fold(0.0f32, |m, p| m.max(p.truncate().abs().max_element()));
        let eps = 4.0 * f32::EPSILON * extent;
        for any in [false, true] {
            let by_coordinate = std::array::from_fn(|k| [q[0][k], q[1][k], q[2][k], q[3][k]]);
            let lanes = quads4(
                &by_coordinate,
                eps,
                ray.depth_scale,
                tnear,
                f32::INFINITY,
                any,
            );
            let loop_ = quads_one_by_one(
                &q,
                eps,
                ray.depth_scale,
                TESSELLATION_RATE,
                tnear,
                f32::INFINITY,
                any,
            );
            let bits = |h: Option<(f32, f32, f32)>| h.map(|(t, u, v)| [t, u, v].map(f32::to_bits));
            assert_eq!(
                bits(lanes),
                bits(loop_),
                "any {any}, cp {cp:?}, org {org}, dir {dir}"
            );
            // The intersector's own step 1 (four points in SSE lanes) gives the point-by-point ray space
            // above, bit for bit, hence the same hit.
            let whole = intersect_tessellated(
                &ray,
                tnear,
                f32::INFINITY,
                cp,
                TESSELLATION_RATE,
                false,
                any,
            );
            assert_eq!(
                whole.map(|h| [h.t, h.u, h.v].map(f32::to_bits)),
                lanes.map(|(t, u, v)| {
                    let h = hit_at(&cp, t, u, v);
                    [h.t, h.u, h.v].map(f32::to_bits)
                }),
                "any {any}, cp {cp:?}, org {org}, dir {dir}: intersect_tessellated"
            );
            compared += 1;
            hits += usize::from(lanes.is_some());
        }
    });
    assert!(
        hits > 10_000,
        "too few hits to compare: {hits} of {compared}"
    );
}

#[test]
fn agrees_with_embree_on_random_single_segments() {
    let device = Device::new().expect("embree device");
    single_segments(&device, 0xf1a7_0001, false, TESSELLATION_RATE)
        .check("single segments, hair-like");
    single_segments(&device, 0xf1a7_0003, true, TESSELLATION_RATE).check("single segments, wild");
}

#[test]
fn another_tessellation_rate_disagrees_with_embree() {
    // The comparison is sensitive to the tessellation: at any rate but Embree's 4 the chords of bent segments
    // move silhouettes and hit points, and the agreement test above fails. Measured (hair-like / wild, of 90 000
    // rays): hit/miss disagreements 339 / 2045 at rate 3, 170 / 1140 at 5, 247 / 1735 at 8.
    let device = Device::new().expect("embree device");
    for rate in [3, 5, 8] {
        for (name, seed, wild) in [
            ("hair-like", 0xf1a7_0001, false),
            ("wild", 0xf1a7_0003, true),
        ] {
            let a = single_segments(&device, seed, wild, rate);
            assert!(
                a.hit_miss * 1000 > a.rays,
                "{name}: rate {rate} agrees with Embree's rate 4 on hit/miss: {} of {}",
                a.hit_miss,
                a.rays
            );
        }
    }
}

#[test]
fn agrees_with_embree_on_a_random_bundle() {
    // 40 wavy strands of 10 points (9 segments each, phantom end points, tapered radii 0.02 → 0.01) rooted
    // in a disk of radius 0.3, growing up; rays near the strands, and secondary rays leaving Embree's hits in
    // random directions (they start on a ribbon: self-intersection avoidance decides those).
    let mut rng = Rng::new(0xf1a7_0002);
    let mut model = HairModel {
        strand_offsets: vec![0],
        ..Default::default()
    };
    for _ in 0..40 {
        let mut p = Vec3::new(rng.range(-0.3, 0.3), 0.0, rng.range(-0.3, 0.3));
        let mut heading = Vec3::Y;
        for _ in 0..10 {
            model.points.push(p);
            model.radius.push(0.02);
            model.transparency.push(0.0);
            model.color.push([0.5; 3]);
            heading = (heading + 0.5 * rng.unit_vector()).normalize();
            p += 0.15 * heading;
        }
        model.strand_offsets.push(model.points.len() as u32);
    }
    let strands = Strands::from_model(&model);
    let tracer = EmbreeTracer::new(&strands, CurveKind::Flat).expect("embree flat curves");
    let (mut primary, mut secondary) = (Agreement::default(), Agreement::default());
    for _ in 0..20_000 {
        let ray = ray_near_curve(&mut rng, &strands);
        let e = embree(&tracer, &ray);
        primary.add(&ray, ours(&strands, &ray), e);
        if let Some((t, ..)) = e {
            let next = Ray::new(ray.at(t), rng.unit_vector());
            secondary.add(&next, ours(&strands, &next), embree(&tracer, &next));
        }
    }
    primary.check("bundle, primary rays");
    secondary.check("bundle, secondary rays from hits");
}
