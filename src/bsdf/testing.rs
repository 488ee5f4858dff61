//! The test battery every hair model runs (STYLE.md, "Tests beside the physics"): white furnace by quadrature,
//! pdf normalisation, sampled furnace, chi-square of sampled directions against the integrated pdf, reciprocity
//! and a finiteness sweep. Each model's tests call these with its own parameters.

use super::frame::{from_spherical, sin_cos_theta, theta_h_range};
use super::histogram::sampled_vs_analytic;
use super::{Bsdf, LobeValues};
use crate::util::stats::{chi_square, sidak};
use glam::{Vec3, Vec3A};
use rand::Rng;
use rand_pcg::Pcg32;
use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};

/// θ cells of the furnace quadrature: midpoint rule in θi, 0.25° apart, ≥ 4 nodes per σ of the narrowest lobe
/// tested (β = 0.5° ⇒ σ(θi) = 1°); the midpoint rule is spectrally accurate on Gaussians at that spacing.
const QUAD_THETA: usize = 720;
/// φ cells of the furnace quadrature: 1° apart (narrowest azimuthal lobe tested: γ = 5°).
const QUAD_PHI: usize = 360;
/// Samples of a chi-square test (pbrt-v4's harness uses 10⁶).
pub const CHI2_SAMPLES: usize = 1_000_000;
/// Histogram cells: 80 in sin θ by 160 in φ, as pbrt-v4.
pub const CHI2_BINS: (usize, usize) = (80, 160);
/// Cells expecting fewer counts than this are pooled (the χ² approximation needs ≥ 5 per cell).
const CHI2_MIN_EXPECTED: f64 = 5.0;
/// Family-wise significance of each chi-square battery, Šidák-corrected over its θo.
pub const CHI2_ALPHA: f64 = 0.01;
/// Samples of a sampled-furnace estimate: with weights of relative spread ≤ 3 the standard error is ≤ 0.3%.
pub const FURNACE_SAMPLES: usize = 1_000_000;

/// The grid of the θh-distribution tests (Marschner's truncated Gaussians, ISHair's truncated Cauchys), as the
/// models form their arguments, in f64 from f32 angles: (centre α, width β, lo, hi) for 41 centres across
/// [−π/4, π/4], widths 1e-4 … π/2, and 61 views θr across [−π/2, π/2] with [lo, hi] = [`theta_h_range`]`(θr)`.
pub fn theta_h_grid() -> impl Iterator<Item = (f64, f64, f64, f64)> {
    const WIDTHS: [f32; 7] = [1e-4, 1e-3, 0.01, 0.1, 0.3, 1.0, FRAC_PI_2];
    (0..=40).flat_map(|i| {
        let centre = -FRAC_PI_4 + i as f32 * FRAC_PI_2 / 40.0;
        WIDTHS.into_iter().flat_map(move |width| {
            (0..=60).map(move |k| {
                let (lo, hi) = theta_h_range(-FRAC_PI_2 + k as f32 * PI / 60.0);
                (centre as f64, width as f64, lo, hi)
            })
        })
    })
}

/// The view direction of the chi-square tests: azimuth 18°, eight φ cells of 2.25°, so that the glint's support
/// edges (φr − φi = ±90°) fall on cell edges. Per-cell Gauss-Legendre integration is exact for smooth pdfs but
/// not across a jump; with φo = 17° those two columns' expected counts were off enough to pull p-values down to
/// ~0.005 at θo = 60°.
pub fn chi2_wo(theta_deg: f32) -> Vec3 {
    from_spherical(theta_deg.to_radians(), 18f32.to_radians())
}

/// The local view direction at longitudinal angle `theta_deg` (azimuth 17°, away from every symmetry axis).
pub fn wo_at(theta_deg: f32) -> Vec3 {
    from_spherical(theta_deg.to_radians(), 17f32.to_radians())
}

/// Calls `f(wi, dω·cos θi)` over the quadrature grid of the sphere (midpoint rule in θi and φi).
fn quadrature(mut f: impl FnMut(Vec3, f64)) {
    let (dt, dp) = (PI / QUAD_THETA as f32, 2.0 * PI / QUAD_PHI as f32);
    for i in 0..QUAD_THETA {
        let t = -FRAC_PI_2 + (i as f32 + 0.5) * dt;
        let cos_t = t.cos() as f64;
        for j in 0..QUAD_PHI {
            let p = -PI + (j as f32 + 0.5) * dp;
            // dω = cos θ dθ dφ.
            f(from_spherical(t, p), cos_t * dt as f64 * dp as f64);
        }
    }
}

