//! Dual scattering (Zinke, Yuksel, Weber & Keyser 2008, "Dual scattering approximation for fast multiple
//! scattering in hair"): the light a fibre receives after scattering in *other* fibres, from averages of the
//! single-fibre model instead of paths through the hair. Built here from Chiang et al.'s model
//! ([`super::chiang`]), whose A_p, N_p and M_p are integrated by the program into the tables below.
//!
//! # The approximation
//!
//! Light from a light towards a shading point x crosses n fibres. If n = 0 it arrives directly (single scattering,
//! the path tracer's own light sample); otherwise only light scattered on the way arrives. Zinke et al. split it
//! into
//!
//! - **global multiple scattering**: the light forward-scattered through the n fibres, arriving with its direction
//!   spread by σ_f² = Σ β̄_f²(θk) ≈ n β̄_f²(θ) in inclination and, in azimuth, over the half circle around the
//!   light; x scatters it with f^G: Chiang's lobes with M_p's variance widened to v_p + σ_f² and N_p averaged
//!   over that half circle (and over h);
//! - **local multiple scattering**: light back-scattered to x by the fibres behind it, as a lobe f_back =
//!   M_b(θi; θo − Δ_b, σ_b²) / π over the backward half (|φ| < π/2), normalised to 1, shifted by Δ_b and spread
//!   by σ_b² (the paper's eq. 16 and the variance derived below).
//!
//! Two forms ([`DualForm`]) weigh these two lobes:
//!
//! - **Published** (Zinke et al.): the forward light is T_f = ∏ ā_f(θk) ≈ ā_f(θ)ⁿ and the back-scattered light
//!   A_b of up to three back-scattering events (eq. 14), with density factors d_f = d_b = 0.7
//!   ([`DENSITY_FORWARD`], [`DENSITY_BACKWARD`]): d_b A_b f_back where n = 0, and
//!   T_f d_f (f^G(σ_f²) + d_b A_b f_back(σ_b² + σ_f²)) where n ≥ 1. The product drops the light that fibres
//!   ahead of x reflect back and forth before it passes, and three back-scatterings leave out the rest of the
//!   series; on a white furnace (σa = 0, the exact answer 1) it gives 0.55 (`tests/dual.rs`).
//! - **Layered** (cuticle's `dual`): the same lobes, their weights summed to every order by the adding method of
//!   two-stream transport, each fibre a layer that passes ā_f and returns ā_b (a stack of n layers has T_n, R_n:
//!   [`layers`]). A second query counts the m fibres behind x (along −ωi). x's own fibre is a layer of the line
//!   too, so the light reaching the fibres behind it passes it first: the light arriving at x from the light's
//!   side is F and from behind B ([`fluxes`]: the stack ahead's T_n, reflected between it and x with the stack
//!   behind). x scatters F − V (V = 1 where n = 0: the direct part is single scattering) with f^G, and B, times
//!   its own albedo ā_f + ā_b at θo, with f_back. No density factors: for white fibres the light arriving at x
//!   from one side, F of the light on that side plus B of the light on the other, is exactly 1 for every n and m
//!   (tested), so nothing needs damping; on the white furnace it gives 0.75, short of 1 because light crosses
//!   real hair along other lines than the straight one counted.
//!
//! The multiple-scattered light at x is f · cos θi on top of single scattering, light-sampled (no material sample
//! estimates it).
//!
//! # The averages (computed by the program, not fitted)
//!
//! In this crate's convention the path tracer weights light from ωi by f(ωo, ωi) cos θi dωi for a fixed ωo, and
//! ∫ f cos θi dωi = Σ A_p (1 with σa = 0). So the average forward attenuation at inclination θ is that integral
//! over the forward half, |φ| > π/2 (φ = φi − φo; φ = 0 sends light back towards ωi), averaged over the offset h:
//! ā_f(θ) = ⟨Σ_p A_p(θ, h) ∫_{|φ|>π/2} N_p(φ, h) dφ⟩_h, and ā_b(θ) the same over |φ| < π/2, so ā_f + ā_b =
//! ⟨Σ A_p⟩ (exactly 1 with σa = 0: tested). The shifts and variances are those of the deviation δ = θi + θo (0
//! for a mirror reflection and for light passing straight through), as angles of the direction, over the
//! forward- (backward-) scattered energy: each lobe's M_p contributes its mean and variance of δ (integrated
//! numerically), mixed by its energy — the variance of the mixture, the spread between the lobes' means included.
//! The tables hold 64 inclinations; N^G a further 64 azimuths in [0, π] (it is even in φ once averaged over h).
//!
//! # Departures from the paper, and why
//!
//! - **Units**: the paper writes shifts and widths of Marschner's θ_h = (θi + θo)/2 and normalises f_back with
//!   2/(π cos²θd); here every angle is of the direction (δ = 2θ_h) and f_back integrates to A_b exactly
//!   (∫ f_back cos θi dωi = A_b), the convention of the rest of the crate.
//! - **σ_b²**: the paper's eq. 17 divides a sum of standard deviations weighted by attenuations by
//!   ā_b + ā_b³(2β̄_f + 3β̄_b), which adds attenuations to angles. Here σ_b² is the variance of the two classes of
//!   paths that eq. 14 sums: A₁ = ā_b ā_f²/(1 − ā_f²) (one back-scattering, k forward events each way, k ≥ 1,
//!   weighted ā_f^{2k}: on average 2/(1 − ā_f²) forward events) and A₃ = ā_b³ ā_f²/(1 − ā_f²)³ (three
//!   back-scatterings; the series ā_f²/(1 − ā_f²)³ = Σ k(k+1)/2 ā_f^{2k} gives on average 2(1 + 2ā_f²)/(1 − ā_f²)
//!   forward events): σ_b² = (A₁ s₁ + A₃ s₃)/(A₁ + A₃), s₁ = 2β̄_f²/(1 − ā_f²) + β̄_b²,
//!   s₃ = 2β̄_f²(1 + 2ā_f²)/(1 − ā_f²) + 3β̄_b².
//! - **Where a table is read**: ā_f and β̄_f along the light's path at the inclination of the direction back
//!   towards x (−θi of the light, the fibres taken parallel to x's, as the paper does); A_b, Δ_b, σ_b² and N^G at
//!   x's own θo.
//!
//! # Which models
//!
//! Chiang's alone. Both forms sum series in ā_f and ā_b, which mean something only when they are the energy a
//! fibre passes on and returns, ā_f + ā_b ≤ 1: the fibre must conserve energy and must transmit. The thesis'
//! Marschner is two R-type lobes and a diffuse term (no transmission lobe carries light forward through a fibre),
//! ISHair's lobes are unit-height Gaussians whose albedo grows with their width (not energy conserving, by design:
//! `bsdf::ishair`), and Kajiya-Kay is a diffuse cylinder and a cone.

