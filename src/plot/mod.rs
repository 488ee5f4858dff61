//! Charts of the measurement layer, drawn with [`plotters`]: line charts with linear or log10 axes ([`LineChart`]),
//! polar charts ([`PolarChart`]), heat maps and colour bars ([`HeatMap`], [`ColorBar`]), for `cuticle plot-bsdf`
//! ([`bsdf`]) and the studies ([`crate::study::figures`]).
//!
//! Every chart is drawn twice from the same code ([`Chart::draw`] is generic over the plotters backend): into a
//! bitmap, kept as an RGB [`Image`] of linear values for [`crate::image::write`] (PNG through OpenImageIO), and into
//! an SVG document ([`Figure`]); [`write_figure`] writes both, atomically. Text is set in DejaVu Sans, embedded in
//! the binary ([`dejavu`], through plotters' `ab_glyph` backend), so a machine without system fonts draws the same
//! labels; the SVG names the family `sans-serif` and leaves the glyphs to the viewer.
//!
//! A log10 axis is drawn as a linear axis over the exponent ([`Axis::position`]), with a labelled tick per decade
//! and light grid lines at 2…9 × 10ᵏ; a value ≤ 0 on it maps one axis length below the start, so a curve dropping
//! to zero dives off the chart (plotters clips lines to the plotting area).

pub mod bsdf;

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint};
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::image::{Image, ImageError};
use crate::util::atomic_file;

/// A chart could not be drawn or written. Variants name the file where there is one.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// plotters refused to draw (a broken layout: an area too small for its labels).
    #[error("cannot draw the {what} chart: {message}")]
    Draw {
        /// The chart and backend (`png`, `svg`).
        what: String,
        /// plotters' message.
        message: String,
    },
    /// The PNG could not be written.
    #[error(transparent)]
    Image(#[from] ImageError),
    /// The SVG or a directory could not be written.
    #[error("{path}: {context}: {source}")]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// What was being done.
        context: String,
        /// The I/O error.
        source: std::io::Error,
    },
}

/// What plotters returns when drawing on backend `DB`.
pub type DrawResult<DB> = Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// A chart that draws itself on any plotters backend (bitmap and SVG).
pub trait Chart {
    /// Draws the whole chart on `root`, which is already filled with the background.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB>;
}

/// The family name the embedded font is registered under (and the SVG asks for).
pub const FONT: &str = "sans-serif";
/// Text sizes, pixels: titles, axis titles and legends, tick labels.
pub const TITLE_SIZE: f64 = 20.0;
/// Axis titles and legend entries.
pub const LABEL_SIZE: f64 = 16.0;
/// Tick labels and small annotations.
pub const TICK_SIZE: f64 = 14.0;

/// Text, axes and ticks (#1a1a1a).
pub const INK: RGBColor = RGBColor(0x1a, 0x1a, 0x1a);
/// Grid lines at labelled ticks.
pub const GRID: RGBColor = RGBColor(0xd4, 0xd4, 0xd4);
/// Grid lines between labelled ticks (2…9 × 10ᵏ on log axes).
pub const LIGHT_GRID: RGBColor = RGBColor(0xee, 0xee, 0xee);

/// Registers DejaVu Sans as [`FONT`] with plotters, once per process.
///
/// # Panics
/// If the embedded font does not parse (a broken build, not a runtime condition).
pub fn register_font() {
    static REGISTER: Once = Once::new();
    REGISTER.call_once(|| {
        let parsed =
            plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular());
        assert!(parsed.is_ok(), "the embedded DejaVu Sans does not parse");
    });
}

/// [`FONT`] at `size` pixels in `color`.
pub fn text_style(size: f64, color: RGBColor) -> TextStyle<'static> {
    (FONT, size).into_font().color(&color)
}

/// The sRGB colour written 0xRRGGBB.
pub fn hex(rgb: u32) -> RGBColor {
    RGBColor((rgb >> 16) as u8, (rgb >> 8) as u8, rgb as u8)
}

/// The linear value of an 8-bit sRGB code (IEC 61966-2-1 decoding): the inverse of
/// [`crate::image::linear_to_srgb8`], which maps it back to the same code.
pub fn srgb8_to_linear(code: u8) -> f32 {
    let v = f32::from(code) / 255.0;
    if v <= 0.040_45 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// A linear RGB colour of an [`Image`] (channels `R, G, B`) for an sRGB colour.
pub fn linear(color: RGBColor) -> [f32; 3] {
    [
        srgb8_to_linear(color.0),
        srgb8_to_linear(color.1),
        srgb8_to_linear(color.2),
    ]
}

/// An `R, G, B` image of linear values holding 8-bit sRGB pixels `rgb` (row-major, top row first).
fn image_from_srgb8(width: usize, height: usize, rgb: &[u8]) -> Image {
    let mut image = Image::new(width, height, vec!["R".into(), "G".into(), "B".into()]);
    for (value, &code) in image.data.iter_mut().zip(rgb) {
        *value = srgb8_to_linear(code);
    }
    image
}

/// The 8-bit sRGB pixels of an `R, G, B` image ([`crate::image::linear_to_srgb8`]).
fn srgb8_from_image(image: &Image) -> Vec<u8> {
    image
        .data
        .iter()
        .map(|&v| crate::image::linear_to_srgb8(v))
        .collect()
}

/// A chart drawn both ways.
#[derive(Debug, Clone)]
pub struct Figure {
    /// The bitmap: channels `R, G, B`, linear (write it as PNG with [`crate::image::write`]).
    pub image: Image,
    /// The same chart as an SVG document.
    pub svg: String,
}

fn draw_error<E: std::fmt::Display>(what: &str) -> impl FnOnce(E) -> PlotError + '_ {
    move |e| PlotError::Draw {
        what: what.to_owned(),
        message: e.to_string(),
    }
}

