//! A walk over an OpenEXR file's header before OpenImageIO opens it: every size the header declares must fit the
//! file, and every attribute OpenEXR knows must declare the size OpenEXR reads for it. OpenEXR 3.1 reads a known
//! attribute's value by its type, not by its declared size, and allocates an unknown one's declared size before
//! reading it: a tile whose channel list was one byte off made OpenEXR read the next attribute's size from the
//! middle of a value and allocate 1.6–1.8 GB for a 1.6 KB file (found by the `merge` fuzz target). When every
//! declared size is the one OpenEXR reads, this walk sees the header exactly as OpenEXR will. It also checks that
//! the file holds the chunk offset table its data window calls for, which OpenEXR allocates before reading.
//!
//! The layout (OpenEXR's "OpenEXR File Layout"): the magic number 20000630 and a version field (its flags: bit 9
//! tiled, bit 10 long names, bit 11 deep data, bit 12 multi-part), then for each part a header of attributes
//! `name\0 type\0 size:i32 value[size]` ended by an empty name; a multi-part file ends its list of headers with one
//! more empty name. Then come the chunk offset tables, 8 bytes per chunk.

use std::io::{self, BufRead, BufReader, Read};

/// The first four bytes of every OpenEXR file (20000630, little-endian).
const MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];

const FLAG_TILED: u32 = 1 << 9;
const FLAG_LONG_NAMES: u32 = 1 << 10;
const FLAG_MULTI_PART: u32 = 1 << 12;

/// Most headers a multi-part file may hold here (cuticle writes one part).
const MAX_PARTS: usize = 1024;

/// Why `file` (of `len` bytes) is not an OpenEXR file whose header fits it, or `Ok`. A file that is not OpenEXR
/// at all is left to OpenImageIO, unless `exr_only`. `max_bytes` bounds each part's pixels as OpenEXR holds them
/// once opened (its data window's channels as 4-byte values, over the rows plus a block of 256, [`super::decoded_rows`]):
/// OpenEXR sizes its decompression buffer from the data window as it opens the file, before the caller can check
/// the image (a forged width made it allocate 1.4 GB).
pub(super) fn check(
    file: impl Read,
    len: u64,
    exr_only: bool,
    max_bytes: u64,
) -> Result<(), String> {
    let mut r = BufReader::new(file.take(len));
    let mut start = [0u8; 8];
    let is_exr = match r.read_exact(&mut start) {
        Ok(()) => start[..4] == MAGIC,
        Err(e) if e.kind() == io::ErrorKind::UnexpectedEof => false,
        Err(e) => return Err(e.to_string()),
    };
    if !is_exr {
        return match exr_only {
            true => Err("it does not start with OpenEXR's magic number".to_owned()),
            false => Ok(()),
        };
    }
    let flags = u32::from_le_bytes([start[4], start[5], start[6], start[7]]);
    let max_name = if flags & FLAG_LONG_NAMES != 0 {
        255
    } else {
        31
    };
    let mut walker = Walker {
        r,
        at: 8,
        len,
        max_name,
    };
    let multi_part = flags & FLAG_MULTI_PART != 0;
    let mut chunks = 0u64;
    for part in 0.. {
        if part == MAX_PARTS {
            return Err(format!("more than {MAX_PARTS} parts"));
        }
        let part = walker.header(flags & FLAG_TILED != 0)?;
        // The data window, and a tile (OpenEXR sizes a tile's buffer from the tile description alone).
        for (w, h) in part.size.into_iter().chain(part.tile) {
            let bytes = [w, super::decoded_rows(h as usize), part.channels.max(1), 4]
                .into_iter()
                .try_fold(1u64, |acc, n| acc.checked_mul(n));
            if bytes.is_none_or(|b| b > max_bytes) {
                return Err(format!(
                    "its data window or tile of {w} x {h} pixels and {} channels would take more than the {} allowed",
                    part.channels,
                    crate::util::input_file::human_bytes(max_bytes)
                ));
            }
        }
        chunks = chunks.saturating_add(part.chunks);
        // One header unless multi-part, whose list ends with an empty name.
        if !multi_part || walker.at_end_of_list()? {
            break;
        }
    }
    let table = chunks.saturating_mul(8);
    if table > len - walker.at.min(len) {
        return Err(format!(
            "its header declares {chunks} chunks, whose offset table alone ({table} bytes) is more than the {} \
             bytes after the header",
            len - walker.at.min(len)
        ));
    }
    Ok(())
}

/// The most bytes of one attribute's value kept for the checks (a channel list of 4096 channels of 16-byte names).
const MAX_KEPT: u64 = 1 << 17;

