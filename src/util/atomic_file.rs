//! Files written whole or not at all, through [`tempfile`]: the content goes into a new temporary file in the
//! target's directory (so the same file system), is flushed to disk, then renamed over the target. A reader never
//! sees half a file; on any failure the temporary file is removed (a [`NamedTempFile`] deletes itself when dropped
//! unpersisted) and the target is left as it was.
//!
//! Temporary names are hidden and keep the target's extension, `.<name>.tmp-<random>.<ext>`: OpenImageIO picks the
//! format of a file it writes from the extension. Used by [`crate::image`] (images), [`crate::plot`] (SVG charts)
//! and [`crate::study::cache`] (CSV tables).
//!
//! **Signals.** Every temporary file of the process is listed while it exists ([`TempFile`]), so that a second
//! SIGINT/SIGTERM, which ends the process at once ([`crate::farm::catch_signals`]), removes them first
//! ([`remove_temporaries_and_exit`]): ending in the signal handler itself left `.tmp-*` files beside the outputs.
//! A set of renames that must happen all or none (a frame's EXR and its preview) runs under [`commit_lock`], which
//! the exit waits for.

use std::ffi::OsString;
use std::fs::File;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

use tempfile::{Builder, NamedTempFile, TempPath};

/// The temporary files of this process that exist now (created, not yet renamed into place or removed).
static LIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Held while renames that must happen together run, and by the exit of [`remove_temporaries_and_exit`].
static COMMIT: Mutex<()> = Mutex::new(());

/// `mutex` locked, whether or not a thread panicked while holding it (the lists stay valid: every change is one
/// push or one removal).
fn lock<T>(mutex: &'static Mutex<T>) -> MutexGuard<'static, T> {
    mutex
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Renames that must happen all or none run while the guard lives: a second signal's exit waits for them
/// ([`remove_temporaries_and_exit`]), so it never falls between a frame's EXR and its preview.
pub fn commit_lock() -> MutexGuard<'static, ()> {
    lock(&COMMIT)
}

/// Removes every temporary file of the process and ends it at once with `status`, without running exit handlers
/// (other threads may still be rendering). Waits for a commit in progress ([`commit_lock`]) first. This is the
/// second SIGINT/SIGTERM's action.
pub fn remove_temporaries_and_exit(status: i32) -> ! {
    let _commit = lock(&COMMIT);
    let live = lock(&LIVE);
    for path in live.iter() {
        let _ = std::fs::remove_file(path);
    }
    signal_hook::low_level::exit(status)
}

/// A temporary file listed in the process's live temporaries while it exists: removed when dropped unless
/// [`persist`]ed, and by [`remove_temporaries_and_exit`].
#[derive(Debug)]
pub struct TempFile {
    // `Some` until the file is renamed into place, handed on as a [`TempPath`], or dropped.
    file: Option<NamedTempFile>,
}

impl TempFile {
    /// Creates the file with `builder` in `dir` and lists it (one step under the list's lock, so a second signal
    /// never sees the file exist unlisted).
    fn create(builder: &Builder<'_, '_>, dir: &Path) -> io::Result<TempFile> {
        let mut live = lock(&LIVE);
        let file = builder.tempfile_in(dir)?;
        live.push(file.path().to_path_buf());
        Ok(TempFile { file: Some(file) })
    }

    fn file(&self) -> &NamedTempFile {
        self.file.as_ref().expect("present until consumed")
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        self.file().path()
    }

    /// The open file.
    pub fn as_file(&self) -> &File {
        self.file().as_file()
    }

    /// The file as a [`TempPath`] (removed when dropped), no longer listed: for a slot used only under
    /// [`commit_lock`], which a second signal's exit waits for.
    pub fn into_temp_path(mut self) -> TempPath {
        let file = self.file.take().expect("present until consumed");
        unlist(file.path());
        file.into_temp_path()
    }
}

impl Write for TempFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.file
            .as_mut()
            .expect("present until consumed")
            .write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.file.as_mut().expect("present until consumed").flush()
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        if let Some(file) = self.file.take() {
            let path = file.path().to_path_buf();
            // Removed first, then unlisted: a second signal between the two finds the path gone, no harm.
            drop(file);
            unlist(&path);
        }
    }
}

