//! The pilots' unit tests (window layout, the candidates' prediction, bias, pooling, gain and merging on
//! synthetic pixels), apart because they outweigh the code they test.

use super::pair::{mean_and_error, Pilot};
use super::*;
use crate::render::integrator::RayCounts;
use rand::Rng;

#[test]
fn windows_lie_inside_the_film_and_do_not_overlap() {
    for (w, h) in [
        (640, 480),
        (512, 512),
        (128, 128),
        (96, 72),
        (20, 10),
        (1, 1),
        (97, 33),
    ] {
        let ws = windows(w, h);
        assert!(!ws.is_empty());
        for (i, r) in ws.iter().enumerate() {
            assert!(r.check_inside(w, h).is_ok(), "{r:?} in {w}x{h}");
            assert!(r.width() > 0 && r.height() > 0);
            for s in &ws[i + 1..] {
                let overlap = r.x0 < s.x1 && s.x0 < r.x1 && r.y0 < s.y1 && s.y0 < r.y1;
                assert!(!overlap, "{r:?} overlaps {s:?} in {w}x{h}");
            }
        }
    }
    // A sixteenth of the film, spread over it: 640x480 has 19 200 pixels to sample, capped at 9 216 (576
    // windows); 128² has 1 024 (64 windows, 8 × 8); small films at least 576 pixels.
    // The grid follows the film's aspect, so the count is rounded: 28 × 21 on 640x480.
    assert_eq!(windows(640, 480).len(), 28 * 21);
    let w128 = windows(128, 128);
    assert_eq!(w128.len(), 64);
    assert_eq!((w128[0].x0, w128[63].x1), (6, 122));
    assert_eq!(windows(96, 72).len(), 7 * 5);
}

#[test]
fn four_light_and_four_material_samples_are_predicted_from_the_other_three() {
    let fur = [
        ((1, 1), 8.73e-2, 0.035),
        ((1, 4), 7.51e-2, 0.055),
        ((4, 1), 7.68e-2, 0.055),
    ];
    assert_eq!(predicted_both((1, 4), &fur), None);
    assert_eq!(predicted_both((4, 4), &fur[..2]), None);
    let (v, s) = predicted_both((4, 4), &fur).unwrap();
    assert!(
        (v - 6.46e-2).abs() < 1e-9 && (s - 0.075).abs() < 1e-9,
        "{v} {s}"
    );
    // The fur ball's: 1.6x (1, 1)'s cost, not rendered.
    assert!(v * s > SKIP_MARGIN * 8.73e-2 * 0.035);
    // Where the light and material noise dominate and each halves, (4, 4) is predicted to win: rendered.
    let noisy = [((1, 1), 1.0, 1.0), ((1, 4), 0.55, 1.3), ((4, 1), 0.55, 1.3)];
    let (v, s) = predicted_both((4, 4), &noisy).unwrap();
    assert!(v * s < SKIP_MARGIN * 1.0 * 1.0, "{v} {s}");
}

/// Path lengths are compared by their noise over the longest path's means: a short path, darker by the bounce
/// it leaves out, has the same absolute noise but is not read as relatively noisier. Here path 0 is half as
/// bright as path 1, as noisy per pixel, and two thirds of its rays: over its own means it would cost 2.6×
/// path 1 per unit of relMSE and lose; over path 1's it costs 2/3 and, its bias within budget, wins.
#[test]
fn path_lengths_are_compared_over_the_longest_paths_means() {
    let pair = |level: f32, camera: u64| {
        let pixels = |sign: f32| -> Vec<[f32; 3]> {
            (0..64)
                .map(|i| [level + if i % 2 == 0 { 0.1 } else { -0.1 } * sign; 3])
                .collect()
        };
        let mut pair = with_variances(pixels(1.0), pixels(-1.0), 0.01);
        for p in &mut pair.0 {
            p.rays.camera = camera;
        }
        pair
    };
    let pairs = [pair(0.5, 2_000_000), pair(1.0, 3_000_000)];
    // Path 1's pixels mean 1 everywhere, so its neighbours' means are 1 too.
    let means = neighbour_means(pairs[1].rgb(), &[region(8, 8)]);
    assert!(means.iter().flatten().all(|&m| (m - 1.0).abs() < 1e-6));
    // Bounce 1's bias 0.02, within half of 0.1 when left out (its tail 0.04 with the unknown ratio ½).
    let (chosen, left, listed) = cheapest_path_length(&pairs, &means, &[0.02], 0.1);
    assert_eq!(chosen, 0, "{listed}");
    assert!((left - 0.04).abs() < 1e-12, "{left}");
    // Over its own means path 0's relMSE is (1.01 / 0.26)× path 1's.
    let own = pairs[0].rel_mse() / pairs[1].rel_mse();
    // (f32 pixel values: to 1e-6 relative.)
    assert!((own / (1.01 / 0.26) - 1.0).abs() < 1e-5, "{own}");
}

