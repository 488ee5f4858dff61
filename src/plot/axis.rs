//! Chart axes: linear and log10 scales ([`Axis`]), their tick labels (powers of ten in superscript digits), and the
//! drawing coordinates plotters sees ([`AxisCoord`]). A log10 axis is drawn as a linear axis over the exponent
//! ([`Axis::position`]).

use std::ops::Range;

use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use super::{text_style, DrawResult, GRID, INK, LIGHT_GRID, TICK_SIZE};

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
    pub(super) fn range(&self) -> Range<f64> {
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
    pub(super) fn coord(&self) -> AxisCoord {
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
pub(super) struct AxisCoord {
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

/// Draws the axes of `chart` (built over the [`Axis::coord`] of `x` and `y`): ticks labelled by
/// [`Axis::tick_label`] at [`TICK_SIZE`], the axis titles at `title_size` pixels, all in [`INK`]; with `grid`, grid
/// lines at the labelled ticks ([`GRID`]) and between them ([`LIGHT_GRID`]), else none.
pub(super) fn draw_axes<DB: DrawingBackend>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<AxisCoord, AxisCoord>>,
    (x, y): (&Axis, &Axis),
    title_size: f64,
    grid: bool,
) -> DrawResult<DB> {
    let x_label = |v: &f64| x.tick_label(*v);
    let y_label = |v: &f64| y.tick_label(*v);
    let mut mesh = chart.configure_mesh();
    mesh.x_desc(x.label.as_str())
        .y_desc(y.label.as_str())
        .x_label_formatter(&x_label)
        .y_label_formatter(&y_label)
        .label_style(text_style(TICK_SIZE, INK))
        .axis_desc_style(text_style(title_size, INK))
        .axis_style(INK);
    if grid {
        mesh.bold_line_style(GRID).light_line_style(LIGHT_GRID);
    } else {
        mesh.disable_mesh();
    }
    mesh.draw()
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
