//! Embree's packet queries (8 and 16 rays per call) against its single-ray queries on a random bundle of wavy,
//! semi-transparent strands, for round and flat curves: the same hits within the agreement criterion of `bench
//! replay --packets` (same strand and segment, |Δt| ≤ 1e-4·t), the same occlusion, per-lane presence keys and
//! ignored strands honoured, lanes without a ray left untouched, and invalid rays reported per lane without
//! reaching Embree.

use cuticle::accel::embree::EmbreeTracer;
use cuticle::accel::{CurveKind, Hit, Tracer};
use cuticle::hair::{HairModel, Strands};
use cuticle::ray::{InvalidRay, Ray};
use cuticle::util::hash::SplitMix64;
use glam::Vec3;

const KINDS: [CurveKind; 2] = [CurveKind::Round, CurveKind::Flat];

/// Relative hit-distance tolerance of the agreement criterion.
const T_RELATIVE: f32 = 1e-4;

/// Packet rays per width and kind.
const RAYS: usize = 4096;

/// At least this fraction of closest hits agree (the rest: a grazing ray on the other side of a surface, or a joint
/// reported on the neighbouring segment).
const MIN_AGREEMENT: f64 = 0.99;

/// 300 wavy strands of 12 points in the cube [−1, 1]³, radii 0.005–0.02, opacity 0.5 (so the stochastic filter
/// decides).
fn bundle(seed: u64) -> Strands {
    let mut rng = SplitMix64::new(seed, 0);
    let mut u = || rng.next_f32();
    let mut model = HairModel {
        strand_offsets: vec![0],
        ..Default::default()
    };
    for _ in 0..300 {
        let mut p = Vec3::new(u(), u(), u()) * 2.0 - Vec3::ONE;
        let dir = (Vec3::new(u(), u(), u()) * 2.0 - Vec3::ONE).normalize_or(Vec3::Y);
        let radius = 0.005 + 0.015 * u();
        for _ in 0..12 {
            model.points.push(p);
            model.radius.push(radius);
            model.transparency.push(0.5);
            model.color.push([0.5; 3]);
            p += 0.1 * dir + 0.05 * (Vec3::new(u(), u(), u()) - Vec3::splat(0.5));
        }
        model.strand_offsets.push(model.points.len() as u32);
    }
    Strands::from_model(&model)
}

/// A ray from a random point on a sphere of radius 3 towards a random point in the bundle, with its key and the
/// strand it ignores (every fourth ray ignores a strand: the one its key picks).
fn random_query(rng: &mut SplitMix64) -> (Ray, Option<u32>, u64) {
    let mut u = || rng.next_f32();
    let from = (Vec3::new(u(), u(), u()) * 2.0 - Vec3::ONE).normalize_or(Vec3::X) * 3.0;
    let to = Vec3::new(u(), u(), u()) * 1.6 - Vec3::splat(0.8);
    let key = rng.next_u64();
    let ignore = key.is_multiple_of(4).then_some((key >> 8) as u32 % 300);
    (Ray::new(from, to - from), ignore, key)
}

fn agree(a: &Option<Hit>, b: &Option<Hit>) -> bool {
    match (a, b) {
        (None, None) => true,
        (Some(a), Some(b)) => {
            a.strand == b.strand
                && a.segment == b.segment
                && (a.t - b.t).abs() <= T_RELATIVE * a.t.abs().max(b.t.abs())
        }
        _ => false,
    }
}

/// Packets of width `W` (lanes filled `W`, then fewer, so partial packets are traced too) against single rays.
fn packets_match_single_rays<const W: usize>(tracer: &EmbreeTracer, kind: CurveKind) {
    let mut rng = SplitMix64::new(0x5eed ^ W as u64, 1);
    let queries: Vec<_> = (0..RAYS).map(|_| random_query(&mut rng)).collect();
    let (mut agreeing, mut hits, mut total) = (0usize, 0usize, 0usize);
    let mut packets = 0;
    let mut at = 0;
    while at < queries.len() {
        // 1..=W active lanes, cycling.
        let n = (packets % W + 1).min(queries.len() - at);
        packets += 1;
        let group = &queries[at..at + n];
        at += n;
        let rays: [Option<Ray>; W] = std::array::from_fn(|k| group.get(k).map(|q| q.0));
        let ignore: [Option<u32>; W] = std::array::from_fn(|k| group.get(k).and_then(|q| q.1));
        let keys: [u64; W] = std::array::from_fn(|k| group.get(k).map_or(0, |q| q.2));

        let mut opaque = [Ok(None); W];
        tracer.intersect_packet(&rays, &mut opaque);
        let mut stochastic = [Ok(None); W];
        tracer.intersect_stochastic_packet(&rays, &ignore, &keys, &mut stochastic);
        let mut occluded = [Ok(false); W];
        tracer.occluded_stochastic_packet(&rays, &ignore, &keys, &mut occluded);

        for (k, &(ray, ignore, key)) in group.iter().enumerate() {
            let single = tracer.intersect(&ray).unwrap();
            let packet = opaque[k].unwrap();
            agreeing += usize::from(agree(&single, &packet));
            hits += usize::from(single.is_some());
            let single = tracer.intersect_stochastic(&ray, ignore, key).unwrap();
            let packet = stochastic[k].unwrap();
            agreeing += usize::from(agree(&single, &packet));
            if let (Some(i), Some(h)) = (ignore, packet) {
                assert_ne!(
                    h.strand, i,
                    "{kind:?} W={W}: lane {k} hit its ignored strand"
                );
            }
            total += 2;
            // Occlusion has no distance to round: only a ray grazing a surface may differ.
            let single = tracer.occluded_stochastic(&ray, ignore, key).unwrap();
            agreeing += usize::from(single == occluded[k].unwrap());
            total += 1;
        }
    }
    let fraction = agreeing as f64 / total as f64;
    println!(
        "{kind:?} W={W}: {agreeing} of {total} queries agree ({fraction:.5}); {hits} opaque hits"
    );
    assert!(
        hits > RAYS / 4,
        "{kind:?}: only {hits} of {RAYS} rays hit, the test says little"
    );
    assert!(
        fraction >= MIN_AGREEMENT,
        "{kind:?} W={W}: {agreeing} of {total} agree"
    );
}

