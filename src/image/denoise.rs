//! The denoised frame: Open Image Denoise's `RT` filter ([`crate::sys::oidn`]) over the beauty, written as
//! `denoised.R/G/B` beside the beauty it came from (which stays as rendered).
//!
//! **A whole-frame step.** The filter reads a neighbourhood of every pixel, so a tile or a crop denoised alone
//! would differ at its edges from the frame denoised whole: `render --denoise` runs on whole frames only, and a
//! frame rendered in tiles is denoised by `cuticle merge --denoise` after its tiles are assembled.
//!
//! **The guide** ([`Guide`]). OIDN's albedo guide is the surface's reflectance with the lighting taken out, in
//! [0, 1]: it lets the filter keep edges in the texture that the lighting's noise would hide. A fibre has no single
//! reflectance; the `albedo` AOV holds the first shading point's directional albedo (the fraction of light from the
//! camera's direction the fibre scatters in all, [`crate::render::film::CHANNELS`]), averaged over the pixel's
//! samples, so a strand against the background or a darker strand is an edge in it. It carries noise of its own
//! (one direction per sample): used as it is, the filter is told its guides are not clean (`cleanAux` off);
//! prefiltered (denoised alone first, as OIDN's documentation advises for noisy guides), it is called clean. The
//! normal guide OIDN also reads is left out: a fibre's normal turns all the way round its axis within a strand's
//! width, so a pixel's mean normal says little, and the tangent AOV in its place measured no better than the
//! albedo (docs/measured/denoise.md). Measured with `study denoise` over the eight straight-hair scenes of the
//! thesis and the peer fur ball at 160x120, 1-128 spp (72 points): neither guide is better in general. Against the
//! colour alone the albedo guides' RMSE is 1.05-1.06 times as large at the median (smaller on 20-22 of the 72
//! points), their detail kept 0.03 and 0.004 lower; under the studio map at 32-128 spp they halve the error
//! (0.40-0.57), under the sunset map at 64-128 spp they raise it by 36-52 %. So the colour alone is the default and
//! the guides are options.

use super::{Image, ImageError};
use crate::sys::oidn::{self, Guides, OidnError};

/// The channels [`add_denoised`] writes.
pub const CHANNELS: [&str; 3] = ["denoised.R", "denoised.G", "denoised.B"];

/// What guides the filter besides the colour (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Guide {
    /// The colour alone (the default: measured as good as either albedo guide on hair).
    #[default]
    Color,
    /// The `albedo` AOV as it is, called noisy.
    Albedo,
    /// The `albedo` AOV denoised alone first, then called clean.
    AlbedoPrefiltered,
}

impl Guide {
    /// Every guide, in the order the study lists them.
    pub const ALL: [Guide; 3] = [Guide::Color, Guide::Albedo, Guide::AlbedoPrefiltered];

    /// The name the command line and the study use.
    pub fn name(self) -> &'static str {
        match self {
            Guide::Color => "color",
            Guide::Albedo => "albedo",
            Guide::AlbedoPrefiltered => "albedo-prefiltered",
        }
    }
}

/// Whether the denoiser can run here; the error says where it looked and how to install it.
pub fn available() -> Result<(), OidnError> {
    oidn::available()
}

/// Denoises `image`'s beauty (R, G, B) with `guide` (the albedo guides need the `albedo` AOV) on `threads` threads,
/// and adds the result as [`CHANNELS`] (replacing any earlier ones). The beauty is left as rendered.
pub fn add_denoised(image: &mut Image, guide: Guide, threads: usize) -> Result<(), OidnError> {
    let denoised = denoised(image, guide, threads)?;
    set_channels(image, &CHANNELS, &denoised);
    Ok(())
}

/// `image`'s beauty denoised with `guide` on `threads` threads, as RGB triples pixel by pixel ([`add_denoised`]
/// without writing them).
pub fn denoised(image: &Image, guide: Guide, threads: usize) -> Result<Vec<f32>, OidnError> {
    let color = image
        .triples(["R", "G", "B"])
        .ok_or_else(|| OidnError("the image has no R, G, B channels to denoise".to_owned()))?;
    let albedo = match guide {
        Guide::Color => None,
        Guide::Albedo | Guide::AlbedoPrefiltered => Some(
            image
                .triples(["albedo.R", "albedo.G", "albedo.B"])
                .ok_or_else(|| {
                    OidnError(format!(
                        "the {} guide needs the albedo AOV (--aovs leaves it out)",
                        guide.name()
                    ))
                })?
                .into_iter()
                .map(|v| v.clamp(0.0, 1.0))
                .collect::<Vec<_>>(),
        ),
    };
    let albedo = match (guide, albedo) {
        (Guide::AlbedoPrefiltered, Some(a)) => Some(oidn::denoise(
            &Guides {
                color: &a,
                albedo: None,
                normal: None,
                hdr: false,
                clean_aux: false,
            },
            image.width,
            image.height,
            threads,
        )?),
        (_, a) => a,
    };
    oidn::denoise(
        &Guides {
            color: &color,
            albedo: albedo.as_deref(),
            normal: None,
            hdr: true,
            clean_aux: guide == Guide::AlbedoPrefiltered,
        },
        image.width,
        image.height,
        threads,
    )
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
