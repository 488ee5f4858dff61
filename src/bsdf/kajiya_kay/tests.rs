//! The model's unit tests, apart because they outweigh the model itself.

use super::super::gaussian::TruncatedGaussian;
use super::super::lanes::{directions, InLanes, LANES};
use super::super::testing;
use super::*;
use glam::Vec3A;
use rand::Rng;
use rand_pcg::Pcg32;
use wide::f32x8;

/// Runs `check` on both forms of `m`: its scalar [`Bsdf`] (the generic code at f32) and its eight-lane form
/// ([`InLanes`]: the f32x8 code with the query in one lane).
fn both_forms(m: &KajiyaKay, mut check: impl FnMut(&str, &dyn Bsdf)) {
    check("scalar", m);
    check("lanes", &InLanes { model: m, h: 0.3 });
}

/// Deterministic stratified estimate of the albedo ∫ f cos θi dωi over the sphere.
fn albedo(m: &KajiyaKay, wo: Vec3) -> (Vec3, f32) {
    const N: usize = 400; // 400² cells: the Riemann sum of a smooth integrand converges to < 0.1%.
    let (mut d, mut s) = (Vec3::ZERO, 0.0);
    let t = Vec3::X;
    for i in 0..N {
        for j in 0..N {
            let z = -1.0 + 2.0 * (i as f32 + 0.5) / N as f32; // uniform in z = sin θ about the tangent
            let phi = std::f32::consts::TAU * (j as f32 + 0.5) / N as f32;
            let r = (1.0 - z * z).sqrt();
            let wi = Vec3::new(z, r * phi.cos(), r * phi.sin());
            let (fd, fs) = m.eval(t, wo, wi);
            let w = cos_theta(t, wi) * 4.0 * std::f32::consts::PI / (N * N) as f32;
            d += fd * w;
            s += fs * w;
        }
    }
    (d, s)
}

#[test]
fn diffuse_albedo_is_k_d() {
    let m = KajiyaKay::new(Vec3::new(0.2, 0.5, 0.9), 0.0, 10.0);
    let (d, _) = albedo(&m, Vec3::new(0.3, 0.95, 0.0).normalize());
    assert!((d - m.k_d).abs().max_element() < 2e-3, "{d}");
}

#[test]
fn specular_albedo_near_k_s_at_normal_incidence() {
    // Laplace approximation error for p = 60 is O(1/p): allow 5%.
    let m = KajiyaKay::new(Vec3::ZERO, 0.3, 60.0);
    let (_, s) = albedo(&m, Vec3::Y);
    assert!((s / 0.3 - 1.0).abs() < 0.05, "specular albedo {s}");
}

fn model(k_d: f32, k_s: f32, p: f32, balance: Balance, sampling: Sampling) -> KajiyaKay {
    KajiyaKay::from_params(KajiyaKayParams {
        k_d: Vec3::splat(k_d),
        k_s,
        p,
        balance,
        sampling,
    })
    .unwrap()
}

/// θo of the furnace and chi-square grids, degrees.
const THETA_O_DEG: [f32; 5] = [-80.0, -40.0, 0.0, 30.0, 75.0];

#[test]
fn white_furnace_diffuse_is_exactly_one() {
    // The diffuse term claims albedo k_d for every θo: k_d = 1 must give 1 within quadrature error.
    let m = model(1.0, 0.0, 60.0, Balance::Sum, Sampling::ExactPdf);
    both_forms(&m, |form, b| {
        for t in THETA_O_DEG {
            let a = testing::albedo(b, testing::wo_at(t)).diffuse;
            assert!(
                (a - Vec3A::ONE).abs().max_element() < 1e-3,
                "{form} θo {t}°: diffuse albedo {a}"
            );
        }
    });
}

