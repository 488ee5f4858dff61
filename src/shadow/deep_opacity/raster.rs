//! Rasterising strands into a map: B-spline segments cut into pieces about a texel long, each point-sampled at the
//! texel centres it covers (see "Building" in the [module docs](super)).

use glam::Vec3;

use super::MapFrame;
use crate::hair::Strands;

/// The opacity above which a strand counts as fully opaque (σ = −ln(1 − a) stays finite: exp(−σ) = 1e-3).
const MAX_OPACITY: f32 = 0.999;
/// Length of the straight pieces a segment is cut into, texels: short enough that a strand's curvature within a
/// piece stays far below a texel (sagitta L²/8ρ for curvature radius ρ texels).
const PIECE_TEXELS: f32 = 4.0;
/// Most pieces one segment is cut into (a segment longer than this many texels is drawn with longer pieces).
const MAX_PIECES: usize = 256;

/// How strands are drawn into a map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Raster {
    /// Least width of a strand, texels.
    pub min_width: f32,
    /// Whether a widened strand's opacity is scaled by (true width / drawn width), keeping its coverage; `false`
    /// shows the over-darkening of widening alone.
    pub keep_coverage: bool,
}

/// Calls `fragment(texel index, depth, σ, strands)` for every texel centre that strand pieces of `strands` cover in
/// `frame`, `strands` being the share of a strand the fragment stands for (w / drawn width when a thin strand is
/// widened with its coverage kept, else 1): the strand count dual scattering reads.
pub(super) fn rasterise(
    strands: &Strands,
    frame: &MapFrame,
    raster: Raster,
    strand_range: std::ops::Range<usize>,
    mut fragment: impl FnMut(usize, f32, f32, f32),
) {
    // One piece: the strand pieces are cut, projected and point-sampled in one pass over the segments.
    let res = frame.resolution as i64;
    let mut points = [(0.0f32, 0.0f32, 0.0f32, 0.0f32); MAX_PIECES + 1];
    for s in strand_range {
        let opacity = strands.opacity[s].min(MAX_OPACITY);
        if opacity <= 0.0 {
            continue;
        }
        for segment in strands.segments_of(s) {
            let first = strands.segment_first[segment] as usize;
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
                let cover = if raster.keep_coverage && drawn > 0.0 {
                    width / drawn
                } else {
                    1.0
                };
                let sigma = -(1.0 - opacity * cover).ln();
                let half = 0.5 * drawn;
                let (dx, dy) = (xb - xa, yb - ya);
                let len2 = dx * dx + dy * dy;
                // Texel centres (tx + 0.5) inside the piece's bounding box …
                let (x0, x1) = centres_in(xa.min(xb) - half, xa.max(xb) + half, (0, res - 1));
                let (y0, y1) = centres_in(ya.min(yb) - half, ya.max(yb) + half, (0, res - 1));
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
                    fragment((ty * res + tx) as usize, za + t * (zb - za), sigma, cover);
                };
                // … visited along the piece's major axis (x for a flat piece, y for a steep one).
                let half_length = half * len2.sqrt();
                if len2 > 0.0 && dx.abs() >= dy.abs() {
                    walk_line((x0, x1), (y0, y1), (xa, ya), (dx, dy), half_length, visit);
                } else if len2 > 0.0 {
                    let visit = |ty, tx| visit(tx, ty);
                    walk_line((y0, y1), (x0, x1), (ya, xa), (dy, dx), half_length, visit);
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

/// Visits a piece's texel centres column by column along its major axis, in (major, minor) coordinates: (x, y) for
/// a flat piece, (y, x) for a steep one. In each column `major` of `majors` only the centres of `minors` that can
/// lie within `half` of the line through `start` along `delta` are visited: |Δminor| ≤ half · length / |Δmajor|
/// (`half_length` = half · length), plus a rounding margin; `visit(major, minor)` decides exactly.
#[inline]
fn walk_line(
    majors: (i64, i64),
    minors: (i64, i64),
    start: (f32, f32),
    delta: (f32, f32),
    half_length: f32,
    mut visit: impl FnMut(i64, i64),
) {
    let (slope, reach) = (delta.1 / delta.0, half_length / delta.0.abs() + 1e-3);
    for major in majors.0..=majors.1 {
        let minor = start.1 + (major as f32 + 0.5 - start.0) * slope;
        let (lo, hi) = centres_in(minor - reach, minor + reach, minors);
        for minor in lo..=hi {
            visit(major, minor);
        }
    }
}

/// The first and last index i whose texel centre i + 0.5 lies in [`lo`, `hi`], clamped to `clamp` (empty when the
/// first exceeds the last).
#[inline]
fn centres_in(lo: f32, hi: f32, clamp: (i64, i64)) -> (i64, i64) {
    (
        ceil_i(lo - 0.5).max(clamp.0),
        floor_i(hi - 0.5).min(clamp.1),
    )
}

/// ⌊v⌋ as an integer without a libm call (baseline x86-64 has no rounding instruction); saturates like `as`.
#[inline]
pub(super) fn floor_i(v: f32) -> i64 {
    let i = v as i64;
    if (i as f32) > v {
        i - 1
    } else {
        i
    }
}

/// ⌈v⌉ as an integer (see [`floor_i`]).
#[inline]
pub(super) fn ceil_i(v: f32) -> i64 {
    let i = v as i64;
    if (i as f32) < v {
        i + 1
    } else {
        i
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_field::{config, map, Line, HALF, RASTER};
    use super::*;
    use crate::shadow::{DeepOpacityConfig, LayerSpacing};

    #[test]
    fn integer_floor_and_ceil() {
        for v in [-2.5f32, -2.0, -0.3, 0.0, 0.3, 1.0, 7.999, 1e6] {
            assert_eq!(floor_i(v), v.floor() as i64, "floor {v}");
            assert_eq!(ceil_i(v), v.ceil() as i64, "ceil {v}");
        }
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
}