/// Draws `chart` on a white `width × height` bitmap and SVG page. `what` names the chart in errors.
pub fn render(
    chart: &impl Chart,
    what: &str,
    (width, height): (usize, usize),
) -> Result<Figure, PlotError> {
    register_font();
    let size = (width as u32, height as u32);
    let mut rgb = vec![0u8; width * height * 3];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
        root.fill(&WHITE)
            .and_then(|()| chart.draw(&root))
            .and_then(|()| root.present())
            .map_err(draw_error(&format!("{what} png")))?;
    }
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        root.fill(&WHITE)
            .and_then(|()| chart.draw(&root))
            .and_then(|()| root.present())
            .map_err(draw_error(&format!("{what} svg")))?;
    }
    Ok(Figure {
        image: image_from_srgb8(width, height, &rgb),
        svg,
    })
}

/// Writes `figure` as `<dir>/<stem>.png` and `<dir>/<stem>.svg` (each atomically) and returns the two paths.
pub fn write_figure(figure: &Figure, dir: &Path, stem: &str) -> Result<[PathBuf; 2], PlotError> {
    let png = dir.join(format!("{stem}.png"));
    crate::image::write(&png, &figure.image)?;
    let svg = dir.join(format!("{stem}.svg"));
    atomic_file::write(&svg, figure.svg.as_bytes()).map_err(|e| PlotError::Io {
        path: svg.clone(),
        context: e.context.to_owned(),
        source: e.source,
    })?;
    Ok([png, svg])
}

/// A piece of text placed on an image by [`annotate`]: its top-left corner, pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct Label {
    /// Column of the left edge.
    pub x: i32,
    /// Row of the top edge.
    pub y: i32,
    /// The text.
    pub text: String,
}

/// Draws `labels` in [`INK`] at `size` pixels on `image` (channels `R, G, B`, linear). The pixels under no label
/// keep their 8-bit sRGB codes exactly ([`srgb8_to_linear`] inverts [`crate::image::linear_to_srgb8`]).
///
/// # Panics
/// If `image` is not `R, G, B`.
pub fn annotate(image: &Image, labels: &[Label], size: f64) -> Result<Image, PlotError> {
    assert_eq!(
        image.channels,
        ["R", "G", "B"],
        "annotate draws on RGB images"
    );
    register_font();
    let mut rgb = srgb8_from_image(image);
    {
        let dims = (image.width as u32, image.height as u32);
        let root = BitMapBackend::with_buffer(&mut rgb, dims).into_drawing_area();
        let style = text_style(size, INK).pos(Pos::new(HPos::Left, VPos::Top));
        labels
            .iter()
            .try_for_each(|l| root.draw_text(&l.text, &style, (l.x, l.y)))
            .and_then(|()| root.present())
            .map_err(draw_error("label"))?;
    }
    Ok(image_from_srgb8(image.width, image.height, &rgb))
}

/// The (width, height) in pixels of `text` at `size` pixels.
pub fn text_size(text: &str, size: f64) -> (u32, u32) {
    register_font();
    (FONT, size).into_font().box_size(text).unwrap_or((0, 0))
}

/// How an axis maps values to positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scale {
    /// Position ∝ value.
    Linear,
    /// Position ∝ log10(value); values ≤ 0 fall below the axis.
    Log10,
}

/// One axis of a chart: its label, range, scale and labelled ticks (in data units).
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    /// The axis title.
    pub label: String,
    /// The value at the start (left, bottom, or the centre of a polar chart).
    pub min: f64,
    /// The value at the end.
    pub max: f64,
    /// Linear or logarithmic.
    pub scale: Scale,
    /// Where labelled ticks and grid lines go.
    pub ticks: Vec<f64>,
}

impl Axis {
    /// A linear axis over [`min`, `max`] with a tick at every multiple of `step` inside it.
    pub fn linear(label: &str, min: f64, max: f64, step: f64) -> Axis {
        let first = (min / step).ceil() as i64;
        let last = (max / step + 1e-4).floor() as i64;
        Axis {
            label: label.to_owned(),
            min,
            max,
            scale: Scale::Linear,
            ticks: (first..=last).map(|k| k as f64 * step).collect(),
        }
    }

