//! The model's unit tests (Bessel accuracy, normalisation, white furnace, χ² of the sampler, reciprocity, the
//! offset h's sign, validation), apart because they outweigh the model itself.

use super::super::frame::{from_spherical, h_from_normal, h_from_ribbon, sin_cos_theta, wrap_phi};
use super::super::lanes::{directions, InLanes, LANES};
use super::super::testing::{self, mean};
use super::super::{Bsdf, LobeValues};
use super::bessel::I0_SWITCH;
use super::*;
use crate::util::sampling::uniform_sphere;
use rand::Rng;
use rand_pcg::Pcg32;
use wide::f32x8;

/// The roughnesses of the white-furnace grid (0.1, 0.2, …, 0.9).
const BETAS: [f32; 9] = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9];
/// θo of the chi-square batteries, degrees.
const CHI2_THETA_O_DEG: [f32; 3] = [-60.0, 10.0, 70.0];

fn model(f: impl FnOnce(&mut ChiangParams)) -> Chiang {
    let mut p = ChiangParams::default();
    f(&mut p);
    Chiang::new(p).unwrap()
}

/// The model at `h` in both its forms: one shading point (`f32`) and a lane of eight (`f32x8`, [`InLanes`]).
fn forms(m: &Chiang, h: f32) -> [(&'static str, Box<dyn Bsdf + '_>); 2] {
    [
        ("f32", Box::new(m.at(h))),
        ("f32x8", Box::new(InLanes { model: m, h })),
    ]
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

/// M_p at the angles of the f32 pairs (sin, cos), in f64 with the full 32-term Bessel function: the angles' sum's
/// 1 − cos as 2 sin²(½(θi + θo)), free of the cancellation an f64 cos θi cos θo − sin θi sin θo − 1 of rounded pairs
/// would carry.
fn m_p_reference(v: f64, (si, ci): (f32, f32), (so, co): (f32, f32)) -> f64 {
    let (ti, to) = ((si as f64).atan2(ci as f64), (so as f64).atan2(co as f64));
    let a = ti.cos() * to.cos() / v;
    let one_minus_cos = 2.0 * (0.5 * (ti + to)).sin().powi(2);
    let log_norm = -v.ln() - (-(-2.0 / v).exp_m1()).ln();
    (log_norm - one_minus_cos / v).exp() * i0e(a)
}

#[test]
fn m_p_in_f32_and_in_lanes_matches_the_full_bessel_function() {
    // Both expansions cut to 16 terms at M_P_SWITCH (10) and the exponent formed without cancellation (the
    // longitudinal module's docs): M_p of f32 unit pairs, one at a time and eight at once, must agree with the f64
    // reference at the same angles to a few f32 roundings of the exponent E = ln M_p (8 ε (1 + |E|)), for a's on both
    // sides of the switch and lobes from βm ≈ 0.05 to the widest.
    let eps = f32::EPSILON as f64;
    for v in [0.002f64, 0.02, 0.0846, 0.2, 0.5, 1.0] {
        let l = Longitudinal::new(v);
        let pair = |t: f64| ((t.sin() as f32), (t.cos() as f32));
        let mut worst = 0.0f64;
        for ti in -40..=40 {
            let sc_i = pair(ti as f64 * 0.039);
            let outs: Vec<(f32, f32)> = (-40..=40)
                .map(|to| {
                    let (s, c) = pair(to as f64 * 0.0391);
                    (s, c.abs())
                })
                .collect();
            for chunk in outs.chunks_exact(LANES) {
                let lanes = m_p_of(
                    f32x8::splat(l.inv_v),
                    f32x8::splat(l.log_norm),
                    [
                        f32x8::splat(sc_i.0),
                        f32x8::splat(sc_i.1),
                        f32x8::new(std::array::from_fn(|k| chunk[k].0)),
                        f32x8::new(std::array::from_fn(|k| chunk[k].1)),
                    ],
                );
                for (k, &sc_o) in chunk.iter().enumerate() {
                    let want = m_p_reference(v, sc_i, sc_o);
                    if want < 1e-30 {
                        continue;
                    }
                    let one = m_p_of(l.inv_v, l.log_norm, [sc_i.0, sc_i.1, sc_o.0, sc_o.1]) as f64;
                    let lane = lanes.as_array_ref()[k] as f64;
                    let tolerance = 8.0 * eps * (1.0 + want.ln().abs());
                    for (form, got) in [("f32", one), ("f32x8", lane)] {
                        let rel = (got / want - 1.0).abs();
                        worst = worst.max(rel / tolerance);
                        assert!(
                            rel < tolerance,
                            "{form} v {v} sc_i {sc_i:?} sc_o {sc_o:?}: {got} vs {want} ({rel:e})"
                        );
                    }
                }
            }
        }
        assert!(worst > 0.0, "v {v}: nothing compared");
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
                    s += m_p(v, si, ci, so, co) as f64 * t.cos() * h;
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
                for (form, b) in forms(&m, h) {
                    let a = mean(testing::albedo(b.as_ref(), testing::wo_at(theta_o)).sum());
                    assert!(
                        (0.999..=1.001).contains(&a),
                        "{form} βm {beta_m} βn {beta_n} θo {theta_o}° h {h}: albedo {a}"
                    );
                }
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
                let h = 2.0 * rng.random::<f32>() - 1.0;
                let wo = uniform_sphere(rng.random(), rng.random());
                let u = rng.random();
                for (form, fibre) in forms(&m, h) {
                    let Some(s) = fibre.sample(wo, u) else {
                        continue;
                    };
                    for c in 0..3 {
                        let w = s.weight[c];
                        assert!(
                            w > 0.99 && w < 1.01,
                            "{form} βm {beta_m} βn {beta_n} h {h} wo {wo}: weight {}",
                            s.weight
                        );
                    }
                    sampled += 1;
                }
            }
        }
    }
    assert!(sampled > 0, "no direction was sampled");
}

