//! A walk over a `.usdc` (crate) file's structure before openusd opens it: openusd 0.6 allocates the tables of the
//! structural sections at the sizes the file declares (a token table of 9 PB from a 10 KB file, found by
//! `fuzz/`'s `usd` target), so those sizes are checked here against the file first.
//!
//! The layout (Pixar's `crateFile.cpp`, as openusd reads it, versions 0.4 and later): a 32-byte bootstrap
//! (`PXR-USDC`, version, offset of the table of contents), the table of contents (a count, then 32-byte sections:
//! a 16-byte name, start, size), and sections that each begin with their counts and then LZ4 blocks, each an 8-byte
//! compressed size and that many bytes. The walk reads only those counts and sizes (a few dozen 8-byte reads).
//!
//! What it checks: the table of contents and every section lie in the file; every compressed block of the
//! structural sections lies in its file; a token table's uncompressed size is within LZ4's largest expansion
//! (255 output bytes per input byte) of its compressed size; and the bytes openusd allocates from the declared
//! counts stay under [`MAX_EXPANSION`] times the file's size plus [`SLACK_BYTES`]. The value arrays (points,
//! widths) are read later, with counts of their own, and are not walked here.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

/// The bootstrap's magic.
const MAGIC: &[u8; 8] = b"PXR-USDC";

/// How many times a file's size the structural tables may take in memory (with [`SLACK_BYTES`]): their counts
/// are stored delta-coded and LZ4-compressed, so regular tables (path indices 0, 1, 2, …) expand far beyond
/// the file, but a file whose tables declare more than this is refused as malformed.
pub(super) const MAX_EXPANSION: u64 = 64;

/// Memory any file's structural tables may take whatever its size: 256 MiB, far beyond a groom's (a 10⁵-strand
/// `.usdc` has a few dozen prims and fields).
pub(super) const SLACK_BYTES: u64 = 256 << 20;

/// LZ4's largest expansion: a match's length continues in bytes of 255 each.
const LZ4_EXPANSION: u64 = 255;

/// Bytes openusd holds per element of each table beyond its encoded integers (its structs: a token's `String`, a
/// field's index and value representation, a path, a spec), taken generously.
const PER_ELEMENT: u64 = 64;

/// Whether `path` is a crate file (its first bytes are [`MAGIC`], whatever its extension: a `.usd` may be either).
pub(super) fn is_crate(path: &Path) -> bool {
    let mut magic = [0u8; 8];
    File::open(path)
        .and_then(|mut f| f.read_exact(&mut magic))
        .is_ok()
        && &magic == MAGIC
}

/// The crate file's bytes, read at offsets.
struct Crate {
    file: File,
    len: u64,
}

impl Crate {
    /// The `N` bytes at `offset`, which must lie in the file.
    fn bytes<const N: usize>(&mut self, offset: u64) -> Result<[u8; N], String> {
        if offset
            .checked_add(N as u64)
            .is_none_or(|end| end > self.len)
        {
            return Err(format!(
                "{N} bytes at byte {offset} lie past the end of the file ({} bytes)",
                self.len
            ));
        }
        let mut b = [0u8; N];
        self.file
            .seek(SeekFrom::Start(offset))
            .and_then(|_| self.file.read_exact(&mut b))
            .map_err(|e| e.to_string())?;
        Ok(b)
    }

    /// The little-endian u64 at `offset`.
    fn u64_at(&mut self, offset: u64) -> Result<u64, String> {
        self.bytes::<8>(offset).map(u64::from_le_bytes)
    }
}

