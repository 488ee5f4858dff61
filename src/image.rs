//! Images in memory and on disk: the render film's output format, written and read through
//! OpenImageIO ([`crate::sys::oiio`]).
//!
//! - [`Image`]: `width × height` pixels of named `f32` channels, interleaved, top row first.
//! - [`write()`]: `.exr` stores every channel as 32-bit float (see below); `.png` writes an 8-bit
//!   sRGB preview of `R,G,B(,A)` ([`write_png_preview`]).
//! - [`read`]: any format OpenImageIO reads (EXR including DWAA/DWAB compression, Radiance `.hdr`,
//!   PNG, TIFF, ...), as `f32`.
//!
//! **Why float32 for every EXR channel**: half floats would halve the file, but they would round
//! depth, tangents and especially ids (integers above 2048 are not exact in half). One pixel type
//! keeps the writer simple and every value exact, so a file read back equals the film bit for bit.
//!
//! **Channel names** follow the EXR `layer.channel` convention: `R,G,B,A` for the beauty, then
//! AOVs such as `depth.Z`, `tangent.X`, `tangent.Y`, `tangent.Z`, `strand.id`. OpenEXR stores
//! channels sorted by name and OpenImageIO reads them back beauty first, so a file read back may
//! list the channels in a different order: look them up with [`Image::channel_index`].
//!
//! **Alpha**: as in EXR, colour is premultiplied by `A` (associated alpha).
//!
//! **Atomic writes** ([`crate::util::atomic_file`]): a file is written to a temporary file in the same
//! directory (named `.<name>.tmp-<random>.<ext>`, keeping the extension from which OpenImageIO
//! picks the format), flushed to disk, then renamed over the target. A reader never sees a half-written frame, and on
//! any failure the temporary file is removed and the target is left as it was.

use std::ffi::OsStr;
use std::fs;
use std::io;
use std::path::{Path, PathBuf};

use crate::sys::oiio::{self, FileFormat, OiioError, Pixels, WriteOptions};
use crate::util::atomic_file;

