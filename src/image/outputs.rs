//! A run's output files written all or nothing ([`Outputs`]): each staged in a temporary file beside its target,
//! verified by reading it back, then all renamed into place together, the old files moved aside and put back if
//! any rename fails.

use std::path::{Path, PathBuf};

use super::{check_before_writing, preview_bytes, ExrInfo, Image, ImageError};
use crate::sys::oiio::{self, FileFormat, OiioError, Pixels, Window, WriteOptions};
use crate::util::atomic_file::{self, TempFile};

/// A run's output files, written to temporary files beside their targets and verified, then renamed into place
/// together by [`Outputs::commit`]. Dropped without a commit, it removes every temporary file and leaves the
/// targets as they were.
#[derive(Debug, Default)]
pub struct Outputs {
    staged: Vec<(TempFile, PathBuf)>,
}

impl Outputs {
    /// No files yet.
    pub fn new() -> Self {
        Outputs::default()
    }

    /// Stages `image` as a float EXR at `path`, with `info` in its header.
    pub fn exr(&mut self, path: &Path, image: &Image, info: &ExrInfo) -> Result<(), ImageError> {
        check_before_writing(path, image)?;
        let window = info
            .window
            .map(|w| -> Result<Window, ImageError> {
                let int = |v: usize| {
                    i32::try_from(v).map_err(|_| ImageError::invalid(path, "data window too large"))
                };
                Ok(Window {
                    x: int(w.x)?,
                    y: int(w.y)?,
                    full_width: int(w.full_width)?,
                    full_height: int(w.full_height)?,
                })
            })
            .transpose()?;
        let options = WriteOptions {
            format: FileFormat::Float,
            unassociated_alpha: false,
        };
        self.stage_with(
            path,
            |temp| {
                oiio::write_image_window(
                    temp,
                    image.width,
                    image.height,
                    &image.channels,
                    Pixels::F32(&image.data),
                    options,
                    window,
                    &info.attributes,
                )
            },
            |temp| verify_exr(temp, image, window),
        )
    }

    /// Stages an 8-bit sRGB preview of `image` at `path` (see [`write_png_preview`](super::write_png_preview)).
    pub fn png_preview(&mut self, path: &Path, image: &Image) -> Result<(), ImageError> {
        check_before_writing(path, image)?;
        let bytes = preview_bytes(path, image)?;
        self.stage_with(
            path,
            |temp| {
                oiio::write_image(
                    temp,
                    image.width,
                    image.height,
                    &["R", "G", "B"],
                    Pixels::U8(&bytes),
                    WriteOptions {
                        format: FileFormat::Uint8,
                        unassociated_alpha: false,
                    },
                )
            },
            |temp| verify_u8(temp, image.width, image.height, &bytes),
        )
    }

    /// [`Outputs::exr`] of `image` at `path` and [`Outputs::png_preview`] of it at `preview`, the two written and
    /// verified at once on two threads (a render's last serial step: on the 512² peer frame the EXR took 0.04 s and
    /// the preview 0.025 s one after the other). Either's error is returned (the EXR's first) and neither file is
    /// staged then.
    pub fn exr_with_preview(
        &mut self,
        path: &Path,
        preview: &Path,
        image: &Image,
        info: &ExrInfo,
    ) -> Result<(), ImageError> {
        self.check_not_staged(path)?;
        self.check_not_staged(preview)?;
        if crate::util::input_file::same_target(path, preview) {
            return Err(ImageError::invalid(path, "is written twice in one run"));
        }
        let (mut exr, mut png) = (Outputs::new(), Outputs::new());
        let (exr_result, png_result) = std::thread::scope(|s| {
            let png_thread = s.spawn(|| png.png_preview(preview, image));
            let exr_result = exr.exr(path, image, info);
            // A panic in the preview's thread is re-raised here, as it would have been without the thread.
            let png_result = png_thread
                .join()
                .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
            (exr_result, png_result)
        });
        exr_result?;
        png_result?;
        self.staged.append(&mut exr.staged);
        self.staged.append(&mut png.staged);
        Ok(())
    }

    /// Writes one file with `write_to` into a temporary file beside `path`, flushes it, and checks it with
    /// `verify` (why it is wrong, or `Ok`). On failure the temporary file is removed; when the file system is full
    /// (a small file cannot be written beside it either) the error is the operating system's.
    pub(crate) fn stage_with(
        &mut self,
        path: &Path,
        write_to: impl FnOnce(&Path) -> Result<(), OiioError>,
        verify: impl FnOnce(&Path) -> Result<(), String>,
    ) -> Result<(), ImageError> {
        if path.is_dir() {
            return Err(ImageError::invalid(path, "is a directory"));
        }
        self.check_not_staged(path)?;
        let temp = atomic_file::temp_beside(path)
            .map_err(|e| ImageError::io(path, e.context, e.source))?;
        let written = write_to(temp.path()).map_err(|source| ImageError::Oiio {
            path: path.to_path_buf(),
            context: "openimageio cannot write it".to_owned(),
            source,
        });
        let checked = written.and_then(|()| {
            atomic_file::sync(temp.path())
                .map_err(|e| ImageError::io(path, e.context, e.source))?;
            verify(temp.path())
                .map_err(|m| ImageError::invalid(path, format!("the written file is wrong: {m}")))
        });
        if let Err(e) = checked {
            // An OS error from a full or failing disk explains the failure better than a writer that lost it.
            return Err(match atomic_file::probe_space(temp.path()) {
                Err(os) => ImageError::io(path, "cannot write", os),
                Ok(()) => e,
            });
        }
        self.staged.push((temp, path.to_path_buf()));
        Ok(())
    }

