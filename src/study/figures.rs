//! The figures of a study:
//!
//! - [`error_time_line_chart`]: error against time on log–log axes, one polyline per series with a `+` marker and a
//!   small label (spp, layers, resolution) at each measured point, drawn by [`crate::plot`] (PNG and SVG);
//! - [`hair_window`]: where the crops are taken, centred on the hair (the coverage's centroid);
//! - [`mosaic`]: rows of equally sized image crops, each labelled above, upscaled by an integer factor (nearest
//!   neighbour, so pixels stay visible) and multiplied by one common exposure. An image, not a chart: the pixels
//!   are copied as image operations, and only the labels are set by [`crate::plot::annotate`].

use glam::Vec3;
use plotters::style::RGBColor;

use crate::image::Image;
use crate::plot::{self, Axis, Label, LineChart, PlotError, Series};

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

/// A series of [`error_time_line_chart`].
#[derive(Debug, Clone, PartialEq)]
pub struct ChartSeries {
    /// The legend text.
    pub label: String,
    /// The line colour.
    pub color: RGBColor,
    /// The points, in drawing order.
    pub points: Vec<Point>,
}

/// Error against time: `series` on log–log axes (whole decades covering every point) labelled `x_label` and
/// `y_label`, each point marked and labelled. Points with a non-positive or non-finite coordinate are left out.
pub(crate) fn error_time_line_chart(
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[ChartSeries],
) -> LineChart {
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
    LineChart {
        title: title.to_owned(),
        x: Axis::log_covering(x_label, x_lo, x_hi),
        y: Axis::log_covering(y_label, y_lo, y_hi),
        series: series
            .iter()
            .map(|s| {
                let kept: Vec<&Point> = s.points.iter().filter(valid).collect();
                Series {
                    markers: true,
                    point_labels: kept.iter().map(|p| p.label.clone()).collect(),
                    ..Series::line(
                        &s.label,
                        s.color,
                        2,
                        kept.iter().map(|p| (p.x, p.y)).collect(),
                    )
                }
            })
            .collect(),
    }
}

/// The 99th percentile of the largest channel over the finite values of `rgb` (an exposure or white level), or
/// `None` when there are none.
pub fn p99_largest_channel(rgb: impl IntoIterator<Item = Vec3>) -> Option<f32> {
    let mut peaks: Vec<f32> = rgb
        .into_iter()
        .map(Vec3::max_element)
        .filter(|v| v.is_finite())
        .collect();
    peaks.sort_by(f32::total_cmp);
    peaks
        .get((peaks.len() * 99 / 100).min(peaks.len().saturating_sub(1)))
        .copied()
}

/// A labelled square crop for [`mosaic`]: `size × size` linear RGB values, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Panel {
    /// Drawn above the crop.
    pub label: String,
    /// The pixels.
    pub rgb: Vec<Vec3>,
}

