//! Uniform sampling of a cone of directions (pbrt-v3 §13.6.4 `UniformSampleCone`), shared by the sun-sized
//! [`super::Distant`] light and the solid-angle sampling of spherical [`super::AreaLight`]s.
//!
//! A cone of half-angle θ_max ≤ π/2 around a unit axis has solid angle Ω = 2π (1 − cos θ_max), and a uniform
//! direction in it has density 1/Ω. Small cones (the sun is 0.0047 rad) lose every digit of 1 − cos θ_max to
//! cancellation in f32, so the cone is built from sin²θ_max and 1 − cos θ_max computed without subtraction, and
//! membership is tested on |ω × axis|² ≤ sin²θ_max rather than on cos θ ≥ cos θ_max.

use glam::Vec3;
use std::f32::consts::TAU;

/// A cone of directions of half-angle θ_max ∈ [0, π/2] around a unit axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cone {
    /// Unit axis.
    axis: Vec3,
    /// Unit vectors completing `axis` to an orthonormal frame.
    tangent: Vec3,
    bitangent: Vec3,
    /// sin²θ_max.
    sin2_theta_max: f32,
    /// sin θ_max.
    sin_theta_max: f32,
    /// 1 − cos θ_max, without cancellation.
    one_minus_cos_theta_max: f32,
}

/// Absolute slack of [`Cone::contains`] on sin θ_max. A unit f32 vector is only resolved to ≈ 6e-8 per component
/// (half an ulp of 1), so a direction drawn on the rim by [`Cone::sample`] may sit that far outside it; 4 ulps keep
/// every sample inside. The cone grows by < 3e-7 rad: 6e-5 of the sun's radius, 1e-4 of its solid angle.
const RIM_SLACK: f32 = 4.0 * f32::EPSILON;

impl Cone {
    /// The cone of half-angle `theta_max` (radians, clamped to [0, π/2]) around the unit `axis`.
    pub fn from_half_angle(axis: Vec3, theta_max: f32) -> Cone {
        let theta_max = theta_max.clamp(0.0, std::f32::consts::FRAC_PI_2);
        let half = (0.5 * theta_max).sin();
        // 1 − cos θ = 2 sin²(θ/2).
        Cone::new(axis, theta_max.sin().powi(2), 2.0 * half * half)
    }

    /// The cone subtended by a sphere whose sin²θ_max = r²/d² (clamped to [0, 1]) around the unit `axis`.
    pub fn from_sin2(axis: Vec3, sin2_theta_max: f32) -> Cone {
        let s2 = sin2_theta_max.clamp(0.0, 1.0);
        // 1 − cos θ = sin²θ / (1 + cos θ).
        Cone::new(axis, s2, s2 / (1.0 + (1.0 - s2).sqrt()))
    }

    fn new(axis: Vec3, sin2_theta_max: f32, one_minus_cos_theta_max: f32) -> Cone {
        let (tangent, bitangent) = axis.any_orthonormal_pair();
        Cone {
            axis,
            tangent,
            bitangent,
            sin2_theta_max,
            sin_theta_max: sin2_theta_max.sqrt(),
            one_minus_cos_theta_max,
        }
    }

    /// The solid angle Ω = 2π (1 − cos θ_max), sr.
    #[inline]
    pub fn solid_angle(&self) -> f32 {
        TAU * self.one_minus_cos_theta_max
    }

    /// The uniform density 1/Ω, or 0 when Ω underflows to 0 (a cone too narrow for f32).
    #[inline]
    pub fn pdf(&self) -> f32 {
        let pdf = 1.0 / self.solid_angle();
        if pdf.is_finite() {
            pdf
        } else {
            0.0
        }
    }

    /// A direction uniform in the cone from two uniform numbers in [0, 1): 1 − cos θ = u₀ (1 − cos θ_max),
    /// φ = 2π u₁.
    #[inline]
    pub fn sample(&self, u: [f32; 2]) -> Vec3 {
        let one_minus_cos = u[0].clamp(0.0, 1.0) * self.one_minus_cos_theta_max;
        // sin²θ = (1 − cos θ)(1 + cos θ), capped at the rim so rounding cannot leave the cone.
        let sin2 = (one_minus_cos * (2.0 - one_minus_cos)).min(self.sin2_theta_max);
        let (sin_theta, cos_theta) = (sin2.max(0.0).sqrt(), 1.0 - one_minus_cos);
        let (sin_phi, cos_phi) = (TAU * u[1]).sin_cos();
        sin_theta * (cos_phi * self.tangent + sin_phi * self.bitangent) + cos_theta * self.axis
    }

    /// Whether the unit direction `w` lies in the cone (rim included, up to [`RIM_SLACK`]).
    #[inline]
    pub fn contains(&self, w: Vec3) -> bool {
        // sin θ = |w × axis| = |(w − axis) × axis|: the difference is exact-ish for w near the axis, where
        // w × axis itself would cancel down to rounding noise.
        let sin_theta = (w - self.axis).cross(self.axis).length();
        w.dot(self.axis) > 0.0 && sin_theta <= self.sin_theta_max + RIM_SLACK
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use rand::Rng;
    use rand_pcg::Pcg32;

    /// The angle between two directions, in f64 and without acos' loss near 0: 2 asin(|â − b̂| / 2).
    pub(crate) fn angle_between(a: Vec3, b: Vec3) -> f64 {
        let (a, b) = (a.as_dvec3().normalize(), b.as_dvec3().normalize());
        2.0 * (0.5 * (a - b).length()).min(1.0).asin()
    }

    #[test]
    fn samples_stay_inside_and_solid_angle_is_exact_for_tiny_cones() {
        let axis = Vec3::new(1.0, 2.0, -0.5).normalize();
        let mut rng = Pcg32::new(1, 1);
        for theta_max in [1e-4f32, 0.004_65, 0.3, std::f32::consts::FRAC_PI_2] {
            let cone = Cone::from_half_angle(axis, theta_max);
            let exact = std::f64::consts::TAU * (1.0 - (theta_max as f64).cos());
            let rel = (cone.solid_angle() as f64 - exact).abs() / exact;
            assert!(
                rel < 1e-5,
                "θmax {theta_max}: Ω {} vs {exact}",
                cone.solid_angle()
            );
            for k in 0..2000 {
                let u = rng.random();
                let u = if k == 0 { [1.0, 0.3] } else { u };
                let w = cone.sample(u);
                assert!((w.length() - 1.0).abs() < 1e-5);
                assert!(cone.contains(w), "θmax {theta_max}, u {u:?}: {w} outside");
                let angle = angle_between(w, axis);
                assert!(
                    angle <= theta_max as f64 + 3e-7,
                    "θmax {theta_max}: angle {angle}"
                );
            }
            // Just outside the rim is outside.
            let (t, _) = axis.any_orthonormal_pair();
            let outside =
                ((theta_max * 1.01).cos() * axis + (theta_max * 1.01).sin() * t).normalize();
            assert!(
                !cone.contains(outside) || theta_max > 1.5,
                "θmax {theta_max}"
            );
        }
        let sphere = Cone::from_sin2(axis, 0.25); // θmax = 30°.
        assert!((sphere.solid_angle() - TAU * (1.0 - 0.75f32.sqrt())).abs() < 1e-6);
        assert_eq!(Cone::from_half_angle(axis, 0.0).pdf(), 0.0);
    }
}