use super::chiang::{m_p, Chiang, P_MAX};
use super::frame::sin_cos_theta;
use glam::Vec3;
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// d_f, the forward-scattering density factor (Zinke et al. 2008, §4.2: 0.7 works for their hair models; kept and
/// judged on this crate's scenes by `cuticle study multiple-scattering`).
pub const DENSITY_FORWARD: f32 = 0.7;

/// d_b, the backward-scattering density factor (as [`DENSITY_FORWARD`]).
pub const DENSITY_BACKWARD: f32 = 0.7;

/// Inclinations θ ∈ (−π/2, π/2) of the tables, at the centres of equal bins.
pub const THETA_BINS: usize = 64;

/// Azimuths φ ∈ [0, π] of the N^G table, end points included.
pub const PHI_BINS: usize = 64;

/// Nodes of the rule over h ∈ [−1, 1] that averages A_p and N_p over the fibre's width.
const H_NODES: usize = 64;

/// Incident inclinations of the midpoint rule that takes M_p's moments.
const THETA_I_NODES: usize = 2048;

/// The most strands a light's path is counted through: past it T_f ≤ ā_f⁶⁴ (2e-5 for ā_f = 0.85) and the count
/// stops (the tracer's list of strands seen holds 64).
pub const MAX_STRANDS: u32 = 64;