    /// A linear axis over [`min`, `max`] with about six ticks at multiples of 1, 2 or 5 times a power of ten.
    pub fn linear_auto(label: &str, min: f64, max: f64) -> Axis {
        let span = (max - min).abs().max(f64::MIN_POSITIVE);
        let rough = span / 6.0;
        let power = 10f64.powf(rough.log10().floor());
        // The 1-2-5 step nearest to a sixth of the span (in ratio).
        let step = [1.0, 2.0, 5.0, 10.0]
            .into_iter()
            .map(|m| m * power)
            .min_by(|a, b| (a / rough).ln().abs().total_cmp(&(b / rough).ln().abs()))
            .unwrap_or(power);
        Axis::linear(label, min, max, step)
    }

    /// A log10 axis `decades` decades tall whose top is the power of ten at or above `max_value` (1 if
    /// `max_value` is not positive and finite), with a tick per decade.
    pub fn log_decades(label: &str, max_value: f64, decades: u32) -> Axis {
        let top = if max_value > 0.0 && max_value.is_finite() {
            max_value.log10().ceil() as i32
        } else {
            0
        };
        let bottom = top - decades.max(1) as i32;
        Axis {
            label: label.to_owned(),
            min: 10f64.powi(bottom),
            max: 10f64.powi(top),
            scale: Scale::Log10,
            ticks: (bottom..=top).map(|e| 10f64.powi(e)).collect(),
        }
    }

    /// A log10 axis of whole decades covering [`lo`, `hi`] (both > 0; anything else gives the decade below 1).
    pub fn log_covering(label: &str, lo: f64, hi: f64) -> Axis {
        let (lo, hi) = if lo > 0.0 && hi >= lo && hi.is_finite() {
            (lo, hi)
        } else {
            (0.1, 1.0)
        };
        let decades = (hi.log10().ceil() - lo.log10().floor()).max(1.0) as u32;
        Axis::log_decades(label, hi, decades)
    }

    /// The axis' range in drawing coordinates: data units, or the exponent on a log axis.
    fn range(&self) -> Range<f64> {
        self.position(self.min)..self.position(self.max)
    }

    /// Where `v` sits along the axis in drawing coordinates (see [`Axis::range`]). On a log axis a value ≤ 0 (or
    /// NaN) maps one axis length below the start, so a curve dropping to zero dives off the chart.
    pub fn position(&self, v: f64) -> f64 {
        match self.scale {
            Scale::Linear => v,
            Scale::Log10 => {
                let (lo, hi) = (self.min.log10(), self.max.log10());
                if v > 0.0 {
                    v.log10().max(2.0 * lo - hi)
                } else {
                    2.0 * lo - hi
                }
            }
        }
    }

    /// The fraction of the axis length at which `v` sits: 0 at `min`, 1 at `max` (−1 for a value ≤ 0 on a log
    /// axis).
    pub fn fraction(&self, v: f64) -> f64 {
        let r = self.range();
        (self.position(v) - r.start) / (r.end - r.start)
    }

    /// The drawing coordinate range with the labelled ticks and, on a log axis, light grid lines at 2…9 × 10ᵏ.
    fn coord(&self) -> AxisCoord {
        let bold: Vec<f64> = self.ticks.iter().map(|&t| self.position(t)).collect();
        let light: Vec<f64> = match self.scale {
            Scale::Linear => Vec::new(),
            Scale::Log10 => self
                .ticks
                .iter()
                .flat_map(|&t| (2..10).map(move |m| t * m as f64))
                .filter(|&v| v < self.max)
                .map(|v| v.log10())
                .collect(),
        };
        AxisCoord {
            linear: self.range().into(),
            bold,
            light,
        }
    }

    /// The text of the tick at drawing coordinate `position`: as many decimals as the tick spacing needs on a
    /// linear axis; on a log axis plain decimals if every tick is within 10⁻³ … 10³, else powers of ten (10⁻⁵).
    pub fn tick_label(&self, position: f64) -> String {
        match self.scale {
            Scale::Linear => {
                let step = match self.ticks.as_slice() {
                    [a, b, ..] => (b - a).abs(),
                    _ => (self.max - self.min).abs(),
                };
                let decimals = if step >= 0.999 || step <= 0.0 {
                    0
                } else {
                    (-step.log10() - 1e-3).ceil().max(0.0) as usize
                };
                let text = format!("{position:.decimals$}");
                if text
                    .trim_start_matches('-')
                    .chars()
                    .all(|c| c == '0' || c == '.')
                {
                    // No "-0".
                    text.trim_start_matches('-').to_owned()
                } else {
                    text.replace('-', "−")
                }
            }
            Scale::Log10 => {
                let e = position.round() as i32;
                let small = self
                    .ticks
                    .iter()
                    .all(|&t| (-3..=3).contains(&(t.log10().round() as i32)));
                if small {
                    format!("{:.*}", (-e).max(0) as usize, 10f64.powi(e))
                } else {
                    format!("10{}", superscript(e))
                }
            }
        }
    }
}

