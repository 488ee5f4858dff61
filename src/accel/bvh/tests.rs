//! Build invariants, determinism across thread counts, traversal against brute force over the segments' boxes,
//! degenerate input, containment of Embree's hits, and (ignored, printing) the build measurements.

use glam::Vec3;

use super::*;
use crate::accel::embree::EmbreeTracer;
use crate::accel::testing::{hair_file, random_bundle};
use crate::accel::{CurveKind, Tracer};
use crate::hair::HairModel;
use crate::util::hash::SplitMix64;

mod embree;

thread_local! {
    /// Nodes visited by this thread's traversals (counted in test builds only), for the measurements.
    pub(super) static NODE_VISITS: std::cell::Cell<u64> = const { std::cell::Cell::new(0) };
}

/// Every bounding mode, the default first.
const BOUNDINGS: [Bounding; 7] = [
    Bounding::Hull,
    Bounding::Spans { levels: 1 },
    Bounding::Spans { levels: 2 },
    Bounding::Spans { levels: 3 },
    Bounding::SpanRefs { levels: 1 },
    Bounding::SpanRefs { levels: 2 },
    Bounding::SpanRefs { levels: 3 },
];

/// Random rays per brute-force comparison on the random bundle: each is checked against every segment.
const BUNDLE_RAYS: usize = 2000;

/// Random rays on straight.hair (brute force over all its segments per ray, so fewer).
const FILE_RAYS: usize = 200;

/// Curve samples per segment when checking that the swept curve lies in its leaf box.
const CURVE_SAMPLES: usize = 16;

/// Relative slack for the curve-sample containment check: `Strands::eval` and the subdivision round differently
/// (a few ulps of the coordinates).
const EVAL_SLACK: f32 = 1e-5;

/// Random rays through the box `(lo, hi)`: from outside and from inside, some with zero direction components
/// (axis-parallel and in-plane rays) and some with a finite `[tnear, tfar]`.
fn random_rays(lo: Vec3, hi: Vec3, n: usize, seed: u64) -> Vec<Ray> {
    let mut rng = SplitMix64::new(seed, 1);
    let mut u = || rng.next_f32();
    let (centre, size) = (0.5 * (lo + hi), hi - lo);
    (0..n)
        .map(|i| {
            let inside = lo + size * Vec3::new(u(), u(), u());
            let target = lo + size * Vec3::new(u(), u(), u());
            let mut dir = Vec3::new(u(), u(), u()) * 2.0 - Vec3::ONE;
            let origin = match i % 3 {
                0 => {
                    centre
                        - 2.0 * size.length() * (target - centre + 0.1 * dir).normalize_or(Vec3::X)
                }
                _ => inside,
            };
            if i % 3 == 0 {
                dir = target - origin;
            }
            // Every 5th ray keeps only one or two axes: 1/d is ±∞ on the others.
            match i % 10 {
                5 => dir = Vec3::new(dir.x, 0.0, 0.0),
                7 => dir = Vec3::new(0.0, -0.0, dir.z),
                9 => dir = Vec3::new(dir.x, dir.y, -0.0),
                _ => {}
            }
            if dir == Vec3::ZERO {
                dir = Vec3::Y;
            }
            if i % 4 == 1 {
                let len = size.length() / dir.length();
                Ray::segment(origin, dir, 0.2 * len * u(), 0.3 * len + len * u())
            } else {
                Ray::new(origin, dir)
            }
        })
        .collect()
}

fn model_bounds(strands: &Strands) -> (Vec3, Vec3) {
    strands.bounds()
}

/// The boxes the tree was built over, per segment (one box, or one per span for `SpanRefs`).
fn primitive_boxes(strands: &Strands, segment: u32, bounding: Bounding) -> Vec<Aabb> {
    match bounding {
        Bounding::SpanRefs { .. } => {
            let mut v = Vec::new();
            build::for_each_span(strands, segment, bounding, |b| v.push(b));
            v
        }
        _ => vec![segment_bounds(strands, segment, bounding)],
    }
}

fn spans_per_segment(bounding: Bounding) -> usize {
    match bounding {
        Bounding::SpanRefs { levels } => 1 << levels,
        _ => 1,
    }
}

