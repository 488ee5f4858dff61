//! The splatting film's unit tests: brute-force weighted means, tilings and crops, fixed point, the quantities
//! summed, the noise share and each source as its own mean.

use super::*;
use crate::render::settings::FilmConfig;
use glam::Vec3;

/// Sample `i` of pixel (x, y) of a synthetic frame: a position and a beauty hashed from (x, y, i).
fn synthetic(x: u32, y: u32, i: u32) -> PathSample {
    let h = |k: u32| {
        let v =
            (x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663) ^ i.wrapping_mul(83_492_791))
                .wrapping_add(k.wrapping_mul(2_654_435_761));
        let v = v ^ (v >> 15);
        let v = v.wrapping_mul(2_246_822_519) ^ (v >> 13);
        (v % 10_000) as f32 / 10_000.0
    };
    PathSample {
        beauty: Vec3::new(h(1) * 3.0, h(2), 0.25 + x as f32 * 0.01),
        alpha: 1.0,
        film: [h(3), h(4)],
        ..Default::default()
    }
}

/// `region` of a `size` frame rendered in work tiles of `side`² with `spp` synthetic samples per pixel (one more
/// in pixels whose x + y is odd), assembled as the driver does: the beauty's R channel.
fn render(size: [u32; 2], region: Region, side: u32, filter: SplatFilter) -> Image {
    render_summing(size, region, side, filter, false)
}

/// [`render`], summing every quantity (`all`) or those the beauty reads.
fn render_summing(
    size: [u32; 2],
    region: Region,
    side: u32,
    filter: SplatFilter,
    all: bool,
) -> Image {
    let film = FilmConfig {
        aovs: vec![],
        ..FilmConfig::default()
    };
    let layout = Layout::new(&film);
    let summed = if all {
        Summed::all()
    } else {
        Summed::new(&layout)
    };
    let mut tiles = Vec::new();
    let mut done = Vec::new();
    let mut edges = Vec::new();
    for ty in (region.y0..region.y1).step_by(side as usize) {
        for tx in (region.x0..region.x1).step_by(side as usize) {
            let (x1, y1) = ((tx + side).min(region.x1), (ty + side).min(region.y1));
            let mut tile = Tile::new(tx, ty, x1, y1, &layout);
            let take = |x: u32, y: u32, sums: &mut SourceSums| {
                let n = 3 + (x + y) % 2;
                for i in 0..n {
                    sums.add(&synthetic(x, y, i));
                }
                n
            };
            edges.extend(render_tile(
                &mut Scratch::default(),
                &mut tile,
                region,
                size,
                filter,
                &summed,
                take,
                |_, _, _, _| {},
            ));
            done.push(Region {
                x0: tx,
                y0: ty,
                x1,
                y1,
            });
            (tile.x0, tile.x1, tile.y0, tile.y1) = (
                tx - region.x0,
                x1 - region.x0,
                ty - region.y0,
                y1 - region.y0,
            );
            tiles.push(tile);
        }
    }
    let mut image = film::assemble(region.width(), region.height(), &tiles, &layout);
    finish_edges(&mut image, region, &layout, &summed, edges, &done);
    image
}

#[test]
fn a_splatted_pixel_is_the_filter_weighted_mean_of_every_sample_that_reaches_it() {
    let size = [9, 7];
    let full = Region::full(9, 7);
    let f = SplatFilter::new(3.0);
    let image = render(size, full, 4, f);
    let g = |d: f64| {
        let sigma = 0.5;
        if d.abs() < 1.5 {
            (-d * d / (2.0 * sigma * sigma)).exp()
        } else {
            0.0
        }
    };
    for py in 0..7u32 {
        for px in 0..9u32 {
            let (mut sum, mut weight) = (0.0f64, 0.0f64);
            for qy in 0..7u32 {
                for qx in 0..9u32 {
                    for i in 0..3 + (qx + qy) % 2 {
                        let s = synthetic(qx, qy, i);
                        let w = g(f64::from(qx) + f64::from(s.film[0]) - f64::from(px) - 0.5)
                            * g(f64::from(qy) + f64::from(s.film[1]) - f64::from(py) - 0.5);
                        sum += w * f64::from(s.beauty.x);
                        weight += w;
                    }
                }
            }
            let want = sum / weight;
            let got = f64::from(image.get(px as usize, py as usize, 0));
            assert!(
                (got - want).abs() < 1e-5 * want.abs().max(1.0),
                "({px}, {py}): {got} against {want}"
            );
        }
    }
}

