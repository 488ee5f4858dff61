//! The model's unit tests (Bessel accuracy, normalisation, white furnace, χ² of the sampler, reciprocity, the
//! offset h's sign, validation), apart because they outweigh the model itself.

use super::super::frame::{from_spherical, sin_cos_theta};
use super::super::testing::{self, mean};
use super::bessel::I0_SWITCH;
use super::*;
use crate::util::sampling::uniform_sphere;
use rand::Rng;
use rand_pcg::Pcg32;

/// The roughnesses of the white-furnace grid (0.1, 0.2, …, 0.9).
const BETAS: [f32; 9] = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9];
/// θo of the chi-square batteries, degrees.
const CHI2_THETA_O_DEG: [f32; 3] = [-60.0, 10.0, 70.0];

fn model(f: impl FnOnce(&mut ChiangParams)) -> Chiang {
    let mut p = ChiangParams::default();
    f(&mut p);
    Chiang::new(p).unwrap()
}

fn white(beta_m: f32, beta_n: f32) -> Chiang {
    model(|p| {
        p.sigma_a = Vec3::ZERO;
        p.beta_m = beta_m;
        p.beta_n = beta_n;
    })
}

/// I₀ₑ(x) = (1/π) ∫₀^π e^{x (cos t − 1)} dt by the trapezoid rule: exponentially convergent for this periodic
/// analytic integrand (error ~ I_{2N}(x)/I₀(x)), an independent reference for the series and the expansion.
fn i0e_reference(x: f64) -> f64 {
    const N: usize = 4000;
    let h = std::f64::consts::PI / N as f64;
    let mut s = 0.5 * (1.0 + (-2.0 * x).exp());
    for k in 1..N {
        s += (x * ((k as f64 * h).cos() - 1.0)).exp();
    }
    s / N as f64
}

#[test]
fn bessel_i0_accurate_over_the_whole_range() {
    let mut x = 1e-3;
    while x < 2e4 {
        for y in [x, I0_SWITCH * (1.0 - 1e-12), I0_SWITCH * (1.0 + 1e-12)] {
            let (got, want) = (i0e(y), i0e_reference(y));
            let rel = (got / want - 1.0).abs();
            assert!(rel < 1e-9, "i0e({y}) = {got}, reference {want}: {rel:e}");
            // ln I₀ = x + ln I₀ₑ where the reference has no cancellation (x ≥ 1).
            if y >= 1.0 {
                let want_log = y + want.ln();
                let rel_log = (log_i0(y) / want_log - 1.0).abs();
                assert!(rel_log < 1e-9, "log_i0({y}): {rel_log:e}");
            }
        }
        x *= 1.3;
    }
    // Tabulated (Abramowitz & Stegun Table 9.8): I₀(1), I₀(2), e^{−10} I₀(10).
    for (x, want) in [
        (1.0, 1.266_065_877_752_008),
        (2.0, 2.279_585_302_336_067),
        (10.0, 2_815.716_628_466_254),
    ] {
        assert!((i0(x) / want - 1.0).abs() < 1e-12, "I0({x}) = {}", i0(x));
    }
    // Small x: ln I₀(x) = x²/4 − x⁴/64 + x⁶/576 − …, relative.
    for x in [1e-6f64, 1e-3, 0.05, 0.3] {
        let want = x * x / 4.0 - x.powi(4) / 64.0 + x.powi(6) / 576.0 - 11.0 * x.powi(8) / 49152.0;
        let rel = (log_i0(x) / want - 1.0).abs();
        assert!(rel < 1e-6, "log_i0({x}) = {} vs {want}: {rel:e}", log_i0(x));
    }
}

#[test]
fn m_p_lanes_match_the_full_bessel_function_to_f32() {
    // The lanes cut both expansions to 16 terms at M_P_SWITCH (10); M_p from the 32-term i0e (within 1e-9 of
    // quadrature, test above) must agree within 3e-9 relative — a twentieth of an f32 ulp — for a's on both
    // sides of the switch, in every lane position, and not one f32 result may differ by more than an ulp.
    for v in [0.002f64, 0.02, 0.0846, 0.2, 0.5, 1.0] {
        let l = Longitudinal::new(v);
        for ti in -40..=40 {
            for to in -40..=40 {
                let sc_i = ((ti as f64 * 0.039).sin(), (ti as f64 * 0.039).cos());
                let sc_o = ((to as f64 * 0.0391).sin(), (to as f64 * 0.0391).cos().abs());
                let got = l.eval(sc_i, sc_o);
                let cc = sc_i.1 * sc_o.1;
                let want =
                    (l.log_norm + (cc - sc_i.0 * sc_o.0 - 1.0) * l.inv_v).exp() * i0e(cc * l.inv_v);
                if want > 1e-300 {
                    let rel = (got / want - 1.0).abs();
                    assert!(
                        rel < 3e-9,
                        "v {v} sc_i {sc_i:?} sc_o {sc_o:?}: {got} vs {want} ({rel:e})"
                    );
                    let (a, b) = ((got as f32).to_bits(), (want as f32).to_bits());
                    assert!(
                        a.abs_diff(b) <= 1,
                        "v {v}: f32 {} vs {}",
                        got as f32,
                        want as f32
                    );
                }
            }
        }
    }
}

