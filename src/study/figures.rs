//! The figures of a study, drawn with the chart rasteriser of [`crate::bsdf::chart`] (RGB images of linear values,
//! for [`crate::image::write`] as PNG):
//!
//! - [`error_time_chart`]: error against time on log–log axes, one polyline per series with a `+` marker and a
//!   small label (spp, layers, resolution) at each measured point;
//! - [`mosaic`]: rows of equally sized image crops, each labelled above, upscaled by an integer factor (nearest
//!   neighbour, so pixels stay visible) and multiplied by one common exposure.

use glam::Vec3;

use crate::bsdf::chart::{text_width, Axis, Canvas, LineChart, Rect, Series, INK, TEXT_HEIGHT};
use crate::image::Image;

/// One measured point of a chart series.
#[derive(Debug, Clone, PartialEq)]
pub struct Point {
    /// Horizontal value (> 0).
    pub x: f64,
    /// Vertical value (> 0).
    pub y: f64,
    /// A short label drawn beside the point.
    pub label: String,
}

/// A series of [`error_time_chart`].
#[derive(Debug, Clone, PartialEq)]
pub struct ChartSeries {
    /// The legend text.
    pub label: String,
    /// Linear RGB.
    pub color: Vec3,
    /// The points, in drawing order.
    pub points: Vec<Point>,
}

/// A log10 axis of whole decades covering [`lo`, `hi`] (both > 0; anything else gives one decade below 1).
fn log_axis(label: &str, lo: f64, hi: f64) -> Axis {
    let (lo, hi) = if lo > 0.0 && hi >= lo && hi.is_finite() {
        (lo, hi)
    } else {
        (0.1, 1.0)
    };
    let top = hi.log10().ceil();
    let bottom = lo.log10().floor();
    let decades = (top - bottom).max(1.0) as u32;
    Axis::log_decades(label, hi as f32, decades)
}

/// Error against time: `series` on log–log axes labelled `x_label` and `y_label`, `width × height` pixels.
/// Points with a non-positive or non-finite coordinate are left out.
pub fn error_time_chart(
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[ChartSeries],
    width: usize,
    height: usize,
) -> Image {
    let valid = |p: &&Point| p.x > 0.0 && p.y > 0.0 && p.x.is_finite() && p.y.is_finite();
    let points = || series.iter().flat_map(|s| s.points.iter().filter(valid));
    let range = |f: fn(&Point) -> f64| {
        points()
            .map(f)
            .fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            })
    };
    let (x_lo, x_hi) = range(|p| p.x);
    let (y_lo, y_hi) = range(|p| p.y);
    let mut chart = LineChart {
        title: title.to_owned(),
        x: log_axis(x_label, x_lo, x_hi),
        y: log_axis(y_label, y_lo, y_hi),
        series: series
            .iter()
            .map(|s| Series {
                label: s.label.clone(),
                color: s.color,
                width: 2.0,
                points: Vec::new(),
            })
            .collect(),
    };
    // A `+` of ±5 pixels at each point, drawn as excursions of the polyline (coverage is a max, so retraced
    // segments are not darkened twice).
    let area = chart.plot_area(width, height);
    let decades = |a: &Axis| (a.max / a.min).log10();
    let fx = 10f32.powf(5.0 * decades(&chart.x) / area.width().max(1) as f32);
    let fy = 10f32.powf(5.0 * decades(&chart.y) / area.height().max(1) as f32);
    for (out, s) in chart.series.iter_mut().zip(series) {
        for p in s.points.iter().filter(valid) {
            let (x, y) = (p.x as f32, p.y as f32);
            out.points.extend([
                (x, y),
                (x * fx, y),
                (x / fx, y),
                (x, y),
                (x, y * fy),
                (x, y / fy),
                (x, y),
            ]);
        }
    }
    let mut canvas = Canvas::from_image(chart.render(width, height));
    for s in series {
        for p in s.points.iter().filter(valid) {
            let (px, py) = chart.to_pixel(area, p.x as f32, p.y as f32);
            if px.is_finite() && py.is_finite() && px >= 0.0 && py >= 0.0 {
                let y = (py as usize).saturating_sub(TEXT_HEIGHT + 4);
                canvas.text(px as usize + 6, y, &p.label, s.color * 0.7);
            }
        }
    }
    canvas.into_image()
}

/// A labelled square crop for [`mosaic`]: `size × size` linear RGB values, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Panel {
    /// Drawn above the crop.
    pub label: String,
    /// The pixels.
    pub rgb: Vec<Vec3>,
}

/// The beauty (`R, G, B`) of the `size × size` window of `image` at (`x0`, `y0`), which must lie inside it.
pub fn crop(image: &Image, x0: usize, y0: usize, size: usize) -> Result<Vec<Vec3>, String> {
    let find = |name: &str| {
        image
            .channel_index(name)
            .ok_or_else(|| format!("the image has no channel {name:?}"))
    };
    let (r, g, b) = (find("R")?, find("G")?, find("B")?);
    if x0 + size > image.width || y0 + size > image.height {
        return Err(format!(
            "crop {size}x{size} at ({x0}, {y0}) leaves the {}x{} image",
            image.width, image.height
        ));
    }
    let mut out = Vec::with_capacity(size * size);
    for y in y0..y0 + size {
        for x in x0..x0 + size {
            let p = image.pixel(x, y);
            out.push(Vec3::new(p[r], p[g], p[b]));
        }
    }
    Ok(out)
}