/// The strands a light sample's light crosses on its way to a shading point: whole numbers when ray traced
/// ([`Crossed::counted`]), footprint averages when read from a deep opacity map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crossed {
    /// Strands between the point and the light.
    pub ahead: f32,
    /// Strands behind the point, along −ωi.
    pub behind: f32,
    /// The share of the light that crosses no strand: single scattering's, left out of the multiple scattering.
    pub direct: f32,
}

impl Crossed {
    /// Ray-traced counts: the light is direct when no strand is ahead.
    pub fn counted(ahead: u32, behind: u32) -> Crossed {
        Crossed {
            ahead: ahead as f32,
            behind: behind as f32,
            direct: if ahead == 0 { 1.0 } else { 0.0 },
        }
    }
}

/// The averages of the single-fibre model at one inclination, per colour channel (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Averages {
    /// ā_f, the energy scattered into the forward half.
    pub forward: Vec3,
    /// ā_b, the energy scattered into the backward half.
    pub backward: Vec3,
    /// ᾱ_f, the mean deviation δ = θi + θo of the forward-scattered light, radians.
    pub shift_forward: Vec3,
    /// ᾱ_b, the same of the backward-scattered light.
    pub shift_backward: Vec3,
    /// β̄_f², the variance of δ of the forward-scattered light, radians².
    pub variance_forward: Vec3,
    /// β̄_b², the same of the backward-scattered light.
    pub variance_backward: Vec3,
}

/// Back-scattering by the fibres around a point, per channel: the paper's A_b (eq. 14), Δ_b (eq. 16) and the
/// variance σ_b² of the module docs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Backscatter {
    /// A_b, the energy returned by up to three back-scattering events.
    pub attenuation: Vec3,
    /// Δ_b, its mean deviation, radians.
    pub shift: Vec3,
    /// σ_b², its variance, radians².
    pub variance: Vec3,
}

impl Averages {
    /// A_b, Δ_b and σ_b² from these averages (module docs).
    pub fn backscatter(&self) -> Backscatter {
        let mut out = Backscatter {
            attenuation: Vec3::ZERO,
            shift: Vec3::ZERO,
            variance: Vec3::ZERO,
        };
        for c in 0..3 {
            let (af, ab) = (self.forward[c] as f64, self.backward[c] as f64);
            let (alpha_f, alpha_b) = (self.shift_forward[c] as f64, self.shift_backward[c] as f64);
            let (beta_f, beta_b) = (
                self.variance_forward[c] as f64,
                self.variance_backward[c] as f64,
            );
            let af2 = af * af;
            let ab2 = ab * ab;
            // ā_f < 1 whenever ā_b > 0 (their sum is at most 1); the floor only keeps a degenerate table finite.
            let one_m = (1.0 - af2).max(1e-9);
            let a1 = ab * af2 / one_m;
            let a3 = ab * ab2 * af2 / one_m.powi(3);
            let shift = alpha_b * (1.0 - 2.0 * ab2 / (one_m * one_m))
                + alpha_f * (2.0 * one_m * one_m + 4.0 * af2 * ab2) / one_m.powi(3);
            let s1 = 2.0 * beta_f / one_m + beta_b;
            let s3 = 2.0 * beta_f * (1.0 + 2.0 * af2) / one_m + 3.0 * beta_b;
            let total = a1 + a3;
            out.attenuation[c] = total as f32;
            out.shift[c] = shift as f32;
            out.variance[c] = if total > 0.0 {
                ((a1 * s1 + a3 * s3) / total) as f32
            } else {
                beta_b as f32
            };
        }
        out
    }
}

/// The dual-scattering tables of one Chiang material, ready to shade (module docs).
#[derive(Debug, Clone)]
pub struct DualScattering {
    model: Chiang,
    /// v_p of M_p per order.
    variances: [f64; P_MAX + 1],
    /// Per inclination bin.
    averages: Vec<Averages>,
    /// Per inclination bin, from `averages`.
    back: Vec<Backscatter>,
    /// N^G_p (A_p included) per inclination bin (major) and azimuth node (minor), per order and channel.
    global_azimuthal: Vec<[Vec3; P_MAX + 1]>,
    /// [`DualScattering::strand_limits`] of [`DualForm::Published`] and of [`DualForm::Layered`].
    limits: [(u32, u32); 2],
    /// Wall time of building the tables, seconds.
    build_seconds: f64,
}

