//! Dual scattering's tables against brute-force integration of the single-fibre model, its closed forms against
//! their series, its energy, and finiteness over the parameter sweep.

use super::*;
use crate::bsdf::chiang::ChiangParams;
use crate::bsdf::frame::from_spherical;
use crate::bsdf::Bsdf;
use rand::Rng;
use rand_pcg::Pcg32;

fn chiang(sigma_a: Vec3, beta_m: f32, beta_n: f32) -> Chiang {
    Chiang::new(ChiangParams {
        sigma_a,
        beta_m,
        beta_n,
        ..ChiangParams::default()
    })
    .unwrap()
}

/// Blond (pbrt-v4's melanin 0.3), brown (1.3) and black (8).
fn absorptions() -> [(&'static str, Vec3); 3] {
    let eu = crate::bsdf::chiang::EUMELANIN_SIGMA_A;
    [
        ("blond", eu * 0.3),
        ("brown", eu * 1.3),
        ("black", eu * 8.0),
    ]
}

/// Monte Carlo of the scalar model ([`Bsdf`] at a uniform h, its own sampler, weights f cos θi/pdf) at
/// inclination `theta_o`: (forward energy, backward energy, mean δ forward, mean δ backward, variance of δ
/// forward, variance backward) per channel, with the energies' standard errors.
fn monte_carlo(model: &Chiang, theta_o: f32, n: usize, seed: u64) -> (Averages, Vec3, Vec3) {
    let mut rng = Pcg32::new(seed, 0xda3e39cb94b95bdb);
    let wo = from_spherical(theta_o, 0.3);
    let phi_o = wo.z.atan2(wo.y);
    let mut sums = [[0.0f64; 3]; 6];
    let mut squares = [[0.0f64; 3]; 2];
    for _ in 0..n {
        let h: f32 = rng.random_range(-1.0..1.0);
        let u = [rng.random(), rng.random(), rng.random()];
        let Some(s) = model.at(h).sample(wo, u) else {
            continue;
        };
        let (sin_i, cos_i) = crate::bsdf::frame::sin_cos_theta(s.wi);
        let theta_i = sin_i.atan2(cos_i) as f64;
        let mut dphi = (s.wi.z.atan2(s.wi.y) - phi_o) as f64;
        dphi -= TAU * (dphi / TAU).round();
        let forward = dphi.abs() > FRAC_PI_2;
        let weight = s.f * cos_i / s.pdf;
        let delta = theta_i + theta_o as f64;
        let k = if forward { 0 } else { 1 };
        for c in 0..3 {
            let w = weight[c] as f64;
            sums[k][c] += w;
            squares[k][c] += w * w;
            sums[2 + k][c] += w * delta;
            sums[4 + k][c] += w * delta * delta;
        }
    }
    let n = n as f64;
    let mut a = Averages {
        forward: Vec3::ZERO,
        backward: Vec3::ZERO,
        shift_forward: Vec3::ZERO,
        shift_backward: Vec3::ZERO,
        variance_forward: Vec3::ZERO,
        variance_backward: Vec3::ZERO,
    };
    let (mut se_f, mut se_b) = (Vec3::ZERO, Vec3::ZERO);
    for c in 0..3 {
        let (ef, eb) = (sums[0][c] / n, sums[1][c] / n);
        a.forward[c] = ef as f32;
        a.backward[c] = eb as f32;
        se_f[c] = ((squares[0][c] / n - ef * ef) / n).sqrt() as f32;
        se_b[c] = ((squares[1][c] / n - eb * eb) / n).sqrt() as f32;
        let (mf, mb) = (sums[2][c] / sums[0][c], sums[3][c] / sums[1][c]);
        a.shift_forward[c] = mf as f32;
        a.shift_backward[c] = mb as f32;
        a.variance_forward[c] = (sums[4][c] / sums[0][c] - mf * mf) as f32;
        a.variance_backward[c] = (sums[5][c] / sums[1][c] - mb * mb) as f32;
    }
    (a, se_f, se_b)
}

/// The tables' forward and backward attenuations, shifts and variances agree with a Monte Carlo integration of
/// the model through its own `Bsdf` (another code path: the sampler, `eval`, the h of each sample) at inclinations
/// across the range, for blond, brown and black hair and two roughnesses.
#[test]
fn averages_match_monte_carlo_integration_of_the_fibre() {
    for (name, sigma_a) in absorptions() {
        for (beta_m, beta_n) in [(0.3, 0.3), (0.15, 0.6)] {
            let model = chiang(sigma_a, beta_m, beta_n);
            let tables = DualScattering::new(&model);
            for (i, theta_deg) in [-60.0f32, -20.0, 0.0, 35.0, 70.0].into_iter().enumerate() {
                let theta = theta_deg.to_radians();
                let (mc, se_f, se_b) = monte_carlo(&model, theta, 200_000, 7 + i as u64);
                let t = tables.averages(theta);
                let what = format!("{name} βm {beta_m} βn {beta_n} θ {theta_deg}°");
                for c in 0..3 {
                    // Energies: within 4 standard errors plus the tables' interpolation between bins (5e-4).
                    for (label, got, want, se) in [
                        ("ā_f", t.forward[c], mc.forward[c], se_f[c]),
                        ("ā_b", t.backward[c], mc.backward[c], se_b[c]),
                    ] {
                        assert!(
                            (got - want).abs() <= 4.0 * se + 5e-4,
                            "{what} channel {c}: {label} table {got:.5} Monte Carlo {want:.5} ± {se:.5}"
                        );
                    }
                    // Shifts and variances where the half carries energy worth measuring.
                    for (label, energy, got, want, gv, wv) in [
                        (
                            "forward",
                            t.forward[c],
                            t.shift_forward[c],
                            mc.shift_forward[c],
                            t.variance_forward[c],
                            mc.variance_forward[c],
                        ),
                        (
                            "backward",
                            t.backward[c],
                            t.shift_backward[c],
                            mc.shift_backward[c],
                            t.variance_backward[c],
                            mc.variance_backward[c],
                        ),
                    ] {
                        if energy < 0.02 {
                            continue;
                        }
                        let sd = wv.sqrt();
                        assert!(
                            (got - want).abs() <= 0.03 * sd + 0.01,
                            "{what} channel {c}: {label} shift table {got:.4} Monte Carlo {want:.4}"
                        );
                        assert!(
                            (gv / wv - 1.0).abs() <= 0.05,
                            "{what} channel {c}: {label} variance table {gv:.4} Monte Carlo {wv:.4}"
                        );
                    }
                }
            }
        }
    }
}

/// With σa = 0 the fibre loses nothing: ā_f + ā_b = 1 at every inclination of the table, for every roughness.
#[test]
fn white_fibre_scatters_everything_forward_or_back() {
    for beta in [0.05f32, 0.3, 0.9] {
        let tables = DualScattering::new(&chiang(Vec3::ZERO, beta, beta));
        for k in 0..THETA_BINS {
            let a = &tables.averages[k];
            let sum = a.forward + a.backward;
            assert!(
                (sum - Vec3::ONE).abs().max_element() < 2e-3,
                "β {beta} bin {k}: ā_f + ā_b = {sum}"
            );
            assert!(a.backward.min_element() > 0.0, "β {beta} bin {k}: {a:?}");
        }
    }
}

/// The closed forms of A_b (eq. 14), Δ_b (eq. 16) and σ_b² are the sums over the paths they stand for, summed
/// here term by term: one back-scattering with k forward events each way (weight ā_b ā_f^{2k}, deviation
/// ᾱ_b + 2k ᾱ_f in the mean of eq. 16's first class, variance β̄_b² + 2k β̄_f²) and three back-scatterings
/// (weight ā_b³ k(k+1)/2 ā_f^{2k}, variance 3β̄_b² + 2k β̄_f²).
#[test]
fn backscatter_closed_forms_are_their_series() {
    for (af, ab) in [(0.8f32, 0.2f32), (0.5, 0.3), (0.3, 0.05), (0.95, 0.05)] {
        let (bf, bb) = (0.01f32, 0.04f32);
        let a = Averages {
            forward: Vec3::splat(af),
            backward: Vec3::splat(ab),
            shift_forward: Vec3::splat(-0.03),
            shift_backward: Vec3::splat(0.07),
            variance_forward: Vec3::splat(bf),
            variance_backward: Vec3::splat(bb),
        };
        let closed = a.backscatter();
        let (af, ab, bf, bb) = (af as f64, ab as f64, bf as f64, bb as f64);
        let (mut a1, mut a3, mut v) = (0.0f64, 0.0f64, 0.0f64);
        for k in 1..20_000 {
            let k = k as f64;
            let x = af.powf(2.0 * k);
            let (w1, w3) = (ab * x, ab.powi(3) * k * (k + 1.0) / 2.0 * x);
            a1 += w1;
            a3 += w3;
            v += w1 * (bb + 2.0 * k * bf) + w3 * (3.0 * bb + 2.0 * k * bf);
        }
        let total = a1 + a3;
        let rel = |got: f32, want: f64| (got as f64 / want - 1.0).abs();
        assert!(
            rel(closed.attenuation.x, total) < 1e-5,
            "ā_f {af} ā_b {ab}: A_b {} against the series {total}",
            closed.attenuation.x
        );
        assert!(
            rel(closed.variance.x, v / total) < 1e-4,
            "ā_f {af} ā_b {ab}: σ_b² {} against the series {}",
            closed.variance.x,
            v / total
        );
    }
}

/// ∫ over the sphere of the local term's f cos θi (unoccluded light) is d_b A_b: the backward half's lobe is a
/// normalised M times 1/π over half the circle.
#[test]
fn local_term_returns_its_backscattered_energy() {
    let tables = DualScattering::new(&chiang(absorptions()[0].1, 0.3, 0.3));
    for theta_deg in [-40.0f32, 0.0, 25.0] {
        let theta_o = theta_deg.to_radians();
        let wo = from_spherical(theta_o, 0.0);
        let (nt, np) = (512, 256);
        let mut sum = Vec3::ZERO;
        for i in 0..nt {
            let theta = -FRAC_PI_2 as f32 + (i as f32 + 0.5) * std::f32::consts::PI / nt as f32;
            for j in 0..np {
                let phi =
                    -std::f32::consts::PI + (j as f32 + 0.5) * std::f32::consts::TAU / np as f32;
                let wi = from_spherical(theta, phi);
                let d_omega = theta.cos()
                    * (std::f32::consts::PI / nt as f32)
                    * (std::f32::consts::TAU / np as f32);
                sum += tables.fcos(DualForm::Published, wo, wi, Crossed::counted(0, 0)) * d_omega;
            }
        }
        let want = DENSITY_BACKWARD * tables.backscatter(theta_o).attenuation;
        assert!(
            ((sum - want).abs() / want).max_element() < 0.02,
            "θo {theta_deg}°: ∫ f cos θi dωi = {sum}, d_b A_b = {want}"
        );
    }
}

/// N^G keeps each order's energy: the average over incident azimuths moves N_p's mass, it does not add any.
#[test]
fn global_azimuthal_keeps_each_orders_energy() {
    let tables = DualScattering::new(&chiang(absorptions()[1].1, 0.3, 0.4));
    for k in [3usize, 20, 32, 50] {
        let theta = theta_of_bin(k) as f32;
        let a = tables.averages(theta);
        let n = 4096;
        let mut mass = Vec3::ZERO;
        for j in 0..n {
            let phi = (j as f32 + 0.5) / n as f32 * std::f32::consts::PI;
            let ng = tables.global_azimuthal(theta, phi);
            mass += ng.iter().copied().sum::<Vec3>() * (2.0 * std::f32::consts::PI / n as f32);
        }
        let want = a.forward + a.backward;
        assert!(
            ((mass - want).abs() / want).max_element() < 5e-3,
            "bin {k}: ∫ Σ N^G dφ = {mass}, Σ A_p = {want}"
        );
    }
}

/// No NaN, Inf or negative value over grazing inclinations, every azimuth, 0 to 64 strands and extreme
/// roughness and absorption.
#[test]
fn finite_over_the_parameter_sweep() {
    let mut rng = Pcg32::new(11, 3);
    for sigma_a in [Vec3::ZERO, absorptions()[0].1, Vec3::splat(20.0)] {
        for (beta_m, beta_n) in [(1e-3, 1e-3), (0.3, 0.3), (1.0, 1.0), (1e-3, 1.0)] {
            let tables = DualScattering::new(&chiang(sigma_a, beta_m, beta_n));
            for _ in 0..400 {
                let theta = |r: &mut Pcg32| {
                    let t: f32 = r.random_range(-1.0..1.0);
                    (t.signum() * t.abs().powf(0.2)) * FRAC_PI_2 as f32
                };
                let wo = from_spherical(theta(&mut rng), rng.random_range(-4.0..4.0));
                let wi = from_spherical(theta(&mut rng), rng.random_range(-4.0..4.0));
                for strands in [0, 1, 3, 17, MAX_STRANDS] {
                    for (form, behind) in [
                        (DualForm::Published, 0),
                        (DualForm::Layered, 0),
                        (DualForm::Layered, 5),
                        (DualForm::Layered, MAX_STRANDS),
                    ] {
                        let f = tables.fcos(form, wo, wi, Crossed::counted(strands, behind));
                        assert!(
                            f.is_finite() && f.min_element() >= 0.0,
                            "σa {sigma_a} βm {beta_m} βn {beta_n} {wo} {wi} n {strands} {form:?}: {f}"
                        );
                    }
                }
            }
            for form in [DualForm::Published, DualForm::Layered] {
                let (ahead, behind) = tables.strand_limits(form);
                assert!((1..=MAX_STRANDS).contains(&ahead) && behind <= MAX_STRANDS);
            }
        }
    }
}

/// The adding method against its definition: one layer is (t, r); a stack of n has T_n + R_n = 1 when nothing is
/// absorbed; and for white fibres the light arriving at a point of the line from one side — F of the light on that
/// side ([`fluxes`] with n ahead, m behind) plus B of the light on the other (m ahead, n behind) — is exactly 1 for
/// every n and m: the layered form conserves the white furnace on a line.
#[test]
fn layers_conserve_a_white_stack() {
    let (t, r) = (Vec3::new(0.7, 0.5, 0.3), Vec3::new(0.1, 0.08, 0.05));
    assert_eq!(layers(t, r, 0), (Vec3::ONE, Vec3::ZERO));
    let (t1, r1) = layers(t, r, 1);
    assert!((t1 - t).abs().max_element() < 1e-7 && (r1 - r).abs().max_element() < 1e-7);
    // Two layers by the series of their inter-reflections: T₂ = t² Σ (r²)^k, R₂ = r + t² r Σ (r²)^k.
    let (t2, r2) = layers(t, r, 2);
    let geometric = Vec3::ONE / (Vec3::ONE - r * r);
    assert!((t2 - t * t * geometric).abs().max_element() < 1e-6);
    assert!((r2 - (r + t * t * r * geometric)).abs().max_element() < 1e-6);
    for white_r in [0.05f32, 0.2, 0.5] {
        let (t, r) = (Vec3::splat(1.0 - white_r), Vec3::splat(white_r));
        for n in [1u32, 3, 10, 64] {
            let (tn, rn) = layers(t, r, n);
            assert!(
                ((tn + rn) - Vec3::ONE).abs().max_element() < 1e-5,
                "n {n}: {tn} + {rn}"
            );
            for m in [0u32, 1, 7, 64] {
                let (nf, mf) = (n as f32, m as f32);
                let arriving = fluxes(t, r, nf, mf).0 + fluxes(t, r, mf, nf).1;
                // f32 over up to 128 additions: a few ulps per step.
                assert!(
                    (arriving - Vec3::ONE).abs().max_element() < 1e-4,
                    "r {white_r} n {n} m {m}: {arriving}"
                );
            }
        }
    }
}
