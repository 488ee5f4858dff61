//! Image output and input through OpenImageIO: exact EXR round trips, the sRGB PNG preview, atomic
//! writes that fail cleanly (error naming the path, nothing left behind), and reading the
//! DWAB-compressed EXR and Radiance environment maps.

use std::fs;
use std::io::ErrorKind;
use std::path::{Path, PathBuf};
use std::process::Command;

mod common;

use cuticle::image::{self, Image, ImageError};

/// The renderer's output channels: beauty, then AOVs as EXR `layer.channel` names.
const CHANNELS: [&str; 9] = [
    "R",
    "G",
    "B",
    "A",
    "depth.Z",
    "tangent.X",
    "tangent.Y",
    "tangent.Z",
    "strand.id",
];

/// The DWAB-compressed environment map of the test data (`CUTICLE_DATA`, see docs/data.md).
const CITY_EXR: &str = "envmaps/city.exr";
/// The same map as Radiance RGBE.
const CITY_HDR: &str = "envmaps/city.hdr";
/// Size of the shipped lat-long environment maps (width, height).
const ENVMAP_SIZE: (usize, usize) = (1024, 512);

fn names(channels: &[&str]) -> Vec<String> {
    channels.iter().map(|c| c.to_string()).collect()
}

/// A small image whose values are all distinct, including ones a half float cannot hold (large
/// strand ids, fine fractions) and infinite depth, as background pixels have.
fn aov_image(width: usize, height: usize) -> Image {
    let mut image = Image::new(width, height, names(&CHANNELS));
    for y in 0..height {
        for x in 0..width {
            let i = (y * width + x) as f32;
            let pixel = image.pixel_mut(x, y);
            for (c, value) in pixel.iter_mut().enumerate() {
                *value = i * 0.123_456_79 + c as f32 * 1.000_001;
            }
            pixel[4] = if x == 0 {
                f32::INFINITY
            } else {
                10.0 + i / 3.0
            };
            pixel[8] = 16_777_000.0 + i; // an integer id, exact in float32 (not in half)
        }
    }
    image
}

/// The names of the entries of `dir`, sorted.
fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("cannot list {}: {e}", dir.display()))
        .map(|entry| entry.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// A one-row image of the given channels whose pixels are `values`, pixel after pixel.
fn row(channels: &[&str], values: &[f32]) -> Image {
    let mut image = Image::new(values.len() / channels.len(), 1, names(channels));
    image.data.copy_from_slice(values);
    image
}

/// The 8-bit codes stored in an 8-bit file, as read back (OpenImageIO returns code / 255).
fn codes(image: &Image) -> Vec<u8> {
    image
        .data
        .iter()
        .map(|&v| {
            let code = v * 255.0;
            assert!(
                (code - code.round()).abs() < 1e-3,
                "{v} is not an 8-bit value"
            );
            code.round() as u8
        })
        .collect()
}

#[test]
fn exr_round_trip_is_exact_and_keeps_channel_names() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("frame.exr");
    let written = aov_image(7, 5);
    image::write(&path, &written).unwrap();
    let read = image::read(&path).unwrap();

    assert_eq!((read.width, read.height), (7, 5));
    // OpenEXR sorts channels by name; OpenImageIO returns the beauty first, then the layers.
    let mut read_names = read.channels.clone();
    read_names.sort();
    let mut written_names = written.channels.clone();
    written_names.sort();
    assert_eq!(read_names, written_names);
    assert_eq!(&read.channels[..4], &["R", "G", "B", "A"]);

    for name in CHANNELS {
        let (w, r) = (
            written.channel_index(name).unwrap(),
            read.channel_index(name).unwrap(),
        );
        for y in 0..5 {
            for x in 0..7 {
                assert_eq!(
                    written.get(x, y, w).to_bits(),
                    read.get(x, y, r).to_bits(),
                    "channel {name} at pixel ({x}, {y})"
                );
            }
        }
    }
    assert_eq!(listing(dir.path()), ["frame.exr"], "no temporary file left");
}

