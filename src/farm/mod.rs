//! One frame across many machines: the names and header metadata of frames, tiles and interrupted renders, the
//! check that tiles belong together, and [`merge`], which assembles them. The tile split itself is
//! [`crate::render::tiles`]; a render farm runs one `cuticle render --tile I/N` per task and `cuticle merge` once
//! (`contrib/slurm/`).
//!
//! **Metadata** (EXR string attributes, written by every render and merge):
//! - `cuticle:job`: a hash of the scene (after command-line overrides), the animation frame and the cuticle
//!   version ([`job_hash`]); tiles merge only when it is equal;
//! - `cuticle:complete`: `1` for a finished render, `0` for the partial EXR of an interrupted one;
//! - `cuticle:tiles`: `done/total` render tiles of the file's region;
//! - `cuticle:frame`: the animation frame.
//!
//! A tile's EXR stores its pixels as the data window of the full frame (display window), so any EXR tool shows it
//! in place.

use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicUsize;
use std::sync::Arc;

use crate::image::{self, DataWindow, ExrInfo, Image, ImageError};
use crate::render::{Reconstruction, Region};
use crate::util::atomic_file;
use crate::util::hash::{fold_words, mix64};

/// Header attribute: the job hash ([`job_hash`]).
pub const KEY_JOB: &str = "cuticle:job";
/// Header attribute: `1` complete, `0` interrupted.
pub const KEY_COMPLETE: &str = "cuticle:complete";
/// Header attribute: `done/total` render tiles.
pub const KEY_TILES: &str = "cuticle:tiles";
/// Header attribute: the animation frame.
pub const KEY_FRAME: &str = "cuticle:frame";
/// Header attribute: how the samples became pixels, `splat` or `importance` ([`crate::render::Reconstruction`]);
/// `merge --denoise` refuses splatted frames. Frames without it were rendered by filter importance sampling.
pub const KEY_RECONSTRUCTION: &str = "cuticle:reconstruction";

/// A farm step failed. Each message names the file.
#[derive(Debug, thiserror::Error)]
pub enum FarmError {
    /// An image could not be read or written.
    #[error(transparent)]
    Image(#[from] ImageError),
    /// Tiles that do not make one frame.
    #[error("{0}")]
    Merge(String),
    /// The render was stopped by a signal; the partial EXR (if any tile was done) is named.
    #[error("{0}")]
    Interrupted(Interrupted),
}

/// A render stopped by SIGINT or SIGTERM.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Interrupted {
    /// The signal number.
    pub signal: i32,
    /// Where the tiles finished so far went, if anywhere.
    pub partial: Option<PathBuf>,
}

impl std::fmt::Display for Interrupted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let name = if self.signal == signal_hook::consts::SIGINT {
            "sigint"
        } else {
            "sigterm"
        };
        match &self.partial {
            Some(p) => write!(
                f,
                "interrupted by {name}: the tiles finished so far are in {} (marked incomplete)",
                p.display()
            ),
            None => write!(f, "interrupted by {name}: nothing was written"),
        }
    }
}

impl Interrupted {
    /// The signal `cancel` (a flag of [`catch_signals`]) has caught, if any, as an interruption that wrote nothing.
    pub fn caught(cancel: &AtomicUsize) -> Option<Interrupted> {
        let signal = cancel.load(std::sync::atomic::Ordering::Relaxed) as i32;
        (signal != 0).then_some(Interrupted {
            signal,
            partial: None,
        })
    }

    /// The conventional exit status of a process ended by this signal (130 for SIGINT, 143 for SIGTERM).
    pub fn exit_code(&self) -> u8 {
        (128 + self.signal).clamp(0, 255) as u8
    }
}

/// Routes SIGINT and SIGTERM into a flag (the signal's number; 0 while none came), which the render loop polls
/// ([`crate::render::Request::cancel`]). A second SIGINT or SIGTERM ends the process at once (status 130) from a
/// thread of its own, which first removes every temporary file and waits for a commit of outputs in progress
/// ([`atomic_file::remove_temporaries_and_exit`]); the handler's own exit left `.tmp-*` files. Two signals that
/// come before the thread wakes count as one.
///
/// Once per process: later calls return the first flag.
pub fn catch_signals() -> std::io::Result<Arc<AtomicUsize>> {
    static FLAG: std::sync::OnceLock<Arc<AtomicUsize>> = std::sync::OnceLock::new();
    if let Some(flag) = FLAG.get() {
        return Ok(Arc::clone(flag));
    }
    use signal_hook::consts::{SIGINT, SIGTERM};
    let flag = Arc::new(AtomicUsize::new(0));
    for signal in [SIGINT, SIGTERM] {
        signal_hook::flag::register_usize(signal, Arc::clone(&flag), signal as usize)?;
    }
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM])?;
    std::thread::Builder::new()
        .name("signals".to_owned())
        .spawn(move || {
            let mut seen = 0usize;
            for _ in signals.forever() {
                seen += 1;
                if seen >= 2 {
                    atomic_file::remove_temporaries_and_exit(130);
                }
            }
        })?;
    Ok(Arc::clone(FLAG.get_or_init(|| flag)))
}

