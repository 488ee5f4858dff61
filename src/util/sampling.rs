//! Sampling of directions: the uniform sphere, the `Sampling::Uniform` baseline of every hair model, the sampler of
//! points on spherical lights and of constant environments, and the map of per-strand noise vectors.

use crate::util::real::Real;
use glam::Vec3;
use std::f32::consts::{PI, TAU};

/// The density of [`uniform_sphere`], 1/4π sr⁻¹.
pub const UNIFORM_SPHERE_PDF: f32 = 1.0 / (4.0 * PI);

/// A direction uniform on the unit sphere from two uniform numbers in [0, 1), with +x as the pole (the tangent u
/// in the local hair frame): sin θ = 1 − 2a is uniform on [−1, 1] (Archimedes: equal heights, equal areas), φ = 2πb
/// from +y towards +z.
#[inline]
pub fn uniform_sphere(a: f32, b: f32) -> Vec3 {
    Vec3::from_array(uniform_sphere_of(a, b))
}

/// [`uniform_sphere`] in any number type ([`Real`]), one direction per lane, component by component
/// (`[x, y, z]`).
#[inline(always)]
pub fn uniform_sphere_of<R: Real>(a: R, b: R) -> [R; 3] {
    let one = R::splat(1.0);
    let sin_theta = (one - R::splat(2.0) * a).clamp_to(-1.0, 1.0);
    let cos_theta = (one - sin_theta * sin_theta).max(R::splat(0.0)).sqrt();
    let (s, c) = (R::splat(TAU) * b).sin_cos();
    [sin_theta, cos_theta * c, cos_theta * s]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_sphere_is_unit_and_covers_both_poles() {
        assert!((uniform_sphere(0.0, 0.3) - Vec3::X).length() < 1e-6);
        assert!((uniform_sphere(1.0, 0.3) + Vec3::X).length() < 1e-6);
        assert!((uniform_sphere(0.5, 0.25) - Vec3::Z).length() < 1e-6);
        for i in 0..50 {
            let v = uniform_sphere(i as f32 / 50.0, (i * 7 % 50) as f32 / 50.0);
            assert!((v.length() - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn uniform_sphere_has_equal_mass_in_equal_height_bands() {
        // Archimedes: the 8 bands of equal height in x, and the 8 equal sectors in φ, each hold 1/8 of a 64 × 64
        // stratified grid over (a, b) exactly, up to the strata that fall on a boundary (none here: 64 / 8 = 8).
        let n = 64;
        let (mut bands, mut sectors) = ([0u32; 8], [0u32; 8]);
        for i in 0..n {
            for j in 0..n {
                let v = uniform_sphere((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                bands[(((1.0 - v.x) / 2.0 * 8.0) as usize).min(7)] += 1;
                let phi = v.z.atan2(v.y).rem_euclid(TAU);
                sectors[((phi / TAU * 8.0) as usize).min(7)] += 1;
            }
        }
        assert_eq!(bands, [(n * n / 8) as u32; 8]);
        assert_eq!(sectors, [(n * n / 8) as u32; 8]);
    }
}
