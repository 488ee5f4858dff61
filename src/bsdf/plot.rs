//! `cuticle plot-bsdf`: lobe shapes like the thesis' figure 4 (Ou et al. 2012's longitudinal and azimuthal
//! lobes) and sampled-versus-analytic histograms, first as plain data ([`longitudinal_lobes`],
//! [`azimuthal_lobes`], [`sampled_vs_analytic`]), then as charts drawn by [`super::chart`] ([`plot_images`],
//! [`write_plots`]).
//!
//! # What the figures show
//!
//! - **longitudinal**: f against θi at fixed θo and φ, one curve per lobe the model has (non-zero somewhere on the
//!   curve) plus the total (the wide grey band under the lobes). f includes the azimuthal factor N(φ), so at the
//!   default φ = 0 ISHair's TT (a Gaussian around φ = 180°, γ_TT = 10°) is ~10⁻⁷⁰ and drops out; plot at
//!   φ = 180° to see it.
//! - **azimuthal**: f against φ = φr − φi at fixed θo, θi (θi = −θo puts θh = 0, every lobe's longitudinal peak
//!   up to its shift α).
//! - **polar**: the same curves around a circle (φ = 0, backward scattering, to the right; φ = ±180°, forward, to
//!   the left), radius on the same log scale.
//! - **histogram**: where `model.sample` sends 10⁶ directions against what [`Bsdf::pdf`] predicts (cells equal in
//!   solid angle, x = φi, y = sin θi), on a shared log colour scale, and their Pearson residual
//!   (sampled − analytic)/√analytic, with Pearson's χ² of the two ([`crate::util::stats::chi_square`]).
//!
//! **The f axis is logarithmic** (base 10, [`DECADES`] decades down from the power of ten above the curve's
//! maximum): the lobes of one model differ by orders of magnitude (ISHair's R against its glints, Marschner's
//! highlights against the diffuse floor), and a log axis keeps the weak ones and the tails readable; a lobe below
//! the axis leaves the chart through its bottom edge. The value plotted is the Rec. 709 luminance of each lobe's
//! RGB f (per steradian, fibre convention: see [`super`]). Charts carry their own text (titles, ticks, legend)
//! but not the model's name, which goes in the file name ([`write_plots`]).

use super::chart::{
    self, color_bar, srgb, Axis, Canvas, Colormap, HeatMap, LineChart, PolarChart, Rect, Series,
};
use super::frame::{from_spherical, phi};
use super::{Bsdf, Lobe, LobeValues};
use crate::image::{self, Image, ImageError};
use crate::util::color::luminance;
use crate::util::stats::chi_square;
use glam::Vec3;
use rand::Rng;
use rand_pcg::Pcg32;
use std::f32::consts::{FRAC_PI_2, PI};
use std::path::{Path, PathBuf};

/// f per lobe against θi ∈ [−π/2, π/2] (`n` ≥ 2 evenly spaced values, ends included), for a view direction at
/// longitudinal angle `theta_o` and a relative azimuth φ = φr − φi of `phi_rel` (radians).
pub fn longitudinal_lobes<B: Bsdf + ?Sized>(
    model: &B,
    theta_o: f32,
    phi_rel: f32,
    n: usize,
) -> Vec<(f32, LobeValues)> {
    let wo = from_spherical(theta_o, 0.0);
    (0..n)
        .map(|k| {
            let theta_i = -FRAC_PI_2 + PI * k as f32 / (n.max(2) - 1) as f32;
            (
                theta_i,
                model.eval_lobes(wo, from_spherical(theta_i, -phi_rel)),
            )
        })
        .collect()
}

/// f per lobe against the relative azimuth φ = φr − φi ∈ [−π, π] (`n` ≥ 2 values, ends included), at longitudinal
/// angles `theta_o` and `theta_i` (radians).
pub fn azimuthal_lobes<B: Bsdf + ?Sized>(
    model: &B,
    theta_o: f32,
    theta_i: f32,
    n: usize,
) -> Vec<(f32, LobeValues)> {
    let wo = from_spherical(theta_o, 0.0);
    (0..n)
        .map(|k| {
            let phi_rel = -PI + 2.0 * PI * k as f32 / (n.max(2) - 1) as f32;
            (
                phi_rel,
                model.eval_lobes(wo, from_spherical(theta_i, -phi_rel)),
            )
        })
        .collect()
}

