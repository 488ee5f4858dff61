//! Per-pixel measures of a study point against its reference, beside RMSE and relMSE ([`super::metrics`]):
//!
//! - **SSIM** (Wang, Bovik, Sheikh & Simoncelli 2004, eq. 13), the perceptual measure the studies report. Chosen
//!   over FLIP (Andersson et al. 2020) because it is fully specified by one short formula with published constants
//!   and no display model, so an independent implementation can be checked number for number (the tests do, against
//!   closed forms and against a NumPy transcription); no well-kept Rust crate exists for either (`dssim-core` is
//!   AGPL and computes a multi-scale variant; `nv-flip` wraps NVIDIA's C++ and needs another native build), so it is
//!   written here. Rendered radiance is HDR, so both images are first mapped to [0, 1) the same way: luminance
//!   Y = 0.2126 R + 0.7152 G + 0.0722 B (Rec. 709), scaled by 1 / (the reference's 99th-percentile luminance) and
//!   compressed by v = Y / (1 + Y) (Reinhard); then L = 1, C₁ = (0.01 L)², C₂ = (0.03 L)², an 11 × 11 Gaussian
//!   window of σ = 1.5 pixels (the paper's), **clipped at the image border and renormalised** there (so images
//!   smaller than the window still work), and the mean of the SSIM map over every pixel. 1 = identical.
//! - **Fireflies**: pixels whose luminance exceeds 10 × the *local median* of the reference's luminance, "local"
//!   being the 5 × 5 window centred on the pixel (clipped at the border). Where the reference is black (the median
//!   is 0, e.g. background), the median is floored at 1 % of the reference's mean luminance, so ordinary noise on a
//!   dark background is not called a firefly but a bright outlier still is. And where the reference's own pixel is
//!   brighter than that median (a lone strand over a dark background, whose 5 × 5 median is background), the
//!   threshold is 10 × the reference pixel instead: a firefly is far brighter than both its surroundings and its own
//!   converged value, so the reference against itself never has one (without this, a 32 × 24 fur ball counted
//!   its thin silhouette pixels as fireflies, more of them at higher spp).
//! - **Non-finite**: pixels with a NaN or infinite value in `R`, `G` or `B`.
//! - **Detail kept** (the strand-structure measure of `study denoise`): how much of the reference's fine structure an
//!   image keeps ([`detail`]). Each luminance map less its Gaussian blur (σ = [`DETAIL_SIGMA`] pixel, clipped and
//!   renormalised at the border) is its detail d; over a window, with the reference in two independent halves a and
//!   b, kept = ⟨d_x, (d_a + d_b)/2⟩ / ⟨d_a, d_b⟩, the image's detail projected on the reference's. Noise, the
//!   image's or either half's, is uncorrelated with the rest, so a noisy render keeps about 1 in expectation however
//!   noisy it is, while a filter that blurs strands together scores what it leaves of them (0:
//!   all of it smoothed away; one-pixel stripes blurred by σ = 1 px keep 0.02, tested). Its companion, the detail
//!   error, counts noise and smoothing together (0 for a converged image).

use crate::image::Image;

/// Window radius of SSIM (11 × 11 pixels).
const SSIM_RADIUS: i64 = 5;
/// Standard deviation of SSIM's Gaussian window, pixels (Wang et al. 2004).
const SSIM_SIGMA: f64 = 1.5;
/// C₁ = (K₁ L)² with K₁ = 0.01, L = 1.
pub const SSIM_C1: f64 = 1e-4;
/// C₂ = (K₂ L)² with K₂ = 0.03, L = 1.
pub const SSIM_C2: f64 = 9e-4;
/// A pixel is a firefly above this multiple of the reference's local median.
pub const FIREFLY_FACTOR: f64 = 10.0;
/// Radius of the firefly median window (5 × 5 pixels).
const FIREFLY_RADIUS: i64 = 2;
/// Floor of the local median, as a fraction of the reference's mean luminance.
const FIREFLY_FLOOR: f64 = 0.01;

