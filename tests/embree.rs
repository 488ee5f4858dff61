//! The Embree tracer against analytic answers: hit distances on straight strands, transmittance through k strands,
//! a brute-force comparison on random rays through a random bundle, `ignore_strand`, rejection of invalid rays,
//! Embree errors reaching Rust as `Err`, and a smoke run of the trace benchmark (the full run is `#[ignore]`d).
//!
//! Straight strands make the reference exact: with the phantom end points of `Strands::from_model` and equally
//! spaced collinear points the B-spline is the straight segment itself, so a round curve is a cylinder of the file
//! radius (`radius_from_file: true`, no taper) and a flat curve is a ribbon of that half-width through the axis,
//! facing the ray. Rays cross strands well away from their ends, where end caps would differ.

use cuticle::accel::embree::EmbreeTracer;
use cuticle::accel::{CurveKind, Tracer};
use cuticle::hair::{HairModel, Strands};
use cuticle::ray::{InvalidRay, Ray};
use cuticle::sys::embree::{
    BuildQuality, CurveBasis, CurveGeometry, Device, ErrorCode, Scene, StrandTable,
    TRANSMITTANCE_CUTOFF,
};
use cuticle::util::hash::SplitMix64;
use glam::Vec3;
use std::sync::Arc;

const KINDS: [CurveKind; 2] = [CurveKind::Round, CurveKind::Flat];

/// Hit distance tolerance for rays starting ~5 units away from strands of radius 0.01–0.05: Embree intersects
/// round B-splines numerically. The largest error seen on the brute-force bundle was ≈ 3e-5 (1 ray in 20 000
/// above 2e-5); 2e-4 leaves headroom and is still 2 % of the thinnest radius.
const T_TOLERANCE: f32 = 2e-4;

/// Transmittance tolerance: a product of a few float factors, compared to the same product in another order.
const TRANSMITTANCE_TOLERANCE: f32 = 1e-5;

/// Points per straight strand: 5 points give 4 segments, so rays also cross segment joints.
const POINTS_PER_STRAND: usize = 5;

/// A model of straight strands `(root, tip, radius, opacity)`, each with [`POINTS_PER_STRAND`] evenly spaced
/// points and its radius taken as given (no taper).
fn straight_strands(strands: &[(Vec3, Vec3, f32, f32)]) -> Strands {
    let mut model = HairModel {
        radius_from_file: true,
        strand_offsets: vec![0],
        ..Default::default()
    };
    for &(root, tip, radius, opacity) in strands {
        for i in 0..POINTS_PER_STRAND {
            let s = i as f32 / (POINTS_PER_STRAND - 1) as f32;
            model.points.push(root.lerp(tip, s));
            model.radius.push(radius);
            model.transparency.push(1.0 - opacity);
            model.color.push([0.5; 3]);
        }
        model.strand_offsets.push(model.points.len() as u32);
    }
    Strands::from_model(&model)
}

/// One vertical strand through the origin, from y = −2 to y = 2.
fn vertical_strand(radius: f32, opacity: f32) -> Strands {
    straight_strands(&[(
        Vec3::new(0.0, -2.0, 0.0),
        Vec3::new(0.0, 2.0, 0.0),
        radius,
        opacity,
    )])
}

fn tracer(strands: &Strands, kind: CurveKind) -> EmbreeTracer {
    EmbreeTracer::new(strands, kind).unwrap_or_else(|e| panic!("{kind:?} tracer: {e}"))
}

