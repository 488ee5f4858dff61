//! From points to conclusions: the per-variant summaries, the error-against-time curves and the equal-error,
//! equal-time and equal-setting read-outs (module docs of [`super`], "Read-outs"), and the references' checks.

use super::charts::{series_names, x_label};
use super::{Kind, Point, ReferenceRun, Stat, Summary};

/// Per reference: its estimated RMSE against a second reference and the smallest mean RMSE of its variants.
pub(super) fn reference_checks(
    kind: &Kind,
    summaries: &[Summary],
    runs: &[ReferenceRun],
) -> Vec<String> {
    kind.references
        .iter()
        .zip(runs)
        .enumerate()
        .filter_map(|(r, (reference, run))| {
            let noise = run.second_rmse?;
            let smallest = summaries
                .iter()
                .filter(|s| kind.variants[s.variant].reference == r)
                .map(|s| s.rmse.mean)
                .fold(f64::INFINITY, f64::min);
            Some(format!(
                "reference {}: RMSE against a second reference (other seeds) {noise:.2e}, {:.1}× below its \
                 variants' smallest mean RMSE {smallest:.2e}",
                reference.label,
                smallest / noise
            ))
        })
        .collect()
}

/// Per-variant mean and spread of `points`.
pub fn summarise(kind: &Kind, points: &[Point]) -> Vec<Summary> {
    (0..kind.variants.len())
        .filter_map(|i| {
            let ps: Vec<&Point> = points.iter().filter(|p| p.variant == i).collect();
            let first = ps.first()?;
            let stat =
                |f: &dyn Fn(&Point) -> f64| Stat::of(&ps.iter().map(|p| f(p)).collect::<Vec<_>>());
            Some(Summary {
                variant: i,
                seeds: ps.len(),
                setup_s: first.setup_s,
                render_s: stat(&|p| p.render_s),
                maps_s: stat(&|p| p.maps_s),
                map_bytes: ps.iter().map(|p| p.map_bytes).max().unwrap_or(0),
                rmse: stat(&|p| p.rmse),
                relmse: stat(&|p| p.relmse),
                rmse_shadowed: stat(&|p| p.rmse_shadowed),
                ssim: stat(&|p| p.ssim),
                fireflies: stat(&|p| p.fireflies as f64),
                non_finite: ps.iter().map(|p| p.non_finite).sum(),
                mean_diff: stat(&|p| p.mean_diff),
                peak_bytes: ps.iter().filter_map(|p| p.peak_bytes).max(),
            })
        })
        .collect()
}

/// The chart time of a summary: render, plus set-up when the kind says so.
pub(super) fn chart_time(kind: &Kind, s: &Summary) -> f64 {
    s.render_s.mean
        + if kind.time_includes_setup {
            s.setup_s
        } else {
            0.0
        }
}

/// The (time, RMSE) curve of `series`, sorted by time.
pub(super) fn curve(kind: &Kind, summaries: &[Summary], series: &str) -> Vec<(f64, f64)> {
    let mut c: Vec<(f64, f64)> = summaries
        .iter()
        .filter(|s| kind.variants[s.variant].series == series)
        .map(|s| (chart_time(kind, s), s.rmse.mean))
        .filter(|(t, e)| *t > 0.0 && *e > 0.0 && t.is_finite() && e.is_finite())
        .collect();
    c.sort_by(|a, b| a.0.total_cmp(&b.0));
    c
}

/// The time at which `curve` (sorted by time) first reaches `error`, interpolated in log–log; `None` if it does
/// not within its measured points, `Some(t0)` bounded above by its first point if it starts below.
pub fn time_to_reach(curve: &[(f64, f64)], error: f64) -> Option<(f64, bool)> {
    let first = curve.first()?;
    if first.1 <= error {
        return Some((first.0, true));
    }
    curve.windows(2).find_map(|w| {
        let ((t0, e0), (t1, e1)) = (w[0], w[1]);
        (e1 <= error && e0 > error).then(|| {
            let f = (error.ln() - e0.ln()) / (e1.ln() - e0.ln());
            ((t0.ln() + f * (t1.ln() - t0.ln())).exp(), false)
        })
    })
}

