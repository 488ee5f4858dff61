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
//!
//! **All or nothing** ([`Outputs`]): a run's files (EXR, PNG preview, dumped maps) are each written to a temporary
//! file, flushed and **read back and compared** with what was meant (OpenImageIO's PNG writer reports success on a
//! full disk), and only when every one of them is verified are they renamed into place and their directory synced.
//! A failure names the file and, when the file system is the cause, the operating system's words ("No space left
//! on device"). [`check_output`] checks a path before a render starts.

use std::ffi::OsStr;
use std::fs;
use std::io;
use std::path::{Path, PathBuf};

use crate::sys::oiio::{self, OiioError};
use crate::util::atomic_file;

pub mod denoise;
mod exr_header;
mod outputs;
pub use outputs::Outputs;

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

    /// The values of the three channels `names` of every pixel, interleaved pixel by pixel (e.g. `["R", "G", "B"]`
    /// as RGB triples), or `None` when one is missing.
    pub fn triples(&self, names: [&str; 3]) -> Option<Vec<f32>> {
        let [Some(a), Some(b), Some(c)] = names.map(|n| self.channel_index(n)) else {
            return None;
        };
        let n = self.channels.len();
        Some(
            self.data
                .chunks_exact(n)
                .flat_map(|p| [p[a], p[b], p[c]])
                .collect(),
        )
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

/// Starts loading the image library (OpenImageIO) in the background, for a command that reads or writes images
/// after other work (`render`): the half second its dependencies take to load then overlaps that work
/// ([`crate::sys::oiio`] has the numbers).
pub fn preload() {
    oiio::preload();
}

/// Waits for the background load [`preload`] started, if any: call before the process exits (a process that exits
/// while a library is being loaded can die of a signal).
pub fn finish_preload() {
    oiio::finish_preload();
}

/// Writes `image` to `path`, atomically and verified (see the [module docs](self)), in the format its extension
/// names (case-insensitive):
///
/// - `.exr`: every channel, 32-bit float, names as given;
/// - `.png`: an 8-bit sRGB preview of the colour channels ([`write_png_preview`]).
///
/// Any other extension is an [`ImageError::Invalid`].
pub fn write(path: impl AsRef<Path>, image: &Image) -> Result<(), ImageError> {
    let path = path.as_ref();
    let mut outputs = Outputs::new();
    match extension(path).as_deref() {
        Some("exr") => outputs.exr(path, image, &ExrInfo::default())?,
        Some("png") => outputs.png_preview(path, image)?,
        _ => return Err(bad_extension(path)),
    }
    outputs.commit().map(drop)
}

/// The lower-case extension of `path`, if it has one.
pub(crate) fn extension(path: &Path) -> Option<String> {
    path.extension()
        .and_then(OsStr::to_str)
        .map(str::to_ascii_lowercase)
}

fn bad_extension(path: &Path) -> ImageError {
    ImageError::invalid(
        path,
        "unsupported image extension: use .exr (all channels, float) \
         or .png (8-bit srgb preview)",
    )
}

/// Checks, before anything is rendered, that an image can be written at `path`: a `.exr` or `.png` extension, not
/// a directory, in an existing directory where a file can be created (a temporary file is created and removed).
pub fn check_output(path: &Path) -> Result<(), ImageError> {
    if !matches!(extension(path).as_deref(), Some("exr" | "png")) {
        return Err(bad_extension(path));
    }
    if path.is_dir() {
        return Err(ImageError::invalid(path, "is a directory"));
    }
    let dir = match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    };
    match fs::metadata(dir) {
        Ok(m) if m.is_dir() => {}
        Ok(_) => {
            return Err(ImageError::invalid(
                path,
                "its directory is not a directory",
            ))
        }
        Err(e) => return Err(ImageError::io(path, "its directory cannot be used", e)),
    }
    atomic_file::temp_beside(path)
        .map(drop)
        .map_err(|e| ImageError::io(path, "cannot create files in its directory", e.source))
}

/// Where an EXR's pixels sit in the full frame (EXR data window inside the display window), in pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DataWindow {
    /// Column of the image's first pixel in the full frame.
    pub x: usize,
    /// Row of the image's first pixel in the full frame.
    pub y: usize,
    /// Width of the full frame.
    pub full_width: usize,
    /// Height of the full frame.
    pub full_height: usize,
}