/// An axis in drawing coordinates with given tick positions: plotters' linear f64 axis with our own key points
/// (plotters' `WithKeyPoints` over it has no label formatter in 0.3.7).
struct AxisCoord {
    linear: RangedCoordf64,
    /// Labelled ticks, with grid lines.
    bold: Vec<f64>,
    /// Light grid lines.
    light: Vec<f64>,
}

impl Ranged for AxisCoord {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        self.linear.map(value, limit)
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            self.light.clone()
        } else {
            self.bold.clone()
        }
    }

    fn range(&self) -> Range<f64> {
        self.linear.range()
    }
}

/// `e` in superscript digits (−12 → ⁻¹²).
fn superscript(e: i32) -> String {
    const DIGITS: [char; 10] = ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'];
    let sign = if e < 0 { "⁻" } else { "" };
    let digits: String = e
        .unsigned_abs()
        .to_string()
        .bytes()
        .map(|b| DIGITS[usize::from(b - b'0')])
        .collect();
    format!("{sign}{digits}")
}

/// One curve: points in data units, drawn in `color`, `width` pixels wide.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// The legend text.
    pub label: String,
    /// The line colour.
    pub color: RGBColor,
    /// Line width, pixels.
    pub width: u32,
    /// (x, y) in data units, in drawing order. A non-finite coordinate breaks the line.
    pub points: Vec<(f64, f64)>,
    /// A `+` at each point.
    pub markers: bool,
    /// Text beside each point (none if empty; else one per point, an empty string draws nothing).
    pub point_labels: Vec<String>,
}

impl Series {
    /// A plain line.
    pub fn line(label: &str, color: RGBColor, width: u32, points: Vec<(f64, f64)>) -> Series {
        Series {
            label: label.to_owned(),
            color,
            width,
            points,
            markers: false,
            point_labels: Vec::new(),
        }
    }
}

/// Height of a line of legend text, pixels.
const LEGEND_LINE: u32 = 24;
/// Swatch length and the gaps around a legend entry, pixels.
const SWATCH: u32 = 26;
/// Space between legend entries.
const LEGEND_GAP: u32 = 22;

/// The rows of legend entries for `series` in `width` pixels: per row, (series index, x offset).
fn legend_layout(series: &[Series], width: u32) -> Vec<Vec<(usize, u32)>> {
    let mut rows: Vec<Vec<(usize, u32)>> = vec![Vec::new()];
    let mut x = 0;
    for (i, s) in series.iter().enumerate() {
        let entry = SWATCH + 6 + text_size(&s.label, LABEL_SIZE).0;
        if x > 0 && x + entry > width {
            rows.push(Vec::new());
            x = 0;
        }
        if let Some(row) = rows.last_mut() {
            row.push((i, x));
        }
        x += entry + LEGEND_GAP;
    }
    rows
}

/// Draws the title centred on the top line of `area` and the legend of `series` under it, from `left` to
/// `right`; returns the height used.
fn header<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    series: &[Series],
    (left, right): (u32, u32),
) -> Result<u32, DrawingAreaErrorKind<DB::ErrorType>> {
    let (width, _) = area.dim_in_pixel();
    let centre = text_style(TITLE_SIZE, INK).pos(Pos::new(HPos::Center, VPos::Top));
    area.draw_text(title, &centre, (width as i32 / 2, 8))?;
    let top = 8 + TITLE_SIZE as u32 + 12;
    let rows = legend_layout(series, right.saturating_sub(left));
    let label = text_style(LABEL_SIZE, INK).pos(Pos::new(HPos::Left, VPos::Center));
    for (r, row) in rows.iter().enumerate() {
        let y = (top + r as u32 * LEGEND_LINE + LEGEND_LINE / 2) as i32;
        for &(i, x) in row {
            let s = &series[i];
            let x = (left + x) as i32;
            let style = s.color.stroke_width(s.width.clamp(2, 8));
            area.draw(&PathElement::new(
                vec![(x, y), (x + SWATCH as i32, y)],
                style,
            ))?;
            area.draw_text(&s.label, &label, (x + SWATCH as i32 + 6, y))?;
        }
    }
    Ok(top + rows.len() as u32 * LEGEND_LINE + 6)
}

/// A line chart: title, a legend row under it, axes with ticks and grid, one polyline per series (later on top).
#[derive(Debug, Clone, PartialEq)]
pub struct LineChart {
    /// The title, centred on top.
    pub title: String,
    /// The horizontal axis.
    pub x: Axis,
    /// The vertical axis.
    pub y: Axis,
    /// The curves, drawn in order.
    pub series: Vec<Series>,
}

/// Room for the tick labels and title of the y axis, pixels.
const Y_LABEL_AREA: u32 = 84;
/// Room for the tick labels and title of the x axis, pixels.
const X_LABEL_AREA: u32 = 56;