#[test]
fn white_furnace_specular_measured() {
    // Kajiya-Kay's cone is normalised for θo = 0 and large p only. Over p ∈ {4 .. 400} and θo ∈ ±80° the
    // measured albedo (k_s = 1) spans [0.032, 0.997]; at large p it is cos²θo (checked at p = 400).
    let models =
        [4.0, 20.0, 60.0, 400.0].map(|p| (p, model(0.0, 1.0, p, Balance::Sum, Sampling::ExactPdf)));
    for form in ["scalar", "lanes"] {
        let (mut lo, mut hi) = (f32::MAX, f32::MIN);
        for (p, m) in &models {
            let lanes = InLanes { model: m, h: 0.3 };
            let b: &dyn Bsdf = if form == "scalar" { m } else { &lanes };
            for t in THETA_O_DEG {
                let a = testing::albedo(b, testing::wo_at(t)).r.x;
                lo = lo.min(a);
                hi = hi.max(a);
                if *p == 400.0 {
                    let want = t.to_radians().cos().powi(2);
                    assert!(
                        (a - want).abs() < 0.01,
                        "{form} p {p} θo {t}°: albedo {a}, cos²θo = {want}"
                    );
                }
                if t == 0.0 && *p >= 60.0 {
                    // Laplace's approximation is O(1/p) low: 0.98 at p = 60.
                    assert!(
                        (a - 1.0).abs() < 0.025,
                        "{form} p {p}: albedo at θo = 0 is {a}"
                    );
                }
            }
        }
        assert!(
            lo > 0.025 && lo < 0.04 && hi > 0.99 && hi <= 1.0,
            "{form}: range [{lo}, {hi}]"
        );
    }
}

#[test]
fn sampler_matches_pdf_chi_square() {
    for sampling in [Sampling::ExactPdf, Sampling::Uniform] {
        let m = model(0.5, 0.5, 30.0, Balance::Fresnel { eta: 1.55 }, sampling);
        both_forms(&m, |form, b| {
            testing::chi_square_battery(
                &format!("kajiya-kay {} {form}", sampling.name()),
                b,
                &THETA_O_DEG[1..],
            );
        });
    }
}

#[test]
fn pdf_integrates_to_one_and_sampled_furnace_matches() {
    for sampling in [Sampling::ExactPdf, Sampling::Uniform] {
        let m = model(0.6, 0.4, 20.0, Balance::User { specular: 0.5 }, sampling);
        both_forms(&m, |form, b| {
            for t in [-60.0, 0.0, 45.0] {
                let wo = testing::wo_at(t);
                let integral = testing::pdf_integral(b, wo);
                assert!(
                    (integral - 1.0).abs() < 2e-3,
                    "{form} {sampling:?} θo {t}°: ∫ pdf = {integral}"
                );
                testing::assert_sampled_furnace_matches(
                    &format!("kajiya-kay {form} {sampling:?} θo {t}°"),
                    b,
                    wo,
                    0.01,
                );
            }
        });
    }
}

#[test]
fn reciprocity_except_fresnel_balance() {
    let user = model(
        0.6,
        0.4,
        20.0,
        Balance::User { specular: 0.3 },
        Sampling::ExactPdf,
    );
    both_forms(&user, |_, b| testing::assert_reciprocal(b, true));
    // Fresnel balance weighs by θo only: not reciprocal, and the test must see it.
    let fresnel = model(
        0.6,
        0.4,
        20.0,
        Balance::Fresnel { eta: 1.55 },
        Sampling::ExactPdf,
    );
    both_forms(&fresnel, |_, b| testing::assert_reciprocal(b, false));
}

#[test]
fn finite_everywhere() {
    for p in [1.0, 60.0, 1e4] {
        for sampling in [Sampling::ExactPdf, Sampling::Uniform] {
            let m = model(0.5, 0.5, p, Balance::Fresnel { eta: 1.55 }, sampling);
            both_forms(&m, |form, b| {
                testing::assert_finite_sweep(&format!("kajiya-kay {form} p {p} {sampling:?}"), b);
            });
        }
    }
}

