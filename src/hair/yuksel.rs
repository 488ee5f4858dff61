//! Cem Yuksel's `.hair` format (<http://www.cemyuksel.com/research/hairmodels/>): reader and writer.
//!
//! Layout, all little-endian:
//!
//! | bytes  | field                                                                      |
//! |--------|----------------------------------------------------------------------------|
//! | 0..4   | magic `"HAIR"`                                                             |
//! | 4..8   | u32 strand count                                                           |
//! | 8..12  | u32 point count (all strands)                                              |
//! | 12..16 | u32 flags: which arrays follow ([`HAS_SEGMENTS`] … [`HAS_COLORS`])         |
//! | 16..20 | u32 default segments per strand (used when there is no segments array)     |
//! | 20..24 | f32 default thickness                                                      |
//! | 24..28 | f32 default transparency                                                   |
//! | 28..40 | f32×3 default colour                                                       |
//! | 40..128| 88-byte info string (NUL-padded)                                           |
//!
//! Then the arrays whose flag is set, in this order: segments (u16 per strand), points (f32×3 per point), thickness
//! (f32 per point), transparency (f32 per point), colours (f32×3 per point). A strand of k segments has k + 1
//! points. Thickness is a *diameter*: the model's radius is half of it.
//!
//! The reader is strict: the file size must be exactly what the header and flags imply, the segments must add up to
//! the point count, and the model must pass [`HairModel::validate`]. Every error names the file and gives the
//! numbers that disagree.

use std::path::Path;

use glam::Vec3;

use super::{f32_at, u32_at};
use super::{HairError, HairModel};

/// The first four bytes of every `.hair` file.
pub const MAGIC: [u8; 4] = *b"HAIR";
/// Size of the fixed header, bytes.
pub const HEADER_SIZE: usize = 128;
/// Size of the header's info string, bytes.
pub const INFO_SIZE: usize = 88;

/// Flag bit: a segments array (u16 per strand) is present.
pub const HAS_SEGMENTS: u32 = 1 << 0;
/// Flag bit: a points array (f32×3 per point) is present. Required.
pub const HAS_POINTS: u32 = 1 << 1;
/// Flag bit: a thickness array (f32 diameter per point) is present.
pub const HAS_THICKNESS: u32 = 1 << 2;
/// Flag bit: a transparency array (f32 per point) is present.
pub const HAS_TRANSPARENCY: u32 = 1 << 3;
/// Flag bit: a colour array (f32×3 per point) is present.
pub const HAS_COLORS: u32 = 1 << 4;
const KNOWN_FLAGS: u32 = HAS_SEGMENTS | HAS_POINTS | HAS_THICKNESS | HAS_TRANSPARENCY | HAS_COLORS;

/// The `format` string of models read from `.hair` files.
pub const FORMAT: &str = "cem yuksel .hair";

/// The fixed 128-byte header of a `.hair` file.
#[derive(Debug, Clone, PartialEq)]
pub struct Header {
    /// Number of strands.
    pub strand_count: u32,
    /// Number of points in all strands.
    pub point_count: u32,
    /// Which arrays follow the header ([`HAS_SEGMENTS`], [`HAS_POINTS`], …).
    pub flags: u32,
    /// Segments per strand when there is no segments array.
    pub default_segments: u32,
    /// Thickness (diameter) of every point when there is no thickness array.
    pub default_thickness: f32,
    /// Transparency of every point when there is no transparency array.
    pub default_transparency: f32,
    /// Colour of every point when there is no colour array.
    pub default_color: [f32; 3],
    /// The free-text info field, up to its first NUL.
    pub info: String,
}

/// One array after the header: its name (for messages), flag, and bytes per element.
struct Array {
    name: &'static str,
    flag: u32,
    per_strand: bool,
    element_size: u64,
}