#[test]
fn m_p_is_normalised_for_every_variance() {
    // ∫ M_p cos θi dθi = 1 (midpoint rule, 40000 nodes: ≥ 10 per standard deviation of the narrowest lobe,
    // βm = 0.01 at p = 1). The peers' truncated I₀ lose up to ~2 % near v ≈ 0.1.
    const N: usize = 40_000;
    for beta_m in [0.01f32, 0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 0.9, 1.0] {
        let v0 = longitudinal_variance(beta_m) as f64;
        for v in [0.25 * v0, v0, 4.0 * v0] {
            for theta_o in [-80f32, -30.0, 0.0, 45.0, 89.0] {
                let (so, co) = theta_o.to_radians().sin_cos();
                let h = std::f64::consts::PI / N as f64;
                let mut s = 0.0;
                for k in 0..N {
                    let t = -std::f64::consts::FRAC_PI_2 + (k as f64 + 0.5) * h;
                    let (si, ci) = (t as f32).sin_cos();
                    s += m_p(v, si, ci, so, co) * t.cos() * h;
                }
                assert!(
                    (s - 1.0).abs() < 1e-5,
                    "βm {beta_m} v {v} θo {theta_o}°: ∫ M_p cos θi dθi = {s}"
                );
            }
        }
    }
}

#[test]
fn white_furnace_by_quadrature() {
    // σa = 0: ∫ f cos θi dωi = Σ A_p = 1 exactly; the quadrature of `eval` must find it within 1e-3 for every
    // (βm, βn) of the grid at two pseudo-random (θo, h) each, with the paper's 2° tilt.
    let mut rng = Pcg32::new(14, 1);
    for beta_m in BETAS {
        for beta_n in BETAS {
            let m = white(beta_m, beta_n);
            // Two pseudo-random views, and the grazing corners for the narrowest lobes.
            let mut views: Vec<(f32, f32)> = (0..2)
                .map(|_| {
                    let theta_o = (rng.random::<f32>() - 0.5) * 170.0;
                    (theta_o, 2.0 * rng.random::<f32>() - 1.0)
                })
                .collect();
            if beta_m == 0.1 && beta_n == 0.1 {
                views.extend([(85.0, 0.99), (-85.0, -0.99), (0.0, 1.0)]);
            }
            for (theta_o, h) in views {
                let a = mean(testing::albedo(&m.at(h), testing::wo_at(theta_o)).sum());
                assert!(
                    (0.999..=1.001).contains(&a),
                    "βm {beta_m} βn {beta_n} θo {theta_o}° h {h}: albedo {a}"
                );
            }
        }
    }
}

#[test]
fn sample_weights_are_one_without_absorption() {
    // With σa = 0 the mixture pdf is exactly f cos θi, so each weight is 1 up to rounding.
    let mut rng = Pcg32::new(3, 3);
    let mut sampled = 0usize;
    for beta_m in BETAS {
        for beta_n in BETAS {
            let m = white(beta_m, beta_n);
            for _ in 0..500 {
                let fibre = m.at(2.0 * rng.random::<f32>() - 1.0);
                let wo = uniform_sphere(rng.random(), rng.random());
                let Some(s) = fibre.sample(wo, rng.random()) else {
                    continue;
                };
                for c in 0..3 {
                    let w = s.weight[c];
                    assert!(
                        w > 0.99 && w < 1.01,
                        "βm {beta_m} βn {beta_n} h {} wo {wo}: weight {}",
                        fibre.h(),
                        s.weight
                    );
                }
                sampled += 1;
            }
        }
    }
    assert!(sampled > 0, "no direction was sampled");
}