#[test]
fn balance_weights_and_validation() {
    let user = model(
        1.0,
        1.0,
        20.0,
        Balance::User { specular: 0.25 },
        Sampling::ExactPdf,
    );
    let sum = model(1.0, 1.0, 20.0, Balance::Sum, Sampling::ExactPdf);
    let fresnel = model(
        1.0,
        1.0,
        20.0,
        Balance::Fresnel { eta: 1.55 },
        Sampling::ExactPdf,
    );
    for form in ["scalar", "lanes"] {
        let eval = |m: &KajiyaKay, wo: Vec3, wi: Vec3| {
            if form == "scalar" {
                m.eval_lobes(wo, wi)
            } else {
                InLanes { model: m, h: 0.3 }.eval_lobes(wo, wi)
            }
        };
        let (wo, wi) = (testing::wo_at(10.0), testing::wo_at(-5.0));
        let l = eval(&user, wo, wi);
        let plain = eval(&sum, wo, wi);
        assert!(
            (l.diffuse - plain.diffuse * 0.75).length() < 1e-6
                && (l.r - plain.r * 0.25).length() < 1e-6,
            "{form}"
        );
        // Fresnel: at normal view incidence w_s = F(1.55, 1) = 0.0465.
        let f = eval(&fresnel, Vec3::Y, wi);
        let plain = eval(&sum, Vec3::Y, wi);
        assert!(
            (f.r.x / plain.r.x - 0.0465).abs() < 1e-3,
            "{form}: {}",
            f.r.x / plain.r.x
        );
    }
    let bad = KajiyaKayParams {
        p: 0.5,
        ..Default::default()
    };
    assert_eq!(
        KajiyaKay::from_params(bad).unwrap_err().to_string(),
        "kajiya-kay: p must be >= 1 and finite, got 0.5"
    );
    let bad = KajiyaKayParams {
        sampling: Sampling::ClampAndFlip,
        ..Default::default()
    };
    assert!(KajiyaKay::from_params(bad)
        .unwrap_err()
        .to_string()
        .contains("published"));
    let bad = KajiyaKayParams {
        balance: Balance::User { specular: 1.5 },
        ..Default::default()
    };
    assert!(KajiyaKay::from_params(bad)
        .unwrap_err()
        .to_string()
        .contains("specular must be in [0, 1]"));
}

#[test]
fn legacy_eval_matches_trait_eval() {
    // The renderer's world-space eval and the trait's local eval agree (same frame: tangent = x), in both
    // forms.
    let m = KajiyaKay::new(Vec3::new(0.3, 0.2, 0.1), 0.3, 60.0);
    let (wo, wi) = (
        testing::wo_at(20.0),
        super::super::frame::from_spherical(-0.3, 2.0),
    );
    let (d, s) = m.eval(Vec3::X, wo, wi);
    both_forms(&m, |form, b| {
        let l = b.eval_lobes(wo, wi);
        assert!(
            (l.diffuse - Vec3A::from(d)).length() < 1e-7 && (l.r.x - s).abs() < 1e-6 * s.max(1.0),
            "{form}: {l:?} against ({d}, {s})"
        );
    });
}

#[test]
fn lobe_indices_follow_lobe_all() {
    for lobe in [Lobe::R, Lobe::Diffuse] {
        assert_eq!(Lobe::ALL[lobe_index(lobe) as usize], lobe);
    }
}

/// f32's machine epsilon, for the tolerances below.
const EPS: f64 = f32::EPSILON as f64;

/// `got` within `rel` of `want`, relative to the larger (or both below 1e-30).
fn close(got: f32, want: f32, rel: f64) -> bool {
    let (g, w) = (got as f64, want as f64);
    (g - w).abs() <= rel * g.abs().max(w.abs()) || g.abs().max(w.abs()) < 1e-30
}

/// Random unit directions, a quarter of them within 1e-3 rad of a pole (where the cone and its pdf are
/// steepest in θ).
fn direction(rng: &mut Pcg32) -> Vec3 {
    let w = crate::util::sampling::uniform_sphere(rng.random(), rng.random());
    if rng.random::<f32>() < 0.25 {
        let s = if rng.random::<bool>() { 1.0 } else { -1.0 };
        super::super::frame::from_spherical(
            s * (FRAC_PI_2 - 1e-3 * rng.random::<f32>()),
            rng.random_range(-PI..PI),
        )
    } else {
        w
    }
}

