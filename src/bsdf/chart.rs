//! A tiny software rasteriser for the figures of `cuticle plot-bsdf` ([`super::plot`]): line charts (axes, ticks,
//! grid, one antialiased polyline per series, a legend of coloured swatches), polar charts, filled-cell heat maps
//! and colour bars, labelled with a built-in 5 × 7 bitmap font (digits, upper-case letters, θ, φ and a few
//! symbols; lower case is drawn as upper case). Everything draws into an RGB [`Image`] of **linear** values, which
//! [`crate::image::write`] encodes as 8-bit sRGB.
//!
//! Pixel coordinates are continuous, y down: pixel (i, j) covers [i, i + 1) × [j, j + 1), its centre is
//! (i + 0.5, j + 0.5). An axis maps its minimum to the centre of the first pixel of the plot area and its maximum
//! to the centre of the last, so a value at a known fraction of the range lands on a known pixel.

use crate::image::Image;
use glam::Vec3;
use std::f32::consts::FRAC_PI_2;

/// The page colour (linear RGB).
pub const BACKGROUND: Vec3 = Vec3::ONE;
/// Text, axes and ticks (linear 0.01 ≈ sRGB #1a1a1a).
pub const INK: Vec3 = Vec3::splat(0.01);
/// Grid lines (linear 0.8 ≈ sRGB #e7e7e7).
pub const GRID: Vec3 = Vec3::splat(0.8);

/// Pixels per font pixel.
pub const TEXT_SCALE: usize = 2;
/// Height of a line of text, pixels.
pub const TEXT_HEIGHT: usize = 7 * TEXT_SCALE;
/// Horizontal advance per character (5 columns plus 1 of spacing), pixels.
pub const TEXT_ADVANCE: usize = 6 * TEXT_SCALE;

/// Linear RGB of an sRGB colour written 0xRRGGBB (IEC 61966-2-1 decoding).
pub fn srgb(hex: u32) -> Vec3 {
    let decode = |byte: u32| {
        let v = byte as f32 / 255.0;
        if v <= 0.040_45 {
            v / 12.92
        } else {
            ((v + 0.055) / 1.055).powf(2.4)
        }
    };
    Vec3::new(
        decode((hex >> 16) & 0xff),
        decode((hex >> 8) & 0xff),
        decode(hex & 0xff),
    )
}

/// A rectangle of pixels, [x0, x1) × [y0, y1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rect {
    /// First column.
    pub x0: usize,
    /// First row (top).
    pub y0: usize,
    /// One past the last column.
    pub x1: usize,
    /// One past the last row (bottom).
    pub y1: usize,
}

impl Rect {
    /// Columns covered.
    pub fn width(&self) -> usize {
        self.x1.saturating_sub(self.x0)
    }

    /// Rows covered.
    pub fn height(&self) -> usize {
        self.y1.saturating_sub(self.y0)
    }

    /// The rectangle shrunk by the given margins, never below one pixel.
    pub fn inset(&self, left: usize, top: usize, right: usize, bottom: usize) -> Rect {
        let x0 = (self.x0 + left).min(self.x1.saturating_sub(1));
        let y0 = (self.y0 + top).min(self.y1.saturating_sub(1));
        Rect {
            x0,
            y0,
            x1: self.x1.saturating_sub(right).max(x0 + 1),
            y1: self.y1.saturating_sub(bottom).max(y0 + 1),
        }
    }
}

/// An RGB image being drawn on.
#[derive(Debug, Clone)]
pub struct Canvas {
    image: Image,
}

impl Canvas {
    /// A `width × height` canvas filled with [`BACKGROUND`].
    pub fn new(width: usize, height: usize) -> Canvas {
        let mut image = Image::new(
            width,
            height,
            vec!["R".to_owned(), "G".to_owned(), "B".to_owned()],
        );
        image.data.fill(1.0);
        Canvas { image }
    }

    /// A canvas drawing on `image` (channels `R, G, B`, linear), e.g. to annotate a rendered chart.
    ///
    /// # Panics
    /// If `image` does not have exactly three channels.
    pub fn from_image(image: Image) -> Canvas {
        assert_eq!(image.channels.len(), 3, "a canvas is RGB");
        Canvas { image }
    }

    /// The whole canvas as a rectangle.
    pub fn bounds(&self) -> Rect {
        Rect {
            x0: 0,
            y0: 0,
            x1: self.image.width,
            y1: self.image.height,
        }
    }

    /// The drawing, channels `R, G, B`, linear.
    pub fn into_image(self) -> Image {
        self.image
    }

    /// The colour of pixel (x, y). Panics outside the canvas.
    pub fn color(&self, x: usize, y: usize) -> Vec3 {
        Vec3::from_slice(self.image.pixel(x, y))
    }

    /// Mixes `color` into pixel (x, y) with weight `alpha`; pixels outside the canvas are ignored.
    fn blend(&mut self, x: usize, y: usize, color: Vec3, alpha: f32) {
        if x < self.image.width && y < self.image.height && alpha > 0.0 {
            let old = self.color(x, y);
            let new = old.lerp(color, alpha.min(1.0));
            self.image.pixel_mut(x, y).copy_from_slice(&new.to_array());
        }
    }