/// Histograms of `n_samples` directions drawn by `model.sample(wo, ·)` (PCG32 seeded with `seed`) and of the
/// counts [`Bsdf::pdf`] predicts, over `bins` = (rows, columns) cells equal in solid angle: rows split
/// sin θi ∈ [−1, 1], columns split φi ∈ [−π, π] (local hair frame; row-major, row 0 at θi = −π/2, column 0 at
/// φi = −π). Returns (sampled, expected).
///
/// Expected counts integrate the pdf over each cell with 5 × 5 Gauss-Legendre nodes in (θ, φ) (the measure
/// cos θ dθ dφ; θ rather than sin θ so that a pdf ∝ 1/cos θi at the poles stays smooth in the variable
/// integrated). Samples the model declines (`None`) are not counted. The rule is exact for smooth pdfs only: put
/// a pdf's jumps on cell edges (ISHair's glints stop at φr − φi = ±π/2, so choose φo a multiple of 2π/columns).
pub fn sampled_vs_analytic<B: Bsdf + ?Sized>(
    model: &B,
    wo: Vec3,
    n_samples: usize,
    bins: (usize, usize),
    seed: u64,
) -> (Vec<f64>, Vec<f64>) {
    let (rows, cols) = (bins.0.max(1), bins.1.max(1));
    let mut sampled = vec![0.0; rows * cols];
    let mut rng = Pcg32::new(seed, 0x5eed);
    for _ in 0..n_samples {
        if let Some(s) = model.sample(wo, rng.random()) {
            let x = s.wi.x.clamp(-1.0, 1.0);
            let i = (((x + 1.0) * 0.5 * rows as f32) as usize).min(rows - 1);
            let j = (((phi(s.wi) + PI) / (2.0 * PI) * cols as f32) as usize).min(cols - 1);
            sampled[i * cols + j] += 1.0;
        }
    }
    // Gauss-Legendre, 5 nodes on [−1, 1].
    const NODES: [f64; 5] = [
        -0.906_179_845_938_664,
        -0.538_469_310_105_683_1,
        0.0,
        0.538_469_310_105_683_1,
        0.906_179_845_938_664,
    ];
    const WEIGHTS: [f64; 5] = [
        0.236_926_885_056_189_1,
        0.478_628_670_499_366_5,
        0.568_888_888_888_888_9,
        0.478_628_670_499_366_5,
        0.236_926_885_056_189_1,
    ];
    let mut expected = vec![0.0; rows * cols];
    for i in 0..rows {
        let t0 = (-1.0 + 2.0 * i as f64 / rows as f64).asin();
        let t1 = (-1.0 + 2.0 * (i + 1) as f64 / rows as f64)
            .clamp(-1.0, 1.0)
            .asin();
        for j in 0..cols {
            let p0 = -std::f64::consts::PI + std::f64::consts::TAU * j as f64 / cols as f64;
            let p1 = p0 + std::f64::consts::TAU / cols as f64;
            let mut sum = 0.0;
            for (a, wa) in NODES.iter().zip(WEIGHTS) {
                let t = 0.5 * (t0 + t1) + 0.5 * (t1 - t0) * a;
                for (b, wb) in NODES.iter().zip(WEIGHTS) {
                    let p = 0.5 * (p0 + p1) + 0.5 * (p1 - p0) * b;
                    let wi = from_spherical(t as f32, p as f32);
                    sum += wa * wb * model.pdf(wo, wi) as f64 * t.cos();
                }
            }
            expected[i * cols + j] = sum * 0.25 * (t1 - t0) * (p1 - p0) * n_samples as f64;
        }
    }
    (sampled, expected)
}

/// Decades of f the line and polar charts show below the power of ten above the maximum (10⁻⁴ of the peak at
/// least: enough for the diffuse floor under a highlight, not so much that the Gaussian tails fill the chart).
pub const DECADES: u32 = 4;
/// Points per curve: 0.25° steps in θi, 0.5° in φ, several per σ of the narrowest default lobe (β = 3.75°).
const CURVE_POINTS: usize = 721;
/// Decades of counts per cell the histogram colour scale spans below the fullest cell.
const HISTOGRAM_DECADES: f32 = 4.0;
/// The Pearson residual at the ends of the difference map's colour scale (±4σ: a cell past it is a defect,
/// not noise, at 3200 cells).
const RESIDUAL_RANGE: f32 = 4.0;
/// Cells expecting fewer counts are pooled for the χ² summary (the approximation needs ≥ 5 per cell; the same
/// value as the model tests).
const MIN_EXPECTED: f64 = 5.0;