#[test]
fn packets_return_the_hits_of_single_rays() {
    let strands = bundle(7);
    for kind in KINDS {
        let tracer = EmbreeTracer::new(&strands, kind).unwrap();
        packets_match_single_rays::<8>(&tracer, kind);
        packets_match_single_rays::<16>(&tracer, kind);
    }
}

/// A hit no query returns, to see which lanes a packet wrote.
const UNTOUCHED: Hit = Hit {
    t: -7.0,
    segment: u32::MAX - 1,
    strand: u32::MAX - 1,
    u: -1.0,
    v: -1.0,
    ng: Vec3::ZERO,
};

#[test]
fn masked_lanes_are_untouched_and_invalid_rays_are_errors() {
    let strands = bundle(11);
    let mut rng = SplitMix64::new(3, 3);
    let queries: Vec<_> = (0..16).map(|_| random_query(&mut rng)).collect();
    for kind in KINDS {
        let tracer = EmbreeTracer::new(&strands, kind).unwrap();
        // Lanes 0, 5, 9: no ray. Lanes 2, 7, 12: invalid rays. The rest: valid.
        let bad = |k: usize| match k {
            2 => Some(Ray::new(Vec3::splat(f32::NAN), Vec3::X)),
            7 => Some(Ray::new(Vec3::ZERO, Vec3::ZERO)),
            12 => Some(Ray::segment(Vec3::ZERO, Vec3::X, -1.0, 1.0)),
            _ => None,
        };
        let rays: [Option<Ray>; 16] = std::array::from_fn(|k| match k {
            0 | 5 | 9 => None,
            2 | 7 | 12 => bad(k),
            _ => Some(queries[k].0),
        });
        let expected_error = |k: usize| match k {
            2 => InvalidRay::NotFinite,
            7 => InvalidRay::ZeroDirection,
            _ => InvalidRay::BadInterval,
        };
        let ignore = [None; 16];
        let keys: [u64; 16] = std::array::from_fn(|k| queries[k].2);

        let mut hits = [Ok(Some(UNTOUCHED)); 16];
        tracer.intersect_packet(&rays, &mut hits);
        let mut stochastic = [Ok(Some(UNTOUCHED)); 16];
        tracer.intersect_stochastic_packet(&rays, &ignore, &keys, &mut stochastic);
        let mut occluded = [Err(InvalidRay::OriginTooFar); 16];
        tracer.occluded_stochastic_packet(&rays, &ignore, &keys, &mut occluded);
        for k in 0..16 {
            match k {
                0 | 5 | 9 => {
                    assert_eq!(hits[k], Ok(Some(UNTOUCHED)), "{kind:?} lane {k}");
                    assert_eq!(stochastic[k], Ok(Some(UNTOUCHED)), "{kind:?} lane {k}");
                    assert_eq!(
                        occluded[k],
                        Err(InvalidRay::OriginTooFar),
                        "{kind:?} lane {k}"
                    );
                }
                2 | 7 | 12 => {
                    let e = expected_error(k);
                    assert_eq!(hits[k], Err(e), "{kind:?} lane {k}");
                    assert_eq!(stochastic[k], Err(e), "{kind:?} lane {k}");
                    assert_eq!(occluded[k], Err(e), "{kind:?} lane {k}");
                }
                _ => {
                    let ray = queries[k].0;
                    assert!(agree(&hits[k].unwrap(), &tracer.intersect(&ray).unwrap()));
                    let single = tracer.intersect_stochastic(&ray, None, keys[k]).unwrap();
                    assert!(agree(&stochastic[k].unwrap(), &single));
                }
            }
        }

        // A packet whose every ray is invalid or absent never calls Embree and reports only errors.
        let rays: [Option<Ray>; 8] =
            std::array::from_fn(|k| if k % 2 == 0 { bad(2) } else { None });
        let mut hits = [Ok(Some(UNTOUCHED)); 8];
        tracer.intersect_packet(&rays, &mut hits);
        for (k, hit) in hits.iter().enumerate() {
            let expected = if k % 2 == 0 {
                Err(InvalidRay::NotFinite)
            } else {
                Ok(Some(UNTOUCHED))
            };
            assert_eq!(*hit, expected, "{kind:?} lane {k}");
        }
    }
}
