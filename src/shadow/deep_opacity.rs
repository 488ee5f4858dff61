//! Deep opacity maps (Yuksel & Keyser 2008, "Deep Opacity Maps", Computer Graphics Forum 27(2)): the shadow maps
//! the thesis got its best hair images from (§5.4, §6.4), here per light of a cuticle scene.
//!
//! # The method
//!
//! Seen from the light, every texel stores
//! 1. **z0**, the depth of the nearest strand (pass 1), and
//! 2. **k layers** of opacity behind it (pass 2): layer i collects the strands whose depth z lies in
//!    [z0 + d_i, z0 + d_{i+1}), the last layer reaching to infinity.
//!
//! Because the layers start at each texel's own z0, they follow the hair's silhouette: few layers suffice where
//! opacity shadow maps (Kim & Neumann 2001), whose slices are planes, need hundreds. A lookup at depth z finds its
//! layer and interpolates linearly inside it, giving the optical depth Ω between the light and z; the transmittance
//! is exp(−Ω).
//!
//! # Opacity as optical depth
//!
//! A strand of opacity a (cuticle's per-strand opacity, the same the ray-traced mode uses) that covers a texel
//! centre adds σ = −ln(1 − a) to its layer, so n strands in front of a point give exp(−Σσ) = ∏(1 − a): the exact
//! transmittance of the ray-traced `transmittance = "exact"` mode, up to the map's sampling. Yuksel & Keyser
//! accumulate opacity additively and map it through exp(−κ Ω); with κ = 1 and σ as above the two agree.
//!
//! # Building: rasterised, not ray traced
//!
//! Each B-spline segment is cut into pieces about a texel long; each piece is a 2-D line of the strand's projected
//! width, and every texel whose *centre* it covers gets a fragment (point sampling, as a GPU rasterises lines).
//! A strand thinner than `min_width` texels is drawn `min_width` wide with opacity a · w / min_width (RenderMan's
//! `hair minwidth`, thesis §5.5): without it, strands thinner than a texel fall between texel centres and light
//! leaks through; drawn wider at full opacity they over-darken (both shown by tests below).
//!
//! Rasterising was chosen over tracing one ray per texel through Embree: the fur ball's 455k segments rasterise into
//! a 1024² map in tens of milliseconds on 2 cores, whereas an all-hits ray per texel runs at ~0.2 Mrays/s inside
//! that fur (`cuticle bench trace`, exact transmittance), i.e. ≈5 s per map — and still aliases without several
//! rays per texel. Both passes run in parallel over strands; fragments are accumulated with integer atomics
//! (z0 by `fetch_min` on the float's bits, optical depth in fixed point by `fetch_add`), so the map is the same
//! whatever the thread count or order.
//!
//! # Lookup
//!
//! Percentage-closer filtering: the transmittance of each texel in a tent footprint of radius `filter + 1` texels is
//! computed against that texel's own z0 and the results are averaged. The lookup depth is moved towards the light by
//! `bias` texels (a texel's world size at the point) so a strand does not shadow itself.
//!
//! # Lights
//!
//! Distant lights get an orthographic map along their direction (a sun of finite size is treated as its centre
//! direction); area lights a perspective map from their centre (all points of the light share it: the map is a
//! point-light approximation, as the thesis' RenderMan maps were). An **environment** gets one orthographic map
//! per cell of a Fibonacci partition of the sphere into `environment_directions` cells, each looking along the
//! cell's radiance-weighted mean direction; a light sample from direction ω reads the map of ω's cell. The error of
//! that approximation (a direction up to a cell's radius, ≈ 2/√K rad, from its map) is measured by
//! `cuticle study shadows`. Environment maps use half the configured resolution (memory: K maps).

use std::sync::atomic::{AtomicU32, Ordering};

use glam::Vec3;
use rayon::prelude::*;

use super::{DeepOpacityConfig, LayerSpacing};
use crate::hair::Strands;
use crate::image::Image;
use crate::light::Light;
use crate::ray::Ray;
use crate::util::color::luminance;