impl Chart for LineChart {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
        let (width, _) = root.dim_in_pixel();
        let right = 24;
        let top = header(
            root,
            &self.title,
            &self.series,
            (Y_LABEL_AREA + 10, width.saturating_sub(right)),
        )?;
        let mut chart = ChartBuilder::on(root)
            .margin_top(top)
            .margin_right(right)
            .margin_bottom(6)
            .margin_left(10)
            .x_label_area_size(X_LABEL_AREA)
            .y_label_area_size(Y_LABEL_AREA)
            .build_cartesian_2d(self.x.coord(), self.y.coord())?;
        let x_label = |v: &f64| self.x.tick_label(*v);
        let y_label = |v: &f64| self.y.tick_label(*v);
        chart
            .configure_mesh()
            .x_desc(self.x.label.as_str())
            .y_desc(self.y.label.as_str())
            .x_label_formatter(&x_label)
            .y_label_formatter(&y_label)
            .label_style(text_style(TICK_SIZE, INK))
            .axis_desc_style(text_style(LABEL_SIZE, INK))
            .axis_style(INK)
            .bold_line_style(GRID)
            .light_line_style(LIGHT_GRID)
            .draw()?;
        for s in &self.series {
            let points: Vec<(f64, f64)> = s
                .points
                .iter()
                .map(|&(x, y)| (self.x.position(x), self.y.position(y)))
                .collect();
            let style = s.color.stroke_width(s.width);
            let clip = (self.x.range(), self.y.range());
            for run in clipped_runs(&points, &clip) {
                // plotters outlines a wide line through integer pixel corners, so hundreds of sub-pixel segments
                // give it ragged edges: keep points at least a line width apart (the curve is smooth at that
                // scale).
                let run = if s.width > 3 {
                    let mut kept = vec![run[0]];
                    let far = |a: (f64, f64), b: (f64, f64)| {
                        let (pa, pb) = (chart.backend_coord(&a), chart.backend_coord(&b));
                        (pa.0 - pb.0).abs().max((pa.1 - pb.1).abs()) >= s.width as i32
                    };
                    for (k, &p) in run.iter().enumerate().skip(1) {
                        if k + 1 == run.len() || far(*kept.last().unwrap_or(&p), p) {
                            kept.push(p);
                        }
                    }
                    kept
                } else {
                    run
                };
                chart.draw_series(LineSeries::new(run, style))?;
            }
            if s.markers {
                let mark = s.color.stroke_width(2);
                chart.draw_series(points.iter().filter(|p| p.0.is_finite()).map(|&p| {
                    EmptyElement::at(p)
                        + PathElement::new(vec![(-6, 0), (6, 0)], mark)
                        + PathElement::new(vec![(0, -6), (0, 6)], mark)
                }))?;
            }
            // Point labels in a darker shade of the series colour, up and right of the point.
            let dark = RGBColor(
                (f64::from(s.color.0) * 0.7) as u8,
                (f64::from(s.color.1) * 0.7) as u8,
                (f64::from(s.color.2) * 0.7) as u8,
            );
            let style = text_style(TICK_SIZE, dark).pos(Pos::new(HPos::Left, VPos::Bottom));
            chart.draw_series(
                points
                    .iter()
                    .zip(&s.point_labels)
                    .filter(|(p, text)| p.0.is_finite() && p.1.is_finite() && !text.is_empty())
                    .map(|(&p, text)| {
                        EmptyElement::at(p) + Text::new(text.clone(), (6, -4), style.clone())
                    }),
            )?;
        }
        Ok(())
    }
}

/// The parts of the polyline `points` inside the rectangle `x × y` (Liang & Barsky's segment clipping), as runs
/// of points. plotters would instead pull points outside the plotting area onto its edge, drawing a curve that
/// leaves the chart along the edge. A non-finite point breaks the line.
fn clipped_runs(points: &[(f64, f64)], (x, y): &(Range<f64>, Range<f64>)) -> Vec<Vec<(f64, f64)>> {
    let (x0, x1) = (x.start.min(x.end), x.start.max(x.end));
    let (y0, y1) = (y.start.min(y.end), y.start.max(y.end));
    let clip = |a: (f64, f64), b: (f64, f64)| {
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        for (p, q) in [
            (-dx, a.0 - x0),
            (dx, x1 - a.0),
            (-dy, a.1 - y0),
            (dy, y1 - a.1),
        ] {
            if p == 0.0 {
                if q < 0.0 {
                    return None;
                }
            } else if p < 0.0 {
                t0 = t0.max(q / p);
            } else {
                t1 = t1.min(q / p);
            }
        }
        // Exact ends where the segment is not cut: a run goes on only through a point it keeps.
        let at = |t: f64| match t {
            0.0 => a,
            1.0 => b,
            _ => (a.0 + t * dx, a.1 + t * dy),
        };
        (t0 <= t1).then(|| (at(t0), at(t1)))
    };
    let finite = |p: &(f64, f64)| p.0.is_finite() && p.1.is_finite();
    let mut runs: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut open = false;
    for pair in points.windows(2) {
        let piece = if finite(&pair[0]) && finite(&pair[1]) {
            clip(pair[0], pair[1])
        } else {
            None
        };
        match (piece, runs.last_mut()) {
            // The previous segment ended inside, where this one starts: the run goes on.
            (Some((a, b)), Some(run)) if open && a == pair[0] => run.push(b),
            (Some((a, b)), _) => runs.push(vec![a, b]),
            (None, _) => {}
        }
        open = piece.is_some_and(|(_, b)| b == pair[1]);
    }
    runs
}