#[test]
fn sampled_furnace_matches_quadrature_with_absorption() {
    let m = model(|_| ());
    for (t, h) in [(-50.0, 0.3), (20.0, -0.9)] {
        testing::assert_sampled_furnace_matches(
            &format!("chiang default θo {t}° h {h}"),
            &m.at(h),
            testing::wo_at(t),
            0.01,
        );
    }
}

#[test]
fn sampler_chi_square() {
    for (beta_m, beta_n, h, alpha_deg) in [
        (0.3, 0.3, 0.0, 2.0),
        (0.1, 0.1, 0.5, 2.0),
        (0.9, 0.9, -0.8, 2.0),
        (0.2, 0.6, 0.95, -3.0),
    ] {
        let m = model(|p| {
            p.beta_m = beta_m;
            p.beta_n = beta_n;
            p.alpha = f32::to_radians(alpha_deg);
        });
        testing::chi_square_battery(
            &format!("chiang βm {beta_m} βn {beta_n} h {h} α {alpha_deg}°"),
            &m.at(h),
            &CHI2_THETA_O_DEG,
        );
    }
}

#[test]
fn uniform_sampling_furnace_and_chi_square() {
    // The uniform switch: a white furnace (σa = 0) by sampling equals 1 like the quadrature's, the sampled
    // furnace with absorption matches the quadrature, the pdf is 1/4π and integrates to 1, and χ² accepts
    // the sampled directions against it.
    let uniform = |f: &dyn Fn(&mut ChiangParams)| {
        model(|p| {
            f(p);
            p.sampling = Sampling::Uniform;
        })
    };
    // βm = βn = 0.7: at the default 0.3 uniform sampling's standard error with 10⁶ samples (0.6 %) is too
    // large to test 1 %.
    let white = uniform(&|p| {
        p.sigma_a = Vec3::ZERO;
        (p.beta_m, p.beta_n) = (0.7, 0.7);
    });
    let absorbing = uniform(&|p| (p.beta_m, p.beta_n) = (0.7, 0.7));
    for (t, h) in [(-50.0, 0.3), (20.0, -0.9)] {
        let wo = testing::wo_at(t);
        let (fibre, w) = (white.at(h), testing::albedo(&white.at(h), wo));
        assert!(
            (mean(w.sum()) - 1.0).abs() < 2e-3,
            "chiang uniform white furnace θo {t}° h {h}: {}",
            mean(w.sum())
        );
        let p = testing::pdf_integral(&fibre, wo);
        assert!((p - 1.0).abs() < 1e-3, "θo {t}° h {h}: ∫ pdf = {p}");
        let wi = uniform_sphere(0.3, 0.7);
        assert_eq!(fibre.pdf(wo, wi), UNIFORM_SPHERE_PDF);
        testing::assert_sampled_furnace_matches(
            &format!("chiang uniform white θo {t}° h {h}"),
            &fibre,
            wo,
            0.01,
        );
        testing::assert_sampled_furnace_matches(
            &format!("chiang uniform default θo {t}° h {h}"),
            &absorbing.at(h),
            wo,
            0.01,
        );
    }
    testing::chi_square_battery("chiang uniform", &absorbing.at(0.4), &CHI2_THETA_O_DEG[..2]);
    // Published (clamp-and-flip) sampling is Marschner's alone.
    let published = Chiang::new(ChiangParams {
        sampling: Sampling::ClampAndFlip,
        ..ChiangParams::default()
    });
    assert!(matches!(published, Err(BsdfError::Sampling { .. })));
}

#[test]
fn pdf_integrates_to_one() {
    for (beta_m, beta_n, h) in [(0.1, 0.1, 0.2), (0.5, 0.9, -0.7)] {
        let m = model(|p| {
            p.beta_m = beta_m;
            p.beta_n = beta_n;
        });
        for t in [-70.0, 0.0, 40.0] {
            let i = testing::pdf_integral(&m.at(h), testing::wo_at(t));
            assert!(
                (i - 1.0).abs() < 1e-3,
                "βm {beta_m} βn {beta_n} θo {t}°: ∫ pdf = {i}"
            );
        }
    }
}