    /// Fills `rect` (clipped to the canvas) with `color`.
    pub fn fill(&mut self, rect: Rect, color: Vec3) {
        for y in rect.y0..rect.y1.min(self.image.height) {
            for x in rect.x0..rect.x1.min(self.image.width) {
                self.blend(x, y, color, 1.0);
            }
        }
    }

    /// Draws an antialiased polyline through `points` (pixel coordinates), `width` pixels wide, drawing only
    /// inside `clip`. Each pixel takes the coverage of the nearest segment, max(0, min(1, width/2 + 1/2 − d)) with
    /// d the distance from its centre, so joints are not drawn twice. A non-finite point breaks the line.
    pub fn polyline(&mut self, points: &[(f32, f32)], width: f32, color: Vec3, clip: Rect) {
        let clip = Rect {
            x1: clip.x1.min(self.image.width),
            y1: clip.y1.min(self.image.height),
            ..clip
        };
        let (w, h) = (clip.width(), clip.height());
        if w == 0 || h == 0 {
            return;
        }
        let mut coverage = vec![0.0f32; w * h];
        let reach = 0.5 * width + 0.5;
        let finite = |p: &(f32, f32)| p.0.is_finite() && p.1.is_finite();
        for pair in points.windows(2) {
            let (a, b) = (pair[0], pair[1]);
            if !finite(&a) || !finite(&b) {
                continue;
            }
            // The segment's bounding box grown by `reach`, in clip-local pixel indices.
            let lo = |u: f32, base: usize| (u - reach - base as f32).floor().max(0.0) as usize;
            let hi = |u: f32, base: usize, n: usize| {
                ((u + reach - base as f32).ceil().max(0.0) as usize).min(n)
            };
            let (i0, i1) = (lo(a.0.min(b.0), clip.x0), hi(a.0.max(b.0), clip.x0, w));
            let (j0, j1) = (lo(a.1.min(b.1), clip.y0), hi(a.1.max(b.1), clip.y0, h));
            let (dx, dy) = (b.0 - a.0, b.1 - a.1);
            let len2 = dx * dx + dy * dy;
            for j in j0..j1 {
                for i in i0..i1 {
                    let px = (clip.x0 + i) as f32 + 0.5;
                    let py = (clip.y0 + j) as f32 + 0.5;
                    let t = if len2 > 0.0 {
                        (((px - a.0) * dx + (py - a.1) * dy) / len2).clamp(0.0, 1.0)
                    } else {
                        0.0
                    };
                    let d = ((px - a.0 - t * dx).powi(2) + (py - a.1 - t * dy).powi(2)).sqrt();
                    let c = (reach - d).clamp(0.0, 1.0);
                    let cell = &mut coverage[j * w + i];
                    *cell = cell.max(c);
                }
            }
        }
        for j in 0..h {
            for i in 0..w {
                self.blend(clip.x0 + i, clip.y0 + j, color, coverage[j * w + i]);
            }
        }
    }

    /// Draws `text` with its top-left corner at (x, y), [`TEXT_SCALE`] pixels per font pixel.
    pub fn text(&mut self, x: usize, y: usize, text: &str, color: Vec3) {
        self.glyphs(text, color, |col, row| (x + col, y + row));
    }

    /// Draws `text` rotated a quarter turn anticlockwise (reading upwards), its bottom-left corner at (x, y).
    pub fn text_vertical(&mut self, x: usize, y: usize, text: &str, color: Vec3) {
        self.glyphs(text, color, |col, row| (x + row, y.wrapping_sub(col + 1)));
    }

    /// Draws `text`'s glyph pixels through `place`, which maps (column, row) of the unrotated text to the canvas.
    fn glyphs(&mut self, text: &str, color: Vec3, place: impl Fn(usize, usize) -> (usize, usize)) {
        for (k, c) in text.chars().enumerate() {
            let bits = glyph(c);
            for (row, line) in bits.iter().enumerate() {
                for col in 0..5 {
                    if line & (0b10000 >> col) == 0 {
                        continue;
                    }
                    for sy in 0..TEXT_SCALE {
                        for sx in 0..TEXT_SCALE {
                            let (px, py) = place(
                                k * TEXT_ADVANCE + col * TEXT_SCALE + sx,
                                row * TEXT_SCALE + sy,
                            );
                            self.blend(px, py, color, 1.0);
                        }
                    }
                }
            }
        }
    }
}

/// Width of `text` in pixels (no trailing spacing).
pub fn text_width(text: &str) -> usize {
    (text.chars().count() * TEXT_ADVANCE).saturating_sub(TEXT_SCALE)
}