/// Depth of the deepest leaf below `index` (the root is at depth 0).
fn depth(nodes: &[Node], index: usize) -> usize {
    let n = &nodes[index];
    if n.is_leaf() {
        0
    } else {
        1 + depth(nodes, index + 1).max(depth(nodes, n.offset as usize))
    }
}

/// Checks every structural invariant, panicking with the node or segment that breaks it.
fn check_invariants(bvh: &Bvh, strands: &Strands, what: &str) {
    // One piece: one walk over the nodes checks every invariant, each with the node that breaks it.
    let nodes = bvh.nodes();
    let bounding = bvh.options().bounding;
    assert_eq!(
        bvh.primitives().len(),
        strands.segment_count() * spans_per_segment(bounding),
        "{what}: primitive count"
    );
    if strands.segment_count() == 0 {
        assert!(nodes.is_empty(), "{what}: nodes for an empty model");
        return;
    }
    // Walk the tree: children inside parents, leaves covering the primitive array exactly once.
    let mut covered = vec![0u32; bvh.primitives().len()];
    let mut leaf_of = vec![Vec::new(); strands.segment_count()];
    let mut stack = vec![0usize];
    let mut visited = 0;
    while let Some(i) = stack.pop() {
        visited += 1;
        let n = &nodes[i];
        if n.is_leaf() {
            assert!(
                n.count as usize <= bvh.options().max_leaf,
                "{what}: leaf {i} holds {} > max_leaf",
                n.count
            );
            let range = n.offset as usize..n.offset as usize + n.count as usize;
            for k in range {
                covered[k] += 1;
                leaf_of[bvh.primitives()[k] as usize].push(i);
            }
        } else {
            for child in [i + 1, n.offset as usize] {
                assert!(
                    child > i && child < nodes.len(),
                    "{what}: node {i} child {child}"
                );
                assert!(
                    n.bounds().contains(&nodes[child].bounds()),
                    "{what}: child {child} {:?} outside parent {i} {:?}",
                    nodes[child].bounds(),
                    n.bounds()
                );
                stack.push(child);
            }
        }
    }
    assert_eq!(visited, nodes.len(), "{what}: unreachable nodes");
    if let Some(k) = covered.iter().position(|&c| c != 1) {
        panic!("{what}: primitive slot {k} is in {} leaves", covered[k]);
    }
    assert!(
        depth(nodes, 0) <= STACK_SIZE,
        "{what}: depth {} > stack",
        depth(nodes, 0)
    );
    let scale = {
        let (lo, hi) = model_bounds(strands);
        lo.abs().max(hi.abs()).max_element().max(1.0)
    };
    for (segment, leaves) in leaf_of.iter().enumerate() {
        let segment = segment as u32;
        assert_eq!(
            leaves.len(),
            spans_per_segment(bounding),
            "{what}: segment {segment} is in {} leaves",
            leaves.len()
        );
        let leaf_union = leaves
            .iter()
            .fold(Aabb::EMPTY, |b, &l| b.union(nodes[l].bounds()));
        // Each of the segment's boxes inside a leaf that holds it.
        for b in primitive_boxes(strands, segment, bounding) {
            assert!(
                leaves.iter().any(|&l| nodes[l].bounds().contains(&b)),
                "{what}: segment {segment} box {b:?} in none of its leaves"
            );
        }
        // The hull of the control points (each ± its radius) inside the leaf for hull bounds.
        if bounding == Bounding::Hull {
            let first = strands.segment_first[segment as usize] as usize;
            for c in &strands.control_points[first..first + 4] {
                let (p, r) = (Vec3::new(c[0], c[1], c[2]), Vec3::splat(c[3]));
                let b = Aabb {
                    lo: p - r,
                    hi: p + r,
                };
                assert!(
                    leaf_union.contains(&b),
                    "{what}: segment {segment} control point {c:?} outside its leaf {leaf_union:?}"
                );
            }
        }
        // The swept curve itself (points ± radius along it) inside its leaves, for every mode.
        let slack = Vec3::splat(EVAL_SLACK * scale);
        for s in 0..=CURVE_SAMPLES {
            let c = strands.eval(segment, s as f32 / CURVE_SAMPLES as f32);
            let b = Aabb {
                lo: c.position - Vec3::splat(c.radius) + slack,
                hi: c.position + Vec3::splat(c.radius) - slack,
            };
            assert!(
                leaf_union.contains(&b),
                "{what}: segment {segment} at u = {s}/{CURVE_SAMPLES}: {c:?} outside its leaves {leaf_union:?}"
            );
        }
    }
}