#[test]
fn the_tail_falls_at_the_largest_ratio_of_the_bounces_measured() {
    assert_eq!(decay_ratio(&[]), 0.5);
    assert_eq!(decay_ratio(&[0.15]), 0.5);
    // A bounce that grew is not extrapolated as growing.
    assert_eq!(decay_ratio(&[0.01, 0.04]), MAX_BOUNCE_RATIO);
    assert_eq!(decay_ratio(&[0.0, 0.04]), 0.5);
    // The Cornell box's pilots (pooled products, 128²) read bounces 1-5 at 0.156, 0.089, 0.050, 0.0214, 0.0102,
    // where two 256-spp seeds per path length measure the bias left after path 3 at ≈ 0.045-0.049 and after
    // path 5 at 0.0143: the rate dips (0.43) and recovers (0.61 for bounce 6), so the last ratio (0.48) reads
    // those tails at 0.041 and 0.0092, and the largest (0.57) at 0.050 and 0.0136.
    let cornell = [0.156, 0.089, 0.050, 0.0214, 0.0102];
    let r = decay_ratio(&cornell);
    assert!((r - 0.089 / 0.156).abs() < 1e-12, "{r}");
    let after_3 = bias_left(cornell[3], r);
    let after_5 = bias_left(cornell[4] * r, r);
    assert!((0.045..0.055).contains(&after_3), "{after_3}");
    assert!((0.0125..0.016).contains(&after_5), "{after_5}");
    let last = cornell[4] / cornell[3];
    assert!(bias_left(cornell[4] * last, last) < 0.0143 * 0.7);
    // The fur ball's ratios grow with depth: the largest is the last.
    let fur = [0.155, 0.058, 0.023];
    assert!((decay_ratio(&fur) - 0.023 / 0.058).abs() < 1e-12);
}

/// A later bounce's bias is the one before's scaled by the ratio of their mean relative contributions, at most
/// 1, and unknown when the one before has no positive mean.
#[test]
fn a_later_bounce_is_scaled_by_the_ratio_of_relative_means() {
    let bounce = |relative_mean| Bounce {
        mean: 1.0,
        standard_error: 1.0,
        relative_mean,
        pooled_mean: 0.0,
    };
    let b = next_bias(0.1, &bounce(0.05), &bounce(0.02)).unwrap();
    assert!((b - 0.04).abs() < 1e-12, "{b}");
    assert_eq!(next_bias(0.1, &bounce(0.05), &bounce(0.08)), Some(0.1));
    assert_eq!(next_bias(0.1, &bounce(0.05), &bounce(-0.01)), Some(0.0));
    assert_eq!(next_bias(0.1, &bounce(0.0), &bounce(0.02)), None);
}

/// The light/material candidates are compared on every second window of every second row of the grid: a
/// quarter spread over the whole film (not two columns of it), or every window where that leaves fewer than 16.
#[test]
fn the_sample_candidates_are_compared_on_a_spread_quarter_of_the_windows() {
    let ws = windows(128, 128);
    let picked = comparison_windows(&ws);
    assert_eq!(picked.len(), 16);
    let xs: std::collections::BTreeSet<u32> = picked.iter().map(|&i| ws[i].x0).collect();
    let ys: std::collections::BTreeSet<u32> = picked.iter().map(|&i| ws[i].y0).collect();
    assert_eq!((xs.len(), ys.len()), (4, 4), "{picked:?}");
    // 640x480: 28 x 21 windows, 14 x 11 picked.
    assert_eq!(comparison_windows(&windows(640, 480)).len(), 14 * 11);
    // 96x72: 7 x 5 windows, a quarter would be 12: all of them.
    assert_eq!(comparison_windows(&windows(96, 72)).len(), 35);
}

/// A subset of a pilot's windows and the rest merge back into the pilot: pixels and rays, in window order.
#[test]
fn a_pilot_split_into_windows_merges_back() {
    let rays = |k: u64| RayCounts {
        camera: k,
        shadow: 2 * k,
        ..RayCounts::default()
    };
    let full = Pilot {
        rgb: (0..12).map(|i| [i as f32, 0.0, 1.0]).collect(),
        var: (0..12).map(|i| [0.0, i as f32, 0.0]).collect(),
        seconds: 3.0,
        samples: 48,
        rays: rays(6),
        windows: (0..3).map(|w| (4 * w, 4, rays(w as u64 + 1))).collect(),
    };
    let a = full.subset(&[0, 2]);
    assert_eq!(a.rgb.len(), 8);
    assert_eq!(a.rgb[4][0], 8.0);
    assert_eq!(a.rays, rays(4));
    let b = full.subset(&[1]);
    let merged = Pilot::merge(&a, &[0, 2], &b, 3);
    assert_eq!(merged.rgb, full.rgb);
    assert_eq!(merged.var, full.var);
    assert_eq!(merged.rays, full.rays);
    assert_eq!(merged.samples, full.samples);
    assert!((merged.seconds - full.seconds).abs() < 1e-12);
    assert_eq!(merged.windows, full.windows);
}