/// Which form of dual scattering shades (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DualForm {
    /// The series summed to every order by the adding method, fibres counted on both sides of the point.
    Layered,
    /// As Zinke et al. published it: ∏ ā_f towards the light, back-scattering to three events, d_f = d_b = 0.7.
    Published,
}

/// θ at the centre of table bin `k`.
fn theta_of_bin(k: usize) -> f64 {
    -FRAC_PI_2 + PI * (k as f64 + 0.5) / THETA_BINS as f64
}

/// φ of azimuth node `j` of the N^G table.
fn phi_of_node(j: usize) -> f64 {
    PI * j as f64 / (PHI_BINS - 1) as f64
}

/// The bins around inclination `theta` and the weight of the upper one (clamped at the ends).
fn theta_lookup(theta: f32) -> (usize, usize, f32) {
    let x = (theta as f64 + FRAC_PI_2) / PI * THETA_BINS as f64 - 0.5;
    let x = x.clamp(0.0, (THETA_BINS - 1) as f64);
    let lo = (x.floor() as usize).min(THETA_BINS - 2);
    (lo, lo + 1, (x - lo as f64) as f32)
}

/// The logistic's CDF 1/(1 + e^{−x/s}).
fn logistic_cdf(x: f64, s: f64) -> f64 {
    1.0 / (1.0 + (-x / s).exp())
}

/// The cumulative integral from −π of the trimmed logistic of scale `s` wrapped around the circle, for any x
/// (it grows by 1 per turn): the trimmed CDF (F(y) − F(−π))/(F(π) − F(−π)) plus the whole turns before y.
fn wrapped_cdf(x: f64, s: f64) -> f64 {
    let turns = ((x + PI) / TAU).floor();
    let y = x - turns * TAU;
    let lo = logistic_cdf(-PI, s);
    let span = logistic_cdf(PI, s) - lo;
    turns + (logistic_cdf(y, s) - lo) / span
}

/// ∫ over φ ∈ [a − w, a + w] of N_p(φ) centred on 0 (the trimmed logistic wrapped), for w ≤ π.
fn logistic_mass(a: f64, w: f64, s: f64) -> f64 {
    wrapped_cdf(a + w, s) - wrapped_cdf(a - w, s)
}

impl DualScattering {
    /// The tables of `model` (~50 ms on one core; the render summary prints the time).
    pub fn new(model: &Chiang) -> DualScattering {
        let start = std::time::Instant::now();
        let variances = model.variances().map(|v| v as f64);
        let s = model.logistic_scale() as f64;
        // h = sin γ at the midpoints of equal steps in γ, each weighted cos γ dγ / 2: A₀ = F climbs to 1 as
        // |h| → 1, where equal steps in h would leave out the steepest part.
        let (hs, h_weights): (Vec<f32>, Vec<f64>) = (0..H_NODES)
            .map(|i| {
                let d = PI / H_NODES as f64;
                let gamma = -FRAC_PI_2 + (i as f64 + 0.5) * d;
                (gamma.sin() as f32, 0.5 * gamma.cos() * d)
            })
            .unzip();
        let mut averages = Vec::with_capacity(THETA_BINS);
        let mut global_azimuthal = Vec::with_capacity(THETA_BINS * PHI_BINS);
        for k in 0..THETA_BINS {
            let theta_o = theta_of_bin(k);
            let (sin_o, cos_o) = (theta_o.sin() as f32, theta_o.cos() as f32);
            let terms: Vec<_> = hs
                .iter()
                .map(|&h| model.azimuthal_terms(h, sin_o, cos_o))
                .collect();
            // Energy per order into each half, per channel, averaged over h.
            let mut forward = [[0.0f64; 3]; P_MAX + 1];
            let mut backward = [[0.0f64; 3]; P_MAX + 1];
            for ((ap, phis), &weight) in terms.iter().zip(&h_weights) {
                for p in 0..=P_MAX {
                    // ∫_{|φ|<π/2} N_p dφ: the residual's N_p is uniform.
                    let back_share = if p < P_MAX {
                        logistic_mass(-(phis[p] as f64), FRAC_PI_2, s)
                    } else {
                        0.5
                    };
                    for c in 0..3 {
                        let a = ap[p][c] as f64 * weight;
                        backward[p][c] += a * back_share;
                        forward[p][c] += a * (1.0 - back_share);
                    }
                }
            }
            let moments = lobe_moments(model, &variances, theta_o);
            averages.push(mix(&forward, &backward, &moments));
            // N^G_p(θo, φ): N_p averaged over incident azimuths within ±π/2 of φ, times A_p, averaged over h.
            for j in 0..PHI_BINS {
                let phi = phi_of_node(j);
                let mut ng = [Vec3::ZERO; P_MAX + 1];
                for ((ap, phis), &weight) in terms.iter().zip(&h_weights) {
                    for (p, n) in ng.iter_mut().enumerate() {
                        let box_average = if p < P_MAX {
                            logistic_mass(phi - phis[p] as f64, FRAC_PI_2, s) / PI
                        } else {
                            0.5 / PI
                        };
                        *n += Vec3::from(ap[p]) * (box_average * weight) as f32;
                    }
                }
                global_azimuthal.push(ng);
            }
        }
        let back = averages.iter().map(Averages::backscatter).collect();
        let limits = [published_limit(&averages), layered_limits(&averages)];
        DualScattering {
            model: *model,
            variances,
            averages,
            back,
            global_azimuthal,
            limits,
            build_seconds: start.elapsed().as_secs_f64(),
        }
    }