/// Fixed-point scale of accumulated optical depth (σ = 1 ⇔ 4096).
const SIGMA_SCALE: f32 = 4096.0;
/// The opacity above which a strand counts as fully opaque (σ = −ln(1 − a) stays finite: exp(−σ) = 1e-3).
const MAX_OPACITY: f32 = 0.999;
/// Length of the straight pieces a segment is cut into, texels: short enough that a strand's curvature within a
/// piece stays far below a texel (sagitta L²/8ρ for curvature radius ρ texels).
const PIECE_TEXELS: f32 = 4.0;
/// Most pieces one segment is cut into (a segment longer than this many texels is drawn with longer pieces).
const MAX_PIECES: usize = 256;

/// How a map projects world points: orthographic (distant lights, environment directions) or perspective (area
/// lights).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Projection {
    /// Parallel rays along `forward`; the map covers a square of half-side `half_extent` around `origin`.
    Orthographic { half_extent: f32 },
    /// Rays from `origin`; the map covers a square frustum of half-angle atan(`tan_half`).
    Perspective { tan_half: f32 },
}

/// Where a map looks from and what it covers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapFrame {
    origin: Vec3,
    right: Vec3,
    up: Vec3,
    forward: Vec3,
    projection: Projection,
    resolution: u32,
}

impl MapFrame {
    /// An orthographic map looking along `forward` at the sphere (`center`, `radius`), depth 0 a little in front of
    /// it, so that every point of the sphere has a positive depth.
    pub fn orthographic(forward: Vec3, center: Vec3, radius: f32, resolution: u32) -> MapFrame {
        let forward = forward.normalize();
        let (right, up) = forward.any_orthonormal_pair();
        MapFrame {
            origin: center - forward * (radius * 1.01),
            right,
            up,
            forward,
            projection: Projection::Orthographic {
                half_extent: radius * 1.01,
            },
            resolution,
        }
    }

    /// An orthographic map looking along `forward`, framing the strands' control points (which bound the curves)
    /// tightly: a square around their projection, depth 0 just in front of the nearest.
    pub fn fit_orthographic(forward: Vec3, strands: &Strands, resolution: u32) -> MapFrame {
        let forward = forward.normalize();
        let (right, up) = forward.any_orthonormal_pair();
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        let mut r_max = 0.0f32;
        for c in &strands.control_points {
            let p = Vec3::new(c[0], c[1], c[2]);
            let q = Vec3::new(p.dot(right), p.dot(up), p.dot(forward));
            lo = lo.min(q);
            hi = hi.max(q);
            r_max = r_max.max(c[3]);
        }
        if !(lo.is_finite() && hi.is_finite()) {
            return MapFrame::orthographic(forward, Vec3::ZERO, 1.0, resolution);
        }
        let mid = 0.5 * (lo + hi);
        let half_extent = (0.5 * (hi.x - lo.x).max(hi.y - lo.y) + r_max).max(1e-6) * 1.01;
        let margin = r_max + 1e-3 * half_extent;
        MapFrame {
            origin: right * mid.x + up * mid.y + forward * (lo.z - margin),
            right,
            up,
            forward,
            projection: Projection::Orthographic { half_extent },
            resolution,
        }
    }

    /// A perspective map from `eye` framing the sphere (`center`, `radius`); `None` when `eye` is inside it.
    pub fn perspective(eye: Vec3, center: Vec3, radius: f32, resolution: u32) -> Option<MapFrame> {
        let to = center - eye;
        let distance = to.length();
        if distance.is_nan() || distance <= radius * 1.01 {
            return None;
        }
        let forward = to / distance;
        let (right, up) = forward.any_orthonormal_pair();
        let sin_half = radius * 1.01 / distance;
        let tan_half = sin_half / (1.0 - sin_half * sin_half).sqrt();
        Some(MapFrame {
            origin: eye,
            right,
            up,
            forward,
            projection: Projection::Perspective { tan_half },
            resolution,
        })
    }

    /// The ray from the light through the centre of texel (`tx`, `ty`) (orthographic maps: from the depth-0 plane
    /// along `forward`; perspective maps: from the eye). For measuring what a ray-traced build would cost.
    pub fn texel_ray(&self, tx: u32, ty: u32) -> Ray {
        let res = self.resolution as f32;
        let (sx, sy) = (
            2.0 * (tx as f32 + 0.5) / res - 1.0,
            2.0 * (ty as f32 + 0.5) / res - 1.0,
        );
        match self.projection {
            Projection::Orthographic { half_extent } => Ray::new(
                self.origin + (self.right * sx + self.up * sy) * half_extent,
                self.forward,
            ),
            Projection::Perspective { tan_half } => Ray::new(
                self.origin,
                (self.forward + (self.right * sx + self.up * sy) * tan_half).normalize(),
            ),
        }
    }