#[test]
fn perpendicular_ray_hits_at_the_expected_distance() {
    let radius = 0.05;
    let strands = vertical_strand(radius, 1.0);
    for kind in KINDS {
        let tracer = tracer(&strands, kind);
        // Offsets across the strand: through the axis, and 0.6 of the radius to the side.
        for x in [0.0, 0.6 * radius] {
            let ray = Ray::new(Vec3::new(x, 0.3, 5.0), Vec3::NEG_Z);
            let hit = tracer
                .intersect(&ray)
                .unwrap()
                .unwrap_or_else(|| panic!("{kind:?}: ray at x = {x} missed the strand"));
            // Round: the tube surface, 5 − sqrt(r² − x²) from the origin. Flat: the ribbon through the axis.
            let expected = match kind {
                CurveKind::Round => 5.0 - (radius * radius - x * x).sqrt(),
                CurveKind::Flat => 5.0,
            };
            assert!(
                (hit.t - expected).abs() < T_TOLERANCE,
                "{kind:?} x = {x}: t = {}, expected {expected}",
                hit.t
            );
            assert_eq!(hit.strand, 0);
            assert!((0.0..=1.0).contains(&hit.u), "{hit:?}");
            match kind {
                CurveKind::Round => {
                    let n = hit.ng.normalize();
                    let expected_n = Vec3::new(x, 0.0, (radius * radius - x * x).sqrt()) / radius;
                    assert!((n - expected_n).length() < 1e-3, "{kind:?}: {hit:?}");
                }
                CurveKind::Flat => {
                    assert!((hit.v.abs() - x / radius).abs() < 1e-3, "{kind:?}: {hit:?}");
                }
            }
            // The same ray with a direction twice as long: t is in units of `dir`.
            let long = Ray::new(ray.origin, 2.0 * ray.dir);
            let t2 = tracer.intersect(&long).unwrap().unwrap().t;
            assert!((2.0 * t2 - expected).abs() < T_TOLERANCE, "{kind:?}: {t2}");
        }
        // Beside the strand (1.2 radii from the axis), and beyond tfar: misses.
        let beside = Ray::new(Vec3::new(1.2 * radius, 0.3, 5.0), Vec3::NEG_Z);
        assert_eq!(tracer.intersect(&beside).unwrap(), None, "{kind:?}");
        let short = Ray::segment(Vec3::new(0.0, 0.3, 5.0), Vec3::NEG_Z, 0.0, 4.0);
        assert_eq!(tracer.intersect(&short).unwrap(), None, "{kind:?}");
        assert_eq!(
            tracer.transmittance(&beside, None).unwrap(),
            1.0,
            "{kind:?}"
        );
    }
}

#[test]
fn transmittance_through_k_strands_is_a_power() {
    let a = 0.3;
    for kind in KINDS {
        for k in 0..=6 {
            // k vertical strands one behind the other along z, 0.2 apart; the ray crosses all of them.
            let bundle: Vec<_> = (0..k)
                .map(|i| {
                    let z = -0.5 + 0.2 * i as f32;
                    (Vec3::new(0.0, -2.0, z), Vec3::new(0.0, 2.0, z), 0.04, a)
                })
                .collect();
            let strands = straight_strands(&bundle);
            let tracer = tracer(&strands, kind);
            // Through a segment joint (y = 0 is a control point) and through the middle of a segment.
            for y in [0.0, 0.5] {
                let ray = Ray::new(Vec3::new(0.01, y, 5.0), Vec3::NEG_Z);
                let t = tracer.transmittance(&ray, None).unwrap();
                let expected = (1.0 - a).powi(k);
                assert!(
                    (t - expected).abs() < TRANSMITTANCE_TOLERANCE,
                    "{kind:?}, k = {k}, y = {y}: transmittance {t}, expected (1 − {a})^{k} = {expected}"
                );
            }
        }
    }
}

#[test]
fn ignore_strand_leaves_that_strand_out() {
    let a = 0.5;
    let bundle: Vec<_> = (0..3)
        .map(|i| {
            let z = -0.2 + 0.2 * i as f32;
            (Vec3::new(0.0, -2.0, z), Vec3::new(0.0, 2.0, z), 0.04, a)
        })
        .collect();
    let strands = straight_strands(&bundle);
    for kind in KINDS {
        let tracer = tracer(&strands, kind);
        let ray = Ray::new(Vec3::new(0.0, 0.2, 5.0), Vec3::NEG_Z);
        assert_eq!(tracer.transmittance(&ray, None).unwrap(), 0.125, "{kind:?}");
        for s in 0..3 {
            assert_eq!(
                tracer.transmittance(&ray, Some(s)).unwrap(),
                0.25,
                "{kind:?} ignoring {s}"
            );
        }
        assert_eq!(
            tracer.transmittance(&ray, Some(99)).unwrap(),
            0.125,
            "{kind:?}"
        );
        // A shadow ray leaving the first strand hit, ignoring that strand, sees the two behind it.
        let hit = tracer.intersect(&ray).unwrap().unwrap();
        assert_eq!(hit.strand, 2, "{kind:?}: the nearest strand is at z = 0.2");
        let shadow = Ray::new(ray.at(hit.t), Vec3::NEG_Z);
        assert_eq!(
            tracer.transmittance(&shadow, Some(hit.strand)).unwrap(),
            0.25,
            "{kind:?}"
        );
    }
}