/// The arrays in file order.
const ARRAYS: [Array; 5] = [
    Array {
        name: "segments",
        flag: HAS_SEGMENTS,
        per_strand: true,
        element_size: 2,
    },
    Array {
        name: "points",
        flag: HAS_POINTS,
        per_strand: false,
        element_size: 12,
    },
    Array {
        name: "thickness",
        flag: HAS_THICKNESS,
        per_strand: false,
        element_size: 4,
    },
    Array {
        name: "transparency",
        flag: HAS_TRANSPARENCY,
        per_strand: false,
        element_size: 4,
    },
    Array {
        name: "colors",
        flag: HAS_COLORS,
        per_strand: false,
        element_size: 12,
    },
];

impl Header {
    /// Parses and checks the header at the start of `bytes`: magic, length, known flags, a points array.
    pub fn parse(path: &Path, bytes: &[u8]) -> Result<Header, HairError> {
        if bytes.is_empty() {
            return Err(HairError::invalid(
                path,
                format!(
                    "empty file (0 bytes); a .hair file starts with a {HEADER_SIZE}-byte header"
                ),
            ));
        }
        let magic_len = bytes.len().min(MAGIC.len());
        if bytes[..magic_len] != MAGIC[..magic_len] {
            return Err(HairError::invalid(
                path,
                format!(
                    "not a cem yuksel .hair file: it starts with \"{}\", expected the magic \"HAIR\"",
                    bytes[..magic_len].escape_ascii()
                ),
            ));
        }
        if bytes.len() < HEADER_SIZE {
            return Err(HairError::invalid(
                path,
                format!(
                    "truncated header: the file has {} bytes, the header alone needs {HEADER_SIZE}",
                    bytes.len()
                ),
            ));
        }
        let info = &bytes[40..HEADER_SIZE];
        let info_len = info.iter().position(|&b| b == 0).unwrap_or(INFO_SIZE);
        let header = Header {
            strand_count: u32_at(bytes, 4),
            point_count: u32_at(bytes, 8),
            flags: u32_at(bytes, 12),
            default_segments: u32_at(bytes, 16),
            default_thickness: f32_at(bytes, 20),
            default_transparency: f32_at(bytes, 24),
            default_color: [f32_at(bytes, 28), f32_at(bytes, 32), f32_at(bytes, 36)],
            info: String::from_utf8_lossy(&info[..info_len])
                .trim_end()
                .to_owned(),
        };
        if header.flags & !KNOWN_FLAGS != 0 {
            return Err(HairError::invalid(
                path,
                format!(
                    "unknown flag bits 0x{:x} in flags 0x{:x} (known: 0x{KNOWN_FLAGS:x}); the array layout is unknown",
                    header.flags & !KNOWN_FLAGS,
                    header.flags
                ),
            ));
        }
        if header.flags & HAS_POINTS == 0 {
            return Err(HairError::invalid(
                path,
                format!(
                    "flags 0x{:x} declare no points array; a .hair file must store points",
                    header.flags
                ),
            ));
        }
        if header.strand_count == 0 {
            return Err(HairError::invalid(path, "the header declares 0 strands"));
        }
        Ok(header)
    }

    /// The arrays present, in file order, with their byte range (u64: counts come from the file and may be huge).
    fn layout(&self) -> Vec<(&'static str, std::ops::Range<u64>)> {
        let mut offset = HEADER_SIZE as u64;
        ARRAYS
            .iter()
            .filter(|a| self.flags & a.flag != 0)
            .map(|a| {
                let count = if a.per_strand {
                    self.strand_count
                } else {
                    self.point_count
                };
                let range = offset..offset + u64::from(count) * a.element_size;
                offset = range.end;
                (a.name, range)
            })
            .collect()
    }

    /// The counts and arrays, for messages: "10000 strands, 160000 points, flags 0x12 (points, colors)".
    fn describe(&self) -> String {
        format!(
            "{} strands, {} points, flags 0x{:x} ({})",
            self.strand_count,
            self.point_count,
            self.flags,
            self.layout()
                .iter()
                .map(|(name, _)| *name)
                .collect::<Vec<_>>()
                .join(", ")
        )
    }
}