/// A `w`×`h` window at the film's corner.
fn region(w: u32, h: u32) -> Region {
    Region {
        x0: 0,
        y0: 0,
        x1: w,
        y1: h,
    }
}

/// Pixels whose estimates are skewed (mostly a little dim, now and then bright, as where few samples find a
/// bright path): each seed's pixel value 0.9 with probability 0.9 and 1.9 with 0.1, mean 1 and variance 0.09
/// (relMSE 0.089, as noisy as the shipped scenes' pilots), so the true relMSE of one estimate is 0.09 / 1.01.
/// Over the pair's own means a pixel whose seeds differ (one bright) divides its error by the bright mean:
/// 1² / 2 / (1.4² + 0.01) with probability 0.18, 0.51 of the truth. Over its neighbours' means (3×3 in 4×4
/// windows, both seeds) the pixel's own samples do not divide, and only the neighbours' noise is left (3 to
/// 8 pixels: 1/(m̃² + 0.01) is convex, so it reads 2–5 % high).
#[test]
fn a_pixels_own_bright_samples_do_not_divide_its_error() {
    let mut rng = rand_pcg::Pcg32::new(7, 7);
    let windows = vec![region(4, 4); 400];
    let mut draw = || -> Vec<[f32; 3]> {
        (0..16 * windows.len())
            .map(|_| std::array::from_fn(|_| if rng.random::<f32>() < 0.1 { 1.9 } else { 0.9 }))
            .collect()
    };
    let pair = with_variances(draw(), draw(), 0.0);
    let truth = 0.09 / 1.01;
    let own = pair.rel_mse() / truth;
    let neighbours = pair
        .rel_mse_over_means(&neighbour_means(pair.rgb(), &windows))
        .0
        / truth;
    assert!((0.45..0.57).contains(&own), "own means: {own} of the truth");
    assert!(
        (0.95..1.1).contains(&neighbours),
        "neighbours' means: {neighbours} of the truth"
    );
}

/// A pair of pilot estimates from two seeds' pixel values, every pixel's sample variance `v`.
fn with_variances(a: Vec<[f32; 3]>, b: Vec<[f32; 3]>, v: f32) -> Pair {
    let pilot = |rgb: Vec<[f32; 3]>| Pilot {
        windows: vec![(0, rgb.len(), RayCounts::default())],
        var: vec![[v; 3]; rgb.len()],
        rgb,
        seconds: 0.0,
        samples: 0,
        rays: RayCounts::default(),
    };
    Pair([pilot(a), pilot(b)])
}

/// A shorter path's means are darker than the longest's by the bounces it leaves out, so its noise reads
/// lower over the longest's means: pixels 1 ± d against 1.2 ± d give (1 + 0.01) / (1.44 + 0.01); a pair
/// against itself 1; never above 1.
#[test]
fn a_darker_path_reads_less_noise_over_the_longest_paths_means() {
    let d = 0.1f32;
    let pixels = |m: f32, sign: f32| vec![[m + sign * d; 3]; 64];
    let short = with_variances(pixels(1.0, 1.0), pixels(1.0, -1.0), 0.0);
    let long = with_variances(pixels(1.2, 1.0), pixels(1.2, -1.0), 0.0);
    let f = darkening_of(&short, &long);
    let expected = 1.01 / 1.45;
    assert!((f - expected).abs() < 1e-4, "{f} against {expected}");
    assert!((darkening_of(&short, &short) - 1.0).abs() < 1e-12);
    assert_eq!(darkening_of(&long, &short), 1.0);
}