#[test]
fn writing_over_an_existing_file_replaces_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("frame.exr");
    image::write(&path, &row(&["R", "G", "B"], &[1.0, 2.0, 3.0])).unwrap();
    image::write(&path, &row(&["R", "G", "B"], &[4.0, 5.0, 6.0])).unwrap();
    assert_eq!(image::read(&path).unwrap().data, [4.0, 5.0, 6.0]);
    assert_eq!(listing(dir.path()), ["frame.exr"]);
}

#[test]
fn png_preview_is_srgb_encoded_clamped_and_rounded() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("preview.png");
    // Linear 0 → 0, 0.5 → 188 (0.7354 × 255 = 187.5), 1 → 255, above 1 clamps, below 0 and NaN
    // give 0, 0.18 (mid grey) → 118, 0.001 lies on the linear segment: 12.92 × 0.001 × 255 = 3.3.
    let linear = [0.0, 0.5, 1.0, 7.5, -0.25, f32::NAN, 0.18, 0.001, 1.0e-9];
    let expected: [u8; 9] = [0, 188, 255, 255, 0, 0, 118, 3, 0];
    image::write(&path, &row(&["R", "G", "B"], &linear)).unwrap();

    let read = image::read(&path).unwrap();
    assert_eq!((read.width, read.height), (3, 1));
    assert_eq!(read.channels, ["R", "G", "B"]);
    assert_eq!(codes(&read), expected);
    assert_eq!(listing(dir.path()), ["preview.png"]);
}

/// Pixels of R, G, B, A plus an AOV the preview drops: a half-covered pixel, an empty pixel, and
/// an opaque white one.
const PREMULTIPLIED_RGBA_AND_DEPTH: [f32; 15] = [
    0.25, 0.25, 0.0, 0.5, 3.0, //
    0.0, 0.0, 0.0, 0.0, 4.0, //
    1.0, 1.0, 1.0, 1.0, 5.0,
];
/// What the PNG must store for them: the colour as rendered, sRGB-encoded (0.25 → 137), no alpha.
const STORED_RGB: [u8; 9] = [137, 137, 0, 0, 0, 0, 255, 255, 255];

/// Writes the RGBA preview of [`PREMULTIPLIED_RGBA_AND_DEPTH`] into `dir`.
fn write_rgba_preview(dir: &Path) -> PathBuf {
    let path = dir.join("preview.png");
    let image = row(
        &["R", "G", "B", "A", "depth.Z"],
        &PREMULTIPLIED_RGBA_AND_DEPTH,
    );
    image::write_png_preview(&path, &image).unwrap();
    path
}

#[test]
fn png_preview_is_rgb_as_rendered() {
    let dir = tempfile::tempdir().unwrap();
    let read = image::read(write_rgba_preview(dir.path())).unwrap();
    assert_eq!(read.channels, ["R", "G", "B"]);
    assert_eq!(codes(&read), STORED_RGB);
}

#[test]
fn png_preview_needs_colour_channels() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("depth.png");
    let err = image::write(&path, &row(&["depth.Z"], &[1.0])).unwrap_err();
    let message = err.to_string();
    assert!(matches!(err, ImageError::Invalid { .. }), "{message}");
    assert!(message.contains(&*path.to_string_lossy()), "{message}");
    assert!(message.contains("\"R\""), "{message}");
    assert!(listing(dir.path()).is_empty());
}

/// Writes `path`, expects an error naming it, and checks that `dir` holds only `expected` after.
fn assert_write_fails_cleanly(path: &Path, dir: &Path, expected: &[&str]) {
    let err = image::write(path, &aov_image(4, 3)).unwrap_err();
    let message = err.to_string();
    assert!(
        message.contains(&*path.to_string_lossy()),
        "the error should name {}: {message}",
        path.display()
    );
    assert_eq!(listing(dir), expected, "after the error: {message}");
}

#[test]
fn writing_into_a_missing_directory_fails_naming_the_path() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("missing").join("frame.exr");
    assert_write_fails_cleanly(&path, dir.path(), &[]);
}

