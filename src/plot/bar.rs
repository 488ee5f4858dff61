//! Bar charts over named categories ([`BarChart`]): one group of bars per category, a bar per series, on a linear
//! or log10 value axis, the category names under their groups (wrapped at spaces and hyphens to fit). For values
//! that belong to unrelated cases, where a line through them would suggest an order or a trend.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::axis::{draw_axes, Axis, Scale};
use super::line::{header, Series};
use super::{text_size, text_style, Chart, DrawResult, INK, LABEL_SIZE, TICK_SIZE};

/// The values of one series, a bar per category.
#[derive(Debug, Clone, PartialEq)]
pub struct Bars {
    /// The legend text.
    pub label: String,
    /// The bars' colour.
    pub color: RGBColor,
    /// One value per category (in [`BarChart::categories`] order); a value that is not finite, or not positive
    /// on a log axis, draws no bar.
    pub values: Vec<f64>,
}

/// Bars grouped by category: title, legend, a value axis, the category names under the groups.
#[derive(Debug, Clone, PartialEq)]
pub struct BarChart {
    /// The title, centred on top.
    pub title: String,
    /// The title under the category names.
    pub category_label: String,
    /// The category names, left to right.
    pub categories: Vec<String>,
    /// The value axis (vertical); bars start at its minimum, so a value there draws no bar.
    pub y: Axis,
    /// The series, each a bar in every group, in order.
    pub series: Vec<Bars>,
}

/// Room for the tick labels and title of the value axis, pixels.
const Y_LABEL_AREA: u32 = 84;
/// Height of a line of category names, pixels.
const NAME_LINE: u32 = 17;
/// The part of a category's width its bars fill.
const GROUP_FILL: f64 = 0.8;

/// `name` broken into lines no wider than `width` pixels at [`TICK_SIZE`], after spaces and hyphens; a piece
/// wider than `width` stays whole on its own line.
pub fn wrap_name(name: &str, width: u32) -> Vec<String> {
    // Pieces ending just after each break point.
    let mut pieces: Vec<String> = Vec::new();
    let mut piece = String::new();
    for c in name.chars() {
        piece.push(c);
        if c == ' ' || c == '-' {
            pieces.push(std::mem::take(&mut piece));
        }
    }
    if !piece.is_empty() {
        pieces.push(piece);
    }
    let fits = |s: &str| text_size(s.trim_end(), TICK_SIZE).0 <= width;
    let mut lines: Vec<String> = Vec::new();
    let mut line = String::new();
    for p in pieces {
        if !line.is_empty() && !fits(&format!("{line}{p}")) {
            lines.push(std::mem::take(&mut line).trim_end().to_owned());
        }
        line.push_str(&p);
    }
    if !line.is_empty() {
        lines.push(line.trim_end().to_owned());
    }
    lines
}

impl BarChart {
    /// The category names wrapped to the width of a group of bars, `plot_width` pixels across.
    fn wrapped(&self, plot_width: u32) -> Vec<Vec<String>> {
        let slot = plot_width / self.categories.len().max(1) as u32;
        self.categories
            .iter()
            .map(|c| wrap_name(c, slot.saturating_sub(6)))
            .collect()
    }
}