    /// Wall time of building these tables, seconds (one thread).
    pub fn build_seconds(&self) -> f64 {
        self.build_seconds
    }

    /// The averages at inclination `theta` (interpolated linearly between the table's bins).
    pub fn averages(&self, theta: f32) -> Averages {
        let (lo, hi, t) = theta_lookup(theta);
        let (a, b) = (&self.averages[lo], &self.averages[hi]);
        let l = |x: Vec3, y: Vec3| x.lerp(y, t);
        Averages {
            forward: l(a.forward, b.forward),
            backward: l(a.backward, b.backward),
            shift_forward: l(a.shift_forward, b.shift_forward),
            shift_backward: l(a.shift_backward, b.shift_backward),
            variance_forward: l(a.variance_forward, b.variance_forward),
            variance_backward: l(a.variance_backward, b.variance_backward),
        }
    }

    /// A_b, Δ_b, σ_b² at inclination `theta` (interpolated).
    pub fn backscatter(&self, theta: f32) -> Backscatter {
        let (lo, hi, t) = theta_lookup(theta);
        let (a, b) = (&self.back[lo], &self.back[hi]);
        Backscatter {
            attenuation: a.attenuation.lerp(b.attenuation, t),
            shift: a.shift.lerp(b.shift, t),
            variance: a.variance.lerp(b.variance, t),
        }
    }

    /// N^G_p (A_p included) per order at inclination `theta` and azimuth |`phi`| (bilinear).
    pub fn global_azimuthal(&self, theta: f32, phi: f32) -> [Vec3; P_MAX + 1] {
        let (lo, hi, t) = theta_lookup(theta);
        let x = (phi.abs() as f64 / PI * (PHI_BINS - 1) as f64).clamp(0.0, (PHI_BINS - 1) as f64);
        let j = (x.floor() as usize).min(PHI_BINS - 2);
        let u = (x - j as f64) as f32;
        let at = |k: usize, j: usize| &self.global_azimuthal[k * PHI_BINS + j];
        std::array::from_fn(|p| {
            let row = |k| at(k, j)[p].lerp(at(k, j + 1)[p], u);
            row(lo).lerp(row(hi), t)
        })
    }

    /// How many strands a light sample of `form` counts towards the light and behind the point (at most
    /// [`MAX_STRANDS`] each): past them what they change is below 1e-3 of the light for the most transparent
    /// inclination of the table. Published: ā_fⁿ < 1e-3 ahead, nothing behind. Layered: T_n < 1e-3 ahead and
    /// R_∞ − R_m < 1e-3 behind, from the largest ā_f and ā_b of the table.
    pub fn strand_limits(&self, form: DualForm) -> (u32, u32) {
        match form {
            DualForm::Published => self.limits[0],
            DualForm::Layered => self.limits[1],
        }
    }

