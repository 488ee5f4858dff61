//! A directional light: the sun, as a delta direction or as a small disk of uniform radiance.
//!
//! Parameters (as in the scene file):
//! - `direction`: the way the light **travels** (from the sun into the scene), world space, any non-zero length.
//!   The direction towards the sun is ω_s = −direction.
//! - `irradiance` E (RGB, W m⁻², ≥ 0): measured on a surface **perpendicular to the sun direction**.
//! - `angular_radius` θ_max (radians, in [0, π/2], default 0). The real sun is 0.00465 rad.
//!
//! With θ_max = 0 the light is a delta distribution: [`Distant::sample_li`] returns ω_s with pdf 1 and
//! "radiance" E (pbrt's convention for delta lights), and no escaping ray can see it ([`Distant::le`] = 0).
//!
//! With θ_max > 0 the sun is a cone of solid angle Ω = 2π (1 − cos θ_max) of uniform radiance L = E / Ω,
//! sampled uniformly (pdf 1/Ω) so BSDF-sampled rays can hit it too, for MIS. Then ∫_cone L dω = E exactly, but the
//! irradiance on a surface facing the sun is ∫ L cos θ dω = E (1 + cos θ_max)/2, which is E only in the
//! small-angle limit (0.999995 E for the real sun); E is the radiant flux density of the beam, not the
//! cosine-weighted value.

use glam::Vec3;

use super::cone::Cone;
use super::{check, check_color, check_direction, clamp_u, unit, LightError, LightSample};
use crate::util::color::luminance;

/// A directional light (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Distant {
    /// ω_s: unit direction towards the sun.
    to_sun: Vec3,
    /// E, W m⁻², perpendicular to ω_s.
    irradiance: Vec3,
    /// θ_max, radians.
    angular_radius: f32,
    /// The sun's cone (`None` for a delta light, or a cone too narrow for f32).
    cone: Option<Cone>,
    /// L = E / Ω for a cone; E for a delta light.
    radiance: Vec3,
}

impl Distant {
    /// A distant light whose light travels along `direction`, delivering `irradiance` from a disk of angular
    /// radius `angular_radius` (radians; 0 for a delta light). A radius too small for its cone's solid angle
    /// to be represented in f32 (≲ 1e-19 rad) is treated as 0.
    pub fn new(
        direction: Vec3,
        irradiance: Vec3,
        angular_radius: f32,
    ) -> Result<Distant, LightError> {
        let travel = check_direction("distant", "direction", direction)?;
        check_color("distant", "irradiance", irradiance)?;
        check(
            "distant",
            "angular_radius",
            angular_radius,
            "in [0, pi/2] radians",
            (0.0..=std::f32::consts::FRAC_PI_2).contains(&angular_radius),
        )?;
        let to_sun = -travel;
        let cone = Some(Cone::from_half_angle(to_sun, angular_radius)).filter(|c| c.pdf() > 0.0);
        let radiance = match &cone {
            Some(c) => irradiance * c.pdf(),
            None => irradiance,
        };
        Ok(Distant {
            to_sun,
            irradiance,
            angular_radius: if cone.is_some() { angular_radius } else { 0.0 },
            cone,
            radiance,
        })
    }

    /// The unit direction towards the sun, ω_s = −direction.
    pub fn to_sun(&self) -> Vec3 {
        self.to_sun
    }

    /// E, W m⁻², perpendicular to the sun direction.
    pub fn irradiance(&self) -> Vec3 {
        self.irradiance
    }

    /// θ_max, radians (0 for a delta light).
    pub fn angular_radius(&self) -> f32 {
        self.angular_radius
    }

    /// Whether the light is a delta direction (θ_max = 0).
    #[inline]
    pub fn is_delta(&self) -> bool {
        self.cone.is_none()
    }

    /// The sun's radiance inside its cone, L = E / Ω (for a delta light: E).
    pub fn radiance(&self) -> Vec3 {
        self.radiance
    }

    /// A direction towards the sun: ω_s itself (pdf 1, `delta`) or uniform in the cone (pdf 1/Ω).
    #[inline]
    pub fn sample_li(&self, u: [f32; 2]) -> Option<LightSample> {
        let (wi, pdf, delta) = match &self.cone {
            None => (self.to_sun, 1.0, true),
            Some(cone) => (cone.sample(clamp_u(u)), cone.pdf(), false),
        };
        Some(LightSample {
            wi,
            radiance: self.radiance,
            pdf,
            distance: f32::INFINITY,
            delta,
        })
    }

    /// 1/Ω for `wi` inside the cone, else 0 (always 0 for a delta light).
    #[inline]
    pub fn pdf_li(&self, wi: Vec3) -> f32 {
        match (&self.cone, unit(wi)) {
            (Some(cone), Some(w)) if cone.contains(w) => cone.pdf(),
            _ => 0.0,
        }
    }

    /// L for an escaping ray travelling along `dir` into the cone, else 0 (always 0 for a delta light).
    #[inline]
    pub fn le(&self, dir: Vec3) -> Vec3 {
        match (&self.cone, unit(dir)) {
            (Some(cone), Some(w)) if cone.contains(w) => self.radiance,
            _ => Vec3::ZERO,
        }
    }