/// A polar chart: series of (angle in radians, value) drawn at distance ∝ `radius.fraction(value)` from the
/// centre (clamped at the centre), angle 0 to the right and increasing anticlockwise, with a ring per radius tick
/// and a spoke every 30°.
#[derive(Debug, Clone, PartialEq)]
pub struct PolarChart {
    /// The title, centred on top.
    pub title: String,
    /// The radial axis (its label goes under the chart).
    pub radius: Axis,
    /// The curves; x is the angle (radians).
    pub series: Vec<Series>,
}

impl Chart for PolarChart {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
        let (width, height) = root.dim_in_pixel();
        let top = header(
            root,
            &self.title,
            &self.series,
            (20, width.saturating_sub(20)),
        )?;
        // The radius label on the bottom line.
        let bottom = LABEL_SIZE as u32 + 14;
        let centre = text_style(LABEL_SIZE, INK).pos(Pos::new(HPos::Center, VPos::Bottom));
        root.draw_text(
            &self.radius.label,
            &centre,
            (width as i32 / 2, height as i32 - 6),
        )?;
        // A square plot area in what is left; the angle labels sit in the outer 16% of its half-width.
        let side = width.min(height.saturating_sub(top + bottom));
        let (x0, y0) = ((width - side) / 2, top);
        let area = root.clone().shrink((x0, y0), (side, side));
        const OUTER: f64 = 1.19;
        let mut chart = ChartBuilder::on(&area).build_cartesian_2d(-OUTER..OUTER, -OUTER..OUTER)?;
        let at = |angle: f64, r: f64| (r * angle.cos(), r * angle.sin());
        let circle = |r: f64| (0..=360).map(move |k| at((k as f64).to_radians(), r));
        let ring = |t: f64| self.radius.fraction(t).clamp(0.0, 1.0);
        for &t in &self.radius.ticks {
            chart.draw_series(LineSeries::new(circle(ring(t)), GRID))?;
        }
        let label = text_style(TICK_SIZE, INK).pos(Pos::new(HPos::Center, VPos::Center));
        for k in 0..12 {
            let angle = (f64::from(k) * 30.0).to_radians();
            chart.draw_series(LineSeries::new([at(angle, 0.0), at(angle, 1.0)], GRID))?;
            let degrees = if k <= 6 { k * 30 } else { k * 30 - 360 };
            let text = format!("{degrees}°").replace('-', "−");
            chart.draw_series([Text::new(text, at(angle, 1.1), label.clone())])?;
        }
        chart.draw_series(LineSeries::new(circle(1.0), INK.stroke_width(2)))?;
        for s in &self.series {
            let points = s
                .points
                .iter()
                .map(|&(a, v)| at(a, self.radius.fraction(v).max(0.0)));
            chart.draw_series(LineSeries::new(points, s.color.stroke_width(s.width)))?;
        }
        // Ring labels on top of the curves, on a white box, just right of the 90° spoke (the centre ring has
        // none).
        let ring_label = text_style(TICK_SIZE, INK).pos(Pos::new(HPos::Left, VPos::Top));
        for &t in &self.radius.ticks {
            let f = self.radius.fraction(t);
            if f <= 0.0 || f > 1.0 {
                continue;
            }
            let text = self.radius.tick_label(self.radius.position(t));
            let (w, h) = text_size(&text, TICK_SIZE);
            let (w, h) = (w as i32, h as i32);
            chart.draw_series([EmptyElement::at((0.0, f))
                + Rectangle::new([(3, 3), (w + 9, h + 7)], WHITE.filled())
                + Text::new(text, (6, 5), ring_label.clone())])?;
        }
        Ok(())
    }
}

/// A colour map from [0, 1] to sRGB.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Colormap {
    /// Perceptually uniform dark blue → green → yellow (matplotlib's viridis, plotters' [`ViridisRGB`]).
    Viridis,
    /// Blue (0) → white (1/2) → red (1) (ColorBrewer RdBu, 7 stops), for signed differences.
    Diverging,
}