    /// Continuous texel coordinates (texel centres at i + 0.5) and depth of `p`; `None` behind a perspective eye.
    #[inline]
    fn project(&self, p: Vec3) -> Option<(f32, f32, f32)> {
        let d = p - self.origin;
        let z = d.dot(self.forward);
        let scale = match self.projection {
            Projection::Orthographic { half_extent } => half_extent,
            Projection::Perspective { tan_half } => {
                if z <= 0.0 {
                    return None;
                }
                z * tan_half
            }
        };
        let half_res = 0.5 * self.resolution as f32;
        Some((
            (d.dot(self.right) / scale + 1.0) * half_res,
            (d.dot(self.up) / scale + 1.0) * half_res,
            z,
        ))
    }

    /// World size of one texel at depth `z`.
    #[inline]
    fn texel_size(&self, z: f32) -> f32 {
        let scale = match self.projection {
            Projection::Orthographic { half_extent } => half_extent,
            Projection::Perspective { tan_half } => z.max(0.0) * tan_half,
        };
        2.0 * scale / self.resolution as f32
    }
}

/// How strands are drawn into a map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Raster {
    /// Least width of a strand, texels.
    pub min_width: f32,
    /// Whether a widened strand's opacity is scaled by (true width / drawn width), keeping its coverage; `false`
    /// shows the over-darkening of widening alone.
    pub keep_coverage: bool,
}

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