#[test]
fn eight_lanes_match_the_scalar_form_lane_by_lane() {
    // The f32x8 code against the f32 code, lane by lane, over random (ωo, ωi, u) for every sampling mode,
    // balance and a range of p. Both forms do the same arithmetic; only the transcendental functions differ
    // (`wide`'s polynomials against libm, each within a few ulp), so each value agrees to a few ulp times the
    // condition number of what it went through: the cone e^{p ln c} by 1 + |p ln c|; the pdf's Gaussian
    // e^{−p t²/2} of t = θi + θo (arctangents a few ulp apart in each angle) by 1 + p |t| (|θi| + |θo|).
    // Samples: the same lobe and ωi within 1e-5.
    let mut rng = Pcg32::new(41, 3);
    let (mut worst_r, mut worst_pdf, mut worst_wi, mut draws) = (0.0f64, 0.0f64, 0.0f32, 0);
    for sampling in [Sampling::ExactPdf, Sampling::Uniform] {
        for balance in [
            Balance::Sum,
            Balance::User { specular: 0.3 },
            Balance::Fresnel { eta: 1.55 },
        ] {
            for p in [1.0, 7.0, 60.0, 1e4] {
                let m = KajiyaKay::from_params(KajiyaKayParams {
                    k_d: Vec3::new(0.2, 0.5, 0.7),
                    k_s: 0.4,
                    p,
                    balance,
                    sampling,
                })
                .unwrap();
                for _ in 0..200 {
                    let wo: [Vec3; LANES] = std::array::from_fn(|_| direction(&mut rng));
                    let wi: [Vec3; LANES] = std::array::from_fn(|_| direction(&mut rng));
                    let u: [[f32; 3]; LANES] = std::array::from_fn(|_| rng.random());
                    let h = f32x8::new(std::array::from_fn(|_| rng.random_range(-1.0..1.0)));
                    let view = m.view(h, directions(&wo));
                    let eval = m.eval_view(&view, directions(&wi));
                    let u8 = std::array::from_fn(|c| f32x8::new(u.map(|u| u[c])));
                    let sample = m.sample_view(&view, u8);
                    for k in 0..LANES {
                        let name = format!(
                            "{sampling:?} {balance:?} p {p} lane {k}: wo {} wi {} u {:?}",
                            wo[k], wi[k], u[k]
                        );
                        let view1 = m.view(0.0, wo[k].to_array());
                        let eval1 = m.eval_view(&view1, wi[k].to_array());
                        let (lobes, pdf) = eval.lane(k);
                        let (lobes1, pdf1) = eval1.lane(0);
                        assert_eq!(lobes.diffuse, lobes1.diffuse, "{name}");
                        assert_eq!(lobes.tt + lobes.trt + lobes.glint, Vec3A::ZERO);
                        let (so, co) = super::super::frame::sin_cos_theta(wo[k]);
                        let (si, ci) = super::super::frame::sin_cos_theta(wi[k]);
                        let c = (ci as f64 * co as f64 - si as f64 * so as f64).max(1e-300);
                        let r_cond = 1.0 + (p as f64 * c.ln()).abs();
                        for ch in 0..3 {
                            assert!(
                                close(lobes.r[ch], lobes1.r[ch], 4.0 * EPS * r_cond),
                                "{name}: R {} against {}",
                                lobes.r,
                                lobes1.r
                            );
                        }
                        if lobes1.r.x > 1e-30 {
                            let e = (lobes.r.x as f64 / lobes1.r.x as f64 - 1.0).abs();
                            worst_r = worst_r.max(e / (EPS * r_cond));
                        }
                        let (to, ti) = ((so as f64).atan2(co as f64), (si as f64).atan2(ci as f64));
                        let pdf_cond = 1.0 + p as f64 * (to + ti).abs() * (to.abs() + ti.abs());
                        assert!(
                            close(pdf, pdf1, 4.0 * EPS * pdf_cond),
                            "{name}: pdf {pdf} against {pdf1}"
                        );
                        worst_pdf = worst_pdf
                            .max((pdf as f64 / pdf1 as f64 - 1.0).abs() / (EPS * pdf_cond));
                        // The sample: same lobe, same direction.
                        let sample1 = m.sample_view(&view1, u[k]);
                        assert_eq!(
                            sample.lobe.lane(k),
                            sample1.lobe,
                            "{name}: lobe {} against {}",
                            sample.lobe.lane(k),
                            sample1.lobe
                        );
                        let d = (sample.wi(k) - sample1.wi(0)).abs().max_element();
                        worst_wi = worst_wi.max(d);
                        assert!(
                            d < 1e-5,
                            "{name}: sampled wi {} against {}",
                            sample.wi(k),
                            sample1.wi(0)
                        );
                        assert_eq!(
                            sample.to_sample(k).is_some(),
                            sample1.to_sample(0).is_some(),
                            "{name}"
                        );
                        draws += 1;
                    }
                }
            }
        }
    }
    eprintln!(
        "{draws} lanes: worst R {worst_r:.2} ulp × (1 + |p ln c|), pdf {worst_pdf:.2} ulp × (1 + p|t|(|θi| + \
         |θo|)), sampled wi {worst_wi:e}"
    );
}