/// Rec. 709 luminance of every pixel of `image` (`R, G, B` looked up by name), row-major.
pub fn luminance(image: &Image) -> Result<Vec<f64>, String> {
    let find = |name: &str| {
        image
            .channel_index(name)
            .ok_or_else(|| format!("the image has no channel {name:?}"))
    };
    let (r, g, b) = (find("R")?, find("G")?, find("B")?);
    let n = image.channels.len();
    Ok(image
        .data
        .chunks_exact(n)
        .map(|p| 0.2126 * f64::from(p[r]) + 0.7152 * f64::from(p[g]) + 0.0722 * f64::from(p[b]))
        .collect())
}

/// Pixels of `image` with a non-finite `R`, `G` or `B`.
pub fn non_finite(image: &Image) -> Result<usize, String> {
    Ok(luminance(image)?.iter().filter(|y| !y.is_finite()).count())
}

/// Mean SSIM of two `width × height` maps of values in [0, 1] (see the module docs for the window).
pub fn ssim_of(x: &[f64], y: &[f64], width: usize, height: usize) -> f64 {
    assert_eq!(x.len(), width * height);
    assert_eq!(y.len(), width * height);
    let weights: Vec<f64> = (-SSIM_RADIUS..=SSIM_RADIUS)
        .map(|d| (-((d * d) as f64) / (2.0 * SSIM_SIGMA * SSIM_SIGMA)).exp())
        .collect();
    let mut sum = 0.0;
    for py in 0..height as i64 {
        for px in 0..width as i64 {
            // Weighted moments over the window clipped to the image.
            let (mut w_sum, mut mx, mut my, mut xx, mut yy, mut xy) =
                (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
            for dy in -SSIM_RADIUS..=SSIM_RADIUS {
                let qy = py + dy;
                if qy < 0 || qy >= height as i64 {
                    continue;
                }
                for dx in -SSIM_RADIUS..=SSIM_RADIUS {
                    let qx = px + dx;
                    if qx < 0 || qx >= width as i64 {
                        continue;
                    }
                    let w =
                        weights[(dy + SSIM_RADIUS) as usize] * weights[(dx + SSIM_RADIUS) as usize];
                    let k = qy as usize * width + qx as usize;
                    let (a, b) = (x[k], y[k]);
                    w_sum += w;
                    mx += w * a;
                    my += w * b;
                    xx += w * a * a;
                    yy += w * b * b;
                    xy += w * a * b;
                }
            }
            let (mx, my) = (mx / w_sum, my / w_sum);
            let var_x = xx / w_sum - mx * mx;
            let var_y = yy / w_sum - my * my;
            let cov = xy / w_sum - mx * my;
            // Wang et al. 2004, eq. 13.
            sum += ((2.0 * mx * my + SSIM_C1) * (2.0 * cov + SSIM_C2))
                / ((mx * mx + my * my + SSIM_C1) * (var_x + var_y + SSIM_C2));
        }
    }
    sum / (width * height) as f64
}

/// The [0, 1) display values of luminances `y` at `scale` (see the module docs); non-finite values become 1.
fn tone_map(y: &[f64], scale: f64) -> Vec<f64> {
    y.iter()
        .map(|&v| {
            let v = (v * scale).max(0.0);
            if v.is_finite() {
                v / (1.0 + v)
            } else {
                1.0
            }
        })
        .collect()
}

/// The 99th percentile of the finite values of `values` (0 when there are none).
fn p99(values: &[f64]) -> f64 {
    let mut v: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    v.get((v.len() * 99 / 100).min(v.len().saturating_sub(1)))
        .copied()
        .unwrap_or(0.0)
}

/// Mean SSIM of `image` against `reference` (same size) after the tone mapping of the module docs.
pub fn ssim(image: &Image, reference: &Image) -> Result<f64, String> {
    same_size(image, reference)?;
    let (yi, yr) = (luminance(image)?, luminance(reference)?);
    let white = p99(&yr);
    let scale = if white > 0.0 { 1.0 / white } else { 1.0 };
    Ok(ssim_of(
        &tone_map(&yi, scale),
        &tone_map(&yr, scale),
        image.width,
        image.height,
    ))
}

fn same_size(image: &Image, reference: &Image) -> Result<(), String> {
    if (image.width, image.height) != (reference.width, reference.height) {
        return Err(format!(
            "image is {}x{}, reference {}x{}",
            image.width, image.height, reference.width, reference.height
        ));
    }
    Ok(())
}

/// The firefly threshold of every pixel of a reference with luminances `y` (`width × height`): 10 × the larger of
/// the local median (floored) and the pixel itself (see the module docs).
pub fn firefly_thresholds(y: &[f64], width: usize, height: usize) -> Vec<f64> {
    let finite: Vec<f64> = y.iter().copied().filter(|v| v.is_finite()).collect();
    let mean = finite.iter().sum::<f64>() / finite.len().max(1) as f64;
    let floor = FIREFLY_FLOOR * mean;
    let mut window = Vec::with_capacity(25);
    let mut out = Vec::with_capacity(y.len());
    for py in 0..height as i64 {
        for px in 0..width as i64 {
            window.clear();
            for qy in (py - FIREFLY_RADIUS).max(0)..=(py + FIREFLY_RADIUS).min(height as i64 - 1) {
                for qx in (px - FIREFLY_RADIUS).max(0)..=(px + FIREFLY_RADIUS).min(width as i64 - 1)
                {
                    let v = y[qy as usize * width + qx as usize];
                    if v.is_finite() {
                        window.push(v);
                    }
                }
            }
            window.sort_by(f64::total_cmp);
            let median = if window.is_empty() {
                0.0
            } else if window.len() % 2 == 1 {
                window[window.len() / 2]
            } else {
                0.5 * (window[window.len() / 2 - 1] + window[window.len() / 2])
            };
            let own = y[py as usize * width + px as usize];
            let own = if own.is_finite() { own } else { 0.0 };
            out.push(FIREFLY_FACTOR * median.max(floor).max(own));
        }
    }
    out
}

/// Pixels of `image` brighter than `thresholds` ([`firefly_thresholds`] of the reference); non-finite pixels are
/// counted by [`non_finite`], not here.
pub fn fireflies(image: &Image, thresholds: &[f64]) -> Result<usize, String> {
    let y = luminance(image)?;
    if y.len() != thresholds.len() {
        return Err(format!(
            "image has {} pixels, the thresholds {}",
            y.len(),
            thresholds.len()
        ));
    }
    Ok(y.iter()
        .zip(thresholds)
        .filter(|(v, t)| v.is_finite() && *v > *t)
        .count())
}

/// The σ of the blur whose residual is an image's detail ([`detail`]): a strand a pixel or two wide is detail,
/// the shading across a lock is not.
pub const DETAIL_SIGMA: f64 = 1.0;

/// `values` (`width × height`, row-major) blurred by a Gaussian of σ = [`DETAIL_SIGMA`] (radius 3σ), clipped at
/// the border and renormalised.
fn blur(values: &[f64], width: usize, height: usize) -> Vec<f64> {
    let radius = (3.0 * DETAIL_SIGMA).ceil() as i64;
    let kernel: Vec<f64> = (-radius..=radius)
        .map(|k| (-(k * k) as f64 / (2.0 * DETAIL_SIGMA * DETAIL_SIGMA)).exp())
        .collect();
    let pass = |src: &[f64], horizontal: bool| -> Vec<f64> {
        let mut out = vec![0.0; src.len()];
        for y in 0..height as i64 {
            for x in 0..width as i64 {
                let (mut sum, mut weight) = (0.0, 0.0);
                for (k, w) in (-radius..=radius).zip(&kernel) {
                    let (sx, sy) = if horizontal { (x + k, y) } else { (x, y + k) };
                    if sx >= 0 && sy >= 0 && sx < width as i64 && sy < height as i64 {
                        sum += w * src[sy as usize * width + sx as usize];
                        weight += w;
                    }
                }
                out[y as usize * width + x as usize] = sum / weight;
            }
        }
        out
    };
    pass(&pass(values, true), false)
}

/// What an image keeps of the reference's detail over a window ([`detail`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detail {
    /// The fraction of the reference's detail the image keeps: ⟨d_x, (d_a + d_b)/2⟩ / ⟨d_a, d_b⟩. Noise leaves it
    /// at 1 in expectation; smoothing lowers it.
    pub kept: f64,
    /// The image's error in the detail band relative to the reference's detail energy: (‖d_x − (d_a + d_b)/2‖² −
    /// ¼‖d_a − d_b‖²) / ⟨d_a, d_b⟩, the reference halves' own noise taken out. Noise and smoothing both raise it; a
    /// converged image scores 0.
    pub error: f64,
}