/// Why a value of type `kind` declared `size` bytes long (its first [`MAX_KEPT`] bytes, `value`) does not have the
/// size OpenEXR 3.1 reads for it, or `None` (also for a type OpenEXR does not know, which it reads by the declared
/// size). Channel lists and string vectors are walked whole, so longer ones than [`MAX_KEPT`] are refused.
fn wrong_size(kind: &[u8], value: &[u8], size: u64) -> Option<String> {
    if matches!(kind, b"chlist" | b"stringvector") && size > MAX_KEPT {
        return Some(format!(
            "a {size}-byte value, more than the {MAX_KEPT} read here"
        ));
    }
    let fixed = match kind {
        b"compression" | b"deepImageState" | b"envmap" | b"lineOrder" => 1,
        b"float" | b"int" => 4,
        b"double" | b"rational" | b"timecode" | b"v2f" | b"v2i" => 8,
        b"tiledesc" => 9,
        b"v3f" | b"v3i" => 12,
        b"box2f" | b"box2i" | b"v2d" => 16,
        b"v3d" => 24,
        b"keycode" => 28,
        b"chromaticities" => 32,
        b"m33f" => 36,
        b"m44f" => 64,
        b"m33d" => 72,
        b"m44d" => 128,
        b"chlist" => return channel_list_size(value),
        b"preview" => {
            // Width and height, then width × height RGBA bytes, which OpenEXR allocates from the two.
            let dim = |i: usize| {
                value
                    .get(4 * i..4 * i + 4)
                    .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            };
            let pixels = dim(0)
                .zip(dim(1))
                .map(|(w, h)| u64::from(w) * u64::from(h) * 4 + 8);
            return (pixels != Some(size)).then(|| "a preview image of another size".to_owned());
        }
        b"stringvector" => return string_vector_size(value),
        _ => return None,
    };
    (size != fixed).then(|| format!("declares {size} bytes for a {fixed}-byte value"))
}

/// Why a channel list does not end, after whole entries (a name, then 16 bytes), exactly at its last byte.
fn channel_list_size(value: &[u8]) -> Option<String> {
    let mut at = 0;
    loop {
        let Some(end) = value[at..].iter().position(|&b| b == 0) else {
            return Some("a channel list without its end".to_owned());
        };
        if end == 0 {
            return (at + 1 != value.len())
                .then(|| "a channel list that ends before its declared size".to_owned());
        }
        if end > 255 {
            return Some("a channel name of more than 255 bytes".to_owned());
        }
        at += end + 1 + 16;
        if at >= value.len() {
            return Some("a channel list without its end".to_owned());
        }
    }
}

/// Why a string vector's strings (each a 4-byte length and its bytes) do not fill it exactly.
fn string_vector_size(value: &[u8]) -> Option<String> {
    let mut at = 0usize;
    while at < value.len() {
        let Some(b) = value.get(at..at + 4) else {
            return Some("a string vector cut inside a length".to_owned());
        };
        let n = i32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        if n < 0 || at + 4 + n as usize > value.len() {
            return Some(format!(
                "a string of {n} bytes past the string vector's end"
            ));
        }
        at += 4 + n as usize;
    }
    None
}

struct Walker<R> {
    r: R,
    at: u64,
    len: u64,
    max_name: usize,
}

impl<R: BufRead> Walker<R> {
    /// A null-terminated name of at most `max_name` bytes; empty at the end of a header.
    fn name(&mut self, what: &str) -> Result<Vec<u8>, String> {
        let mut name = Vec::new();
        let mut limited = (&mut self.r).take(self.max_name as u64 + 1);
        limited
            .read_until(0, &mut name)
            .map_err(|e| e.to_string())?;
        self.at += name.len() as u64;
        if name.pop() != Some(0) {
            return Err(format!(
                "an {what} is not ended within {} bytes (or the file ends)",
                self.max_name
            ));
        }
        Ok(name)
    }

    /// An attribute's value of `size` bytes (already checked to fit the file): kept whole when it is at most
    /// [`MAX_KEPT`] bytes, else its first [`MAX_KEPT`] bytes with the rest skipped.
    fn value(&mut self, size: u64) -> Result<Vec<u8>, String> {
        let mut value = Vec::new();
        (&mut self.r)
            .take(size.min(MAX_KEPT))
            .read_to_end(&mut value)
            .map_err(|e| e.to_string())?;
        io::copy(
            &mut (&mut self.r).take(size - value.len() as u64),
            &mut io::sink(),
        )
        .map_err(|e| e.to_string())?;
        self.at += size;
        Ok(value)
    }

