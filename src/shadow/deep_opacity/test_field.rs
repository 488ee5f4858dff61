//! The method's failure modes, each shown with numbers on a synthetic strand field whose exact transmittance is
//! known in closed form: straight strands along x at (y_i, z_i), light travelling along +z, so a point
//! (x, y, z) is shadowed by every strand with |y − y_i| < r_i and z_i < z. This file holds the field; the tests
//! sit beside the code whose failure they show (`raster.rs`, `map.rs`).

use glam::Vec3;

use super::framing::Projection;
use super::{DeepOpacityMap, MapFrame, Raster};
use crate::hair::{HairModel, Strands};
use crate::shadow::{DeepOpacityConfig, LayerSpacing};

/// One straight strand: y, z of its axis, radius, opacity.
#[derive(Clone, Copy)]
pub(super) struct Line {
    pub(super) y: f32,
    pub(super) z: f32,
    pub(super) r: f32,
    pub(super) a: f32,
}

pub(super) const HALF: f32 = 1.0; // the field spans x, y ∈ [−1, 1]

fn strands(lines: &[Line]) -> Strands {
    let mut model = HairModel::default();
    for l in lines {
        model.strand_offsets.push(model.points.len() as u32);
        for i in 0..5 {
            let x = -1.2 * HALF + 2.4 * HALF * i as f32 / 4.0;
            model.points.push(Vec3::new(x, l.y, l.z));
            model.radius.push(l.r);
            model.transparency.push(1.0 - l.a);
            model.color.push([1.0; 3]);
        }
    }
    model.strand_offsets.push(model.points.len() as u32);
    model.radius_from_file = true;
    Strands::from_model(&model)
}

pub(super) fn exact(lines: &[Line], p: Vec3) -> f32 {
    lines
        .iter()
        .filter(|l| (p.y - l.y).abs() < l.r && l.z < p.z)
        .map(|l| 1.0 - l.a)
        .product()
}

pub(super) fn config(resolution: u32, layers: u32, spacing: LayerSpacing) -> DeepOpacityConfig {
    DeepOpacityConfig {
        resolution,
        layers,
        spacing,
        ..DeepOpacityConfig::default()
    }
}

/// A map looking along +z at the field, framing the square [−1, 1]² exactly (texel centres off the strands'
/// symmetry), with layers over `depth`.
pub(super) fn map(
    lines: &[Line],
    config: &DeepOpacityConfig,
    depth: f32,
    raster: Raster,
) -> DeepOpacityMap {
    let frame = MapFrame {
        origin: Vec3::new(0.0, 0.0, -1.0),
        right: Vec3::X,
        up: Vec3::Y,
        forward: Vec3::Z,
        projection: Projection::Orthographic { half_extent: HALF },
        resolution: config.resolution,
    };
    DeepOpacityMap::build(&strands(lines), frame, config, depth, raster, true)
}

pub(super) const RASTER: Raster = Raster {
    min_width: 1.0,
    keep_coverage: true,
};

/// Mean |T_map − T_exact| over a grid of points at the given depths.
pub(super) fn mean_error(lines: &[Line], m: &DeepOpacityMap, depths: &[f32]) -> f32 {
    let mut sum = 0.0;
    let mut n = 0;
    for &z in depths {
        for i in 0..64 {
            for j in 0..64 {
                let p = Vec3::new(
                    -0.8 + 1.6 * (i as f32 + 0.37) / 64.0,
                    -0.8 + 1.6 * (j as f32 + 0.61) / 64.0,
                    z,
                );
                sum += (m.transmittance(p) - exact(lines, p)).abs();
                n += 1;
            }
        }
    }
    sum / n as f32
}

/// `n` strands at y = `y_first` + `step` · i (i = 0 … n − 1), each at depth `z(y)`, of radius `r` and opacity `a`.
pub(super) fn row(
    n: usize,
    y_first: f32,
    step: f32,
    z: impl Fn(f32) -> f32,
    r: f32,
    a: f32,
) -> Vec<Line> {
    (0..n)
        .map(|i| {
            let y = y_first + step * i as f32;
            Line { y, z: z(y), r, a }
        })
        .collect()
}

/// Sheets of strands that tile y completely (each sheet multiplies transmittance by 1 − a everywhere).
pub(super) fn sheet(z: f32, spacing: f32, a: f32) -> Vec<Line> {
    let n = (2.0 * HALF / spacing).ceil() as usize + 1;
    row(n, -HALF, spacing, |_| z, 0.5 * spacing, a)
}
