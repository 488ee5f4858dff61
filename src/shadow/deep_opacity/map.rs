//! One deep opacity map: z0 and the opacity layers behind it, built in two rasterised passes, and the
//! percentage-closer lookup (see "The method", "Building" and "Lookup" in the [module docs](super)).

use std::sync::atomic::{AtomicU32, Ordering};

use glam::Vec3;
use rayon::prelude::*;

use super::raster::{ceil_i, floor_i, rasterise};
use super::{MapFrame, Raster};
use crate::hair::Strands;
use crate::image::Image;
use crate::shadow::{DeepOpacityConfig, LayerSpacing};

/// Fixed-point scale of accumulated optical depth (σ = 1 ⇔ 4096).
const SIGMA_SCALE: f32 = 4096.0;

/// Strands per parallel work item of a build.
const STRANDS_PER_TASK: usize = 256;

/// One deep opacity map (see the module docs).
#[derive(Debug, Clone)]
pub struct DeepOpacityMap {
    frame: MapFrame,
    /// Layer boundaries behind z0, world units: d_0 = 0 < d_1 < … < d_k.
    bounds: Vec<f32>,
    /// Nearest strand depth per texel (`INFINITY` where no strand is).
    z0: Vec<f32>,
    /// Optical depth up to the *end* of each layer: `cumulative[layer × texels + texel]` (layer-major).
    cumulative: Vec<f32>,
    /// Filter radius (texels) and depth bias (texels) of lookups.
    filter: u32,
    bias: f32,
}

/// Layer boundaries d_0..d_k for `layers` layers over `depth` world units.
fn layer_bounds(layers: u32, depth: f32, spacing: LayerSpacing) -> Vec<f32> {
    let k = layers as f32;
    (0..=layers)
        .map(|i| {
            let i = i as f32;
            match spacing {
                LayerSpacing::Uniform => depth * i / k,
                // Thickness of layer i ∝ (i + 1): d_i = D · i(i + 1) / (k(k + 1)).
                LayerSpacing::Growing => depth * i * (i + 1.0) / (k * (k + 1.0)),
            }
        })
        .collect()
}

impl DeepOpacityMap {
    /// Builds the map of `strands` seen through `frame`.
    pub fn build(
        strands: &Strands,
        frame: MapFrame,
        config: &DeepOpacityConfig,
        depth: f32,
        raster: Raster,
    ) -> DeepOpacityMap {
        let texels = (frame.resolution as usize).pow(2);
        let k = config.layers as usize;
        let bounds = layer_bounds(config.layers, depth, config.spacing);
        let tasks: Vec<std::ops::Range<usize>> = (0..strands.strand_count())
            .step_by(STRANDS_PER_TASK)
            .map(|s| s..(s + STRANDS_PER_TASK).min(strands.strand_count()))
            .collect();

        // Pass 1: the nearest strand per texel. Depths are positive, so their bit patterns order like the floats.
        let z0_bits: Vec<AtomicU32> = (0..texels)
            .map(|_| AtomicU32::new(f32::INFINITY.to_bits()))
            .collect();
        tasks.par_iter().for_each(|range| {
            rasterise(strands, &frame, raster, range.clone(), |texel, z, _| {
                // Most fragments lie behind the texel's current front: a plain load spares them the atomic RMW.
                let bits = z.max(0.0).to_bits();
                if bits < z0_bits[texel].load(Ordering::Relaxed) {
                    z0_bits[texel].fetch_min(bits, Ordering::Relaxed);
                }
            });
        });
        let z0: Vec<f32> = z0_bits
            .into_iter()
            .map(|b| f32::from_bits(b.into_inner()))
            .collect();

        // Pass 2: optical depth per layer, in fixed point (integer sums do not depend on the order).
        let layers: Vec<AtomicU32> = (0..texels * k).map(|_| AtomicU32::new(0)).collect();
        tasks.par_iter().for_each(|range| {
            rasterise(strands, &frame, raster, range.clone(), |texel, z, sigma| {
                let layer = layer_of(&bounds, z - z0[texel]);
                let add = (sigma * SIGMA_SCALE + 0.5) as u32; // σ ≥ 0: rounds to nearest
                layers[layer * texels + texel].fetch_add(add, Ordering::Relaxed);
            });
        });
        let mut cumulative: Vec<f32> = layers
            .into_iter()
            .map(|v| v.into_inner() as f32 / SIGMA_SCALE)
            .collect();
        // Layer-major storage: one piece's fragments fall on neighbouring texels of mostly one layer, so they
        // share cache lines; the running sum over layers is then a sum of whole rows.
        for i in 1..k {
            let (front, back) = cumulative.split_at_mut(i * texels);
            back[..texels]
                .par_iter_mut()
                .zip(&front[(i - 1) * texels..])
                .for_each(|(c, prev)| *c += *prev);
        }
        DeepOpacityMap {
            frame,
            bounds,
            z0,
            cumulative,
            filter: config.filter,
            bias: config.bias,
        }
    }