#[test]
fn opaque_strand_stops_the_ray() {
    let bundle = [
        (
            Vec3::new(0.0, -2.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
            0.04,
            1.0,
        ),
        (
            Vec3::new(0.0, -2.0, -0.3),
            Vec3::new(0.0, 2.0, -0.3),
            0.04,
            0.5,
        ),
    ];
    let strands = straight_strands(&bundle);
    for kind in KINDS {
        let tracer = tracer(&strands, kind);
        let ray = Ray::new(Vec3::new(0.0, 0.2, 5.0), Vec3::NEG_Z);
        assert_eq!(tracer.transmittance(&ray, None).unwrap(), 0.0, "{kind:?}");
        assert_eq!(
            tracer.transmittance(&ray, Some(0)).unwrap(),
            0.5,
            "{kind:?}"
        );
    }
}

// ---------------------------------------------------------------------------------------------------------------
// Brute force: random rays through a random bundle against an analytic reference.

/// The crate's SplitMix64, seeded as the reference implementation: deterministic, so every failure reproduces.
struct Rng(SplitMix64);

impl Rng {
    fn new(seed: u64) -> Rng {
        Rng(SplitMix64::from_state(seed))
    }

    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.0.next_f32()
    }

    /// A point in the disk of radius `r` in the xz plane.
    fn disk(&mut self, r: f32) -> Vec3 {
        loop {
            let p = Vec3::new(self.range(-r, r), 0.0, self.range(-r, r));
            if p.length() <= r {
                return p;
            }
        }
    }
}

const BUNDLE_STRANDS: usize = 150;
const BUNDLE_RAYS: usize = 20_000;
/// Rays passing a strand's surface closer than this fraction of its radius are "grazing": which side Embree puts
/// them on is float noise, so they are left out of the comparison (and counted). With a band of 1e-5 instead,
/// 1 ray in 20 000 lands on the other side of a round strand's surface.
const GRAZING: f32 = 2e-3;
/// At most this fraction of rays may be grazing, so the comparison cannot silently shrink. Expected: about
/// 2·GRAZING per strand crossed (≈ 6 per ray), i.e. ≈ 2.4 %.
const MAX_GRAZING_FRACTION: f64 = 0.04;

struct Bundle {
    /// (point on axis, unit axis direction, radius, opacity) per strand.
    axes: Vec<(Vec3, Vec3, f32, f32)>,
    strands: Strands,
}

/// Straight strands, 6 long, vertical within 0.15 rad, roots in a disk of radius 0.5.
fn random_bundle(rng: &mut Rng) -> Bundle {
    let mut list = Vec::new();
    let mut axes = Vec::new();
    for _ in 0..BUNDLE_STRANDS {
        let center = rng.disk(0.5);
        let tilt = rng.disk(0.15);
        let axis = (Vec3::Y + tilt).normalize();
        let radius = rng.range(0.01, 0.03);
        let opacity = rng.range(0.05, 0.6);
        list.push((center - 3.0 * axis, center + 3.0 * axis, radius, opacity));
        axes.push((center, axis, radius, opacity));
    }
    Bundle {
        axes,
        strands: straight_strands(&list),
    }
}

/// What the reference says about one strand and one ray.
enum Crossing {
    Miss,
    Grazing,
    /// Crossed, with the hit distance for the given curve kind.
    Hit(f32),
}