/// The hash that ties a frame's tiles together: `description` (the scene after overrides, as text), the animation
/// `frame` and this cuticle's version, as 16 hex digits ([`mix64`] folded over the bytes).
pub fn job_hash(description: &str, frame: i32) -> String {
    let text = format!(
        "{description}\nframe {frame}\ncuticle {}",
        env!("CARGO_PKG_VERSION")
    );
    let h = fold_words(mix64(text.len() as u64), text.as_bytes());
    format!("{h:016x}")
}

/// The most frames one `--frames` range may hold: an hour at 24 frames per second is 86,400. Every frame's output
/// paths are checked before anything renders, and `0..2147483647` grew 3 GB listing them.
pub const MAX_FRAMES: u64 = 100_000;

/// Parses `A..B` (inclusive, e.g. `1..24`; `7` alone is `7..7`), at most [`MAX_FRAMES`] frames.
pub fn parse_frames(s: &str) -> Result<RangeInclusive<i32>, String> {
    let err = || format!("expected A..B (inclusive frame numbers, e.g. 1..24), got `{s}`");
    let (a, b) = s.split_once("..").unwrap_or((s, s));
    let a = a.trim().parse::<i32>().map_err(|_| err())?;
    let b = b.trim().parse::<i32>().map_err(|_| err())?;
    if a > b {
        return Err(format!("frames `{s}`: the first frame is after the last"));
    }
    let count = (i64::from(b) - i64::from(a) + 1) as u64;
    if count > MAX_FRAMES {
        return Err(format!(
            "frames `{s}`: {count} frames, more than the {MAX_FRAMES} one job may render (split the range)"
        ));
    }
    Ok(a..=b)
}

/// The file of animation `frame` for the output `path`: `name.####.ext` (`name.0007.exr`; `None`: `path` itself).
pub fn frame_path(path: &Path, frame: Option<i32>) -> PathBuf {
    match frame {
        None => path.to_path_buf(),
        Some(f) => insert_before_extension(path, &format!("{f:04}")),
    }
}

/// Where an interrupted render of `path` puts its finished tiles: `name.partial.exr`, never the frame's name.
pub fn partial_path(path: &Path) -> PathBuf {
    insert_before_extension(&path.with_extension("exr"), "partial")
}

/// Where an interrupted render of `path` puts its finished tiles without replacing the partial EXR of an earlier
/// interrupted run (which may hold more tiles): [`partial_path`] if free, else `name.partial.2.exr`, `.3`, … (the
/// first free one).
pub fn free_partial_path(path: &Path) -> PathBuf {
    let first = partial_path(path);
    if !first.exists() {
        return first;
    }
    (2u32..)
        .map(|n| insert_before_extension(&path.with_extension("exr"), &format!("partial.{n}")))
        .find(|p| !p.exists())
        .expect("some name of 2^32 is free")
}

/// `path` with `.part` before its extension, byte for byte (a name that is not UTF-8 keeps its bytes).
fn insert_before_extension(path: &Path, part: &str) -> PathBuf {
    let mut name = path.file_stem().unwrap_or_default().to_os_string();
    name.push(".");
    name.push(part);
    if let Some(ext) = path.extension() {
        name.push(".");
        name.push(ext);
    }
    path.with_file_name(name)
}

/// The header of a render's EXR: `region` of a `width` × `height` frame (a data window unless it is the whole
/// frame), the job hash, the frame number and `done/total` tiles (complete when equal).
pub fn render_info(
    region: Region,
    width: u32,
    height: u32,
    job: &str,
    frame: i32,
    done: usize,
    total: usize,
) -> ExrInfo {
    let window = (!region.is_full(width, height)).then_some(DataWindow {
        x: region.x0 as usize,
        y: region.y0 as usize,
        full_width: width as usize,
        full_height: height as usize,
    });
    let complete = if done == total { "1" } else { "0" };
    ExrInfo {
        window,
        attributes: vec![
            (KEY_JOB.to_owned(), job.to_owned()),
            (KEY_COMPLETE.to_owned(), complete.to_owned()),
            (KEY_TILES.to_owned(), format!("{done}/{total}")),
            (KEY_FRAME.to_owned(), frame.to_string()),
        ],
    }
}

