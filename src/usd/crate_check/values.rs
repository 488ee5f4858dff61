//! The walk over a crate file's path tree and every field's value, as openusd reads them ([`super`]'s module doc).

use std::io::{Read, Seek};

use super::{
    decode_ints, encoded_size, Crate, Halt, LZ4_EXPANSION, MAX_DEPTH, MAX_EXPANSION, MAX_VALUES,
    PER_OBJECT, SLACK_BYTES,
};

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
pub(super) struct Values<'a, R> {
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

impl<'a, R: Read + Seek> Values<'a, R> {
    /// The walk of `c` (file version `version`, `0x00MMmmpp`) with `declared` bytes already allocated by its tables,
    /// of `allowed`.
    pub(super) fn new(c: &'a mut Crate<R>, version: u32, declared: u64, allowed: u64) -> Self {
        Values {
            c,
            version,
            text: 0,
            path_text: 0,
            declared,
            allowed,
            read: 0,
            max_read: 0,
        }
    }

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
    pub(super) fn tables(
        &mut self,
        first: &std::collections::HashMap<String, u64>,
    ) -> Result<(), Halt> {
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
    pub(super) fn tokens(&mut self, start: u64) -> Result<Vec<u64>, Halt> {
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
    pub(super) fn reps(&mut self, start: u64) -> Result<Vec<u64>, Halt> {
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