/// The albedo ∫ f cos θi dωi of every lobe, RGB, by quadrature of [`Bsdf::eval_lobes`].
pub fn albedo<B: Bsdf + ?Sized>(model: &B, wo: Vec3) -> LobeValues {
    let mut acc = [[0.0f64; 3]; 5];
    quadrature(|wi, d_omega| {
        let l = model.eval_lobes(wo, wi);
        let w = d_omega * sin_cos_theta(wi).1 as f64;
        for (k, v) in [l.r, l.tt, l.trt, l.glint, l.diffuse].iter().enumerate() {
            for c in 0..3 {
                acc[k][c] += v[c] as f64 * w;
            }
        }
    });
    let v = |k: usize| Vec3A::new(acc[k][0] as f32, acc[k][1] as f32, acc[k][2] as f32);
    LobeValues {
        r: v(0),
        tt: v(1),
        trt: v(2),
        glint: v(3),
        diffuse: v(4),
    }
}

/// ∫ pdf dωi by quadrature.
pub fn pdf_integral<B: Bsdf + ?Sized>(model: &B, wo: Vec3) -> f64 {
    let mut s = 0.0;
    quadrature(|wi, d_omega| s += model.pdf(wo, wi) as f64 * d_omega);
    s
}

/// (mean, standard error) of the sample weights f cos θi / pdf, RGB summed to their mean channel.
pub fn sampled_furnace<B: Bsdf + ?Sized>(model: &B, wo: Vec3, n: usize, seed: u64) -> (f64, f64) {
    let mut rng = Pcg32::new(seed, 7);
    let (mut s, mut s2) = (0.0f64, 0.0f64);
    for _ in 0..n {
        if let Some(x) = model.sample(wo, rng.random()) {
            let w = (x.weight.x + x.weight.y + x.weight.z) as f64 / 3.0;
            s += w;
            s2 += w * w;
        }
    }
    let mean = s / n as f64;
    let var = (s2 / n as f64 - mean * mean).max(0.0);
    (mean, (var / n as f64).sqrt())
}

/// The mean channel of a colour.
pub fn mean(c: impl Into<Vec3>) -> f64 {
    let c = c.into();
    (c.x + c.y + c.z) as f64 / 3.0
}

/// Asserts the sampled furnace (mean of f cos θi / pdf) equals the quadrature furnace within `rel_tol`.
pub fn assert_sampled_furnace_matches<B: Bsdf + ?Sized>(
    name: &str,
    model: &B,
    wo: Vec3,
    rel_tol: f64,
) {
    let want = mean(albedo(model, wo).sum());
    let (got, se) = sampled_furnace(model, wo, FURNACE_SAMPLES, 11);
    assert!(
        se < 0.3 * rel_tol * want,
        "{name}: standard error {se} too large to test {rel_tol}"
    );
    assert!(
        (got - want).abs() <= rel_tol * want,
        "{name}: sampled furnace {got} ± {se} vs quadrature {want}"
    );
}

/// Runs the chi-square test of `model.sample` against `model.pdf` at each θo (degrees), with the family-wise
/// significance [`CHI2_ALPHA`] Šidák-corrected over them. On failure writes both histograms to
/// `target/chi2-<name>-<θo>.csv` and panics. Returns the p-values.
pub fn chi_square_battery<B: Bsdf + ?Sized>(
    name: &str,
    model: &B,
    theta_o_deg: &[f32],
) -> Vec<f64> {
    let alpha = sidak(CHI2_ALPHA, theta_o_deg.len());
    let mut ps = Vec::new();
    for (k, &t) in theta_o_deg.iter().enumerate() {
        let (obs, exp) =
            sampled_vs_analytic(model, chi2_wo(t), CHI2_SAMPLES, CHI2_BINS, 1000 + k as u64);
        let r = chi_square(&obs, &exp, CHI2_MIN_EXPECTED);
        if r.p_value < alpha || r.outside_support > 0.0 {
            let path = write_histograms(name, t, &obs, &exp);
            panic!("{name} θo {t}°: chi-square rejects the sampler: {r:?}; histograms in {path}");
        }
        ps.push(r.p_value);
    }
    ps
}

