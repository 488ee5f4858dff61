//! Image error against a reference, as the shadow study reports it.
//!
//! For a test image x and reference r (beauty `R, G, B`; premultiplied, as rendered), over a set of pixels P and the
//! three channels:
//!
//! - **RMSE** = √( mean over P × {R,G,B} of (x − r)² ) — in the image's radiance units;
//! - **relMSE** = mean over P × {R,G,B} of (x − r)² / (r² + 0.01) — relative, so dark pixels count as much as bright
//!   ones (the ε = 0.01 keeps black pixels finite; Rousselle et al. 2011 use the same form).
//!
//! Both are computed over the whole image and over the **shadowed pixels**: those where the reference's `shadow.Y`
//! AOV (the fraction of light-sample contributions its shadow rays let through) is below ½ and its alpha is above 0
//! (hair or a shape was hit). Images are matched by channel *name*, since an EXR read back may list its channels in
//! another order.

use crate::image::Image;

/// ε of relMSE's denominator.
pub const REL_EPSILON: f64 = 0.01;
/// A pixel is shadowed when the reference's visibility is below this.
pub const SHADOWED_BELOW: f32 = 0.5;

/// The errors of one image.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Errors {
    /// RMSE over every pixel.
    pub rmse: f64,
    /// relMSE over every pixel.
    pub relmse: f64,
    /// RMSE over the shadowed pixels (NaN if there are none).
    pub rmse_shadowed: f64,
    /// relMSE over the shadowed pixels (NaN if there are none).
    pub relmse_shadowed: f64,
}

/// The index of channel `name` of `image`, or a message naming what is missing.
fn channel(image: &Image, name: &str) -> Result<usize, String> {
    image.channel_index(name).ok_or_else(|| {
        format!(
            "the image has no channel {name:?} (it has {})",
            image.channels.join(", ")
        )
    })
}

/// Which pixels of `reference` are shadowed (row-major, one flag per pixel; see the module docs).
pub fn shadowed_mask(reference: &Image) -> Result<Vec<bool>, String> {
    let (s, a) = (channel(reference, "shadow.Y")?, channel(reference, "A")?);
    let n = reference.channels.len();
    Ok(reference
        .data
        .chunks_exact(n)
        .map(|p| p[s] < SHADOWED_BELOW && p[a] > 0.0)
        .collect())
}

/// The errors of `image` against `reference` (same size), the shadowed pixels given by `mask`.
pub fn errors(image: &Image, reference: &Image, mask: &[bool]) -> Result<Errors, String> {
    if (image.width, image.height) != (reference.width, reference.height) {
        return Err(format!(
            "image is {}x{}, reference {}x{}",
            image.width, image.height, reference.width, reference.height
        ));
    }
    let rgb = |im: &Image| -> Result<[usize; 3], String> {
        Ok([channel(im, "R")?, channel(im, "G")?, channel(im, "B")?])
    };
    let (ci, cr) = (rgb(image)?, rgb(reference)?);
    let (ni, nr) = (image.channels.len(), reference.channels.len());
    // [sum of squares, sum of relative squares, count] for all pixels and for the shadowed ones.
    let mut all = [0.0f64; 3];
    let mut shadowed = [0.0f64; 3];
    for (k, (p, q)) in image
        .data
        .chunks_exact(ni)
        .zip(reference.data.chunks_exact(nr))
        .enumerate()
    {
        for c in 0..3 {
            let (x, r) = (f64::from(p[ci[c]]), f64::from(q[cr[c]]));
            let d2 = (x - r) * (x - r);
            let rel = d2 / (r * r + REL_EPSILON);
            let add = |acc: &mut [f64; 3]| {
                acc[0] += d2;
                acc[1] += rel;
                acc[2] += 1.0;
            };
            add(&mut all);
            if mask[k] {
                add(&mut shadowed);
            }
        }
    }
    let finish = |acc: [f64; 3]| {
        if acc[2] > 0.0 {
            ((acc[0] / acc[2]).sqrt(), acc[1] / acc[2])
        } else {
            (f64::NAN, f64::NAN)
        }
    };
    let ((rmse, relmse), (rmse_shadowed, relmse_shadowed)) = (finish(all), finish(shadowed));
    Ok(Errors {
        rmse,
        relmse,
        rmse_shadowed,
        relmse_shadowed,
    })
}

/// The top-left corner of the `size × size` window (clamped to the image) holding the most flagged pixels of
/// `mask` (`width × height`, row-major); the first such window in row-major order on ties. Returns (x0, y0, size).
pub fn densest_window(
    mask: &[bool],
    width: usize,
    height: usize,
    size: usize,
) -> (usize, usize, usize) {
    let size = size.min(width).min(height).max(1);
    // Summed-area table with a zero row and column in front.
    let w1 = width + 1;
    let mut sat = vec![0u32; w1 * (height + 1)];
    for y in 0..height {
        for x in 0..width {
            sat[(y + 1) * w1 + x + 1] =
                u32::from(mask[y * width + x]) + sat[y * w1 + x + 1] + sat[(y + 1) * w1 + x]
                    - sat[y * w1 + x];
        }
    }
    let mut best = (0, 0, 0u32);
    for y in 0..=height.saturating_sub(size) {
        for x in 0..=width.saturating_sub(size) {
            let (x1, y1) = (x + size, y + size);
            let count = sat[y1 * w1 + x1] + sat[y * w1 + x] - sat[y * w1 + x1] - sat[y1 * w1 + x];
            if count > best.2 {
                best = (x, y, count);
            }
        }
    }
    (best.0, best.1, size)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(values: &[[f32; 5]]) -> Image {
        let channels = ["R", "G", "B", "A", "shadow.Y"]
            .iter()
            .map(|c| c.to_string())
            .collect();
        let mut im = Image::new(values.len(), 1, channels);
        im.data = values.iter().flatten().copied().collect();
        im
    }

    #[test]
    fn errors_of_a_reference_against_itself_are_zero_and_known_otherwise() {
        let r = image(&[[1.0, 1.0, 1.0, 1.0, 0.2], [0.0, 0.0, 0.0, 0.0, 1.0]]);
        let mask = shadowed_mask(&r).unwrap();
        assert_eq!(mask, [true, false]);
        let e = errors(&r, &r, &mask).unwrap();
        assert_eq!(e, Errors::default());
        // Off by 0.5 in every channel of the shadowed pixel: MSE over all = 0.25 · 3 / 6, relMSE = 0.25 / 1.01.
        let x = image(&[[1.5, 1.5, 1.5, 1.0, 0.2], [0.0, 0.0, 0.0, 0.0, 1.0]]);
        let e = errors(&x, &r, &mask).unwrap();
        assert!((e.rmse - 0.125f64.sqrt()).abs() < 1e-12);
        assert!((e.rmse_shadowed - 0.5).abs() < 1e-12);
        assert!((e.relmse_shadowed - 0.25 / 1.01).abs() < 1e-12);
        assert!((e.relmse - 0.5 * 0.25 / 1.01).abs() < 1e-12);
    }

    #[test]
    fn densest_window_finds_the_block() {
        let (w, h) = (10, 8);
        let mut mask = vec![false; w * h];
        for y in 4..7 {
            for x in 5..8 {
                mask[y * w + x] = true;
            }
        }
        assert_eq!(densest_window(&mask, w, h, 3), (5, 4, 3));
        // Larger than the image: clamped, one window.
        assert_eq!(densest_window(&mask, w, h, 128), (0, 0, 8));
    }
}