/// Calls `fragment(texel index, depth, σ)` for every texel centre that strand pieces of `strands` cover in `frame`.
fn rasterise(
    strands: &Strands,
    frame: &MapFrame,
    raster: Raster,
    strand_range: std::ops::Range<usize>,
    mut fragment: impl FnMut(usize, f32, f32),
) {
    let res = frame.resolution as i64;
    let mut points = [(0.0f32, 0.0f32, 0.0f32, 0.0f32); MAX_PIECES + 1];
    for s in strand_range {
        let opacity = strands.opacity[s].min(MAX_OPACITY);
        if opacity <= 0.0 {
            continue;
        }
        let first_cp = strands.strand_offsets[s] as usize;
        let last_cp = strands.strand_offsets[s + 1] as usize;
        if last_cp < first_cp + 4 {
            continue;
        }
        for first in first_cp..=last_cp - 4 {
            let cps = &strands.control_points[first..first + 4];
            // Number of pieces: the control polygon's projected length bounds the curve's, in texels.
            let mut length = 0.0;
            let mut prev: Option<(f32, f32, f32)> = None;
            let mut visible = true;
            for c in cps {
                let Some(q) = frame.project(Vec3::new(c[0], c[1], c[2])) else {
                    visible = false;
                    break;
                };
                if let Some(pq) = prev {
                    length += ((q.0 - pq.0).powi(2) + (q.1 - pq.1).powi(2)).sqrt();
                }
                prev = Some(q);
            }
            if !visible {
                continue;
            }
            let n = (ceil_i(length / PIECE_TEXELS).max(1) as usize).min(MAX_PIECES);
            for (i, point) in points.iter_mut().enumerate().take(n + 1) {
                let u = i as f32 / n as f32;
                let b = crate::hair::strands::bspline_basis(u);
                let mut p = Vec3::ZERO;
                let mut r = 0.0;
                for j in 0..4 {
                    p += b[j] * Vec3::new(cps[j][0], cps[j][1], cps[j][2]);
                    r += b[j] * cps[j][3];
                }
                let (x, y, z) = frame.project(p).unwrap_or((f32::NAN, f32::NAN, f32::NAN));
                *point = (x, y, z, 2.0 * r / frame.texel_size(z));
            }
            for w in points[..=n].windows(2) {
                let ((xa, ya, za, wa), (xb, yb, zb, wb)) = (w[0], w[1]);
                if !(xa.is_finite() && xb.is_finite()) {
                    continue;
                }
                let width = 0.5 * (wa + wb);
                let drawn = width.max(raster.min_width);
                let a = if raster.keep_coverage && drawn > 0.0 {
                    opacity * width / drawn
                } else {
                    opacity
                };
                let sigma = -(1.0 - a).ln();
                let half = 0.5 * drawn;
                let (dx, dy) = (xb - xa, yb - ya);
                let len2 = dx * dx + dy * dy;
                // Texel centres (tx + 0.5) inside the piece's bounding box …
                let x0 = ceil_i(xa.min(xb) - half - 0.5).max(0);
                let x1 = floor_i(xa.max(xb) + half - 0.5).min(res - 1);
                let y0 = ceil_i(ya.min(yb) - half - 0.5).max(0);
                let y1 = floor_i(ya.max(yb) + half - 0.5).min(res - 1);
                let mut visit = |tx: i64, ty: i64| {
                    let (cx, cy) = (tx as f32 + 0.5, ty as f32 + 0.5);
                    // Parameter of the texel centre's projection onto the piece: half-open [0, 1) so a centre on
                    // the joint of two pieces is drawn once.
                    let t = if len2 > 0.0 {
                        ((cx - xa) * dx + (cy - ya) * dy) / len2
                    } else {
                        0.0
                    };
                    if !(0.0..1.0).contains(&t) {
                        return;
                    }
                    let (px, py) = (xa + t * dx - cx, ya + t * dy - cy);
                    if px * px + py * py > half * half {
                        return;
                    }
                    fragment((ty * res + tx) as usize, za + t * (zb - za), sigma);
                };
                // … visited along the piece's major axis, each column (row) only over the centres within `half` of
                // the line (|Δminor| ≤ half · length / |Δmajor|, plus a rounding margin; `visit` decides exactly).
                if len2 > 0.0 && dx.abs() >= dy.abs() {
                    let (slope, reach) = (dy / dx, half * len2.sqrt() / dx.abs() + 1e-3);
                    for tx in x0..=x1 {
                        let y = ya + (tx as f32 + 0.5 - xa) * slope;
                        for ty in ceil_i(y - reach - 0.5).max(y0)..=floor_i(y + reach - 0.5).min(y1)
                        {
                            visit(tx, ty);
                        }
                    }
                } else if len2 > 0.0 {
                    let (slope, reach) = (dx / dy, half * len2.sqrt() / dy.abs() + 1e-3);
                    for ty in y0..=y1 {
                        let x = xa + (ty as f32 + 0.5 - ya) * slope;
                        for tx in ceil_i(x - reach - 0.5).max(x0)..=floor_i(x + reach - 0.5).min(x1)
                        {
                            visit(tx, ty);
                        }
                    }
                } else {
                    for ty in y0..=y1 {
                        for tx in x0..=x1 {
                            visit(tx, ty);
                        }
                    }
                }
            }
        }
    }
}

/// ⌊v⌋ as an integer without a libm call (baseline x86-64 has no rounding instruction); saturates like `as`.
#[inline]
fn floor_i(v: f32) -> i64 {
    let i = v as i64;
    if (i as f32) > v {
        i - 1
    } else {
        i
    }
}

/// ⌈v⌉ as an integer (see [`floor_i`]).
#[inline]
fn ceil_i(v: f32) -> i64 {
    let i = v as i64;
    if (i as f32) < v {
        i + 1
    } else {
        i
    }
}

/// Strands per parallel work item of a build.
const STRANDS_PER_TASK: usize = 256;

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

/// What stands in for a shadow ray towards light j.
#[derive(Debug, Clone)]
enum LightMaps {
    /// One map for every direction of the light.
    One(Box<DeepOpacityMap>),
    /// An environment: cell directions (Fibonacci points) and one map per cell.
    Cells {
        centres: Vec<Vec3>,
        maps: Vec<DeepOpacityMap>,
    },
    /// No map could be framed (an area light inside the hair's bounding sphere): ray-traced shadows instead.
    Raytraced,
}

/// The deep opacity maps of every light of a scene.
#[derive(Debug, Clone)]
pub struct ShadowMaps {
    lights: Vec<LightMaps>,
}

