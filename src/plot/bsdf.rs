//! `cuticle plot-bsdf`: lobe shapes like the thesis' figure 4 (Ou et al. 2012's longitudinal and azimuthal
//! lobes) and sampled-versus-analytic histograms, charted from the plain data of [`crate::bsdf::lobe_curves`] and
//! [`crate::bsdf::histogram`] ([`plot_figures`], [`write_plots`]).
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
//!   (sampled − analytic)/√analytic, with Pearson's χ² of the two ([`chi_square`]).
//!
//! **The f axis is logarithmic** (base 10, [`DECADES`] decades down from the power of ten above the curve's
//! maximum): the lobes of one model differ by orders of magnitude (ISHair's R against its glints, Marschner's
//! highlights against the diffuse floor), and a log axis keeps the weak ones and the tails readable; a lobe below
//! the axis leaves the chart through its bottom edge. The value plotted is the Rec. 709 luminance of each lobe's
//! RGB f (per steradian, fibre convention: see [`crate::bsdf`]). Charts carry their own text (titles, ticks,
//! legend) but not the model's name, which goes in the file name ([`write_plots`]).

use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::{
    hex, render, text_style, write_figure, Axis, Chart, ColorBar, Colormap, DrawResult, Figure,
    HeatMap, LineChart, PlotError, PolarChart, Series, INK, TICK_SIZE,
};
use crate::bsdf::frame::from_spherical;
use crate::bsdf::histogram::sampled_vs_analytic;
use crate::bsdf::lobe_curves::{azimuthal_lobes, longitudinal_lobes};
use crate::bsdf::{Bsdf, Lobe, LobeValues};
use crate::util::color::luminance;
use crate::util::stats::chi_square;

/// Decades of f the line and polar charts show below the power of ten above the maximum (10⁻⁴ of the peak at
/// least: enough for the diffuse floor under a highlight, not so much that the Gaussian tails fill the chart).
pub const DECADES: u32 = 4;
/// Points per curve: 0.25° steps in θi, 0.5° in φ, several per σ of the narrowest default lobe (β = 3.75°).
const CURVE_POINTS: usize = 721;
/// Decades of counts per cell the histogram colour scale spans below the fullest cell.
const HISTOGRAM_DECADES: f64 = 4.0;
/// The Pearson residual at the ends of the difference map's colour scale (±4σ: a cell past it is a defect,
/// not noise, at 3200 cells).
const RESIDUAL_RANGE: f64 = 4.0;
/// Cells expecting fewer counts are pooled for the χ² summary (the approximation needs ≥ 5 per cell; the same
/// value as the model tests).
const MIN_EXPECTED: f64 = 5.0;

/// What `cuticle plot-bsdf` draws. Angles in degrees, in the local hair frame (see [`crate::bsdf`]).
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

/// The figure stems, in the order drawn.
pub const STEMS: [&str; 4] = ["longitudinal", "azimuthal", "polar", "histogram"];

/// Draws the figures of `model` (see the [module docs](self)) and returns (file stem, figure) pairs in the order
/// of [`STEMS`], each `options.size`. Pure: prints nothing, writes nothing.
pub fn plot_figures(
    model: &dyn Bsdf,
    options: &PlotOptions,
) -> Result<Vec<(String, Figure)>, PlotError> {
    let size = options.size;
    let figures = [
        render(&longitudinal_chart(model, options), "longitudinal", size)?,
        render(&azimuthal_chart(model, options), "azimuthal", size)?,
        render(&polar_chart(model, options), "polar", size)?,
        render(&histogram_chart(model, options), "histogram", size)?,
    ];
    Ok(STEMS.iter().map(|s| s.to_string()).zip(figures).collect())
}

/// Writes [`plot_figures`] as `<dir>/<prefix>-<stem>.png` and `.svg` (`<stem>.png` if `prefix` is empty),
/// creating `dir` and its parents, and returns their paths in the order drawn, each PNG before its SVG.
pub fn write_plots(
    model: &dyn Bsdf,
    prefix: &str,
    dir: &Path,
    options: &PlotOptions,
) -> Result<Vec<PathBuf>, PlotError> {
    std::fs::create_dir_all(dir).map_err(|source| PlotError::Io {
        path: dir.to_path_buf(),
        context: "cannot create the plot directory".to_owned(),
        source,
    })?;
    let mut paths = Vec::with_capacity(2 * STEMS.len());
    for (stem, figure) in plot_figures(model, options)? {
        let name = if prefix.is_empty() {
            stem
        } else {
            format!("{prefix}-{stem}")
        };
        paths.extend(write_figure(&figure, dir, &name)?);
    }
    Ok(paths)
}