    /// An error if `path` is a target already staged, however spelled (a dumped shadow map named like the frame
    /// was lost to it).
    fn check_not_staged(&self, path: &Path) -> Result<(), ImageError> {
        if self
            .staged
            .iter()
            .any(|(_, p)| crate::util::input_file::same_target(p, path))
        {
            return Err(ImageError::invalid(path, "is written twice in one run"));
        }
        Ok(())
    }

    /// The targets staged so far.
    pub fn paths(&self) -> Vec<&Path> {
        self.staged.iter().map(|(_, p)| p.as_path()).collect()
    }

    /// Renames every staged file into place (and syncs their directories) as a unit; returns their paths. The
    /// targets that exist are first moved aside; if any rename fails, those already made are undone and the old
    /// files put back, so a frame's EXR and its preview are replaced both or neither (a failed PNG rename left the
    /// new EXR beside the old PNG). A second signal's exit waits for it to end ([`atomic_file::commit_lock`]).
    pub fn commit(self) -> Result<Vec<PathBuf>, ImageError> {
        let _together = atomic_file::commit_lock();
        let mut aside: Vec<(PathBuf, Option<tempfile::TempPath>)> = Vec::new();
        for (_, path) in &self.staged {
            let backup = if path.exists() {
                let slot = atomic_file::temp_beside(path)
                    .map_err(|e| ImageError::io(path, e.context, e.source))?
                    .into_temp_path();
                if let Err(e) = std::fs::rename(path, &slot) {
                    restore(&mut aside);
                    return Err(ImageError::io(path, "cannot move the old file aside", e));
                }
                Some(slot)
            } else {
                None
            };
            aside.push((path.clone(), backup));
        }
        let mut done = Vec::with_capacity(self.staged.len());
        for (temp, path) in self.staged {
            if let Err(e) = atomic_file::persist(temp, &path) {
                for made in &done {
                    let _ = std::fs::remove_file(made);
                }
                restore(&mut aside);
                return Err(ImageError::io(&path, e.context, e.source));
            }
            done.push(path);
        }
        // The old files, moved aside, are removed as their temporary paths drop.
        drop(aside);
        Ok(done)
    }
}

/// Puts the files moved aside by [`Outputs::commit`] back in place.
fn restore(aside: &mut Vec<(PathBuf, Option<tempfile::TempPath>)>) {
    for (path, backup) in aside.drain(..) {
        if let Some(slot) = backup {
            // Keeping the temporary path from deleting the file it names once it is back in place.
            let _ = std::fs::rename(&slot, &path);
            let _ = slot.keep();
        }
    }
}

/// Why the EXR at `temp` does not hold `image` (every channel by name, bit for bit) at `window`, or `Ok`.
fn verify_exr(temp: &Path, image: &Image, window: Option<Window>) -> Result<(), String> {
    let file = oiio::open_image(temp).map_err(|e| e.message)?;
    if let Some(w) = window {
        if file.window() != w {
            return Err(format!("data window {:?}, meant {w:?}", file.window()));
        }
    }
    let back = file.read().map_err(|e| e.message)?;
    if (back.width, back.height) != (image.width, image.height) {
        return Err(format!(
            "reads back as {}x{}, meant {}x{}",
            back.width, back.height, image.width, image.height
        ));
    }
    let (n, m) = (image.channels.len(), back.channels.len());
    if n != m {
        return Err(format!("reads back with {m} channels, meant {n}"));
    }
    for (c, name) in image.channels.iter().enumerate() {
        let b = back
            .channels
            .iter()
            .position(|x| x == name)
            .ok_or_else(|| format!("channel {name} is missing"))?;
        let same = image
            .data
            .chunks_exact(n)
            .zip(back.data.chunks_exact(m))
            .all(|(p, q)| p[c].to_bits() == q[b].to_bits());
        if !same {
            return Err(format!("channel {name} reads back different"));
        }
    }
    Ok(())
}

/// Why the 8-bit file at `temp` does not hold `bytes` (`width` × `height`, interleaved RGB), or `Ok`.
pub(super) fn verify_u8(
    temp: &Path,
    width: usize,
    height: usize,
    bytes: &[u8],
) -> Result<(), String> {
    let back = oiio::read_image(temp).map_err(|e| e.message)?;
    if (back.width, back.height, back.data.len()) != (width, height, bytes.len()) {
        return Err(format!(
            "reads back as {}x{} with {} values, meant {width}x{height} with {}",
            back.width,
            back.height,
            back.data.len(),
            bytes.len()
        ));
    }
    if back
        .data
        .iter()
        .zip(bytes)
        .any(|(v, b)| (v * 255.0).round() != f32::from(*b))
    {
        return Err("pixels read back different".to_owned());
    }
    Ok(())
}