/// Takes `path` off the live list.
fn unlist(path: &Path) {
    let mut live = lock(&LIVE);
    if let Some(i) = live.iter().rposition(|p| p == path) {
        live.swap_remove(i);
    }
}

/// A step of an atomic write failed. The caller names the target file (see [`crate::image::ImageError`]).
#[derive(Debug, thiserror::Error)]
#[error("{context}: {source}")]
pub struct WriteError {
    /// What was being done, lower case.
    pub context: &'static str,
    /// The I/O error.
    #[source]
    pub source: io::Error,
}

fn fail(context: &'static str) -> impl FnOnce(io::Error) -> WriteError {
    move |source| WriteError { context, source }
}

/// The longest file name (bytes) of the file systems cuticle writes to (ext4, XFS, Btrfs, tmpfs).
const MAX_NAME_BYTES: usize = 255;

/// tempfile's random characters in a name (its default).
const RANDOM_CHARS: usize = 6;

/// `name`'s first `room` bytes (all of it if it fits).
fn cut_name(name: &std::ffi::OsStr, room: usize) -> OsString {
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStrExt;
        let bytes = name.as_bytes();
        std::ffi::OsStr::from_bytes(&bytes[..bytes.len().min(room)]).to_os_string()
    }
    #[cfg(not(unix))]
    {
        let _ = room;
        name.to_os_string()
    }
}

/// A new, empty temporary file beside `path` (see the [module docs](self)), removed when dropped unless
/// [`persist`]ed.
pub fn temp_beside(path: &Path) -> Result<TempFile, WriteError> {
    let name = path.file_name().ok_or_else(|| WriteError {
        context: "not a file name",
        source: io::Error::from(io::ErrorKind::InvalidInput),
    })?;
    let dir = parent(path);
    let mut suffix = OsString::new();
    if let Some(extension) = path.extension() {
        suffix.push(".");
        suffix.push(extension);
    }
    // The temporary name must fit the file system's 255 bytes where the target's does: the target's name is cut
    // (byte for byte) to leave room for the dot, ".tmp-", tempfile's 6 random characters and the suffix.
    let room = MAX_NAME_BYTES.saturating_sub(1 + 5 + RANDOM_CHARS + suffix.len());
    let mut prefix = OsString::from(".");
    prefix.push(cut_name(name, room));
    prefix.push(".tmp-");
    let mut builder = Builder::new();
    builder
        .prefix(&prefix)
        .suffix(&suffix)
        .rand_bytes(RANDOM_CHARS);
    // tempfile creates owner-only files (0600); the target gets the permissions of a plain new file (0666 less
    // the umask), as before the rename.
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
    TempFile::create(&builder, dir).map_err(fail("cannot create a temporary file in its directory"))
}

/// Flushes what was written to `temp` (through its path: a writer may have replaced the file) to disk, renames
/// it over `path`, and syncs the directory so the rename itself survives a crash. On failure `temp` is removed.
pub fn persist(mut temp: TempFile, path: &Path) -> Result<(), WriteError> {
    sync(temp.path())?;
    let file = temp.file.take().expect("present until consumed");
    let name = file.path().to_path_buf();
    // On failure the file comes back in the error and is removed as it drops, before it is unlisted.
    let renamed = file
        .persist(path)
        .map(drop)
        .map_err(|e| fail("cannot rename the temporary file over it")(e.error));
    unlist(&name);
    renamed?;
    sync_dir(parent(path))
}

/// Flushes the file at `path` to disk.
pub fn sync(path: &Path) -> Result<(), WriteError> {
    File::open(path)
        .and_then(|f| f.sync_all())
        .map_err(fail("cannot flush the written file to disk"))
}