/// Reads a `.hair` file and parses it with [`parse`]. Only a regular file is read, and only once its size is what
/// its header declares: a header claiming 2³² strands or a file with gigabytes of trailing data is refused after
/// reading 128 bytes, before anything is allocated for it.
pub fn read(path: &Path) -> Result<HairModel, HairError> {
    use crate::util::input_file::{open_with_head, read_rest};
    let io = |source| HairError::Io {
        path: path.to_path_buf(),
        source,
    };
    let (file, file_len, head) = open_with_head(path, HEADER_SIZE).map_err(io)?;
    Header::parse(path, &head)?.check_file_len(path, file_len)?;
    // The size matches the header, so the file is exactly `file_len` bytes of declared arrays.
    let bytes = read_rest(file, head, file_len).map_err(io)?;
    parse(path, &bytes)
}

impl Header {
    /// The file size the header and flags imply.
    pub fn expected_len(&self) -> u64 {
        self.layout()
            .last()
            .map_or(HEADER_SIZE as u64, |(_, r)| r.end)
    }

    /// The points the strands hold by the header alone (strands × (default segments + 1)), when there is no
    /// segments array.
    fn default_points(&self) -> Option<u64> {
        (self.flags & HAS_SEGMENTS == 0)
            .then(|| u64::from(self.strand_count) * (u64::from(self.default_segments) + 1))
    }

    fn point_count_mismatch(&self, path: &Path, points_in_strands: u64) -> HairError {
        let how = if self.flags & HAS_SEGMENTS != 0 {
            format!(
                "the segments array implies {points_in_strands} points (segments + 1 per strand)"
            )
        } else {
            format!(
                "{} strands × ({} default segments + 1) = {points_in_strands} points",
                self.strand_count, self.default_segments
            )
        };
        HairError::invalid(
            path,
            format!(
                "point count mismatch: the header declares {} points but {how}",
                self.point_count
            ),
        )
    }

    /// Checks a file of `file_len` bytes against the header alone (nothing read or allocated): the default
    /// segments against the point count, then every array against the file's end, then trailing bytes.
    pub fn check_file_len(&self, path: &Path, file_len: u64) -> Result<(), HairError> {
        if let Some(n) = self.default_points() {
            if n != u64::from(self.point_count) {
                return Err(self.point_count_mismatch(path, n));
            }
        }
        let expected_len = self.expected_len();
        if let Some((name, range)) = self.layout().into_iter().find(|(_, r)| r.end > file_len) {
            return Err(HairError::invalid(
                path,
                format!(
                    "truncated in the {name} array: it needs bytes {}..{} but the file has {file_len} bytes \
                     (header: {}; expected {expected_len} bytes in all)",
                    range.start,
                    range.end,
                    self.describe()
                ),
            ));
        }
        if file_len > expected_len {
            return Err(HairError::invalid(
                path,
                format!(
                    "{} bytes of trailing data: the file has {file_len} bytes but the header ({}) accounts for {expected_len} bytes",
                    file_len - expected_len,
                    self.describe()
                ),
            ));
        }
        Ok(())
    }
}