/// The sampler's gain from the pilot pair alone: G = mean s² / (4 relMSE(4)) = (4g − 1) / 3. Pixels 1 ± d
/// (relMSE 2d² / 1.01 per channel) with s² = 8d² · 7/3 give G = 7/3, g = 2; lowered by its standard errors but
/// never under 1; and 1 where the pair is noisier than its samples' variance predicts (nothing to credit).
#[test]
fn the_sampler_gain_compares_the_pixels_sample_variance_with_the_pair() {
    let d = 0.1f32;
    let pair = |variance: f32| {
        let v = |s: f32| -> Vec<[f32; 3]> {
            (0..400)
                .map(|i| [1.0 + s * d * (1.0 + 0.1 * ((i % 3) as f32 - 1.0)); 3])
                .collect()
        };
        with_variances(v(1.0), v(-1.0), variance)
    };
    // The ±10 % spread of d makes the mean of d² 1.00667 d².
    let two = pair(8.0 * d * d * 1.00667 * 7.0 / 3.0);
    let (exact, point) = sampler_gain(&two, 0.0);
    assert!(
        (point - 2.0).abs() < 0.01 && exact == point,
        "{point} {exact}"
    );
    let (lowered, _) = sampler_gain(&two, 2.0);
    assert!(lowered < point && lowered >= 1.0, "{lowered}");
    let noisy = pair(8.0 * d * d * 0.5);
    let (gain, point) = sampler_gain(&noisy, 0.0);
    assert!(point < 1.0 && gain == 1.0, "{point} {gain}");
}

/// Pilot pixels of a bounce found by few samples (each of 4 samples hits with probability 0.3, and a hit
/// carries the bounce, as on dense fur): the pixel's own mean rises with its bounce, so a denominator from it
/// underestimates the bias; the neighbours' does not. Pooled over the 3×3 neighbourhoods, the products read
/// the same bias with less than half the spread.
#[test]
fn a_bounce_found_by_few_samples_is_not_underestimated() {
    let ws = windows(256, 256);
    let pixels: usize = ws.iter().map(|r| (r.width() * r.height()) as usize).sum();
    let mut state = 0x1234_5678_u64;
    let mut uniform = move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((state >> 40) as f64) / f64::from(1u32 << 24)
    };
    let (p, beta) = (0.3, 0.2);
    let mut render = || {
        let (mut before, mut after) = (Vec::new(), Vec::new());
        for _ in 0..pixels {
            let (mut b, mut a) = ([0.0f32; 3], [0.0f32; 3]);
            for c in 0..3 {
                let (mut x, mut d) = (0.0, 0.0);
                for _ in 0..PILOT_SPP {
                    if uniform() < p {
                        x += 1.0 / p;
                        d += beta / p * 2.0 * uniform();
                    }
                }
                let n = f64::from(PILOT_SPP);
                b[c] = (x / n) as f32;
                a[c] = ((x + d) / n) as f32;
            }
            before.push(b);
            after.push(a);
        }
        (before, after)
    };
    let truth = beta * beta / ((1.0 + beta) * (1.0 + beta) + 0.01);
    // Six independent pilot pairs: the pixel products and the pooled ones ([`pooled_bias`]) read the same
    // squared bias, the pooled with far less spread between pairs.
    let pairs: Vec<Bounce> = (0..6)
        .map(|_| {
            let (b0, a0) = render();
            let (b1, a1) = render();
            bounce_bias([&b0, &b1], [&a0, &a1], &ws)
        })
        .collect();
    let spread = |f: fn(&Bounce) -> f64| {
        let (m, _) = mean_and_error(pairs.iter().map(f));
        let var = pairs.iter().map(|b| (f(b) - m).powi(2)).sum::<f64>() / 5.0;
        (m, var.sqrt())
    };
    let (pixel_mean, pixel_spread) = spread(|b| b.mean);
    let (pooled_mean, pooled_spread) = spread(|b| b.pooled_mean);
    assert!(
        (pooled_mean / truth - 1.0).abs() < 0.15,
        "pooled {pooled_mean:.4e} against {truth:.4e}"
    );
    assert!(
        pooled_spread < 0.5 * pixel_spread,
        "pooled {pooled_mean:.4e} ± {pooled_spread:.1e}, pixel products {pixel_mean:.4e} ± {pixel_spread:.1e} \
         (mean ± spread over six pairs)"
    );
    let (b0, a0) = render();
    let (b1, a1) = render();
    let Bounce {
        mean,
        standard_error: error,
        ..
    } = bounce_bias([&b0, &b1], [&a0, &a1], &ws);
    // The same products over each pixel's own mean (the estimator before): far under the truth.
    let own = (0..pixels)
        .flat_map(|i| (0..3).map(move |c| (i, c)))
        .map(|(i, c)| {
            let (da, db) = (
                f64::from(a0[i][c] - b0[i][c]),
                f64::from(a1[i][c] - b1[i][c]),
            );
            let m = 0.5 * f64::from(a0[i][c] + a1[i][c]);
            da * db / (m * m + 0.01)
        })
        .sum::<f64>()
        / (3 * pixels) as f64;
    assert!(
        own < 0.8 * truth,
        "the model shows the failure: {own:.4e} against {truth:.4e}"
    );
    assert!(
        mean > 0.9 * truth && mean < 1.3 * truth,
        "{mean:.4e} ± {error:.1e} against {truth:.4e}"
    );
}