    /// Whether the next byte ends a multi-part file's list of headers (consumed if so).
    fn at_end_of_list(&mut self) -> Result<bool, String> {
        let buf = self.r.fill_buf().map_err(|e| e.to_string())?;
        match buf.first() {
            None => Err("the file ends inside its headers".to_owned()),
            Some(0) => {
                self.r.consume(1);
                self.at += 1;
                Ok(true)
            }
            Some(_) => Ok(false),
        }
    }

    /// Walks one header; returns the chunks its data window and tiling declare (at least).
    fn header(&mut self, tiled_file: bool) -> Result<Part, String> {
        let mut window = None;
        let mut channels = 0u64;
        let mut tiles = None;
        let mut chunk_count = None;
        let mut compression = None;
        let mut tiled = tiled_file;
        loop {
            let name = self.name("attribute name")?;
            if name.is_empty() {
                break;
            }
            let kind = self.name("attribute type")?;
            let mut size = [0u8; 4];
            self.r
                .read_exact(&mut size)
                .map_err(|_| "the file ends inside its header".to_owned())?;
            self.at += 4;
            let size = i32::from_le_bytes(size);
            let left = self.len - self.at.min(self.len);
            let label = String::from_utf8_lossy(&name).into_owned();
            if size < 0 || size as u64 > left {
                return Err(format!(
                    "attribute {label:?} declares {size} bytes, and the file has {left} left"
                ));
            }
            let value = self.value(size as u64)?;
            let int = |i: usize| {
                value
                    .get(4 * i..4 * i + 4)
                    .map(|b| i64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])))
            };
            if let Some(m) = wrong_size(&kind, &value, size as u64) {
                return Err(format!("attribute {label:?}: {m}"));
            }
            match (name.as_slice(), kind.as_slice()) {
                (b"dataWindow", b"box2i") => {
                    window = Some([0, 1, 2, 3].map(|i| int(i).unwrap_or(0)))
                }
                (b"tiles", b"tiledesc") => tiles = Some([0, 1].map(|i| int(i).unwrap_or(0))),
                (b"chunkCount", b"int") => chunk_count = int(0),
                // Whole entries (checked above): a name and 16 bytes each, then the closing empty name.
                (b"channels", b"chlist") => {
                    let (mut at, mut n) = (0usize, 0u64);
                    while let Some(end) =
                        value.get(at..).and_then(|v| v.iter().position(|&b| b == 0))
                    {
                        if end == 0 {
                            break;
                        }
                        at += end + 1 + 16;
                        n += 1;
                    }
                    channels = n;
                }
                (b"compression", b"compression") => compression = value.first().copied(),
                (b"type", b"string") => tiled |= value.starts_with(b"tiled"),
                _ => {}
            }
        }
        // A chunk holds one tile, or the scan lines of one block of the compression (OpenEXR's table).
        let lines = match compression {
            Some(0..=2) => 1,
            Some(3 | 5) => 16,
            Some(9) => 256,
            _ => 32,
        };
        let from_window = window.map_or(0, |[x0, y0, x1, y1]| {
            let (w, h) = ((x1 - x0 + 1).max(0) as u64, (y1 - y0 + 1).max(0) as u64);
            match (tiled, tiles) {
                (true, Some([tw, th])) if tw > 0 && th > 0 => {
                    w.div_ceil(tw as u64).saturating_mul(h.div_ceil(th as u64))
                }
                _ => h.div_ceil(lines),
            }
        });
        Ok(Part {
            chunks: chunk_count.map_or(from_window, |c| c.max(0) as u64),
            size: window
                .map(|[x0, y0, x1, y1]| ((x1 - x0 + 1).max(0) as u64, (y1 - y0 + 1).max(0) as u64)),
            channels,
            tile: tiles
                .filter(|_| tiled)
                .map(|[tw, th]| (tw.max(0) as u64, th.max(0) as u64)),
        })
    }
}

/// What one header declares that the checks read.
struct Part {
    /// Chunks its offset table holds.
    chunks: u64,
    /// The data window's width and height.
    size: Option<(u64, u64)>,
    /// Channels in its channel list.
    channels: u64,
    /// A tile's width and height, for a tiled part.
    tile: Option<(u64, u64)>,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scan-line header of `attributes` (name, type, value) after the magic number and a version field.
    fn exr(attributes: &[(&str, &str, Vec<u8>)], declared: Option<i32>) -> Vec<u8> {
        let mut b = MAGIC.to_vec();
        b.extend(2u32.to_le_bytes());
        for (name, kind, value) in attributes {
            b.extend(name.as_bytes());
            b.push(0);
            b.extend(kind.as_bytes());
            b.push(0);
            b.extend(declared.unwrap_or(value.len() as i32).to_le_bytes());
            b.extend(value);
        }
        b.push(0);
        b
    }

