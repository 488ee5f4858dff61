//! Statistics of a hair model, as `cuticle info` prints them: counts, points per strand, bounds, thickness and
//! transparency ranges.

use std::fmt;

use glam::Vec3;

use super::HairModel;

/// What `cuticle info` reports about a model.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// The reader that produced the model (e.g. `Cem Yuksel .hair`).
    pub format: String,
    /// The file's own description, possibly empty.
    pub info: String,
    /// Strands.
    pub strands: usize,
    /// Points over all strands.
    pub points: usize,
    /// Fewest and most points of one strand (0, 0 for an empty model).
    pub points_per_strand: (usize, usize),
    /// Bounding box (min, max); zeros for an empty model.
    pub bounds: (Vec3, Vec3),
    /// Thickness (twice the radius) over all points: min, mean, max (0s for an empty model).
    pub thickness: (f32, f64, f32),
    /// Whether the thickness is per point from the file, or a default tapered to half at the tip.
    pub thickness_from_file: bool,
    /// Transparency over all points: min, max (0s for an empty model).
    pub transparency: (f32, f32),
}

/// (min, max) of `values`, or (0, 0) when there are none.
fn range(values: impl Iterator<Item = f32>) -> (f32, f32) {
    let (lo, hi) = values.fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    if lo <= hi {
        (lo, hi)
    } else {
        (0.0, 0.0)
    }
}

impl HairModel {
    /// The statistics `cuticle info` prints.
    pub fn summary(&self) -> Summary {
        let strands = self.strand_count();
        let points = self.points.len();
        let lengths = (0..strands).map(|s| self.strand_range(s).len());
        let points_per_strand = (
            lengths.clone().min().unwrap_or(0),
            lengths.max().unwrap_or(0),
        );
        let (tmin, tmax) = range(self.radius.iter().map(|r| 2.0 * r));
        let tmean = if points == 0 {
            0.0
        } else {
            self.radius.iter().map(|&r| 2.0 * f64::from(r)).sum::<f64>() / points as f64
        };
        Summary {
            format: self.format.clone(),
            info: self.info.clone(),
            strands,
            points,
            points_per_strand,
            bounds: if points == 0 {
                (Vec3::ZERO, Vec3::ZERO)
            } else {
                self.bounds()
            },
            thickness: (tmin, tmean, tmax),
            thickness_from_file: self.radius_from_file,
            transparency: range(self.transparency.iter().copied()),
        }
    }
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "format:       {}", self.format)?;
        if !self.info.is_empty() {
            writeln!(f, "info:         {}", self.info)?;
        }
        writeln!(f, "strands:      {}", self.strands)?;
        writeln!(f, "points:       {}", self.points)?;
        writeln!(
            f,
            "per strand:   min {} / mean {:.1} / max {} points",
            self.points_per_strand.0,
            self.points as f64 / self.strands.max(1) as f64,
            self.points_per_strand.1
        )?;
        let (lo, hi) = self.bounds;
        writeln!(
            f,
            "bounds:       [{:.4}, {:.4}, {:.4}] .. [{:.4}, {:.4}, {:.4}]",
            lo.x, lo.y, lo.z, hi.x, hi.y, hi.z
        )?;
        let (tmin, tmean, tmax) = self.thickness;
        writeln!(
            f,
            "thickness:    min {tmin:.6} / mean {tmean:.6} / max {tmax:.6} ({})",
            if self.thickness_from_file {
                "per point, from the file"
            } else {
                "file default; tapered to half at the tip"
            }
        )?;
        write!(
            f,
            "transparency: min {:.4} / max {:.4}",
            self.transparency.0, self.transparency.1
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_strands() -> HairModel {
        HairModel {
            points: vec![
                Vec3::ZERO,
                Vec3::X,
                Vec3::Y,
                Vec3::Y * 2.0,
                Vec3::new(0.0, 3.0, -1.0),
            ],
            strand_offsets: vec![0, 2, 5],
            radius: vec![0.1, 0.1, 0.2, 0.2, 0.4],
            transparency: vec![0.0, 0.0, 0.5, 0.5, 0.25],
            ..Default::default()
        }
    }

    #[test]
    fn counts_ranges_and_means() {
        let s = two_strands().summary();
        assert_eq!((s.strands, s.points), (2, 5));
        assert_eq!(s.points_per_strand, (2, 3));
        assert_eq!(
            s.bounds,
            (Vec3::new(0.0, 0.0, -1.0), Vec3::new(1.0, 3.0, 0.0))
        );
        assert_eq!((s.thickness.0, s.thickness.2), (0.2, 0.8));
        assert!((s.thickness.1 - 0.4).abs() < 1e-6, "{}", s.thickness.1);
        assert_eq!(s.transparency, (0.0, 0.5));
        let text = s.to_string();
        assert!(
            text.contains("per strand:   min 2 / mean 2.5 / max 3 points"),
            "{text}"
        );
    }

    #[test]
    fn an_empty_model_has_zero_ranges_not_infinities() {
        let s = HairModel {
            strand_offsets: vec![0],
            ..Default::default()
        }
        .summary();
        assert_eq!(s.thickness, (0.0, 0.0, 0.0));
        assert_eq!(s.transparency, (0.0, 0.0));
        assert!(!s.to_string().contains("inf"));
    }
}