/// An image could not be written or read. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// The file system refused: a missing directory, a path through a regular file, no
    /// permission, a full disk, or a missing file to read.
    #[error("{path}: {context}: {source}")]
    Io {
        /// The image file asked for.
        path: PathBuf,
        /// What was being done, lower case.
        context: String,
        /// The I/O error.
        source: io::Error,
    },
    /// OpenImageIO could not write or read the file.
    #[error("{path}: {context}: {source}")]
    Oiio {
        /// The image file asked for.
        path: PathBuf,
        /// What was being done, lower case.
        context: String,
        /// OpenImageIO's message.
        source: OiioError,
    },
    /// The request does not fit the file: an unsupported extension, missing channels, or a file
    /// whose content cannot be an [`Image`].
    #[error("{path}: {message}")]
    Invalid {
        /// The image file asked for.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

impl ImageError {
    fn io(path: &Path, context: impl Into<String>, source: io::Error) -> Self {
        ImageError::Io {
            path: path.to_path_buf(),
            context: context.into(),
            source,
        }
    }

    fn invalid(path: &Path, message: impl Into<String>) -> Self {
        ImageError::Invalid {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }
}

/// `width × height` pixels of named `f32` channels, interleaved and top row first: channel `c` of
/// pixel `(x, y)` is `data[(y * width + x) * channels.len() + c]`.
///
/// The fields are public so a film can fill `data` directly. Keep them consistent: channel names
/// non-empty, unique and free of NUL bytes, and `data.len() == width * height * channels.len()`.
/// [`Image::new`] guarantees it; [`write()`] checks it and refuses an inconsistent image.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Channel names, in storage order (e.g. `R, G, B, A, depth.Z, strand.id`).
    pub channels: Vec<String>,
    /// `width * height * channels.len()` values, interleaved, top row first.
    pub data: Vec<f32>,
}

/// Why a channel list cannot name the channels of an [`Image`], or `Ok`.
fn check_channels(channels: &[String]) -> Result<(), String> {
    if channels.is_empty() {
        return Err("an image needs at least one channel".to_owned());
    }
    for (i, name) in channels.iter().enumerate() {
        if name.is_empty() || name.contains('\0') {
            return Err(format!("channel {i} has an invalid name {name:?}"));
        }
        if channels[..i].contains(name) {
            return Err(format!("channel {name:?} appears twice"));
        }
    }
    Ok(())
}

impl Image {
    /// A `width × height` image of the given channels, all zero.
    ///
    /// # Panics
    /// If the channel list is empty, a name is empty or repeated, or the size overflows `usize`.
    pub fn new(width: usize, height: usize, channels: Vec<String>) -> Self {
        if let Err(message) = check_channels(&channels) {
            panic!("invalid image channels {channels:?}: {message}");
        }
        let len = width
            .checked_mul(height)
            .and_then(|n| n.checked_mul(channels.len()))
            .unwrap_or_else(|| panic!("image size {width}x{height} overflows"));
        Image {
            width,
            height,
            channels,
            data: vec![0.0; len],
        }
    }

    /// Why the fields are inconsistent (see [`Image`]), or `Ok`.
    fn check(&self) -> Result<(), String> {
        check_channels(&self.channels)?;
        let expected = self
            .width
            .checked_mul(self.height)
            .and_then(|n| n.checked_mul(self.channels.len()));
        if expected != Some(self.data.len()) {
            return Err(format!(
                "image data holds {} values, but {}x{} pixels of {} channels need {}",
                self.data.len(),
                self.width,
                self.height,
                self.channels.len(),
                expected.map_or_else(|| "more than fit in memory".to_owned(), |n| n.to_string())
            ));
        }
        Ok(())
    }

    /// The index of the channel called `name` (exact match), if there is one.
    pub fn channel_index(&self, name: &str) -> Option<usize> {
        self.channels.iter().position(|c| c == name)
    }

    fn pixel_start(&self, x: usize, y: usize) -> usize {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) is outside the {}x{} image",
            self.width,
            self.height
        );
        (y * self.width + x) * self.channels.len()
    }

    /// The channel values of pixel `(x, y)`, `(0, 0)` being top left.
    ///
    /// # Panics
    /// If the pixel is outside the image.
    pub fn pixel(&self, x: usize, y: usize) -> &[f32] {
        let start = self.pixel_start(x, y);
        &self.data[start..start + self.channels.len()]
    }

    /// The channel values of pixel `(x, y)`, mutable.
    ///
    /// # Panics
    /// If the pixel is outside the image.
    pub fn pixel_mut(&mut self, x: usize, y: usize) -> &mut [f32] {
        let start = self.pixel_start(x, y);
        let n = self.channels.len();
        &mut self.data[start..start + n]
    }

    /// Channel `channel` (an index, see [`Image::channel_index`]) of pixel `(x, y)`.
    ///
    /// # Panics
    /// If the pixel or the channel is out of range.
    pub fn get(&self, x: usize, y: usize, channel: usize) -> f32 {
        self.pixel(x, y)[channel]
    }

    /// Sets channel `channel` of pixel `(x, y)` to `value`.
    ///
    /// # Panics
    /// If the pixel or the channel is out of range.
    pub fn set(&mut self, x: usize, y: usize, channel: usize, value: f32) {
        self.pixel_mut(x, y)[channel] = value;
    }
}

/// Refuses an image whose fields are inconsistent, naming the file it was to be written to.
fn check_before_writing(path: &Path, image: &Image) -> Result<(), ImageError> {
    image
        .check()
        .map_err(|message| ImageError::invalid(path, message))
}