/// A lobe's curve colour (Okabe & Ito's colour-blind-safe palette).
fn lobe_color(lobe: Lobe) -> RGBColor {
    hex(match lobe {
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
    let curve = |value: &dyn Fn(&LobeValues) -> f32| -> Vec<(f64, f64)> {
        data.iter()
            .map(|(x, v)| (f64::from(x.to_degrees()), f64::from(value(v))))
            .collect()
    };
    let total = Series::line("total", hex(0xb0b0b0), 7, curve(&|v| luminance(v.sum())));
    let lobes = Lobe::ALL.into_iter().filter_map(|lobe| {
        let points = curve(&|v| luminance(v.get(lobe).into()));
        points
            .iter()
            .any(|p| p.1 > 0.0)
            .then(|| Series::line(lobe.name(), lobe_color(lobe), 2, points))
    });
    std::iter::once(total).chain(lobes).collect()
}

/// The largest y of `series` (0 if none is positive).
fn max_y(series: &[Series]) -> f64 {
    series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.1))
        .fold(0.0, f64::max)
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
        x: Axis::linear("φ = φr − φi (degrees)", -180.0, 180.0, 45.0),
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

/// The 2 × 2 histogram figure: sampled and analytic counts (top), their Pearson residual, and the colour scales
/// with a χ² summary (bottom).
#[derive(Debug, Clone, PartialEq)]
struct HistogramChart {
    /// Sampled, analytic, residual.
    maps: [HeatMap; 3],
    /// The count scale and the residual scale.
    bars: [ColorBar; 2],
    /// The summary under the colour bars.
    lines: Vec<String>,
}

/// Height of a colour bar with its ticks and label, pixels.
const BAR_HEIGHT: u32 = 80;
/// Line height of the histogram summary, pixels.
const SUMMARY_LINE: i32 = 19;

impl Chart for HistogramChart {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
        let panels = root.split_evenly((2, 2));
        for (map, panel) in self.maps.iter().zip(&panels) {
            map.draw(panel)?;
        }
        let key = &panels[3];
        let (bars, summary) = key.split_vertically(2 * BAR_HEIGHT + 12);
        let (first, second) = bars.split_vertically(BAR_HEIGHT + 6);
        self.bars[0].draw(&first.margin(6, 0, 0, 0))?;
        self.bars[1].draw(&second.margin(6, 0, 0, 0))?;
        let style = text_style(TICK_SIZE + 1.0, INK).pos(Pos::new(HPos::Left, VPos::Top));
        for (k, line) in self.lines.iter().enumerate() {
            summary.draw_text(line, &style, (16, 4 + k as i32 * SUMMARY_LINE))?;
        }
        Ok(())
    }
}

