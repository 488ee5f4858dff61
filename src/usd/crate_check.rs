//! A walk over a `.usdc` (crate) file before openusd opens it: openusd 0.6 allocates what the file declares (a
//! token table of 9 PB from a 10 KB file, a token array of more than a terabyte: both found by `fuzz/`'s `usd`
//! target), and an allocation that fails aborts the process, so every size it allocates from is held to the file
//! here first, as are its recursion and loops. A `.usdz`'s crate files are walked the same way, each in its byte
//! range of the package.
//!
//! The layout (Pixar's `crateFile.cpp`, as openusd reads it, versions 0.4 and later): a 32-byte bootstrap
//! (`PXR-USDC`, version, offset of the table of contents), the table of contents (a count, then 32-byte sections:
//! a 16-byte name, start, size), and sections that each begin with their counts and then compressed blocks, each an
//! 8-byte compressed size and that many bytes (a chunk count, 0, then one LZ4 block). Integer tables are LZ4 blocks
//! of Pixar's integer coding (`integerCoding.cpp`: a common value, a 2-bit code per integer, then the deltas that
//! are not the common one, 1, 2 or 4 bytes each). The FIELDS section's last block holds every field's value
//! representation (8 bytes: a type in bits 48–55, the flags array, inlined and compressed in bits 63, 62, 61, and a
//! 48-bit payload, the offset in the file of a value that is not inlined). At that offset an array is a count (u32
//! before version 0.7, u64 from it; a u32 shape before it, before 0.5) and that many elements, or, compressed (ints
//! from 0.5, floats from 0.6, at least 4 elements), a compressed block of the integer coding (floats: a code `i`
//! before it, or `t`, a u32 count and a lookup table of that many floats); lists of tokens, strings or paths are a
//! u64 count and u32 indices; list operations a header byte and up to six such lists; dictionaries and time samples
//! hold relative offsets to further value representations.
//!
//! What is checked, before openusd allocates from it:
//! - **structure**: the table of contents and every section lie in the file, and so does every compressed block of
//!   the structural sections; the token table's uncompressed size is within LZ4's largest expansion (255 bytes per
//!   byte) of its compressed size;
//! - **path tree**: decoded as openusd builds it (token indices, jumps to siblings), counting the length of every
//!   path string it builds and copies; an entry reached twice is refused (openusd would build its subtree again
//!   for every way to reach it, exponentially often);
//! - **values**: every field's value as openusd reads it ([`Values`]): each count it allocates from, times the
//!   element's size in the file, lies in the file after it; a compressed array's compressed bytes lie in the file
//!   and its count is within what they can decode to (LZ4's 255 times, 4 integers per code byte); nesting stops at
//!   [`MAX_DEPTH`] (openusd recurses, one stack frame per level, and a dictionary holding itself overflows the
//!   stack), and the values read at one per field and per 8 bytes of the file, plus [`MAX_VALUES`] (a dictionary
//!   whose entries lead back to themselves loops for its count);
//! - **memory**: what openusd allocates from all of it (tables, path strings, every value read once, with a copy of
//!   the text of every token, string and path a value holds, each taken at the longest) stays under
//!   [`MAX_EXPANSION`] times the file's size plus [`SLACK_BYTES`].
//!
//! What is left to openusd: anything it fails to decode (a wrong code, a block that does not decompress, an index
//! out of range: it reports or panics, and `usd::read` catches the panic), and whatever it reads without allocating
//! from a count. Layers the stage composes from other files (sublayers, references, payloads) are opened by
//! openusd without this walk.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

mod values;

use values::Values;

/// The bootstrap's magic.
const MAGIC: &[u8; 8] = b"PXR-USDC";

/// How many times a file's size what openusd allocates from it may take (with [`SLACK_BYTES`]): counts are stored
/// delta-coded and LZ4-compressed, so regular tables (path indices 0, 1, 2, …) expand far beyond the file, but a
/// file that declares more than this is refused as malformed.
pub(super) const MAX_EXPANSION: u64 = 64;

/// Memory any file's tables and values may take whatever its size: 256 MiB, far beyond a small groom's (a
/// 10⁵-strand `.usdc` has a few dozen prims and fields).
pub(super) const SLACK_BYTES: u64 = 256 << 20;

/// LZ4's largest expansion: a match's length continues in bytes of 255 each.
const LZ4_EXPANSION: u64 = 255;

/// Bytes openusd holds per element of each table beyond its encoded integers (its structs: a token's `String`, a
/// field's index and value representation, a path, a spec), taken generously.
const PER_ELEMENT: u64 = 64;

/// Bytes openusd holds per object a value decodes into (a `String`, token, path, asset path, reference, payload,
/// `sdf::Value`, dictionary entry, time sample), besides the text it copies: at least the largest of them (160
/// bytes, an `sdf::Value`; checked by a test), with room for a map's or list's own overhead.
const PER_OBJECT: u64 = 256;

/// The deepest nesting of values (dictionaries in dictionaries, time samples, references' custom data) the walk
/// accepts: openusd reads each level in a stack frame of its own.
pub(super) const MAX_DEPTH: u32 = 32;