/// What an EXR records besides its pixels.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ExrInfo {
    /// Where the pixels sit in a larger frame (a tile); `None`: the image is the whole frame.
    pub window: Option<DataWindow>,
    /// String attributes stored in the header, `(name, value)`, e.g. `("cuticle:complete", "1")`.
    pub attributes: Vec<(String, String)>,
}

/// Rows of an image `height` rows tall that decoding it holds at once, for its memory bound: the decoded floats and
/// OpenImageIO 2.4's conversion buffer, which holds at least 256 rows (its `read_chunk`) whatever the image's
/// height: a 458 753 × 4 tile (29 MB as floats) made it allocate 1.9 GB (the `merge` fuzz target). For narrow
/// images that buffer may reach 64 MB, which every bound here allows for.
fn decoded_rows(height: usize) -> u64 {
    height as u64 + 256
}

/// Reads the image at `path` with where it sits in its full frame and the string attributes named in `names`
/// (`None` where the file has none).
pub fn read_with_info(
    path: &Path,
    names: &[&str],
) -> Result<(Image, DataWindow, Vec<Option<String>>), ImageError> {
    read_with_info_at_most(path, names, u64::MAX)
}

/// [`read_with_info`], refusing before decoding an image whose pixels or whose full frame (display window) would
/// take more than `max_bytes` as f32 (a forged tile declaring a 100 000² frame aborted `merge` in the allocator).
pub fn read_with_info_at_most(
    path: &Path,
    names: &[&str],
    max_bytes: u64,
) -> Result<(Image, DataWindow, Vec<Option<String>>), ImageError> {
    let file = open_as(path, true, max_bytes)?;
    let attributes = file.attributes(names).map_err(|source| ImageError::Oiio {
        path: path.to_path_buf(),
        context: "openimageio cannot read its header".to_owned(),
        source,
    })?;
    let w = file.window();
    let bytes = |width: u64, height: u64| {
        [width, height, file.channels.len() as u64, 4]
            .into_iter()
            .try_fold(1u64, |acc, n| acc.checked_mul(n))
    };
    let sizes = [
        (file.width as u64, decoded_rows(file.height)),
        (
            u64::try_from(w.full_width).unwrap_or(0),
            u64::try_from(w.full_height).unwrap_or(0),
        ),
    ];
    for (width, height) in sizes {
        if bytes(width, height).is_none_or(|b| b > max_bytes) {
            return Err(ImageError::invalid(
                path,
                format!(
                    "a {width} x {height} image of {} channels would take more than the {} allowed",
                    file.channels.len(),
                    crate::util::input_file::human_bytes(max_bytes)
                ),
            ));
        }
    }
    let image = decode(path, file)?;
    let int =
        |v: i32| usize::try_from(v).map_err(|_| ImageError::invalid(path, "negative data window"));
    let window = DataWindow {
        x: int(w.x)?,
        y: int(w.y)?,
        full_width: int(w.full_width)?,
        full_height: int(w.full_height)?,
    };
    Ok((image, window, attributes))
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
    let mut outputs = Outputs::new();
    outputs.png_preview(path.as_ref(), image)?;
    outputs.commit().map(drop)
}

/// The sRGB-encoded 8-bit `R,G,B` of every pixel of `image`, interleaved.
fn preview_bytes(path: &Path, image: &Image) -> Result<Vec<u8>, ImageError> {
    // The denoised frame where the image holds one ([`denoise`]): the preview is what a user looks at first.
    if let [Some(r), Some(g), Some(b)] = denoise::CHANNELS.map(|name| image.channel_index(name)) {
        return Ok(rgb_bytes(image, [r, g, b]));
    }
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
    Ok(rgb_bytes(image, rgb))
}

/// The sRGB-encoded 8-bit values of channels `rgb` of every pixel of `image`, interleaved.
fn rgb_bytes(image: &Image, rgb: [usize; 3]) -> Vec<u8> {
    let n = image.channels.len();
    let mut bytes = Vec::with_capacity(image.width * image.height * 3);
    for pixel in image.data.chunks_exact(n) {
        bytes.extend(rgb.map(|c| linear_to_srgb8(pixel[c])));
    }
    bytes
}

/// Reads the image at `path` (first subimage; any format OpenImageIO reads) as `f32`.
///
/// 8-bit files come back as stored, divided by 255: no sRGB decoding. Colour comes back
/// premultiplied by alpha, as [`Image`] holds it: OpenImageIO multiplies it in for formats that
/// store straight alpha (PNG).
pub fn read(path: impl AsRef<Path>) -> Result<Image, ImageError> {
    let path = path.as_ref();
    decode(path, open(path)?)
}

