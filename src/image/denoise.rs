//! The denoised frame: Open Image Denoise's `RT` filter ([`crate::sys::oidn`]) over the beauty, guided by the
//! frame's albedo AOV, written as `denoised.R/G/B` beside the beauty it came from (which stays as rendered).
//!
//! **A whole-frame step.** The filter reads a neighbourhood of every pixel, so a tile or a crop denoised alone
//! would differ at its edges from the frame denoised whole: `render --denoise` runs on whole frames only, and a
//! frame rendered in tiles is denoised by `cuticle merge --denoise` after its tiles are assembled.
//!
//! **The guide.** OIDN's albedo guide is the surface's reflectance with the lighting taken out, in [0, 1]: it lets
//! the filter keep edges in the texture (here, where one strand ends and the next, or the background, begins)
//! that the lighting's noise would hide. A fibre has no single reflectance; the `albedo` AOV holds the first
//! shading point's directional albedo (the fraction of light from the camera's direction the fibre scatters in all,
//! [`crate::render::film::CHANNELS`]), averaged over the pixel's samples: a strand against the background or a
//! darker strand is an edge in it, as OIDN expects. It carries some noise of its own (one direction per sample), so
//! the filter is told its guides are not clean (`cleanAux` off, OIDN's default). Where the background shows, the
//! albedo is 0 and the filter keeps the background's own values.

use super::{Image, ImageError};
use crate::sys::oidn::{self, Guides, OidnError};

/// The channels [`add_denoised`] writes.
pub const CHANNELS: [&str; 3] = ["denoised.R", "denoised.G", "denoised.B"];

/// Whether the denoiser can run here; the error says where it looked and how to install it.
pub fn available() -> Result<(), OidnError> {
    oidn::available()
}

/// The RGB triples of channels `names` of every pixel of `image`, or `None` when one is missing.
fn triples(image: &Image, names: [&str; 3]) -> Option<Vec<f32>> {
    let index = names.map(|n| image.channel_index(n));
    let [Some(r), Some(g), Some(b)] = index else {
        return None;
    };
    let n = image.channels.len();
    Some(
        image
            .data
            .chunks_exact(n)
            .flat_map(|p| [p[r], p[g], p[b]])
            .collect(),
    )
}

/// Denoises `image`'s beauty (R, G, B) with its albedo AOV as the guide (when the image has it) on `threads`
/// threads, and adds the result as [`CHANNELS`] (replacing any earlier ones). The beauty is left as rendered.
pub fn add_denoised(image: &mut Image, threads: usize) -> Result<(), OidnError> {
    let color = triples(image, ["R", "G", "B"])
        .ok_or_else(|| OidnError("the image has no R, G, B channels to denoise".to_owned()))?;
    let albedo = triples(image, ["albedo.R", "albedo.G", "albedo.B"])
        .map(|a| a.into_iter().map(|v| v.clamp(0.0, 1.0)).collect::<Vec<_>>());
    let denoised = oidn::denoise(
        &Guides {
            color: &color,
            albedo: albedo.as_deref(),
            normal: None,
        },
        image.width,
        image.height,
        threads,
    )?;
    set_channels(image, &CHANNELS, &denoised);
    Ok(())
}

/// Writes `values` (triples, pixel by pixel) into channels `names` of `image`, appending the channels it lacks.
fn set_channels(image: &mut Image, names: &[&str; 3], values: &[f32]) {
    let missing: Vec<String> = names
        .iter()
        .filter(|n| image.channel_index(n).is_none())
        .map(|n| n.to_string())
        .collect();
    if !missing.is_empty() {
        let old = image.channels.len();
        let mut channels = image.channels.clone();
        channels.extend(missing);
        let new = channels.len();
        let mut data = Vec::with_capacity(image.width * image.height * new);
        for pixel in image.data.chunks_exact(old) {
            data.extend_from_slice(pixel);
            data.extend(std::iter::repeat_n(0.0, new - old));
        }
        image.channels = channels;
        image.data = data;
    }
    let index = names.map(|n| image.channel_index(n).expect("added above"));
    let n = image.channels.len();
    for (pixel, rgb) in image.data.chunks_exact_mut(n).zip(values.chunks_exact(3)) {
        for (i, v) in index.iter().zip(rgb) {
            pixel[*i] = *v;
        }
    }
}

/// An [`ImageError`] naming `path` for a denoiser failure.
pub fn error_at(path: &std::path::Path, e: OidnError) -> ImageError {
    ImageError::invalid(path, format!("cannot denoise it: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn denoised_channels_are_appended_once_and_the_beauty_is_kept() {
        let mut image = Image::new(2, 1, vec!["R".into(), "G".into(), "B".into()]);
        image.data = vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        set_channels(&mut image, &CHANNELS, &[0.1, 0.2, 0.3, 0.4, 0.5, 0.6]);
        assert_eq!(image.channels.len(), 6);
        assert_eq!(image.pixel(1, 0), [4.0, 5.0, 6.0, 0.4, 0.5, 0.6]);
        set_channels(&mut image, &CHANNELS, &[0.0; 6]);
        assert_eq!(image.channels.len(), 6);
        assert_eq!(image.pixel(0, 0), [1.0, 2.0, 3.0, 0.0, 0.0, 0.0]);
    }
}