/// Writes `image` to `path`, atomically (see the [module docs](self)), in the format its extension
/// names (case-insensitive):
///
/// - `.exr`: every channel, 32-bit float, names as given;
/// - `.png`: an 8-bit sRGB preview of the colour channels ([`write_png_preview`]).
///
/// Any other extension is an [`ImageError::Invalid`].
pub fn write(path: impl AsRef<Path>, image: &Image) -> Result<(), ImageError> {
    let path = path.as_ref();
    let extension = path
        .extension()
        .and_then(OsStr::to_str)
        .map(str::to_ascii_lowercase);
    match extension.as_deref() {
        Some("exr") => write_exr(path, image),
        Some("png") => write_png_preview(path, image),
        _ => Err(ImageError::invalid(
            path,
            "unsupported image extension: use .exr (all channels, float) \
             or .png (8-bit srgb preview)",
        )),
    }
}

/// Writes every channel of `image` as 32-bit float (the format follows the extension: `.exr`).
fn write_exr(path: &Path, image: &Image) -> Result<(), ImageError> {
    check_before_writing(path, image)?;
    let options = WriteOptions {
        format: FileFormat::Float,
        unassociated_alpha: false,
    };
    write_atomically(path, |temp| {
        let pixels = Pixels::F32(&image.data);
        oiio::write_image(
            temp,
            image.width,
            image.height,
            &image.channels,
            pixels,
            options,
        )
    })
}

/// The sRGB opto-electronic transfer function (IEC 61966-2-1) of a linear value, clamped to
/// [0, 1] and rounded to 8 bits. NaN encodes as 0.
pub fn linear_to_srgb8(linear: f32) -> u8 {
    if linear.is_nan() || linear <= 0.0 {
        return 0;
    }
    let v = linear.min(1.0);
    let encoded = if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    };
    // In [0, 255.5) after the clamp; `as` truncates, so adding 0.5 rounds to nearest.
    (encoded * 255.0 + 0.5) as u8
}

/// Writes an 8-bit RGB preview of `image`'s `R`, `G`, `B` channels to `path` (atomically; the
/// format follows the extension, normally `.png`). Other channels, alpha included, are left out:
/// the preview shows the frame as rendered (with the environment behind the hair where the scene
/// makes it visible); the EXR carries alpha for compositing.
///
/// Encoding is the sRGB transfer function with no exposure or tone mapping, clamping to [0, 1] and
/// rounding ([`linear_to_srgb8`]). OpenImageIO does not sRGB-encode 8-bit output, which is why this
/// happens here.
pub fn write_png_preview(path: impl AsRef<Path>, image: &Image) -> Result<(), ImageError> {
    let path = path.as_ref();
    check_before_writing(path, image)?;
    let find = |name: &str| {
        image.channel_index(name).ok_or_else(|| {
            ImageError::invalid(
                path,
                format!(
                    "an 8-bit preview needs channels R, G and B; channel {name:?} is missing \
                     (the image has {})",
                    image.channels.join(", ")
                ),
            )
        })
    };
    let rgb = [find("R")?, find("G")?, find("B")?];
    let out_channels: &[&str] = &["R", "G", "B"];

    let n = image.channels.len();
    let mut bytes = Vec::with_capacity(image.width * image.height * out_channels.len());
    for pixel in image.data.chunks_exact(n) {
        bytes.extend(rgb.map(|c| linear_to_srgb8(pixel[c])));
    }
    write_atomically(path, |temp| {
        oiio::write_image(
            temp,
            image.width,
            image.height,
            out_channels,
            Pixels::U8(&bytes),
            WriteOptions {
                format: FileFormat::Uint8,
                unassociated_alpha: false,
            },
        )
    })
}