    /// Memory held, bytes.
    pub fn bytes(&self) -> usize {
        (self.z0.len() + self.cumulative.len() + self.bounds.len()) * std::mem::size_of::<f32>()
    }

    /// Optical depth between the light and depth `z` at texel `texel` (against the texel's own z0).
    #[inline]
    fn optical_depth(&self, texel: usize, z: f32) -> f32 {
        let z0 = self.z0[texel];
        let delta = z - z0;
        if delta.is_nan() || delta <= 0.0 {
            return 0.0; // in front of the nearest strand, or an empty texel (z0 = ∞)
        }
        let k = self.bounds.len() - 1;
        let texels = self.z0.len();
        let i = layer_of(&self.bounds, delta);
        let before = if i == 0 {
            0.0
        } else {
            self.cumulative[(i - 1) * texels + texel]
        };
        let own = self.cumulative[i * texels + texel] - before;
        let (d0, d1) = (self.bounds[i], self.bounds[i + 1]);
        let fraction = if i == k - 1 && delta >= d1 {
            1.0
        } else {
            ((delta - d0) / (d1 - d0)).clamp(0.0, 1.0)
        };
        before + own * fraction
    }

    /// Transmittance from the light to world point `p`, in [0, 1], percentage-closer filtered.
    pub fn transmittance(&self, p: Vec3) -> f32 {
        let Some((x, y, z)) = self.frame.project(p) else {
            return 1.0;
        };
        let res = self.frame.resolution as i64;
        let z = z - self.bias * self.frame.texel_size(z);
        let reach = self.filter as f32 + 1.0;
        let (cx, cy) = (x - 0.5, y - 0.5);
        let (x0, x1) = (ceil_i(cx - reach), floor_i(cx + reach));
        let (y0, y1) = (ceil_i(cy - reach), floor_i(cy + reach));
        if x1 < 0 || y1 < 0 || x0 >= res || y0 >= res {
            return 1.0; // outside the map: no strand between p and the light
        }
        let (mut sum, mut weights) = (0.0, 0.0);
        for ty in y0..=y1 {
            let wy = 1.0 - (ty as f32 - cy).abs() / reach;
            if wy <= 0.0 {
                continue;
            }
            for tx in x0..=x1 {
                let wx = 1.0 - (tx as f32 - cx).abs() / reach;
                if wx <= 0.0 {
                    continue;
                }
                let w = wx * wy;
                let od = if (0..res).contains(&tx) && (0..res).contains(&ty) {
                    self.optical_depth((ty * res + tx) as usize, z)
                } else {
                    0.0
                };
                let t = if od > 0.0 { (-od).exp() } else { 1.0 };
                sum += w * t;
                weights += w;
            }
        }
        if weights > 0.0 {
            (sum / weights).clamp(0.0, 1.0)
        } else {
            1.0
        }
    }