/// Assembled tiles: the frame and the header its EXR gets.
#[derive(Debug)]
pub struct Merged {
    /// The full frame.
    pub image: Image,
    /// The job hash, frame and completeness of the tiles.
    pub info: ExrInfo,
}

/// Assembles the tile EXRs `tiles` into one frame. Refuses a tile that is incomplete, of another job (scene,
/// settings, frame or version: [`KEY_JOB`]), of another frame size or channel list, tiles that overlap, and gaps;
/// every pixel of the result comes from exactly one tile.
pub fn merge(tiles: &[PathBuf]) -> Result<Merged, FarmError> {
    // The frame, its tiles and the owner map must fit the memory limit: a tile's header declares the frame's size,
    // and a forged one must not make the frame's allocation abort the process.
    let (limit, _) = crate::render::budget::default_limit();
    merge_within(tiles, limit / 3)
}

/// [`merge`], with the frame and each tile refused before they are allocated when their decoded `f32` pixels would
/// take more than `max_bytes` each (the fuzz target runs with a small bound).
pub fn merge_within(tiles: &[PathBuf], max_bytes: u64) -> Result<Merged, FarmError> {
    // One piece: each tile is checked against the first and the coverage so far as it is read.
    let fail = |path: &Path, m: String| FarmError::Merge(format!("{}: {m}", path.display()));
    let Some(first) = tiles.first() else {
        return Err(FarmError::Merge("merge: no tiles given".to_owned()));
    };
    let mut frame: Option<(Image, String, String, DataWindow)> = None;
    // How the first tile was reconstructed: every tile of one job was (the job hash covers the scene's film).
    let mut reconstruction = None;
    // Which tile wrote each pixel (index + 1; 0: none yet).
    let mut owner: Vec<u32> = Vec::new();
    for (t, path) in tiles.iter().enumerate() {
        let (tile, window, attrs) = image::read_with_info_at_most(
            path,
            &[KEY_JOB, KEY_COMPLETE, KEY_FRAME, KEY_RECONSTRUCTION],
            max_bytes,
        )?;
        let [job, complete, frame_no, built] = [0, 1, 2, 3].map(|i| attrs[i].clone());
        if t == 0 {
            reconstruction = built;
        }
        let Some(job) = job else {
            return Err(fail(
                path,
                format!("has no {KEY_JOB} attribute: not a cuticle render"),
            ));
        };
        if complete.as_deref() != Some("1") {
            return Err(fail(
                path,
                "is an incomplete (interrupted) render".to_owned(),
            ));
        }
        let frame_no = frame_no.unwrap_or_default();
        let (image, job0, _, full) = frame.get_or_insert_with(|| {
            let image = Image::new(window.full_width, window.full_height, tile.channels.clone());
            owner = vec![0; window.full_width * window.full_height];
            (image, job.clone(), frame_no.clone(), window)
        });
        if job != *job0 {
            return Err(fail(
                path,
                format!(
                    "belongs to another job ({KEY_JOB} {job}, {} has {job0}): a different scene, settings, \
                     frame or cuticle version",
                    first.display()
                ),
            ));
        }
        if (window.full_width, window.full_height) != (full.full_width, full.full_height) {
            return Err(fail(
                path,
                format!(
                    "is a tile of a {}x{} frame, {} of a {}x{} one",
                    window.full_width,
                    window.full_height,
                    first.display(),
                    full.full_width,
                    full.full_height
                ),
            ));
        }
        if window.x + tile.width > full.full_width || window.y + tile.height > full.full_height {
            return Err(fail(path, "reaches outside its frame".to_owned()));
        }
        let index: Vec<usize> = image
            .channels
            .iter()
            .map(|c| tile.channel_index(c))
            .collect::<Option<_>>()
            .filter(|_| tile.channels.len() == image.channels.len())
            .ok_or_else(|| fail(path, "has other channels than the first tile".to_owned()))?;
        for y in 0..tile.height {
            for x in 0..tile.width {
                let (fx, fy) = (window.x + x, window.y + y);
                let o = &mut owner[fy * full.full_width + fx];
                if *o != 0 {
                    return Err(fail(
                        path,
                        format!(
                            "overlaps {} at pixel ({fx}, {fy})",
                            tiles[*o as usize - 1].display()
                        ),
                    ));
                }
                *o = t as u32 + 1;
                let src = tile.pixel(x, y);
                for (dst, &i) in image.pixel_mut(fx, fy).iter_mut().zip(&index) {
                    *dst = src[i];
                }
            }
        }
    }
    let (image, job, frame_no, full) = frame.expect("at least one tile was read");
    if let Some(gap) = owner.iter().position(|&o| o == 0) {
        return Err(FarmError::Merge(format!(
            "merge: the tiles leave pixel ({}, {}) of the {}x{} frame uncovered",
            gap % full.full_width,
            gap / full.full_width,
            full.full_width,
            full.full_height
        )));
    }
    let tiles_total = tiles.len();
    let mut attributes = vec![
        (KEY_JOB.to_owned(), job),
        (KEY_COMPLETE.to_owned(), "1".to_owned()),
        (KEY_TILES.to_owned(), format!("{tiles_total} merged")),
        (KEY_FRAME.to_owned(), frame_no),
    ];
    attributes.extend(reconstruction.map(|r| (KEY_RECONSTRUCTION.to_owned(), r)));
    let info = ExrInfo {
        window: None,
        attributes,
    };
    Ok(Merged { image, info })
}