/// Values the walk reads beyond one per field and one per 8 bytes of the file (a value representation's size).
pub(super) const MAX_VALUES: u64 = 1 << 16;

/// Whether `path` is a crate file (its first bytes are [`MAGIC`], whatever its extension: a `.usd` may be either).
fn is_crate(path: &Path) -> bool {
    let mut magic = [0u8; 8];
    File::open(path)
        .and_then(|mut f| f.read_exact(&mut magic))
        .is_ok()
        && &magic == MAGIC
}

/// Whether `name` has the extension of a `.usdz` (openusd picks a layer's format by extension, in any case).
pub(super) fn is_package(name: &str) -> bool {
    extension_is(name, &["usdz"])
}

/// Whether `name`'s extension is one of `exts`, in any case.
fn extension_is(name: &str, exts: &[&str]) -> bool {
    name.rsplit_once('.')
        .is_some_and(|(_, ext)| exts.iter().any(|e| ext.eq_ignore_ascii_case(e)))
}

/// Walks the stage file at `path` as openusd will read it: a `.usdz`'s stored crate files, or the file itself when
/// it is a crate file; anything else (a `.usda`) passes. `Err` says what is wrong, for the reader to name the file.
pub(super) fn check(path: &Path) -> Result<(), String> {
    if path.to_str().is_some_and(is_package) {
        check_package(path)
    } else if is_crate(path) {
        let file = File::open(path).map_err(|e| e.to_string())?;
        let len = file.metadata().map_err(|e| e.to_string())?.len();
        walk(&mut Crate {
            src: file,
            base: 0,
            len,
        })
    } else {
        Ok(())
    }
}

/// A `.usdz` (a zip archive, USDZ spec): every stored entry that starts with [`MAGIC`] is walked in its byte range.
/// The entries are those of the archive's central directory, as openusd lists them with the same `zip` crate.
/// openusd opens an entry as a layer by its name's extension (a `.usd` by its magic) and inflates a compressed one,
/// which the walk cannot see into, so a compressed entry with a USD extension is refused (the spec stores every
/// entry uncompressed); other compressed entries (textures) are no layer openusd reads. An archive `zip` cannot
/// read passes: openusd reports it.
fn check_package(path: &Path) -> Result<(), String> {
    let file = File::open(path).map_err(|e| e.to_string())?;
    let len = file.metadata().map_err(|e| e.to_string())?.len();
    let Ok(mut archive) = zip::ZipArchive::new(file) else {
        return Ok(());
    };
    let mut src = File::open(path).map_err(|e| e.to_string())?;
    for k in 0..archive.len() {
        let Ok(entry) = archive.by_index_raw(k) else {
            continue; // openusd fails to read it too
        };
        let (name, method) = (entry.name().to_owned(), entry.compression());
        let (start, size) = (entry.data_start(), entry.compressed_size());
        drop(entry);
        if method != zip::CompressionMethod::Stored {
            if extension_is(&name, &["usd", "usda", "usdc", "usdz"]) {
                return Err(format!(
                    "the package's {name} is compressed ({method}); a .usdz stores its layers uncompressed"
                ));
            }
            continue;
        }
        let Some(start) = start else { continue };
        if start.checked_add(size).is_none_or(|end| end > len) {
            return Err(format!(
                "the package's {name} ({size} bytes at byte {start}) runs past the end of the file ({len} bytes)"
            ));
        }
        let mut layer = Crate {
            src: &mut src,
            base: start,
            len: size,
        };
        if size >= 32 && &layer.bytes::<8>(0)? == MAGIC {
            walk(&mut layer).map_err(|e| format!("the package's {name}: {e}"))?;
        }
    }
    Ok(())
}

/// A crate file's bytes: the `len` bytes of `src` from `base` (a whole file, or an entry of a `.usdz`). Offsets are
/// the crate file's own, from its first byte.
struct Crate<R> {
    src: R,
    base: u64,
    len: u64,
}

impl<R: Read + Seek> Crate<R> {
    /// The `N` bytes at `offset`, which must lie in the file.
    fn bytes<const N: usize>(&mut self, offset: u64) -> Result<[u8; N], String> {
        let mut b = [0u8; N];
        self.read(offset, &mut b)?;
        Ok(b)
    }

    /// `buf.len()` bytes at `offset`, which must lie in the file.
    fn read(&mut self, offset: u64, buf: &mut [u8]) -> Result<(), String> {
        let n = buf.len() as u64;
        if offset.checked_add(n).is_none_or(|end| end > self.len) {
            return Err(format!(
                "{n} bytes at byte {offset} lie past the end of the file ({} bytes)",
                self.len
            ));
        }
        self.src
            .seek(SeekFrom::Start(self.base + offset))
            .and_then(|_| self.src.read_exact(buf))
            .map_err(|e| e.to_string())
    }

    /// The little-endian u64 at `offset`.
    fn u64_at(&mut self, offset: u64) -> Result<u64, String> {
        self.bytes::<8>(offset).map(u64::from_le_bytes)
    }