/// The brute-force answers for `ray` over the primitive boxes: the nearest entry and the set of segments hit.
fn brute_force(boxes: &[(u32, Aabb)], ray: &Ray) -> (Option<f32>, Vec<u32>) {
    let r = RayInv::new(ray);
    let mut nearest: Option<f32> = None;
    let mut hit = Vec::new();
    for (segment, b) in boxes {
        if let Some(t) = b.entry(&r) {
            nearest = Some(nearest.map_or(t, |n| n.min(t)));
            hit.push(*segment);
        }
    }
    hit.sort_unstable();
    hit.dedup();
    (nearest, hit)
}

/// Every (segment, box) pair, and the boxes per segment.
type SegmentBoxes = (Vec<(u32, Aabb)>, Vec<Vec<Aabb>>);

/// The primitive boxes of every segment under `bounding`: as one list of (segment, box), and per segment.
fn all_boxes(strands: &Strands, bounding: Bounding) -> SegmentBoxes {
    let seg_boxes: Vec<Vec<Aabb>> = (0..strands.segment_count() as u32)
        .map(|s| primitive_boxes(strands, s, bounding))
        .collect();
    let boxes = seg_boxes
        .iter()
        .enumerate()
        .flat_map(|(s, b)| b.iter().map(move |b| (s as u32, *b)))
        .collect();
    (boxes, seg_boxes)
}

/// Traversal with the box as primitive against brute force: the same nearest entry distance, and the all-hits
/// walk reaches exactly the segments whose boxes the ray crosses. Returns (rays that hit, segments reported).
fn check_traversal(bvh: &Bvh, strands: &Strands, rays: &[Ray], what: &str) -> (usize, usize) {
    let (boxes, seg_boxes) = all_boxes(strands, bvh.options().bounding);
    let (mut hits, mut reported) = (0, 0);
    for (i, ray) in rays.iter().enumerate() {
        let (want_t, want_set) = brute_force(&boxes, ray);
        // The primitive test: the segment's nearest box entry before the current tfar.
        let got_t = bvh.closest(ray, |segment, tfar| {
            let clipped = Ray { tfar, ..*ray };
            let r = RayInv::new(&clipped);
            seg_boxes[segment as usize]
                .iter()
                .filter_map(|b| b.entry(&r))
                .min_by(f32::total_cmp)
        });
        assert_eq!(
            got_t.map(f32::to_bits),
            want_t.map(f32::to_bits),
            "{what}: ray {i} {ray:?}: closest {got_t:?}, brute force {want_t:?}"
        );
        let mut got_set = Vec::new();
        let stopped = bvh.for_each(ray, |segment, _| {
            let r = RayInv::new(ray);
            if seg_boxes[segment as usize]
                .iter()
                .any(|b| b.entry(&r).is_some())
            {
                got_set.push(segment);
            }
            Control::Continue
        });
        assert!(!stopped, "{what}: walk stopped by itself");
        got_set.sort_unstable();
        got_set.dedup();
        assert_eq!(
            got_set, want_set,
            "{what}: ray {i} {ray:?}: all-hits walk differs from brute force"
        );
        hits += usize::from(want_t.is_some());
        reported += want_set.len();
    }
    (hits, reported)
}

/// The cross-section spheres of a segment at u = 0, ¼, ½, ¾, 1 (centre c(u), radius r(u)): primitives inside its
/// swept surface, so inside every bound the trees keep for it.
fn cross_sections(cp: [[f32; 4]; 4]) -> [glam::Vec4; 5] {
    [0.0, 0.25, 0.5, 0.75, 1.0].map(|u| {
        let b = crate::hair::strands::bspline_basis(u);
        (0..4).map(|k| b[k] * glam::Vec4::from_array(cp[k])).sum()
    })
}

