//! Uniform sampling of the sphere, the [`super::Sampling::Uniform`] baseline of every model.

use glam::Vec3;
use std::f32::consts::{PI, TAU};

/// The density of [`uniform_sphere`], 1/4π sr⁻¹.
pub const UNIFORM_SPHERE_PDF: f32 = 1.0 / (4.0 * PI);

/// A direction uniform on the unit sphere from two uniform numbers in [0, 1), in the local hair frame:
/// sin θ = 1 − 2a is uniform on [−1, 1] (Archimedes: equal heights, equal areas), φ = 2πb.
#[inline]
pub fn uniform_sphere(a: f32, b: f32) -> Vec3 {
    let sin_theta = (1.0 - 2.0 * a).clamp(-1.0, 1.0);
    let cos_theta = (1.0 - sin_theta * sin_theta).max(0.0).sqrt();
    let (s, c) = (TAU * b).sin_cos();
    Vec3::new(sin_theta, cos_theta * c, cos_theta * s)
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
}