    /// f · cos θi of the multiple-scattered light only (single scattering is the caller's, for the `crossed.direct`
    /// share of the light), RGB, for light from `wi` seen from `wo` (local hair frame, unit) that crosses
    /// `crossed` fibres on its way ([`Crossed::behind`] is read by [`DualForm::Layered`] only).
    pub fn fcos(&self, form: DualForm, wo: Vec3, wi: Vec3, crossed: Crossed) -> Vec3 {
        match form {
            DualForm::Layered => self.layered(wo, wi, crossed),
            DualForm::Published => self.published(wo, wi, crossed),
        }
    }

    /// [`DualForm::Layered`] (module docs). The back-scattered light arrives through Zinke et al.'s lobe, as if
    /// the fibres behind the point lay beside it along its own axis (hair lying in layers). Returning it from
    /// −ωi through the point's own lobes instead fits the radial fibres of a fur ball better (white furnace 0.91
    /// against 0.75; the blond fur ball under the city and a sun −21 % against −31 %) but lying hair worse
    /// (straight.hair under the city, blond: −26 % against −12 %), so the published lobe stays.
    fn layered(&self, wo: Vec3, wi: Vec3, crossed: Crossed) -> Vec3 {
        let g = Geometry::of(wo, wi);
        let along = self.averages(-g.theta_i);
        let (t, r) = (along.forward, along.backward);
        let (forward, backward) = fluxes(t, r, crossed.ahead, crossed.behind);
        let spread = along.variance_forward * crossed.ahead;
        let mut out = Vec3::ZERO;
        let scattered = (forward - Vec3::splat(crossed.direct)).max(Vec3::ZERO);
        if scattered.max_element() > 0.0 {
            out += scattered * self.global_lobes(&g, spread);
        }
        // Back-scattered light leaves towards the backward half only (`back_lobe`): no lookups for the rest.
        if backward.max_element() > 0.0 && g.phi.abs() < std::f32::consts::FRAC_PI_2 {
            let own = self.averages(g.theta_o);
            let albedo = own.forward + own.backward;
            out += backward * albedo * back_lobe(&g, &self.backscatter(g.theta_o), spread);
        }
        out
    }

    /// [`DualForm::Published`] (module docs): the unoccluded share `crossed.direct` of the light gets the local
    /// term alone, the rest crosses the mean number of strands of the occluded share (at least one).
    fn published(&self, wo: Vec3, wi: Vec3, crossed: Crossed) -> Vec3 {
        let g = Geometry::of(wo, wi);
        let back = self.backscatter(g.theta_o);
        // f_back cos θi = A_b M(θi; θo − Δ_b, σ_b² + extra) / π on the backward half.
        let f_back = |extra: Vec3| back.attenuation * back_lobe(&g, &back, extra);
        let direct = crossed.direct.clamp(0.0, 1.0);
        let local = if direct > 0.0 {
            direct * DENSITY_BACKWARD * f_back(Vec3::ZERO)
        } else {
            Vec3::ZERO
        };
        if direct >= 1.0 {
            return local;
        }
        let along = self.averages(-g.theta_i);
        let n = (crossed.ahead / (1.0 - direct)).max(1.0);
        let transmittance = along.forward.powf(n);
        if transmittance.max_element() <= 0.0 {
            return local;
        }
        let spread = along.variance_forward * n;
        local
            + (1.0 - direct)
                * transmittance
                * DENSITY_FORWARD
                * (self.global_lobes(&g, spread) + DENSITY_BACKWARD * f_back(spread))
    }

    /// f^G cos θi per unit of forward-scattered light whose direction is spread by `spread` (radians², per
    /// channel): Σ_p N^G_p M_p with M_p's variance widened to v_p + spread.
    fn global_lobes(&self, g: &Geometry, spread: Vec3) -> Vec3 {
        let ng = self.global_azimuthal(g.theta_o, g.phi);
        let tilted = self.model.tilted(g.sin_o, g.cos_o);
        let mut out = Vec3::ZERO;
        for (p, &(s, co)) in tilted.iter().enumerate() {
            for c in 0..3 {
                let v = self.variances[p] + spread[c] as f64;
                out[c] += ng[p][c] * m_p(v, g.sin_i, g.cos_i, s, co);
            }
        }
        out
    }
}

