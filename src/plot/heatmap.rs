//! Heat maps ([`HeatMap`]) and horizontal colour bars ([`ColorBar`]), coloured by a [`Colormap`].

use plotters::coord::Shift;
use plotters::prelude::*;

use super::axis::{draw_axes, Axis};
use super::{hex, text_style, Chart, DrawResult, INK, LABEL_SIZE, TICK_SIZE};

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
        draw_axes(&mut chart, (&self.x, &self.y), TICK_SIZE, false)
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
    fn colormaps_hit_their_end_stops() {
        assert_eq!(Colormap::Viridis.color(-1.0), ViridisRGB.get_color(0.0));
        assert_eq!(Colormap::Diverging.color(0.5), hex(0xf7f7f7));
        assert_eq!(Colormap::Diverging.color(2.0), hex(0xb2182b));
    }
}