/// What `cuticle plot-bsdf` draws. Angles in degrees, in the local hair frame (see [`super`]).
#[derive(Debug, Clone, PartialEq)]
pub struct PlotOptions {
    /// θo of every figure.
    pub theta_o_deg: f32,
    /// θi of the azimuthal figures.
    pub theta_i_deg: f32,
    /// φ = φr − φi of the longitudinal figure.
    pub phi_deg: f32,
    /// Directions drawn for the histogram.
    pub samples: usize,
    /// Histogram cells, (rows in sin θi, columns in φi).
    pub bins: (usize, usize),
    /// Seed of the sampler's random numbers.
    pub seed: u64,
    /// (width, height) of every image, pixels.
    pub size: (usize, usize),
}

impl Default for PlotOptions {
    /// θo = 30°, θi = −30° (so θh = 0), φ = 0; 10⁶ samples (pbrt-v4's chi-square count: ~300 per cell on
    /// average, so ±6% noise, and well under a second for every model here) in 40 × 80 cells (4.5° wide, so
    /// ISHair's glint cut-offs at φ = ±90° fall on cell edges); 800 × 500 pixels.
    fn default() -> Self {
        PlotOptions {
            theta_o_deg: 30.0,
            theta_i_deg: -30.0,
            phi_deg: 0.0,
            samples: 1_000_000,
            bins: (40, 80),
            seed: 1,
            size: (800, 500),
        }
    }
}

/// Draws the figures of `model` (see the [module docs](self)) and returns (file stem, image) pairs:
/// `longitudinal`, `azimuthal`, `polar` and `histogram`, each `options.size`, channels `R, G, B` linear, ready
/// for [`image::write`]. Pure: prints nothing, writes nothing.
pub fn plot_images(model: &dyn Bsdf, options: &PlotOptions) -> Vec<(String, Image)> {
    let (w, h) = options.size;
    vec![
        (
            "longitudinal".to_owned(),
            longitudinal_chart(model, options).render(w, h),
        ),
        (
            "azimuthal".to_owned(),
            azimuthal_chart(model, options).render(w, h),
        ),
        ("polar".to_owned(), polar_chart(model, options).render(w, h)),
        ("histogram".to_owned(), histogram_image(model, options)),
    ]
}

/// Writes [`plot_images`] as PNGs `<dir>/<prefix>-<stem>.png` (`<stem>.png` if `prefix` is empty), creating
/// `dir` and its parents, and returns their paths in the order drawn.
pub fn write_plots(
    model: &dyn Bsdf,
    prefix: &str,
    dir: &Path,
    options: &PlotOptions,
) -> Result<Vec<PathBuf>, ImageError> {
    std::fs::create_dir_all(dir).map_err(|source| ImageError::Io {
        path: dir.to_path_buf(),
        context: "cannot create the plot directory".to_owned(),
        source,
    })?;
    plot_images(model, options)
        .into_iter()
        .map(|(stem, img)| {
            let name = if prefix.is_empty() {
                format!("{stem}.png")
            } else {
                format!("{prefix}-{stem}.png")
            };
            let path = dir.join(name);
            image::write(&path, &img)?;
            Ok(path)
        })
        .collect()
}

/// A lobe's curve colour (Okabe & Ito's colour-blind-safe palette).
fn lobe_color(lobe: Lobe) -> Vec3 {
    srgb(match lobe {
        Lobe::R => 0xd55e00,
        Lobe::Tt => 0x0072b2,
        Lobe::Trt => 0x009e73,
        Lobe::Glint => 0xcc79a7,
        Lobe::Diffuse => 0xe69f00,
    })
}

/// The series of a curve of lobe values against `x` (degrees): the total first, as a wide light band, then one
/// line per lobe that is non-zero somewhere on the curve, in [`Lobe::ALL`] order. The y values are luminances.
fn lobe_series(data: &[(f32, LobeValues)]) -> Vec<Series> {
    let total = Series {
        label: "total".to_owned(),
        color: srgb(0xb0b0b0),
        width: 7.0,
        points: data
            .iter()
            .map(|(x, v)| (x.to_degrees(), luminance(v.sum())))
            .collect(),
    };
    let lobes = Lobe::ALL.into_iter().filter_map(|lobe| {
        let points: Vec<(f32, f32)> = data
            .iter()
            .map(|(x, v)| (x.to_degrees(), luminance(v.get(lobe))))
            .collect();
        points.iter().any(|p| p.1 > 0.0).then(|| Series {
            label: lobe.name().to_owned(),
            color: lobe_color(lobe),
            width: 2.0,
            points,
        })
    });
    std::iter::once(total).chain(lobes).collect()
}