/// Flushes the directory `dir` (its entries: a rename or a new name) to disk.
pub fn sync_dir(dir: &Path) -> Result<(), WriteError> {
    #[cfg(unix)]
    {
        File::open(dir)
            .and_then(|d| d.sync_all())
            .map_err(fail("cannot flush its directory to disk"))
    }
    #[cfg(not(unix))]
    {
        // Directories cannot be opened as files elsewhere; the rename is as durable as the platform makes it.
        let _ = dir;
        Ok(())
    }
}

/// Bytes [`probe_space`] writes.
const PROBE_BYTES: usize = 64 * 1024;

/// Whether a small file (64 KiB) can still be written and flushed beside `path`: the operating system's error
/// (e.g. "No space left on device") when not. Used to explain a writer that failed, or lost the error.
pub fn probe_space(path: &Path) -> io::Result<()> {
    let mut probe = TempFile::create(Builder::new().prefix(".cuticle-probe.tmp-"), parent(path))?;
    probe.write_all(&[0u8; PROBE_BYTES])?;
    probe.as_file().sync_all()
}

/// The directory of `path` (`.` for a bare file name).
fn parent(path: &Path) -> &Path {
    match path.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir,
        _ => Path::new("."),
    }
}

/// Writes `bytes` to `path` atomically.
pub fn write(path: &Path, bytes: &[u8]) -> Result<(), WriteError> {
    let mut temp = temp_beside(path)?;
    temp.write_all(bytes).map_err(fail("cannot write"))?;
    persist(temp, path)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn listing(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn temporary_names_are_hidden_beside_the_target_and_keep_the_extension() {
        let dir = tempfile::tempdir().unwrap();
        let temp = temp_beside(&dir.path().join("frame.exr")).unwrap();
        let name = temp.path().file_name().unwrap().to_string_lossy();
        assert!(
            name.starts_with(".frame.exr.tmp-") && name.ends_with(".exr"),
            "{name}"
        );
        assert_eq!(temp.path().parent(), Some(dir.path()));
        drop(temp);
        assert!(listing(dir.path()).is_empty(), "removed when dropped");
    }

    /// A target whose name is as long as the file system allows (255 bytes) still gets a temporary file, its name
    /// cut to fit: a 249-byte name failed ("File name too long") with the temporary name at 265 bytes.
    #[test]
    fn the_longest_legal_names_get_a_temporary_file_that_fits() {
        let dir = tempfile::tempdir().unwrap();
        for len in [200, 249, 255] {
            let name = format!("{}.exr", "n".repeat(len - 4));
            let target = dir.path().join(&name);
            write(&target, b"x").unwrap_or_else(|e| panic!("{len}: {e}"));
            assert_eq!(std::fs::read(&target).unwrap(), b"x");
            let temp = temp_beside(&target).unwrap();
            let temp_name = temp.path().file_name().unwrap().len();
            assert!(temp_name <= 255, "{len}: {temp_name}");
        }
    }

    #[test]
    fn write_replaces_the_target_and_leaves_nothing_else() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("table.csv");
        write(&path, b"old").unwrap();
        write(&path, b"new").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"new");
        assert_eq!(listing(dir.path()), ["table.csv"]);
    }

    #[cfg(unix)]
    #[test]
    fn the_target_gets_the_permissions_of_a_plain_new_file() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let plain = dir.path().join("plain.txt");
        std::fs::write(&plain, "x").unwrap();
        let path = dir.path().join("table.csv");
        write(&path, b"x").unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode();
        assert_eq!(mode(&path), mode(&plain));
    }

    #[test]
    fn a_failed_rename_removes_the_temporary_file_and_keeps_the_target() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("table.csv");
        std::fs::create_dir(&path).unwrap();
        std::fs::write(path.join("inside"), "kept").unwrap();
        let err = write(&path, b"new").unwrap_err();
        assert_eq!(err.context, "cannot rename the temporary file over it");
        assert_eq!(listing(dir.path()), ["table.csv"]);
        assert!(path.join("inside").is_file());
    }

    #[test]
    fn a_missing_directory_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let err = write(&dir.path().join("missing").join("table.csv"), b"x").unwrap_err();
        assert_eq!(err.source.kind(), io::ErrorKind::NotFound, "{err}");
        assert!(listing(dir.path()).is_empty());
    }
}
