//! The BVH's boxes against Embree's hits: every point where Embree hits a strand lies in that segment's box.

use super::*;

/// Where Embree hits a strand, that point lies in the hit segment's box (to Embree's numerical tolerance), so
/// the BVH's walk offers the segment to the curve test: the boxes are conservative for the real surfaces.
fn check_embree_hits_inside_boxes(strands: &Strands, rays: &[Ray], what: &str) -> usize {
    let scale = {
        let (lo, hi) = model_bounds(strands);
        (hi - lo).max_element()
    };
    // Embree's round-curve hits are within ~3e-5 of the exact surface on unit-scale scenes (tests/embree.rs).
    let tolerance = Vec3::splat(1e-4 * scale.max(1.0));
    let mut checked = 0;
    for kind in [CurveKind::Round, CurveKind::Flat] {
        let tracer =
            EmbreeTracer::new(strands, kind).unwrap_or_else(|e| panic!("{what}: embree: {e}"));
        for bounding in [Bounding::Hull, Bounding::Spans { levels: 2 }] {
            let bvh = Bvh::build(
                strands,
                BuildOptions {
                    bounding,
                    ..BuildOptions::default()
                },
            );
            let wide = wide::WideBvh::new(&bvh, strands);
            for (i, ray) in rays.iter().enumerate() {
                let Some(hit) = tracer.intersect(ray).expect("valid ray") else {
                    continue;
                };
                let p = ray.origin + hit.t * ray.dir;
                let b = segment_bounds(strands, hit.segment, bounding);
                assert!(
                    p.cmpge(b.lo - tolerance).all() && p.cmple(b.hi + tolerance).all(),
                    "{what}, {kind:?}, {bounding:?}: ray {i}: embree hit {p} on segment {} outside its box {b:?}",
                    hit.segment
                );
                // Each walk stops at Embree's segment, so it stopped exactly when it offered it.
                let up_to_hit = Ray {
                    tfar: hit.t * 1.001 + 1e-4,
                    ..*ray
                };
                let stop_at = |segment: u32| {
                    if segment == hit.segment {
                        Control::Stop
                    } else {
                        Control::Continue
                    }
                };
                let offered = bvh.for_each(&up_to_hit, |s, _| stop_at(s));
                assert!(
                    offered,
                    "{what}, {kind:?}, {bounding:?}: ray {i}: walk never offered embree's segment {}",
                    hit.segment
                );
                // The wide tree's bounds (aligned and oriented) let Embree's segment through too.
                let offered = wide.for_each(&up_to_hit, |p, _| stop_at(p.segment));
                assert!(
                    offered,
                    "{what}, {kind:?}, {bounding:?}: ray {i}: the wide walk never offered embree's segment {}",
                    hit.segment
                );
                // The unordered walk offers the same segments (leaves deferred, none lost), each once.
                let mut ordered = Vec::new();
                wide.for_each(ray, |p, _| {
                    ordered.push(p.segment);
                    Control::Continue
                });
                let mut unordered = Vec::new();
                wide.for_each_unordered(ray, |p, _| {
                    unordered.push(p.segment);
                    Control::Continue
                });
                ordered.sort_unstable();
                unordered.sort_unstable();
                assert_eq!(
                    ordered, unordered,
                    "{what}, {kind:?}, {bounding:?}: ray {i}"
                );
                assert!(wide.for_each_unordered(&up_to_hit, |p, _| stop_at(p.segment)));
                checked += 1;
            }
        }
    }
    checked
}

#[test]
fn embree_hits_lie_in_the_segment_boxes() {
    let bundle = random_bundle(500, 8, 7);
    let (lo, hi) = model_bounds(&bundle);
    let checked = check_embree_hits_inside_boxes(&bundle, &random_rays(lo, hi, 4000, 8), "bundle");
    assert!(checked > 1000, "bundle: only {checked} embree hits");
    let hair = hair_file("straight.hair");
    let (lo, hi) = model_bounds(&hair);
    let checked =
        check_embree_hits_inside_boxes(&hair, &random_rays(lo, hi, 4000, 9), "straight.hair");
    assert!(checked > 1000, "straight.hair: only {checked} embree hits");
}