/// The 5 × 7 bitmap of `c`, one byte per row, top first, bit 4 leftmost. Lower case is drawn as upper case and
/// unknown characters as `?`.
fn glyph(c: char) -> [u8; 7] {
    match c.to_ascii_uppercase() {
        '0' => [0x0e, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0e],
        '1' => [0x04, 0x0c, 0x04, 0x04, 0x04, 0x04, 0x0e],
        '2' => [0x0e, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1f],
        '3' => [0x1f, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0e],
        '4' => [0x02, 0x06, 0x0a, 0x12, 0x1f, 0x02, 0x02],
        '5' => [0x1f, 0x10, 0x1e, 0x01, 0x01, 0x11, 0x0e],
        '6' => [0x06, 0x08, 0x10, 0x1e, 0x11, 0x11, 0x0e],
        '7' => [0x1f, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08],
        '8' => [0x0e, 0x11, 0x11, 0x0e, 0x11, 0x11, 0x0e],
        '9' => [0x0e, 0x11, 0x11, 0x0f, 0x01, 0x02, 0x0c],
        'A' => [0x0e, 0x11, 0x11, 0x11, 0x1f, 0x11, 0x11],
        'B' => [0x1e, 0x11, 0x11, 0x1e, 0x11, 0x11, 0x1e],
        'C' => [0x0e, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0e],
        'D' => [0x1c, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1c],
        'E' => [0x1f, 0x10, 0x10, 0x1e, 0x10, 0x10, 0x1f],
        'F' => [0x1f, 0x10, 0x10, 0x1e, 0x10, 0x10, 0x10],
        'G' => [0x0e, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0f],
        'H' => [0x11, 0x11, 0x11, 0x1f, 0x11, 0x11, 0x11],
        'I' => [0x0e, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0e],
        'J' => [0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0c],
        'K' => [0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11],
        'L' => [0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1f],
        'M' => [0x11, 0x1b, 0x15, 0x15, 0x11, 0x11, 0x11],
        'N' => [0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11],
        'O' => [0x0e, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0e],
        'P' => [0x1e, 0x11, 0x11, 0x1e, 0x10, 0x10, 0x10],
        'Q' => [0x0e, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0d],
        'R' => [0x1e, 0x11, 0x11, 0x1e, 0x14, 0x12, 0x11],
        'S' => [0x0f, 0x10, 0x10, 0x0e, 0x01, 0x01, 0x1e],
        'T' => [0x1f, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04],
        'U' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0e],
        'V' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x0a, 0x04],
        'W' => [0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0a],
        'X' => [0x11, 0x11, 0x0a, 0x04, 0x0a, 0x11, 0x11],
        'Y' => [0x11, 0x11, 0x11, 0x0a, 0x04, 0x04, 0x04],
        'Z' => [0x1f, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1f],
        ' ' => [0; 7],
        '-' | '−' => [0x00, 0x00, 0x00, 0x1f, 0x00, 0x00, 0x00],
        '+' => [0x00, 0x04, 0x04, 0x1f, 0x04, 0x04, 0x00],
        '.' => [0x00, 0x00, 0x00, 0x00, 0x00, 0x0c, 0x0c],
        ',' => [0x00, 0x00, 0x00, 0x00, 0x0c, 0x04, 0x08],
        ':' => [0x00, 0x0c, 0x0c, 0x00, 0x0c, 0x0c, 0x00],
        '=' => [0x00, 0x00, 0x1f, 0x00, 0x1f, 0x00, 0x00],
        '(' => [0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02],
        ')' => [0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08],
        '/' => [0x00, 0x01, 0x02, 0x04, 0x08, 0x10, 0x00],
        '°' => [0x0c, 0x12, 0x12, 0x0c, 0x00, 0x00, 0x00],
        'θ' => [0x0e, 0x11, 0x11, 0x1f, 0x11, 0x11, 0x0e],
        'φ' => [0x04, 0x0e, 0x15, 0x15, 0x15, 0x0e, 0x04],
        '√' => [0x07, 0x04, 0x04, 0x04, 0x14, 0x0c, 0x04],
        'Σ' => [0x1f, 0x10, 0x08, 0x04, 0x08, 0x10, 0x1f],
        'χ' => [0x00, 0x00, 0x11, 0x0a, 0x04, 0x0a, 0x11],
        '²' => [0x0c, 0x02, 0x04, 0x08, 0x0e, 0x00, 0x00],
        '×' => [0x00, 0x11, 0x0a, 0x04, 0x0a, 0x11, 0x00],
        _ => [0x0e, 0x11, 0x01, 0x02, 0x04, 0x00, 0x04],
    }
}

/// How an axis maps values to positions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scale {
    /// Position ∝ value.
    Linear,
    /// Position ∝ log10(value); values ≤ 0 fall below the axis.
    Log10,
}

/// One axis of a chart: its label, range, scale and tick positions (in data units).
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    /// The axis title.
    pub label: String,
    /// The value at the start (left, bottom, or the centre of a polar chart).
    pub min: f32,
    /// The value at the end.
    pub max: f32,
    /// Linear or logarithmic.
    pub scale: Scale,
    /// Where ticks, grid lines and tick labels go.
    pub ticks: Vec<f32>,
}

