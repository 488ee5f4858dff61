//! Hair models: readers for real files (Cem Yuksel's `.hair`, AMD TressFX `.tfx`), procedural models, and the
//! cubic B-spline [`Strands`] every tracer consumes.
//!
//! Data flow: a reader or generator produces a [`HairModel`] (polylines with per-point radius, transparency and
//! colour, exactly what the file says), then [`Strands::from_model`] turns it into B-spline control points.

pub mod procedural;
pub mod source;
pub mod strands;
pub mod summary;
pub mod tfx;
pub mod yuksel;

use std::path::{Path, PathBuf};

use glam::Vec3;

pub use source::{HairSource, HairSpec};
pub use strands::Strands;
pub use summary::Summary;

/// Everything that can go wrong while reading or building a hair model. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum HairError {
    /// The file could not be opened or read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying I/O error.
        source: std::io::Error,
    },
    /// The file was read but its content is not a valid hair model.
    #[error("{path}: {message}")]
    Invalid {
        /// The file (or `procedural:<name>` for generated models).
        path: PathBuf,
        /// What is wrong, lower case, with the offending numbers.
        message: String,
    },
}

/// The little-endian u32 at `offset`. Callers have checked the length.
fn u32_at(b: &[u8], offset: usize) -> u32 {
    u32::from_le_bytes([b[offset], b[offset + 1], b[offset + 2], b[offset + 3]])
}

/// The little-endian f32 at `offset`. Callers have checked the length.
fn f32_at(b: &[u8], offset: usize) -> f32 {
    f32::from_bits(u32_at(b, offset))
}

impl HairError {
    /// An [`HairError::Invalid`] for `path`.
    pub fn invalid(path: &Path, message: impl Into<String>) -> Self {
        HairError::Invalid {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }
}

/// Largest strand colour channel (a reflectance-like tint; see [`HairModel::validate`]).
pub const MAX_COLOR: f32 = 1.0;

/// Checks that every point, inflated by its radius × `radius_scale`, lies within [`crate::ray::MAX_SCENE_COORD`] of
/// the origin, so every ray that starts on a strand passes [`crate::ray::Ray::check`]. `what` is appended to the
/// message (e.g. " with hair.radius_scale = 1e30"). An empty `radius` checks the points alone (a format whose radius
/// is derived from the points, checked before deriving it).
pub(crate) fn check_extent(
    path: &Path,
    points: &[Vec3],
    radius: &[f32],
    radius_scale: f32,
    what: &str,
) -> Result<(), HairError> {
    let max = crate::ray::MAX_SCENE_COORD;
    let r = |i: usize| radius.get(i).map_or(0.0, |r| r * radius_scale);
    let far = points.iter().enumerate().position(|(i, p)| {
        let reach = p.abs().max_element() + r(i);
        !(..=max).contains(&reach)
    });
    if let Some(i) = far {
        let with = if radius.is_empty() {
            String::new()
        } else {
            format!(" with radius {:e}", r(i))
        };
        return Err(HairError::invalid(
            path,
            format!(
                "point {i} at {:?}{with} reaches farther than {max:e} from the origin{what}: rays from it could not \
                 be traced in single precision (scale the model down)",
                points[i].to_array(),
            ),
        ));
    }
    Ok(())
}

/// The relative extent under which a strand has zero length ([`HairModel::drop_zero_length`]): about 8 units in
/// the last place of an f32.
pub const ZERO_LENGTH: f32 = 1e-6;

/// A hair model as polylines: the common form of every reader and generator, before B-spline conversion.
///
/// All per-point arrays have one entry per point; absent file arrays are filled with the file's defaults.
#[derive(Debug, Clone, Default)]
pub struct HairModel {
    /// All strand points, strand after strand, in model units.
    pub points: Vec<Vec3>,
    /// Index of each strand's first point in `points`; `strand_count + 1` entries, the last is `points.len()`.
    pub strand_offsets: Vec<u32>,
    /// Per-point fibre radius (half the file's thickness), model units.
    pub radius: Vec<f32>,
    /// True when `radius` came from a per-point thickness array in the file; false when it is a default that the
    /// B-spline conversion may taper (thesis §5.2).
    pub radius_from_file: bool,
    /// Per-point transparency in [0, 1] (1 − opacity).
    pub transparency: Vec<f32>,
    /// Per-point linear RGB colour.
    pub color: Vec<[f32; 3]>,
    /// Human-readable format name ("cem yuksel .hair", "tressfx .tfx", "procedural furball").
    pub format: String,
    /// The file's free-text info field, if any.
    pub info: String,
}

impl HairModel {
    /// Number of strands.
    pub fn strand_count(&self) -> usize {
        self.strand_offsets.len().saturating_sub(1)
    }