    /// The nearest-strand depth map (for inspection): row-major, `resolution`² values, ∞ where empty.
    pub fn z0(&self) -> &[f32] {
        &self.z0
    }

    /// Texels along a side.
    pub fn resolution(&self) -> u32 {
        self.frame.resolution
    }

    /// The map as a flat multi-channel image for inspection: `Z` = z0 (0 where no strand is), then `T.00`, `T.01`, …
    /// = the transmittance at the back of each layer (row 0 = the map's bottom edge, as `up` points).
    pub fn to_image(&self) -> Image {
        let res = self.frame.resolution as usize;
        let k = self.bounds.len() - 1;
        let mut channels = vec!["Z".to_string()];
        channels.extend((0..k).map(|i| format!("T.{i:02}")));
        let mut image = Image::new(res, res, channels);
        for texel in 0..res * res {
            let (x, y) = (texel % res, res - 1 - texel / res);
            let z0 = self.z0[texel];
            image.set(x, y, 0, if z0.is_finite() { z0 } else { 0.0 });
            for i in 0..k {
                image.set(x, y, 1 + i, (-self.cumulative[i * res * res + texel]).exp());
            }
        }
        image
    }
}

/// The layer of a depth `delta` ≥ 0 behind z0: i with d_i ≤ delta < d_{i+1}, the last layer taking everything deeper.
#[inline]
fn layer_of(bounds: &[f32], delta: f32) -> usize {
    let k = bounds.len() - 1;
    // bounds[1..k] are the inner boundaries; count how many lie at or before delta.
    bounds[1..k].partition_point(|&d| d <= delta)
}

#[cfg(test)]
mod tests {
    use super::super::test_field::{config, map, mean_error, row, sheet, Line, RASTER};
    use super::*;

    #[test]
    fn layer_boundaries_grow_and_cover_the_depth() {
        for spacing in [LayerSpacing::Uniform, LayerSpacing::Growing] {
            let b = layer_bounds(8, 2.0, spacing);
            assert_eq!(b.len(), 9);
            assert_eq!(b[0], 0.0);
            assert!((b[8] - 2.0).abs() < 1e-6);
            assert!(b.windows(2).all(|w| w[1] > w[0]));
        }
        let g = layer_bounds(4, 1.0, LayerSpacing::Growing);
        assert!(g[2] - g[1] > g[1] - g[0], "growing layers thicken: {g:?}");
        assert_eq!(layer_of(&g, 0.0), 0);
        assert_eq!(layer_of(&g, 10.0), 3);
    }

    #[test]
    fn one_opaque_sheet_gives_its_transmittance_behind_and_none_in_front() {
        let lines = sheet(0.0, 0.05, 0.6);
        let m = map(&lines, &config(256, 8, LayerSpacing::Uniform), 0.5, RASTER);
        for &(z, want) in &[(-0.2, 1.0), (0.3, 0.4), (2.0, 0.4)] {
            let t = m.transmittance(Vec3::new(0.1, 0.2, z));
            assert!((t - want).abs() < 0.01, "z = {z}: T = {t}, want {want}");
        }
        // Outside the map's footprint nothing shadows.
        assert_eq!(m.transmittance(Vec3::new(5.0, 0.0, 1.0)), 1.0);
    }

    #[test]
    fn too_few_layers_band_and_enough_layers_do_not() {
        // One sheet at the front and a dense cluster of 8 sheets deeper, all inside the layer range D = 1: with 2
        // layers the cluster's opacity is smeared forwards over the empty gap (linear interpolation inside a layer),
        // with 32 the gap stays lit.
        let mut lines = sheet(0.0, 0.05, 0.3);
        for s in 0..8 {
            lines.extend(sheet(0.40 + 0.01 * s as f32, 0.05, 0.3));
        }
        let depths = [0.2, 0.3, 0.6, 0.9];
        let e2 = mean_error(
            &lines,
            &map(&lines, &config(256, 2, LayerSpacing::Uniform), 1.0, RASTER),
            &depths,
        );
        let e32 = mean_error(
            &lines,
            &map(&lines, &config(256, 32, LayerSpacing::Uniform), 1.0, RASTER),
            &depths,
        );
        assert!(e2 > 0.15, "2 layers should band visibly, mean |ΔT| = {e2}");
        assert!(e32 < 0.02, "32 layers should not, mean |ΔT| = {e32}");
    }