/// The largest y of `series` (0 if none is positive).
fn max_y(series: &[Series]) -> f32 {
    series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.1))
        .fold(0.0, f32::max)
}

/// The y-axis label of the f charts.
const F_LABEL: &str = "f (luminance, 1/sr)";

/// f per lobe against θi (figure 4, left).
fn longitudinal_chart(model: &dyn Bsdf, options: &PlotOptions) -> LineChart {
    let data = longitudinal_lobes(
        model,
        options.theta_o_deg.to_radians(),
        options.phi_deg.to_radians(),
        CURVE_POINTS,
    );
    let series = lobe_series(&data);
    LineChart {
        title: format!(
            "longitudinal lobes: θo = {}°, φ = {}°",
            options.theta_o_deg, options.phi_deg
        ),
        x: Axis::linear("θi (degrees)", -90.0, 90.0, 30.0),
        y: Axis::log_decades(F_LABEL, max_y(&series), DECADES),
        series,
    }
}

/// The data and title of the azimuthal charts.
fn azimuthal_series(model: &dyn Bsdf, options: &PlotOptions) -> (Vec<Series>, String) {
    let data = azimuthal_lobes(
        model,
        options.theta_o_deg.to_radians(),
        options.theta_i_deg.to_radians(),
        CURVE_POINTS,
    );
    (
        lobe_series(&data),
        format!(
            "azimuthal lobes: θo = {}°, θi = {}°",
            options.theta_o_deg, options.theta_i_deg
        ),
    )
}

/// f per lobe against φ (figure 4, right).
fn azimuthal_chart(model: &dyn Bsdf, options: &PlotOptions) -> LineChart {
    let (series, title) = azimuthal_series(model, options);
    LineChart {
        title,
        x: Axis::linear("φ = φr - φi (degrees)", -180.0, 180.0, 45.0),
        y: Axis::log_decades(F_LABEL, max_y(&series), DECADES),
        series,
    }
}

/// The azimuthal curves around a circle.
fn polar_chart(model: &dyn Bsdf, options: &PlotOptions) -> PolarChart {
    let (mut series, title) = azimuthal_series(model, options);
    for s in &mut series {
        for p in &mut s.points {
            p.0 = p.0.to_radians();
        }
    }
    PolarChart {
        title,
        radius: Axis::log_decades(
            "radius: f (luminance, 1/sr), log scale",
            max_y(&series),
            DECADES,
        ),
        series,
    }
}

