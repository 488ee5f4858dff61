//! AMD TressFX 4 `.tfx` files: guide strands, as shipped with the TressFX samples (e.g. Ratboy's mohawk).
//!
//! Layout, all little-endian (`TressFXTFXFileHeader` in TressFX's `TressFXFileFormat.h`):
//!
//! | bytes   | field                                                                            |
//! |---------|----------------------------------------------------------------------------------|
//! | 0..4    | f32 version (4.0)                                                                |
//! | 4..8    | u32 numHairStrands                                                               |
//! | 8..12   | u32 numVerticesPerStrand (every strand has the same count)                       |
//! | 12..16  | u32 offsetVertexPosition: f32×4 (x, y, z, inverse mass) per vertex, strand-major  |
//! | 16..20  | u32 offsetStrandUV: f32×2 per strand, 0 if absent                                |
//! | 20..24  | u32 offsetVertexUV: f32×2 per vertex, 0 if absent                                |
//! | 24..28  | u32 offsetStrandThickness: f32 per strand, 0 if absent                           |
//! | 28..32  | u32 offsetVertexColor: f32×4 per vertex, 0 if absent                             |
//! | 32..160 | `u32 reserved[32]`                                                             |
//!
//! Offsets are bytes from the start of the file. Only the positions are used, as in AMD's own loader
//! (`TressFXAsset::LoadHairData`): the inverse mass `w` is a simulation input, UVs are for textures, and the
//! strand-thickness and vertex-colour arrays have no documented units (AMD's exporters write them as absent). The
//! other arrays are still bounds-checked, so a truncated file is caught wherever it is cut.
//!
//! The file has no thickness, transparency or colour, so the reader supplies defaults:
//!
//! * **radius** = [`RADIUS_PER_SEGMENT`] × the median segment length (the fibre is as wide as a typical segment is
//!   long), tapered by [`Strands::from_model`](super::Strands::from_model) (`radius_from_file` is false). Tying the
//!   radius to the segment length makes it follow the groom's scale whatever the file's units: exporters resample
//!   every strand to the same vertex count, so the segment length is a fixed fraction of the strand length. For
//!   Ratboy's mohawk (median segment 0.0026, median strand 0.080, model 1.1 units across) this gives a root radius
//!   of 0.0013: about 1/850 of the model, inside the 1/300–1/1000 that reads as hair at full-model framing, and
//!   0.6 of TressFX's own default fibre radius (0.0021), which TressFX applies to the guides *plus* the follow
//!   hairs it generates at run time. A physical radius (0.04 mm on a metre-scale model, 0.00004) would leave 2,228
//!   guides as a faint haze; these strands stand for many hairs each.
//! * **transparency** = 0 (opaque; scenes can override the shadow opacity).
//! * **colour** = [`DEFAULT_COLOR`], a medium brown.
//!
//! TressFX requires a power of two from 4 to 64 vertices per strand for its simulation; a renderer only needs 2,
//! so that is all this reader asks.

use std::ops::Range;
use std::path::Path;

use glam::Vec3;

use super::{f32_at, u32_at};
use super::{HairError, HairModel};

/// Size of the fixed header, bytes.
pub const HEADER_SIZE: usize = 160;

/// The `format` string of models read from `.tfx` files.
pub const FORMAT: &str = "tressfx .tfx";

/// Default root radius as a fraction of the file's median segment length (see the module docs for why).
pub const RADIUS_PER_SEGMENT: f32 = 0.5;

/// Default colour (linear RGB): a medium brown. The file stores none; a scene's material usually overrides it.
pub const DEFAULT_COLOR: [f32; 3] = [0.30, 0.17, 0.08];

/// The header fields this reader uses.
#[derive(Debug, Clone, PartialEq)]
pub struct Header {
    /// TressFX version; 4.x is accepted.
    pub version: f32,
    /// Number of (guide) strands.
    pub strand_count: u32,
    /// Vertices in every strand.
    pub vertices_per_strand: u32,
    /// Byte offsets of the arrays, in header order (positions, strand UV, vertex UV, strand thickness, vertex
    /// colour); 0 means absent, except for positions, which are required.
    pub offsets: [u32; 5],
}