impl Axis {
    /// A linear axis over [`min`, `max`] with a tick at every multiple of `step` inside it.
    pub fn linear(label: &str, min: f32, max: f32, step: f32) -> Axis {
        let first = (min / step).ceil() as i64;
        let last = (max / step + 1e-4).floor() as i64;
        Axis {
            label: label.to_owned(),
            min,
            max,
            scale: Scale::Linear,
            ticks: (first..=last).map(|k| k as f32 * step).collect(),
        }
    }

    /// A linear axis over [`min`, `max`] with about six ticks (four to nine) at multiples of 1, 2 or 5 times a power
    /// of ten.
    pub fn linear_auto(label: &str, min: f32, max: f32) -> Axis {
        let span = (max - min).abs().max(f32::MIN_POSITIVE);
        let rough = span / 6.0;
        let power = 10f32.powf(rough.log10().floor());
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
    pub fn log_decades(label: &str, max_value: f32, decades: u32) -> Axis {
        let top = if max_value > 0.0 && max_value.is_finite() {
            max_value.log10().ceil() as i32
        } else {
            0
        };
        let bottom = top - decades.max(1) as i32;
        Axis {
            label: label.to_owned(),
            min: 10f32.powi(bottom),
            max: 10f32.powi(top),
            scale: Scale::Log10,
            ticks: (bottom..=top).map(|e| 10f32.powi(e)).collect(),
        }
    }

    /// Where `v` sits along the axis: 0 at `min`, 1 at `max`, outside [0, 1] beyond them. On a log axis a value
    /// ≤ 0 (or NaN) maps to −1, one axis length below the start, so a curve dropping to zero dives off the chart.
    pub fn fraction(&self, v: f32) -> f32 {
        match self.scale {
            Scale::Linear => (v - self.min) / (self.max - self.min),
            Scale::Log10 => {
                if v > 0.0 {
                    ((v / self.min).log10() / (self.max / self.min).log10()).max(-1.0)
                } else {
                    -1.0
                }
            }
        }
    }

    /// The text of the tick at `v`: as many decimals as the tick spacing needs on a linear axis; on a log axis
    /// plain decimals if every tick is within 10^−3 … 10^3, else `1E-5` style for all.
    pub fn tick_label(&self, v: f32) -> String {
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
                let text = format!("{v:.decimals$}");
                if text
                    .trim_start_matches('-')
                    .chars()
                    .all(|c| c == '0' || c == '.')
                {
                    // No "-0".
                    text.trim_start_matches('-').to_owned()
                } else {
                    text
                }
            }
            Scale::Log10 => {
                let exponent = |t: f32| t.log10().round() as i32;
                let e = exponent(v);
                if self.ticks.iter().all(|&t| (-3..=3).contains(&exponent(t))) {
                    format!("{:.*}", (-e).max(0) as usize, 10f64.powi(e))
                } else {
                    format!("1E{e}")
                }
            }
        }
    }
}

/// One curve: points in data units, drawn in `color` (linear RGB), `width` pixels wide.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// The legend text.
    pub label: String,
    /// Linear RGB.
    pub color: Vec3,
    /// Line width, pixels.
    pub width: f32,
    /// (x, y) in data units, in drawing order.
    pub points: Vec<(f32, f32)>,
}

/// Draws a row of legend entries (a swatch and the label of each series) from (x, y), wrapping at `right`.
fn legend(canvas: &mut Canvas, x: usize, y: usize, right: usize, series: &[Series]) {
    const SWATCH: usize = 24;
    const GAP: usize = 20;
    let (mut cx, mut cy) = (x, y);
    for s in series {
        let entry = SWATCH + 6 + text_width(&s.label);
        if cx > x && cx + entry > right {
            cx = x;
            cy += TEXT_HEIGHT + 6;
        }
        let mid = cy + TEXT_HEIGHT / 2;
        let thick = (s.width.round() as usize).max(2);
        canvas.fill(
            Rect {
                x0: cx,
                y0: mid - thick / 2,
                x1: cx + SWATCH,
                y1: mid - thick / 2 + thick,
            },
            s.color,
        );
        canvas.text(cx + SWATCH + 6, cy, &s.label, INK);
        cx += entry + GAP;
    }
}

/// Draws `title` centred horizontally in `rect`, at its top.
fn title(canvas: &mut Canvas, rect: Rect, text: &str) {
    let x = rect.x0 + rect.width().saturating_sub(text_width(text)) / 2;
    canvas.text(x, rect.y0, text, INK);
}

