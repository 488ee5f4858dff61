//! Line charts ([`LineChart`]): curves ([`Series`]) on linear or log10 axes, under a title and a legend that wraps
//! into rows ([`header`], shared with the polar chart). Curves are clipped to the plotting area here
//! ([`clipped_runs`]), not by plotters, which would pull them onto its edge.

use std::ops::Range;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::axis::{draw_axes, Axis};
use super::{text_size, text_style, Chart, DrawResult, INK, LABEL_SIZE, TICK_SIZE, TITLE_SIZE};

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
pub(super) fn header<DB: DrawingBackend>(
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
        draw_axes(&mut chart, (&self.x, &self.y), LABEL_SIZE, true)?;
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plot::{linear, render};

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
}