#[test]
fn importance_and_uniform_sampling_agree() {
    // A smooth lighting L(ωi) = 1 + 0.8 x + 0.5 y² − 0.3 y z (> 0): ∫ f L cos θi dωi by the model's sampler
    // and by uniform sphere sampling (weight f cos θi · 4π), each with 1e6 samples.
    /// Samples of each estimate: uniform sampling needs 4× more for a 0.5 % standard error at θo = 75°.
    const N: usize = 1_000_000;
    const N_UNIFORM: usize = 4 * N;
    let light = |w: Vec3| 1.0 + 0.8 * w.x + 0.5 * w.y * w.y - 0.3 * w.y * w.z;
    let m = model(|_| ());
    for (t, h) in [(-40.0, 0.1), (30.0, -0.6), (75.0, 0.9)] {
        let (fibre, wo) = (m.at(h), testing::wo_at(t));
        let mut rng = Pcg32::new(8, 8);
        let (mut si, mut si2, mut su, mut su2) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        for _ in 0..N {
            if let Some(s) = fibre.sample(wo, rng.random()) {
                let x = mean(s.weight) * light(s.wi) as f64;
                (si, si2) = (si + x, si2 + x * x);
            }
        }
        for _ in 0..N_UNIFORM {
            let wi = uniform_sphere(rng.random(), rng.random());
            let x = mean(fibre.eval(wo, wi)) * (sin_cos_theta(wi).1 * light(wi) * 4.0 * PI) as f64;
            (su, su2) = (su + x, su2 + x * x);
        }
        let (n, nu) = (N as f64, N_UNIFORM as f64);
        let (mi, mu) = (si / n, su / nu);
        let (ei, eu) = (
            ((si2 / n - mi * mi) / n).sqrt(),
            ((su2 / nu - mu * mu) / nu).sqrt(),
        );
        assert!(
            eu < 0.005 * mu && ei < 0.005 * mi,
            "standard errors too large to test 2 %"
        );
        assert!(
            (mi / mu - 1.0).abs() < 0.02,
            "importance {mi} vs uniform {mu}"
        );
    }
}

#[test]
fn reciprocity_only_term_by_term() {
    // The whole model is not reciprocal (A_p and h belong to the view).
    testing::assert_reciprocal(&model(|_| ()).at(0.0), false);
    testing::assert_reciprocal(&model(|p| p.alpha = 0.0).at(0.0), false);
    // M_p(θi, θo) = M_p(θo, θi); N_p even in φ at h = 0.
    let mut rng = Pcg32::new(1, 2);
    for _ in 0..1000 {
        let (a, b) = (
            (rng.random::<f32>() - 0.5) * PI,
            (rng.random::<f32>() - 0.5) * PI,
        );
        let ((sa, ca), (sb, cb)) = (a.sin_cos(), b.sin_cos());
        for v in [0.001, 0.05, 0.5, 5.0] {
            let (x, y) = (m_p(v, sa, ca, sb, cb), m_p(v, sb, cb, sa, ca));
            assert!(
                (x - y).abs() <= 1e-6 * x.max(y) + 1e-30,
                "M_p({a}, {b}) = {x} vs {y}"
            );
        }
        let phi = (rng.random::<f32>() - 0.5) * TAU;
        for p in 0..P_MAX {
            let n = |x: f32| trimmed_logistic(wrap_phi(x - phi_p(p, 0.0, 0.0)), 0.3);
            assert!(
                (n(phi) - n(-phi)).abs() <= 1e-5 * n(phi) + 1e-12,
                "N_{p}({phi})"
            );
        }
    }
}

#[test]
fn h_sign_matches_a_mirror_reflection_on_the_cylinder() {
    // The outward normal at offset h has azimuth φo − γo (module docs); a mirror reflection of the incoming
    // ray −ωo about it must be where R peaks (narrow lobes, no tilt).
    let m = model(|p| {
        p.beta_m = 0.1;
        p.beta_n = 0.1;
        p.alpha = 0.0;
    });
    for h in [-0.7f32, -0.2, 0.4, 0.9] {
        let (theta_o, phi_o) = (0.3f32, 0.5f32);
        let wo = from_spherical(theta_o, phi_o);
        // n from the definition h = u · (n × ω̂o⊥).
        let n = from_spherical(0.0, phi_o - h.asin());
        let w_perp = Vec3::new(0.0, wo.y, wo.z).normalize();
        assert!((Vec3::X.dot(n.cross(w_perp)) - h).abs() < 1e-5);
        let d = -wo;
        let mirror = d - 2.0 * d.dot(n) * n;
        let fibre = m.at(h);
        let best = (0..3600)
            .map(|k| from_spherical(-theta_o, -PI + k as f32 * TAU / 3600.0))
            .max_by(|a, b| {
                fibre
                    .eval_lobes(wo, *a)
                    .r
                    .x
                    .total_cmp(&fibre.eval_lobes(wo, *b).r.x)
            })
            .unwrap();
        assert!(
            best.dot(mirror) > 0.9999,
            "h {h}: R peaks at {best}, the mirror direction is {mirror}"
        );
    }
}