/// The whole beauty of `image` resampled (nearest) into a `size × size` square (aspect kept, centred on black), with
/// the window (`x0`, `y0`, `window`) outlined in red: where the crops come from.
pub fn overview(image: &Image, x0: usize, y0: usize, window: usize, size: usize) -> Vec<Vec3> {
    let mut out = vec![Vec3::ZERO; size * size];
    let (Some(r), Some(g), Some(b)) = (
        image.channel_index("R"),
        image.channel_index("G"),
        image.channel_index("B"),
    ) else {
        return out;
    };
    let scale = (image.width.max(image.height) as f32 / size as f32).max(f32::MIN_POSITIVE);
    let (ox, oy) = (
        (size as f32 - image.width as f32 / scale) * 0.5,
        (size as f32 - image.height as f32 / scale) * 0.5,
    );
    for j in 0..size {
        for i in 0..size {
            let sx = ((i as f32 + 0.5 - ox) * scale).floor();
            let sy = ((j as f32 + 0.5 - oy) * scale).floor();
            if sx < 0.0 || sy < 0.0 || sx >= image.width as f32 || sy >= image.height as f32 {
                continue;
            }
            let p = image.pixel(sx as usize, sy as usize);
            out[j * size + i] = Vec3::new(p[r], p[g], p[b]);
        }
    }
    // The outline, in panel pixels (so no edge falls between sampled source pixels).
    let to_panel =
        |v: usize, o: f32| ((v as f32 / scale + o).round().max(0.0) as usize).min(size - 1);
    let (i0, i1) = (
        to_panel(x0, ox),
        to_panel(x0 + window, ox).saturating_sub(1),
    );
    let (j0, j1) = (
        to_panel(y0, oy),
        to_panel(y0 + window, oy).saturating_sub(1),
    );
    let red = Vec3::new(1.0, 0.0, 0.0);
    for i in i0..=i1.max(i0) {
        out[j0 * size + i] = red;
        out[j1.max(j0) * size + i] = red;
    }
    for j in j0..=j1.max(j0) {
        out[j * size + i0] = red;
        out[j * size + i1.max(i0)] = red;
    }
    out
}

/// Gap between panels, pixels.
const GAP: usize = 10;
/// Panels are upscaled to at least this many pixels across (and to their widest label).
const MIN_PANEL: usize = 168;

/// Rows of `size × size` panels under `title`, each panel's pixels multiplied by `exposure` (values above 1 clip
/// when written as 8-bit).
pub fn mosaic(title: &str, rows: &[Vec<Panel>], size: usize, exposure: f32) -> Image {
    let size = size.max(1);
    let widest = rows
        .iter()
        .flatten()
        .map(|p| text_width(&p.label))
        .max()
        .unwrap_or(0);
    let scale = MIN_PANEL.max(widest + 4).div_ceil(size);
    let panel = size * scale;
    let cols = rows.iter().map(Vec::len).max().unwrap_or(0).max(1);
    let label_h = TEXT_HEIGHT + 6;
    let title_h = TEXT_HEIGHT + 16;
    let width = (GAP + cols * (panel + GAP)).max(text_width(title) + 2 * GAP);
    let height = title_h + rows.len() * (label_h + panel + GAP) + GAP;
    let mut canvas = Canvas::new(width, height);
    canvas.text(GAP, 8, title, INK);
    for (r, row) in rows.iter().enumerate() {
        let top = title_h + r * (label_h + panel + GAP);
        for (c, p) in row.iter().enumerate() {
            let left = GAP + c * (panel + GAP);
            canvas.text(left, top, &p.label, INK);
            let y_img = top + label_h;
            for (k, v) in p.rgb.iter().enumerate().take(size * size) {
                let (i, j) = (k % size, k / size);
                canvas.fill(
                    Rect {
                        x0: left + i * scale,
                        y0: y_img + j * scale,
                        x1: left + (i + 1) * scale,
                        y1: y_img + (j + 1) * scale,
                    },
                    *v * exposure,
                );
            }
        }
    }
    canvas.into_image()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mosaic_places_panels_and_scales_them() {
        let red = Vec3::new(1.0, 0.0, 0.0);
        let panel = |label: &str| Panel {
            label: label.to_owned(),
            rgb: vec![red; 4],
        };
        let image = mosaic(
            "T",
            &[vec![panel("A"), panel("B")], vec![panel("C")]],
            2,
            1.0,
        );
        let scale = MIN_PANEL.div_ceil(2);
        let panel_px = 2 * scale;
        assert_eq!(image.width, GAP + 2 * (panel_px + GAP));
        let canvas = Canvas::from_image(image);
        let top = TEXT_HEIGHT + 16 + TEXT_HEIGHT + 6;
        assert_eq!(canvas.color(GAP, top), red);
        assert_eq!(canvas.color(GAP + panel_px - 1, top + panel_px - 1), red);
        assert_ne!(canvas.color(GAP + panel_px, top), red);
    }

    #[test]
    fn chart_axes_cover_every_point() {
        let s = ChartSeries {
            label: "S".to_owned(),
            color: Vec3::new(0.0, 0.0, 1.0),
            points: vec![
                Point {
                    x: 0.03,
                    y: 0.2,
                    label: "1".to_owned(),
                },
                Point {
                    x: 12.0,
                    y: 0.004,
                    label: "64".to_owned(),
                },
            ],
        };
        let x = log_axis("X", 0.03, 12.0);
        assert_eq!((x.min, x.max), (0.01, 100.0));
        let image = error_time_chart("C", "X", "Y", &[s], 600, 400);
        assert_eq!((image.width, image.height), (600, 400));
    }
}