    fn window(x1: i32, y1: i32) -> (&'static str, &'static str, Vec<u8>) {
        let v: Vec<u8> = [0, 0, x1, y1]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        ("dataWindow", "box2i", v)
    }

    #[test]
    fn a_header_that_fits_its_file_passes_and_other_formats_are_left_alone() {
        let mut file = exr(&[window(7, 7)], None);
        file.extend([0u8; 8]);
        assert_eq!(
            check(file.as_slice(), file.len() as u64, true, u64::MAX),
            Ok(())
        );
        let png = b"\x89PNG\r\n\x1a\n....";
        assert_eq!(check(&png[..], png.len() as u64, false, u64::MAX), Ok(()));
        assert_eq!(check(&b"ab"[..], 2, false, u64::MAX), Ok(()));
        assert!(check(&png[..], png.len() as u64, true, u64::MAX).is_err());
    }

    #[test]
    fn an_attribute_larger_than_the_file_is_refused() {
        let file = exr(
            &[("comments", "string", b"x".to_vec())],
            Some(1_879_048_192),
        );
        let e = check(file.as_slice(), file.len() as u64, true, u64::MAX).unwrap_err();
        assert!(e.contains("\"comments\" declares 1879048192 bytes"), "{e}");
        let file = exr(&[("comments", "string", b"x".to_vec())], Some(-5));
        assert!(check(file.as_slice(), file.len() as u64, true, u64::MAX).is_err());
    }

    #[test]
    fn a_data_window_whose_offset_table_the_file_cannot_hold_is_refused() {
        let mut file = exr(&[window(7, 1 << 30)], None);
        file.extend([0u8; 64]);
        let e = check(file.as_slice(), file.len() as u64, true, u64::MAX).unwrap_err();
        assert!(e.contains("chunks, whose offset table alone"), "{e}");
    }

    /// A known type whose declared size is not the one OpenEXR reads is refused: OpenEXR would read on from the
    /// middle of the header. The channel list of cuticle's own tiles passes; one a byte short does not.
    #[test]
    fn known_types_must_declare_the_size_openexr_reads() {
        let mut long_box = window(7, 7);
        long_box.2.extend([0u8; 4]);
        let file = exr(&[long_box], None);
        let e = check(file.as_slice(), file.len() as u64, true, u64::MAX).unwrap_err();
        assert!(e.contains("declares 20 bytes for a 16-byte value"), "{e}");
        let channel = |name: &str| {
            let mut v = name.as_bytes().to_vec();
            v.push(0);
            v.extend([2, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0]);
            v
        };
        let mut list: Vec<u8> = ["A", "B", "G", "R"]
            .iter()
            .flat_map(|n| channel(n))
            .collect();
        list.push(0);
        let mut file = exr(&[("channels", "chlist", list.clone()), window(7, 7)], None);
        file.extend([0u8; 8]);
        assert_eq!(
            check(file.as_slice(), file.len() as u64, true, u64::MAX),
            Ok(())
        );
        list.remove(3);
        let file = exr(&[("channels", "chlist", list), window(7, 7)], None);
        assert!(check(file.as_slice(), file.len() as u64, true, u64::MAX).is_err());
        let mut strings = 3i32.to_le_bytes().to_vec();
        strings.extend(b"abc");
        strings.extend(1_000_000i32.to_le_bytes());
        let file = exr(&[("names", "stringvector", strings)], None);
        let e = check(file.as_slice(), file.len() as u64, true, u64::MAX).unwrap_err();
        assert!(e.contains("a string of 1000000 bytes past"), "{e}");
    }

    /// A data window whose pixels would pass the bound is refused before OpenEXR sizes its buffers from it.
    #[test]
    fn a_data_window_larger_than_the_bound_is_refused() {
        let mut file = exr(&[window((1 << 28) - 1, 0)], None);
        file.extend([0u8; 64]);
        let e = check(file.as_slice(), file.len() as u64, true, 64 << 20).unwrap_err();
        assert!(
            e.contains("data window or tile of 268435456 x 1 pixels"),
            "{e}"
        );
        assert_eq!(
            check(file.as_slice(), file.len() as u64, true, u64::MAX),
            Ok(())
        );
    }

    #[test]
    fn names_must_end_and_the_file_must_not_end_inside_a_header() {
        let mut file = MAGIC.to_vec();
        file.extend(2u32.to_le_bytes());
        file.extend([b'a'; 40]);
        assert!(check(file.as_slice(), file.len() as u64, true, u64::MAX).is_err());
        let file = exr(&[window(7, 7)], None);
        let cut = &file[..file.len() - 6];
        assert!(check(cut, cut.len() as u64, true, u64::MAX).is_err());
    }
}