#[test]
fn writing_under_a_regular_file_fails_naming_the_path() {
    // A read-only directory stops nobody running as root; a regular file used as a directory
    // stops everyone.
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("file.txt");
    fs::write(&file, "not a directory").unwrap();
    for name in ["frame.exr", "preview.png"] {
        assert_write_fails_cleanly(&file.join(name), dir.path(), &["file.txt"]);
    }
}

#[test]
fn a_failed_openimageio_write_removes_the_temporary_file() {
    // The temporary file is created, then OpenImageIO finds no writer for the extension.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("preview.nosuchformat");
    let err = image::write_png_preview(&path, &row(&["R", "G", "B"], &[0.5; 3])).unwrap_err();
    assert!(matches!(err, ImageError::Oiio { .. }), "{err}");
    assert!(err.to_string().contains("preview.nosuchformat"), "{err}");
    assert!(listing(dir.path()).is_empty(), "{:?}", listing(dir.path()));
}

#[test]
fn writing_over_a_directory_fails_and_leaves_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("frame.exr");
    fs::create_dir(&path).unwrap();
    assert_write_fails_cleanly(&path, dir.path(), &["frame.exr"]);
    assert!(path.is_dir());
}

#[test]
fn reading_a_missing_file_fails_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("absent.exr");
    let err = image::read(&path).unwrap_err();
    let message = err.to_string();
    assert!(message.contains(&*path.to_string_lossy()), "{message}");
    match err {
        ImageError::Io { source, .. } => assert_eq!(source.kind(), ErrorKind::NotFound),
        other => panic!("expected an i/o error, got {other}"),
    }
}

#[test]
fn reading_a_file_that_is_not_an_image_fails_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("notes.exr");
    fs::write(&path, "plain text, not OpenEXR").unwrap();
    let err = image::read(&path).unwrap_err();
    assert!(matches!(err, ImageError::Oiio { .. }), "{err}");
    assert!(err.to_string().contains(&*path.to_string_lossy()), "{err}");
}

/// DWAB is lossy: the shipped EXR holds small negative values (down to about -0.0016) where the
/// source was clamped to 0. Anything below this is a decoding error.
const DWAB_UNDERSHOOT: f32 = -0.01;

/// Relative difference allowed between the channel means of the EXR and HDR versions of a map
/// (measured: 0.3%, from DWAB and RGBE quantisation).
const MAP_MEAN_TOLERANCE: f64 = 0.01;

/// The environment map `rel` of the test data, checked for its size, channels and values; panics naming the file
/// when it is missing.
#[track_caller]
fn read_envmap(rel: &str) -> Image {
    let file = common::data::file(rel);
    let path = file.display();
    let map = image::read(&file).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!((map.width, map.height), ENVMAP_SIZE, "{path}");
    assert_eq!(map.channels, ["R", "G", "B"], "{path}");
    if let Some(bad) = map
        .data
        .iter()
        .position(|v| !v.is_finite() || *v < DWAB_UNDERSHOOT)
    {
        panic!("{path}: value {} at index {bad}", map.data[bad]);
    }
    map
}

/// The mean of each channel.
fn channel_means(image: &Image) -> Vec<f64> {
    let n = image.channels.len();
    let mut sums = vec![0.0f64; n];
    for pixel in image.data.chunks_exact(n) {
        for (sum, &v) in sums.iter_mut().zip(pixel) {
            *sum += f64::from(v);
        }
    }
    let count = (image.width * image.height) as f64;
    sums.iter().map(|s| s / count).collect()
}

#[test]
fn reads_the_dwab_compressed_exr_environment_map() {
    let map = read_envmap(CITY_EXR);
    assert!(
        channel_means(&map).iter().all(|&m| m > 0.0),
        "{CITY_EXR}: black"
    );
}

