//! The charts and the crops mosaic a kind writes (`<kind>-error-time`, `<kind>-time`, `<kind>-crops`): drawing,
//! apart from measuring.

use super::super::figures::{self, ChartSeries};
use super::super::StudyError;
use super::readouts::chart_time;
use super::run::Judge;
use super::{Kind, StudyConfig, Summary};
use crate::image::Image;
use crate::plot::{self, hex, Axis, BarChart, Bars, LineChart, Series, WithNotes};

/// Rows of crops: per series, its reference's crop then each variant at seed 0 in sweep order; one exposure for
/// every panel (the first reference crop's 99th percentile maps to 0.9). Top left: the whole first reference with
/// the window outlined.
pub(super) fn crops_mosaic(
    kind: &Kind,
    judges: &[Judge],
    (cx, cy, cs): (usize, usize, usize),
    crops: &[Option<Vec<glam::Vec3>>],
    config: &StudyConfig,
) -> Result<Image, StudyError> {
    let reference_crops = judges
        .iter()
        .map(|j| figures::crop(&j.reference, cx, cy, cs).map_err(StudyError::Config))
        .collect::<Result<Vec<_>, _>>()?;
    let exposure = figures::exposure(&reference_crops[0]);
    let mut rows = vec![vec![figures::Panel {
        label: "WHOLE IMAGE".into(),
        rgb: figures::overview(&judges[0].reference, cx, cy, cs, cs),
    }]];
    for name in series_names(kind) {
        let members: Vec<usize> = (0..kind.variants.len())
            .filter(|&i| kind.variants[i].series == name && crops[i].is_some())
            .collect();
        let Some(&first) = members.first() else {
            continue;
        };
        let r = kind.variants[first].reference;
        let mut row = vec![figures::Panel {
            label: format!("REFERENCE {} SPP", config.reference_spp),
            rgb: reference_crops[r].clone(),
        }];
        row.extend(members.iter().map(|&i| {
            figures::Panel {
                label: format!(
                    "{} {}",
                    kind.variants[i].series,
                    kind.x_name(kind.variants[i].x)
                )
                .to_uppercase(),
                rgb: crops[i].clone().unwrap_or_default(),
            }
        }));
        rows.push(row);
    }
    Ok(figures::mosaic(
        &format!(
            "{}: crop {cs}×{cs} at ({cx}, {cy}), seed 0, reference {} spp, exposure ×{exposure:.2}",
            kind.name, config.reference_spp
        ),
        &rows,
        cs,
        exposure,
    )?)
}

/// Colours of the series, in order (Okabe & Ito, then greys).
pub(super) fn color(i: usize) -> plotters::style::RGBColor {
    const C: [u32; 8] = [
        0x0072b2, 0xd55e00, 0x009e73, 0xcc79a7, 0xe69f00, 0x56b4e9, 0x555555, 0xf0e442,
    ];
    hex(C[i % C.len()])
}

/// Series names in order of first appearance.
pub(super) fn series_names(kind: &Kind) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for v in &kind.variants {
        if !names.contains(&v.series) {
            names.push(v.series.clone());
        }
    }
    names
}

/// A number as a point label: integers without decimals.
pub(super) fn x_label(x: f64) -> String {
    if x.fract() == 0.0 && x.abs() < 1e9 {
        format!("{}", x as i64)
    } else {
        format!("{x}")
    }
}

pub(super) fn error_time_figure(
    kind: &Kind,
    summaries: &[Summary],
    notes: &[String],
    caption: &str,
) -> Result<plot::Figure, StudyError> {
    let series: Vec<ChartSeries> = series_names(kind)
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let mut pts: Vec<figures::Point> = summaries
                .iter()
                .filter(|s| &kind.variants[s.variant].series == name)
                .map(|s| figures::Point {
                    x: chart_time(kind, s),
                    y: s.rmse.mean,
                    label: x_label(kind.variants[s.variant].x),
                })
                .collect();
            pts.sort_by(|a, b| a.x.total_cmp(&b.x));
            ChartSeries {
                label: name.clone(),
                color: color(i),
                points: pts,
            }
        })
        .collect();
    let time = if kind.time_includes_setup {
        "set-up + render time (s)"
    } else {
        "render time (s)"
    };
    let chart = WithNotes {
        chart: figures::error_time_line_chart(
            &format!("{}: RMSE vs time, {caption}", kind.name),
            time,
            "RMSE (mean over seeds)",
            &series,
        ),
        notes: notes.to_vec(),
    };
    let height = 640 + chart.extra_height();
    Ok(plot::render(
        &chart,
        &format!("{} error-time", kind.name),
        (960, height),
    )?)
}