/// Exact crossing of a ray with an infinite straight strand (the crossings are far from the ends): the distance
/// between the two lines decides; round curves are hit where the ray enters the cylinder, flat curves where the
/// ray meets the ray-facing ribbon through the axis (at the lines' closest approach).
fn crossing(
    ray: &Ray,
    (center, axis, radius, _): (Vec3, Vec3, f32, f32),
    kind: CurveKind,
) -> Crossing {
    let delta = ray.origin - center;
    let d_perp = ray.dir - ray.dir.dot(axis) * axis;
    let delta_perp = delta - delta.dot(axis) * axis;
    let a = d_perp.length_squared();
    let t_closest = -delta_perp.dot(d_perp) / a;
    let distance = (delta_perp + t_closest * d_perp).length();
    if (distance - radius).abs() < GRAZING * radius {
        return Crossing::Grazing;
    }
    if distance > radius {
        return Crossing::Miss;
    }
    match kind {
        CurveKind::Round => {
            let half_chord = ((radius * radius - distance * distance) / a).sqrt();
            Crossing::Hit(t_closest - half_chord)
        }
        CurveKind::Flat => Crossing::Hit(t_closest),
    }
}

#[test]
fn random_rays_match_a_brute_force_reference() {
    let mut rng = Rng::new(0x5eed_cafe);
    let bundle = random_bundle(&mut rng);
    for kind in KINDS {
        let tracer = tracer(&bundle.strands, kind);
        let (mut compared, mut grazing, mut crossings) = (0usize, 0usize, 0usize);
        let mut failures = Vec::new();
        for ray_index in 0..BUNDLE_RAYS {
            // Aim at the middle of the bundle from outside it, at least 45° away from the strand direction.
            let target = rng.disk(0.6) + Vec3::new(0.0, rng.range(-1.0, 1.0), 0.0);
            let dir = loop {
                let d = Vec3::new(
                    rng.range(-1.0, 1.0),
                    rng.range(-0.7, 0.7),
                    rng.range(-1.0, 1.0),
                );
                if d.length() > 0.2 && d.length() <= 1.0 && d.normalize().y.abs() < 0.7 {
                    break d.normalize();
                }
            };
            let ray = Ray::new(target - 4.0 * dir, dir);
            let mut reference = 1.0f32;
            let mut nearest: Option<(f32, u32)> = None;
            let mut crossed = 0;
            let mut is_grazing = false;
            for (s, &strand) in bundle.axes.iter().enumerate() {
                match crossing(&ray, strand, kind) {
                    Crossing::Miss => {}
                    Crossing::Grazing => is_grazing = true,
                    Crossing::Hit(t) => {
                        reference *= 1.0 - strand.3;
                        crossed += 1;
                        if nearest.is_none_or(|(tn, _)| t < tn) {
                            nearest = Some((t, s as u32));
                        }
                    }
                }
            }
            if is_grazing {
                grazing += 1;
                continue;
            }
            compared += 1;
            crossings += crossed;
            assert!(
                crossed < 64,
                "the reference would overflow the seen-strand list"
            );
            if reference < TRANSMITTANCE_CUTOFF {
                reference = 0.0;
            }
            let transmittance = tracer.transmittance(&ray, None).unwrap();
            let hit = tracer.intersect(&ray).unwrap();
            let hit_matches = match (hit, nearest) {
                (None, None) => true,
                (Some(h), Some((t, s))) => h.strand == s && (h.t - t).abs() < T_TOLERANCE,
                _ => false,
            };
            if (transmittance - reference).abs() > TRANSMITTANCE_TOLERANCE || !hit_matches {
                failures.push(format!(
                    "ray {ray_index} {ray:?}: transmittance {transmittance} vs {reference} ({crossed} strands); \
                     hit {hit:?} vs (t, strand) {nearest:?}"
                ));
            }
        }
        assert!(
            crossings > 0,
            "{kind:?}: none of {compared} rays crossed a strand; nothing was compared"
        );
        assert!(
            (grazing as f64) < MAX_GRAZING_FRACTION * BUNDLE_RAYS as f64,
            "{kind:?}: {grazing} grazing rays"
        );
        assert!(
            failures.is_empty(),
            "{kind:?}: {} of {compared} rays disagree with the reference, e.g.\n{}",
            failures.len(),
            failures[..failures.len().min(5)].join("\n")
        );
    }
}