/// Parses the bytes of a `.hair` file; `path` names it in errors. Nothing proportional to the header's counts is
/// allocated before the byte count is checked against them, so any byte string (a fuzzer's) is safe to pass.
pub fn parse(path: &Path, bytes: &[u8]) -> Result<HairModel, HairError> {
    // One piece: the header's counts are checked against the byte length before each array is read, in file order.
    let header = Header::parse(path, bytes)?;
    let layout = header.layout();
    let file_len = bytes.len() as u64;
    let section = |name: &str| -> Option<&[u8]> {
        layout
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, r)| &bytes[r.start as usize..r.end as usize])
    };

    // Strand lengths first: a point count that disagrees with them is the root cause of any size mismatch. Summed
    // straight from the bytes (when they are there), without allocating.
    if let Some((_, r)) = layout.iter().find(|(n, _)| *n == "segments") {
        if r.end <= file_len {
            let b = &bytes[r.start as usize..r.end as usize];
            let points_in_strands: u64 = b
                .chunks_exact(2)
                .map(|c| u64::from(u16::from_le_bytes([c[0], c[1]])) + 1)
                .sum();
            if points_in_strands != u64::from(header.point_count) {
                return Err(header.point_count_mismatch(path, points_in_strands));
            }
        }
    }
    header.check_file_len(path, file_len)?;
    // From here on every array is inside `bytes`: allocations are bounded by the input's length.
    let segments: Vec<u32> = match section("segments") {
        Some(b) => b
            .chunks_exact(2)
            .map(|c| u32::from(u16::from_le_bytes([c[0], c[1]])))
            .collect(),
        None => vec![header.default_segments; header.strand_count as usize],
    };

    let n = header.point_count as usize;
    let vec3s = |b: &[u8]| -> Vec<[f32; 3]> {
        b.chunks_exact(12)
            .map(|c| [f32_at(c, 0), f32_at(c, 4), f32_at(c, 8)])
            .collect()
    };
    let floats = |b: &[u8]| -> Vec<f32> { b.chunks_exact(4).map(|c| f32_at(c, 0)).collect() };

    let points: Vec<Vec3> = vec3s(section("points").unwrap_or_default())
        .into_iter()
        .map(Vec3::from)
        .collect();
    let radius_from_file = header.flags & HAS_THICKNESS != 0;
    let radius = match section("thickness") {
        Some(b) => floats(b).into_iter().map(|t| 0.5 * t).collect(),
        None => {
            let t = header.default_thickness;
            if !(t.is_finite() && t > 0.0) {
                return Err(HairError::invalid(
                    path,
                    format!("the header's default thickness is {t} (must be > 0) and there is no thickness array"),
                ));
            }
            vec![0.5 * t; n]
        }
    };
    let transparency = match section("transparency") {
        Some(b) => floats(b),
        None => {
            let t = header.default_transparency;
            if !(0.0..=1.0).contains(&t) {
                return Err(HairError::invalid(
                    path,
                    format!(
                        "the header's default transparency is {t} (must be in [0, 1]) and there is no transparency array"
                    ),
                ));
            }
            vec![t; n]
        }
    };
    let color = match section("colors") {
        Some(b) => {
            let color = vec3s(b);
            if let Some(i) = color.iter().position(|c| !c.iter().all(|x| x.is_finite())) {
                return Err(HairError::invalid(
                    path,
                    format!("point {i} has a non-finite colour {:?}", color[i]),
                ));
            }
            color
        }
        None => {
            let c = header.default_color;
            if !c.iter().all(|x| x.is_finite()) {
                return Err(HairError::invalid(
                    path,
                    format!("the header's default colour {c:?} is not finite and there is no colour array"),
                ));
            }
            vec![c; n]
        }
    };

    let mut strand_offsets = Vec::with_capacity(segments.len() + 1);
    strand_offsets.push(0u32);
    let mut end = 0u32;
    for k in &segments {
        // Cannot overflow: the sum of (k + 1) equals the u32 point count, checked above.
        end += k + 1;
        strand_offsets.push(end);
    }

    let model = HairModel {
        points,
        strand_offsets,
        radius,
        radius_from_file,
        transparency,
        color,
        format: FORMAT.to_owned(),
        info: header.info,
    };
    model.validate(path)?;
    Ok(model)
}