/// Walks the crate file at `path` (see the module doc); `Err` says what is wrong, for the reader to name the file.
pub(super) fn check(path: &Path) -> Result<(), String> {
    let file = File::open(path).map_err(|e| e.to_string())?;
    let len = file.metadata().map_err(|e| e.to_string())?.len();
    let mut c = Crate { file, len };
    if len < 32 {
        return Err(format!(
            "{len} bytes is shorter than a crate file's 32-byte header"
        ));
    }
    let toc = c.u64_at(16)?;
    let sections = c.u64_at(toc)?;
    if !(1..64).contains(&sections) {
        return Err(format!(
            "{sections} sections in the table of contents (1 to 63 expected)"
        ));
    }
    if toc + 8 + 32 * sections > len {
        return Err(format!(
            "the table of contents at byte {toc} ({sections} sections) runs past the end of the file ({len} bytes)"
        ));
    }
    let mut declared = 0u64;
    for k in 0..sections {
        let entry = toc + 8 + 32 * k;
        let name: [u8; 16] = c.bytes(entry)?;
        let (start, size) = (c.u64_at(entry + 16)?, c.u64_at(entry + 24)?);
        if start.checked_add(size).is_none_or(|end| end > len) {
            return Err(format!(
                "section {} ({start} + {size} bytes) runs past the end of the file ({len} bytes)",
                section_name(&name)
            ));
        }
        // Each structural section: its leading counts, then its LZ4 blocks.
        let (counts, blocks): (u64, u64) = match section_name(&name).as_str() {
            "TOKENS" => {
                let (count, uncompressed, compressed) = (
                    c.u64_at(start)?,
                    c.u64_at(start + 8)?,
                    c.u64_at(start + 16)?,
                );
                if compressed > len - (start + 24) {
                    return Err(format!("the token table's {compressed} compressed bytes run past the end of the file"));
                }
                if uncompressed > LZ4_EXPANSION.saturating_mul(compressed).saturating_add(16) {
                    return Err(format!(
                        "the token table declares {uncompressed} bytes from {compressed} compressed bytes, more than \
                         LZ4 can expand them to"
                    ));
                }
                declared = declared
                    .saturating_add(uncompressed)
                    .saturating_add(compressed)
                    .saturating_add(count.saturating_mul(PER_ELEMENT));
                continue;
            }
            "STRINGS" => {
                let count = c.u64_at(start)?;
                if count.saturating_mul(4) > size {
                    return Err(format!(
                        "{count} strings do not fit their {size}-byte section"
                    ));
                }
                declared = declared.saturating_add(count.saturating_mul(12));
                continue;
            }
            "FIELDS" => (1, 2),
            "FIELDSETS" => (1, 1),
            "PATHS" => (2, 3),
            "SPECS" => (1, 3),
            _ => continue,
        };
        let mut pos = start;
        for _ in 0..counts {
            // Each count is held as encoded integers (4 bytes each, and a code) and as the table's elements.
            declared = declared.saturating_add(c.u64_at(pos)?.saturating_mul(4 + 1 + PER_ELEMENT));
            pos += 8;
        }
        for _ in 0..blocks {
            let compressed = c.u64_at(pos)?;
            if compressed > len - (pos + 8) {
                return Err(format!(
                    "section {}: a block of {compressed} compressed bytes at byte {pos} runs past the end of the file",
                    section_name(&name)
                ));
            }
            declared = declared.saturating_add(compressed);
            pos += 8 + compressed;
        }
    }
    let allowed = MAX_EXPANSION
        .saturating_mul(len)
        .saturating_add(SLACK_BYTES);
    if declared > allowed {
        return Err(format!(
            "its tables declare about {declared} bytes, more than {MAX_EXPANSION} times the file's {len} bytes (plus \
             {SLACK_BYTES}): a malformed or hostile file"
        ));
    }
    Ok(())
}

/// A section's name up to its first NUL.
fn section_name(name: &[u8; 16]) -> String {
    let end = name.iter().position(|&b| b == 0).unwrap_or(16);
    String::from_utf8_lossy(&name[..end]).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn groom() -> Vec<u8> {
        std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/usd/groom.usdc"))
            .unwrap()
    }

    /// `bytes` with the u64 at `offset` set to `value`.
    fn with(mut bytes: Vec<u8>, offset: usize, value: u64) -> Vec<u8> {
        bytes[offset..offset + 8].copy_from_slice(&value.to_le_bytes());
        bytes
    }

    /// The offset of section `name`'s start in `bytes`' table of contents.
    fn section_start(bytes: &[u8], name: &str) -> usize {
        let u = |o: usize| u64::from_le_bytes(bytes[o..o + 8].try_into().unwrap()) as usize;
        let toc = u(16);
        (0..u(toc))
            .map(|k| toc + 8 + 32 * k)
            .find(|&e| bytes[e..e + 16].starts_with(name.as_bytes()) && bytes[e + name.len()] == 0)
            .map(|e| u(e + 16))
            .unwrap()
    }

    fn checked(bytes: &[u8]) -> Result<(), String> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.usdc");
        std::fs::write(&path, bytes).unwrap();
        assert!(is_crate(&path));
        check(&path)
    }

    #[test]
    fn a_crate_file_passes_and_its_declared_sizes_are_held_to_the_file() {
        let good = groom();
        assert_eq!(checked(&good), Ok(()));
        let tokens = section_start(&good, "TOKENS");
        // A token table claiming more than LZ4 can expand its compressed bytes to.
        let huge = with(good.clone(), tokens + 8, 1 << 40);
        assert!(checked(&huge)
            .unwrap_err()
            .contains("more than LZ4 can expand"));
        // Compressed bytes past the end of the file (the fuzzer's 9 PB table was one).
        let past = with(good.clone(), tokens + 16, 1 << 50);
        assert!(checked(&past).unwrap_err().contains("run past the end"));
        // A paths table declaring 2^40 paths: more than the file's tables may take.
        let paths = with(good.clone(), section_start(&good, "PATHS"), 1 << 40);
        assert!(checked(&paths).unwrap_err().contains("tables declare"));
        // A table of contents past the end, and a truncated file.
        assert!(checked(&with(good.clone(), 16, good.len() as u64)).is_err());
        assert!(checked(&good[..good.len() / 2]).is_err());
        assert!(checked(&good[..20]).unwrap_err().contains("32-byte header"));
    }
}