/// The 2 × 2 histogram figure: sampled and analytic counts (top), their Pearson residual and the colour scales
/// with a χ² summary (bottom).
fn histogram_image(model: &dyn Bsdf, options: &PlotOptions) -> Image {
    let (rows, cols) = (options.bins.0.max(1), options.bins.1.max(1));
    let wo = from_spherical(options.theta_o_deg.to_radians(), 0.0);
    let (sampled, expected) =
        sampled_vs_analytic(model, wo, options.samples, (rows, cols), options.seed);
    let log = |v: &f64| {
        if *v > 0.0 {
            v.log10() as f32
        } else {
            f32::NEG_INFINITY
        }
    };
    // The colour scale: from the emptiest cell the pdf expects (at most HISTOGRAM_DECADES, at least one decade
    // below the fullest) to the fullest.
    let top = sampled
        .iter()
        .chain(&expected)
        .fold(1.0f64, |m, &v| m.max(v))
        .log10() as f32;
    let emptiest = expected
        .iter()
        .filter(|&&e| e > 0.0)
        .fold(f64::INFINITY, |m, &e| m.min(e));
    let bottom = (emptiest.log10() as f32).clamp(top - HISTOGRAM_DECADES, top - 1.0);
    let range = (bottom.floor(), top);
    // Pearson residuals; a count where none is expected is off the scale.
    let residual: Vec<f32> = sampled
        .iter()
        .zip(&expected)
        .map(|(&s, &e)| {
            if e > 0.0 {
                ((s - e) / e.sqrt()) as f32
            } else if s > 0.0 {
                f32::INFINITY
            } else {
                0.0
            }
        })
        .collect();
    let x = Axis::linear("φi (degrees)", -180.0, 180.0, 90.0);
    let y = Axis::linear("sin θi", -1.0, 1.0, 0.5);
    let map = |title: String, values: Vec<f32>, colormap, range| HeatMap {
        title,
        rows,
        cols,
        values,
        colormap,
        range,
        x: x.clone(),
        y: y.clone(),
    };
    let (w, h) = options.size;
    let mut canvas = Canvas::new(w, h);
    let panel = |i: usize, j: usize| Rect {
        x0: j * w / 2,
        y0: i * h / 2 + 6,
        x1: (j + 1) * w / 2,
        y1: (i + 1) * h / 2,
    };
    map(
        format!("sampled ({} samples)", options.samples),
        sampled.iter().map(log).collect(),
        Colormap::Viridis,
        range,
    )
    .draw(&mut canvas, panel(0, 0));
    map(
        "analytic (integrated pdf)".to_owned(),
        expected.iter().map(log).collect(),
        Colormap::Viridis,
        range,
    )
    .draw(&mut canvas, panel(0, 1));
    map(
        "residual (s - a) / √a".to_owned(),
        residual,
        Colormap::Diverging,
        (-RESIDUAL_RANGE, RESIDUAL_RANGE),
    )
    .draw(&mut canvas, panel(1, 0));

    // Colour scales and the summary, bottom right.
    let key = panel(1, 1);
    let line = chart::TEXT_HEIGHT + 8;
    let bar_h = 16 + 2 * chart::TEXT_HEIGHT + 24;
    color_bar(
        &mut canvas,
        Rect {
            y1: key.y0 + bar_h,
            ..key
        },
        Colormap::Viridis,
        &Axis::linear_auto("log10 count per cell", range.0, range.1),
    );
    color_bar(
        &mut canvas,
        Rect {
            y0: key.y0 + bar_h + 8,
            y1: key.y0 + 2 * bar_h + 8,
            ..key
        },
        Colormap::Diverging,
        &Axis::linear("pearson residual", -RESIDUAL_RANGE, RESIDUAL_RANGE, 2.0),
    );
    let chi = chi_square(&sampled, &expected, MIN_EXPECTED);
    let n = options.samples.max(1) as f64;
    let p = if chi.p_value >= 1e-3 {
        format!("{:.3}", chi.p_value)
    } else {
        format!("{:.1e}", chi.p_value)
    };
    let lines = [
        format!(
            "θo = {}°, φo = 0°, seed {}",
            options.theta_o_deg, options.seed
        ),
        format!("χ² = {:.0}, dof {}, p = {p}", chi.statistic, chi.dof),
        format!(
            "mass: sampled {:.4}, pdf {:.4}",
            sampled.iter().sum::<f64>() / n,
            expected.iter().sum::<f64>() / n
        ),
        format!("outside support: {}", chi.outside_support),
    ];
    for (k, text) in lines.iter().enumerate() {
        canvas.text(
            key.x0 + 12,
            key.y0 + 2 * bar_h + 20 + k * line,
            text,
            chart::INK,
        );
    }
    canvas.into_image()
}

#[cfg(test)]
mod tests {
    use super::super::ishair::{IsHair, IsHairParams};
    use super::super::kajiya_kay::{KajiyaKay, KajiyaKayParams};
    use super::super::marschner::{Marschner, MarschnerParams};
    use super::*;

    /// Small figures for fast tests: 20 000 samples in 10 × 20 cells (100 per cell on average).
    fn small() -> PlotOptions {
        PlotOptions {
            samples: 20_000,
            bins: (10, 20),
            size: (480, 320),
            ..PlotOptions::default()
        }
    }

    fn ishair() -> IsHair {
        IsHair::new(IsHairParams::default()).unwrap()
    }

    fn marschner() -> Marschner {
        Marschner::new(MarschnerParams::default()).unwrap()
    }

    #[test]
    fn every_figure_has_the_requested_size_and_is_drawn_on() {
        let kk = KajiyaKay::from_params(KajiyaKayParams::default()).unwrap();
        let images = plot_images(&kk, &small());
        let stems: Vec<&str> = images.iter().map(|(s, _)| s.as_str()).collect();
        assert_eq!(stems, ["longitudinal", "azimuthal", "polar", "histogram"]);
        for (stem, img) in &images {
            assert_eq!((img.width, img.height), (480, 320), "{stem}");
            assert_eq!(img.channels, ["R", "G", "B"], "{stem}");
            let white = img.data.chunks_exact(3).filter(|p| p == &[1.0; 3]).count();
            let drawn = img.width * img.height - white;
            assert!(
                drawn > img.width * img.height / 50,
                "{stem}: only {drawn} pixels drawn"
            );
        }
    }

