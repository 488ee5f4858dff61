//! Charts of the measurement layer, drawn with [`plotters`]: line charts with linear or log10 axes ([`LineChart`]),
//! bar charts over named categories ([`BarChart`]),
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
//!
//! The files: this one holds the errors, the style (font, sizes, colours), [`render`] and [`write_figure`], and
//! [`annotate`]; `axis.rs` the axes ([`Axis`]); `line.rs` the line charts with their series, legend and clipping
//! ([`LineChart`], [`Series`]); `polar.rs` the polar charts ([`PolarChart`]); `heatmap.rs` the heat maps, colour
//! maps and colour bars ([`HeatMap`], [`Colormap`], [`ColorBar`]); `table.rs` line charts from a CSV table
//! ([`CsvChart`], for `cuticle plot-csv`); `bar.rs` the bar charts ([`BarChart`]).

mod axis;
mod bar;
pub mod bsdf;
mod heatmap;
mod line;
mod notes;
mod polar;
mod table;

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

pub use axis::{Axis, Scale};
pub use bar::{wrap_name, BarChart, Bars};
pub use heatmap::{ColorBar, Colormap, HeatMap};
pub use line::{LineChart, Series};
pub use notes::WithNotes;
pub use polar::PolarChart;
pub use table::{CsvChart, TableError};

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

/// Fills `root` white, draws `chart` on it and presents it; `what` names the chart and backend in errors.
fn draw_page<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    chart: &impl Chart,
    what: &str,
) -> Result<(), PlotError> {
    root.fill(&WHITE)
        .and_then(|()| chart.draw(root))
        .and_then(|()| root.present())
        .map_err(draw_error(what))
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
    draw_page(
        &BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area(),
        chart,
        &format!("{what} png"),
    )?;
    let mut svg = String::new();
    draw_page(
        &SVGBackend::with_string(&mut svg, size).into_drawing_area(),
        chart,
        &format!("{what} svg"),
    )?;
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