/// Names and element sizes (bytes per strand or per vertex) of the arrays, in header order.
const ARRAYS: [(&str, bool, u64); 5] = [
    ("vertex position", false, 16),
    ("strand uv", true, 8),
    ("vertex uv", false, 8),
    ("strand thickness", true, 4),
    ("vertex color", false, 16),
];

impl Header {
    /// Parses and checks the header at the start of `bytes`: length, version, counts.
    pub fn parse(path: &Path, bytes: &[u8]) -> Result<Header, HairError> {
        if bytes.is_empty() {
            return Err(HairError::invalid(
                path,
                format!(
                    "empty file (0 bytes); a tressfx .tfx file starts with a {HEADER_SIZE}-byte header"
                ),
            ));
        }
        let truncated_header = || {
            HairError::invalid(
                path,
                format!(
                    "truncated header: the file has {} bytes, the header alone needs {HEADER_SIZE}",
                    bytes.len()
                ),
            )
        };
        if bytes.len() < 4 {
            return Err(truncated_header());
        }
        // The version is the nearest thing the format has to a magic number.
        let version = f32_at(bytes, 0);
        if !(4.0..5.0).contains(&version) {
            return Err(HairError::invalid(
                path,
                format!(
                    "not a tressfx 4 .tfx file: the version field is {version} (bytes \"{}\"), expected 4.0",
                    bytes[..4].escape_ascii()
                ),
            ));
        }
        if bytes.len() < HEADER_SIZE {
            return Err(truncated_header());
        }
        let header = Header {
            version,
            strand_count: u32_at(bytes, 4),
            vertices_per_strand: u32_at(bytes, 8),
            offsets: [12, 16, 20, 24, 28].map(|o| u32_at(bytes, o)),
        };
        if header.strand_count == 0 {
            return Err(HairError::invalid(path, "the header declares 0 strands"));
        }
        if header.vertices_per_strand < 2 {
            return Err(HairError::invalid(
                path,
                format!(
                    "the header declares {} vertices per strand; a strand needs at least 2",
                    header.vertices_per_strand
                ),
            ));
        }
        Ok(header)
    }

    /// The arrays present, with their byte ranges, in header order. Sizes are computed in u64 with checked
    /// arithmetic: counts come from the file, and a product that overflows is reported against the counts that
    /// caused it (not as a bogus overlap or truncation further on).
    fn layout(&self, path: &Path) -> Result<Vec<(&'static str, Range<u64>)>, HairError> {
        let strands = u64::from(self.strand_count);
        // Cannot overflow: both factors are u32.
        let vertices = strands * u64::from(self.vertices_per_strand);
        let mut out = Vec::with_capacity(ARRAYS.len());
        for (i, (&(name, per_strand, size), offset)) in ARRAYS.iter().zip(self.offsets).enumerate()
        {
            if i != 0 && offset == 0 {
                continue;
            }
            let count = if per_strand { strands } else { vertices };
            let start = u64::from(offset);
            let end = count
                .checked_mul(size)
                .and_then(|bytes| bytes.checked_add(start))
                .ok_or_else(|| {
                    HairError::invalid(
                        path,
                        format!(
                            "the header's counts ({} strands × {} vertices per strand) make the {name} array \
                             larger than any file can be",
                            self.strand_count, self.vertices_per_strand
                        ),
                    )
                })?;
            out.push((name, start..end));
        }
        Ok(out)
    }