/// A `w` × `h` frame splatted as one work tile with the 3-pixel filter, the beauty alone: each source pixel's
/// samples from `samples`, which returns the scale its sums are added with ([`TileSplats::add`]).
fn one_tile(w: u32, h: u32, samples: impl Fn(u32, u32, &mut SourceSums) -> f32) -> Image {
    let region = Region::full(w, h);
    let filter = SplatFilter::new(3.0);
    let film = FilmConfig {
        aovs: vec![],
        ..FilmConfig::default()
    };
    let layout = Layout::new(&film);
    let summed = Summed::new(&layout);
    let mut tile = Tile::new(0, 0, w, h, &layout);
    let mut scratch = Scratch::default();
    let mut splats = TileSplats::new(&mut scratch, &tile, region, [w, h], filter, &summed);
    let mut source = SourceSums::new(filter, summed.clone());
    for (x, y) in sources(&tile, region, [w, h], filter.reach()) {
        source.clear();
        let scale = samples(x, y, &mut source);
        splats.add(x, y, &source, scale);
    }
    let taken = vec![0; (w * h) as usize];
    assert!(splats
        .finish(&mut tile, &summed, &taken, |_, _, _, _| {})
        .is_empty());
    film::assemble(w, h, &[tile], &layout)
}

/// The noise model adaptive sampling's stop reads ([`SplatFilter::noise_shares`]) against splatted noise: i.i.d.
/// samples (uniform on [0, 3), variance ¾) at 8 or 32 per pixel in 4 × 4 blocks, each source summed as the mean
/// of its own samples (scale 1/n, as adaptive sampling does). The image's mean squared error is the mean over
/// pixels of share · σ² / n within 10 % (measured 1.002; its own noise here is ~4 %); with the share left out
/// (1) it would be 3× off.
#[test]
fn the_noise_share_predicts_the_splatted_images_noise() {
    let (w, h) = (64u32, 64u32);
    let count = |x: u32, y: u32| {
        if (x / 4 + y / 4).is_multiple_of(2) {
            8
        } else {
            32
        }
    };
    let image = one_tile(w, h, |x, y, source| {
        let n = count(x, y);
        for i in 0..n {
            source.add(&synthetic(x, y, i));
        }
        1.0 / n as f32
    });
    let (mean, variance) = (1.5 * 9_999.0 / 10_000.0, 0.75);
    let shares = SplatFilter::new(3.0).noise_shares([w, h]);
    let (mut measured, mut predicted) = (0.0f64, 0.0f64);
    for y in 0..h {
        for x in 0..w {
            let e = f64::from(image.get(x as usize, y as usize, 0)) - mean;
            measured += e * e;
            predicted += shares.at(x, y) * variance / f64::from(count(x, y));
        }
    }
    let ratio = measured / predicted;
    assert!(
        (0.9..1.1).contains(&ratio),
        "measured {measured:.4} against {predicted:.4}: {ratio:.3}"
    );
    // Inside the frame the 3-pixel Gaussian keeps about a third of each pixel's variance of the mean.
    assert!(
        (0.30..0.34).contains(&shares.at(32, 32)),
        "{}",
        shares.at(32, 32)
    );
    assert!(shares.at(0, 0) > 1.5 * shares.at(32, 32));
}

/// Under adaptive sampling each source counts as the mean of its own samples (scale 1/n): pixels of 4 and 64
/// samples in a checkerboard, each pixel's samples on a stratified grid and its value constant (1 on one colour,
/// 0 on the other), give every pixel the filter's weighted mean of its neighbours' values whatever their counts:
/// the image of 64 samples everywhere, up to the 2 × 2 grid's quadrature of the filter (0.010 at worst).
/// Summing every sample alike (scale 1) weighs the 64-sample pixels 16× and misses it by 0.57.
#[test]
fn a_source_counts_as_its_own_mean_whatever_its_count() {
    let (w, h) = (12u32, 12u32);
    let render = |mixed: bool, scaled: bool| {
        one_tile(w, h, |x, y, source| {
            let even = (x + y) % 2 == 0;
            let side = if even || !mixed { 8u32 } else { 2 };
            for i in 0..side * side {
                source.add(&PathSample {
                    beauty: Vec3::splat(f32::from(u8::from(even))),
                    alpha: 1.0,
                    film: [
                        ((i % side) as f32 + 0.5) / side as f32,
                        ((i / side) as f32 + 0.5) / side as f32,
                    ],
                    ..Default::default()
                });
            }
            if scaled {
                1.0 / (side * side) as f32
            } else {
                1.0
            }
        })
    };
    let reference = render(false, false);
    let (scaled, alike) = (render(true, true), render(true, false));
    let (mut worst_scaled, mut worst_alike) = (0.0f32, 0.0f32);
    for y in 0..h as usize {
        for x in 0..w as usize {
            let r = reference.get(x, y, 0);
            worst_scaled = worst_scaled.max((scaled.get(x, y, 0) - r).abs());
            worst_alike = worst_alike.max((alike.get(x, y, 0) - r).abs());
        }
    }
    assert!(worst_scaled < 0.02, "{worst_scaled}");
    assert!(worst_alike > 0.4, "{worst_alike}");
}