/// [`read`], refusing before any pixel is decoded an image whose decoded `f32` texels would take more than
/// `max_bytes` (its header's width × channels × 4 × the rows decoding holds, [`decoded_rows`]): a small compressed
/// file can declare a huge image.
pub fn read_at_most(path: impl AsRef<Path>, max_bytes: u64) -> Result<Image, ImageError> {
    Ok(read_at_most_with(path.as_ref(), &[], max_bytes)?.0)
}

/// [`read_at_most`], with the string attributes named in `names` (`None` where the file has none): a texture's
/// `oiio:ColorSpace` says whether its texels are sRGB-encoded.
pub fn read_at_most_with(
    path: &Path,
    names: &[&str],
    max_bytes: u64,
) -> Result<(Image, Vec<Option<String>>), ImageError> {
    let file = open_as(path, false, max_bytes)?;
    let attributes = file.attributes(names).map_err(|source| ImageError::Oiio {
        path: path.to_path_buf(),
        context: "openimageio cannot read its header".to_owned(),
        source,
    })?;
    let bytes = [
        file.width as u64,
        decoded_rows(file.height),
        file.channels.len() as u64,
        4,
    ]
    .into_iter()
    .try_fold(1u64, |acc, n| acc.checked_mul(n));
    if bytes.is_none_or(|b| b > max_bytes) {
        return Err(ImageError::invalid(
            path,
            format!(
                "{} x {} pixels of {} channels would take {} decoded, more than the {} allowed",
                file.width,
                file.height,
                file.channels.len(),
                bytes.map_or(
                    "over 16 EiB".to_owned(),
                    crate::util::input_file::human_bytes
                ),
                crate::util::input_file::human_bytes(max_bytes)
            ),
        ));
    }
    Ok((decode(path, file)?, attributes))
}

/// Opens the image at `path` for reading (its header only; see [`oiio::OpenImage`]).
fn open(path: &Path) -> Result<oiio::OpenImage, ImageError> {
    open_as(path, false, u64::MAX)
}

/// [`open`]; `exr_only`: refuse any file but OpenEXR before OpenImageIO sees it (a tile is an EXR, and each other
/// format OpenImageIO would try is one more reader a forged tile reaches); `max_bytes`: refuse an OpenEXR file whose
/// data window's pixels would take more, before OpenEXR sizes its buffers from it.
fn open_as(path: &Path, exr_only: bool, max_bytes: u64) -> Result<oiio::OpenImage, ImageError> {
    let metadata = fs::metadata(path).map_err(|e| ImageError::io(path, "cannot read", e))?;
    if metadata.is_dir() {
        return Err(ImageError::invalid(path, "is a directory, not an image"));
    }
    // A regular file only: OpenImageIO would block forever opening a FIFO and never end reading `/dev/zero`.
    let (file, len) = crate::util::input_file::open_regular(path)
        .map_err(|e| ImageError::io(path, "cannot read", e))?;
    // An OpenEXR header's declared sizes must fit the file before OpenEXR allocates them.
    exr_header::check(file, len, exr_only, max_bytes)
        .map_err(|m| ImageError::invalid(path, format!("not a valid OpenEXR file: {m}")))?;
    oiio::open_image(path).map_err(|source| ImageError::Oiio {
        path: path.to_path_buf(),
        context: "openimageio cannot read it".to_owned(),
        source,
    })
}

