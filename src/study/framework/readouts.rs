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
            let how = match same_or_times(smallest / noise, 1) {
                None => "about equal to".to_owned(),
                Some(_) if smallest >= noise => format!("{:.1}× below", smallest / noise),
                Some(_) => format!("{:.1}× above", noise / smallest),
            };
            Some(format!(
                "reference {}: RMSE against a second reference (other seeds) {noise:.2e}, {how} its variants' \
                 smallest mean RMSE {smallest:.2e}",
                reference.label,
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

/// Whether a series name is a plural noun: it ends in s (`light samples`, `deep opacity layers`; no singular
/// name of a kind does).
fn plural(name: &str) -> bool {
    name.ends_with('s')
}

/// `name` with the possessive ending: `chiang uniform's`, `light samples'`.
pub(super) fn possessive(name: &str) -> String {
    if plural(name) {
        format!("{name}'")
    } else {
        format!("{name}'s")
    }
}

/// The form of a verb or pronoun that agrees with `name`: `singular` or `plural` (`reaches` / `reach`).
pub(super) fn agree<'a>(name: &str, singular: &'a str, plural_form: &'a str) -> &'a str {
    if plural(name) {
        plural_form
    } else {
        singular
    }
}

/// `None` when `ratio` is 1 within 1 % ("the same"), else the ratio written with `decimals` decimals and `×`.
pub(super) fn same_or_times(ratio: f64, decimals: usize) -> Option<String> {
    ((ratio - 1.0).abs() > 0.01).then(|| format!("{ratio:.decimals$}×"))
}

/// How long A takes to do what B did, from `speedup` = B's time ÷ A's: "N× less time" (N > 1), "N× more time",
/// or "the same time" within 1 %. `bounded`: A's time is an upper bound (it was already there at its first
/// point), so A takes at most that.
pub(super) fn time_words(speedup: f64, bounded: bool) -> String {
    let at_most = if bounded { "at most " } else { "" };
    match same_or_times(speedup, 2) {
        None => format!("{at_most}the same time"),
        Some(n) if speedup > 1.0 => format!("{}{n} less time", if bounded { "≥ " } else { "" }),
        Some(_) => format!("{at_most}{:.2}× more time", 1.0 / speedup),
    }
}

/// A relative difference in words, to two decimals of a percent: "1.46 % above `what`", "0.45 % below `what`", or
/// "the same as `what` within 0.01 %" when it rounds to zero.
pub(super) fn relative_words(difference: f64, what: &str) -> String {
    let percent = 100.0 * difference;
    if percent.abs() < 0.005 {
        format!("the same as {what} within 0.01 %")
    } else if percent > 0.0 {
        format!("{percent:.2} % above {what}")
    } else {
        format!("{:.2} % below {what}", -percent)
    }
}

/// `error` and `best` (> `error`) in scientific notation with the fewest digits (3 to 6 significant) that show
/// them apart, or `None` when they agree to 6 digits.
pub(super) fn apart(error: f64, best: f64) -> Option<(String, String)> {
    (2..=5).find_map(|decimals| {
        let (e, b) = (
            format!("{error:.decimals$e}"),
            format!("{best:.decimals$e}"),
        );
        (e != b).then_some((e, b))
    })
}

/// A setting in words: "8 samples per pixel" for a count ("samples per …" labels), else "radius scale 2" (the
/// label without a trailing parenthesis).
pub(super) fn setting_words(label: &str, x: &str) -> String {
    let label = match label.find(" (") {
        Some(i) if label.ends_with(')') => &label[..i],
        _ => label,
    };
    if label.starts_with("samples per") {
        format!("{x} {label}")
    } else {
        format!("{label} {x}")
    }
}

/// The read-out lines of `kind` (see the module docs).
pub fn readouts(kind: &Kind, summaries: &[Summary]) -> Vec<String> {
    let mut out = Vec::new();
    for (a, b) in &kind.compare {
        let (ca, cb) = (curve(kind, summaries, a), curve(kind, summaries, b));
        let Some(&(tb, eb)) = cb.last() else { continue };
        let bs = possessive(b);
        let its = agree(a, "its", "their");
        let equal_error = match time_to_reach(&ca, eb) {
            Some((ta, bounded)) => format!(
                "{a} {} {bs} RMSE {eb:.2e} ({tb:.3} s) in {}",
                agree(a, "reaches", "reach"),
                time_words(tb / ta, bounded)
            ),
            None => {
                let best = ca.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
                match apart(eb, best) {
                    Some((e, best)) => format!(
                        "{a} {} not reach {bs} RMSE {e} in {its} measured range (best {best})",
                        agree(a, "does", "do")
                    ),
                    None => format!(
                        "{a} just {} {bs} RMSE {eb:.2e} in {its} measured range",
                        agree(a, "misses", "miss")
                    ),
                }
            }
        };
        // Equal time: at the longest time both curves cover.
        let common = ca.last().map_or(0.0, |p| p.0).min(tb);
        let equal_time = match (error_at(&ca, common), error_at(&cb, common)) {
            (Some(ea), Some(e)) => match same_or_times(ea / e, 2) {
                Some(r) => format!("; at equal time ({common:.3} s) {its} RMSE is {r} {bs}"),
                None => format!("; at equal time ({common:.3} s) {its} RMSE is the same as {bs}"),
            },
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
                let rmse = same_or_times(sa.rmse.mean / sb.rmse.mean, 2);
                let time = same_or_times(chart_time(kind, sa) / chart_time(kind, sb), 2);
                let how = match (rmse, time) {
                    (None, None) => format!("{its} RMSE and time are the same as {bs}"),
                    (None, Some(t)) => {
                        format!("{its} RMSE is the same as {bs} and {its} time {t} {bs}")
                    }
                    (Some(r), None) => format!("{its} RMSE is {r} {bs} and {its} time the same"),
                    (Some(r), Some(t)) => format!("{its} RMSE is {r} and {its} time {t} {bs}"),
                };
                format!("; at {} {how}", setting_words(&kind.x_label, &x_label(x)))
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
                    "{name}: at {} the image mean is {} (sd {:.2} %), RMSE {:.2e}",
                    setting_words(&kind.x_label, &x_label(kind.variants[s.variant].x)),
                    relative_words(s.mean_diff.mean, "the reference's"),
                    100.0 * s.mean_diff.sd,
                    s.rmse.mean
                ));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn possessives_and_verbs_agree_with_plural_series_names() {
        assert_eq!(possessive("chiang uniform"), "chiang uniform's");
        assert_eq!(
            possessive("marschner light samples"),
            "marschner light samples'"
        );
        assert_eq!(agree("deep opacity layers", "does", "do"), "do");
        assert_eq!(agree("ray traced exact", "reaches", "reach"), "reaches");
    }

    #[test]
    fn times_read_as_the_same_within_one_percent_and_more_or_less_otherwise() {
        assert_eq!(time_words(1.0, false), "the same time");
        assert_eq!(time_words(1.009, false), "the same time");
        assert_eq!(time_words(0.995, true), "at most the same time");
        assert_eq!(time_words(1.5, false), "1.50× less time");
        assert_eq!(time_words(1.5, true), "≥ 1.50× less time");
        assert_eq!(time_words(0.5, false), "2.00× more time");
        assert_eq!(time_words(0.5, true), "at most 2.00× more time");
        assert_eq!(same_or_times(1.005, 2), None);
        assert_eq!(same_or_times(0.8, 2).as_deref(), Some("0.80×"));
    }

    #[test]
    fn a_missed_target_is_printed_with_the_digits_that_show_the_difference() {
        assert_eq!(
            apart(1.59e-2, 1.6e-2),
            Some(("1.59e-2".to_owned(), "1.60e-2".to_owned()))
        );
        assert_eq!(
            apart(3.3091e-2, 3.3132e-2),
            Some(("3.309e-2".to_owned(), "3.313e-2".to_owned()))
        );
        assert_eq!(apart(1.0e-2, 1.0e-2 * (1.0 + 1e-9)), None);
    }

    #[test]
    fn settings_and_relative_differences_read_as_words() {
        assert_eq!(
            setting_words("samples per pixel", "8"),
            "8 samples per pixel"
        );
        assert_eq!(
            setting_words("strand radius scale (width in pixels ∝)", "2"),
            "strand radius scale 2"
        );
        assert_eq!(relative_words(0.0146, "it"), "1.46 % above it");
        assert_eq!(relative_words(-0.0045, "it"), "0.45 % below it");
        assert_eq!(
            relative_words(-0.00002, "it"),
            "the same as it within 0.01 %"
        );
    }

    /// The read-out of two series whose errors and times are equal at every point says "the same", never "1.00×
    /// less", and names a plural series in the plural.
    #[test]
    fn readouts_of_equal_series_say_the_same() {
        use super::super::{Budget, Variant};
        let variant = |series: &str, x: f64| Variant {
            series: series.into(),
            method: series.into(),
            settings: String::new(),
            x,
            overrides: Vec::new(),
            reference: 0,
        };
        let kind = Kind {
            name: "k".into(),
            title: String::new(),
            x_label: "samples per pixel".into(),
            time_includes_setup: false,
            references: Vec::new(),
            variants: vec![
                variant("light samples", 1.0),
                variant("light samples", 2.0),
                variant("material samples", 1.0),
                variant("material samples", 2.0),
            ],
            compare: vec![("light samples".into(), "material samples".into())],
            bias_readout: false,
            equal_setting: true,
            budget: Budget::default(),
            differences: Vec::new(),
            categories: Vec::new(),
        };
        let summary = |variant: usize, x: f64| Summary {
            variant,
            seeds: 1,
            setup_s: 0.0,
            render_s: Stat { mean: x, sd: 0.0 },
            maps_s: Stat::default(),
            map_bytes: 0,
            rmse: Stat {
                mean: 0.1 / x,
                sd: 0.0,
            },
            relmse: Stat::default(),
            rmse_shadowed: Stat::default(),
            ssim: Stat::default(),
            fireflies: Stat::default(),
            non_finite: 0,
            mean_diff: Stat::default(),
            peak_bytes: None,
        };
        let summaries = [
            summary(0, 1.0),
            summary(1, 2.0),
            summary(2, 1.0),
            summary(3, 2.0),
        ];
        let lines = readouts(&kind, &summaries);
        assert_eq!(
            lines,
            ["light samples reach material samples' RMSE 5.00e-2 (2.000 s) in the same time; at equal time \
              (2.000 s) their RMSE is the same as material samples'; at 2 samples per pixel their RMSE and time are \
              the same as material samples'"]
        );
    }
}