#[test]
fn cone_sampler_is_the_truncated_gaussian() {
    // The f32 cone distribution against the f64 TruncatedGaussian it replaces (N(0, 1/p) on [θo − π/2,
    // θo + π/2]), in both forms, for p from 1 to 10⁴ and θo across [−π/2, π/2] (ends included): the pdf within
    // 2e-6 relative plus the f32 rounding of its exponent (6e-8 per unit, 1e-7 allowed) where the density is
    // within e^{−20} of its peak, and the sampler's value at each CDF level within 2e-6 in CDF level
    // (|t32 − t64| · pdf).
    let (mut worst_pdf, mut worst_level) = (0.0f64, 0.0f64);
    for p in [1.0f32, 4.0, 60.0, 1e3, 1e4] {
        let sqrt_p = p.sqrt();
        let thetas: Vec<f32> = (0..=40)
            .map(|i| (-FRAC_PI_2 + i as f32 * PI / 40.0).clamp(-FRAC_PI_2, FRAC_PI_2))
            .collect();
        for chunk in thetas.chunks(LANES) {
            let theta8 = f32x8::new(std::array::from_fn(|k| chunk[k.min(chunk.len() - 1)]));
            let cone8 = ConeSampler::new(theta8, sqrt_p);
            for (k, &theta_o) in chunk.iter().enumerate() {
                let cone1 = ConeSampler::new(theta_o, sqrt_p);
                let (lo, hi) = (theta_o - FRAC_PI_2, theta_o + FRAC_PI_2);
                let tg = TruncatedGaussian::new(0.0, 1.0 / (p as f64).sqrt(), lo as f64, hi as f64);
                let peak = tg.pdf(0.0);
                for j in 0..=200 {
                    let t = lo + (hi - lo) * j as f32 / 200.0;
                    let exact = tg.pdf(t as f64);
                    if exact == 0.0 || (peak / exact).ln() > 20.0 {
                        continue;
                    }
                    let e = 0.5 * p as f64 * (t as f64).powi(2);
                    for got in [cone1.pdf(t), cone8.pdf(f32x8::splat(t)).lane(k)] {
                        let err = (got as f64 / exact - 1.0).abs();
                        worst_pdf = worst_pdf.max(err);
                        assert!(
                            err < 2e-6 + 1e-7 * e,
                            "p {p} θo {theta_o} t {t}: pdf {got} against {exact}"
                        );
                    }
                }
                for j in 0..=100 {
                    let u = (j as f32 / 100.0).min(1.0 - f32::EPSILON / 2.0);
                    let t64 = tg.sample(u as f64);
                    for t32 in [cone1.sample(u), cone8.sample(f32x8::splat(u)).lane(k)] {
                        assert!((lo..=hi).contains(&t32), "p {p} θo {theta_o}: {t32}");
                        let level = (t32 as f64 - t64).abs() * tg.pdf(0.5 * (t32 as f64 + t64));
                        worst_level = worst_level.max(level);
                        assert!(
                            level < 2e-6,
                            "p {p} θo {theta_o} u {u}: sample {t32} against {t64}"
                        );
                    }
                }
            }
        }
    }
    eprintln!("worst pdf {worst_pdf:e}, worst CDF level {worst_level:e}");
}