/// Reads the image at `path` (first subimage; any format OpenImageIO reads) as `f32`.
///
/// 8-bit files come back as stored, divided by 255: no sRGB decoding. Colour comes back
/// premultiplied by alpha, as [`Image`] holds it: OpenImageIO multiplies it in for formats that
/// store straight alpha (PNG).
pub fn read(path: impl AsRef<Path>) -> Result<Image, ImageError> {
    let path = path.as_ref();
    let metadata = fs::metadata(path).map_err(|e| ImageError::io(path, "cannot read", e))?;
    if metadata.is_dir() {
        return Err(ImageError::invalid(path, "is a directory, not an image"));
    }
    let decoded = oiio::read_image(path).map_err(|source| ImageError::Oiio {
        path: path.to_path_buf(),
        context: "openimageio cannot read it".to_owned(),
        source,
    })?;
    check_channels(&decoded.channels).map_err(|m| ImageError::invalid(path, m))?;
    Ok(Image {
        width: decoded.width,
        height: decoded.height,
        channels: decoded.channels,
        data: decoded.data,
    })
}

/// Runs `write_to` on a temporary file next to `path` and renames it over `path`
/// ([`crate::util::atomic_file`]). On any failure the temporary file is removed.
fn write_atomically(
    path: &Path,
    write_to: impl FnOnce(&Path) -> Result<(), OiioError>,
) -> Result<(), ImageError> {
    if path.is_dir() {
        return Err(ImageError::invalid(path, "is a directory"));
    }
    let io = |e: atomic_file::WriteError| ImageError::io(path, e.context, e.source);
    let temp = atomic_file::temp_beside(path).map_err(io)?;
    write_to(temp.path()).map_err(|source| ImageError::Oiio {
        path: path.to_path_buf(),
        context: "openimageio cannot write it".to_owned(),
        source,
    })?;
    atomic_file::persist(temp, path).map_err(io)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(channels: &[&str]) -> Vec<String> {
        channels.iter().map(|c| c.to_string()).collect()
    }

    #[test]
    fn srgb_encoding_matches_reference_values() {
        // Reference values of the IEC 61966-2-1 curve, rounded to 8 bits.
        assert_eq!(linear_to_srgb8(0.0), 0);
        assert_eq!(linear_to_srgb8(0.5), 188);
        assert_eq!(linear_to_srgb8(0.18), 118);
        assert_eq!(linear_to_srgb8(1.0), 255);
        assert_eq!(linear_to_srgb8(7.0), 255);
        assert_eq!(linear_to_srgb8(-1.0), 0);
        assert_eq!(linear_to_srgb8(f32::NAN), 0);
        assert_eq!(linear_to_srgb8(0.001), 3); // linear segment: 12.92 * 0.001 * 255 = 3.29
    }

    #[test]
    fn pixels_are_interleaved_top_row_first() {
        let mut image = Image::new(3, 2, names(&["R", "G"]));
        image.set(2, 1, 1, 5.0);
        assert_eq!(image.data[(3 + 2) * 2 + 1], 5.0);
        assert_eq!(image.pixel(2, 1), &[0.0, 5.0]);
        assert_eq!(image.channel_index("G"), Some(1));
        assert_eq!(image.channel_index("B"), None);
    }

    #[test]
    #[should_panic(expected = "appears twice")]
    fn repeated_channel_names_are_refused() {
        let _ = Image::new(1, 1, names(&["R", "R"]));
    }

    #[test]
    #[should_panic(expected = "outside")]
    fn pixels_outside_panic() {
        let image = Image::new(3, 2, names(&["R"]));
        let _ = image.pixel(3, 0);
    }

    #[test]
    fn inconsistent_images_are_refused() {
        let mut image = Image::new(2, 2, names(&["R", "G", "B"]));
        image.data.pop();
        let err = write("/nonexistent/frame.exr", &image).unwrap_err();
        assert!(err.to_string().contains("holds 11 values"), "{err}");
    }

    #[test]
    fn unknown_extensions_are_refused() {
        let err = write("frame.jpg", &Image::new(1, 1, names(&["R"]))).unwrap_err();
        assert!(err.to_string().contains("frame.jpg"), "{err}");
    }
}
