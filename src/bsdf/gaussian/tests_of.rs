//! Unit tests of the Gaussian tools, apart because they outweigh the tools themselves.

use super::*;
use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};
use wide::f32x8;

#[test]
fn f32_quantile_matches_f64() {
    // PPND7 in f32 against PPND16 in f64, over levels from 1e-30 to 1 − 1e-7 (both tails, all three pieces),
    // in f32 and in eight lanes: within 1e-6 of |x| (the f32 result's own resolution is 6e-8).
    let mut levels = Vec::new();
    for i in 0..=600 {
        let p = 10f64.powf(-30.0 + 30.0 * i as f64 / 600.0);
        levels.push(p as f32);
        levels.push((1.0 - p.max(1e-7)) as f32);
    }
    let mut worst = 0.0f64;
    for chunk in levels.chunks_exact(8) {
        let lanes = normal_quantile_of(f32x8::new(chunk.try_into().unwrap()));
        for (k, &p) in chunk.iter().enumerate() {
            let want = normal_quantile(p as f64);
            let one = normal_quantile_of(p) as f64;
            let eight = lanes.lane(k) as f64;
            for got in [one, eight] {
                worst = worst.max((got - want).abs() / want.abs().max(1.0));
            }
        }
    }
    assert!(worst < 1e-6, "worst {worst:e}");
    assert_eq!(normal_quantile_of(0.0f32), f32::NEG_INFINITY);
    assert_eq!(normal_quantile_of(1.0f32), f32::INFINITY);
    assert_eq!(normal_quantile_of(0.5f32), 0.0);
}

/// The grid of the f32 type's tests with the ends as a model forms them in f32, θr/2 ∓ π/4, and the f64 type
/// on those same ends: (μ, σ, lo, hi).
fn grid_f32() -> impl Iterator<Item = (f32, f32, f32, f32)> {
    const WIDTHS: [f32; 7] = [1e-4, 1e-3, 0.01, 0.1, 0.3, 1.0, FRAC_PI_2];
    (0..=40).flat_map(|i| {
        let mu = -FRAC_PI_4 + i as f32 * FRAC_PI_2 / 40.0;
        WIDTHS.into_iter().flat_map(move |sigma| {
            (0..=60).map(move |k| {
                let c = 0.5 * (-FRAC_PI_2 + k as f32 * PI / 60.0);
                (mu, sigma, c - FRAC_PI_4, c + FRAC_PI_4)
            })
        })
    })
}

/// Eight distributions of the grid at once, or one.
fn both_forms(
    mu: f32,
    sigma: f32,
    lo: f32,
    hi: f32,
) -> (TruncatedGaussianOf<f32>, TruncatedGaussianOf<f32x8>) {
    let inv = (1.0 / sigma as f64) as f32;
    // The query in lane 3; other lanes hold other ends, so a lane that leaked would show.
    let spread = |x: f32, d: f32| {
        f32x8::new(std::array::from_fn(|k| {
            if k == 3 {
                x
            } else {
                x + d * k as f32
            }
        }))
    };
    (
        TruncatedGaussianOf::new(mu, sigma, inv, lo, hi),
        TruncatedGaussianOf::new(mu, sigma, inv, spread(lo, 0.07), spread(hi, 0.07)),
    )
}