/// The nearest entry of `ray` in `[ray.tnear, tfar]` into the spheres.
fn sphere_hit(ray: &Ray, spheres: &[glam::Vec4], tfar: f32) -> Option<f32> {
    let dd = ray.dir.dot(ray.dir);
    spheres
        .iter()
        .filter_map(|c| {
            // Stable form: the closest approach first, so the miss distance is not lost to cancellation.
            let tc = (c.truncate() - ray.origin).dot(ray.dir) / dd;
            let miss2 = (ray.at(tc) - c.truncate()).length_squared();
            if miss2 > c.w * c.w {
                return None;
            }
            let half = ((c.w * c.w - miss2) / dd).sqrt();
            [tc - half, tc + half]
                .into_iter()
                .find(|t| *t >= ray.tnear && *t <= tfar)
        })
        .min_by(f32::total_cmp)
}

/// [`wide::WideBvh`] over `bvh` against brute force, with each segment's [`cross_sections`] as its primitive: the
/// nearest sphere the walk finds is the one a test of every segment finds, bit for bit; the all-hits walk offers
/// every segment with a sphere on the ray, each with its own control points and strand, and offers a segment once
/// unless the tree references it once per span. Returns (rays hitting a sphere, segments offered).
fn check_wide_traversal(
    wide: &wide::WideBvh,
    bounding: Bounding,
    strands: &Strands,
    rays: &[Ray],
    what: &str,
) -> (usize, usize) {
    let once = !matches!(bounding, Bounding::SpanRefs { .. });
    wide.check_bounds(strands, once);
    let spheres: Vec<[glam::Vec4; 5]> = (0..strands.segment_count())
        .map(|s| {
            let first = strands.segment_first[s] as usize;
            let p = &strands.control_points[first..first + 4];
            cross_sections([p[0], p[1], p[2], p[3]])
        })
        .collect();
    let (mut hits, mut offered) = (0, 0);
    for (i, ray) in rays.iter().enumerate() {
        let want_t = spheres
            .iter()
            .filter_map(|s| sphere_hit(ray, s, ray.tfar))
            .min_by(f32::total_cmp);
        let got_t = wide.closest(ray, |p, tfar| {
            sphere_hit(ray, &cross_sections(p.control_points), tfar)
        });
        assert_eq!(
            got_t.map(f32::to_bits),
            want_t.map(f32::to_bits),
            "{what}, wide: ray {i} {ray:?}: closest {got_t:?}, brute force {want_t:?}"
        );
        hits += usize::from(got_t.is_some());
        let mut got = Vec::new();
        assert!(!wide.for_each(ray, |p, _| {
            let first = strands.segment_first[p.segment as usize] as usize;
            assert_eq!(
                p.control_points[..],
                strands.control_points[first..first + 4]
            );
            assert_eq!(p.strand, strands.segment_strand[p.segment as usize]);
            got.push(p.segment);
            Control::Continue
        }));
        got.sort_unstable();
        let all = got.len();
        got.dedup();
        assert!(
            !once || all == got.len(),
            "{what}, wide: ray {i}: a segment offered twice"
        );
        for (s, spheres) in spheres.iter().enumerate() {
            if sphere_hit(ray, spheres, ray.tfar).is_some() {
                assert!(
                    got.binary_search(&(s as u32)).is_ok(),
                    "{what}, wide: ray {i} {ray:?}: segment {s} has a sphere on the ray but was never offered"
                );
            }
        }
        offered += got.len();
    }
    (hits, offered)
}

#[test]
fn wide_nodes_are_128_and_224_bytes() {
    // The boxes (96 or 192 bytes, 16-byte aligned) and 21 bytes of links: one 16-byte step each.
    assert_eq!(std::mem::size_of::<wide::WideNode<wide::Boxes4>>(), 128);
    assert_eq!(std::mem::size_of::<wide::WideNode<wide::Obbs4>>(), 224);
}

#[test]
fn node_is_32_bytes() {
    assert_eq!(std::mem::size_of::<Node>(), 32);
}