    /// The index range of strand `s` in the per-point arrays.
    pub fn strand_range(&self, s: usize) -> std::ops::Range<usize> {
        self.strand_offsets[s] as usize..self.strand_offsets[s + 1] as usize
    }

    /// Removes the strands of zero length and returns how many there were: every point within
    /// [`ZERO_LENGTH`] × (the first point's largest coordinate + its radius) of the first point. Such a strand is a
    /// point, not a fibre (in f32 it spans a few units in the last place), and N of them at one place made every ray
    /// there test all N: 20 000 strands at one point took 24 ms per camera ray. Keeps at least a strand count of
    /// zero's meaning: a model of only such strands comes back empty.
    pub fn drop_zero_length(&mut self) -> usize {
        let zero = |s: usize| {
            let r = self.strand_range(s);
            let p0 = self.points[r.start];
            let scale = p0.abs().max_element() + self.radius[r.start];
            self.points[r]
                .iter()
                .all(|p| (*p - p0).abs().max_element() <= ZERO_LENGTH * scale)
        };
        let dropped: Vec<bool> = (0..self.strand_count()).map(zero).collect();
        let count = dropped.iter().filter(|&&d| d).count();
        if count == 0 {
            return 0;
        }
        let mut keep = HairModel {
            points: Vec::new(),
            strand_offsets: vec![0],
            radius: Vec::new(),
            radius_from_file: self.radius_from_file,
            transparency: Vec::new(),
            color: Vec::new(),
            format: std::mem::take(&mut self.format),
            info: std::mem::take(&mut self.info),
        };
        for (s, _) in dropped.iter().enumerate().filter(|(_, &d)| !d) {
            let r = self.strand_range(s);
            keep.points.extend_from_slice(&self.points[r.clone()]);
            keep.radius.extend_from_slice(&self.radius[r.clone()]);
            keep.transparency
                .extend_from_slice(&self.transparency[r.clone()]);
            keep.color.extend_from_slice(&self.color[r]);
            keep.strand_offsets.push(keep.points.len() as u32);
        }
        *self = keep;
        count
    }

    /// Axis-aligned bounds of the points (not inflated by radius): (min, max).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.points.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        )
    }

    /// Checks the invariants every reader promises: consistent array lengths, at least 2 points per strand, finite
    /// points, positive finite radii, transparency in [0, 1]. `path` names the source in the error.
    pub fn validate(&self, path: &Path) -> Result<(), HairError> {
        let n = self.points.len();
        if self.strand_count() == 0 || n == 0 {
            return Err(HairError::invalid(path, "the model has no strands"));
        }
        if self.strand_offsets[0] != 0 || *self.strand_offsets.last().unwrap_or(&0) as usize != n {
            return Err(HairError::invalid(
                path,
                "strand offsets do not cover the point array",
            ));
        }
        for (name, len) in [
            ("radius", self.radius.len()),
            ("transparency", self.transparency.len()),
            ("color", self.color.len()),
        ] {
            if len != n {
                return Err(HairError::invalid(
                    path,
                    format!("{name} array has {len} entries for {n} points"),
                ));
            }
        }
        for s in 0..self.strand_count() {
            let r = self.strand_range(s);
            if r.len() < 2 {
                return Err(HairError::invalid(
                    path,
                    format!(
                        "strand {s} has {} point(s); a strand needs at least 2",
                        r.len()
                    ),
                ));
            }
        }
        if let Some(i) = self.points.iter().position(|p| !p.is_finite()) {
            return Err(HairError::invalid(
                path,
                format!("point {i} is not finite: {:?}", self.points[i]),
            ));
        }
        if let Some(i) = self
            .radius
            .iter()
            .position(|r| !(r.is_finite() && *r > 0.0))
        {
            return Err(HairError::invalid(
                path,
                format!(
                    "point {i} has thickness {} (must be > 0)",
                    2.0 * self.radius[i]
                ),
            ));
        }
        check_extent(path, &self.points, &self.radius, 1.0, "")?;
        // A strand colour tints the diffuse lobe like a reflectance: above 1 a strand would reflect more light than
        // reaches it, and a huge finite colour (1e38) overflows the film's sums to infinity. [0, 1] is what every
        // real file stores (straight.hair: 0.57 to 1).
        if let Some(i) = self
            .color
            .iter()
            .position(|c| !c.iter().all(|x| (0.0..=MAX_COLOR).contains(x)))
        {
            return Err(HairError::invalid(
                path,
                format!(
                    "point {i} has colour {:?} (every channel must be in [0, {MAX_COLOR}])",
                    self.color[i]
                ),
            ));
        }
        if let Some(i) = self
            .transparency
            .iter()
            .position(|t| !(0.0..=1.0).contains(t))
        {
            return Err(HairError::invalid(
                path,
                format!(
                    "point {i} has transparency {} (must be in [0, 1])",
                    self.transparency[i]
                ),
            ));
        }
        Ok(())
    }
}

