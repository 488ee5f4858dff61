//! Reading files a user names, without letting the file exhaust the machine: only regular files are opened for
//! reading (a FIFO would block forever, `/dev/zero` never ends, a directory is not data), the size the file system
//! reports is checked against the caller's bound before anything is allocated, and the read itself stops at the
//! bound (a file that grows while it is read cannot make it grow without limit).
//!
//! Errors are [`io::Error`]s whose message says what is wrong with the file; the caller names the file once.

use std::fs::File;
use std::io::{self, Read};
use std::path::Path;

/// Opens `path` for reading if it is a regular file (symbolic links followed), and returns it with its size in
/// bytes. A FIFO, a character device (`/dev/zero`), a socket or a directory is an [`io::ErrorKind::InvalidInput`]
/// error naming the kind of file.
pub fn open_regular(path: &Path) -> io::Result<(File, u64)> {
    // Checked on the path before opening: opening a FIFO for reading blocks until a writer appears.
    let meta = std::fs::metadata(path)?;
    check_kind(&meta)?;
    let file = File::open(path)?;
    // Checked again on the open handle: the path may have been replaced in between.
    let meta = file.metadata()?;
    check_kind(&meta)?;
    Ok((file, meta.len()))
}

/// A header-first file: the regular file `path` opened ([`open_regular`]), its size, and its first `head_len`
/// bytes (fewer when the file is shorter), so a reader can check the header's declared sizes against the file's
/// before reading the rest ([`read_rest`]).
pub fn open_with_head(path: &Path, head_len: usize) -> io::Result<(File, u64, Vec<u8>)> {
    let (mut file, len) = open_regular(path)?;
    let mut head = Vec::with_capacity(head_len);
    (&mut file).take(head_len as u64).read_to_end(&mut head)?;
    Ok((file, len, head))
}

/// `head` followed by the rest of `file`, whose whole size was `len` when opened ([`open_with_head`]): at most
/// `len − head.len()` more bytes are read, so a file that grew since is an error, not an unbounded read.
pub fn read_rest(file: File, mut head: Vec<u8>, len: u64) -> io::Result<Vec<u8>> {
    let rest_len = len.saturating_sub(head.len() as u64);
    head.extend_from_slice(&read_at_most(file, rest_len, rest_len)?);
    Ok(head)
}

fn check_kind(meta: &std::fs::Metadata) -> io::Result<()> {
    let t = meta.file_type();
    if t.is_file() {
        return Ok(());
    }
    let kind = if t.is_dir() {
        "a directory"
    } else {
        kind_of_special(&t)
    };
    Err(io::Error::new(
        io::ErrorKind::InvalidInput,
        format!("is {kind}, not a regular file"),
    ))
}

#[cfg(unix)]
fn kind_of_special(t: &std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if t.is_fifo() {
        "a named pipe (FIFO)"
    } else if t.is_char_device() {
        "a character device"
    } else if t.is_block_device() {
        "a block device"
    } else if t.is_socket() {
        "a socket"
    } else {
        "a special file"
    }
}

#[cfg(not(unix))]
fn kind_of_special(_: &std::fs::FileType) -> &'static str {
    "a special file"
}

/// A human-readable size: "16 MiB", "1.5 GiB", "512 bytes".
pub fn human_bytes(n: u64) -> String {
    const UNITS: [&str; 4] = ["KiB", "MiB", "GiB", "TiB"];
    if n < 1024 {
        return format!("{n} bytes");
    }
    let mut v = n as f64 / 1024.0;
    let mut unit = 0;
    while v >= 1024.0 && unit + 1 < UNITS.len() {
        v /= 1024.0;
        unit += 1;
    }
    if v.fract() == 0.0 {
        format!("{v} {}", UNITS[unit])
    } else {
        format!("{v:.1} {}", UNITS[unit])
    }
}

