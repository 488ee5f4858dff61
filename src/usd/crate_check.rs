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
    let mut values = Values {
        c,
        version,
        text: 0,
        path_text: 0,
        declared,
        allowed,
        read: 0,
        max_read: 0,
    };
    match values.tables(&first) {
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

/// The kinds of array openusd reads through `unpack_array_len`, which decides whether it is compressed.
#[derive(Clone, Copy, PartialEq)]
enum Kind {
    /// Compressed from version 0.5 when flagged.
    Ints,
    /// Compressed from version 0.6 when flagged.
    Floats,
    /// Never compressed.
    Other,
}

/// What a list holds, for the bytes openusd allocates per element besides the list's own.
#[derive(Clone, Copy)]
enum Text {
    /// Tokens, strings and asset paths: a copy of a token's text.
    Token,
    /// Paths: a copy of a path's text.
    Path,
}

/// What a list operation's lists hold.
#[derive(Clone, Copy)]
enum ListOf {
    /// u32 indices of tokens, strings or paths.
    Indices(Text),
    /// Plain integers of this many bytes.
    Ints(u64),
    /// References (asset path, prim path, layer offset, custom data).
    References,
    /// Payloads (asset path, prim path, layer offset from version 0.8).
    Payloads,
}

/// The walk over a crate file's path tree and values, with the memory openusd allocates so far.
struct Values<'a, R> {
    c: &'a mut Crate<R>,
    /// The file's version, `0x00MMmmpp`.
    version: u32,
    /// The longest token: the text a token, string or asset path in a value copies at most.
    text: u64,
    /// The longest path openusd builds.
    path_text: u64,
    /// Bytes openusd allocates from the file so far.
    declared: u64,
    /// What it may (see [`MAX_EXPANSION`]).
    allowed: u64,
    /// Values read so far, and the most the walk reads.
    read: u64,
    max_read: u64,
}

