//! Line charts straight from a CSV table ([`CsvChart`], behind `cuticle plot-csv`): one column against another,
//! one curve per value of a grouping column, a `+` and an optional label at each row's point. For measurements
//! taken outside the renderer (`scripts/equal-error.sh` times Cycles too), so their charts come from the CSV with
//! the same code and look as the studies' charts do.

use plotters::style::RGBColor;

use super::{hex, Axis, LineChart, Series};

/// A table could not be charted: a missing column, an unreadable CSV, nothing to draw.
#[derive(Debug, thiserror::Error)]
pub enum TableError {
    /// The CSV does not parse.
    #[error("cannot read the table: {0}")]
    Csv(#[from] csv::Error),
    /// A column named on the command line is not in the header.
    #[error("no column \"{name}\" in the table (columns: {columns})")]
    NoColumn {
        /// The requested column.
        name: String,
        /// The header, comma-separated.
        columns: String,
    },
    /// No row has a number in both the x and y columns (> 0 on a log axis).
    #[error("no row has a plottable ({x}, {y}) point")]
    Empty {
        /// The x column.
        x: String,
        /// The y column.
        y: String,
    },
}

/// What to draw from a table: column names, scales and texts.
#[derive(Debug, Clone, PartialEq)]
pub struct CsvChart {
    /// The horizontal column.
    pub x: String,
    /// The vertical column.
    pub y: String,
    /// One curve per distinct value of this column, in order of first appearance (one curve if `None`).
    pub by: Option<String>,
    /// The column whose value labels each point (none if `None`).
    pub point_label: Option<String>,
    /// Log10 horizontal axis (whole decades covering the points).
    pub log_x: bool,
    /// Log10 vertical axis.
    pub log_y: bool,
    /// The chart title.
    pub title: String,
    /// The axis titles (the column names if `None`).
    pub x_label: Option<String>,
    /// See `x_label`.
    pub y_label: Option<String>,
}

/// Curve colours, the studies' palette (Okabe & Ito's colour-blind-safe set).
const COLORS: [u32; 6] = [0x0072b2, 0xd55e00, 0x009e73, 0xe69f00, 0x56b4e9, 0xcc79a7];

impl CsvChart {
    /// The line chart of the CSV `text` (a header line, then rows). Rows whose x or y is empty, not a number, or
    /// ≤ 0 on a log axis are left out (e.g. the references of `equal-error.csv`, which have no error); points keep
    /// the rows' order.
    pub fn line_chart(&self, text: &str) -> Result<LineChart, TableError> {
        let mut reader = csv::Reader::from_reader(text.as_bytes());
        let header = reader.headers()?.clone();
        let column = |name: &str| {
            header
                .iter()
                .position(|h| h.trim() == name)
                .ok_or_else(|| TableError::NoColumn {
                    name: name.to_owned(),
                    columns: header.iter().collect::<Vec<_>>().join(","),
                })
        };
        let (xi, yi) = (column(&self.x)?, column(&self.y)?);
        let by = self.by.as_deref().map(column).transpose()?;
        let label = self.point_label.as_deref().map(column).transpose()?;
        let plottable = |v: f64, log: bool| v.is_finite() && (!log || v > 0.0);
        // One series per group, in order of first appearance.
        let mut groups: Vec<Series> = Vec::new();
        for record in reader.records() {
            let record = record?;
            let number = |i: usize| record.get(i).and_then(|s| s.trim().parse::<f64>().ok());
            let (Some(x), Some(y)) = (number(xi), number(yi)) else {
                continue;
            };
            if !(plottable(x, self.log_x) && plottable(y, self.log_y)) {
                continue;
            }
            let field = |i: Option<usize>| {
                i.and_then(|i| record.get(i))
                    .unwrap_or("")
                    .trim()
                    .to_owned()
            };
            let group = field(by);
            let k = match groups.iter().position(|g| g.label == group) {
                Some(k) => k,
                None => {
                    let color: RGBColor = hex(COLORS[groups.len() % COLORS.len()]);
                    groups.push(Series {
                        markers: true,
                        ..Series::line(&group, color, 2, Vec::new())
                    });
                    groups.len() - 1
                }
            };
            groups[k].points.push((x, y));
            groups[k].point_labels.push(field(label));
        }
        let all = || groups.iter().flat_map(|g| g.points.iter());
        if all().next().is_none() {
            return Err(TableError::Empty {
                x: self.x.clone(),
                y: self.y.clone(),
            });
        }
        let range = |f: fn(&(f64, f64)) -> f64| {
            all()
                .map(f)
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                    (lo.min(v), hi.max(v))
                })
        };
        let axis = |name: &str, text: &Option<String>, (lo, hi): (f64, f64), log: bool| {
            let text = text.as_deref().unwrap_or(name);
            if log {
                Axis::log_covering(text, lo, hi)
            } else {
                let pad = ((hi - lo) * 0.05).max(f64::EPSILON);
                Axis::linear_auto(text, lo - pad, hi + pad)
            }
        };
        Ok(LineChart {
            title: self.title.clone(),
            x: axis(&self.x, &self.x_label, range(|p| p.0), self.log_x),
            y: axis(&self.y, &self.y_label, range(|p| p.1), self.log_y),
            series: groups,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plot::{render, Scale};

    fn spec() -> CsvChart {
        CsvChart {
            x: "wall_s".to_owned(),
            y: "rmse".to_owned(),
            by: Some("renderer".to_owned()),
            point_label: Some("spp".to_owned()),
            log_x: true,
            log_y: true,
            title: "test".to_owned(),
            x_label: None,
            y_label: Some("RMSE".to_owned()),
        }
    }

    /// Rows without an error (the references) are left out, groups keep their order of appearance, and the log
    /// axes cover the points in whole decades.
    #[test]
    fn csv_rows_become_one_series_per_group() {
        let text = "renderer,spp,seed,wall_s,render_s,rmse\n\
                    a,1024,1000,300,290,\n\
                    b,1024,1000,200,190,\n\
                    a,4,1,2.5,1.2,0.2\n\
                    b,4,1,5,3,0.15\n\
                    a,16,2,6,4.5,0.05\n\
                    b,16,2,12,9,0.06\n";
        let chart = spec().line_chart(text).unwrap();
        let names: Vec<&str> = chart.series.iter().map(|s| s.label.as_str()).collect();
        assert_eq!(names, ["a", "b"]);
        assert_eq!(chart.series[0].points, [(2.5, 0.2), (6.0, 0.05)]);
        assert_eq!(chart.series[1].point_labels, ["4", "16"]);
        assert!(chart.series[0].markers);
        assert_ne!(chart.series[0].color, chart.series[1].color);
        assert_eq!(chart.x.scale, Scale::Log10);
        assert_eq!((chart.x.min, chart.x.max), (1.0, 100.0));
        assert_eq!((chart.y.min, chart.y.max), (0.01, 1.0));
        assert_eq!(
            (chart.x.label.as_str(), chart.y.label.as_str()),
            ("wall_s", "RMSE")
        );
        let figure = render(&chart, "csv", (480, 320)).unwrap();
        assert!(figure.svg.contains("RMSE") && figure.svg.contains("\nb\n"));
    }

    #[test]
    fn missing_columns_and_empty_tables_are_errors_naming_them() {
        let text = "renderer,wall_s,rmse\na,1,\n";
        let err = CsvChart {
            y: "error".to_owned(),
            ..spec()
        }
        .line_chart(text)
        .unwrap_err();
        assert!(err.to_string().contains("no column \"error\""), "{err}");
        let err = CsvChart {
            by: None,
            point_label: None,
            ..spec()
        }
        .line_chart(text)
        .unwrap_err();
        assert!(err.to_string().contains("no row"), "{err}");
    }
}
