//! The CSV tables a kind writes (`<kind>.csv`, `<kind>-summary.csv`): their headers and one serialised row per
//! point or variant.

use serde::Serialize;

use super::{Kind, Point, Summary};

/// Header of `<kind>.csv`.
pub const POINT_HEADER: &str = "kind,series,method,settings,x,seed,setup_s,render_s,camera_rays,shadow_rays,material_rays,rmse,relmse,ssim,fireflies,non_finite,mean_diff,peak_mb,maps_s,map_mb,rmse_shadowed";
/// Header of `<kind>-summary.csv`.
pub const SUMMARY_HEADER: &str = "kind,series,method,settings,x,seeds,setup_s,render_s,render_s_sd,rmse,rmse_sd,relmse,relmse_sd,ssim,ssim_sd,fireflies,fireflies_sd,non_finite,mean_diff,mean_diff_sd,peak_mb,maps_s,map_mb,rmse_shadowed,rmse_shadowed_sd";

#[derive(Serialize)]
pub(super) struct PointRow<'a> {
    kind: &'a str,
    series: &'a str,
    method: &'a str,
    settings: &'a str,
    x: f64,
    seed: u32,
    setup_s: String,
    render_s: String,
    camera_rays: u64,
    shadow_rays: u64,
    material_rays: u64,
    rmse: String,
    relmse: String,
    ssim: String,
    fireflies: usize,
    non_finite: usize,
    mean_diff: String,
    peak_mb: Option<String>,
    maps_s: String,
    map_mb: String,
    rmse_shadowed: String,
}

#[derive(Serialize)]
pub(super) struct SummaryRow<'a> {
    kind: &'a str,
    series: &'a str,
    method: &'a str,
    settings: &'a str,
    x: f64,
    seeds: usize,
    setup_s: String,
    render_s: String,
    render_s_sd: String,
    rmse: String,
    rmse_sd: String,
    relmse: String,
    relmse_sd: String,
    ssim: String,
    ssim_sd: String,
    fireflies: String,
    fireflies_sd: String,
    non_finite: usize,
    mean_diff: String,
    mean_diff_sd: String,
    peak_mb: Option<String>,
    maps_s: String,
    map_mb: String,
    rmse_shadowed: String,
    rmse_shadowed_sd: String,
}

pub(super) fn sci(x: f64) -> String {
    format!("{x:.6e}")
}

pub(super) fn mb(b: Option<u64>) -> Option<String> {
    b.map(|b| format!("{:.1}", b as f64 / 1e6))
}

/// The CSV text `writer` holds.
pub(crate) fn finish_csv(writer: csv::Writer<Vec<u8>>) -> Result<String, csv::Error> {
    let bytes = writer.into_inner().map_err(|e| e.into_error())?;
    String::from_utf8(bytes)
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, e).into())
}

/// `<kind>.csv` ([`POINT_HEADER`]).
pub fn points_csv(kind: &Kind, points: &[Point]) -> Result<String, csv::Error> {
    let mut w = csv::Writer::from_writer(Vec::new());
    if points.is_empty() {
        w.write_record(POINT_HEADER.split(','))?;
    }
    for p in points {
        let v = &kind.variants[p.variant];
        w.serialize(PointRow {
            kind: &kind.name,
            series: &v.series,
            method: &v.method,
            settings: &v.settings,
            x: v.x,
            seed: p.seed,
            setup_s: format!("{:.4}", p.setup_s),
            render_s: format!("{:.4}", p.render_s),
            camera_rays: p.camera_rays,
            shadow_rays: p.shadow_rays,
            material_rays: p.material_rays,
            rmse: sci(p.rmse),
            relmse: sci(p.relmse),
            ssim: format!("{:.6}", p.ssim),
            fireflies: p.fireflies,
            non_finite: p.non_finite,
            mean_diff: sci(p.mean_diff),
            peak_mb: mb(p.peak_bytes),
            maps_s: format!("{:.4}", p.maps_s),
            map_mb: format!("{:.3}", p.map_bytes as f64 / 1e6),
            rmse_shadowed: sci(p.rmse_shadowed),
        })?;
    }
    finish_csv(w)
}

/// `<kind>-summary.csv` ([`SUMMARY_HEADER`]).
pub fn summary_csv(kind: &Kind, summaries: &[Summary]) -> Result<String, csv::Error> {
    let mut w = csv::Writer::from_writer(Vec::new());
    if summaries.is_empty() {
        w.write_record(SUMMARY_HEADER.split(','))?;
    }
    for s in summaries {
        let v = &kind.variants[s.variant];
        w.serialize(SummaryRow {
            kind: &kind.name,
            series: &v.series,
            method: &v.method,
            settings: &v.settings,
            x: v.x,
            seeds: s.seeds,
            setup_s: format!("{:.4}", s.setup_s),
            render_s: format!("{:.4}", s.render_s.mean),
            render_s_sd: format!("{:.4}", s.render_s.sd),
            rmse: sci(s.rmse.mean),
            rmse_sd: sci(s.rmse.sd),
            relmse: sci(s.relmse.mean),
            relmse_sd: sci(s.relmse.sd),
            ssim: format!("{:.6}", s.ssim.mean),
            ssim_sd: format!("{:.6}", s.ssim.sd),
            fireflies: format!("{:.2}", s.fireflies.mean),
            fireflies_sd: format!("{:.2}", s.fireflies.sd),
            non_finite: s.non_finite,
            mean_diff: sci(s.mean_diff.mean),
            mean_diff_sd: sci(s.mean_diff.sd),
            peak_mb: mb(s.peak_bytes),
            maps_s: format!("{:.4}", s.maps_s.mean),
            map_mb: format!("{:.3}", s.map_bytes as f64 / 1e6),
            rmse_shadowed: sci(s.rmse_shadowed.mean),
            rmse_shadowed_sd: sci(s.rmse_shadowed.sd),
        })?;
    }
    finish_csv(w)
}