#[test]
fn sampled_furnace_matches_quadrature_with_absorption() {
    let m = model(|_| ());
    for (t, h) in [(-50.0, 0.3), (20.0, -0.9)] {
        for (form, b) in forms(&m, h) {
            testing::assert_sampled_furnace_matches(
                &format!("chiang {form} default θo {t}° h {h}"),
                b.as_ref(),
                testing::wo_at(t),
                0.01,
            );
        }
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
        for (form, b) in forms(&m, h) {
            testing::chi_square_battery(
                &format!("chiang {form} βm {beta_m} βn {beta_n} h {h} α {alpha_deg}°"),
                b.as_ref(),
                &CHI2_THETA_O_DEG,
            );
        }
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
    for (form, b) in forms(&absorbing, 0.4) {
        testing::chi_square_battery(
            &format!("chiang uniform {form}"),
            b.as_ref(),
            &CHI2_THETA_O_DEG[..2],
        );
    }
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
            for (form, b) in forms(&m, h) {
                let i = testing::pdf_integral(b.as_ref(), testing::wo_at(t));
                assert!(
                    (i - 1.0).abs() < 1e-3,
                    "{form} βm {beta_m} βn {beta_n} θo {t}°: ∫ pdf = {i}"
                );
            }
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
    for m in [model(|_| ()), model(|p| p.alpha = 0.0)] {
        for (_, b) in forms(&m, 0.0) {
            testing::assert_reciprocal(b.as_ref(), false);
        }
    }
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
            // Symmetric up to f32 rounding: swapping the angles reorders the fused products of the exponent, whose
            // roundings scale M_p by a few ε times the exponent's terms, ln c(v) + 1/v ≈ −ln v and ln M_p.
            let terms = 1.0 + (v as f32).ln().abs() + x.max(y).ln().abs();
            let bound = 8.0 * f32::EPSILON * terms;
            assert!(
                x == y || (x - y).abs() <= bound * x.max(y) + 1e-30,
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
                for (form, b) in forms(&m, h) {
                    testing::assert_finite_sweep(
                        &format!(
                            "chiang {form} βm {beta_m} βn {beta_n} α {alpha} σa {sigma_a} h {h}"
                        ),
                        b.as_ref(),
                    );
                }
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

/// Asserts that eight lanes give bit for bit the values of one shading point at a time (every lobe, channel and
/// the pdf) over batches of (h, ωo, ωi), and that every value is finite and non-negative: the same generic code,
/// whose functions are the same on one lane and on eight ([`crate::util::real`]).
fn assert_lanes_match_scalar(name: &str, m: &Chiang, cases: &[(f32, Vec3, Vec3)]) {
    for batch in cases.chunks_exact(LANES) {
        let h = f32x8::new(std::array::from_fn(|k| batch[k].0));
        let wo: [Vec3; LANES] = std::array::from_fn(|k| batch[k].1);
        let wi: [Vec3; LANES] = std::array::from_fn(|k| batch[k].2);
        let got = m.eval_view(&m.view(h, directions(&wo)), directions(&wi));
        for k in 0..LANES {
            let want = m.eval_view(&m.view(batch[k].0, wo[k].to_array()), wi[k].to_array());
            let ((w, w_pdf), (g, g_pdf)) = (want.lane(0), got.lane(k));
            let mut pairs = vec![(w_pdf, g_pdf)];
            for (a, b) in [(w.r, g.r), (w.tt, g.tt), (w.trt, g.trt)] {
                pairs.extend((0..3).map(|c| (a[c], b[c])));
            }
            for (a, b) in pairs {
                assert!(b.is_finite() && b >= 0.0, "{name} case {:?}: {b}", batch[k]);
                assert_eq!(
                    a.to_bits(),
                    b.to_bits(),
                    "{name} case {:?}: {b} against {a}",
                    batch[k]
                );
            }
        }
    }
}

#[test]
fn eight_lanes_give_the_values_of_one_at_a_time() {
    let mut rng = Pcg32::new(27, 8);
    for beta_m in [0.001f32, 0.005, 0.02, 0.1, 0.3, 0.6, 1.0] {
        for beta_n in [0.001f32, 0.05, 0.3, 0.9, 1.0] {
            for sigma in [0.0f32, 0.5, 4.0] {
                let m = model(|p| {
                    (p.beta_m, p.beta_n) = (beta_m, beta_n);
                    p.sigma_a = Vec3::new(sigma, 2.0 * sigma, 0.5 * sigma);
                });
                let cases: Vec<(f32, Vec3, Vec3)> = (0..16 * LANES)
                    .map(|_| {
                        let h = rng.random_range(-1.0f32..=1.0);
                        let wo = uniform_sphere(rng.random(), rng.random());
                        (h, wo, uniform_sphere(rng.random(), rng.random()))
                    })
                    .collect();
                assert_lanes_match_scalar(
                    &format!("βm {beta_m} βn {beta_n} σ {sigma}"),
                    &m,
                    &cases,
                );
            }
        }
    }
}

#[test]
fn eight_lanes_draw_the_samples_of_one_at_a_time() {
    // Same hits, same random numbers: the lanes must draw bit for bit the sample of one at a time.
    let mut rng = Pcg32::new(27, 10);
    let mut n = 0usize;
    for beta_m in [0.01f32, 0.1, 0.3, 1.0] {
        for beta_n in [0.01f32, 0.3, 1.0] {
            let m = model(|p| (p.beta_m, p.beta_n) = (beta_m, beta_n));
            for _ in 0..64 {
                let h: [f32; LANES] = std::array::from_fn(|_| rng.random_range(-1.0f32..=1.0));
                let wo: [Vec3; LANES] =
                    std::array::from_fn(|_| uniform_sphere(rng.random(), rng.random()));
                let u: [[f32; 3]; LANES] = std::array::from_fn(|_| rng.random());
                let lanes = m.sample_view(
                    &m.view(f32x8::new(h), directions(&wo)),
                    std::array::from_fn(|c| f32x8::new(u.map(|u| u[c]))),
                );
                for k in 0..LANES {
                    let one = m.sample_view(&m.view(h[k], wo[k].to_array()), u[k]);
                    let (Some(want), Some(got)) = (one.to_sample(0), lanes.to_sample(k)) else {
                        assert_eq!(one.eval.pdf > 0.0, lanes.eval.pdf.as_array_ref()[k] > 0.0);
                        continue;
                    };
                    n += 1;
                    assert_eq!(got, want, "βm {beta_m} βn {beta_n}");
                }
            }
        }
    }
    assert!(n > 1000, "only {n} lanes compared");
}

#[test]
fn eight_lanes_stay_finite_and_match_at_grazing_angles_and_edges() {
    // ωo and ωi along the fibre (θ = ±90°), a hair's breadth from it, and across it; h at the fibre's edges and
    // centre; the roughness range's ends: finite, non-negative and the same in lanes.
    let thetas = [-90.0f32, -89.99, -60.0, 0.0, 45.0, 89.99, 90.0].map(f32::to_radians);
    let dir = |t: f32, p: f32| Vec3::new(t.sin(), t.cos() * p.cos(), t.cos() * p.sin());
    let mut cases = Vec::new();
    for &to in &thetas {
        for &ti in &thetas {
            for pi in [0.0f32, 1.0, PI] {
                for h in [-1.0f32, -0.9999, 0.0, 0.5, 0.9999, 1.0] {
                    cases.push((h, dir(to, 0.3), dir(ti, 0.3 + pi)));
                }
            }
        }
    }
    for beta_m in [0.001f32, 0.3, 1.0] {
        for beta_n in [0.001f32, 0.3, 1.0] {
            let m = model(|p| (p.beta_m, p.beta_n) = (beta_m, beta_n));
            assert_lanes_match_scalar(&format!("βm {beta_m} βn {beta_n}"), &m, &cases);
        }
    }
}
