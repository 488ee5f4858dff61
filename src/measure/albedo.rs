//! The single-fibre albedo of a hair material, and Chiang's absorption matched to it (`cuticle study models`
//! compares models "at matched colour").
//!
//! **Albedo** here is the energy one fibre scatters once, per RGB channel: ∫ f(ωo, ωi) cos θi dωi, averaged over
//! ωo uniform on the sphere and the offset h uniform in [−1, 1] (only Chiang reads h). The inner integral is a
//! midpoint rule over a grid uniform in (sin θi, φi) — [`GRID_SIN`] × [`GRID_PHI`] cells of equal solid angle —
//! and the outer average a midpoint rule over [`VIEWS`] values of sin θo and [`OFFSETS`] values of h. Deterministic
//! and smooth in the parameters, so a bisection on it converges.
//!
//! **Why the albedo and not the image mean**: the image mean depends on the scene's lights, its self-shadowing and
//! its multiple scattering, which is exactly where an energy-conserving model is meant to differ from the thesis'
//! models; the albedo says what a fibre does to light once, independent of the scene, and costs a second rather
//! than renders. Chiang is energy conserving (albedo 1 at σa = 0), so any albedo in (0, 1) is reached by some σa.

use glam::Vec3;

use crate::bsdf::chiang::ChiangParams;
use crate::bsdf::{Bsdf, Material};

/// Cells of the direction grid along sin θi: a Marschner R lobe of β = 5° spans about 4 cells at the equator.
pub const GRID_SIN: usize = 96;
/// Cells along φi (3.75° each).
pub const GRID_PHI: usize = 96;
/// Values of sin θo averaged over.
pub const VIEWS: usize = 8;
/// Values of h averaged over (Chiang only; the other models ignore h).
pub const OFFSETS: usize = 8;

/// ∫ f cos θi dωi of `bsdf` at `wo` (local frame), per channel.
pub fn directional_albedo<B: Bsdf + ?Sized>(bsdf: &B, wo: Vec3) -> Vec3 {
    let d_omega = 4.0 * std::f32::consts::PI / (GRID_SIN * GRID_PHI) as f32;
    let mut sum = Vec3::ZERO;
    for i in 0..GRID_SIN {
        let sin_t = -1.0 + 2.0 * (i as f32 + 0.5) / GRID_SIN as f32;
        let cos_t = (1.0 - sin_t * sin_t).max(0.0).sqrt();
        for j in 0..GRID_PHI {
            let phi = std::f32::consts::TAU * (j as f32 + 0.5) / GRID_PHI as f32;
            let wi = Vec3::new(sin_t, cos_t * phi.cos(), cos_t * phi.sin());
            sum += bsdf.eval(wo, wi) * cos_t;
        }
    }
    sum * d_omega
}

/// The fibre albedo of `material` (see the module docs), per channel.
pub fn fibre_albedo(material: &Material) -> Vec3 {
    let mut sum = Vec3::ZERO;
    for v in 0..VIEWS {
        let sin_o = -1.0 + 2.0 * (v as f32 + 0.5) / VIEWS as f32;
        let wo = Vec3::new(sin_o, (1.0 - sin_o * sin_o).max(0.0).sqrt(), 0.0);
        let offsets = if material.uses_offset() { OFFSETS } else { 1 };
        for k in 0..offsets {
            let h = -1.0 + 2.0 * (k as f32 + 0.5) / offsets as f32;
            sum += directional_albedo(&material.at(h), wo) / offsets as f32;
        }
    }
    sum / VIEWS as f32
}

/// Chiang's σa (per unit fibre radius) whose fibre albedo matches `target` per channel, with `base`'s other
/// parameters; by bisection on ln σa in [1e-4, 1e2], each channel alone (Chiang's channels do not mix). A target
/// above the albedo at σa = 1e-4 gives 1e-4, one below the albedo at 1e2 gives 1e2.
pub fn chiang_sigma_a_for_albedo(base: ChiangParams, target: Vec3) -> Result<Vec3, String> {
    let albedo = |sigma_a: Vec3| -> Result<Vec3, String> {
        let model = crate::bsdf::chiang::Chiang::new(ChiangParams { sigma_a, ..base })
            .map_err(|e| e.to_string())?;
        let material = Material {
            scattering: crate::bsdf::Scattering::Chiang(model),
            tint_diffuse_by_strand: false,
            name: "chiang",
            dual: Default::default(),
        };
        Ok(fibre_albedo(&material))
    };
    let (mut lo, mut hi) = (Vec3::splat(1e-4f32.ln()), Vec3::splat(1e2f32.ln()));
    // 16 halvings of a 13.8-wide log interval: σa to 2e-4 relative, below the albedo grid's own error.
    for _ in 0..16 {
        let mid = 0.5 * (lo + hi);
        let a = albedo(mid.exp())?;
        for c in 0..3 {
            // Albedo falls as σa grows.
            if a[c] > target[c] {
                lo[c] = mid[c];
            } else {
                hi[c] = mid[c];
            }
        }
    }
    Ok((0.5 * (lo + hi)).exp())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::chiang::Chiang;
    use crate::bsdf::Scattering;

    fn chiang(sigma_a: Vec3) -> Material {
        Material {
            scattering: Scattering::Chiang(
                Chiang::new(ChiangParams {
                    sigma_a,
                    ..ChiangParams::default()
                })
                .unwrap(),
            ),
            tint_diffuse_by_strand: false,
            name: "chiang",
            dual: Default::default(),
        }
    }

    #[test]
    fn chiang_without_absorption_scatters_everything() {
        let a = fibre_albedo(&chiang(Vec3::ZERO));
        // The grid's own error at βm = βn = 0.3 (broad lobes) is well under 1 %.
        for c in 0..3 {
            assert!((a[c] - 1.0).abs() < 0.01, "albedo {a}");
        }
    }

    #[test]
    fn matching_recovers_the_absorption_that_gave_the_albedo() {
        let sigma_a = Vec3::new(0.2, 0.8, 2.5);
        let target = fibre_albedo(&chiang(sigma_a));
        assert!(target.x > target.y && target.y > target.z, "{target}");
        let found = chiang_sigma_a_for_albedo(ChiangParams::default(), target).unwrap();
        for c in 0..3 {
            assert!(
                (found[c] / sigma_a[c] - 1.0).abs() < 1e-3,
                "σa {sigma_a} gave albedo {target}, matched {found}"
            );
        }
    }
}