/// The histogram figure's data: both histograms, the residuals and the χ² summary.
fn histogram_chart(model: &dyn Bsdf, options: &PlotOptions) -> HistogramChart {
    // One piece: the sampled and expected counts, residuals and χ² share one binning.
    let (rows, cols) = (options.bins.0.max(1), options.bins.1.max(1));
    let wo = from_spherical(options.theta_o_deg.to_radians(), 0.0);
    let (sampled, expected) =
        sampled_vs_analytic(model, wo, options.samples, (rows, cols), options.seed);
    let log = |v: &f64| {
        if *v > 0.0 {
            v.log10()
        } else {
            f64::NEG_INFINITY
        }
    };
    // The colour scale: from the emptiest cell the pdf expects (at most HISTOGRAM_DECADES, at least one decade
    // below the fullest) to the fullest.
    let top = sampled
        .iter()
        .chain(&expected)
        .fold(1.0f64, |m, &v| m.max(v))
        .log10();
    let emptiest = expected
        .iter()
        .filter(|&&e| e > 0.0)
        .fold(f64::INFINITY, |m, &e| m.min(e));
    let bottom = emptiest.log10().clamp(top - HISTOGRAM_DECADES, top - 1.0);
    let range = (bottom.floor(), top);
    // Pearson residuals; a count where none is expected is off the scale.
    let residual: Vec<f64> = sampled
        .iter()
        .zip(&expected)
        .map(|(&s, &e)| {
            if e > 0.0 {
                (s - e) / e.sqrt()
            } else if s > 0.0 {
                f64::INFINITY
            } else {
                0.0
            }
        })
        .collect();
    let x = Axis::linear("φi (degrees)", -180.0, 180.0, 90.0);
    let y = Axis::linear("sin θi", -1.0, 1.0, 0.5);
    let map = |title: String, values: Vec<f64>, colormap, range| HeatMap {
        title,
        rows,
        cols,
        values,
        colormap,
        range,
        x: x.clone(),
        y: y.clone(),
    };
    let chi = chi_square(&sampled, &expected, MIN_EXPECTED);
    let n = options.samples.max(1) as f64;
    let p = if chi.p_value >= 1e-3 {
        format!("{:.3}", chi.p_value)
    } else {
        format!("{:.1e}", chi.p_value)
    };
    let lines = vec![
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
    HistogramChart {
        maps: [
            map(
                format!("sampled ({} samples)", options.samples),
                sampled.iter().map(log).collect(),
                Colormap::Viridis,
                range,
            ),
            map(
                "analytic (integrated pdf)".to_owned(),
                expected.iter().map(log).collect(),
                Colormap::Viridis,
                range,
            ),
            map(
                "residual (s − a) / √a".to_owned(),
                residual,
                Colormap::Diverging,
                (-RESIDUAL_RANGE, RESIDUAL_RANGE),
            ),
        ],
        bars: [
            ColorBar {
                colormap: Colormap::Viridis,
                axis: Axis::linear_auto("log10 count per cell", range.0, range.1),
            },
            ColorBar {
                colormap: Colormap::Diverging,
                axis: Axis::linear("pearson residual", -RESIDUAL_RANGE, RESIDUAL_RANGE, 2.0),
            },
        ],
        lines,
    }
}

#[cfg(test)]
mod tests {
    use super::super::linear;
    use super::*;
    use crate::bsdf::ishair::{IsHair, IsHairParams};
    use crate::bsdf::kajiya_kay::{KajiyaKay, KajiyaKayParams};
    use crate::bsdf::marschner::{Marschner, MarschnerParams};
    use crate::image::{self, Image};

    /// Small figures for fast tests: 20 000 samples in 10 × 20 cells (100 per cell on average).
    fn small() -> PlotOptions {
        PlotOptions {
            samples: 20_000,
            bins: (10, 20),
            size: (640, 400),
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
        let figures = plot_figures(&kk, &small()).unwrap();
        let stems: Vec<&str> = figures.iter().map(|(s, _)| s.as_str()).collect();
        assert_eq!(stems, STEMS);
        for (stem, figure) in &figures {
            let img = &figure.image;
            assert_eq!((img.width, img.height), (640, 400), "{stem}");
            assert_eq!(img.channels, ["R", "G", "B"], "{stem}");
            let white = img.data.chunks_exact(3).filter(|p| p == &[1.0; 3]).count();
            let drawn = img.width * img.height - white;
            assert!(
                drawn > img.width * img.height / 50,
                "{stem}: only {drawn} pixels drawn"
            );
            assert!(
                figure.svg.starts_with("<svg") && figure.svg.len() > 2000,
                "{stem}: svg of {} bytes",
                figure.svg.len()
            );
        }
    }

    /// The series are the lobes each model has, plus the total, and the colour of each lobe is on the chart.
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

        // Every lobe's colour is drawn: a legend swatch and its curve are well over 100 pixels.
        let figure = render(&a, "azimuthal", options.size).unwrap();
        for s in &a.series {
            let color = linear(s.color);
            let count = figure
                .image
                .data
                .chunks_exact(3)
                .filter(|p| *p == color)
                .count();
            assert!(count > 100, "{}: {count} pixels of its colour", s.label);
            assert!(
                figure.svg.contains(&format!("\n{}\n", s.label)),
                "{}",
                s.label
            );
        }
    }

    #[test]
    fn write_plots_creates_nonempty_pngs_and_svgs() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("plots");
        let options = small();
        for (name, model) in [
            ("marschner", &marschner() as &dyn Bsdf),
            ("ishair", &ishair() as &dyn Bsdf),
        ] {
            let paths = write_plots(model, name, &out, &options).unwrap();
            let expected: Vec<PathBuf> = STEMS
                .iter()
                .flat_map(|stem| ["png", "svg"].map(|ext| out.join(format!("{name}-{stem}.{ext}"))))
                .collect();
            assert_eq!(paths, expected);
            for path in &paths {
                let len = std::fs::metadata(path).unwrap().len();
                assert!(len > 1000, "{}: {len} bytes", path.display());
            }
            for png in paths.iter().step_by(2) {
                let back = image::read(png).unwrap();
                assert_eq!((back.width, back.height), options.size);
            }
        }
    }

    /// The sampled and analytic panels of an exact sampler look alike: over the middle of the two panels (cells
    /// only: same place in each), the mean colour difference is a few per cent of the colour map's span, while
    /// against another view direction's analytic panel it is several times larger (so the comparison can fail).
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
        let (w, h) = options.size;
        // Inside the cells of the top-left panel (the panels are w/2 × h/2; the axes take their left 20% and
        // bottom 26%, the title their top 18%).
        let (x0, x1, y0, y1) = (w / 2 * 3 / 10, w / 2 * 95 / 100, h / 2 / 4, h / 2 * 7 / 10);
        let mean_diff = |a: &Image, b: &Image| {
            let (mut sum, mut n) = (0.0, 0);
            for y in y0..y1 {
                for x in x0..x1 {
                    let p = a.pixel(x, y);
                    let q = b.pixel(x + w / 2, y);
                    sum += p.iter().zip(q).map(|(p, q)| (p - q).abs()).sum::<f32>() / 3.0;
                    n += 1;
                }
            }
            sum / n as f32
        };
        let model = ishair();
        let draw = |options: &PlotOptions| {
            render(&histogram_chart(&model, options), "histogram", (w, h))
                .unwrap()
                .image
        };
        let here = draw(&options);
        let there = draw(&PlotOptions {
            theta_o_deg: -45.0,
            ..options.clone()
        });
        let alike = mean_diff(&here, &here);
        let unlike = mean_diff(&here, &there);
        assert!(
            alike < ALIKE && unlike > 3.0 * ALIKE,
            "ishair θo 30° vs 30°: {alike}, vs −45°: {unlike}"
        );
    }
}