/// The frame of a plot area: the x axis along the bottom, the y axis along the left, ticks pointing out, tick
/// labels, axis titles and, if `grid`, grid lines inside. `to_px`/`to_py` map data to continuous pixel coordinates.
fn axes(
    canvas: &mut Canvas,
    area: Rect,
    x: &Axis,
    y: &Axis,
    grid: bool,
    to_px: impl Fn(f32) -> f32,
    to_py: impl Fn(f32) -> f32,
) {
    const TICK: usize = 5;
    for &t in &x.ticks {
        let px = to_px(t).floor() as usize;
        if grid {
            canvas.fill(
                Rect {
                    x0: px,
                    x1: px + 1,
                    ..area
                },
                GRID,
            );
        }
        canvas.fill(
            Rect {
                x0: px,
                x1: px + 1,
                y0: area.y1,
                y1: area.y1 + TICK,
            },
            INK,
        );
        let label = x.tick_label(t);
        let lx = px.saturating_sub(text_width(&label) / 2);
        canvas.text(lx, area.y1 + TICK + 3, &label, INK);
    }
    for &t in &y.ticks {
        let py = to_py(t).floor() as usize;
        if grid {
            canvas.fill(
                Rect {
                    y0: py,
                    y1: py + 1,
                    ..area
                },
                GRID,
            );
        }
        canvas.fill(
            Rect {
                x0: area.x0.saturating_sub(TICK + 1),
                x1: area.x0,
                y0: py,
                y1: py + 1,
            },
            INK,
        );
        let label = y.tick_label(t);
        let lx = area.x0.saturating_sub(TICK + 4 + text_width(&label));
        canvas.text(lx, py.saturating_sub(TEXT_HEIGHT / 2), &label, INK);
    }
    // The axis lines sit just outside the area so they never hide a curve at the range's ends.
    canvas.fill(
        Rect {
            x0: area.x0.saturating_sub(1),
            x1: area.x1,
            y0: area.y1,
            y1: area.y1 + 1,
        },
        INK,
    );
    canvas.fill(
        Rect {
            x0: area.x0.saturating_sub(1),
            x1: area.x0,
            ..area
        },
        INK,
    );
    let xl = area.x0 + area.width().saturating_sub(text_width(&x.label)) / 2;
    canvas.text(xl, area.y1 + TICK + TEXT_HEIGHT + 9, &x.label, INK);
    let widest = y
        .ticks
        .iter()
        .map(|&t| text_width(&y.tick_label(t)))
        .max()
        .unwrap_or(0);
    let yl = area.y1 - area.height().saturating_sub(text_width(&y.label)) / 2;
    canvas.text_vertical(
        area.x0.saturating_sub(TICK + 10 + widest + TEXT_HEIGHT),
        yl,
        &y.label,
        INK,
    );
}

/// Maps an axis fraction to a pixel coordinate between the centres of the first and last pixel of
/// [`start`, `end`) (increasing; flip for y).
fn along(fraction: f32, start: usize, end: usize) -> f32 {
    start as f32 + 0.5 + fraction * (end.saturating_sub(start + 1)) as f32
}

/// A line chart: axes with ticks and grid, one polyline per series, a legend row under the title.
#[derive(Debug, Clone, PartialEq)]
pub struct LineChart {
    /// The title, centred on top.
    pub title: String,
    /// The horizontal axis.
    pub x: Axis,
    /// The vertical axis.
    pub y: Axis,
    /// The curves, drawn in order (later on top).
    pub series: Vec<Series>,
}

impl LineChart {
    /// Margins around the plot area: room for the title and legend above, tick labels and axis titles left and
    /// below.
    const MARGIN: (usize, usize, usize, usize) = (
        3 * TEXT_HEIGHT + 60,
        2 * TEXT_HEIGHT + 30,
        30,
        2 * TEXT_HEIGHT + 22,
    );

    /// The plot area of a `width × height` rendering (the rectangle the axes enclose).
    pub fn plot_area(&self, width: usize, height: usize) -> Rect {
        let (left, top, right, bottom) = LineChart::MARGIN;
        let rows = legend_rows(&self.series, width.saturating_sub(left + right));
        Rect {
            x0: 0,
            y0: 0,
            x1: width,
            y1: height,
        }
        .inset(
            left,
            top + (rows.saturating_sub(1)) * (TEXT_HEIGHT + 6),
            right,
            bottom,
        )
    }

    /// The continuous pixel coordinates of data point (x, y) in plot area `area`.
    pub fn to_pixel(&self, area: Rect, x: f32, y: f32) -> (f32, f32) {
        (
            along(self.x.fraction(x), area.x0, area.x1),
            area.y1 as f32 - along(self.y.fraction(y), 0, area.height()),
        )
    }

    /// Renders the chart into a new `width × height` RGB image (linear).
    pub fn render(&self, width: usize, height: usize) -> Image {
        let mut canvas = Canvas::new(width, height);
        let area = self.plot_area(width, height);
        axes(
            &mut canvas,
            area,
            &self.x,
            &self.y,
            true,
            |x| self.to_pixel(area, x, self.y.min).0,
            |y| self.to_pixel(area, self.x.min, y).1,
        );
        for s in &self.series {
            let points: Vec<(f32, f32)> = s
                .points
                .iter()
                .map(|&(x, y)| self.to_pixel(area, x, y))
                .collect();
            canvas.polyline(&points, s.width, s.color, area);
        }
        let bounds = canvas.bounds();
        title(&mut canvas, bounds.inset(0, 8, 0, 0), &self.title);
        legend(
            &mut canvas,
            area.x0,
            8 + TEXT_HEIGHT + 12,
            area.x1,
            &self.series,
        );
        canvas.into_image()
    }
}