pub(super) fn time_figure(
    kind: &Kind,
    summaries: &[Summary],
    caption: &str,
) -> Result<plot::Figure, StudyError> {
    let names = series_names(kind);
    let mut series = Vec::new();
    let (mut x_lo, mut x_hi, mut y_lo, mut y_hi) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
    for (i, name) in names.iter().enumerate() {
        let mut pts: Vec<(f64, f64)> = summaries
            .iter()
            .filter(|s| &kind.variants[s.variant].series == name)
            .map(|s| (kind.variants[s.variant].x, chart_time(kind, s)))
            .filter(|(x, y)| *x > 0.0 && *y > 0.0)
            .collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        for &(x, y) in &pts {
            (x_lo, x_hi, y_lo, y_hi) = (x_lo.min(x), x_hi.max(x), y_lo.min(y), y_hi.max(y));
        }
        series.push(Series {
            markers: true,
            ..Series::line(name, color(i), 2, pts)
        });
    }
    let chart = LineChart {
        title: format!("{}: time vs {}, {caption}", kind.name, kind.x_label),
        x: Axis::log_covering(&kind.x_label, x_lo, x_hi),
        y: Axis::log_covering("time (s, mean over seeds)", y_lo, y_hi),
        series,
    };
    Ok(plot::render(
        &chart,
        &format!("{} time", kind.name),
        (960, 640),
    )?)
}

/// A bar chart of `value` per category and series, for a kind whose variants are unrelated cases
/// ([`Kind::categories`]): a group per case, a bar per series, on a log axis covering every bar, `notes` under it.
pub(super) fn category_figure(
    kind: &Kind,
    summaries: &[Summary],
    (what, value): (&str, fn(&Kind, &Summary) -> f64),
    notes: &[String],
    caption: &str,
) -> Result<plot::Figure, StudyError> {
    let series: Vec<Bars> = series_names(kind)
        .iter()
        .enumerate()
        .map(|(i, name)| {
            let mut values = vec![f64::NAN; kind.categories.len()];
            for s in summaries {
                let v = &kind.variants[s.variant];
                let c = v.x - 1.0;
                if &v.series == name && c >= 0.0 && (c as usize) < values.len() {
                    values[c as usize] = value(kind, s);
                }
            }
            Bars {
                label: name.clone(),
                color: color(i),
                values,
            }
        })
        .collect();
    let (lo, hi) = series
        .iter()
        .flat_map(|s| s.values.iter().copied())
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    let chart = WithNotes {
        chart: BarChart {
            title: format!("{}: {what} per {}, {caption}", kind.name, kind.x_label),
            category_label: kind.x_label.clone(),
            categories: kind.categories.clone(),
            y: Axis::log_covering(
                &if what == "render time" {
                    "render time (s, mean over seeds)".to_owned()
                } else {
                    format!("{what} (mean over seeds)")
                },
                // Below the smallest value, so its bar has a height even when it is a power of ten.
                0.9 * lo,
                hi,
            ),
            series,
        },
        notes: notes.to_vec(),
    };
    let height = 640 + chart.extra_height();
    Ok(plot::render(
        &chart,
        &format!("{} {what}", kind.name),
        (960, height),
    )?)
}

/// The mean RMSE of a summary (the value of `<kind>-rmse`).
pub(super) fn rmse_of(_: &Kind, s: &Summary) -> f64 {
    s.rmse.mean
}
