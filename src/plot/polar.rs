//! Polar charts ([`PolarChart`]): curves of a value against an angle, on a radial [`Axis`].

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::axis::Axis;
use super::line::{header, Series};
use super::{text_size, text_style, Chart, DrawResult, GRID, INK, LABEL_SIZE, TICK_SIZE};

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plot::{linear, render};

    /// A constant red series at half the radius is drawn as a circle (its red pixels under the legend span a square
    /// about half the plot's width), and the title, legend, radius label and angle labels are in the SVG.
    #[test]
    fn polar_chart_draws_a_constant_series_as_a_circle() {
        let red = RGBColor(255, 0, 0);
        let half: Vec<(f64, f64)> = (0..=360)
            .map(|k| (f64::from(k).to_radians(), 0.5))
            .collect();
        let chart = PolarChart {
            title: "polar test".to_owned(),
            radius: Axis::linear("r label", 0.0, 1.0, 0.5),
            series: vec![Series::line("half", red, 3, half)],
        };
        let (width, height) = (400, 500);
        let figure = render(&chart, "test", (width, height)).unwrap();
        // Below the title and legend (whose swatch is red too).
        let red_pixels: Vec<(usize, usize)> = (100..height)
            .flat_map(|y| (0..width).map(move |x| (x, y)))
            .filter(|&(x, y)| figure.image.pixel(x, y) == linear(red))
            .collect();
        let span = |coord: fn(&(usize, usize)) -> usize| {
            let values = red_pixels.iter().map(coord);
            values.clone().max().unwrap_or(0) - values.min().unwrap_or(0)
        };
        let (w, h) = (span(|p| p.0), span(|p| p.1));
        // The plot is 400 pixels wide and the unit circle 1/1.19 of its half-width: a 168-pixel circle.
        assert!((150..195).contains(&w), "circle {w} × {h} pixels");
        assert!(w.abs_diff(h) <= 6, "circle {w} × {h} pixels");
        for text in ["polar test", "half", "r label", "90°", "−90°"] {
            assert!(figure.svg.contains(text), "{text} missing from the svg");
        }
    }
}