/// The pixels of `file` (opened from `path`) as an [`Image`], its channels checked.
fn decode(path: &Path, file: oiio::OpenImage) -> Result<Image, ImageError> {
    let decoded = file.read().map_err(|source| ImageError::Oiio {
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

#[cfg(test)]
mod tests {
    use super::outputs::verify_u8;
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

    #[test]
    fn a_failed_writer_leaves_no_file_and_no_target() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("frame.exr");
        let mut outputs = Outputs::new();
        let err = outputs
            .stage_with(
                &path,
                |_| {
                    Err(OiioError {
                        message: "disk on fire".into(),
                    })
                },
                |_| Ok(()),
            )
            .unwrap_err();
        assert!(
            err.to_string().contains("frame.exr") && err.to_string().contains("disk on fire"),
            "{err}"
        );
        outputs.commit().unwrap();
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[test]
    fn a_truncated_file_fails_verification_and_nothing_is_renamed() {
        let dir = tempfile::tempdir().unwrap();
        let exr = dir.path().join("frame.exr");
        let png = dir.path().join("frame.png");
        std::fs::write(&exr, "previous").unwrap();
        let image = Image::new(4, 3, names(&["R", "G", "B"]));
        let mut outputs = Outputs::new();
        outputs.exr(&exr, &image, &ExrInfo::default()).unwrap();
        // A writer that reports success but leaves half a file (OpenImageIO's PNG writer on a full disk).
        let err = outputs
            .stage_with(
                &png,
                |temp| {
                    write_png_preview(temp, &image).map_err(|e| OiioError {
                        message: e.to_string(),
                    })?;
                    let len = std::fs::metadata(temp).unwrap().len();
                    std::fs::OpenOptions::new()
                        .write(true)
                        .open(temp)
                        .unwrap()
                        .set_len(len / 2)
                        .unwrap();
                    Ok(())
                },
                |temp| verify_u8(temp, 4, 3, &[0; 36]),
            )
            .unwrap_err();
        assert!(
            err.to_string()
                .contains("frame.png: the written file is wrong"),
            "{err}"
        );
        drop(outputs);
        assert_eq!(std::fs::read(&exr).unwrap(), b"previous", "nothing renamed");
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            1,
            "temporaries removed"
        );
    }

    #[test]
    fn staged_files_are_verified_and_renamed_together() {
        let dir = tempfile::tempdir().unwrap();
        let mut image = Image::new(4, 3, names(&["R", "G", "B", "depth.Z"]));
        image.set(1, 2, 3, f32::INFINITY);
        image.set(0, 0, 0, -0.0);
        let mut outputs = Outputs::new();
        let info = ExrInfo {
            window: Some(DataWindow {
                x: 2,
                y: 1,
                full_width: 8,
                full_height: 5,
            }),
            attributes: vec![("cuticle:complete".into(), "1".into())],
        };
        outputs
            .exr(&dir.path().join("a.exr"), &image, &info)
            .unwrap();
        outputs
            .png_preview(&dir.path().join("a.png"), &image)
            .unwrap();
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            2,
            "only temporaries so far"
        );
        assert!(!dir.path().join("a.exr").exists());
        let written = outputs.commit().unwrap();
        assert_eq!(written.len(), 2);
        let (back, window, attrs) =
            read_with_info(&dir.path().join("a.exr"), &["cuticle:complete"]).unwrap();
        assert_eq!(window, info.window.unwrap());
        assert_eq!(attrs[0].as_deref(), Some("1"));
        assert_eq!(
            back.get(1, 2, back.channel_index("depth.Z").unwrap()),
            f32::INFINITY
        );
    }

    #[test]
    fn exr_and_preview_are_written_together_or_not_at_all() {
        let dir = tempfile::tempdir().unwrap();
        let mut image = Image::new(4, 3, names(&["R", "G", "B"]));
        image.set(2, 1, 0, 0.5);
        let (exr, png) = (dir.path().join("a.exr"), dir.path().join("a.png"));
        let mut outputs = Outputs::new();
        outputs
            .exr_with_preview(&exr, &png, &image, &ExrInfo::default())
            .unwrap();
        assert_eq!(outputs.commit().unwrap(), [exr.clone(), png.clone()]);
        assert_eq!(read(&exr).unwrap().get(2, 1, 0), 0.5);
        assert_eq!(read(&png).unwrap().width, 4);
        // The preview cannot be written (its directory does not exist): the EXR, written fine on the other
        // thread, is not staged either, and its temporary file is gone.
        let dir = tempfile::tempdir().unwrap();
        let (exr, png) = (dir.path().join("b.exr"), dir.path().join("no/b.png"));
        let mut outputs = Outputs::new();
        let err = outputs
            .exr_with_preview(&exr, &png, &image, &ExrInfo::default())
            .unwrap_err();
        assert!(err.to_string().contains("b.png"), "{err}");
        assert!(outputs.commit().unwrap().is_empty());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    #[test]
    fn check_output_refuses_before_anything_is_written() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("d.png")).unwrap();
        let e = check_output(&dir.path().join("d.png")).unwrap_err();
        assert!(e.to_string().ends_with("d.png: is a directory"), "{e}");
        assert!(check_output(&dir.path().join("x.tif")).is_err());
        assert!(check_output(&dir.path().join("no/x.exr")).is_err());
        check_output(&dir.path().join("x.exr")).unwrap();
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