impl Colormap {
    /// The colour at `t` (clamped to [0, 1]; NaN is dark grey).
    pub fn color(self, t: f64) -> RGBColor {
        if t.is_nan() {
            return RGBColor(0x33, 0x33, 0x33);
        }
        let t = t.clamp(0.0, 1.0);
        match self {
            Colormap::Viridis => ViridisRGB.get_color(t),
            Colormap::Diverging => {
                const RDBU: [u32; 7] = [
                    0x2166ac, 0x67a9cf, 0xd1e5f0, 0xf7f7f7, 0xfddbc7, 0xef8a62, 0xb2182b,
                ];
                DerivedColorMap::new(&RDBU.map(hex)).get_color(t)
            }
        }
    }
}

/// A heat map: `rows × cols` cells filled by colour map over a value range, with axes and a title.
#[derive(Debug, Clone, PartialEq)]
pub struct HeatMap {
    /// The title, above the map.
    pub title: String,
    /// Number of rows (along y).
    pub rows: usize,
    /// Number of columns (along x).
    pub cols: usize,
    /// Row-major values; row 0 is at the bottom (y = `y.min`), column 0 at the left.
    pub values: Vec<f64>,
    /// The colour map.
    pub colormap: Colormap,
    /// The values mapped to the ends of the colour map (values beyond are clamped).
    pub range: (f64, f64),
    /// The horizontal axis, spanning the columns (linear).
    pub x: Axis,
    /// The vertical axis, spanning the rows (linear).
    pub y: Axis,
}

impl Chart for HeatMap {
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
        let mut chart = ChartBuilder::on(area)
            .caption(&self.title, text_style(LABEL_SIZE, INK))
            .margin(8)
            .x_label_area_size(44)
            .y_label_area_size(56)
            .build_cartesian_2d(self.x.coord(), self.y.coord())?;
        let (lo, hi) = self.range;
        let (dx, dy) = (
            (self.x.max - self.x.min) / self.cols as f64,
            (self.y.max - self.y.min) / self.rows as f64,
        );
        chart.draw_series((0..self.rows * self.cols).map(|k| {
            let (i, j) = (k / self.cols, k % self.cols);
            let (x0, y0) = (self.x.min + j as f64 * dx, self.y.min + i as f64 * dy);
            let color = self.colormap.color((self.values[k] - lo) / (hi - lo));
            Rectangle::new([(x0, y0), (x0 + dx, y0 + dy)], color.filled())
        }))?;
        let x_label = |v: &f64| self.x.tick_label(*v);
        let y_label = |v: &f64| self.y.tick_label(*v);
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc(self.x.label.as_str())
            .y_desc(self.y.label.as_str())
            .x_label_formatter(&x_label)
            .y_label_formatter(&y_label)
            .label_style(text_style(TICK_SIZE, INK))
            .axis_desc_style(text_style(TICK_SIZE, INK))
            .axis_style(INK)
            .draw()
    }
}

/// A horizontal colour bar: the colour map spread along a linear `axis`, with its ticks and label.
#[derive(Debug, Clone, PartialEq)]
pub struct ColorBar {
    /// The colour map.
    pub colormap: Colormap,
    /// The values along the bar (linear).
    pub axis: Axis,
}

impl Chart for ColorBar {
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
        let mut chart = ChartBuilder::on(area)
            .margin_left(16)
            .margin_right(24)
            .x_label_area_size(44)
            .build_cartesian_2d(self.axis.coord(), 0.0..1.0)?;
        const STEPS: usize = 256;
        let (lo, hi) = (self.axis.min, self.axis.max);
        chart.draw_series((0..STEPS).map(|k| {
            let (t0, t1) = (k as f64 / STEPS as f64, (k + 1) as f64 / STEPS as f64);
            let color = self.colormap.color((t0 + t1) * 0.5);
            let x = |t: f64| lo + t * (hi - lo);
            Rectangle::new([(x(t0), 0.0), (x(t1), 1.0)], color.filled())
        }))?;
        let x_label = |v: &f64| self.axis.tick_label(*v);
        chart
            .configure_mesh()
            .disable_mesh()
            .disable_y_axis()
            .x_desc(self.axis.label.as_str())
            .x_label_formatter(&x_label)
            .label_style(text_style(TICK_SIZE, INK))
            .axis_desc_style(text_style(TICK_SIZE, INK))
            .axis_style(INK)
            .draw()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_codes_survive_the_round_trip_through_linear() {
        for code in 0..=255u8 {
            assert_eq!(
                crate::image::linear_to_srgb8(srgb8_to_linear(code)),
                code,
                "code {code}"
            );
        }
    }