impl Merged {
    /// Whether the tiles splatted their samples ([`KEY_RECONSTRUCTION`]).
    pub fn splatted(&self) -> bool {
        self.info
            .attributes
            .iter()
            .any(|(k, v)| k == KEY_RECONSTRUCTION && v == Reconstruction::Splat.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_of_frames_and_partials() {
        let p = Path::new("out/shot.exr");
        assert_eq!(frame_path(p, None), p);
        assert_eq!(frame_path(p, Some(7)), Path::new("out/shot.0007.exr"));
        assert_eq!(partial_path(p), Path::new("out/shot.partial.exr"));
        assert_eq!(
            partial_path(&frame_path(p, Some(12))),
            Path::new("out/shot.0012.partial.exr")
        );
        assert_eq!(
            partial_path(Path::new("shot.png")),
            Path::new("shot.partial.exr")
        );
    }

    /// Frame and partial names keep a name's bytes: one that is not UTF-8 was mangled to U+FFFD by a lossy
    /// conversion.
    #[cfg(unix)]
    #[test]
    fn names_that_are_not_utf8_keep_their_bytes() {
        use std::ffi::OsStr;
        use std::os::unix::ffi::OsStrExt;
        let p = Path::new(OsStr::from_bytes(b"out/sh\xffot.exr"));
        assert_eq!(
            frame_path(p, Some(7)).as_os_str().as_bytes(),
            b"out/sh\xffot.0007.exr"
        );
        assert_eq!(
            partial_path(p).as_os_str().as_bytes(),
            b"out/sh\xffot.partial.exr"
        );
    }

    /// An interrupted render never replaces the partial EXR of an earlier one: the next free name.
    #[test]
    fn partial_names_never_replace_an_earlier_partial() {
        let dir = tempfile::tempdir().unwrap();
        let frame = dir.path().join("shot.exr");
        assert_eq!(
            free_partial_path(&frame),
            dir.path().join("shot.partial.exr")
        );
        std::fs::write(dir.path().join("shot.partial.exr"), b"x").unwrap();
        assert_eq!(
            free_partial_path(&frame),
            dir.path().join("shot.partial.2.exr")
        );
        std::fs::write(dir.path().join("shot.partial.2.exr"), b"x").unwrap();
        assert_eq!(
            free_partial_path(&frame),
            dir.path().join("shot.partial.3.exr")
        );
    }

    #[test]
    fn frame_ranges() {
        assert_eq!(parse_frames("1..24"), Ok(1..=24));
        assert_eq!(parse_frames("7"), Ok(7..=7));
        assert!(parse_frames("5..2").unwrap_err().contains("after the last"));
        assert!(parse_frames("a..b").is_err());
        assert_eq!(parse_frames("1..100000"), Ok(1..=100_000));
        let e = parse_frames("0..2147483647").unwrap_err();
        assert!(e.contains("2147483648 frames, more than the 100000"), "{e}");
        assert!(parse_frames("-2147483648..2147483647").is_err());
    }

    #[test]
    fn the_job_hash_changes_with_the_scene_and_the_frame() {
        let a = job_hash("scene a", 0);
        assert_eq!(a, job_hash("scene a", 0));
        assert_ne!(a, job_hash("scene b", 0));
        assert_ne!(a, job_hash("scene a", 1));
        assert_eq!(a.len(), 16);
    }

    #[test]
    fn exit_codes_follow_the_shell_convention() {
        let i = Interrupted {
            signal: signal_hook::consts::SIGINT,
            partial: None,
        };
        assert_eq!(i.exit_code(), 130);
    }
}