/// Writes `row,col,sampled,expected` for a failed chi-square test; returns the path.
fn write_histograms(name: &str, theta_o: f32, obs: &[f64], exp: &[f64]) -> String {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target");
    let file: String = name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
        .collect();
    let path = dir.join(format!("chi2-{file}-{theta_o}.csv"));
    let mut s = String::from("row,col,sampled,expected\n");
    for (i, (o, e)) in obs.iter().zip(exp).enumerate() {
        s += &format!("{},{},{o},{e}\n", i / CHI2_BINS.1, i % CHI2_BINS.1);
    }
    let _ = std::fs::create_dir_all(&dir);
    match std::fs::write(&path, s) {
        Ok(()) => path.display().to_string(),
        Err(e) => format!("(not written: {e})"),
    }
}

/// Pairs of directions over the sphere, avoiding the exact poles.
fn direction_pairs() -> Vec<(Vec3, Vec3)> {
    let mut v = Vec::new();
    let mut rng = Pcg32::new(5, 9);
    for _ in 0..2000 {
        let a = from_spherical(
            (rng.random::<f32>() - 0.5) * 3.1,
            (rng.random::<f32>() - 0.5) * (2.0 * PI - 0.01),
        );
        let b = from_spherical(
            (rng.random::<f32>() - 0.5) * 3.1,
            (rng.random::<f32>() - 0.5) * (2.0 * PI - 0.01),
        );
        v.push((a, b));
    }
    v
}

/// Asserts f(ωo, ωi) = f(ωi, ωo) over many pairs (relative 1e-4) if `reciprocal`, or that some pair differs by
/// more than 1% if not.
pub fn assert_reciprocal<B: Bsdf + ?Sized>(model: &B, reciprocal: bool) {
    let mut worst = 0.0f32;
    for (a, b) in direction_pairs() {
        let (fab, fba) = (model.eval(a, b), model.eval(b, a));
        let scale = fab.max_element().max(fba.max_element()).max(1e-12);
        worst = worst.max((fab - fba).abs().max_element() / scale);
    }
    if reciprocal {
        assert!(
            worst < 1e-4,
            "not reciprocal: worst relative difference {worst}"
        );
    } else {
        assert!(
            worst > 0.01,
            "expected a non-reciprocal model, worst relative difference {worst}"
        );
    }
}

/// Angles at and near the poles, the equator and ±π, radians, for the finiteness sweep.
fn sweep_angles() -> (Vec<f32>, Vec<f32>) {
    let d = |x: f32| x.to_radians();
    let thetas = vec![
        -FRAC_PI_2,
        d(-89.999),
        d(-89.0),
        d(-45.0),
        0.0,
        d(30.0),
        d(89.0),
        d(89.999),
        FRAC_PI_2,
    ];
    let phis = vec![
        -PI,
        d(-179.999),
        d(-90.0),
        0.0,
        d(1e-3),
        d(90.0),
        d(179.999),
        PI,
    ];
    (thetas, phis)
}