    /// Checks the arrays' placement against the header and a file of `file_len` bytes, without reading them:
    /// inside the header, overlapping, truncated, trailing data. Returns the byte range of the positions.
    pub fn check_file_len(&self, path: &Path, file_len: u64) -> Result<Range<u64>, HairError> {
        let mut layout = self.layout(path)?;
        let describe = format!(
            "header: {} strands × {} vertices",
            self.strand_count, self.vertices_per_strand
        );
        let positions = layout[0].1.clone();
        // In file order, so the first problem reported is the first one in the file. Overlaps come before
        // truncation: a wrong count makes an array run into the next one, and the file then looks truncated only
        // as a consequence.
        layout.sort_by_key(|(_, r)| r.start);
        if let Some((name, range)) = layout.iter().find(|(_, r)| r.start < HEADER_SIZE as u64) {
            return Err(HairError::invalid(
                path,
                format!(
                    "the {name} array starts at byte {}, inside the {HEADER_SIZE}-byte header",
                    range.start
                ),
            ));
        }
        for pair in layout.windows(2) {
            let ((a, ra), (b, rb)) = (&pair[0], &pair[1]);
            if rb.start < ra.end {
                return Err(HairError::invalid(
                    path,
                    format!(
                        "the {a} array (bytes {}..{}) overlaps the {b} array (bytes {}..{}) ({describe})",
                        ra.start, ra.end, rb.start, rb.end
                    ),
                ));
            }
        }
        if let Some((name, range)) = layout.iter().find(|(_, r)| r.end > file_len) {
            return Err(HairError::invalid(
                path,
                format!(
                    "truncated in the {name} array: it needs bytes {}..{} but the file has {file_len} bytes ({describe})",
                    range.start, range.end
                ),
            ));
        }
        let end = layout.iter().map(|(_, r)| r.end).max().unwrap_or(0);
        if file_len > end {
            return Err(HairError::invalid(
                path,
                format!(
                    "{} bytes of trailing data: the file has {file_len} bytes but its arrays end at byte {end} ({describe})",
                    file_len - end
                ),
            ));
        }
        Ok(positions)
    }
}

/// Reads a `.tfx` file and parses it with [`parse`]. Only a regular file is read, and only once its size agrees
/// with its header: huge declared counts or trailing gigabytes are refused after reading 160 bytes.
pub fn read(path: &Path) -> Result<HairModel, HairError> {
    use crate::util::input_file::{open_with_head, read_rest};
    let io = |source| HairError::Io {
        path: path.to_path_buf(),
        source,
    };
    let (file, file_len, head) = open_with_head(path, HEADER_SIZE).map_err(io)?;
    Header::parse(path, &head)?.check_file_len(path, file_len)?;
    let bytes = read_rest(file, head, file_len).map_err(io)?;
    parse(path, &bytes)
}

/// Parses the bytes of a `.tfx` file; `path` names it in errors. Nothing is allocated for the arrays before their
/// sizes are checked against `bytes`, so any byte string (a fuzzer's) is safe to pass.
pub fn parse(path: &Path, bytes: &[u8]) -> Result<HairModel, HairError> {
    let header = Header::parse(path, bytes)?;
    let positions = header.check_file_len(path, bytes.len() as u64)?;

    // Positions: x, y, z of each f32×4; w (inverse mass) is for simulation.
    let points: Vec<Vec3> = bytes[positions.start as usize..positions.end as usize]
        .chunks_exact(16)
        .map(|c| Vec3::new(f32_at(c, 0), f32_at(c, 4), f32_at(c, 8)))
        .collect();
    if let Some(i) = points.iter().position(|p| !p.is_finite()) {
        return Err(HairError::invalid(
            path,
            format!("point {i} is not finite: {:?}", points[i]),
        ));
    }
    // The radius is derived from the points' spacing: points too far out would make it infinite and the error
    // blame a thickness the file does not have, so the points are checked first.
    super::check_extent(path, &points, &[], 1.0, "")?;
    let per_strand = header.vertices_per_strand as usize;
    let median = median_segment_length(&points, per_strand);
    if median <= 0.0 {
        return Err(HairError::invalid(
            path,
            format!(
                "the median segment length is {median} (most vertices coincide); cannot choose a default radius"
            ),
        ));
    }
    let n = points.len();
    // Offsets are u32 (Embree's index format); only a file with over 64 GiB of positions could overflow them.
    let strand_offsets = (0..=header.strand_count as usize)
        .map(|s| u32::try_from(s * per_strand))
        .collect::<Result<Vec<u32>, _>>()
        .map_err(|_| {
            HairError::invalid(path, format!("{n} points do not fit 32-bit strand offsets"))
        })?;
    let model = HairModel {
        points,
        strand_offsets,
        radius: vec![RADIUS_PER_SEGMENT * median; n],
        radius_from_file: false,
        transparency: vec![0.0; n],
        color: vec![DEFAULT_COLOR; n],
        format: FORMAT.to_owned(),
        info: String::new(),
    };
    model.validate(path)?;
    Ok(model)
}

