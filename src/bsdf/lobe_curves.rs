//! Lobe curves: f per lobe along a one-parameter sweep of directions, the data of the thesis' figure 4 (Ou et al.
//! 2012's longitudinal and azimuthal lobes). Plain numbers, no drawing: `cuticle plot-bsdf` ([`crate::plot::bsdf`])
//! charts them and the model tests check their peaks. Angles in radians, in the local hair frame (see [`super`]).

use super::frame::from_spherical;
use super::{Bsdf, LobeValues};
use std::f32::consts::{FRAC_PI_2, PI};

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