#[test]
fn slab_test_is_robust_to_zero_direction_components() {
    let b = Aabb {
        lo: Vec3::ZERO,
        hi: Vec3::ONE,
    };
    let entry = |o: Vec3, d: Vec3| b.entry(&RayInv::new(&Ray::new(o, d)));
    // Along +x inside the y and z slabs, on the box's faces, with +0 and −0 components.
    assert_eq!(entry(Vec3::new(-1.0, 0.5, 0.5), Vec3::X), Some(1.0));
    assert_eq!(entry(Vec3::new(-1.0, 0.0, 1.0), Vec3::X), Some(1.0));
    assert_eq!(
        entry(Vec3::new(-1.0, 0.0, 1.0), Vec3::new(1.0, -0.0, -0.0)),
        Some(1.0)
    );
    assert_eq!(entry(Vec3::new(2.0, 0.5, 0.5), Vec3::NEG_X), Some(1.0));
    // Outside a slab with no motion along it: a miss, whatever the sign of the zero.
    assert_eq!(entry(Vec3::new(-1.0, 1.5, 0.5), Vec3::X), None);
    assert_eq!(
        entry(Vec3::new(-1.0, 1.5, 0.5), Vec3::new(1.0, -0.0, 0.0)),
        None
    );
    assert_eq!(
        entry(Vec3::new(-1.0, -0.5, 0.5), Vec3::new(1.0, -0.0, 0.0)),
        None
    );
    // Starting inside: the entry is tnear.
    assert_eq!(
        entry(Vec3::splat(0.5), Vec3::new(0.3, -0.2, 0.0)),
        Some(0.0)
    );
    // A flat box (zero extent) is still hit through its plane.
    let flat = Aabb {
        lo: Vec3::new(0.0, 0.0, 1.0),
        hi: Vec3::new(1.0, 1.0, 1.0),
    };
    assert_eq!(
        flat.entry(&RayInv::new(&Ray::new(Vec3::splat(0.5), Vec3::Z))),
        Some(0.5)
    );
}

#[test]
fn subdivision_reproduces_the_curve() {
    // The spans of midpoint subdivision are the same cubic: evaluate span k of 2^levels at its start.
    let strands = random_bundle(3, 6, 11);
    let first = strands.segment_first[2] as usize;
    let p: [glam::Vec4; 4] =
        std::array::from_fn(|i| glam::Vec4::from_array(strands.control_points[first + i]));
    let mut starts = Vec::new();
    build_spans_control_points(p, 2, &mut starts);
    for (k, q) in starts.iter().enumerate() {
        let u = k as f32 / 4.0;
        let want = strands.eval(2, u);
        let b = crate::hair::strands::bspline_basis(0.0);
        let got = b[0] * q[0] + b[1] * q[1] + b[2] * q[2] + b[3] * q[3];
        assert!(
            (got.truncate() - want.position).length() < 1e-5 && (got.w - want.radius).abs() < 1e-6,
            "span {k}: {got:?} vs {want:?}"
        );
    }
}

/// The control points of the 2^levels spans, by the same rule as `build::subdivide`.
fn build_spans_control_points(p: [glam::Vec4; 4], levels: u32, out: &mut Vec<[glam::Vec4; 4]>) {
    if levels == 0 {
        out.push(p);
        return;
    }
    let e = |i: usize| 0.5 * (p[i] + p[i + 1]);
    let v = |i: usize| 0.125 * (p[i - 1] + 6.0 * p[i] + p[i + 1]);
    build_spans_control_points([e(0), v(1), e(1), v(2)], levels - 1, out);
    build_spans_control_points([v(1), e(1), v(2), e(2)], levels - 1, out);
}

#[test]
fn random_bundle_builds_valid_trees_that_traverse_like_brute_force() {
    let strands = random_bundle(300, 8, 1);
    let (lo, hi) = model_bounds(&strands);
    let rays = random_rays(lo, hi, BUNDLE_RAYS, 2);
    for bounding in BOUNDINGS {
        for max_leaf in [1, 4, 8] {
            let options = BuildOptions {
                bounding,
                max_leaf,
                ..BuildOptions::default()
            };
            let what = format!("random bundle, {options:?}");
            let bvh = Bvh::build(&strands, options);
            check_invariants(&bvh, &strands, &what);
            let (hits, reported) = check_traversal(&bvh, &strands, &rays, &what);
            // Guard against a vacuous test: most rays must hit something.
            assert!(hits > rays.len() / 4, "{what}: only {hits} rays hit");
            assert!(reported > rays.len(), "{what}: {reported} boxes crossed");
            // One chunk (span references: two per segment, more than one chunk): the lean build is the collapse
            // of the whole binary tree, bit for bit.
            let wide = wide::WideBvh::build(&strands, options);
            assert!(
                bvh.primitives().len() >= build::PARALLEL_MIN
                    || wide == wide::WideBvh::new(&bvh, &strands),
                "{what}: the lean build differs from the collapsed binary tree"
            );
            let (hits, offered) = check_wide_traversal(&wide, bounding, &strands, &rays, &what);
            assert!(
                offered > rays.len() / 2,
                "{what}, wide: {offered} segments offered"
            );
            assert!(
                hits > rays.len() / 20,
                "{what}, wide: only {hits} sphere hits"
            );
        }
    }
}