/// Median length of all segments, strands of `per_strand` points laid end to end in `points`.
fn median_segment_length(points: &[Vec3], per_strand: usize) -> f32 {
    let mut lengths: Vec<f32> = points
        .chunks_exact(per_strand)
        .flat_map(|strand| strand.windows(2).map(|w| w[0].distance(w[1])))
        .collect();
    if lengths.is_empty() {
        return 0.0;
    }
    let mid = lengths.len() / 2;
    *lengths.select_nth_unstable_by(mid, f32::total_cmp).1
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A minimal file: `strands` straight strands of `per_strand` vertices spaced 0.01 apart along y.
    fn file(strands: u32, per_strand: u32) -> Vec<u8> {
        let mut b = Vec::new();
        b.extend_from_slice(&4.0f32.to_le_bytes());
        b.extend_from_slice(&strands.to_le_bytes());
        b.extend_from_slice(&per_strand.to_le_bytes());
        b.extend_from_slice(&(HEADER_SIZE as u32).to_le_bytes());
        b.resize(HEADER_SIZE, 0);
        for s in 0..strands {
            for k in 0..per_strand {
                for x in [s as f32, 0.01 * k as f32, 0.0, 1.0] {
                    b.extend_from_slice(&x.to_le_bytes());
                }
            }
        }
        b
    }

    #[test]
    fn minimal_file_parses_with_defaults() {
        let m = parse(Path::new("t.tfx"), &file(3, 4)).unwrap();
        assert_eq!(m.strand_count(), 3);
        assert_eq!(m.strand_offsets, vec![0, 4, 8, 12]);
        assert_eq!(m.points[5], Vec3::new(1.0, 0.01, 0.0));
        assert!((m.radius[0] - RADIUS_PER_SEGMENT * 0.01).abs() < 1e-6);
        assert!(!m.radius_from_file);
        assert_eq!(m.color[0], DEFAULT_COLOR);
        assert_eq!(m.transparency[0], 0.0);
    }

    #[test]
    fn median_ignores_outliers() {
        let pts = [0.0, 1.0, 2.0, 3.0, 100.0].map(|y| Vec3::new(0.0, y, 0.0));
        assert_eq!(median_segment_length(&pts, 5), 1.0);
    }

    #[test]
    fn overlapping_arrays_are_rejected() {
        let mut b = file(2, 4);
        // Strand UVs (16 bytes) claimed to start inside the positions.
        b[16..20].copy_from_slice(&(HEADER_SIZE as u32 + 16).to_le_bytes());
        let e = parse(Path::new("t.tfx"), &b).unwrap_err().to_string();
        assert!(e.contains("overlaps"), "{e}");
    }

    #[test]
    fn array_inside_header_is_rejected() {
        let mut b = file(2, 4);
        b[12..16].copy_from_slice(&0u32.to_le_bytes());
        let e = parse(Path::new("t.tfx"), &b).unwrap_err().to_string();
        assert!(e.contains("inside the 160-byte header"), "{e}");
    }

    #[test]
    fn coincident_points_give_an_error_not_a_zero_radius() {
        let mut b = file(1, 4);
        b.truncate(HEADER_SIZE);
        b.resize(HEADER_SIZE + 4 * 16, 0);
        let e = parse(Path::new("t.tfx"), &b).unwrap_err().to_string();
        assert!(e.contains("median segment length is 0"), "{e}");
    }
}