/// How many rows the legend of `series` takes in `width` pixels.
fn legend_rows(series: &[Series], width: usize) -> usize {
    let (mut rows, mut x) = (1, 0);
    for s in series {
        let entry = 24 + 6 + text_width(&s.label);
        if x > 0 && x + entry > width {
            rows += 1;
            x = 0;
        }
        x += entry + 20;
    }
    rows
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

impl PolarChart {
    /// Renders the chart into a new `width × height` RGB image (linear).
    pub fn render(&self, width: usize, height: usize) -> Image {
        let mut canvas = Canvas::new(width, height);
        let bounds = canvas.bounds();
        let rows = legend_rows(&self.series, width.saturating_sub(40));
        // Title, legend, then a line for the 90° label above the circle; the −90° label and the radius label
        // below it.
        let top = 8 + TEXT_HEIGHT + 12 + rows * (TEXT_HEIGHT + 6) + TEXT_HEIGHT + 8;
        let bottom = 2 * TEXT_HEIGHT + 24;
        let inner = height.saturating_sub(top + bottom);
        let r_px =
            (width.saturating_sub(2 * (5 * TEXT_ADVANCE + 8)) as f32).min(inner as f32) * 0.5;
        let (cx, cy) = (width as f32 * 0.5, (top + inner / 2) as f32);
        let at = |angle: f32, r: f32| (cx + r * angle.cos(), cy - r * angle.sin());
        let circle = |r: f32| -> Vec<(f32, f32)> {
            (0..=180)
                .map(|k| at(k as f32 * std::f32::consts::TAU / 180.0, r))
                .collect()
        };
        for &t in &self.radius.ticks {
            let r = self.radius.fraction(t).clamp(0.0, 1.0) * r_px;
            canvas.polyline(&circle(r), 1.0, GRID, bounds);
        }
        for k in 0..12 {
            let angle = (k as f32 * 30.0).to_radians();
            canvas.polyline(&[at(angle, 0.0), at(angle, r_px)], 1.0, GRID, bounds);
            let degrees = if k <= 6 { k * 30 } else { k * 30 - 360 };
            let label = format!("{degrees}°");
            // Centre the label's box just outside the circle, its half-extent along the spoke clear of it.
            let (w, h) = (text_width(&label) as f32, TEXT_HEIGHT as f32);
            let reach = 0.5 * (w * angle.cos().abs() + h * angle.sin().abs());
            let (lx, ly) = at(angle, r_px + 8.0 + reach);
            canvas.text(
                (lx - 0.5 * w).max(0.0) as usize,
                (ly - 0.5 * h).max(0.0) as usize,
                &label,
                INK,
            );
        }
        canvas.polyline(&circle(r_px), 1.5, INK, bounds);
        for s in &self.series {
            let points: Vec<(f32, f32)> = s
                .points
                .iter()
                .map(|&(a, v)| at(a, self.radius.fraction(v).max(0.0) * r_px))
                .collect();
            canvas.polyline(&points, s.width, s.color, bounds);
        }
        // Ring labels on top of the curves, on a background box, just inside each ring right of the 90° spoke
        // (the centre ring has none).
        for &t in &self.radius.ticks {
            let f = self.radius.fraction(t);
            if f <= 0.0 || f > 1.0 {
                continue;
            }
            let (lx, ly) = at(FRAC_PI_2, f * r_px);
            let label = self.radius.tick_label(t);
            let (x0, y0) = (lx as usize + 4, ly as usize + 4);
            canvas.fill(
                Rect {
                    x0: x0 - 2,
                    y0: y0.saturating_sub(2),
                    x1: x0 + text_width(&label) + 2,
                    y1: y0 + TEXT_HEIGHT + 2,
                },
                BACKGROUND,
            );
            canvas.text(x0, y0, &label, INK);
        }
        title(&mut canvas, bounds.inset(0, 8, 0, 0), &self.title);
        legend(
            &mut canvas,
            20,
            8 + TEXT_HEIGHT + 12,
            width.saturating_sub(20),
            &self.series,
        );
        let label = &self.radius.label;
        canvas.text(
            width.saturating_sub(text_width(label)) / 2,
            height.saturating_sub(TEXT_HEIGHT + 6),
            label,
            INK,
        );
        canvas.into_image()
    }
}

/// A colour map from [0, 1] to linear RGB.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Colormap {
    /// Perceptually uniform dark blue → green → yellow (matplotlib's viridis, 9 stops).
    Viridis,
    /// Blue (0) → white (1/2) → red (1) (ColorBrewer RdBu, 7 stops), for signed differences.
    Diverging,
}