#[test]
fn concurrent_queries_agree_with_serial_ones() {
    let mut rng = Rng::new(7);
    let bundle = random_bundle(&mut rng);
    let tracer = tracer(&bundle.strands, CurveKind::Round);
    let rays: Vec<Ray> = (0..4000)
        .map(|_| {
            let target = rng.disk(0.6);
            let dir = Vec3::new(rng.range(-1.0, 1.0), 0.1, rng.range(-1.0, 1.0)).normalize();
            Ray::new(target - 4.0 * dir, dir)
        })
        .collect();
    let serial: Vec<_> = rays
        .iter()
        .map(|r| {
            (
                tracer.intersect(r).unwrap(),
                tracer.transmittance(r, None).unwrap(),
            )
        })
        .collect();
    let parallel: Vec<Vec<_>> = std::thread::scope(|scope| {
        let handles: Vec<_> = rays
            .chunks(1000)
            .map(|chunk| {
                let tracer = &tracer;
                scope.spawn(move || {
                    chunk
                        .iter()
                        .map(|r| {
                            (
                                tracer.intersect(r).unwrap(),
                                tracer.transmittance(r, None).unwrap(),
                            )
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    assert_eq!(serial, parallel.concat());
}

// ---------------------------------------------------------------------------------------------------------------
// Bad input.

#[test]
fn invalid_rays_are_rejected_before_embree() {
    let strands = vertical_strand(0.05, 0.5);
    let o = Vec3::new(0.0, 0.0, 5.0);
    let bad = [
        (
            Ray::new(Vec3::new(f32::NAN, 0.0, 5.0), Vec3::NEG_Z),
            InvalidRay::NotFinite,
        ),
        (
            Ray::new(o, Vec3::new(0.0, 0.0, f32::NEG_INFINITY)),
            InvalidRay::NotFinite,
        ),
        (
            Ray::segment(o, Vec3::NEG_Z, -1e-3, 10.0),
            InvalidRay::BadInterval,
        ),
        (
            Ray::new(Vec3::new(0.0, 1e20, 0.0), Vec3::NEG_Z),
            InvalidRay::OriginTooFar,
        ),
        (Ray::new(o, Vec3::ZERO), InvalidRay::ZeroDirection),
        (
            Ray::segment(o, Vec3::NEG_Z, 0.0, f32::NAN),
            InvalidRay::BadInterval,
        ),
    ];
    for kind in KINDS {
        let tracer = tracer(&strands, kind);
        for (ray, why) in bad {
            assert_eq!(
                tracer.intersect(&ray),
                Err(why),
                "{kind:?} intersect {ray:?}"
            );
            assert_eq!(
                tracer.transmittance(&ray, None),
                Err(why),
                "{kind:?} transmittance {ray:?}"
            );
        }
        // Still alive and still tracing.
        let good = Ray::new(o, Vec3::NEG_Z);
        assert!(tracer.intersect(&good).unwrap().is_some(), "{kind:?}");
    }
}

#[test]
fn very_long_directions_are_traced_not_rejected() {
    // Embree asserts on direction components above ~1.8e18, which `Ray::check` allows: the wrapper rescales.
    let strands = vertical_strand(0.05, 0.5);
    for kind in KINDS {
        let tracer = tracer(&strands, kind);
        let ray = Ray::new(Vec3::new(0.0, 0.0, 5.0), Vec3::new(0.0, 0.0, -1e19));
        let hit = tracer.intersect(&ray).unwrap().expect("hit");
        let expected = match kind {
            CurveKind::Round => 4.95e-19,
            CurveKind::Flat => 5e-19,
        };
        assert!(
            (hit.t / expected - 1.0).abs() < 1e-4,
            "{kind:?}: t = {}",
            hit.t
        );
        assert_eq!(tracer.transmittance(&ray, None).unwrap(), 0.5, "{kind:?}");
    }
}

#[test]
fn extreme_but_valid_rays_do_not_abort() {
    // Rays that pass `Ray::check` but sit at the edge of float range. Debian's libembree3 aborts (not panics) on
    // rays it considers invalid, so a failure here takes the test process down: it would show as a crash.
    let strands = vertical_strand(0.05, 0.5);
    let o = Vec3::new(0.0, 0.0, 5.0);
    let rays = [
        Ray::new(o, Vec3::new(0.0, 0.0, -1e-30)),
        Ray::new(o, Vec3::new(1e-40, 0.0, -1e-40)),
        Ray::new(Vec3::new(9.9e17, 0.0, 0.0), Vec3::NEG_X),
        Ray::new(Vec3::new(-9.9e17, 9.9e17, 5.0), Vec3::new(1e18, -1e18, 0.0)),
        Ray::segment(o, Vec3::NEG_Z, 1e30, f32::INFINITY),
        Ray::segment(o, Vec3::NEG_Z, 0.0, f32::MAX),
        Ray::segment(o, Vec3::NEG_Z, f32::MAX / 2.0, f32::MAX),
    ];
    for kind in KINDS {
        let tracer = tracer(&strands, kind);
        for ray in rays {
            assert!(tracer.intersect(&ray).is_ok(), "{kind:?} {ray:?}");
            assert!(tracer.transmittance(&ray, None).is_ok(), "{kind:?} {ray:?}");
        }
    }
}

#[test]
fn an_empty_model_builds_and_misses() {
    for kind in KINDS {
        let tracer = tracer(&Strands::default(), kind);
        let ray = Ray::new(Vec3::ZERO, Vec3::X);
        assert_eq!(tracer.intersect(&ray).unwrap(), None);
        assert_eq!(tracer.transmittance(&ray, None).unwrap(), 1.0);
    }
}

#[test]
fn embree_errors_reach_rust() {
    // Embree checks that a geometry and the scene it joins share a device, and reports the mismatch through the
    // error callback: the wrapper turns it into an `Err`.
    let strands = vertical_strand(0.05, 0.5);
    let table = Arc::new(
        StrandTable::new(strands.segment_strand.clone(), strands.opacity.clone()).unwrap(),
    );
    let (a, b) = (Device::new().unwrap(), Device::new().unwrap());
    let geometry = CurveGeometry::bspline(
        &a,
        CurveBasis::RoundBSpline,
        &strands.control_points,
        &strands.segment_first,
        table,
    )
    .unwrap();
    let mut scene = Scene::new(&b, BuildQuality::Medium).unwrap();
    let err = scene.attach(geometry).unwrap_err();
    assert_eq!(err.code, ErrorCode::InvalidArgument, "{err}");
    assert!(err.message.contains("different devices"), "{err}");
    // A malformed device configuration makes `rtcNewDevice` fail (Embree's parser throws on "abc").
    let bad_config = Device::with_config("threads=abc").unwrap_err();
    assert!(bad_config.message.contains("threads=abc"), "{bad_config}");
    // The error was consumed: the next call on the same device succeeds.
    let scene = scene.commit().unwrap();
    assert_eq!(
        scene.intersect1(&Ray::new(Vec3::ZERO, Vec3::X)).unwrap(),
        None
    );
}

#[test]
fn bad_curve_input_is_rejected_by_the_wrapper() {
    let device = Device::new().unwrap();
    let points = [[0.0, 0.0, 0.0, 0.1]; 4];
    let table = |n: usize| Arc::new(StrandTable::new(vec![0; n], vec![0.5]).unwrap());
    let new = |points: &[[f32; 4]], firsts: &[u32], n| {
        CurveGeometry::bspline(&device, CurveBasis::FlatBSpline, points, firsts, table(n))
    };
    assert!(new(&points, &[0], 1).is_ok());
    // A segment reading past the vertex buffer, a segment count that disagrees with the table, a NaN point.
    let past_end = new(&points, &[1], 1).unwrap_err();
    assert!(past_end.message.contains("segment 0"), "{past_end}");
    assert!(new(&points, &[0, 0], 1).is_err());
    let mut nan = points;
    nan[2][1] = f32::NAN;
    assert!(new(&nan, &[0], 1).is_err());
    assert!(Device::with_config("threads=1\0").is_err());
}

// ---------------------------------------------------------------------------------------------------------------
// The trace benchmark.

/// `count` random wavy strands of 16 points on a unit sphere (a crude fur ball), for benchmarks without data.
fn synthetic_fur(count: usize) -> Strands {
    let mut rng = Rng::new(42);
    let mut model = HairModel {
        radius_from_file: true,
        strand_offsets: vec![0],
        ..Default::default()
    };
    for _ in 0..count {
        let root = loop {
            let p = Vec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            );
            if p.length() > 0.1 && p.length() <= 1.0 {
                break p.normalize();
            }
        };
        let wobble = Vec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        );
        for i in 0..16 {
            let s = i as f32 / 15.0;
            let p = root * (1.0 + 0.5 * s) + 0.05 * (6.0 * s).sin() * wobble;
            model.points.push(p);
            model.radius.push(0.002);
            model.transparency.push(0.7);
            model.color.push([0.5; 3]);
        }
        model.strand_offsets.push(model.points.len() as u32);
    }
    Strands::from_model(&model)
}

#[test]
fn bench_trace_measures_both_backends_on_the_same_rays() {
    use cuticle::accel::{Backend, CurveKind};
    use cuticle::bench::trace::RayType;
    let strands = synthetic_fur(500);
    let (lo, hi) = strands.bounds();
    let centre = 0.5 * (lo + hi);
    let eye = centre + Vec3::new(0.0, 0.0, 2.5 * (hi - lo).max_element());
    let camera = cuticle::render::camera::Camera::look_at(eye, centre, Vec3::Y, 50.0, 64, 64);
    let mut config = cuticle::bench::TraceConfig::new(camera, 2);
    config.threads = vec![1, 2];
    config.repetitions = 1;
    let report = cuticle::bench::trace(&strands, &config).unwrap();
    assert_eq!(report.measurements.len(), 2 * 2 * 2, "{report}");
    for kind in [CurveKind::Round, CurveKind::Flat] {
        let embree = report.get(kind, Backend::Embree, 2).unwrap();
        for m in report.measurements.iter().filter(|m| m.kind == kind) {
            assert!(m.memory_bytes > 0, "{report}");
            for (r, e) in m.rays.iter().zip(&embree.rays) {
                assert!(r.throughput.rays > 0, "{:?} has no rays\n{report}", r.ray);
                // The same rays through either backend: the same work, so (up to a few silhouette grazes) the
                // same correctness figure.
                assert_eq!(r.throughput.rays, e.throughput.rays, "{report}");
                assert!(
                    (r.figure - e.figure).abs() <= 0.01,
                    "{kind:?} {:?} {:?} figure {} against embree's {}\n{report}",
                    m.backend,
                    r.ray,
                    r.figure,
                    e.figure
                );
            }
            let camera = &m.rays[0];
            assert_eq!(camera.ray, RayType::Camera);
            assert!(camera.figure > 0.0 && camera.figure < 1.0, "{report}");
        }
    }
    // The script-readable lines: one per (measure, curves, backend, threads), with a positive finite number.
    let text = report.to_string();
    for what in [
        "build",
        "memory",
        "camera",
        "secondary",
        "shadow-exact",
        "shadow-stochastic",
    ] {
        for kind in ["round", "flat"] {
            for backend in ["embree", "bvh"] {
                for threads in ["1-threads", "2-threads"] {
                    let line = text
                        .lines()
                        .find(|l| {
                            l.starts_with(&format!("{what} {kind} {backend} "))
                                && l.ends_with(threads)
                        })
                        .unwrap_or_else(|| {
                            panic!("no `{what} {kind} {backend} … {threads}` line in\n{text}")
                        });
                    let value: f64 = line.split_whitespace().nth(3).unwrap().parse().unwrap();
                    assert!(value.is_finite() && value > 0.0, "{line}");
                }
            }
        }
    }
}

#[test]
fn a_full_seen_strand_list_ends_the_ray_dark_and_says_so() {
    // 70 strands of opacity 0.01 in a row: (0.99)^70 ≈ 0.49, but the filter remembers only SEEN_STRANDS = 64.
    let bundle: Vec<_> = (0..70)
        .map(|i| {
            let z = -3.5 + 0.1 * i as f32;
            (Vec3::new(0.0, -2.0, z), Vec3::new(0.0, 2.0, z), 0.02, 0.01)
        })
        .collect();
    let strands = straight_strands(&bundle);
    for kind in KINDS {
        let tracer = tracer(&strands, kind);
        let ray = Ray::new(Vec3::new(0.0, 0.3, 5.0), Vec3::NEG_Z);
        let t = tracer.transmittance_detail(&ray, None).unwrap();
        assert_eq!(t.value, 0.0, "{kind:?}: {t:?}");
        assert_eq!(
            t.strands as usize,
            cuticle::sys::embree::SEEN_STRANDS,
            "{kind:?}: {t:?}"
        );
        assert_eq!(
            t.cutoff,
            Some(cuticle::sys::embree::Cutoff::SeenListFull),
            "{kind:?}"
        );
        // Fewer strands than the list holds are counted exactly.
        let short = Ray::segment(ray.origin, ray.dir, 0.0, 5.0 + 3.5 - 0.1 * 10.0 + 0.05);
        let t = tracer.transmittance_detail(&short, None).unwrap();
        assert_eq!(t.strands, 60, "{kind:?}: {t:?}");
        assert!(
            (t.value - 0.99f32.powi(60)).abs() < TRANSMITTANCE_TOLERANCE,
            "{kind:?}: {t:?}"
        );
    }
}

/// k strands of opacity `a` one behind the other along z, crossed by a ray along −z.
fn bundle_of(k: usize, a: f32) -> Strands {
    let bundle: Vec<_> = (0..k)
        .map(|i| {
            let z = -0.5 + 0.2 * i as f32;
            (Vec3::new(0.0, -2.0, z), Vec3::new(0.0, 2.0, z), 0.04, a)
        })
        .collect();
    straight_strands(&bundle)
}

#[test]
fn stochastic_occlusion_averages_to_the_transmittance() {
    // E[not occluded] over ray keys must equal ∏ (1 − a): the stochastic shadow is the exact one, in expectation.
    let (k, a, n) = (4, 0.3f32, 20_000u64);
    for kind in KINDS {
        let strands = bundle_of(k, a);
        let tracer = tracer(&strands, kind);
        let ray = Ray::new(Vec3::new(0.01, 0.3, 5.0), Vec3::NEG_Z);
        let exact = f64::from(tracer.transmittance(&ray, None).unwrap());
        let visible = (0..n)
            .filter(|&key| !tracer.occluded_stochastic(&ray, None, key).unwrap())
            .count() as f64
            / n as f64;
        let sigma = (exact * (1.0 - exact) / n as f64).sqrt();
        assert!(
            (visible - exact).abs() < 4.0 * sigma,
            "{kind:?}: stochastic visibility {visible}, exact transmittance {exact} (σ {sigma})"
        );
        // Ignoring the first strand removes its factor.
        let ignored = (0..n)
            .filter(|&key| !tracer.occluded_stochastic(&ray, Some(0), key).unwrap())
            .count() as f64
            / n as f64;
        let expected = (1.0 - f64::from(a)).powi(k as i32 - 1);
        assert!((ignored - expected).abs() < 4.0 * (expected * (1.0 - expected) / n as f64).sqrt());
    }
}

#[test]
fn stochastic_closest_hit_is_the_first_present_strand() {
    let (k, a) = (5, 0.5f32);
    for kind in KINDS {
        let strands = bundle_of(k, a);
        let t = tracer(&strands, kind);
        let ray = Ray::new(Vec3::new(0.01, 0.3, 5.0), Vec3::NEG_Z);
        let mut first_counts = vec![0u32; k + 1];
        for key in 0..4000u64 {
            let hit = t.intersect_stochastic(&ray, None, key).unwrap();
            // Strands are numbered from the back (z = −0.5) to the front: the ray meets strand k − 1 first.
            let expected = (0..k as u32)
                .rev()
                .find(|&s| cuticle::accel::strand_present(key, s, a));
            assert_eq!(hit.map(|h| h.strand), expected, "{kind:?}, key {key}");
            first_counts[hit.map_or(k, |h| h.strand as usize)] += 1;
        }
        // Every strand is sometimes the first present one, and sometimes none is.
        assert!(first_counts.iter().all(|&c| c > 0), "{first_counts:?}");
        // With opacity 1 the stochastic query is the opaque one.
        let opaque = bundle_of(k, 1.0);
        let t2 = tracer(&opaque, kind);
        assert_eq!(
            t2.intersect_stochastic(&ray, None, 99)
                .unwrap()
                .map(|h| h.strand),
            t2.intersect(&ray).unwrap().map(|h| h.strand)
        );
    }
}