/// Asserts that what `sample` returns agrees with `eval` and `pdf` at the sampled direction. The samplers compute
/// f and the pdf along their own path, at the angles they drew ([`super::frame::Angles::from_sampled`]), while
/// `eval`/`pdf` see the returned direction: that one rounded to f32 (≈ 1e-7 rad away) and then measured with
/// [`super::frame::atan2`] (error < 6e-7 rad). So the sample's values must lie within the range `eval`/`pdf` take
/// over a 3 × 3 grid of directions spanning ±[`SAMPLE_NEIGHBOURHOOD`] rad around the returned one (which
/// contains the drawn direction as seen through that arctangent), widened by 1e-5 relative for the arithmetic.
/// For a smooth lobe of width β the range is ~1e-6/β relative: a wrong formula on the sampler's path shows far
/// beyond it.
pub fn assert_sample_consistent<B: Bsdf + ?Sized>(name: &str, model: &B) {
    let mut rng = Pcg32::new(77, 1);
    for _ in 0..2000 {
        let wo = crate::util::sampling::uniform_sphere(rng.random::<f32>(), rng.random::<f32>());
        let Some(s) = model.sample(wo, rng.random()) else {
            continue;
        };
        // An orthonormal pair perpendicular to wi.
        let a = if s.wi.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
        let a = a.reject_from(s.wi).normalize();
        let b = s.wi.cross(a);
        let (mut p_lo, mut p_hi) = (f32::INFINITY, 0.0f32);
        let (mut f_lo, mut f_hi) = (Vec3::INFINITY, Vec3::ZERO);
        for i in -1..=1 {
            for j in -1..=1 {
                let d = SAMPLE_NEIGHBOURHOOD;
                // The centre is the returned direction itself, not renormalised (a sharp lobe, Kajiya-Kay at
                // p = 10⁴, moves by 1e-3 relative with the rounding of a normalisation).
                let w = if i == 0 && j == 0 {
                    s.wi
                } else {
                    (s.wi + (i as f32 * d) * a + (j as f32 * d) * b).normalize()
                };
                let (f, p) = (model.eval(wo, w), model.pdf(wo, w));
                (p_lo, p_hi) = (p_lo.min(p), p_hi.max(p));
                (f_lo, f_hi) = (f_lo.min(f), f_hi.max(f));
            }
        }
        let within = |x: f32, lo: f32, hi: f32| {
            let tol = 1e-5 * hi.abs() + 1e-30;
            x >= lo - tol && x <= hi + tol
        };
        assert!(
            within(s.pdf, p_lo, p_hi),
            "{name}: sample pdf {} outside pdf()'s [{p_lo}, {p_hi}] near wi (wo {wo}, wi {})",
            s.pdf,
            s.wi
        );
        for c in 0..3 {
            assert!(
                within(s.f[c], f_lo[c], f_hi[c]),
                "{name}: sample f {} outside eval()'s [{f_lo}, {f_hi}] near wi (wo {wo}, wi {})",
                s.f,
                s.wi
            );
        }
    }
}

/// The half-width, in radians, of the neighbourhood of [`assert_sample_consistent`]: the rounding of the returned
/// direction (≈ 1e-7) plus [`super::frame::atan2`]'s error (< 6e-7), with margin.
pub const SAMPLE_NEIGHBOURHOOD: f32 = 2e-6;

/// Asserts eval, eval_lobes, pdf and sample are finite (pdf ≥ 0, f ≥ 0, sample pdf > 0) for directions at and
/// near θ = ±π/2 and φ = ±π, and for random numbers at 0 and just below 1.
pub fn assert_finite_sweep<B: Bsdf + ?Sized>(name: &str, model: &B) {
    let (thetas, phis) = sweep_angles();
    let dirs: Vec<Vec3> = thetas
        .iter()
        .flat_map(|&t| phis.iter().map(move |&p| from_spherical(t, p)))
        .collect();
    let us = [0.0, 1e-7, 0.25, 0.5, 0.999, 1.0 - f32::EPSILON / 2.0];
    assert_sample_consistent(name, model);
    for &wo in &dirs {
        for &wi in &dirs {
            let l = model.eval_lobes(wo, wi);
            for lobe in super::Lobe::ALL {
                let v = l.get(lobe);
                assert!(
                    v.is_finite() && v.min_element() >= 0.0,
                    "{name}: {lobe:?} = {v} for wo {wo} wi {wi}"
                );
            }
            let p = model.pdf(wo, wi);
            assert!(
                p.is_finite() && p >= 0.0,
                "{name}: pdf {p} for wo {wo} wi {wi}"
            );
        }
        for &a in &us {
            for &b in &us {
                for &c in &us {
                    if let Some(s) = model.sample(wo, [a, b, c]) {
                        let ok = s.wi.is_finite()
                            && (s.wi.length() - 1.0).abs() < 1e-4
                            && s.f.is_finite()
                            && s.pdf.is_finite()
                            && s.pdf > 0.0
                            && s.weight.is_finite();
                        assert!(ok, "{name}: sample {s:?} for wo {wo} u {:?}", [a, b, c]);
                    }
                }
            }
        }
    }
}