#[test]
fn h_from_a_ray_cylinder_hit_and_from_a_ribbon() {
    // A fibre of radius r along u through c, a ray towards it from the view direction ωo at signed offset d
    // along b = ω̂o⊥ × u: the hit's outward normal gives h = d/r (h_from_normal), and so does a ribbon facing
    // the ray across b with v = (d/r + 1)/2 (h_from_ribbon). Frames turned arbitrarily, world space.
    let mut rng = Pcg32::new(21, 4);
    for _ in 0..200 {
        let u = uniform_sphere(rng.random(), rng.random());
        let wo = uniform_sphere(rng.random(), rng.random());
        if u.dot(wo).abs() > 0.99 {
            continue;
        }
        let (c, r) = (Vec3::new(0.3, -1.0, 2.0), 0.01 + rng.random::<f32>());
        let w_perp = wo.reject_from_normalized(u).normalize();
        let b = w_perp.cross(u);
        let d = r * (2.0 * rng.random::<f32>() - 1.0) * 0.999;
        // The ray starts far along ωo, offset by d b, and travels along −ωo: in the normal plane it meets the
        // circle where its in-plane distance to c is r (in f64: the quadratic cancels in f32).
        let (u64_, c64) = (u.as_dvec3(), c.as_dvec3());
        let o = c64 + 10.0 * wo.as_dvec3() + (d * b).as_dvec3();
        let dir = -wo.as_dvec3();
        let (oc, dp) = (
            (o - c64).reject_from_normalized(u64_),
            dir.reject_from_normalized(u64_),
        );
        let r64 = r as f64;
        let (qa, qb, qc) = (dp.dot(dp), 2.0 * oc.dot(dp), oc.dot(oc) - r64 * r64);
        let t = (-qb - (qb * qb - 4.0 * qa * qc).sqrt()) / (2.0 * qa);
        let hit = o + t * dir;
        let n = ((hit - c64).reject_from_normalized(u64_) / r64).as_vec3();
        let h = h_from_normal(u, n, wo);
        assert!((h - d / r).abs() < 1e-4, "h {h} vs d/r {}", d / r);
        let v = 0.5 * (d / r + 1.0);
        let h_ribbon = h_from_ribbon(v, b, u, wo);
        assert!((h_ribbon - d / r).abs() < 1e-4, "{h_ribbon} vs {}", d / r);
        // In a local hair frame (here v along n), the outward normal's azimuth is φo − γo, γo = asin h.
        let frame = super::super::frame::HairFrame::from_round_curve(u, n);
        let (wo_l, n_l) = (frame.to_local(wo), frame.to_local(n));
        let phi_n = super::super::frame::phi(n_l);
        let gamma = wrap_phi(super::super::frame::phi(wo_l) - phi_n);
        assert!(
            (gamma.sin() - h).abs() < 2e-3,
            "sin γo {} vs h {h}",
            gamma.sin()
        );
    }
}

#[test]
fn tilt_moves_each_lobe_as_documented() {
    // Narrow lobes: the θi where each lobe peaks, at h = 0 and φ at its Φ (R 0, TT π, TRT 2π ≡ 0), is
    // −θo + 2α (R), −θo − α (TT), −θo − 4α (TRT).
    let alpha = 5f32.to_radians();
    let m = model(|p| {
        p.beta_m = 0.05;
        p.beta_n = 0.3;
        p.alpha = alpha;
        p.sigma_a = Vec3::ZERO;
    });
    let fibre = m.at(0.0);
    let theta_o = 0.4f32;
    let wo = from_spherical(theta_o, 0.0);
    let peak = |phi: f32, lobe: fn(&LobeValues) -> f32| {
        (0..20_000)
            .map(|k| -1.5 + 3.0 * k as f32 / 20_000.0)
            .max_by(|a, b| {
                let f = |t: f32| lobe(&fibre.eval_lobes(wo, from_spherical(t, phi)));
                f(*a).total_cmp(&f(*b))
            })
            .unwrap()
    };
    let r = peak(0.0, |l| l.r.x);
    let tt = peak(PI, |l| l.tt.x);
    let trt = peak(0.0, |l| l.trt.x);
    // f = M_p A_p N_p / cos θi peaks within ~v tan θi of the lobe's centre (v₀ = 1.5e-3, v₂ = 5.9e-3 here).
    assert!((r - (-theta_o + 2.0 * alpha)).abs() < 3e-3, "R {r}");
    assert!((tt - (-theta_o - alpha)).abs() < 3e-3, "TT {tt}");
    assert!((trt - (-theta_o - 4.0 * alpha)).abs() < 1e-2, "TRT {trt}");
}