    /// The series are the lobes each model has, plus the total, and the colour of a lobe is on the chart.
    #[test]
    fn charts_have_one_series_per_nonzero_lobe() {
        let labels = |chart: &LineChart| -> Vec<String> {
            chart.series.iter().map(|s| s.label.clone()).collect()
        };
        let options = PlotOptions::default();
        let m = longitudinal_chart(&marschner(), &options);
        assert_eq!(labels(&m), ["total", "r", "trt", "diffuse"]);
        // At φ = 0, ISHair's TT (a Gaussian around φ = 180°) underflows to zero; the azimuthal curve has it.
        let i = longitudinal_chart(&ishair(), &options);
        assert_eq!(labels(&i), ["total", "r", "trt", "glint", "diffuse"]);
        let a = azimuthal_chart(&ishair(), &options);
        assert_eq!(labels(&a), ["total", "r", "tt", "trt", "glint", "diffuse"]);
        // The axis tops out at the power of ten above the total's peak.
        let peak = max_y(&a.series);
        assert!(a.y.max >= peak && a.y.max < 10.0 * peak, "{peak} {:?}", a.y);

        // The R lobe's peak: its colour is drawn at the pixel of its maximum.
        let (w, h) = options.size;
        let img = m.render(w, h);
        let r = &m.series[1];
        let &(x, y) = r.points.iter().max_by(|a, b| a.1.total_cmp(&b.1)).unwrap();
        let (px, py) = m.to_pixel(m.plot_area(w, h), x, y);
        let c = Vec3::from_slice(img.pixel(px as usize, py as usize));
        assert!(
            (c - lobe_color(Lobe::R)).length() < 1e-3,
            "pixel ({px}, {py}) at the R peak ({x}°, {y}) is {c}"
        );
    }

    #[test]
    fn write_plots_creates_nonempty_pngs() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("plots");
        let options = small();
        for (name, model) in [
            ("marschner", &marschner() as &dyn Bsdf),
            ("ishair", &ishair() as &dyn Bsdf),
        ] {
            let paths = write_plots(model, name, &out, &options).unwrap();
            assert_eq!(paths.len(), 4);
            for (path, stem) in
                paths
                    .iter()
                    .zip(["longitudinal", "azimuthal", "polar", "histogram"])
            {
                assert_eq!(path, &out.join(format!("{name}-{stem}.png")));
                let len = std::fs::metadata(path).unwrap().len();
                assert!(len > 1000, "{}: {len} bytes", path.display());
                let back = image::read(path).unwrap();
                assert_eq!((back.width, back.height), options.size);
            }
        }
    }

    /// The sampled and analytic panels of an exact sampler look alike: over the cells, the mean colour difference
    /// is a few per cent of the colour map's span, while against another view direction's analytic panel it is
    /// several times larger (so the comparison can fail).
    #[test]
    fn exact_sampler_histograms_look_alike() {
        /// Mean |Δ| per channel allowed between the two panels (noise of ~1000 counts per cell on a 4-decade log
        /// scale moves a colour by ≈ 0.5% of the map; 2% leaves room for the cells near the support's edge).
        const ALIKE: f32 = 0.02;
        let options = PlotOptions {
            samples: 200_000,
            bins: (10, 20),
            size: (640, 400),
            ..PlotOptions::default()
        };
        let mean_diff = |a: &Image, b: &Image| {
            let (w, h) = options.size;
            let left = HeatMap::cells(Rect {
                x0: 0,
                y0: 6,
                x1: w / 2,
                y1: h / 2,
            });
            let right = HeatMap::cells(Rect {
                x0: w / 2,
                y0: 6,
                x1: w,
                y1: h / 2,
            });
            let (mut sum, mut n) = (0.0, 0);
            for y in left.y0..left.y1 {
                for dx in 0..left.width() {
                    let p = Vec3::from_slice(a.pixel(left.x0 + dx, y));
                    let q = Vec3::from_slice(b.pixel(right.x0 + dx, y));
                    sum += (p - q).abs().element_sum() / 3.0;
                    n += 1;
                }
            }
            sum / n as f32
        };
        let model = ishair();
        let here = histogram_image(&model, &options);
        let there = histogram_image(
            &model,
            &PlotOptions {
                theta_o_deg: -45.0,
                ..options.clone()
            },
        );
        let alike = mean_diff(&here, &here);
        let unlike = mean_diff(&here, &there);
        assert!(
            alike < ALIKE && unlike > 3.0 * ALIKE,
            "ishair θo 30° vs 30°: {alike}, vs −45°: {unlike}"
        );
    }
}