/// `n` points spread evenly over the sphere (the spherical Fibonacci lattice).
pub fn fibonacci_sphere(n: u32) -> Vec<Vec3> {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - (2.0 * i as f32 + 1.0) / n as f32;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = golden * i as f32;
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

#[inline]
fn nearest(centres: &[Vec3], w: Vec3) -> usize {
    let mut best = (0, f32::NEG_INFINITY);
    for (i, c) in centres.iter().enumerate() {
        let d = c.dot(w);
        if d > best.1 {
            best = (i, d);
        }
    }
    best.0
}

impl ShadowMaps {
    /// Builds the maps of `lights` for `strands`.
    pub fn build(strands: &Strands, lights: &[Light], config: &DeepOpacityConfig) -> ShadowMaps {
        let (lo, hi) = strands.bounds();
        let center = 0.5 * (lo + hi);
        let radius = (0.5 * (hi - lo).length()).max(1e-6);
        let depth = config.depth * radius;
        let raster = Raster {
            min_width: config.min_width,
            keep_coverage: true,
        };
        let map = |frame| DeepOpacityMap::build(strands, frame, config, depth, raster);
        let lights = lights
            .iter()
            .map(|light| match light {
                Light::Distant(d) => LightMaps::One(Box::new(map(MapFrame::fit_orthographic(
                    -d.to_sun(),
                    strands,
                    config.resolution,
                )))),
                Light::Area(a) => {
                    match MapFrame::perspective(
                        a.shape().center(),
                        center,
                        radius,
                        config.resolution,
                    ) {
                        Some(frame) => LightMaps::One(Box::new(map(frame))),
                        None => LightMaps::Raytraced,
                    }
                }
                Light::Environment(_) => {
                    let centres = fibonacci_sphere(config.environment_directions);
                    let directions = environment_directions(light, &centres);
                    let resolution = (config.resolution / 2).max(16);
                    let maps = directions
                        .iter()
                        .map(|&to_light| {
                            map(MapFrame::fit_orthographic(-to_light, strands, resolution))
                        })
                        .collect();
                    LightMaps::Cells { centres, maps }
                }
            })
            .collect();
        ShadowMaps { lights }
    }

    /// Transmittance towards light `light` from `p` along `wi` (towards the light); `None` when this light has no
    /// map and needs a shadow ray.
    #[inline]
    pub fn transmittance(&self, light: usize, p: Vec3, wi: Vec3) -> Option<f32> {
        match &self.lights[light] {
            LightMaps::One(m) => Some(m.transmittance(p)),
            LightMaps::Cells { centres, maps } => Some(maps[nearest(centres, wi)].transmittance(p)),
            LightMaps::Raytraced => None,
        }
    }

    /// Memory held by all maps, bytes.
    pub fn bytes(&self) -> usize {
        self.lights
            .iter()
            .map(|l| match l {
                LightMaps::One(m) => m.bytes(),
                LightMaps::Cells { maps, .. } => maps.iter().map(DeepOpacityMap::bytes).sum(),
                LightMaps::Raytraced => 0,
            })
            .sum()
    }

    /// Every map with a name (`light0`, `light1.cell3`, …), for inspection.
    pub fn maps(&self) -> Vec<(String, &DeepOpacityMap)> {
        let mut out = Vec::new();
        for (j, l) in self.lights.iter().enumerate() {
            match l {
                LightMaps::One(m) => out.push((format!("light{j}"), m.as_ref())),
                LightMaps::Cells { maps, .. } => {
                    for (c, m) in maps.iter().enumerate() {
                        out.push((format!("light{j}.cell{c}"), m));
                    }
                }
                LightMaps::Raytraced => {}
            }
        }
        out
    }
}

/// Radiance-weighted mean direction (towards the light) of each Fibonacci cell of an environment, estimated from
/// stratified importance samples; a cell no sample reached keeps its centre.
fn environment_directions(light: &Light, centres: &[Vec3]) -> Vec<Vec3> {
    const PER_SIDE: u32 = 128;
    let mut sums = vec![Vec3::ZERO; centres.len()];
    for i in 0..PER_SIDE {
        for j in 0..PER_SIDE {
            let u = [
                (i as f32 + 0.5) / PER_SIDE as f32,
                (j as f32 + 0.5) / PER_SIDE as f32,
            ];
            let Some(ls) = light.sample_li(Vec3::ZERO, u) else {
                continue;
            };
            let weight = luminance(ls.radiance) / ls.pdf;
            if weight.is_finite() && weight > 0.0 {
                sums[nearest(centres, ls.wi)] += weight * ls.wi;
            }
        }
    }
    sums.iter()
        .zip(centres)
        .map(|(s, c)| s.try_normalize().unwrap_or(*c))
        .collect()
}

#[cfg(test)]
mod tests {
    //! The method's failure modes, each shown with numbers on a synthetic strand field whose exact transmittance is
    //! known in closed form: straight strands along x at (y_i, z_i), light travelling along +z, so a point
    //! (x, y, z) is shadowed by every strand with |y − y_i| < r_i and z_i < z.

    use super::*;
    use crate::hair::HairModel;

    /// One straight strand: y, z of its axis, radius, opacity.
    #[derive(Clone, Copy)]
    struct Line {
        y: f32,
        z: f32,
        r: f32,
        a: f32,
    }

    const HALF: f32 = 1.0; // the field spans x, y ∈ [−1, 1]

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

    fn exact(lines: &[Line], p: Vec3) -> f32 {
        lines
            .iter()
            .filter(|l| (p.y - l.y).abs() < l.r && l.z < p.z)
            .map(|l| 1.0 - l.a)
            .product()
    }

    fn config(resolution: u32, layers: u32, spacing: LayerSpacing) -> DeepOpacityConfig {
        DeepOpacityConfig {
            resolution,
            layers,
            spacing,
            ..DeepOpacityConfig::default()
        }
    }

    /// A map looking along +z at the field, framing the square [−1, 1]² exactly (texel centres off the strands'
    /// symmetry), with layers over `depth`.
    fn map(
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
        DeepOpacityMap::build(&strands(lines), frame, config, depth, raster)
    }

    const RASTER: Raster = Raster {
        min_width: 1.0,
        keep_coverage: true,
    };

    /// Mean |T_map − T_exact| over a grid of points at the given depths.
    fn mean_error(lines: &[Line], m: &DeepOpacityMap, depths: &[f32]) -> f32 {
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

    /// Sheets of strands that tile y completely (each sheet multiplies transmittance by 1 − a everywhere).
    fn sheet(z: f32, spacing: f32, a: f32) -> Vec<Line> {
        let n = (2.0 * HALF / spacing).ceil() as i32;
        (0..=n)
            .map(|i| Line {
                y: -HALF + spacing * i as f32,
                z,
                r: 0.5 * spacing,
                a,
            })
            .collect()
    }

    #[test]
    fn texel_rays_project_back_to_their_texels() {
        let frames = [
            MapFrame::orthographic(Vec3::new(1.0, -1.0, 1.0), Vec3::new(0.0, 0.5, 0.0), 2.0, 64),
            MapFrame::perspective(Vec3::new(0.0, 5.0, 1.0), Vec3::ZERO, 1.5, 64).unwrap(),
        ];
        for frame in frames {
            for (tx, ty) in [(0, 0), (17, 40), (63, 63)] {
                let ray = frame.texel_ray(tx, ty);
                let (x, y, _) = frame.project(ray.at(2.5)).unwrap();
                assert!(
                    (x - (tx as f32 + 0.5)).abs() < 1e-3 && (y - (ty as f32 + 0.5)).abs() < 1e-3
                );
            }
        }
        assert!(MapFrame::perspective(Vec3::ZERO, Vec3::ZERO, 1.0, 64).is_none());
    }

    #[test]
    fn integer_floor_and_ceil() {
        for v in [-2.5f32, -2.0, -0.3, 0.0, 0.3, 1.0, 7.999, 1e6] {
            assert_eq!(floor_i(v), v.floor() as i64, "floor {v}");
            assert_eq!(ceil_i(v), v.ceil() as i64, "ceil {v}");
        }
    }

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
        println!("layer banding: mean |ΔT| = {e2:.4} with 2 layers, {e32:.4} with 32");
        assert!(e2 > 0.15, "2 layers should band visibly, mean |ΔT| = {e2}");
        assert!(e32 < 0.02, "32 layers should not, mean |ΔT| = {e32}");
    }

    #[test]
    fn thin_strands_leak_without_min_width_and_over_darken_without_coverage() {
        // Strands 0.3 texel wide, one per texel row, each 0.25 texel off the row's texel centre: point-sampled at
        // their true width they cover no centre at all (light leaks through); drawn 1 texel wide at full opacity
        // they cover every centre (over-darkening); drawn 1 texel wide with opacity scaled by 0.3 they are right
        // on average.
        let res = 128;
        let texel = 2.0 * HALF / res as f32;
        let a = 0.5;
        let lines: Vec<Line> = (0..res)
            .map(|i| Line {
                y: -HALF + texel * (i as f32 + 0.75),
                z: 0.0,
                r: 0.15 * texel,
                a,
            })
            .collect();
        let cfg = DeepOpacityConfig {
            filter: 2,
            ..config(res, 4, LayerSpacing::Uniform)
        };
        let mean_t = |raster: Raster| {
            let m = map(&lines, &cfg, 0.5, raster);
            let mut sum = 0.0;
            for i in 0..50 {
                for j in 0..50 {
                    sum += m.transmittance(Vec3::new(
                        -0.5 + i as f32 / 50.0,
                        -0.5 + j as f32 / 50.0,
                        0.5,
                    ));
                }
            }
            sum / 2500.0
        };
        let want = 1.0 - a * 0.3; // the strands cover 30 % of the area
        let leak = mean_t(Raster {
            min_width: 0.0,
            keep_coverage: true,
        });
        let dark = mean_t(Raster {
            min_width: 1.0,
            keep_coverage: false,
        });
        let right = mean_t(RASTER);
        println!("thin strands: exact mean T {want:.3}; no min width {leak:.3}; widened at full opacity {dark:.3}; min width with coverage {right:.3}");
        assert!(
            leak > 0.99,
            "thin strands should leak without min_width: T = {leak}"
        );
        assert!(
            dark < 0.55,
            "widening at full opacity should over-darken: T = {dark}"
        );
        assert!(
            (right - want).abs() < 0.01,
            "min_width should keep the mean: T = {right}, want {want}"
        );
    }

    #[test]
    fn depth_bias_removes_self_shadow_acne() {
        // A single sheet of strands tilted 45° to the light: shading points on the strands' far halves (between the
        // axis and the back surface) must see no strand in front of them — they are on it. Without bias the
        // filter footprint reaches texels whose z0 lies in front of the point (acne); the default bias removes it.
        let mut lines = Vec::new();
        for i in 0..40 {
            let y = -0.95 + 0.0475 * i as f32;
            lines.push(Line {
                y,
                z: y, // 45°: depth grows with y along the tilted sheet
                r: 0.008,
                a: 0.8,
            });
        }
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
        let one = lit_fraction(1.0);
        let default = lit_fraction(DeepOpacityConfig::default().bias);
        println!("acne on a 45° sheet: mean T = {no_bias:.3} without bias, {one:.3} at 1 texel, {default:.3} with the default bias");
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
        let mut lines = Vec::new();
        for i in 0..25 {
            let y = -0.96 + 0.08 * i as f32;
            lines.push(Line {
                y,
                z: 0.0,
                r: 0.01,
                a: 0.9,
            });
            lines.push(Line {
                y: y + 0.04,
                z: 0.2,
                r: 0.01,
                a: 0.9,
            });
        }
        let err = |res: u32| {
            let cfg = DeepOpacityConfig {
                filter: 0,
                ..config(res, 8, LayerSpacing::Uniform)
            };
            mean_error(&lines, &map(&lines, &cfg, 0.5, RASTER), &[0.4])
        };
        let (coarse, fine) = (err(32), err(1024));
        println!("stripes: mean |ΔT| = {coarse:.4} at 32², {fine:.4} at 1024²");
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

    #[test]
    fn environment_cells_follow_the_light() {
        let centres = fibonacci_sphere(16);
        assert!(centres.iter().all(|c| (c.length() - 1.0).abs() < 1e-5));
        // A constant environment: every cell's mean direction stays inside its own cell.
        let env = Light::Environment(crate::light::Environment::constant(Vec3::ONE).unwrap());
        let dirs = environment_directions(&env, &centres);
        for (i, d) in dirs.iter().enumerate() {
            assert_eq!(
                nearest(&centres, *d),
                i,
                "cell {i}: mean direction {d} left its cell"
            );
        }
    }
}