/// The `size × size` window of `image` (`size` clamped to the image) centred on the hair: on the centroid of the
/// coverage (`A`, clamped to [0, 1]; non-finite values count as none), moved inside the image where the centroid is
/// nearer an edge than half the window. Without coverage (no `A` channel, or nothing covered) the image's centre.
/// Returns (x0, y0, side).
pub fn hair_window(image: &Image, size: usize) -> (usize, usize, usize) {
    let (w, h) = (image.width, image.height);
    let size = size.min(w).min(h).max(1);
    let mut centre = (w as f64 * 0.5, h as f64 * 0.5);
    if let Some(a) = image.channel_index("A") {
        let n = image.channels.len();
        let (mut sum, mut sx, mut sy) = (0.0f64, 0.0f64, 0.0f64);
        for (k, p) in image.data.chunks_exact(n).enumerate() {
            let c = if p[a].is_finite() {
                f64::from(p[a].clamp(0.0, 1.0))
            } else {
                0.0
            };
            sum += c;
            sx += c * ((k % w) as f64 + 0.5);
            sy += c * ((k / w) as f64 + 0.5);
        }
        if sum > 0.0 {
            centre = (sx / sum, sy / sum);
        }
    }
    let place = |c: f64, extent: usize| {
        let start = (c - size as f64 * 0.5).round().max(0.0) as usize;
        start.min(extent.saturating_sub(size))
    };
    (place(centre.0, w), place(centre.1, h), size)
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

/// The exposure that puts the 99th percentile of `crop`'s largest channel at 0.9 (within [1/8, 64]; 1 for a black
/// crop): the one exposure a mosaic's panels share.
pub fn exposure(crop: &[Vec3]) -> f32 {
    match p99_largest_channel(crop.iter().copied()) {
        Some(p99) if p99 > 0.0 => (0.9 / p99).clamp(0.125, 64.0),
        _ => 1.0,
    }
}

/// Gap between panels, pixels.
const GAP: usize = 10;
/// Panels are upscaled to at least this many pixels across (and to their widest label).
const MIN_PANEL: usize = 168;
/// Size of the labels and title, pixels.
const TEXT_SIZE: f64 = 15.0;
/// Height of a line of text, pixels.
const TEXT_HEIGHT: usize = 18;

/// Rows of `size × size` panels under `title`, each panel's pixels multiplied by `exposure` (values above 1 clip
/// when written as 8-bit).
pub fn mosaic(
    title: &str,
    rows: &[Vec<Panel>],
    size: usize,
    exposure: f32,
) -> Result<Image, PlotError> {
    let size = size.max(1);
    let text_width = |text: &str| plot::text_size(text, TEXT_SIZE).0 as usize;
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
    let mut image = Image::new(width, height, vec!["R".into(), "G".into(), "B".into()]);
    image.data.fill(1.0);
    let mut labels = vec![Label {
        x: GAP as i32,
        y: 8,
        text: title.to_owned(),
    }];
    for (r, row) in rows.iter().enumerate() {
        let top = title_h + r * (label_h + panel + GAP);
        for (c, p) in row.iter().enumerate() {
            let left = GAP + c * (panel + GAP);
            labels.push(Label {
                x: left as i32,
                y: top as i32,
                text: p.label.clone(),
            });
            let y_img = top + label_h;
            for (k, v) in p.rgb.iter().enumerate().take(size * size) {
                let (i, j) = (k % size, k / size);
                let rgb = (*v * exposure).to_array();
                for y in y_img + j * scale..y_img + (j + 1) * scale {
                    for x in left + i * scale..left + (i + 1) * scale {
                        image.pixel_mut(x, y).copy_from_slice(&rgb);
                    }
                }
            }
        }
    }
    plot::annotate(&image, &labels, TEXT_SIZE)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `w × h` image whose coverage `A` is 1 inside the rectangle `[x0, x1) × [y0, y1)` and 0 elsewhere.
    fn covered(w: usize, h: usize, (x0, x1): (usize, usize), (y0, y1): (usize, usize)) -> Image {
        let mut image = Image::new(w, h, ["R", "G", "B", "A"].map(String::from).to_vec());
        for y in y0..y1 {
            for x in x0..x1 {
                image.pixel_mut(x, y)[3] = 1.0;
            }
        }
        image
    }

    #[test]
    fn the_crop_window_is_centred_on_the_hair_and_stays_inside() {
        // Coverage in the bottom-right corner of a 100 × 80 image: the window sits there, not at (0, 0).
        assert_eq!(
            hair_window(&covered(100, 80, (80, 100), (60, 80)), 16),
            (82, 62, 16)
        );
        // In the middle of the top edge: centred across, clamped to the top.
        assert_eq!(
            hair_window(&covered(100, 80, (40, 60), (0, 4)), 16),
            (42, 0, 16)
        );
        // No coverage, or no A channel: the image's centre.
        assert_eq!(
            hair_window(&covered(100, 80, (0, 0), (0, 0)), 16),
            (42, 32, 16)
        );
        let rgb = Image::new(100, 80, ["R", "G", "B"].map(String::from).to_vec());
        assert_eq!(hair_window(&rgb, 16), (42, 32, 16));
        // A window larger than the image is clamped to it.
        assert_eq!(
            hair_window(&covered(32, 24, (0, 8), (0, 8)), 64),
            (0, 0, 24)
        );
    }

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
        )
        .unwrap();
        let scale = MIN_PANEL.div_ceil(2);
        let panel_px = 2 * scale;
        assert_eq!(image.width, GAP + 2 * (panel_px + GAP));
        let top = TEXT_HEIGHT + 16 + TEXT_HEIGHT + 6;
        let red = [1.0, 0.0, 0.0];
        assert_eq!(image.pixel(GAP, top), red);
        assert_eq!(image.pixel(GAP + panel_px - 1, top + panel_px - 1), red);
        assert_ne!(image.pixel(GAP + panel_px, top), red);
        // The labels are drawn: dark pixels in the label line over the first panel.
        let dark = (top - TEXT_HEIGHT - 6..top)
            .flat_map(|y| (GAP..GAP + panel_px).map(move |x| (x, y)))
            .filter(|&(x, y)| image.pixel(x, y)[1] < 0.1)
            .count();
        assert!(dark > 10, "{dark} dark pixels in the label line");
    }

    #[test]
    fn chart_axes_cover_every_point_and_label_them() {
        let s = ChartSeries {
            label: "S".to_owned(),
            color: RGBColor(0, 0, 255),
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
                Point {
                    x: 0.0,
                    y: 1.0,
                    label: "left out".to_owned(),
                },
            ],
        };
        let chart = error_time_line_chart("C", "X", "Y", std::slice::from_ref(&s));
        assert_eq!((chart.x.min, chart.x.max), (0.01, 100.0));
        assert_eq!((chart.y.min, chart.y.max), (0.001, 1.0));
        assert_eq!(chart.series[0].points, [(0.03, 0.2), (12.0, 0.004)]);
        let figure = plot::render(&chart, "error-time", (600, 400)).unwrap();
        assert_eq!((figure.image.width, figure.image.height), (600, 400));
        // plotters writes each text on a line of its own.
        assert!(figure.svg.contains("\n64\n") && !figure.svg.contains("left out"));
    }
}