#[test]
fn finite_everywhere() {
    for (beta_m, beta_n) in [
        (BETA_MIN, BETA_MIN),
        (1.0, 1.0),
        (BETA_MIN, 1.0),
        (1.0, BETA_MIN),
    ] {
        for (alpha, sigma_a) in [(FRAC_PI_8, Vec3::ZERO), (-FRAC_PI_8, Vec3::splat(1e3))] {
            let m = model(|p| {
                p.beta_m = beta_m;
                p.beta_n = beta_n;
                p.alpha = alpha;
                p.sigma_a = sigma_a;
            });
            for h in [-1.0, -0.999, 0.0, 0.5, 1.0] {
                testing::assert_finite_sweep(
                    &format!("chiang βm {beta_m} βn {beta_n} α {alpha} σa {sigma_a} h {h}"),
                    &m.at(h),
                );
            }
        }
    }
}

#[test]
fn melanin_and_colour() {
    // pbrt-v4's default hair: eumelanin 1.3.
    let s = sigma_a_from_melanin(1.3, 0.2).unwrap();
    let want = Vec3::new(0.5821, 0.9861, 1.991);
    assert!((s - want).abs().max_element() < 1e-3, "{s}");
    assert_eq!(
        ChiangParams::default().sigma_a,
        sigma_a_from_melanin(1.3, 0.0).unwrap()
    );
    // eq. 9 by hand: βn = 0.3 gives D = 5.88841, so C = 0.5 needs σa = (ln 2 / D)² = 0.0138565.
    let s = sigma_a_from_color(Vec3::splat(0.5), 0.3).unwrap();
    assert!((s.x - 0.013_856_5).abs() < 1e-6, "{s}");
    // Round trip, and darker colours absorb more.
    for beta_n in [0.1, 0.3, 0.6, 1.0] {
        for c in [Vec3::new(0.9, 0.5, 0.2), Vec3::new(0.05, 0.3, 1.0)] {
            let s = sigma_a_from_color(c, beta_n).unwrap();
            let back = color_from_sigma_a(s, beta_n);
            assert!(
                (back - c).abs().max_element() < 1e-5,
                "βn {beta_n}: {c} → {s} → {back}"
            );
        }
        let dark = sigma_a_from_color(Vec3::splat(0.1), beta_n).unwrap();
        let light = sigma_a_from_color(Vec3::splat(0.8), beta_n).unwrap();
        assert!(dark.x > light.x);
    }
    // Absorption lowers the fibre's albedo, channel by channel in σa's order.
    let a = testing::albedo(&model(|_| ()).at(0.0), testing::wo_at(0.0)).sum();
    assert!(a.x > a.y && a.y > a.z && a.x < 1.0, "{a}");
}

#[test]
fn validation_names_the_parameter() {
    let err = |f: fn(&mut ChiangParams)| {
        let mut p = ChiangParams::default();
        f(&mut p);
        Chiang::new(p).unwrap_err().to_string()
    };
    assert_eq!(
        err(|p| p.beta_m = 0.0),
        "chiang: beta_m must be in [1e-3, 1], got 0"
    );
    assert!(err(|p| p.beta_n = 1.5).starts_with("chiang: beta_n must be"));
    assert!(err(|p| p.eta = 1.0).starts_with("chiang: eta must be in (1, 10]"));
    assert!(err(|p| p.alpha = 1.0).starts_with("chiang: alpha must be"));
    assert!(err(|p| p.sigma_a = Vec3::new(0.1, -1.0, 0.1)).starts_with("chiang: sigma_a must be"));
    let e = sigma_a_from_color(Vec3::new(0.5, 0.0, 0.5), 0.3).unwrap_err();
    assert_eq!(
        e.to_string(),
        "chiang: color must be in (0, 1] per channel, got 0"
    );
    let e = sigma_a_from_melanin(-1.0, 0.0).unwrap_err();
    assert!(e.to_string().starts_with("chiang: eumelanin must be >= 0"));
}
