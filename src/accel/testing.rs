//! Test fixtures shared by the tests of the BVH, the ray–curve intersectors and the BVH tracer: a seeded random
//! source, a random bundle of wavy strands and the real hair models of the test data. Every failure reproduces
//! from its seed.

use glam::Vec3;

use crate::hair::{HairModel, Strands};
use crate::util::hash::SplitMix64;

/// Seeded SplitMix64 with the draws the tests need.
pub(crate) struct Rng(SplitMix64);

impl Rng {
    /// The stream whose state starts at `seed`.
    pub(crate) fn new(seed: u64) -> Self {
        Rng(SplitMix64::from_state(seed))
    }

    /// The next 64 random bits.
    pub(crate) fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// Uniform in [`lo`, `hi`).
    pub(crate) fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.0.next_f32()
    }

    /// A uniform unit vector (rejection sampling of the ball, shell 0.1–1 so the normalisation is well
    /// conditioned).
    pub(crate) fn unit_vector(&mut self) -> Vec3 {
        loop {
            let p = Vec3::new(
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
            );
            let l = p.length();
            if (0.1..=1.0).contains(&l) {
                return p / l;
            }
        }
    }
}

/// `count` random wavy strands of `points` points in the cube [−1, 1]³, radii 0.002–0.02, opacity 0.5.
pub(crate) fn random_bundle(count: usize, points: usize, seed: u64) -> Strands {
    let mut rng = SplitMix64::new(seed, 0);
    let mut u = || rng.next_f32();
    let mut model = HairModel {
        strand_offsets: vec![0],
        ..Default::default()
    };
    for _ in 0..count {
        let mut p = Vec3::new(u(), u(), u()) * 2.0 - Vec3::ONE;
        let dir = (Vec3::new(u(), u(), u()) * 2.0 - Vec3::ONE).normalize_or(Vec3::Y);
        let radius = 0.002 + 0.018 * u();
        for _ in 0..points {
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

/// The hair model `name` of the data folder's `hair/` ([`crate::util::test_data`]) as strands. Panics naming the
/// file when it is missing or unreadable: the tests never pass silently without it.
#[track_caller]
pub(crate) fn hair_file(name: &str) -> Strands {
    let path = crate::util::test_data::file(&format!("hair/{name}"));
    let model = crate::hair::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    Strands::from_model(&model)
}
