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

/// Fixed-point scale of accumulated optical depth (σ = 1 ⇔ 4096) and of strand counts (one strand ⇔ 4096).
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
    /// Strands up to the end of each layer, laid out as `cumulative`, when the map counts them (dual scattering).
    strands: Option<Vec<f32>>,
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
    /// Builds the map of `strands` seen through `frame`, with a strand count per layer if `count` (what
    /// [`DeepOpacityMap::strands`] reads).
    pub fn build(
        strands: &Strands,
        frame: MapFrame,
        config: &DeepOpacityConfig,
        depth: f32,
        raster: Raster,
        count: bool,
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
            rasterise(strands, &frame, raster, range.clone(), |texel, z, _, _| {
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

        // Pass 2: optical depth (and strands) per layer, in fixed point (integer sums do not depend on the order).
        let zeros = |n: usize| (0..n).map(|_| AtomicU32::new(0)).collect::<Vec<_>>();
        let layers = zeros(texels * k);
        let counts = zeros(if count { texels * k } else { 0 });
        tasks.par_iter().for_each(|range| {
            rasterise(
                strands,
                &frame,
                raster,
                range.clone(),
                |texel, z, sigma, cover| {
                    let i = layer_of(&bounds, z - z0[texel]) * texels + texel;
                    // σ, cover ≥ 0: rounds to nearest.
                    layers[i].fetch_add((sigma * SIGMA_SCALE + 0.5) as u32, Ordering::Relaxed);
                    if count {
                        counts[i].fetch_add((cover * SIGMA_SCALE + 0.5) as u32, Ordering::Relaxed);
                    }
                },
            );
        });
        DeepOpacityMap {
            frame,
            bounds,
            z0,
            cumulative: running_sums(layers, texels),
            strands: count.then(|| running_sums(counts, texels)),
            filter: config.filter,
            bias: config.bias,
        }
    }

    /// Memory held, bytes.
    pub fn bytes(&self) -> usize {
        let counts = self.strands.as_ref().map_or(0, Vec::len);
        (self.z0.len() + self.cumulative.len() + counts + self.bounds.len())
            * std::mem::size_of::<f32>()
    }

    /// What `layers` (laid out as [`DeepOpacityMap::cumulative`]) hold between the light and depth `z` at texel
    /// `texel` (against the texel's own z0), interpolated linearly inside z's layer.
    #[inline]
    fn up_to(&self, layers: &[f32], texel: usize, z: f32) -> f32 {
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
            layers[(i - 1) * texels + texel]
        };
        let own = layers[i * texels + texel] - before;
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
        let [t] = self.filtered(p, [1.0], |texel, z, bias| {
            let od = texel.map_or(0.0, |t| self.up_to(&self.cumulative, t, z - bias));
            [if od > 0.0 { (-od).exp() } else { 1.0 }]
        });
        t.clamp(0.0, 1.0)
    }

    /// Strands on the line through world point `p` along the light's direction, filtered as
    /// [`DeepOpacityMap::transmittance`]: those between the light and p, those behind p, and the share of the
    /// footprint with no strand between the light and p (a texel counts min(1, strands ahead) of it as blocked),
    /// each averaged over the footprint. A strand at p is neither ahead nor behind it (the depth bias either way).
    /// `None` when the map was built without counts.
    pub fn strands(&self, p: Vec3) -> Option<[f32; 3]> {
        let counts = self.strands.as_ref()?;
        let last = (self.bounds.len() - 2) * self.z0.len();
        Some(self.filtered(p, [0.0, 0.0, 1.0], |texel, z, bias| {
            let Some(t) = texel else {
                return [0.0, 0.0, 1.0];
            };
            let ahead = self.up_to(counts, t, z - bias);
            let behind = (counts[last + t] - self.up_to(counts, t, z + bias)).max(0.0);
            [ahead, behind, (1.0 - ahead).max(0.0)]
        }))
    }

    /// The percentage-closer filter of both lookups: `per_texel(texel, z, bias)` of each texel in a tent of radius
    /// `filter + 1` texels around `p`'s projection (`None` for a texel outside the map), with p's depth z and the
    /// depth bias in world units, averaged with the tent's weights; `outside` where p projects off the map.
    fn filtered<const N: usize>(
        &self,
        p: Vec3,
        outside: [f32; N],
        per_texel: impl Fn(Option<usize>, f32, f32) -> [f32; N],
    ) -> [f32; N] {
        let Some((x, y, z)) = self.frame.project(p) else {
            return outside;
        };
        let res = self.frame.resolution as i64;
        let bias = self.bias * self.frame.texel_size(z);
        let reach = self.filter as f32 + 1.0;
        let (cx, cy) = (x - 0.5, y - 0.5);
        let (x0, x1) = (ceil_i(cx - reach), floor_i(cx + reach));
        let (y0, y1) = (ceil_i(cy - reach), floor_i(cy + reach));
        if x1 < 0 || y1 < 0 || x0 >= res || y0 >= res {
            return outside; // outside the map: no strand on p's line
        }
        let (mut sum, mut weights) = ([0.0; N], 0.0);
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
                let inside = (0..res).contains(&tx) && (0..res).contains(&ty);
                let v = per_texel(inside.then_some((ty * res + tx) as usize), z, bias);
                for (s, v) in sum.iter_mut().zip(v) {
                    *s += w * v;
                }
                weights += w;
            }
        }
        if weights > 0.0 {
            sum.map(|s| s / weights)
        } else {
            outside
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

/// Layer-major per-layer sums (fixed point) made running sums over the layers, as floats: one piece's fragments
/// fall on neighbouring texels of mostly one layer, so they share cache lines, and the running sum is a sum of
/// whole rows.
fn running_sums(layers: Vec<AtomicU32>, texels: usize) -> Vec<f32> {
    let mut out: Vec<f32> = layers
        .into_iter()
        .map(|v| v.into_inner() as f32 / SIGMA_SCALE)
        .collect();
    for i in 1..out.len() / texels.max(1) {
        let (front, back) = out.split_at_mut(i * texels);
        back[..texels]
            .par_iter_mut()
            .zip(&front[(i - 1) * texels..])
            .for_each(|(c, prev)| *c += *prev);
    }
    out
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

    /// Dual scattering's counts: three sheets that each cover every texel centre once give whole numbers of
    /// strands ahead of and behind points between them (and the direct share 1 only in front of all three), and a
    /// row of strands thinner than a texel, widened with their coverage kept, counts the share of the line of sight
    /// they cover (2r / spacing) on average.
    #[test]
    fn strand_counts_are_the_strands_ahead_and_behind() {
        let mut lines = sheet(0.0, 0.05, 1.0);
        lines.extend(sheet(0.3, 0.05, 1.0));
        lines.extend(sheet(0.6, 0.05, 1.0));
        let m = map(&lines, &config(256, 16, LayerSpacing::Uniform), 1.0, RASTER);
        for &(z, ahead, behind) in &[
            (-0.2, 0.0, 3.0),
            (0.15, 1.0, 2.0),
            (0.45, 2.0, 1.0),
            (0.9, 3.0, 0.0),
        ] {
            let [n, b, direct] = m.strands(Vec3::new(0.1, 0.2, z)).unwrap();
            assert!(
                (n - ahead).abs() < 0.01 && (b - behind).abs() < 0.01,
                "z = {z}: {n} ahead, {b} behind; want {ahead}, {behind}"
            );
            let want = if ahead == 0.0 { 1.0 } else { 0.0 };
            assert!((direct - want).abs() < 1e-6, "z = {z}: direct {direct}");
        }
        // Off the map: nothing on the line.
        assert_eq!(m.strands(Vec3::new(5.0, 0.0, 1.0)), Some([0.0, 0.0, 1.0]));

        let texel = 2.0 / 256.0;
        // Spacing and offset off the texel grid, so no strand sits exactly between two texel centres.
        let (r, spacing) = (0.2 * texel, 3.37 * texel);
        let thin = row(200, -0.8031, spacing, |_| 0.0, r, 1.0);
        let m = map(&thin, &config(256, 8, LayerSpacing::Uniform), 1.0, RASTER);
        let (mut sum, mut n) = (0.0, 0);
        for i in 0..97 {
            for j in 0..101 {
                let p = Vec3::new(-0.5 + i as f32 / 97.0, -0.5 + j as f32 / 101.0, 0.5);
                sum += m.strands(p).unwrap()[0];
                n += 1;
            }
        }
        let (mean, want) = (sum / n as f32, 2.0 * r / spacing);
        assert!(
            (mean / want - 1.0).abs() < 0.05,
            "thin strands: {mean} ahead on average, want {want}"
        );
        // Without counts the map has none to give.
        let plain = DeepOpacityMap { strands: None, ..m };
        assert!(plain.strands(Vec3::ZERO).is_none());
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
        assert_eq!(a.strands, b.strands);
    }
}