/// What `image` keeps of the reference's detail over the window `(x0, y0, size)` (see the module docs), the
/// reference given as two independent halves `reference` (`[a, b]`, e.g. two seeds): the detail energy is
/// ⟨d_a, d_b⟩, so the reference's own noise, uncorrelated between the halves, adds nothing to it (with one
/// reference, a 256-spp default scene put a 16-spp render at 0.59). NaN where the halves share no detail there.
pub fn detail(
    image: &Image,
    reference: [&Image; 2],
    window: (usize, usize, usize),
) -> Result<Detail, String> {
    same_size(image, reference[0])?;
    same_size(image, reference[1])?;
    let (x0, y0, size) = window;
    let (w, h) = (
        size.min(image.width - x0.min(image.width)),
        size.min(image.height - y0.min(image.height)),
    );
    let band = |im: &Image| -> Result<Vec<f64>, String> {
        let y = luminance(im)?;
        let crop: Vec<f64> = (y0..y0 + h)
            .flat_map(|row| {
                y[row * im.width + x0..row * im.width + x0 + w]
                    .iter()
                    .copied()
            })
            .collect();
        let blurred = blur(&crop, w, h);
        Ok(crop.iter().zip(&blurred).map(|(v, b)| v - b).collect())
    };
    let (dx, da, db) = (band(image)?, band(reference[0])?, band(reference[1])?);
    let (mut cross, mut energy, mut error, mut halves) = (0.0, 0.0, 0.0, 0.0);
    for k in 0..dx.len() {
        let mean = 0.5 * (da[k] + db[k]);
        cross += dx[k] * mean;
        energy += da[k] * db[k];
        error += (dx[k] - mean).powi(2);
        halves += (da[k] - db[k]).powi(2);
    }
    Ok(if energy > 0.0 {
        Detail {
            kept: cross / energy,
            error: (error - 0.25 * halves) / energy,
        }
    } else {
        Detail {
            kept: f64::NAN,
            error: f64::NAN,
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Detail kept: 1 for the reference itself, about 1 for the reference plus noise of twice its detail's
    /// amplitude, and a fraction for a blurred copy (one-pixel stripes blurred by σ = 1 px keep 0.02: the blur
    /// removes nearly all of what a σ = 1 residual holds).
    #[test]
    fn detail_ignores_noise_in_what_is_kept_and_counts_blur() {
        let (w, h) = (64usize, 64usize);
        let stripes: Vec<f32> = (0..w * h)
            .map(|k| if (k % w) % 2 == 0 { 0.8 } else { 0.2 })
            .collect();
        let reference = rgb(w, h, &stripes);
        let window = (0, 0, 64);
        let same = [&reference, &reference];
        assert!((detail(&reference, same, window).unwrap().kept - 1.0).abs() < 1e-12);
        let mut rng = 0x2545_f491_4f6c_dd1du64;
        let mut noisy = |amplitude: f32| -> Image {
            let values: Vec<f32> = stripes
                .iter()
                .map(|v| {
                    rng ^= rng << 13;
                    rng ^= rng >> 7;
                    rng ^= rng << 17;
                    v + amplitude * ((rng >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 2.0
                })
                .collect();
            rgb(w, h, &values)
        };
        // Noisy reference halves (as noisy as the detail itself) and a noisier image: still about 1.
        let (a, b, x) = (noisy(0.3), noisy(0.3), noisy(0.6));
        let d = detail(&x, [&a, &b], window).unwrap();
        assert!((d.kept - 1.0).abs() < 0.06, "noisy keeps {}", d.kept);
        // Its error in the band is its own noise: (0.6² + 0.3²/2) / 3 per value over the detail's energy, about
        // 0.24 / 0.09 of it; the reference's halves' noise is taken out.
        let quiet = detail(&noisy(0.15), [&a, &b], window).unwrap();
        assert!(
            d.error > 2.0 * quiet.error && quiet.error > 0.0,
            "{d:?} {quiet:?}"
        );
        let y: Vec<f64> = stripes.iter().map(|&v| f64::from(v)).collect();
        let blurred: Vec<f32> = blur(&y, w, h).iter().map(|&v| v as f32).collect();
        let d = detail(&rgb(w, h, &blurred), [&a, &b], window).unwrap();
        assert!((0.0..0.05).contains(&d.kept), "blurred keeps {}", d.kept);
        assert!(d.error > 0.9, "blurred: {d:?}");
    }

    fn rgb(width: usize, height: usize, values: &[f32]) -> Image {
        let mut im = Image::new(width, height, vec!["R".into(), "G".into(), "B".into()]);
        im.data = values.iter().flat_map(|&v| [v, v, v]).collect();
        im
    }

    /// SSIM of constant maps has a closed form (σ = 0): (2 μx μy + C₁) / (μx² + μy² + C₁).
    #[test]
    fn ssim_of_constant_maps_is_the_closed_form() {
        let (a, b) = (0.3, 0.6);
        let x = vec![a; 7 * 5];
        let y = vec![b; 7 * 5];
        let expected = (2.0 * a * b + SSIM_C1) / (a * a + b * b + SSIM_C1);
        assert!((ssim_of(&x, &y, 7, 5) - expected).abs() < 1e-12);
        assert_eq!(ssim_of(&x, &x, 7, 5), 1.0);
    }

    /// A 16 × 12 map against a perturbed copy, against a NumPy transcription of the same definition (11 × 11
    /// Gaussian, σ 1.5, clipped and renormalised at the border):
    /// `x[i,j] = ((3i + 5j) % 7) / 7`, `y = 0.8 x + 0.1 + 0.05 ((i j) % 3)` (`docs/measured/study/ssim_check.py`).
    #[test]
    fn ssim_matches_an_independent_transcription() {
        let (w, h) = (16usize, 12usize);
        let mut x = vec![0.0; w * h];
        let mut y = vec![0.0; w * h];
        for i in 0..h {
            for j in 0..w {
                let v = ((3 * i + 5 * j) % 7) as f64 / 7.0;
                x[i * w + j] = v;
                y[i * w + j] = 0.8 * v + 0.1 + 0.05 * ((i * j) % 3) as f64;
            }
        }
        let s = ssim_of(&x, &y, w, h);
        assert!((s - NUMPY_SSIM).abs() < 1e-11, "ssim {s}");
    }

    /// Printed by `python3 docs/measured/study/ssim_check.py`.
    const NUMPY_SSIM: f64 = 0.958_764_231_623;

    #[test]
    fn images_against_themselves_have_ssim_one_and_no_outliers() {
        let r = rgb(6, 6, &[0.5; 36]);
        assert_eq!(ssim(&r, &r).unwrap(), 1.0);
        let t = firefly_thresholds(&luminance(&r).unwrap(), 6, 6);
        assert_eq!(fireflies(&r, &t).unwrap(), 0);
        assert_eq!(non_finite(&r).unwrap(), 0);
    }

    #[test]
    fn fireflies_are_ten_times_the_local_median() {
        // A 0.1 reference; one pixel at 1.5 (15×) and one at 0.9 (9×), one NaN.
        let r = rgb(8, 8, &[0.1; 64]);
        let mut v = vec![0.1f32; 64];
        v[9] = 1.5;
        v[40] = 0.9;
        v[63] = f32::NAN;
        let x = rgb(8, 8, &v);
        let t = firefly_thresholds(&luminance(&r).unwrap(), 8, 8);
        assert!((t[0] - 1.0).abs() < 1e-6);
        assert_eq!(fireflies(&x, &t).unwrap(), 1);
        assert_eq!(non_finite(&x).unwrap(), 1);
        // Black reference: the floor (1 % of the mean, here of a reference with one bright pixel).
        let mut black = vec![0.0f32; 64];
        black[0] = 6.4;
        let t = firefly_thresholds(&luminance(&rgb(8, 8, &black)).unwrap(), 8, 8);
        assert!((t[63] - 10.0 * 0.01 * 0.1).abs() < 1e-9, "{}", t[63]);
        // The bright pixel itself: 10 × its own value, not 10 × its black surroundings' median.
        assert!((t[0] - 64.0).abs() < 1e-4, "{}", t[0]);
    }
}