#[test]
fn reads_the_radiance_hdr_environment_map_as_the_same_picture() {
    let hdr = read_envmap(CITY_HDR);
    assert!(
        hdr.data.iter().all(|&v| v >= 0.0),
        "rgbe cannot hold negative values"
    );
    let exr = read_envmap(CITY_EXR);
    for (c, (h, e)) in channel_means(&hdr)
        .iter()
        .zip(channel_means(&exr))
        .enumerate()
    {
        assert!(
            (h - e).abs() <= MAP_MEAN_TOLERANCE * e,
            "channel {c}: hdr mean {h}, exr mean {e}"
        );
    }
}

/// Runs `oiiotool` with `args`, failing with an install hint if it is not on PATH.
fn oiiotool(args: &[&str]) -> String {
    let output = match Command::new("oiiotool").args(args).output() {
        Ok(output) => output,
        Err(e) if e.kind() == ErrorKind::NotFound => panic!(
            "oiiotool not found on PATH: install openimageio-tools \
             (sudo apt-get install openimageio-tools)"
        ),
        Err(e) => panic!("cannot run oiiotool: {e}"),
    };
    assert!(
        output.status.success(),
        "oiiotool {args:?} failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8_lossy(&output.stdout).into_owned()
}

#[test]
fn oiiotool_lists_the_written_exr_channels() {
    let dir = tempfile::tempdir().unwrap();
    let path: PathBuf = dir.path().join("frame.exr");
    image::write(&path, &aov_image(4, 3)).unwrap();
    let info = oiiotool(&["--info", "-v", path.to_str().unwrap()]);
    let channel_list = info
        .lines()
        .find_map(|line| line.trim().strip_prefix("channel list:"))
        .unwrap_or_else(|| panic!("no channel list in oiiotool's output:\n{info}"));
    let mut listed: Vec<&str> = channel_list.split(',').map(str::trim).collect();
    listed.sort_unstable();
    let mut expected = CHANNELS;
    expected.sort_unstable();
    assert_eq!(listed, expected, "oiiotool --info -v:\n{info}");
    assert!(info.contains("9 channel, float openexr"), "{info}");
}

#[test]
fn oiiotool_sees_straight_srgb_colour_in_the_png_preview() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_rgba_preview(dir.path());
    // Ask for the stored (unassociated) values, and print them as integers.
    let dump = oiiotool(&[
        "--dumpdata",
        "-iconfig",
        "oiio:UnassociatedAlpha",
        "1",
        path.to_str().unwrap(),
    ]);
    assert!(dump.contains("3 channel, uint8 png"), "{dump}");
    let stored: Vec<u8> = dump
        .lines()
        .filter_map(|line| line.trim().strip_prefix("Pixel ("))
        .flat_map(|line| {
            let codes = line.split("):").nth(1).unwrap().split('(').next().unwrap();
            codes
                .split_whitespace()
                .map(|c| c.parse::<u8>().unwrap())
                .collect::<Vec<_>>()
        })
        .collect();
    assert_eq!(stored, STORED_RGB, "oiiotool --dumpdata:\n{dump}");
}

/// A frame's EXR and its preview are replaced as a unit: when the preview cannot be put in place (its name is now
/// a directory), the old EXR stays, byte for byte, and no temporary file is left (the EXR was replaced alone).
#[test]
fn an_exr_and_its_preview_are_replaced_both_or_neither() {
    let dir = tempfile::tempdir().unwrap();
    let (exr, png) = (dir.path().join("f.exr"), dir.path().join("f.png"));
    image::write(&exr, &row(&["R", "G", "B"], &[1.0, 2.0, 3.0])).unwrap();
    let old = fs::read(&exr).unwrap();
    let mut outputs = image::Outputs::new();
    outputs
        .exr_with_preview(
            &exr,
            &png,
            &row(&["R", "G", "B"], &[4.0, 5.0, 6.0]),
            &Default::default(),
        )
        .unwrap();
    fs::create_dir(&png).unwrap();
    fs::write(png.join("keep"), b"x").unwrap();
    assert!(outputs.commit().is_err());
    assert_eq!(fs::read(&exr).unwrap(), old);
    let mut left: Vec<String> = fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["f.exr", "f.png"]);
}