    #[test]
    fn depth_bias_removes_self_shadow_acne() {
        // A single sheet of strands tilted 45° to the light: shading points on the strands' far halves (between the
        // axis and the back surface) must see no strand in front of them — they are on it. Without bias the
        // filter footprint reaches texels whose z0 lies in front of the point (acne); the default bias removes it.
        // 45°: depth grows with y along the tilted sheet.
        let lines = row(40, -0.95, 0.0475, |y| y, 0.008, 0.8);
        let lit_fraction = |bias: f32| {
            let cfg = DeepOpacityConfig {
                bias,
                ..config(512, 16, LayerSpacing::Growing)
            };
            let m = map(&lines, &cfg, 0.5, RASTER);
            let mut sum = 0.0;
            let mut n = 0;
            for l in &lines[2..38] {
                for k in 0..20 {
                    let x = -0.8 + 1.6 * k as f32 / 20.0;
                    // A point on the strand's surface facing the viewer but not the light: on the axis, half a
                    // radius deeper.
                    sum += m.transmittance(Vec3::new(x, l.y, l.z + 0.5 * l.r));
                    n += 1;
                }
            }
            sum / n as f32
        };
        let no_bias = lit_fraction(0.0);
        let default = lit_fraction(DeepOpacityConfig::default().bias);
        assert!(no_bias < 0.9, "expected acne without bias, T = {no_bias}");
        assert!(
            default > 0.99,
            "the default bias should remove the acne, T = {default}"
        );
    }

    #[test]
    fn a_map_too_coarse_for_the_strand_spacing_blurs_the_shadow() {
        // Two sheets of thin, sparse strands (width 0.01, spacing 0.08, offset between sheets): the shadow behind
        // them is a fine stripe pattern. A 32² map (texel 0.0625) cannot resolve it; a 1024² map can.
        // The second sheet: each strand of the first moved 0.04 along y, to depth 0.2.
        let behind = |l: Line| Line {
            y: l.y + 0.04,
            z: 0.2,
            ..l
        };
        let lines: Vec<Line> = row(25, -0.96, 0.08, |_| 0.0, 0.01, 0.9)
            .into_iter()
            .flat_map(|l| [l, behind(l)])
            .collect();
        let err = |res: u32| {
            let cfg = DeepOpacityConfig {
                filter: 0,
                ..config(res, 8, LayerSpacing::Uniform)
            };
            mean_error(&lines, &map(&lines, &cfg, 0.5, RASTER), &[0.4])
        };
        let (coarse, fine) = (err(32), err(1024));
        // The fine map's residue is the bilinear footprint at the stripes' 100 edges (≈1 texel each).
        assert!(coarse > 0.3, "a 32² map should blur the stripes: {coarse}");
        assert!(fine < 0.1, "a 1024² map should resolve them: {fine}");
    }

    #[test]
    fn the_build_does_not_depend_on_the_thread_count() {
        let mut lines = sheet(0.0, 0.05, 0.3);
        lines.extend(sheet(0.3, 0.07, 0.6));
        let cfg = config(128, 8, LayerSpacing::Growing);
        let build = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| map(&lines, &cfg, 0.5, RASTER))
        };
        let (a, b) = (build(1), build(3));
        assert_eq!(a.z0, b.z0);
        assert_eq!(a.cumulative, b.cumulative);
    }
}