#[test]
fn straight_hair_builds_a_valid_tree_that_traverses_like_brute_force() {
    let strands = hair_file("straight.hair");
    let (lo, hi) = model_bounds(&strands);
    let rays = random_rays(lo, hi, FILE_RAYS, 3);
    for bounding in [Bounding::Hull, Bounding::Spans { levels: 2 }] {
        let options = BuildOptions {
            bounding,
            ..BuildOptions::default()
        };
        let what = format!("straight.hair, {options:?}");
        let bvh = Bvh::build(&strands, options);
        check_invariants(&bvh, &strands, &what);
        let (hits, _) = check_traversal(&bvh, &strands, &rays, &what);
        assert!(hits > rays.len() / 4, "{what}: only {hits} rays hit");
        check_wide_traversal(
            &wide::WideBvh::new(&bvh, &strands),
            bounding,
            &strands,
            &rays,
            &what,
        );
        // Many chunks: the lean build's own tree.
        assert!(strands.segment_count() > 4 * build::PARALLEL_MIN);
        let lean = wide::WideBvh::build(&strands, options);
        let (hits, _) = check_wide_traversal(&lean, bounding, &strands, &rays, &what);
        assert!(
            hits > rays.len() / 20,
            "{what}, lean: only {hits} sphere hits"
        );
    }
}

/// Builds on pools of 1 and 2 threads and compares every node and primitive bit for bit.
fn check_deterministic(strands: &Strands, what: &str) {
    let pool = |n| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .expect("thread pool")
    };
    for bounding in [
        Bounding::Hull,
        Bounding::Spans { levels: 2 },
        Bounding::SpanRefs { levels: 1 },
    ] {
        let options = BuildOptions {
            bounding,
            ..BuildOptions::default()
        };
        let one = pool(1).install(|| Bvh::build(strands, options));
        let two = pool(2).install(|| Bvh::build(strands, options));
        assert!(
            one.primitives().len() >= 2 * build::PARALLEL_MIN,
            "{what}: too small to take the parallel path"
        );
        assert_eq!(one.nodes().len(), two.nodes().len(), "{what}: node counts");
        let bits = |b: &Bvh| -> Vec<[u32; 8]> {
            b.nodes()
                .iter()
                .map(|n| {
                    [
                        n.lo[0].to_bits(),
                        n.lo[1].to_bits(),
                        n.lo[2].to_bits(),
                        n.hi[0].to_bits(),
                        n.hi[1].to_bits(),
                        n.hi[2].to_bits(),
                        n.offset,
                        n.count,
                    ]
                })
                .collect()
        };
        assert!(
            bits(&one) == bits(&two),
            "{what}, {bounding:?}: nodes differ between 1 and 2 threads"
        );
        assert_eq!(
            one.primitives(),
            two.primitives(),
            "{what}: primitive order"
        );
        // The lean wide build: chunks land where they finish, so compare the trees, not the arrays.
        let one = pool(1).install(|| wide::WideBvh::build(strands, options));
        let two = pool(2).install(|| wide::WideBvh::build(strands, options));
        assert!(
            one.shape() == two.shape(),
            "{what}, {bounding:?}: lean wide trees differ between 1 and 2 threads"
        );
    }
}

#[test]
fn build_is_the_same_for_one_and_two_threads() {
    check_deterministic(&random_bundle(3000, 8, 5), "random bundle");
    check_deterministic(&hair_file("straight.hair"), "straight.hair");
}

/// One strand of `n` copies of the same point (zero-length segments), radius `radius`.
fn coincident_strand(n: usize, radius: f32) -> HairModel {
    HairModel {
        points: vec![Vec3::new(0.25, -0.5, 1.0); n],
        strand_offsets: vec![0, n as u32],
        radius: vec![radius; n],
        radius_from_file: true,
        transparency: vec![0.0; n],
        color: vec![[0.5; 3]; n],
        ..Default::default()
    }
}