    /// Power through a disk of radius `scene_radius` perpendicular to the beam: π r² · luminance(E).
    pub fn power(&self, scene_radius: f32) -> f32 {
        std::f32::consts::PI * scene_radius * scene_radius * luminance(self.irradiance)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light::cone::tests::angle_between;
    use crate::light::Light;
    use rand::Rng;
    use rand_pcg::Pcg32;

    /// Quadrature grid of the cone integral (cos θ × φ); the midpoint rule in cos θ is exact for a constant
    /// integrand, so the error comes only from the rim cells (< 1/N_THETA of the cap).
    const N_THETA: usize = 400;
    const N_PHI: usize = 64;

    fn sun(radius: f32) -> Distant {
        Distant::new(
            Vec3::new(0.3, -1.0, 0.2),
            Vec3::new(1.0, 0.9, 0.7) * 3.0,
            radius,
        )
        .unwrap()
    }

    #[test]
    fn delta_when_radius_is_zero() {
        let l = Light::Distant(sun(0.0));
        assert!(l.is_delta() && l.is_infinite());
        let s = l.sample_li(Vec3::ZERO, [0.3, 0.8]).unwrap();
        assert!(s.delta && s.pdf == 1.0 && s.distance == f32::INFINITY);
        assert!((s.wi - Vec3::new(-0.3, 1.0, -0.2).normalize()).length() < 1e-6);
        assert_eq!(s.radiance, Vec3::new(1.0, 0.9, 0.7) * 3.0);
        assert_eq!(l.pdf_li(Vec3::ZERO, s.wi), 0.0);
        assert_eq!(l.le(s.wi), Vec3::ZERO);
        assert!(l
            .intersect(&crate::ray::Ray::new(Vec3::ZERO, s.wi))
            .is_none());
    }

    #[test]
    fn cone_samples_inside_and_pdf_consistent() {
        let mut rng = Pcg32::new(9, 9);
        for radius in [0.004_65f32, 0.1, 0.5] {
            let l = Light::Distant(sun(radius));
            assert!(!l.is_delta());
            let axis = Vec3::new(-0.3, 1.0, -0.2).normalize();
            for _ in 0..5_000 {
                let s = l.sample_li(Vec3::ONE, rng.random()).unwrap();
                let angle = angle_between(s.wi, axis);
                assert!(
                    angle <= radius as f64 + 3e-7,
                    "radius {radius}: angle {angle}"
                );
                assert!(!s.delta && s.distance == f32::INFINITY);
                assert_eq!(s.pdf, l.pdf_li(Vec3::ONE, s.wi), "radius {radius}");
                assert_eq!(s.radiance, l.le(s.wi));
            }
            let pdf = l.pdf_li(Vec3::ZERO, axis);
            let omega = std::f64::consts::TAU * (1.0 - (radius as f64).cos());
            assert!(
                (pdf as f64 * omega - 1.0).abs() < 1e-4,
                "radius {radius}: pdf {pdf}"
            );
            assert_eq!(l.pdf_li(Vec3::ZERO, -axis), 0.0);
        }
    }

    #[test]
    fn cone_radiance_integrates_to_irradiance() {
        for radius in [0.004_65f32, 0.2] {
            let d = sun(radius);
            let axis = d.to_sun();
            let (t, b) = axis.any_orthonormal_pair();
            // ∫ L dω over a cap 10 % wider than the sun, in (cos θ, φ) around ω_s, with 1 − cos θ in f64.
            let cap = 2.0 * (0.55 * radius as f64).sin().powi(2);
            let mut sum = Vec3::ZERO.as_dvec3();
            for i in 0..N_THETA {
                let omc = cap * (i as f64 + 0.5) / N_THETA as f64;
                let sin_t = (omc * (2.0 - omc)).sqrt();
                for j in 0..N_PHI {
                    let phi = std::f64::consts::TAU * (j as f64 + 0.5) / N_PHI as f64;
                    let w = (sin_t * phi.cos()) as f32 * t
                        + (sin_t * phi.sin()) as f32 * b
                        + (1.0 - omc) as f32 * axis;
                    sum += d.le(w).as_dvec3();
                }
            }
            let e = sum * (cap * std::f64::consts::TAU / (N_THETA * N_PHI) as f64);
            let rel = (e / d.irradiance().as_dvec3() - 1.0).abs().max_element();
            assert!(
                rel < 0.01,
                "radius {radius}: ∫L dω = {e:?} vs E = {}",
                d.irradiance()
            );
        }
    }

    #[test]
    fn degenerate_inputs_stay_finite() {
        for radius in [0.0, 1e-30, 0.004_65, std::f32::consts::FRAC_PI_2] {
            let l = Light::Distant(sun(radius));
            for d in [
                Vec3::ZERO,
                Vec3::NAN,
                Vec3::INFINITY,
                Vec3::splat(1e-30),
                Vec3::splat(1e30),
                -Vec3::Y,
            ] {
                assert!(
                    l.le(d).is_finite() && l.pdf_li(Vec3::NAN, d).is_finite(),
                    "radius {radius}, dir {d}"
                );
            }
            for u in [[0.0, 0.0], [1.0, 1.0], [f32::NAN, 0.5], [-2.0, 7.0]] {
                let s = l.sample_li(Vec3::NAN, u).unwrap();
                assert!(
                    s.wi.is_finite() && s.radiance.is_finite() && s.pdf > 0.0 && s.pdf.is_finite(),
                    "{s:?}"
                );
            }
            assert!(l.power(10.0).is_finite());
        }
        // A radius below what f32 can give a solid angle to is a delta light.
        assert!(sun(1e-30).is_delta());
    }

    #[test]
    fn bad_parameters_are_named() {
        let e = Distant::new(Vec3::ZERO, Vec3::ONE, 0.0)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("distant light: direction"), "{e}");
        let e = Distant::new(Vec3::Y, Vec3::ONE, -0.1)
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "distant light: angular_radius must be in [0, pi/2] radians, got -0.1"
        );
        let e = Distant::new(Vec3::Y, Vec3::new(1.0, f32::INFINITY, 1.0), 0.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("irradiance") && e.contains("inf"), "{e}");
    }
}