impl Colormap {
    /// The colour at `t` (clamped to [0, 1]; NaN is grey), interpolated in sRGB between the stops.
    pub fn color(self, t: f32) -> Vec3 {
        const VIRIDIS: [u32; 9] = [
            0x440154, 0x472c7a, 0x3b528b, 0x2c728e, 0x21918c, 0x27ad81, 0x5ec962, 0xaadc32,
            0xfde725,
        ];
        const DIVERGING: [u32; 7] = [
            0x2166ac, 0x67a9cf, 0xd1e5f0, 0xf7f7f7, 0xfddbc7, 0xef8a62, 0xb2182b,
        ];
        if t.is_nan() {
            return Vec3::splat(0.2);
        }
        let stops: &[u32] = match self {
            Colormap::Viridis => &VIRIDIS,
            Colormap::Diverging => &DIVERGING,
        };
        let s = t.clamp(0.0, 1.0) * (stops.len() - 1) as f32;
        let k = (s.floor() as usize).min(stops.len() - 2);
        let bytes = |hex: u32| {
            Vec3::new(
                ((hex >> 16) & 0xff) as f32,
                ((hex >> 8) & 0xff) as f32,
                (hex & 0xff) as f32,
            )
        };
        let mixed = bytes(stops[k]).lerp(bytes(stops[k + 1]), s - k as f32);
        let hex = mixed.round().as_uvec3();
        srgb((hex.x << 16) | (hex.y << 8) | hex.z)
    }
}

/// A heat map: `rows × cols` cells filled by colour map over a value range, with axes.
#[derive(Debug, Clone, PartialEq)]
pub struct HeatMap {
    /// The title, above the map.
    pub title: String,
    /// Number of rows (along y).
    pub rows: usize,
    /// Number of columns (along x).
    pub cols: usize,
    /// Row-major values; row 0 is at the bottom (y = `y.min`), column 0 at the left.
    pub values: Vec<f32>,
    /// The colour map.
    pub colormap: Colormap,
    /// The values mapped to the ends of the colour map (values beyond are clamped).
    pub range: (f32, f32),
    /// The horizontal axis, spanning the columns.
    pub x: Axis,
    /// The vertical axis, spanning the rows.
    pub y: Axis,
}

impl HeatMap {
    /// The rectangle the cells fill inside `panel` (the rest holds the title, ticks and labels).
    pub fn cells(panel: Rect) -> Rect {
        panel.inset(
            2 * TEXT_HEIGHT + 4 * TEXT_ADVANCE,
            TEXT_HEIGHT + 12,
            2 * TEXT_ADVANCE,
            2 * TEXT_HEIGHT + 22,
        )
    }

    /// Draws the map, its axes and title into `panel` of `canvas`.
    pub fn draw(&self, canvas: &mut Canvas, panel: Rect) {
        let area = HeatMap::cells(panel);
        let (lo, hi) = self.range;
        for i in 0..self.rows {
            // Row 0 at the bottom.
            let y1 = area.y1 - i * area.height() / self.rows;
            let y0 = area.y1 - (i + 1) * area.height() / self.rows;
            for j in 0..self.cols {
                let x0 = area.x0 + j * area.width() / self.cols;
                let x1 = area.x0 + (j + 1) * area.width() / self.cols;
                let v = self.values[i * self.cols + j];
                let color = self.colormap.color((v - lo) / (hi - lo));
                canvas.fill(Rect { x0, y0, x1, y1 }, color);
            }
        }
        // Ticks at cell edges: the axes span the area edge to edge.
        let to_px = |x: f32| area.x0 as f32 + self.x.fraction(x) * area.width() as f32;
        let to_py = |y: f32| area.y1 as f32 - self.y.fraction(y) * area.height() as f32;
        axes(canvas, area, &self.x, &self.y, false, to_px, to_py);
        title(canvas, panel, &self.title);
    }
}

