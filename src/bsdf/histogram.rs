//! The histogram of directions drawn by [`Bsdf::sample`] against the counts [`Bsdf::pdf`] predicts, cell by cell:
//! the data of the chi-square test every model runs (`bsdf::testing`, [`crate::util::stats::chi_square`]) and of the
//! histogram figure of `cuticle plot-bsdf` ([`crate::plot::bsdf`]). Plain numbers, no drawing.

use super::frame::{from_spherical, phi};
use super::Bsdf;
use glam::Vec3;
use rand::Rng;
use rand_pcg::Pcg32;
use std::f32::consts::PI;

/// Histograms of `n_samples` directions drawn by `model.sample(wo, ·)` (PCG32 seeded with `seed`) and of the
/// counts [`Bsdf::pdf`] predicts, over `bins` = (rows, columns) cells equal in solid angle: rows split
/// sin θi ∈ [−1, 1], columns split φi ∈ [−π, π] (local hair frame; row-major, row 0 at θi = −π/2, column 0 at
/// φi = −π). Returns (sampled, expected).
///
/// Expected counts integrate the pdf over each cell with 5 × 5 Gauss-Legendre nodes in (θ, φ) (the measure
/// cos θ dθ dφ; θ rather than sin θ so that a pdf ∝ 1/cos θi at the poles stays smooth in the variable
/// integrated). Samples the model declines (`None`) are not counted. The rule is exact for smooth pdfs only: put
/// a pdf's jumps on cell edges (ISHair's glints stop at φr − φi = ±π/2, so choose φo a multiple of 2π/columns).
pub fn sampled_vs_analytic<B: Bsdf + ?Sized>(
    model: &B,
    wo: Vec3,
    n_samples: usize,
    bins: (usize, usize),
    seed: u64,
) -> (Vec<f64>, Vec<f64>) {
    let (rows, cols) = (bins.0.max(1), bins.1.max(1));
    let mut sampled = vec![0.0; rows * cols];
    let mut rng = Pcg32::new(seed, 0x5eed);
    for _ in 0..n_samples {
        if let Some(s) = model.sample(wo, rng.random()) {
            let x = s.wi.x.clamp(-1.0, 1.0);
            let i = (((x + 1.0) * 0.5 * rows as f32) as usize).min(rows - 1);
            let j = (((phi(s.wi) + PI) / (2.0 * PI) * cols as f32) as usize).min(cols - 1);
            sampled[i * cols + j] += 1.0;
        }
    }
    // Gauss-Legendre, 5 nodes on [−1, 1].
    const NODES: [f64; 5] = [
        -0.906_179_845_938_664,
        -0.538_469_310_105_683_1,
        0.0,
        0.538_469_310_105_683_1,
        0.906_179_845_938_664,
    ];
    const WEIGHTS: [f64; 5] = [
        0.236_926_885_056_189_1,
        0.478_628_670_499_366_5,
        0.568_888_888_888_888_9,
        0.478_628_670_499_366_5,
        0.236_926_885_056_189_1,
    ];
    let mut expected = vec![0.0; rows * cols];
    for i in 0..rows {
        let t0 = (-1.0 + 2.0 * i as f64 / rows as f64).asin();
        let t1 = (-1.0 + 2.0 * (i + 1) as f64 / rows as f64)
            .clamp(-1.0, 1.0)
            .asin();
        for j in 0..cols {
            let p0 = -std::f64::consts::PI + std::f64::consts::TAU * j as f64 / cols as f64;
            let p1 = p0 + std::f64::consts::TAU / cols as f64;
            let mut sum = 0.0;
            for (a, wa) in NODES.iter().zip(WEIGHTS) {
                let t = 0.5 * (t0 + t1) + 0.5 * (t1 - t0) * a;
                for (b, wb) in NODES.iter().zip(WEIGHTS) {
                    let p = 0.5 * (p0 + p1) + 0.5 * (p1 - p0) * b;
                    let wi = from_spherical(t as f32, p as f32);
                    sum += wa * wb * model.pdf(wo, wi) as f64 * t.cos();
                }
            }
            expected[i * cols + j] = sum * 0.25 * (t1 - t0) * (p1 - p0) * n_samples as f64;
        }
    }
    (sampled, expected)
}