/// Writes `model` as a `.hair` file (see [`encode`] for what is stored).
pub fn write(path: &Path, model: &HairModel) -> Result<(), HairError> {
    let bytes = encode(path, model)?;
    std::fs::write(path, bytes).map_err(|source| HairError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Encodes `model` as the bytes of a `.hair` file; `path` names the destination in errors.
///
/// Arrays whose values are all equal become header defaults: no segments array when every strand has the same
/// number of points, no transparency or colour array when they are uniform, and no thickness array when the radius
/// is uniform and not from a file (so [`parse`] gives back `radius_from_file == false`). Everything else is stored
/// per point, so `parse(encode(m))` reproduces `m`'s arrays exactly. The info string is cut to 87 bytes (at a
/// character boundary) to keep a terminating NUL for C readers.
pub fn encode(path: &Path, model: &HairModel) -> Result<Vec<u8>, HairError> {
    model.validate(path)?;
    let strand_count = model.strand_count();
    let point_count = model.points.len();
    let too_many = |what: &str, n: usize| {
        HairError::invalid(
            path,
            format!("{n} {what} do not fit the .hair format's 32-bit counts"),
        )
    };
    let strand_count_u32 =
        u32::try_from(strand_count).map_err(|_| too_many("strands", strand_count))?;
    let point_count_u32 =
        u32::try_from(point_count).map_err(|_| too_many("points", point_count))?;

    let lengths: Vec<usize> = (0..strand_count)
        .map(|s| model.strand_range(s).len())
        .collect();
    if let Some(s) = lengths.iter().position(|&n| n - 1 > usize::from(u16::MAX)) {
        return Err(HairError::invalid(
            path,
            format!(
                "strand {s} has {} segments; the .hair format holds at most {} per strand",
                lengths[s] - 1,
                u16::MAX
            ),
        ));
    }
    let uniform_segments = lengths.iter().all(|&n| n == lengths[0]);
    let all_equal = |v: &[f32]| v.iter().all(|x| x.to_bits() == v[0].to_bits());
    let thickness_array = model.radius_from_file || !all_equal(&model.radius);
    let transparency_array = !all_equal(&model.transparency);
    let color_array = !model
        .color
        .iter()
        .all(|c| c.map(f32::to_bits) == model.color[0].map(f32::to_bits));

    let mut flags = HAS_POINTS;
    for (present, flag) in [
        (!uniform_segments, HAS_SEGMENTS),
        (thickness_array, HAS_THICKNESS),
        (transparency_array, HAS_TRANSPARENCY),
        (color_array, HAS_COLORS),
    ] {
        if present {
            flags |= flag;
        }
    }

    let mut out = Vec::with_capacity(HEADER_SIZE + 2 * strand_count + 32 * point_count);
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&strand_count_u32.to_le_bytes());
    out.extend_from_slice(&point_count_u32.to_le_bytes());
    out.extend_from_slice(&flags.to_le_bytes());
    // Fits: checked against u16::MAX above.
    out.extend_from_slice(&((lengths[0] - 1) as u32).to_le_bytes());
    out.extend_from_slice(&(2.0 * model.radius[0]).to_le_bytes());
    out.extend_from_slice(&model.transparency[0].to_le_bytes());
    for x in model.color[0] {
        out.extend_from_slice(&x.to_le_bytes());
    }
    let mut info_len = model.info.len().min(INFO_SIZE - 1);
    while !model.info.is_char_boundary(info_len) {
        info_len -= 1;
    }
    out.extend_from_slice(&model.info.as_bytes()[..info_len]);
    out.resize(HEADER_SIZE, 0);

    if flags & HAS_SEGMENTS != 0 {
        for &n in &lengths {
            out.extend_from_slice(&((n - 1) as u16).to_le_bytes());
        }
    }
    for p in &model.points {
        for x in p.to_array() {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
    if flags & HAS_THICKNESS != 0 {
        for r in &model.radius {
            out.extend_from_slice(&(2.0 * r).to_le_bytes());
        }
    }
    if flags & HAS_TRANSPARENCY != 0 {
        for t in &model.transparency {
            out.extend_from_slice(&t.to_le_bytes());
        }
    }
    if flags & HAS_COLORS != 0 {
        for c in &model.color {
            for x in c {
                out.extend_from_slice(&x.to_le_bytes());
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two strands (3 and 2 points) with every array varying, so every flag is exercised.
    fn model() -> HairModel {
        HairModel {
            points: vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
                Vec3::new(0.5, 2.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(1.0, 1.0, 1.0),
            ],
            strand_offsets: vec![0, 3, 5],
            radius: vec![0.1, 0.08, 0.06, 0.1, 0.05],
            radius_from_file: true,
            transparency: vec![0.0, 0.1, 0.2, 0.3, 0.4],
            color: vec![
                [1.0, 0.5, 0.25],
                [0.9, 0.5, 0.25],
                [0.8, 0.5, 0.25],
                [0.1, 0.2, 0.3],
                [0.1, 0.2, 0.4],
            ],
            format: FORMAT.to_owned(),
            info: "unit test".to_owned(),
        }
    }

    #[test]
    fn encode_parse_round_trip_with_every_array() {
        let path = Path::new("mem.hair");
        let m = model();
        let bytes = encode(path, &m).unwrap();
        let h = Header::parse(path, &bytes).unwrap();
        assert_eq!(h.flags, KNOWN_FLAGS);
        assert_eq!(bytes.len(), HEADER_SIZE + 2 * 2 + 5 * (12 + 4 + 4 + 12));
        let back = parse(path, &bytes).unwrap();
        assert_eq!(back.points, m.points);
        assert_eq!(back.strand_offsets, m.strand_offsets);
        assert_eq!(back.radius, m.radius);
        assert!(back.radius_from_file);
        assert_eq!(back.transparency, m.transparency);
        assert_eq!(back.color, m.color);
        assert_eq!(back.info, "unit test");
    }

    #[test]
    fn uniform_arrays_become_header_defaults() {
        let path = Path::new("mem.hair");
        let mut m = model();
        m.strand_offsets = vec![0, 2, 4];
        m.points.truncate(4);
        m.radius = vec![0.05; 4];
        m.radius_from_file = false;
        m.transparency = vec![0.25; 4];
        m.color = vec![[0.5; 3]; 4];
        let bytes = encode(path, &m).unwrap();
        let h = Header::parse(path, &bytes).unwrap();
        assert_eq!(h.flags, HAS_POINTS);
        assert_eq!(
            (
                h.default_segments,
                h.default_thickness,
                h.default_transparency
            ),
            (1, 0.1, 0.25)
        );
        assert_eq!(bytes.len(), HEADER_SIZE + 4 * 12);
        let back = parse(path, &bytes).unwrap();
        assert!(!back.radius_from_file);
        assert_eq!(back.radius, m.radius);
        assert_eq!(back.color, m.color);
    }

    #[test]
    fn long_info_is_cut_at_a_char_boundary() {
        let path = Path::new("mem.hair");
        let mut m = model();
        m.info = "é".repeat(60); // 120 bytes
        let back = parse(path, &encode(path, &m).unwrap()).unwrap();
        assert_eq!(
            back.info,
            "é".repeat(43),
            "86 bytes: the largest char boundary <= 87"
        );
    }

    #[test]
    fn short_non_magic_prefix_is_bad_magic_and_magic_prefix_is_truncation() {
        let path = Path::new("x.hair");
        let e = parse(path, b"HA").unwrap_err().to_string();
        assert!(e.contains("truncated header"), "{e}");
        let e = parse(path, b"PK").unwrap_err().to_string();
        assert!(e.contains("magic"), "{e}");
    }

    #[test]
    fn unknown_flags_and_missing_points_are_rejected() {
        let path = Path::new("x.hair");
        let mut bytes = encode(path, &model()).unwrap();
        bytes[12..16].copy_from_slice(&(KNOWN_FLAGS | 0x40).to_le_bytes());
        let e = parse(path, &bytes).unwrap_err().to_string();
        assert!(e.contains("unknown flag bits 0x40"), "{e}");
        bytes[12..16].copy_from_slice(&HAS_SEGMENTS.to_le_bytes());
        let e = parse(path, &bytes).unwrap_err().to_string();
        assert!(e.contains("no points array"), "{e}");
    }
}