    #[test]
    fn log_axis_spans_whole_decades_and_sends_zero_below() {
        let axis = Axis::log_decades("F", 3.2, 4);
        assert_eq!((axis.min, axis.max), (1e-3, 10.0));
        assert_eq!(axis.ticks.len(), 5);
        assert!((axis.fraction(0.1) - 0.5).abs() < 1e-9);
        assert_eq!(axis.fraction(0.0), -1.0);
        assert_eq!(axis.fraction(1e-30), -1.0);
        assert_eq!(axis.tick_label(axis.position(1e-3)), "0.001");
        assert_eq!(axis.tick_label(axis.position(10.0)), "10");
        let low = Axis::log_decades("F", 1e-2, 3);
        assert_eq!(low.tick_label(-5.0), "10⁻⁵");
        assert_eq!(low.tick_label(-2.0), "10⁻²");
        let cover = Axis::log_covering("X", 0.03, 12.0);
        assert_eq!((cover.min, cover.max), (0.01, 100.0));
        let lin = Axis::linear_auto("X", -90.0, 90.0);
        assert_eq!(lin.ticks.first(), Some(&-80.0));
        assert_eq!(lin.tick_label(0.0), "0");
        assert_eq!(Axis::linear("S", -1.0, 1.0, 0.5).tick_label(-0.5), "−0.5");
    }

    #[test]
    fn polylines_are_clipped_not_pulled_onto_the_edge() {
        let r = (0.0..1.0, 0.0..1.0);
        // In, out through the bottom, back in: two runs, each ending or starting on the edge y = 0.
        let runs = clipped_runs(&[(0.0, 0.5), (0.5, -0.5), (1.0, 0.5)], &r);
        assert_eq!(
            runs,
            [vec![(0.0, 0.5), (0.25, 0.0)], vec![(0.75, 0.0), (1.0, 0.5)]]
        );
        // Wholly inside: one run of every point; wholly outside: none.
        let inside = [(0.1, 0.1), (0.2, 0.3), (0.9, 0.9)];
        assert_eq!(clipped_runs(&inside, &r), [inside.to_vec()]);
        assert!(clipped_runs(&[(0.0, -1.0), (1.0, -2.0)], &r).is_empty());
        // A NaN breaks the line.
        let broken = clipped_runs(&[(0.1, 0.1), (0.2, f64::NAN), (0.3, 0.3), (0.4, 0.4)], &r);
        assert_eq!(broken, [vec![(0.3, 0.3), (0.4, 0.4)]]);
    }

    #[test]
    fn colormaps_hit_their_end_stops() {
        assert_eq!(Colormap::Viridis.color(-1.0), ViridisRGB.get_color(0.0));
        assert_eq!(Colormap::Diverging.color(0.5), hex(0xf7f7f7));
        assert_eq!(Colormap::Diverging.color(2.0), hex(0xb2182b));
    }

    /// A red series on a [0, 1] axis at 1/2 is drawn (its colour is on the bitmap, in a horizontal band), its
    /// legend entry and axis titles are in the SVG, and text is drawn with the embedded font (dark pixels above the
    /// plot area, where only the title and legend are).
    #[test]
    fn line_chart_draws_its_series_legend_and_text() {
        let red = RGBColor(255, 0, 0);
        let chart = LineChart {
            title: "θ test".to_owned(),
            x: Axis::linear("x label", 0.0, 10.0, 2.0),
            y: Axis::linear("y label", 0.0, 1.0, 0.25),
            series: vec![Series::line(
                "constant",
                red,
                3,
                (0..=10).map(|k| (f64::from(k), 0.5)).collect(),
            )],
        };
        let figure = render(&chart, "test", (400, 300)).unwrap();
        let image = &figure.image;
        let is_red = |x: usize, y: usize| image.pixel(x, y) == linear(red);
        let red_rows: Vec<usize> = (0..300)
            .filter(|&y| (0..400).filter(|&x| is_red(x, y)).count() > 200)
            .collect();
        assert!(
            !red_rows.is_empty() && red_rows.len() <= 4,
            "rows with a long red run: {red_rows:?}"
        );
        let row = red_rows[0];
        assert!((100..260).contains(&row), "the line is at row {row}");
        let dark = |y: usize| (0..400).any(|x| image.pixel(x, y)[1] < 0.1 && !is_red(x, y));
        assert!((0..40).any(dark), "no title drawn");
        for text in ["θ test", "constant", "x label", "y label"] {
            assert!(figure.svg.contains(text), "{text} missing from the svg");
        }
    }

    #[test]
    fn annotate_writes_text_and_keeps_other_pixels() {
        let mut image = Image::new(120, 40, vec!["R".into(), "G".into(), "B".into()]);
        image.data.fill(srgb8_to_linear(200));
        let labels = [Label {
            x: 4,
            y: 4,
            text: "ABC".to_owned(),
        }];
        let out = annotate(&image, &labels, 16.0).unwrap();
        let inked = (0..40).flat_map(|y| (0..120).map(move |x| (x, y)));
        let dark: Vec<(usize, usize)> = inked
            .filter(|&(x, y)| out.pixel(x, y)[0] < srgb8_to_linear(100))
            .collect();
        assert!(dark.len() > 20, "{} dark pixels", dark.len());
        assert!(dark.iter().all(|&(x, y)| x < 60 && y < 30), "{dark:?}");
        assert_eq!(out.pixel(100, 35), image.pixel(100, 35));
    }
}