/// The whole of the regular file `path`, refused before it is read when it is larger than `max_bytes`.
pub fn read_bounded(path: &Path, max_bytes: u64) -> io::Result<Vec<u8>> {
    let (file, len) = open_regular(path)?;
    if len > max_bytes {
        return Err(too_big(len, max_bytes));
    }
    read_at_most(file, len, max_bytes)
}

/// The whole of `file` (whose size was `len` when checked), reading at most `max_bytes`: a file that grew past the
/// bound since is an error, not an unbounded read.
pub fn read_at_most(file: impl Read, len: u64, max_bytes: u64) -> io::Result<Vec<u8>> {
    // `len` is at most `max_bytes`, which callers keep far below usize::MAX.
    let mut bytes = Vec::with_capacity(len.min(max_bytes) as usize);
    file.take(max_bytes.saturating_add(1))
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > max_bytes {
        return Err(too_big(bytes.len() as u64, max_bytes));
    }
    Ok(bytes)
}

/// The UTF-8 text of the regular file `path`, refused when larger than `max_bytes`.
pub fn read_text_bounded(path: &Path, max_bytes: u64) -> io::Result<String> {
    let bytes = read_bounded(path, max_bytes)?;
    String::from_utf8(bytes).map_err(|e| {
        io::Error::new(
            io::ErrorKind::InvalidData,
            format!(
                "is not UTF-8 text (invalid byte at offset {})",
                e.utf8_error().valid_up_to()
            ),
        )
    })
}

fn too_big(len: u64, max_bytes: u64) -> io::Error {
    io::Error::new(
        io::ErrorKind::InvalidData,
        format!(
            "is {} ({len} bytes), more than the {} this kind of file may have",
            human_bytes(len),
            human_bytes(max_bytes)
        ),
    )
}

/// Whether two paths name the same target, however spelled: equal, the same existing file ([`same_file`]), or the
/// same absolute path with `.` components gone (for files not written yet).
pub fn same_target(a: &Path, b: &Path) -> bool {
    a == b
        || same_file(a, b)
        || matches!(
            (std::path::absolute(a), std::path::absolute(b)),
            (Ok(x), Ok(y)) if x == y
        )
}

/// Whether `a` and `b` name the same existing file, however spelled (`sc.toml`, `./sc.toml`, a link): the same
/// device and inode on Unix, the same canonical path elsewhere. False when either does not exist.
pub fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        match (std::fs::metadata(a), std::fs::metadata(b)) {
            (Ok(x), Ok(y)) => x.dev() == y.dev() && x.ino() == y.ino(),
            _ => false,
        }
    }
    #[cfg(not(unix))]
    {
        match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
            (Ok(x), Ok(y)) => x == y,
            _ => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn directories_and_devices_are_refused_by_kind() {
        let e = open_regular(Path::new(".")).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidInput);
        assert!(e.to_string().contains("a directory"), "{e}");
        #[cfg(unix)]
        {
            let e = read_bounded(Path::new("/dev/zero"), 1 << 20).unwrap_err();
            assert!(e.to_string().contains("character device"), "{e}");
        }
    }

    #[test]
    fn a_file_over_the_bound_is_refused_and_one_at_it_is_read() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f");
        std::fs::write(&path, [7u8; 100]).unwrap();
        assert_eq!(read_bounded(&path, 100).unwrap().len(), 100);
        let e = read_bounded(&path, 99).unwrap_err().to_string();
        assert!(e.contains("100 bytes") && e.contains("99 bytes"), "{e}");
        // A reader longer than its stated length stops one byte past the bound.
        let e = read_at_most(&[0u8; 1000][..], 10, 50)
            .unwrap_err()
            .to_string();
        assert!(e.contains("51 bytes"), "{e}");
    }

    #[test]
    fn sizes_read_in_binary_units() {
        assert_eq!(human_bytes(512), "512 bytes");
        assert_eq!(human_bytes(16 << 20), "16 MiB");
        assert_eq!(human_bytes(3 << 29), "1.5 GiB");
    }
}