    /// The little-endian u32 at `offset`.
    fn u32_at(&mut self, offset: u64) -> Result<u32, String> {
        self.bytes::<4>(offset).map(u32::from_le_bytes)
    }

    /// The bytes of the file from `offset` on.
    fn remaining(&self, offset: u64) -> u64 {
        self.len.saturating_sub(offset)
    }

    /// The compressed block at `offset` (its 8-byte size, then that many bytes, which must lie in the file),
    /// decompressed as openusd does into at most `out` bytes; `None` where openusd fails to. The buffer is also
    /// held to what LZ4 can expand the block to, so a declared `out` never sizes it beyond the file's bytes.
    fn block(&mut self, offset: u64, out: u64) -> Result<Option<Vec<u8>>, String> {
        let size = self.u64_at(offset)?;
        if size > self.remaining(offset + 8) {
            return Err(format!(
                "a block of {size} compressed bytes at byte {offset} runs past the end of the file"
            ));
        }
        let mut input = vec![0u8; size as usize];
        self.read(offset + 8, &mut input)?;
        let out = out.min(LZ4_EXPANSION.saturating_mul(size).saturating_add(16));
        Ok(decompress(&input, out as usize))
    }
}

/// openusd's `decompress_lz4`: a chunk count (0: one LZ4 block follows; openusd panics on any other) and the block,
/// into a buffer of `out` bytes; `None` where openusd fails.
fn decompress(input: &[u8], out: usize) -> Option<Vec<u8>> {
    let (&0, block) = input.split_first()? else {
        return None;
    };
    let mut buf = vec![0u8; out];
    let n = lz4_flex::block::decompress_into(block, &mut buf).ok()?;
    buf.truncate(n);
    Some(buf)
}

/// openusd's `decode_ints` for 32-bit integers (Pixar's integer coding, see the module doc): `count` integers from
/// `data`, as their bits; `None` where openusd fails or panics.
fn decode_ints(data: &[u8], count: usize) -> Option<Vec<u32>> {
    if count == 0 {
        return Some(Vec::new());
    }
    let common = i32::from_le_bytes(data.get(..4)?.try_into().ok()?) as i64;
    let codes = data.get(4..4 + count.div_ceil(4))?;
    let mut ints = data.get(4 + codes.len()..)?;
    let mut take = |n: usize| -> Option<i64> {
        let (b, rest) = ints.split_at_checked(n)?;
        ints = rest;
        Some(match n {
            1 => b[0] as i8 as i64,
            2 => i16::from_le_bytes([b[0], b[1]]) as i64,
            _ => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as i64,
        })
    };
    let mut out = Vec::with_capacity(codes.len() * 4);
    let mut prev = 0i64;
    for &code in codes {
        for k in 0..4 {
            let delta = match (code >> (2 * k)) & 3 {
                0 => common,
                1 => take(1)?,
                2 => take(2)?,
                _ => take(4)?,
            };
            prev = prev.wrapping_add(delta);
            out.push(prev as u32);
        }
    }
    out.truncate(count);
    Some(out)
}

/// The size openusd gives the buffer of `count` encoded 32-bit integers (`encoded_buffer_size`).
fn encoded_size(count: u64) -> u64 {
    if count == 0 {
        0
    } else {
        4u64.saturating_add(count.div_ceil(4))
            .saturating_add(count.saturating_mul(4))
    }
}

/// Why a walk stops.
enum Halt {
    /// The file is refused: what is wrong.
    Refuse(String),
    /// openusd fails here (an error or a caught panic) before allocating more: the value (or, in the structural
    /// tables, the whole file) is not read further.
    Fails,
}

impl From<String> for Halt {
    fn from(message: String) -> Self {
        Halt::Refuse(message)
    }
}

/// Walks the crate file `c` (see the module doc).
fn walk<R: Read + Seek>(c: &mut Crate<R>) -> Result<(), String> {
    let len = c.len;
    if len < 32 {
        return Err(format!(
            "{len} bytes is shorter than a crate file's 32-byte header"
        ));
    }
    let v: [u8; 8] = c.bytes(8)?;
    let version = u32::from_be_bytes([0, v[0], v[1], v[2]]);
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
    // The first section of each name: the one openusd reads.
    let mut first = std::collections::HashMap::new();
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
        first.entry(section_name(&name)).or_insert(start);
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
    // Files before version 0.4 reach openusd's `todo!`s (a panic) before any value is read.
    if version < 0x00_04_00 {
        return Ok(());
    }
    match Values::new(c, version, declared, allowed).tables(&first) {
        Ok(()) => Ok(()),
        Err(Halt::Refuse(message)) => Err(message),
        Err(Halt::Fails) => Ok(()),
    }
}

/// A section's name up to its first NUL.
fn section_name(name: &[u8; 16]) -> String {
    let end = name.iter().position(|&b| b == 0).unwrap_or(16);
    String::from_utf8_lossy(&name[..end]).into_owned()
}

#[cfg(test)]
mod tests;