impl Chart for BarChart {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
        let (width, _) = root.dim_in_pixel();
        let right = 24;
        let legend: Vec<Series> = self
            .series
            .iter()
            .map(|s| Series::line(&s.label, s.color, 8, Vec::new()))
            .collect();
        let top = header(
            root,
            &self.title,
            &legend,
            (Y_LABEL_AREA + 10, width.saturating_sub(right)),
        )?;
        let names = self.wrapped(width.saturating_sub(Y_LABEL_AREA + 10 + right));
        let name_lines = names.iter().map(Vec::len).max().unwrap_or(1) as u32;
        let n = self.categories.len().max(1) as f64;
        // A category axis with no ticks: the names are drawn under the groups below.
        let x = Axis {
            label: self.category_label.clone(),
            min: 0.0,
            max: n,
            scale: Scale::Linear,
            ticks: Vec::new(),
        };
        let mut chart = ChartBuilder::on(root)
            .margin_top(top)
            .margin_right(right)
            .margin_bottom(6)
            .margin_left(10)
            .x_label_area_size(name_lines * NAME_LINE + 14 + LABEL_SIZE as u32 + 8)
            .y_label_area_size(Y_LABEL_AREA)
            .build_cartesian_2d(x.coord(), self.y.coord())?;
        draw_axes(&mut chart, (&x, &self.y), LABEL_SIZE, true)?;
        let base = self.y.position(self.y.min);
        let m = self.series.len().max(1) as f64;
        for (j, s) in self.series.iter().enumerate() {
            let bars = s.values.iter().enumerate().filter_map(|(i, &v)| {
                let shown = v.is_finite() && (self.y.scale == Scale::Linear || v > 0.0);
                shown.then(|| {
                    let left = i as f64 + (1.0 - GROUP_FILL) / 2.0 + GROUP_FILL * j as f64 / m;
                    let right = left + GROUP_FILL / m;
                    let top = self.y.position(v).min(self.y.position(self.y.max));
                    Rectangle::new([(left, base), (right, top)], s.color.filled())
                })
            });
            chart.draw_series(bars)?;
        }
        // The names, centred under their groups, from just below the axis down.
        let style = text_style(TICK_SIZE, INK).pos(Pos::new(HPos::Center, VPos::Top));
        for (i, lines) in names.iter().enumerate() {
            let (cx, cy) = chart.backend_coord(&(i as f64 + 0.5, base));
            for (k, line) in lines.iter().enumerate() {
                root.draw_text(line, &style, (cx, cy + 8 + (k as u32 * NAME_LINE) as i32))?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plot::{linear, render};

    #[test]
    fn long_names_wrap_after_hyphens_and_spaces() {
        let wide = text_size("narrow-lobes", TICK_SIZE).0;
        assert_eq!(wrap_name("narrow-lobes", wide + 1), ["narrow-lobes"]);
        assert_eq!(wrap_name("narrow-lobes", wide - 1), ["narrow-", "lobes"]);
        assert_eq!(wrap_name("a b c", 1), ["a", "b", "c"]);
        assert_eq!(wrap_name("unbreakable", 1), ["unbreakable"]);
    }

    /// Two series over three categories on a log axis: each bar is drawn in its colour, taller for the larger
    /// value, a value of 0 draws nothing, and every category name is in the SVG.
    #[test]
    fn bars_are_drawn_per_category_and_series_with_their_names() {
        let (red, blue) = (RGBColor(230, 20, 20), RGBColor(20, 20, 230));
        let chart = BarChart {
            title: "bars".to_owned(),
            category_label: "case".to_owned(),
            categories: vec!["control".into(), "thin-strands".into(), "1-spp".into()],
            y: Axis::log_covering("RMSE", 1e-3, 1.0),
            series: vec![
                Bars {
                    label: "red".into(),
                    color: red,
                    values: vec![0.01, 0.1, 0.0],
                },
                Bars {
                    label: "blue".into(),
                    color: blue,
                    values: vec![0.5, 0.002, 0.2],
                },
            ],
        };
        let figure = render(&chart, "bars", (600, 400)).unwrap();
        let image = &figure.image;
        // The height, in rows under the legend, of `color` in the column through the middle of bar `j` of
        // category `i` (the plotting area spans x = 94 to 576: the margin and value axis, and the right margin).
        let height = |color: RGBColor, i: usize, j: usize| {
            let f = (i as f64 + 0.1 + 0.4 * j as f64 + 0.2) / 3.0;
            let x = (94.0 + f * 482.0) as usize;
            (70..image.height)
                .filter(|&y| image.pixel(x, y) == linear(color))
                .count()
        };
        let r: Vec<usize> = (0..3).map(|i| height(red, i, 0)).collect();
        let b: Vec<usize> = (0..3).map(|i| height(blue, i, 1)).collect();
        assert!(r[0] > 20 && r[1] > r[0] && r[2] == 0, "red {r:?}");
        assert!(
            b[0] > b[2] && b[2] > b[1] && b[1] > 0,
            "0.5 > 0.2 > 0.002: blue {b:?}"
        );
        // A decade is the same height wherever it is: 0.01 → 0.1 as 0.001 (the axis' start) → 0.01 (±2 rows).
        assert!((r[1] - r[0]).abs_diff(r[0]) <= 2, "red {r:?}");
        for name in ["control", "thin-strands", "1-spp", "RMSE", "case"] {
            assert!(figure.svg.contains(name), "{name} missing from the svg");
        }
    }
}
