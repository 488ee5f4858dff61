//! The fits of every fixed configuration (err² = b² + v/n from two sample counts) and their table, which is also
//! the fits' cache.

use std::fmt::Write as _;

use crate::accel::CurveKind;
use crate::render::{Frame, RenderSettings, Request};
use crate::scene::ShadowMode;

use super::super::StudyError;
use super::measure::{Config, Fit, Yardstick};
use super::{FIT_SPP, FIXED_CONFIGS, FIXED_PATH_LENGTHS};

/// Renders every fixed configuration at [`FIT_SPP`] and fits err² = b² + v/n.
pub(super) fn fit_all(
    frames: &[Frame; 2],
    base: &RenderSettings,
    reference: &Yardstick,
    progress: &indicatif::ProgressBar,
) -> Result<Vec<Fit>, StudyError> {
    let frame_of = |c: CurveKind| &frames[usize::from(c == CurveKind::Flat)];
    let mut fits = Vec::new();
    for (curves, shadows, path_length) in configs() {
        let c = Config {
            curves,
            shadows,
            path_length,
        };
        let mut s = base.clone();
        s.shadows.mode = shadows;
        s.integrator.path_length = path_length;
        let frame = frame_of(curves);
        let mut e2 = [0.0; 2];
        let mut last = (0.0, 0.0);
        progress.set_message(c.name());
        for (k, &spp) in FIT_SPP.iter().enumerate() {
            progress.inc(1);
            s.film.spp = spp;
            let r = frame.render(Request::new(&s));
            let (image, stats) = (r.image, r.stats);
            e2[k] = reference.rel_rmse(&image)?.powi(2);
            last = (stats.seconds, stats.shadow_build_seconds);
        }
        let (n1, n2) = (f64::from(FIT_SPP[0]), f64::from(FIT_SPP[1]));
        let variance = ((e2[0] - e2[1]) / (1.0 / n1 - 1.0 / n2)).max(0.0);
        let bias2 = (e2[1] - variance / n2).max(0.0);
        fits.push(Fit {
            config: c,
            bias2,
            variance,
            seconds_per_spp: last.0 / n2,
            setup_seconds: last.1,
        });
    }
    Ok(fits)
}

/// The [`FIXED_CONFIGS`] fixed configurations, in the order of the fits' table.
pub(super) fn configs() -> impl Iterator<Item = (CurveKind, ShadowMode, u32)> {
    [CurveKind::Round, CurveKind::Flat]
        .into_iter()
        .flat_map(|c| {
            [ShadowMode::Raytraced, ShadowMode::DeepOpacity]
                .into_iter()
                .flat_map(move |s| FIXED_PATH_LENGTHS.map(move |p| (c, s, p)))
        })
}

/// The fits' table: `exact` writes b² and v in full (the cache, read back by [`parse_fits`]), otherwise rounded
/// for reading.
pub(super) fn fits_csv(fits: &[Fit], exact: bool) -> String {
    // Every digit (shortest round-trip form) for the cache, `decimals` places for reading.
    let number = |x: f64, decimals: usize| {
        if exact {
            format!("{x:e}")
        } else {
            format!("{x:.decimals$}")
        }
    };
    let mut csv = String::from("config,bias,variance_x_spp,seconds_per_spp,setup_seconds\n");
    for f in fits {
        let _ = writeln!(
            csv,
            "{},{},{},{},{}",
            f.config.name(),
            number(f.bias2.sqrt(), 5),
            number(f.variance, 5),
            number(f.seconds_per_spp, 4),
            number(f.setup_seconds, 3)
        );
    }
    csv
}

/// A cached fits table ([`fits_csv`] exact), `None` unless it lists all [`FIXED_CONFIGS`] configurations in order.
pub(super) fn parse_fits(text: &str) -> Option<Vec<Fit>> {
    let mut fits = Vec::new();
    for ((curves, shadows, path_length), line) in configs().zip(text.lines().skip(1)) {
        let config = Config {
            curves,
            shadows,
            path_length,
        };
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 5 || f[0] != config.name() {
            return None;
        }
        let num = |i: usize| f[i].parse::<f64>().ok().filter(|v| v.is_finite());
        let bias = num(1)?;
        fits.push(Fit {
            config,
            bias2: bias * bias,
            variance: num(2)?,
            seconds_per_spp: num(3)?,
            setup_seconds: num(4)?,
        });
    }
    (fits.len() == FIXED_CONFIGS).then_some(fits)
}