/// The angles both forms read of a pair of local directions.
struct Geometry {
    sin_o: f32,
    cos_o: f32,
    sin_i: f32,
    cos_i: f32,
    theta_o: f32,
    theta_i: f32,
    /// φ = φi − φo.
    phi: f32,
}

impl Geometry {
    fn of(wo: Vec3, wi: Vec3) -> Geometry {
        let (sin_o, cos_o) = sin_cos_theta(wo);
        let (sin_i, cos_i) = sin_cos_theta(wi);
        Geometry {
            sin_o,
            cos_o,
            sin_i,
            cos_i,
            theta_o: sin_o.atan2(cos_o),
            theta_i: sin_i.atan2(cos_i),
            phi: (wo.y * wi.z - wo.z * wi.y).atan2(wo.y * wi.y + wo.z * wi.z),
        }
    }
}

/// The back-scattering lobe per unit of light, f_back cos θi / A_b = M(θi; θo − Δ_b, σ_b² + `extra`) / π on the
/// backward half (|φ| < π/2), 0 on the forward half: it integrates to 1.
fn back_lobe(g: &Geometry, back: &Backscatter, extra: Vec3) -> Vec3 {
    if g.phi.abs() >= std::f32::consts::FRAC_PI_2 {
        return Vec3::ZERO;
    }
    Vec3::from(std::array::from_fn::<f32, 3, _>(|c| {
        let (s, co) = (g.theta_o - back.shift[c]).sin_cos();
        let v = (back.variance[c] + extra[c]).max(1e-6) as f64;
        m_p(v, g.sin_i, g.cos_i, s, co.abs()) / std::f32::consts::PI
    }))
}

/// [`layers`] at a fractional number of layers `n` ≥ 0 (a deep opacity map's footprint average), interpolated
/// linearly between the whole numbers either side.
pub fn layers_at(t: Vec3, r: Vec3, n: f32) -> (Vec3, Vec3) {
    let whole = n.max(0.0).floor();
    let (tn, rn) = layers(t, r, whole as u32);
    let f = n - whole;
    if f <= 0.0 {
        return (tn, rn);
    }
    let d = (Vec3::ONE - rn * r).max(Vec3::splat(1e-9));
    let (next_t, next_r) = (tn * t / d, rn + tn * tn * r / d);
    (tn.lerp(next_t, f), rn.lerp(next_r, f))
}

/// Transmittance and reflectance of `n` identical layers that each transmit `t` and reflect `r` (the adding
/// method of two-stream transport: a layer added behind a stack of (T, R) gives T t/(1 − R r) and
/// R + T² r/(1 − R r)).
pub fn layers(t: Vec3, r: Vec3, n: u32) -> (Vec3, Vec3) {
    let (mut tn, mut rn) = (Vec3::ONE, Vec3::ZERO);
    for _ in 0..n {
        let d = (Vec3::ONE - rn * r).max(Vec3::splat(1e-9));
        let next = tn * t / d;
        rn += tn * tn * r / d;
        tn = next;
    }
    (tn, rn)
}

/// The largest ā_f and ā_b of a table, per channel.
fn largest(averages: &[Averages]) -> (Vec3, Vec3) {
    averages.iter().fold((Vec3::ZERO, Vec3::ZERO), |(f, b), a| {
        (f.max(a.forward), b.max(a.backward))
    })
}

/// The light arriving at a point of a line of fibres that each pass `t` and return `r`, `ahead` of them between it and
/// the light and `behind` beyond it, per unit of light: (from the light's side, from behind). The point's own fibre
/// is a layer of the line too, so light reaches the fibres behind it only through it: with (T_n, R_n) the stack
/// ahead, R_m the one behind and R_x = r + t² R_m/(1 − r R_m) the point's fibre with the stack behind, the light
/// arriving from the front is T_n/(1 − R_n R_x) (passed by the stack ahead, reflected back and forth between it and
/// what is behind), and from behind that times t R_m/(1 − r R_m).
pub fn fluxes(t: Vec3, r: Vec3, ahead: f32, behind: f32) -> (Vec3, Vec3) {
    let floor = Vec3::splat(1e-9);
    let (tn, rn) = layers_at(t, r, ahead);
    let (_, rm) = layers_at(t, r, behind);
    let behind_x = r + t * t * rm / (Vec3::ONE - r * rm).max(floor);
    let forward = tn / (Vec3::ONE - rn * behind_x).max(floor);
    (forward, forward * t * rm / (Vec3::ONE - r * rm).max(floor))
}