/// The error of `curve` at time `t`, interpolated in log–log; `None` outside its measured times.
pub fn error_at(curve: &[(f64, f64)], t: f64) -> Option<f64> {
    if let [(t0, e0)] = curve {
        return (*t0 == t).then_some(*e0);
    }
    curve.windows(2).find_map(|w| {
        let ((t0, e0), (t1, e1)) = (w[0], w[1]);
        (t0 <= t && t <= t1 && t1 > t0).then(|| {
            let f = (t.ln() - t0.ln()) / (t1.ln() - t0.ln());
            (e0.ln() + f * (e1.ln() - e0.ln())).exp()
        })
    })
}

/// The read-out lines of `kind` (see the module docs).
pub fn readouts(kind: &Kind, summaries: &[Summary]) -> Vec<String> {
    let mut out = Vec::new();
    for (a, b) in &kind.compare {
        let (ca, cb) = (curve(kind, summaries, a), curve(kind, summaries, b));
        let Some(&(tb, eb)) = cb.last() else { continue };
        let equal_error = match time_to_reach(&ca, eb) {
            Some((ta, bounded)) => {
                let ratio = tb / ta;
                let how = if ratio >= 1.0 {
                    format!("{}{ratio:.2}× less time", if bounded { "≥ " } else { "" })
                } else {
                    format!("{:.2}× more time", 1.0 / ratio)
                };
                format!("{a} reaches {b}'s RMSE {eb:.2e} ({tb:.3} s) in {how}")
            }
            None => format!(
                "{a} does not reach {b}'s RMSE {eb:.2e} in its measured range (best {:.2e})",
                ca.iter().map(|p| p.1).fold(f64::INFINITY, f64::min)
            ),
        };
        // Equal time: at the longest time both curves cover.
        let common = ca.last().map_or(0.0, |p| p.0).min(tb);
        let equal_time = match (error_at(&ca, common), error_at(&cb, common)) {
            (Some(ea), Some(e)) => format!(
                "; at equal time ({common:.3} s) its RMSE is {:.2}× {b}'s",
                ea / e
            ),
            _ => "; their times do not overlap".to_owned(),
        };
        // Equal setting: at the largest swept value both series measured (e.g. the same spp).
        let at_x = |series: &str, x: f64| {
            summaries.iter().find(|s| {
                let v = &kind.variants[s.variant];
                v.series == series && v.x == x
            })
        };
        let equal_setting = summaries
            .iter()
            .filter(|_| kind.equal_setting)
            .filter(|s| kind.variants[s.variant].series == *a)
            .map(|s| kind.variants[s.variant].x)
            .filter(|&x| at_x(b, x).is_some())
            .fold(None, |m: Option<f64>, x| Some(m.map_or(x, |m| m.max(x))))
            .and_then(|x| Some((x, at_x(a, x)?, at_x(b, x)?)))
            .map(|(x, sa, sb)| {
                format!(
                    "; at equal {} ({}) its RMSE is {:.2}× and its time {:.2}× {b}'s",
                    kind.x_label,
                    x_label(x),
                    sa.rmse.mean / sb.rmse.mean,
                    chart_time(kind, sa) / chart_time(kind, sb)
                )
            })
            .unwrap_or_default();
        out.push(equal_error + &equal_time + &equal_setting);
    }
    if kind.bias_readout {
        for name in series_names(kind) {
            let last = summaries
                .iter()
                .filter(|s| kind.variants[s.variant].series == name)
                .max_by(|a, b| {
                    kind.variants[a.variant]
                        .x
                        .total_cmp(&kind.variants[b.variant].x)
                });
            if let Some(s) = last {
                out.push(format!(
                    "{name}: image mean {:+.2} % (sd {:.2} %) of the reference's at {} ({}), RMSE {:.2e}",
                    100.0 * s.mean_diff.mean,
                    100.0 * s.mean_diff.sd,
                    x_label(kind.variants[s.variant].x),
                    kind.x_label,
                    s.rmse.mean
                ));
            }
        }
    }
    out
}
