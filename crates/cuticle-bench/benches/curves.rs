//! Cost of one ray–segment test of the pure-Rust curve intersectors (`accel::curves::{round, flat}`).
//!
//! `cargo bench -p cuticle-bench --bench curves`. Segments like the fur ball's: thin (radius 1e-3 of the segment's length), gently
//! curved (the heading turns by ~0.1 rad per control point). Two ray sets per curve kind, generated from a fixed
//! seed: **hit** (aimed within 0.9 radii of a point of the curve, kept if the intersector hits) and **miss** (through
//! a random point of the segment's bounding box, radius included — what the BVH offers a leaf — kept if it misses).
//! Each measured iteration runs a batch of [`BATCH`] calls; criterion's time per iteration / [`BATCH`] is the time
//! per call. Single thread, `bench` profile.
//!
//! **Instruction counts**: with `CURVES_CALLS=<case>:<n>` (case `round-hit`, `round-miss`, `flat-hit`, `flat-miss`)
//! the binary makes n calls of that case and exits without criterion, for
//! `CURVES_CALLS=round-miss:20000 valgrind --tool=callgrind target/release/deps/curves-…`; the difference of the
//! totals of two call counts over the difference of the counts is the instructions per call.

use criterion::{black_box, criterion_group, Criterion, Throughput};
use cuticle::accel::curves::{flat, round, CurveHit};
use cuticle::hair::strands::bspline_basis;
use glam::Vec3;
use rand::Rng;
use rand_pcg::Pcg32;

/// Calls per measured iteration.
const BATCH: usize = 1024;
/// Segments in a ray set (rays cycle over them).
const SEGMENTS: usize = 64;

type Intersect = fn(Vec3, Vec3, f32, f32, [[f32; 4]; 4]) -> Option<CurveHit>;

struct Case {
    segment: Vec<[[f32; 4]; 4]>,
    org: Vec<Vec3>,
    dir: Vec<Vec3>,
}

fn unit_vector(rng: &mut Pcg32) -> Vec3 {
    loop {
        let v = Vec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let l = v.length_squared();
        if l > 1e-4 && l <= 1.0 {
            return v / l.sqrt();
        }
    }
}

/// A fur-ball-like segment: control points 1 apart along a slowly turning heading, radius ~1e-3.
fn segment(rng: &mut Pcg32) -> [[f32; 4]; 4] {
    let mut p = Vec3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    );
    let mut heading = unit_vector(rng);
    let mut cp = [[0.0; 4]; 4];
    for c in &mut cp {
        *c = [p.x, p.y, p.z, rng.random_range(0.8e-3..1.2e-3)];
        heading = (heading + 0.1 * unit_vector(rng)).normalize();
        p += heading;
    }
    cp
}

fn eval(cp: &[[f32; 4]; 4], u: f32) -> (Vec3, f32) {
    let b = bspline_basis(u);
    let mut p = [0.0f32; 4];
    for (bi, c) in b.iter().zip(cp) {
        for k in 0..4 {
            p[k] += bi * c[k];
        }
    }
    (Vec3::new(p[0], p[1], p[2]), p[3])
}

/// [`BATCH`] rays over [`SEGMENTS`] segments that hit (`want_hit`) or miss the segment under `intersect`.
fn case(intersect: Intersect, want_hit: bool, seed: u64) -> Case {
    let mut rng = Pcg32::new(seed, 13);
    let segments: Vec<_> = (0..SEGMENTS).map(|_| segment(&mut rng)).collect();
    let mut c = Case {
        segment: Vec::new(),
        org: Vec::new(),
        dir: Vec::new(),
    };
    while c.org.len() < BATCH {
        let cp = segments[c.org.len() % SEGMENTS];
        let target = if want_hit {
            let (p, r) = eval(&cp, rng.random_range(0.0..1.0));
            p + rng.random_range(0.0..0.9) * r * unit_vector(&mut rng)
        } else {
            let r = cp.iter().fold(0.0f32, |m, c| m.max(c[3]));
            let lo = cp
                .iter()
                .fold(Vec3::INFINITY, |m, c| m.min(Vec3::new(c[0], c[1], c[2])));
            let hi = cp.iter().fold(Vec3::NEG_INFINITY, |m, c| {
                m.max(Vec3::new(c[0], c[1], c[2]))
            });
            let s = Vec3::new(
                rng.random_range(0.0..1.0),
                rng.random_range(0.0..1.0),
                rng.random_range(0.0..1.0),
            );
            (lo - r) + s * (hi - lo + 2.0 * r)
        };
        let dir = unit_vector(&mut rng) * rng.random_range(0.5..2.0);
        let org = target - 3.0 * dir;
        if intersect(org, dir, 0.0, f32::INFINITY, cp).is_some() == want_hit {
            c.segment.push(cp);
            c.org.push(org);
            c.dir.push(dir);
        }
    }
    c
}

/// Runs every ray of `c` once; the number of hits.
fn run(intersect: Intersect, c: &Case) -> usize {
    let mut hits = 0;
    for k in 0..BATCH {
        let hit = intersect(
            black_box(c.org[k]),
            black_box(c.dir[k]),
            0.0,
            f32::INFINITY,
            black_box(c.segment[k]),
        );
        hits += usize::from(hit.is_some());
    }
    hits
}

const CASES: [(&str, Intersect, bool); 4] = [
    ("round-hit", round::intersect, true),
    ("round-miss", round::intersect, false),
    ("flat-hit", flat::intersect, true),
    ("flat-miss", flat::intersect, false),
];

fn curves(c: &mut Criterion) {
    let mut g = c.benchmark_group("curves");
    g.throughput(Throughput::Elements(BATCH as u64));
    for (seed, (name, intersect, want_hit)) in CASES.into_iter().enumerate() {
        let rays = case(intersect, want_hit, seed as u64);
        g.bench_function(name, |b| b.iter(|| run(intersect, &rays)));
    }
    g.finish();
}

/// `CURVES_CALLS=<case>:<n>`: n calls of one case, for callgrind (module docs).
fn fixed_calls() -> bool {
    let Ok(spec) = std::env::var("CURVES_CALLS") else {
        return false;
    };
    let (name, n) = spec.split_once(':').expect("CURVES_CALLS=<case>:<calls>");
    let n: usize = n.parse().expect("CURVES_CALLS: calls must be a number");
    let (seed, &(_, intersect, want_hit)) = CASES
        .iter()
        .enumerate()
        .find(|(_, c)| c.0 == name)
        .unwrap_or_else(|| panic!("CURVES_CALLS: no case {name:?}"));
    let rays = case(intersect, want_hit, seed as u64);
    let mut hits = 0;
    for _ in 0..n / BATCH {
        hits += run(intersect, &rays);
    }
    println!("{name}: {} calls, {hits} hits", n / BATCH * BATCH);
    true
}

criterion_group! {
    name = benches;
    // 2-core machine, short runs, as in benches/bsdf.rs.
    config = Criterion::default().warm_up_time(std::time::Duration::from_secs(1)).measurement_time(std::time::Duration::from_secs(2)).sample_size(50);
    targets = curves
}

fn main() {
    if fixed_calls() {
        return;
    }
    benches();
    Criterion::default().configure_from_args().final_summary();
}