impl<R: Read + Seek> Values<'_, R> {
    /// Adds `bytes` to what openusd allocates; more than allowed refuses the file.
    fn add(&mut self, bytes: u64) -> Result<(), Halt> {
        self.declared = self.declared.saturating_add(bytes);
        if self.declared > self.allowed {
            return Err(Halt::Refuse(format!(
                "its tables and values declare about {} bytes, more than {MAX_EXPANSION} times the file's {} bytes \
                 (plus {SLACK_BYTES}): a malformed or hostile file",
                self.declared, self.c.len
            )));
        }
        Ok(())
    }

    /// The token table, the path tree, then every field's value.
    fn tables(&mut self, first: &std::collections::HashMap<String, u64>) -> Result<(), Halt> {
        let tokens = match first.get("TOKENS") {
            Some(&start) => self.tokens(start)?,
            None => Vec::new(),
        };
        self.text = tokens.iter().copied().max().unwrap_or(0);
        if let Some(&start) = first.get("PATHS") {
            self.paths(start, &tokens)?;
        }
        if let Some(&start) = first.get("SPECS") {
            // `CrateData::open` keys every spec by a copy of its path.
            let specs = self.c.u64_at(start)?;
            self.add(specs.saturating_mul(self.path_text))?;
        }
        let Some(&start) = first.get("FIELDS") else {
            return Ok(());
        };
        let reps = self.reps(start)?;
        self.max_read = (reps.len() as u64)
            .saturating_add(self.c.len / 8)
            .saturating_add(MAX_VALUES);
        for rep in reps {
            match self.value(rep, 0) {
                Ok(()) | Err(Halt::Fails) => {}
                Err(refuse) => return Err(refuse),
            }
        }
        Ok(())
    }

    /// The token table at `start`, decompressed as openusd does: the length of each token.
    fn tokens(&mut self, start: u64) -> Result<Vec<u64>, Halt> {
        let (count, uncompressed) = (self.c.u64_at(start)?, self.c.u64_at(start + 8)?);
        let buffer = self.c.block(start + 16, uncompressed)?.ok_or(Halt::Fails)?;
        if buffer.len() as u64 != uncompressed || buffer.last().is_some_and(|&b| b != 0) {
            return Err(Halt::Fails);
        }
        let lengths: Vec<u64> = match buffer.split_last() {
            Some((_, text)) => text.split(|&b| b == 0).map(|t| t.len() as u64).collect(),
            None => Vec::new(),
        };
        if lengths.len() as u64 != count {
            return Err(Halt::Fails);
        }
        Ok(lengths)
    }

    /// The path tree at `start`, built as openusd's `build_compressed_paths` builds it but with the lengths of the
    /// strings only: what they take, and the longest.
    fn paths(&mut self, start: u64, tokens: &[u64]) -> Result<(), Halt> {
        let (paths, count) = (self.c.u64_at(start)?, self.c.u64_at(start + 8)?);
        let mut pos = start + 16;
        let mut table = || -> Result<Vec<u32>, Halt> {
            let data = self.c.block(pos, encoded_size(count))?.ok_or(Halt::Fails)?;
            pos += 8 + self.c.u64_at(pos)?;
            decode_ints(&data, count as usize).ok_or(Halt::Fails)
        };
        let (indices, elements, jumps) = (table()?, table()?, table()?);
        if indices.is_empty() {
            return Ok(());
        }
        // Each path's length (0: openusd's empty default path), and which entries were built.
        let mut length = vec![0u64; paths as usize];
        let mut built = vec![false; count as usize];
        let (mut bytes, mut longest) = (0u64, 0u64);
        let mut pending = vec![(0usize, 0u64)];
        while let Some((mut next, mut parent)) = pending.pop() {
            loop {
                let k = next;
                next += 1;
                if *built.get(k).ok_or(Halt::Fails)? {
                    return Err(Halt::Refuse(format!(
                        "its path tree reaches entry {k} twice (openusd would build it again for every way there)"
                    )));
                }
                built[k] = true;
                let this = if parent == 0 {
                    // The root: "/", at the entry's own index; it is the parent of what follows.
                    *length.get_mut(k).ok_or(Halt::Fails)? = 1;
                    parent = 1;
                    1
                } else {
                    let token = elements[k].cast_signed().unsigned_abs() as usize;
                    let text = *tokens.get(token).ok_or(Halt::Fails)?;
                    let this = parent + 1 + text;
                    *length.get_mut(indices[k] as usize).ok_or(Halt::Fails)? = this;
                    this
                };
                bytes = bytes.saturating_add(this);
                longest = longest.max(this);
                let jump = jumps[k].cast_signed();
                let (child, sibling) = (jump > 0 || jump == -1, jump >= 0);
                if child {
                    if sibling {
                        // The sibling's subtree waits with a copy of the parent path.
                        pending.push((k + jump as usize, parent));
                        bytes = bytes.saturating_add(parent);
                    }
                    // The child's parent: a copy of this entry's path.
                    parent = *length.get(indices[k] as usize).ok_or(Halt::Fails)?;
                    bytes = bytes.saturating_add(parent);
                }
                if !child && !sibling {
                    break;
                }
            }
            self.add(std::mem::take(&mut bytes))?;
        }
        self.path_text = longest;
        Ok(())
    }

    /// The fields' value representations: the FIELDS section's second block, decompressed as openusd does (its
    /// count is bounded by the structural walk).
    fn reps(&mut self, start: u64) -> Result<Vec<u64>, Halt> {
        let count = self.c.u64_at(start)?;
        let reps_at = start + 16 + self.c.u64_at(start + 8)?;
        let data = self
            .c
            .block(reps_at, count.saturating_mul(8))?
            .ok_or(Halt::Fails)?;
        Ok(data
            .chunks_exact(8)
            .map(|b| u64::from_le_bytes(b.try_into().unwrap()))
            .collect())
    }

    /// The value `rep`, as openusd's `CrateFile::value` reads it, `depth` values deep.
    fn value(&mut self, rep: u64, depth: u32) -> Result<(), Halt> {
        if depth > MAX_DEPTH {
            return Err(Halt::Refuse(format!(
                "its values nest more than {MAX_DEPTH} deep (a dictionary or time samples holding itself?)"
            )));
        }
        self.read += 1;
        if self.read > self.max_read {
            return Err(Halt::Refuse(format!(
                "reading its values reads more than {} of them (a dictionary whose entries lead back to themselves?)",
                self.max_read
            )));
        }
        let (ty, at) = ((rep >> 48) & 0xff, rep & ((1 << 48) - 1));
        let (array, inlined, compressed) = (rep >> 63 != 0, rep & 1 << 62 != 0, rep & 1 << 61 != 0);
        match ty {
            // bool, uchar, int, uint, int64, uint64, half, float, double.
            1 | 2 if array => self.array(at, Kind::Other, 1, compressed),
            3 | 4 if array => self.array(at, Kind::Ints, 4, compressed),
            5 | 6 if array => self.array(at, Kind::Ints, 8, compressed),
            7..=9 if array && !inlined => self.array(at, Kind::Floats, 1 << (ty - 6), compressed),
            // string, asset path and path expression arrays: string indices.
            10 | 12 | 57 if array => self.list_at(at, Text::Token),
            // token arrays: counted as other arrays are.
            11 if array => {
                let Some((pos, count, _)) = self.array_len(at, Kind::Other, false)? else {
                    return Ok(());
                };
                self.elements(at, pos, count, 4)?;
                self.add(count.saturating_mul(PER_OBJECT + self.text))
            }
            // matrix2d, 3d, 4d; quatd, quatf, quath; vec2d … vec4i.
            13..=30 if array => {
                const SIZES: [u64; 18] = [
                    32, 72, 128, 32, 16, 8, 16, 8, 4, 8, 24, 12, 6, 12, 32, 16, 8, 16,
                ];
                self.array(at, Kind::Other, SIZES[ty as usize - 13], false)
            }
            // dictionary.
            31 if !inlined && !compressed && !array => self.dictionary(at, depth).map(drop),
            // token, string, path and unregistered-value list operations.
            32 | 33 | 54 if !inlined => self.list_op(at, ListOf::Indices(Text::Token), depth),
            34 if !inlined => self.list_op(at, ListOf::Indices(Text::Path), depth),
            35 if !inlined => self.list_op(at, ListOf::References, depth),
            36 | 38 if !inlined => self.list_op(at, ListOf::Ints(4), depth),
            37 | 39 if !inlined => self.list_op(at, ListOf::Ints(8), depth),
            55 => self.list_op(at, ListOf::Payloads, depth),
            // path vector; token and string vectors.
            40 if !inlined => self.list_at(at, Text::Path),
            41 | 50 if !inlined => self.list_at(at, Text::Token),
            // variant selection map: pairs of string indices into a map sized by the count.
            45 if !inlined && !array && !compressed => {
                let count = self.c.u64_at(at)?;
                self.elements(at, at + 8, count, 8)?;
                self.add(count.saturating_mul(2 * (PER_OBJECT + self.text)))
            }
            46 if !inlined && !compressed => self.time_samples(at, depth),
            // double vector, and time code arrays: doubles.
            48 | 56 if (ty == 48 || array) && !inlined => {
                self.array(at, Kind::Floats, 8, compressed)
            }
            // layer offset vector: two doubles each.
            49 if !inlined && !array && !compressed => {
                let count = self.c.u64_at(at)?;
                self.elements(at, at + 8, count, 16)
            }
            // relocates: pairs of path indices.
            58 if !inlined => {
                let count = self.c.u64_at(at)?;
                self.elements(at, at + 8, count, 8)?;
                self.add(count.saturating_mul(2 * (PER_OBJECT + self.path_text)))
            }
            // Scalars (inlined or read in place), and whatever openusd refuses to read.
            _ => Ok(()),
        }
    }

    /// `count` elements of `size` bytes at `pos` (the count read at `at`): they must lie in the file, since openusd
    /// allocates them before reading them; what it allocates is added.
    fn elements(&mut self, at: u64, pos: u64, count: u64, size: u64) -> Result<(), Halt> {
        let remaining = self.c.remaining(pos);
        if count
            .checked_mul(size)
            .is_none_or(|bytes| bytes > remaining)
        {
            return Err(Halt::Refuse(format!(
                "value array at byte {at} declares {count} elements of {size} bytes, more than the file's remaining \
                 {remaining} bytes"
            )));
        }
        self.add(count * size)
    }

    /// openusd's `unpack_array_len`: where an array's elements start, its count, and whether it is compressed;
    /// `None` for the empty array (payload 0).
    fn array_len(
        &mut self,
        at: u64,
        kind: Kind,
        flagged: bool,
    ) -> Result<Option<(u64, u64, bool)>, Halt> {
        if at == 0 {
            return Ok(None);
        }
        // Before 0.5 a u32 shape comes first.
        let mut pos = if self.version < 0x00_05_00 {
            at + 4
        } else {
            at
        };
        let count = if self.version < 0x00_07_00 {
            pos += 4;
            self.c.u32_at(pos - 4)? as u64
        } else {
            pos += 8;
            self.c.u64_at(pos - 8)?
        };
        let compressed = flagged
            && count >= 4
            && match kind {
                Kind::Ints => self.version >= 0x00_05_00,
                Kind::Floats => self.version >= 0x00_06_00,
                Kind::Other => false,
            };
        Ok(Some((pos, count, compressed)))
    }

    /// An array of numbers of `size` bytes each, at `at`: plain, or compressed (integers, and floats as integers or
    /// through a lookup table).
    fn array(&mut self, at: u64, kind: Kind, size: u64, flagged: bool) -> Result<(), Halt> {
        let Some((pos, count, compressed)) = self.array_len(at, kind, flagged)? else {
            return Ok(());
        };
        if !compressed {
            // The elements read, and a copy for the arrays openusd regroups (matrices, quaternions, bools).
            self.elements(at, pos, count, size)?;
            return self.add(count.saturating_mul(size));
        }
        if kind == Kind::Ints {
            return self.encoded(at, pos, count, size);
        }
        match self.c.bytes::<1>(pos)?[0] {
            b'i' => self.encoded(at, pos + 1, count, 4)?,
            b't' => {
                let table = self.c.u32_at(pos + 1)? as u64;
                self.elements(at, pos + 5, table, size)?;
                self.encoded(at, pos + 5 + table * size, count, 4)?;
            }
            _ => return Err(Halt::Fails),
        }
        // The floats converted from the integers.
        self.add(count.saturating_mul(size))
    }

    /// `count` integers of `size` bytes in the integer coding, compressed at `pos` (of the array at `at`): openusd
    /// allocates the compressed bytes, a buffer for the coding and the integers before it decompresses, so the
    /// compressed bytes must lie in the file and the count be one they can decode to.
    fn encoded(&mut self, at: u64, pos: u64, count: u64, size: u64) -> Result<(), Halt> {
        let compressed = self.c.u64_at(pos)?;
        let remaining = self.c.remaining(pos + 8);
        if compressed > remaining {
            return Err(Halt::Refuse(format!(
                "compressed value array at byte {at}: its {compressed} compressed bytes run past the end of the \
                 file ({remaining} bytes remain)"
            )));
        }
        // LZ4 expands a byte to at most 255, and the coding holds 4 integers per byte (2-bit codes, a common
        // delta taking no bytes of its own).
        let most = 4 * LZ4_EXPANSION.saturating_mul(compressed).saturating_add(16);
        if count > most {
            return Err(Halt::Refuse(format!(
                "compressed value array at byte {at} declares {count} elements, more than its {compressed} \
                 compressed bytes can decode to ({most})"
            )));
        }
        self.add(
            compressed
                .saturating_add(encoded_size(count))
                .saturating_add(count.saturating_mul(size)),
        )
    }

    /// A list of u32 indices of tokens, strings or paths at `pos` (a u64 count first); returns where it ends.
    fn list(&mut self, at: u64, pos: u64, text: Text) -> Result<u64, Halt> {
        let count = self.c.u64_at(pos)?;
        self.elements(at, pos + 8, count, 4)?;
        let text = match text {
            Text::Token => self.text,
            Text::Path => self.path_text,
        };
        self.add(count.saturating_mul(PER_OBJECT + text))?;
        Ok(pos + 8 + count * 4)
    }

    /// A list read where the payload points. openusd reads these without the empty array's payload 0 test, so at 0
    /// it reads the magic as the count: 4.8·10¹⁸ indices, a capacity overflow (a panic) rather than an allocation.
    fn list_at(&mut self, at: u64, text: Text) -> Result<(), Halt> {
        if at == 0 {
            return Err(Halt::Fails);
        }
        self.list(at, at, text).map(drop)
    }

    /// A list operation at `at`: a header byte, then each list its bits name, in openusd's order.
    fn list_op(&mut self, at: u64, of: ListOf, depth: u32) -> Result<(), Halt> {
        let header = self.c.bytes::<1>(at)?[0];
        let mut pos = at + 1;
        // Explicit, added, prepended, appended, deleted, ordered.
        for bit in [1, 2, 5, 6, 3, 4] {
            if header & 1 << bit == 0 {
                continue;
            }
            pos = match of {
                ListOf::Indices(text) => self.list(at, pos, text)?,
                ListOf::Ints(size) => {
                    let count = self.c.u64_at(pos)?;
                    self.elements(at, pos + 8, count, size)?;
                    pos + 8 + count * size
                }
                ListOf::References => self.references(at, pos, depth)?,
                ListOf::Payloads => {
                    // A string and a path index, then a layer offset from 0.8.
                    let each = if self.version >= 0x00_08_00 { 24 } else { 8 };
                    let count = self.c.u64_at(pos)?;
                    self.elements(at, pos + 8, count, each)?;
                    self.add(count.saturating_mul(PER_OBJECT + self.text + self.path_text))?;
                    pos + 8 + count * each
                }
            };
        }
        Ok(())
    }

    /// A list of references at `pos`: each a string and a path index, a layer offset and a dictionary of custom
    /// data; returns where it ends.
    fn references(&mut self, at: u64, pos: u64, depth: u32) -> Result<u64, Halt> {
        let count = self.c.u64_at(pos)?;
        // openusd reserves the list from the count; each reference takes at least its 24 bytes and its
        // dictionary's count.
        self.elements(at, pos + 8, count, 32)?;
        self.add(count.saturating_mul(PER_OBJECT + self.text + self.path_text))?;
        let mut pos = pos + 8;
        for _ in 0..count {
            pos = self.dictionary(pos + 24, depth + 1)?;
        }
        Ok(pos)
    }

    /// A dictionary at `pos` (openusd's `read_custom_data`): a count, then per entry a string index and a relative
    /// offset to the entry's value representation, read there; returns where openusd's reading ends.
    fn dictionary(&mut self, pos: u64, depth: u32) -> Result<u64, Halt> {
        let count = self.c.u64_at(pos)?;
        let mut pos = pos + 8;
        for _ in 0..count {
            // The key, then the offset, relative to where the offset starts.
            self.c.u32_at(pos)?;
            let rep_at = self.jump(pos + 4)?;
            let rep = self.c.u64_at(rep_at)?;
            if !(1..=58).contains(&((rep >> 48) & 0xff)) {
                return Err(Halt::Fails);
            }
            self.add(PER_OBJECT + self.text)?;
            self.value(rep, depth + 1)?;
            pos = rep_at + 8;
        }
        Ok(pos)
    }

    /// Time samples at `at`: an offset to the times' value representation (a double vector or array), then, after
    /// it, an offset to the samples' count and value representations.
    fn time_samples(&mut self, at: u64, depth: u32) -> Result<(), Halt> {
        let times_at = self.jump(at)?;
        let times = self.c.u64_at(times_at)?;
        let ty = (times >> 48) & 0xff;
        if !(ty == 48 || ty == 9 && times >> 63 != 0) {
            return Err(Halt::Fails);
        }
        self.value(times, depth + 1)?;
        let samples_at = self.jump(times_at + 8)?;
        let count = self.c.u64_at(samples_at)?;
        // openusd reads them only if there are as many as times, but allocates them at that count.
        self.elements(samples_at, samples_at + 8, count, 8)?;
        self.add(count.saturating_mul(PER_OBJECT))?;
        for k in 0..count {
            let rep = self.c.u64_at(samples_at + 8 + 8 * k)?;
            self.value(rep, depth + 1)?;
        }
        Ok(())
    }

    /// Where the relative offset at `pos` leads (openusd's `apply_recursive_offset`: from `pos` itself).
    fn jump(&mut self, pos: u64) -> Result<u64, Halt> {
        let offset = self.c.u64_at(pos)?.cast_signed();
        pos.checked_add_signed(offset).ok_or(Halt::Fails)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    fn data(name: &str) -> Vec<u8> {
        std::fs::read(
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("tests/data/usd")
                .join(name),
        )
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

    /// The crate file `bytes` walked in memory.
    fn walked(bytes: &[u8]) -> Result<(), String> {
        walk(&mut Crate {
            src: Cursor::new(bytes),
            base: 0,
            len: bytes.len() as u64,
        })
    }

    /// The stage file `bytes` named `name` checked as `usd::read` checks it.
    fn checked(name: &str, bytes: &[u8]) -> Result<(), String> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        check(&path)
    }

    /// The value representations of `bytes`' fields.
    fn reps(bytes: &[u8]) -> Vec<u64> {
        let mut c = Crate {
            src: Cursor::new(bytes),
            base: 0,
            len: bytes.len() as u64,
        };
        let mut values = Values {
            c: &mut c,
            version: 0x00_08_00,
            text: 0,
            path_text: 0,
            declared: 0,
            allowed: u64::MAX,
            read: 0,
            max_read: 0,
        };
        let Ok(reps) = values.reps(section_start(bytes, "FIELDS") as u64) else {
            panic!("the fields do not decompress")
        };
        reps
    }

    /// The offset of the count of the largest uncompressed array of type `ty` among `bytes`' fields.
    fn largest_array(bytes: &[u8], ty: u64) -> (usize, u64) {
        reps(bytes)
            .into_iter()
            .filter(|r| {
                r >> 63 != 0
                    && (r >> 48) & 0xff == ty
                    && r & 1 << 61 == 0
                    && r & 0xffff_ffff_ffff != 0
            })
            .map(|r| (r & 0xffff_ffff_ffff) as usize)
            .map(|at| {
                (
                    at,
                    u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()),
                )
            })
            .max_by_key(|&(_, count)| count)
            .unwrap()
    }

    #[test]
    fn a_crate_file_passes_and_its_declared_sizes_are_held_to_the_file() {
        let good = data("groom.usdc");
        assert_eq!(walked(&good), Ok(()));
        assert_eq!(checked("g.usdc", &good), Ok(()));
        let tokens = section_start(&good, "TOKENS");
        // A token table claiming more than LZ4 can expand its compressed bytes to.
        let huge = with(good.clone(), tokens + 8, 1 << 40);
        assert!(walked(&huge)
            .unwrap_err()
            .contains("more than LZ4 can expand"));
        // Compressed bytes past the end of the file (the fuzzer's 9 PB table was one).
        let past = with(good.clone(), tokens + 16, 1 << 50);
        assert!(walked(&past).unwrap_err().contains("run past the end"));
        // A paths table declaring 2^40 paths: more than the file's tables may take.
        let paths = with(good.clone(), section_start(&good, "PATHS"), 1 << 40);
        assert!(walked(&paths).unwrap_err().contains("tables declare"));
        // A table of contents past the end, and a truncated file.
        assert!(walked(&with(good.clone(), 16, good.len() as u64)).is_err());
        assert!(walked(&good[..good.len() / 2]).is_err());
        assert!(walked(&good[..20]).unwrap_err().contains("32-byte header"));
    }

    #[test]
    fn a_value_array_declaring_more_than_the_file_is_refused() {
        let good = data("groom.usdc");
        // The curves' points: the largest vec3f array.
        let (at, count) = largest_array(&good, 24);
        assert!(count >= 36 * 6, "{count} points");
        let bad = with(good.clone(), at, 1 << 40);
        let e = checked("g.usdc", &bad).unwrap_err();
        assert!(
            e.contains(&format!(
                "value array at byte {at} declares 1099511627776 elements of 12 bytes, more than the file's \
                 remaining {} bytes",
                good.len() - at - 8
            )),
            "{e}"
        );
        // One point more than the file holds, and the count the file holds.
        let room = (good.len() - at - 8) as u64 / 12;
        assert!(walked(&with(good.clone(), at, room + 1)).is_err());
        assert!(walked(&with(good.clone(), at, room)).is_ok());
        // The token array the fuzzer found (xformOpOrder), at 2^40 tokens.
        let (at, _) = largest_array(&good, 11);
        let e = walked(&with(good.clone(), at, 1 << 40)).unwrap_err();
        assert!(
            e.contains("declares 1099511627776 elements of 4 bytes"),
            "{e}"
        );
    }

    /// The value representation of `bytes`' field whose array of type `ty` is at `at`.
    fn field_of(bytes: &[u8], ty: u64, at: usize) -> usize {
        reps(bytes)
            .iter()
            .position(|r| (r >> 48) & 0xff == ty && r & 0xffff_ffff_ffff == at as u64)
            .unwrap()
    }

    /// The offset of the largest compressed array of type `ty` among `bytes`' fields, and its count.
    fn largest_compressed(bytes: &[u8], ty: u64) -> (usize, u64) {
        reps(bytes)
            .into_iter()
            .filter(|r| r >> 63 != 0 && (r >> 48) & 0xff == ty && r & 1 << 61 != 0)
            .map(|r| (r & 0xffff_ffff_ffff) as usize)
            .map(|at| {
                (
                    at,
                    u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()),
                )
            })
            .max_by_key(|&(_, count)| count)
            .unwrap()
    }

    /// An LZ4 block of `data` as one run of literals, behind openusd's chunk count (0), with its 8-byte size.
    fn block_of(data: &[u8]) -> Vec<u8> {
        let mut b = vec![0u8];
        if data.len() < 15 {
            b.push((data.len() as u8) << 4);
        } else {
            b.push(0xf0);
            let mut rest = data.len() - 15;
            while rest >= 255 {
                b.push(255);
                rest -= 255;
            }
            b.push(rest as u8);
        }
        b.extend_from_slice(data);
        [(b.len() as u64).to_le_bytes().to_vec(), b].concat()
    }

    /// `values` in Pixar's integer coding for 32 bits: the commonest delta, 2-bit codes, the other deltas.
    fn encode_ints(values: &[i32]) -> Vec<u8> {
        let mut prev = 0i32;
        let deltas: Vec<i32> = values
            .iter()
            .map(|&v| (v.wrapping_sub(prev), prev = v).0)
            .collect();
        let mut counts = std::collections::HashMap::new();
        deltas
            .iter()
            .for_each(|&d| *counts.entry(d).or_insert(0) += 1);
        let common = counts
            .into_iter()
            .max_by_key(|&(d, n)| (n, -(d as i64)))
            .map_or(0, |(d, _)| d);
        let mut codes = vec![0u8; deltas.len().div_ceil(4)];
        let mut rest = Vec::new();
        for (k, &d) in deltas.iter().enumerate() {
            let code = if d == common {
                0
            } else if let Ok(d) = i8::try_from(d) {
                rest.push(d as u8);
                1
            } else if let Ok(d) = i16::try_from(d) {
                rest.extend(d.to_le_bytes());
                2
            } else {
                rest.extend(d.to_le_bytes());
                3
            };
            codes[k / 4] |= code << (2 * (k % 4));
        }
        [common.to_le_bytes().to_vec(), codes, rest].concat()
    }

    /// `bytes` with section `name` moved to `section`, appended at the end (its table of contents entry
    /// repointed).
    fn with_section(bytes: Vec<u8>, name: &str, section: &[u8]) -> Vec<u8> {
        let u = |o: usize| u64::from_le_bytes(bytes[o..o + 8].try_into().unwrap()) as usize;
        let toc = u(16);
        let entry = (0..u(toc))
            .map(|k| toc + 8 + 32 * k)
            .find(|&e| bytes[e..e + 16].starts_with(name.as_bytes()) && bytes[e + name.len()] == 0)
            .unwrap();
        let start = bytes.len() as u64;
        let bytes = [bytes, section.to_vec()].concat();
        with(
            with(bytes, entry + 16, start),
            entry + 24,
            section.len() as u64,
        )
    }

    /// `bytes` with its fields' value representations edited by `edit`, which may append values to the file: a
    /// FIELDS section at the end, its representations in a literal LZ4 block.
    fn with_reps(bytes: &[u8], edit: impl FnOnce(&mut Vec<u64>, &mut Vec<u8>)) -> Vec<u8> {
        let mut reps = reps(bytes);
        let fields = section_start(bytes, "FIELDS");
        let indices =
            u64::from_le_bytes(bytes[fields + 8..fields + 16].try_into().unwrap()) as usize;
        let mut file = bytes.to_vec();
        edit(&mut reps, &mut file);
        let section = [
            (reps.len() as u64).to_le_bytes().to_vec(),
            bytes[fields + 8..fields + 16 + indices].to_vec(),
            block_of(
                &reps
                    .iter()
                    .flat_map(|r| r.to_le_bytes())
                    .collect::<Vec<u8>>(),
            ),
        ]
        .concat();
        with_section(file, "FIELDS", &section)
    }

    /// `bytes` with a string table of one string (token 0), for dictionaries' keys (groom.usdc has no strings).
    fn with_a_string(bytes: Vec<u8>) -> Vec<u8> {
        with_section(
            bytes,
            "STRINGS",
            &[&1u64.to_le_bytes()[..], &0u32.to_le_bytes()].concat(),
        )
    }

    /// `bytes` with its path tree replaced by a chain of `n` paths (the root, then each the child of the one before,
    /// named by the longest token) whose jumps `jump` gives (the last one's is -2: no child, no sibling).
    fn with_path_chain(bytes: &[u8], n: i32, jump: i32) -> Vec<u8> {
        let longest = {
            let mut c = Crate {
                src: Cursor::new(bytes),
                base: 0,
                len: bytes.len() as u64,
            };
            let mut values = Values {
                c: &mut c,
                version: 0x00_08_00,
                text: 0,
                path_text: 0,
                declared: 0,
                allowed: u64::MAX,
                read: 0,
                max_read: 0,
            };
            let Ok(tokens) = values.tokens(section_start(bytes, "TOKENS") as u64) else {
                panic!("the tokens do not decompress")
            };
            (0..tokens.len()).max_by_key(|&k| tokens[k]).unwrap() as i32
        };
        let jumps: Vec<i32> = (0..n).map(|k| if k + 1 == n { -2 } else { jump }).collect();
        let section = [
            (n as u64).to_le_bytes().to_vec(),
            (n as u64).to_le_bytes().to_vec(),
            block_of(&encode_ints(&(0..n).collect::<Vec<_>>())),
            block_of(&encode_ints(&vec![longest; n as usize])),
            block_of(&encode_ints(&jumps)),
        ]
        .concat();
        with_section(bytes.to_vec(), "PATHS", &section)
    }

    /// A `.usdz` of `entries` (name, bytes), stored as the USDZ spec asks.
    fn package(entries: &[(&str, &[u8])]) -> Vec<u8> {
        use std::io::Write;
        let mut zip = zip::ZipWriter::new(Cursor::new(Vec::new()));
        let stored = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Stored);
        for (name, bytes) in entries {
            zip.start_file(*name, stored).unwrap();
            zip.write_all(bytes).unwrap();
        }
        zip.finish().unwrap().into_inner()
    }

    /// A `.usdz` whose groom.usdc, `layer`, is deflated (as the spec does not allow and openusd reads: zip's
    /// deflate is built for openusd).
    fn deflated(layer: &[u8]) -> Vec<u8> {
        use std::io::Write;
        let mut zip = zip::ZipWriter::new(Cursor::new(Vec::new()));
        let deflated = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Deflated);
        zip.start_file("groom.usdc", deflated).unwrap();
        zip.write_all(layer).unwrap();
        zip.finish().unwrap().into_inner()
    }

    /// `package` with its entry `name` marked as deflated (compression method 8) in its local and central headers.
    fn marked_deflated(mut package: Vec<u8>, name: &str) -> Vec<u8> {
        let u16_at = |p: &[u8], o: usize| u16::from_le_bytes([p[o], p[o + 1]]) as usize;
        for k in 0..package.len() - 4 {
            // The method's offset, and where the name and its length are, in a local or central header.
            let (method, name_at, length_at) =
                match u32::from_le_bytes(package[k..k + 4].try_into().unwrap()) {
                    0x0403_4b50 => (k + 8, k + 30, k + 26),
                    0x0201_4b50 => (k + 10, k + 46, k + 28),
                    _ => continue,
                };
            if package.get(name_at..name_at + u16_at(&package, length_at)) == Some(name.as_bytes())
            {
                package[method..method + 2].copy_from_slice(&8u16.to_le_bytes());
            }
        }
        package
    }

    /// The hostile files of these tests, by corpus name (`fuzz/corpus/usd/`, less the format byte).
    fn hostile() -> Vec<(&'static str, Vec<u8>)> {
        let good = data("groom.usdc");
        let (points, _) = largest_array(&good, 24);
        let (tokens, _) = largest_array(&good, 11);
        let (ints, _) = largest_compressed(&good, 3);
        let field = field_of(&good, 24, points);
        let bad_points = with(good.clone(), points, 1 << 40);
        vec![
            ("c-points-2pow40.usdc", bad_points.clone()),
            (
                "c-token-array-2pow40.usdc",
                with(good.clone(), tokens, 1 << 40),
            ),
            (
                "c-compressed-ints-2pow40.usdc",
                with(good.clone(), ints, 1 << 40),
            ),
            (
                "c-dictionary-holding-itself.usdc",
                with_reps(&with_a_string(good.clone()), |reps, file| {
                    // Points as a dictionary of one entry: this dictionary (its offset, 8, runs from the offset to
                    // the value representation after it).
                    let at = file.len() as u64;
                    file.extend(1u64.to_le_bytes());
                    file.extend(0u32.to_le_bytes());
                    file.extend(8i64.to_le_bytes());
                    file.extend((31 << 48 | at).to_le_bytes());
                    reps[field] = 31 << 48 | at;
                }),
            ),
            (
                "c-dictionary-looping.usdc",
                with_reps(&with_a_string(good.clone()), |reps, file| {
                    // Points as a dictionary of 2^40 entries: the first leads to an inlined int, each next one's
                    // offset (-12) back to that int, after which the next entry begins again.
                    let at = file.len() as u64;
                    file.extend((1u64 << 40).to_le_bytes());
                    file.extend(0u32.to_le_bytes());
                    file.extend(8i64.to_le_bytes());
                    file.extend((3u64 << 48 | 1 << 62 | 7).to_le_bytes());
                    file.extend(0u32.to_le_bytes());
                    file.extend((-12i64).to_le_bytes());
                    reps[field] = 31 << 48 | at;
                }),
            ),
            (
                "c-time-samples-holding-themselves.usdc",
                with_reps(&good, |reps, file| {
                    // Points as time samples: offsets to the times (a double vector of one, at +40) and to the
                    // samples (at +24: one, these time samples).
                    let at = file.len() as u64;
                    file.extend(8i64.to_le_bytes());
                    file.extend((48u64 << 48 | (at + 40)).to_le_bytes());
                    file.extend(8i64.to_le_bytes());
                    file.extend(1u64.to_le_bytes());
                    file.extend((46u64 << 48 | at).to_le_bytes());
                    file.extend(1u64.to_le_bytes());
                    file.extend(1.0f64.to_le_bytes());
                    reps[field] = 46 << 48 | at;
                }),
            ),
            (
                "c-path-tree-exponential.usdc",
                with_path_chain(&good, 64, 1),
            ),
            (
                "c-path-tree-quadratic.usdc",
                with_path_chain(&good, 1 << 15, -1),
            ),
            (
                "z-points-2pow40.usdz",
                package(&[("groom.usdc", &bad_points)]),
            ),
            ("z-deflated-points-2pow40.usdz", deflated(&bad_points)),
        ]
    }

    /// A file of [`hostile`].
    fn hostile_file(name: &str) -> Vec<u8> {
        hostile().into_iter().find(|(n, _)| *n == name).unwrap().1
    }

    #[test]
    fn a_compressed_array_declaring_more_than_its_bytes_decode_to_is_refused() {
        let good = data("groom.usdc");
        // The mesh's face vertex indices: the largest compressed int array.
        let (at, count) = largest_compressed(&good, 3);
        assert!(count > 100, "{count}");
        let e = walked(&with(good.clone(), at, 1 << 40)).unwrap_err();
        assert!(
            e.contains(&format!(
                "compressed value array at byte {at} declares 1099511627776 elements, more than"
            )),
            "{e}"
        );
        // Its compressed size past the end of the file.
        let e = walked(&with(good.clone(), at + 8, 1 << 40)).unwrap_err();
        assert!(e.contains("compressed bytes run past the end"), "{e}");
        // The widths: a compressed float array.
        let (at, _) = largest_compressed(&good, 8);
        let e = walked(&with(good.clone(), at, 1 << 40)).unwrap_err();
        assert!(e.contains("declares 1099511627776 elements"), "{e}");
        // A list operation's paths (a relationship's targets) and a token vector (a prim's children).
        let path_ops: Vec<usize> = reps(&good)
            .into_iter()
            .filter(|r| (r >> 48) & 0xff == 34)
            .map(|r| (r & 0xffff_ffff_ffff) as usize)
            .collect();
        assert_eq!(good[path_ops[0]], 3, "an explicit list");
        let e = walked(&with(good.clone(), path_ops[0] + 1, 1 << 40)).unwrap_err();
        assert!(
            e.contains("declares 1099511627776 elements of 4 bytes"),
            "{e}"
        );
        let children = reps(&good)
            .into_iter()
            .find(|r| (r >> 48) & 0xff == 41)
            .map(|r| (r & 0xffff_ffff_ffff) as usize)
            .unwrap();
        let e = walked(&with(good.clone(), children, 1 << 40)).unwrap_err();
        assert!(
            e.contains("declares 1099511627776 elements of 4 bytes"),
            "{e}"
        );
    }

    #[test]
    fn rewritten_tables_read_and_values_holding_themselves_are_refused() {
        let good = data("groom.usdc");
        // The rewriting itself keeps the file good, for the walk and for openusd.
        let same = with_reps(&good, |_, _| {});
        assert_eq!(walked(&same), Ok(()));
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("same.usdc"), &same).unwrap();
        let stage = super::super::read(&dir.path().join("same.usdc"), None, 0.01).unwrap();
        assert_eq!(stage.strands.unwrap().strand_count(), 36);
        let e = walked(&hostile_file("c-dictionary-holding-itself.usdc")).unwrap_err();
        assert!(
            e.contains(&format!("nest more than {MAX_DEPTH} deep")),
            "{e}"
        );
        let e = walked(&hostile_file("c-time-samples-holding-themselves.usdc")).unwrap_err();
        assert!(
            e.contains(&format!("nest more than {MAX_DEPTH} deep")),
            "{e}"
        );
        let e = walked(&hostile_file("c-dictionary-looping.usdc")).unwrap_err();
        assert!(e.contains("reads more than"), "{e}");
    }

    #[test]
    fn a_path_tree_reaching_an_entry_twice_or_building_too_much_is_refused() {
        let good = data("groom.usdc");
        // A chain of 64 paths each the child of the one before passes; with jumps of 1 (a child and a sibling,
        // both the next entry) openusd would build entry k 2^k times: the last entry is the first reached again.
        assert_eq!(walked(&with_path_chain(&good, 64, -1)), Ok(()));
        let e = walked(&hostile_file("c-path-tree-exponential.usdc")).unwrap_err();
        assert!(e.contains("reaches entry 63 twice"), "{e}");
        // 2^15 nested paths: 2^29 path strings of up to 2^15 components, from a few KB.
        let e = walked(&hostile_file("c-path-tree-quadratic.usdc")).unwrap_err();
        assert!(e.contains("tables and values declare"), "{e}");
    }

    #[test]
    fn a_package_s_crate_files_are_walked_and_compressed_layers_refused() {
        let good = data("groom.usdc");
        assert_eq!(checked("g.usdz", &data("groom.usdz")), Ok(()));
        assert_eq!(
            checked("g.usdz", &package(&[("groom.usdc", &good)])),
            Ok(())
        );
        // The points at 2^40 in the package's groom.usdc, through `usd::read`.
        let (at, _) = largest_array(&good, 24);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("g.usdz");
        std::fs::write(&path, hostile_file("z-points-2pow40.usdz")).unwrap();
        let e = super::super::read(&path, None, 0.01)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(&format!(
                "malformed file: the package's groom.usdc: value array at byte {at} declares 1099511627776 elements of \
                 12 bytes"
            )),
            "{e}"
        );
        // Also when the crate file is not the first entry nor named as one.
        let named = package(&[
            ("a.usda", b"#usda 1.0\n"),
            ("b.bin", &with(good.clone(), at, 1 << 40)),
        ]);
        assert!(checked("g.usdz", &named)
            .unwrap_err()
            .contains("the package's b.bin"));
        // A compressed layer is refused; a compressed texture is left.
        let e = checked("g.usdz", &hostile_file("z-deflated-points-2pow40.usdz")).unwrap_err();
        assert!(e.contains("groom.usdc is compressed (Deflated)"), "{e}");
        assert!(checked("g.usdz", &deflated(&good))
            .unwrap_err()
            .contains("compressed (Deflated)"));
        let texture = marked_deflated(
            package(&[("groom.usdc", &good), ("sky.exr", b"not read")]),
            "sky.exr",
        );
        assert_eq!(checked("g.usdz", &texture), Ok(()));
    }

    /// Writes [`hostile`] into the fuzz corpus, each behind its format byte (1: `.usdc`, 2: `.usdz`):
    /// `cargo test --release --lib write_usd_corpus -- --ignored`.
    #[test]
    #[ignore]
    fn write_usd_corpus() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/corpus/usd");
        for (name, bytes) in hostile() {
            let kind = if name.ends_with(".usdz") { 2u8 } else { 1 };
            std::fs::write(dir.join(name), [&[kind][..], &bytes].concat()).unwrap();
        }
    }

    #[test]
    fn openusd_objects_fit_the_bytes_counted_for_them() {
        use openusd::{sdf, tf};
        use std::mem::size_of;
        for size in [
            size_of::<String>(),
            size_of::<tf::Token>(),
            size_of::<sdf::Path>(),
            size_of::<sdf::AssetPath>(),
            size_of::<sdf::Reference>(),
            size_of::<sdf::Payload>(),
            size_of::<sdf::Value>(),
            size_of::<(String, sdf::Value)>(),
        ] {
            assert!(size as u64 <= PER_OBJECT, "{size} bytes");
        }
    }

    #[test]
    fn ints_decode_as_openusd_decodes_them() {
        // Common delta 1, then a small (-3), a medium (300) and a large (70000) delta: 0b11_10_01_00.
        let mut data = 1i32.to_le_bytes().to_vec();
        data.push(0b11_10_01_00);
        data.push(-3i8 as u8);
        data.extend(300i16.to_le_bytes());
        data.extend(70000i32.to_le_bytes());
        assert_eq!(
            decode_ints(&data, 4),
            Some(vec![1, (-2i32) as u32, 298, 70298])
        );
        assert_eq!(decode_ints(&data[..data.len() - 1], 4), None);
    }
}