/// A horizontal colour bar: the colour map spread along `axis` (linear), with its ticks and label, in `panel`.
pub fn color_bar(canvas: &mut Canvas, panel: Rect, colormap: Colormap, axis: &Axis) {
    let bar = Rect {
        x0: panel.x0 + 12,
        x1: panel.x1.saturating_sub(12),
        y0: panel.y0,
        y1: panel.y0 + 16,
    };
    for x in bar.x0..bar.x1 {
        let t = (x - bar.x0) as f32 / (bar.width().max(2) - 1) as f32;
        canvas.fill(
            Rect {
                x0: x,
                x1: x + 1,
                ..bar
            },
            colormap.color(t),
        );
    }
    let none = Axis {
        label: String::new(),
        min: 0.0,
        max: 1.0,
        scale: Scale::Linear,
        ticks: Vec::new(),
    };
    axes(
        canvas,
        bar,
        axis,
        &none,
        false,
        |v| bar.x0 as f32 + axis.fraction(v) * bar.width() as f32,
        |_| bar.y1 as f32,
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A constant series on a [0, 1] axis at 1/2 draws a horizontal line through the middle row of the plot area,
    /// from the first to the last column, and nothing a few rows away.
    #[test]
    fn constant_series_draws_a_horizontal_line_at_its_row() {
        let red = Vec3::new(1.0, 0.0, 0.0);
        let chart = LineChart {
            title: "TEST".to_owned(),
            x: Axis::linear("X", 0.0, 10.0, 2.0),
            y: Axis::linear("Y", 0.0, 1.0, 0.25),
            series: vec![Series {
                label: "C".to_owned(),
                color: red,
                width: 2.0,
                points: (0..=10).map(|k| (k as f32, 0.5)).collect(),
            }],
        };
        let (w, h) = (401, 301);
        let area = chart.plot_area(w, h);
        // Make the middle row exact: an odd number of rows puts y = 1/2 on a pixel centre.
        assert!(area.height() % 2 == 1, "area {area:?}");
        let row = area.y0 + area.height() / 2;
        let canvas = Canvas {
            image: chart.render(w, h),
        };
        for x in area.x0..area.x1 {
            assert_eq!(canvas.color(x, row), red, "pixel ({x}, {row})");
            for dy in [3, 10] {
                for y in [row - dy, row + dy] {
                    let c = canvas.color(x, y);
                    assert!(
                        c.y > 0.5,
                        "pixel ({x}, {y}) is {c}: the line is too thick or misplaced"
                    );
                }
            }
        }
        // Nothing red outside the plot area (the line is clipped).
        assert_ne!(canvas.color(area.x0 - 2, row), red);
        assert_ne!(canvas.color(area.x1 + 2, row), red);
    }

    /// A diagonal from the area's bottom-left to its top-right corner hits both corner pixels and the centre.
    #[test]
    fn diagonal_series_passes_through_the_corners() {
        let chart = LineChart {
            title: String::new(),
            x: Axis::linear("", -1.0, 1.0, 0.5),
            y: Axis::linear("", -1.0, 1.0, 0.5),
            series: vec![Series {
                label: "D".to_owned(),
                color: Vec3::new(0.0, 0.0, 1.0),
                width: 1.0,
                points: vec![(-1.0, -1.0), (1.0, 1.0)],
            }],
        };
        let area = chart.plot_area(301, 301);
        let (px, py) = chart.to_pixel(area, 1.0, 1.0);
        assert_eq!(
            (px, py),
            (area.x1 as f32 - 0.5, area.y0 as f32 + 0.5),
            "{area:?}"
        );
        let (qx, qy) = chart.to_pixel(area, -1.0, -1.0);
        assert_eq!((qx, qy), (area.x0 as f32 + 0.5, area.y1 as f32 - 0.5));
        let canvas = Canvas {
            image: chart.render(301, 301),
        };
        let blue = Vec3::new(0.0, 0.0, 1.0);
        assert_eq!(canvas.color(area.x0, area.y1 - 1), blue);
        assert_eq!(canvas.color(area.x1 - 1, area.y0), blue);
    }

    #[test]
    fn log_axis_spans_whole_decades_and_sends_zero_below() {
        let axis = Axis::log_decades("F", 3.2, 4);
        assert_eq!((axis.min, axis.max), (1e-3, 10.0));
        assert_eq!(axis.ticks.len(), 5);
        assert!((axis.fraction(0.1) - 0.5).abs() < 1e-6);
        assert_eq!(axis.fraction(0.0), -1.0);
        assert_eq!(axis.tick_label(1e-3), "0.001");
        assert_eq!(axis.tick_label(10.0), "10");
        let low = Axis::log_decades("F", 1e-2, 3);
        assert_eq!(low.tick_label(1e-5), "1E-5");
        assert_eq!(low.tick_label(1e-2), "1E-2");
        let lin = Axis::linear_auto("X", -90.0, 90.0);
        assert_eq!(lin.ticks.first(), Some(&-80.0));
        assert_eq!(lin.tick_label(0.0), "0");
        assert_eq!(Axis::linear("S", -1.0, 1.0, 0.5).tick_label(-0.5), "-0.5");
    }

    /// Text lands where asked, in the ink colour, and `text_width` covers it exactly.
    #[test]
    fn text_covers_its_box() {
        let mut canvas = Canvas::new(100, 30);
        canvas.text(10, 5, "1E", INK);
        // 'E' has a full top row and a full last column.
        assert_eq!(canvas.color(10 + TEXT_ADVANCE, 5), INK);
        assert_eq!(canvas.color(10 + TEXT_ADVANCE + 5 * TEXT_SCALE - 1, 5), INK);
        let right = 10 + text_width("1E");
        let inked = (0..100).filter(|&x| (0..30).any(|y| canvas.color(x, y) == INK));
        assert_eq!(inked.max(), Some(right - 1));
        let bottom = (0..30).filter(|&y| (0..100).any(|x| canvas.color(x, y) == INK));
        assert_eq!(bottom.max(), Some(5 + TEXT_HEIGHT - 1));
    }

    #[test]
    fn colormaps_hit_their_end_stops() {
        assert!((Colormap::Viridis.color(0.0) - srgb(0x440154)).length() < 1e-6);
        assert!((Colormap::Viridis.color(2.0) - srgb(0xfde725)).length() < 1e-6);
        assert!((Colormap::Diverging.color(0.5) - srgb(0xf7f7f7)).length() < 1e-6);
    }
}