/// The strands and points a hair file declares, from its header alone (the file is opened, at most a header's
/// bytes are read, and its size is checked against the header as [`load`] would): what
/// [`crate::render::budget`] estimates a frame's memory from before the file is read.
pub fn declared_counts(path: &Path) -> Result<(u64, u64), HairError> {
    let io = |source| HairError::Io {
        path: path.to_path_buf(),
        source,
    };
    let format = format_of(path)?;
    let (_, file_len, head) =
        crate::util::input_file::open_with_head(path, tfx::HEADER_SIZE.max(yuksel::HEADER_SIZE))
            .map_err(io)?;
    match format {
        Format::Yuksel => {
            let h = yuksel::Header::parse(path, &head)?;
            h.check_file_len(path, file_len)?;
            Ok((u64::from(h.strand_count), u64::from(h.point_count)))
        }
        Format::Tfx => {
            let h = tfx::Header::parse(path, &head)?;
            h.check_file_len(path, file_len)?;
            let strands = u64::from(h.strand_count);
            Ok((strands, strands * u64::from(h.vertices_per_strand)))
        }
    }
}

enum Format {
    Yuksel,
    Tfx,
}

fn format_of(path: &Path) -> Result<Format, HairError> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("hair") => Ok(Format::Yuksel),
        Some("tfx") => Ok(Format::Tfx),
        _ => Err(HairError::invalid(
            path,
            "unknown hair format (expected a .hair or .tfx file)",
        )),
    }
}

/// Loads a hair model by file extension: `.hair` (Cem Yuksel) or `.tfx` (TressFX 4 guide strands).
pub fn load(path: &Path) -> Result<HairModel, HairError> {
    match format_of(path)? {
        Format::Yuksel => yuksel::read(path),
        Format::Tfx => tfx::read(path),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A model of strands with the given points, radius 0.01.
    fn of(strands: &[&[Vec3]]) -> HairModel {
        let mut m = HairModel {
            strand_offsets: vec![0],
            ..Default::default()
        };
        for s in strands {
            m.points.extend_from_slice(s);
            m.radius.extend(s.iter().map(|_| 0.01));
            m.transparency.extend(s.iter().map(|_| 0.0));
            let c = 0.1 * m.strand_count() as f32;
            m.color.extend(s.iter().map(|_| [c; 3]));
            m.strand_offsets.push(m.points.len() as u32);
        }
        m
    }

    /// Only strands shorter than a few units in the last place are left out: a short strand (a tenth of its own
    /// width, far from the origin) stays, with its own colour.
    #[test]
    fn only_strands_of_zero_length_are_left_out() {
        let far = Vec3::splat(1e3);
        let mut m = of(&[
            &[Vec3::ZERO, Vec3::ZERO, Vec3::ZERO],
            &[far, far + Vec3::new(0.0, 2e-3, 0.0)],
            &[far, far + Vec3::new(0.0, 1e-4, 0.0)],
            &[Vec3::X, Vec3::X * (1.0 + 1e-7)],
        ]);
        assert_eq!(m.drop_zero_length(), 3);
        assert_eq!(m.strand_count(), 1);
        assert_eq!(m.points, [far, far + Vec3::new(0.0, 2e-3, 0.0)]);
        assert_eq!(m.color, [[0.1; 3]; 2]);
        assert!(m.validate(Path::new("m.hair")).is_ok());
        assert_eq!(m.drop_zero_length(), 0);
    }
}