#[test]
fn generic_pdf_matches_f64() {
    // Every case (central, tail, uniform) against the f64 type on the same ends, where the density is within
    // e^{−20} of the interval's largest, in log form; allowed: 1e-6 plus the f32 standardisation's 4e-7 per
    // unit of the exponent (see the type's docs).
    let (mut worst, mut tails, mut fallbacks) = (0.0f64, 0, 0);
    for (mu, sigma, lo, hi) in grid_f32() {
        let (m64, s64, lo64, hi64) = (mu as f64, sigma as f64, lo as f64, hi as f64);
        let tg = TruncatedGaussian::new(m64, s64, lo64, hi64);
        let (one, eight) = both_forms(mu, sigma, lo, hi);
        tails += (one.b <= 0.0) as u32;
        fallbacks += (tg.mass() == 0.0) as u32;
        let peak = tg.pdf(m64.clamp(lo64, hi64));
        for j in 0..=200 {
            let y = lo + (hi - lo) * j as f32 / 200.0;
            let exact = tg.pdf(y as f64);
            if exact == 0.0 || (peak / exact).ln() > 20.0 {
                continue;
            }
            let x = (y - mu) * (1.0 / sigma);
            let g = INV_SQRT_TAU / sigma * exp_lobe(-0.5 * x * x);
            let e = 0.5
                * (((y as f64 - m64) / s64).powi(2)
                    - ((m64.clamp(lo64, hi64) - m64) / s64).powi(2));
            let spread = |x: f32| f32x8::new(std::array::from_fn(|k| if k == 3 { x } else { 0.0 }));
            let got = [
                one.pdf_given(y, g) as f64,
                eight.pdf_given(spread(y), spread(g)).lane(3) as f64,
            ];
            for got in got {
                worst = worst.max((got / exact).ln().abs() / (1e-6 + 4e-7 * e));
            }
        }
    }
    assert!(
        tails > 1000 && fallbacks > 0,
        "{tails} tails, {fallbacks} fallbacks"
    );
    assert!(worst < 1.0, "worst error {worst} of the allowance");
}

#[test]
fn generic_sampler_matches_f64() {
    // As `f32_sampler_matches_f64`, every case: the f32 value against the f64 sampler's, in CDF level
    // (≈ pdf · |y32 − y64|) beyond the f32 rounding of the value itself (an ulp of y, which the old scalar
    // sampler had too).
    let (mut worst, mut central) = (0.0f64, 0);
    for (mu, sigma, lo, hi) in grid_f32() {
        let tg = TruncatedGaussian::new(mu as f64, sigma as f64, lo as f64, hi as f64);
        let (one, eight) = both_forms(mu, sigma, lo, hi);
        central += (one.b > 0.0) as u32;
        for j in 0..=100 {
            let u = j as f32 / 100.0;
            let y64 = tg.sample(u as f64);
            let spread = f32x8::new(std::array::from_fn(|k| if k == 3 { u } else { 0.5 }));
            for y32 in [one.sample(u), eight.sample(spread).lane(3)] {
                let ulp = (y64 as f32).abs().max(1e-30) * f32::EPSILON;
                let d = ((y32 as f64 - y64).abs() - ulp as f64).max(0.0);
                let level = d * tg.pdf(0.5 * (y32 as f64 + y64));
                worst = worst.max(level);
            }
        }
    }
    assert!(central > 1000 && worst < 2e-6, "worst {worst:e}");
}

#[test]
fn generic_tails_and_exponential_match_the_scalar_ones() {
    let zs = [0.0f32, 0.3, 1.0, 2.5, 4.0, 5.9, 6.1, 30.0];
    let eight = upper_tail_of(f32x8::new(zs));
    for (k, &z) in zs.iter().enumerate() {
        let want = upper_tail_f32(z as f64);
        // (z/√2 is rounded in f32 here, in f64 there: the exponent −z²/2 differs by ~1e-7 z².)
        for got in [upper_tail_of(z), eight.lane(k)] {
            assert!(
                (got - want).abs() <= 4e-7 * (1.0 + z * z) * want,
                "Φ(−{z}): {got} vs {want}"
            );
        }
    }
    let xs = [0.0f32, -1.0, -20.0, -87.0, -100.0, -103.9, -104.1, -1e6];
    let eight = exp_lobe_of(f32x8::new(xs));
    for (k, &x) in xs.iter().enumerate() {
        // f32's exponential is the lanes' on one lane (util::real): the two forms agree bit for bit, and with
        // libm's within a few ulp (subnormal results flush to 0).
        assert_eq!(exp_lobe_of(x).to_bits(), eight.lane(k).to_bits());
        let want = exp_lobe(x);
        let got = eight.lane(k);
        assert!(
            (got - want).abs() <= 4e-7 * want + 1.2e-38,
            "e^{x}: {got} vs {want}"
        );
    }
}