#[test]
fn degenerate_input_builds_and_traverses() {
    let rays = random_rays(Vec3::splat(-1.0), Vec3::splat(1.5), 300, 9);
    // Empty model: no nodes, nothing hit, the callback never called.
    let empty = Bvh::build(&Strands::default(), BuildOptions::default());
    assert!(empty.nodes().is_empty() && empty.primitives().is_empty());
    for ray in &rays {
        assert_eq!(
            empty.closest(ray, |s, _| panic!("segment {s} in an empty bvh")),
            None
        );
        assert!(!empty.for_each(ray, |s, _| panic!("segment {s} in an empty bvh")));
    }
    let lean = wide::WideBvh::build(&Strands::default(), BuildOptions::default());
    assert!(lean == wide::WideBvh::new(&empty, &Strands::default()));
    check_wide_traversal(
        &lean,
        BuildOptions::default().bounding,
        &Strands::default(),
        &rays,
        "empty",
    );
    let cases = [
        ("one strand", random_bundle(1, 5, 3)),
        (
            "zero-length segments",
            Strands::from_model(&coincident_strand(40, 0.01)),
        ),
        (
            "zero-length segments of zero radius",
            Strands::from_model(&coincident_strand(40, 0.0)),
        ),
    ];
    for (what, strands) in &cases {
        for bounding in BOUNDINGS {
            let options = BuildOptions {
                bounding,
                ..BuildOptions::default()
            };
            let bvh = Bvh::build(strands, options);
            let what = format!("{what}, {bounding:?}");
            check_invariants(&bvh, strands, &what);
            check_traversal(&bvh, strands, &rays, &what);
            let lean = wide::WideBvh::build(strands, options);
            assert!(lean == wide::WideBvh::new(&bvh, strands), "{what}");
            check_wide_traversal(&lean, bounding, strands, &rays, &what);
        }
    }
    // A ray through the coincident point's box hits it: the traversal handles zero-size boxes.
    let strands = &cases[1].1;
    let bvh = Bvh::build(strands, BuildOptions::default());
    let ray = Ray::new(Vec3::new(0.25, -0.5, -3.0), Vec3::Z);
    let t = bvh.closest(&ray, |s, tfar| {
        segment_bounds(strands, s, Bounding::Hull).entry(&RayInv::new(&Ray { tfar, ..ray }))
    });
    assert!(
        t.is_some_and(|t| (t - 3.99).abs() < 1e-4),
        "zero-length segments: {t:?}"
    );
}

#[test]
fn all_hits_walk_stops_when_asked() {
    let strands = random_bundle(200, 6, 4);
    let bvh = Bvh::build(&strands, BuildOptions::default());
    let ray = Ray::new(Vec3::new(-3.0, 0.0, 0.0), Vec3::X);
    let mut calls = 0;
    assert!(bvh.for_each(&ray, |_, _| {
        calls += 1;
        Control::Stop
    }));
    assert_eq!(calls, 1);
}

/// Two bundles of `per_bundle` straight strands of `points` points each and length 2, crossing at right angles at
/// the origin (strands along (1, 1, 0) and (1, −1, 0), each bundle 0.1 × 0.1 across): an X that no axis-aligned
/// plane separates. Strands of the first bundle come first.
fn crossing_bundles(per_bundle: usize, points: usize) -> HairModel {
    let mut rng = SplitMix64::new(17, 3);
    let mut model = HairModel {
        strand_offsets: vec![0],
        radius_from_file: true,
        ..Default::default()
    };
    for bundle in 0..2 {
        let along = if bundle == 0 {
            Vec3::new(1.0, 1.0, 0.0)
        } else {
            Vec3::new(1.0, -1.0, 0.0)
        }
        .normalize();
        let across = Vec3::Z.cross(along);
        for _ in 0..per_bundle {
            let offset = across * (rng.next_f32() - 0.5) + Vec3::Z * (rng.next_f32() - 0.5);
            let start = -along + 0.1 * offset;
            for k in 0..points {
                model
                    .points
                    .push(start + along * (2.0 * k as f32 / (points - 1) as f32));
                model.radius.push(0.002);
                model.transparency.push(0.0);
                model.color.push([0.5; 3]);
            }
            model.strand_offsets.push(model.points.len() as u32);
        }
    }
    model
}