#[test]
fn a_frame_sums_only_the_quantities_its_channels_read_and_gets_the_same_pixels() {
    let film = |aovs: &[&str]| FilmConfig {
        aovs: aovs.iter().map(|a| a.to_string()).collect(),
        ..FilmConfig::default()
    };
    assert_eq!(
        Summed::new(&Layout::new(&film(&[]))).quantities,
        [0, 1, 2, 3]
    );
    assert_eq!(
        Summed::new(&Layout::new(&film(&["all"]))).quantities,
        (0..QUANTITIES).collect::<Vec<_>>()
    );
    assert_eq!(
        Summed::new(&Layout::new(&film(&["shadow", "depth", "spp"]))).quantities,
        [0, 1, 2, 3, 25, 26]
    );
    let (size, full, f) = ([11, 6], Region::full(11, 6), SplatFilter::new(3.0));
    assert_eq!(
        render_summing(size, full, 4, f, false).data,
        render_summing(size, full, 4, f, true).data
    );
}

#[test]
fn splatted_pixels_do_not_depend_on_the_work_tiles_or_the_region() {
    let size = [13, 9];
    let full = Region::full(13, 9);
    for width in [3.0, 4.0, 5.5] {
        let f = SplatFilter::new(width);
        let one = render(size, full, 64, f);
        for side in [1, 2, 3, 5] {
            assert_eq!(
                render(size, full, side, f).data,
                one.data,
                "width {width}, tiles of {side}"
            );
        }
        // A crop (its margin rendered for its splats) holds the full frame's pixels bit for bit: inside the
        // frame, on its corners, and a band of whole rows as `--tile` makes.
        for (x0, y0, x1, y1) in [(2, 3, 11, 7), (0, 0, 5, 9), (8, 0, 13, 4), (0, 5, 13, 9)] {
            let crop = Region { x0, y0, x1, y1 };
            let part = render(size, crop, 3, f);
            for y in 0..crop.height() as usize {
                for x in 0..crop.width() as usize {
                    let bits = |p: &[f32]| p.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                    assert_eq!(
                        bits(part.pixel(x, y)),
                        bits(one.pixel(x + x0 as usize, y + y0 as usize)),
                        "width {width}, crop {crop:?}, pixel ({x}, {y})"
                    );
                }
            }
        }
    }
}

#[test]
fn fixed_point_is_exact_and_its_sums_do_not_depend_on_order() {
    for v in [1.0f32, -2.5, 1e-12, 3.0e9, 0.1, -7.25e-5] {
        let back = fixed(v) as f64 * UNIT;
        assert_eq!(back as f32, v, "{v}");
    }
    assert_eq!(fixed(0.0), 0);
    assert_eq!(fixed(f32::NAN), 0);
    assert_eq!(fixed(f32::INFINITY), i128::MAX);
    assert_eq!(fixed(1e-30), 0);
    // f32 sums of these depend on the order; their fixed-point sums do not.
    let values = [1.0f32, 1e8, -1e8, 3e-3];
    let forward: i128 = values.iter().map(|&v| fixed(v)).sum();
    let backward: i128 = values.iter().rev().map(|&v| fixed(v)).sum();
    assert_eq!(forward, backward);
    let f32_forward: f32 = values.iter().sum();
    let f32_backward: f32 = values.iter().rev().sum();
    assert_ne!(f32_forward, f32_backward, "the example must show the order");
}

#[test]
fn a_sample_reaches_the_pixels_its_filter_covers() {
    let f = SplatFilter::new(3.0);
    assert_eq!(f.reach(), 1);
    assert_eq!(SplatFilter::new(4.0).reach(), 2);
    assert_eq!(SplatFilter::new(1.0).reach(), 0);
    let mut w = [0.0; 3];
    // At the pixel's centre: its own weight 1, the neighbours' centres 1 px away: exp(−2).
    f.weights(0.5, &mut w);
    assert!((w[1] - 1.0).abs() < 1e-6);
    assert!((w[0] - (-2.0f32).exp()).abs() < 1e-6 && w[0] == w[2]);
    // On the left edge the right neighbour's centre is 1.5 px away: outside the truncated filter; just inside
    // it, in with a small weight.
    f.weights(0.0, &mut w);
    assert!(w[0] > 0.5 && w[2] == 0.0, "{w:?}");
    f.weights(0.001, &mut w);
    assert!(w[2] > 0.0 && w[2] < 0.02, "{w:?}");
}