/// [`DualScattering::strand_limits`] of [`DualForm::Published`].
fn published_limit(averages: &[Averages]) -> (u32, u32) {
    let t = largest(averages).0.max_element() as f64;
    if t <= 0.0 {
        return (1, 0);
    }
    let n = (1e-3f64).ln() / t.min(1.0 - 1e-9).ln();
    ((n.ceil() as u32).clamp(1, MAX_STRANDS), 0)
}

/// [`DualScattering::strand_limits`] of [`DualForm::Layered`].
fn layered_limits(averages: &[Averages]) -> (u32, u32) {
    let (t, r) = largest(averages);
    let ahead = (1..=MAX_STRANDS)
        .find(|&n| layers(t, r, n).0.max_element() < 1e-3)
        .unwrap_or(MAX_STRANDS);
    let infinite = layers(t, r, 4096).1;
    let behind = (0..=MAX_STRANDS)
        .find(|&m| (infinite - layers(t, r, m).1).max_element() < 1e-3)
        .unwrap_or(MAX_STRANDS);
    (ahead, behind)
}

/// Per order p, the mean and variance of δ = θi + θo under M_p(θi, θo′_p) cos θi (a density over θi) at `theta_o`.
fn lobe_moments(
    model: &Chiang,
    variances: &[f64; P_MAX + 1],
    theta_o: f64,
) -> [(f64, f64); P_MAX + 1] {
    let tilted = model.tilted(theta_o.sin() as f32, theta_o.cos() as f32);
    let d = PI / THETA_I_NODES as f64;
    std::array::from_fn(|p| {
        let (so, co) = tilted[p];
        let (mut w, mut m1, mut m2) = (0.0f64, 0.0f64, 0.0f64);
        for i in 0..THETA_I_NODES {
            let theta_i = -FRAC_PI_2 + (i as f64 + 0.5) * d;
            let (si, ci) = theta_i.sin_cos();
            let density = m_p(variances[p], si as f32, ci as f32, so, co) as f64 * ci * d;
            let delta = theta_i + theta_o;
            w += density;
            m1 += density * delta;
            m2 += density * delta * delta;
        }
        let mean = m1 / w;
        (mean, (m2 / w - mean * mean).max(0.0))
    })
}

/// The averages from each order's energy into the two halves and its moments of δ: energies summed, means and
/// variances of the energy-weighted mixture.
fn mix(
    forward: &[[f64; 3]; P_MAX + 1],
    backward: &[[f64; 3]; P_MAX + 1],
    moments: &[(f64, f64); P_MAX + 1],
) -> Averages {
    let half = |energy: &[[f64; 3]; P_MAX + 1]| -> (Vec3, Vec3, Vec3) {
        let mut out = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
        #[allow(clippy::needless_range_loop)] // c indexes the inner arrays of every order
        for c in 0..3 {
            let total: f64 = (0..=P_MAX).map(|p| energy[p][c]).sum();
            let mean = if total > 0.0 {
                (0..=P_MAX)
                    .map(|p| energy[p][c] * moments[p].0)
                    .sum::<f64>()
                    / total
            } else {
                0.0
            };
            let variance = if total > 0.0 {
                (0..=P_MAX)
                    .map(|p| energy[p][c] * (moments[p].1 + (moments[p].0 - mean).powi(2)))
                    .sum::<f64>()
                    / total
            } else {
                0.0
            };
            out.0[c] = total as f32;
            out.1[c] = mean as f32;
            out.2[c] = variance as f32;
        }
        out
    };
    let (f, fm, fv) = half(forward);
    let (b, bm, bv) = half(backward);
    Averages {
        forward: f,
        backward: b,
        shift_forward: fm,
        shift_backward: bm,
        variance_forward: fv,
        variance_backward: bv,
    }
}

#[cfg(test)]
mod tests;