#[test]
fn oriented_splits_separate_crossing_bundles() {
    let strands = Strands::from_model(&crossing_bundles(12, 9));
    assert!(strands.segment_count() <= build::ORIENTED_SPLIT_MAX);
    let first_b = strands.segment_count() as u32 / 2;
    // The root's two children: which bundles each holds.
    let bundles_below = |bvh: &Bvh| {
        let nodes = bvh.nodes();
        [1, nodes[0].offset as usize].map(|child| {
            let (first, count) = subtree_range(nodes, child);
            let below = &bvh.primitives()[first..first + count];
            (
                below.iter().any(|&s| s < first_b),
                below.iter().any(|&s| s >= first_b),
            )
        })
    };
    let aligned = Bvh::build(
        &strands,
        BuildOptions {
            oriented_splits: false,
            ..BuildOptions::default()
        },
    );
    assert!(
        bundles_below(&aligned).contains(&(true, true)),
        "the aligned SAH should mix the crossing bundles at the root: {:?}",
        bundles_below(&aligned)
    );
    let oriented = Bvh::build(
        &strands,
        BuildOptions {
            oriented_splits: true,
            ..BuildOptions::default()
        },
    );
    let what = "crossing bundles, oriented splits";
    check_invariants(&oriented, &strands, what);
    let (lo, hi) = model_bounds(&strands);
    let rays = random_rays(lo, hi, BUNDLE_RAYS, 5);
    let (hits, _) = check_traversal(&oriented, &strands, &rays, what);
    assert!(hits > rays.len() / 20, "{what}: only {hits} rays hit");
    let options = oriented.options();
    let lean = wide::WideBvh::build(&strands, options);
    assert!(lean == wide::WideBvh::new(&oriented, &strands), "{what}");
    check_wide_traversal(&lean, options.bounding, &strands, &rays, what);
    let split = bundles_below(&oriented);
    assert!(
        split == [(true, false), (false, true)] || split == [(false, true), (true, false)],
        "oriented splits should put one bundle on each side of the root: {split:?}"
    );
}

/// First primitive and primitive count below binary node `i`.
fn subtree_range(nodes: &[Node], i: usize) -> (usize, usize) {
    let mut stack = vec![i];
    let (mut lo, mut hi) = (usize::MAX, 0);
    while let Some(k) = stack.pop() {
        let n = &nodes[k];
        if n.is_leaf() {
            lo = lo.min(n.offset as usize);
            hi = hi.max((n.offset + n.count) as usize);
        } else {
            stack.extend([k + 1, n.offset as usize]);
        }
    }
    (lo, hi - lo)
}

#[test]
fn a_tree_over_boxes_is_the_curve_tree_over_the_same_boxes() {
    // The box build and the curve build are one build: over each segment's box, without oriented splits, they
    // give the same nodes and primitive order.
    let strands = random_bundle(3000, 8, 7);
    for bounding in [Bounding::Hull, Bounding::Spans { levels: 2 }] {
        for max_leaf in [1, 4] {
            let options = BuildOptions {
                bounding,
                max_leaf,
                ..BuildOptions::default()
            };
            let boxes: Vec<Aabb> = (0..strands.segment_count() as u32)
                .map(|s| segment_bounds(&strands, s, bounding))
                .collect();
            let from_boxes = Bvh::build_boxes(&boxes, options);
            let from_curves = Bvh::build(&strands, options);
            assert!(from_boxes == from_curves, "{options:?}: trees differ");
        }
    }
    // Oriented splits do not apply to boxes, and an empty list builds an empty tree.
    let oriented = BuildOptions {
        oriented_splits: true,
        ..BuildOptions::default()
    };
    assert!(
        !Bvh::build_boxes(
            &[Aabb::EMPTY.union(Aabb {
                lo: Vec3::ZERO,
                hi: Vec3::ONE
            })],
            oriented
        )
        .options()
        .oriented_splits
    );
    assert!(Bvh::build_boxes(&[], oriented).nodes().is_empty());
}
