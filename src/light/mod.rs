//! Light sources: what a shading point sees of the emitters, for next-event estimation and for rays that
//! escape or hit an emitter after BSDF sampling (so the two strategies can be combined by MIS).
//!
//! # Conventions (every light)
//!
//! - Positions and directions are in **world space**.
//! - `wi` is a **unit vector from the shading point towards the light** (the direction a shadow ray travels).
//! - pdfs are densities **per unit solid angle** (sr⁻¹) at the shading point, whatever the light samples
//!   internally (area lights convert with dist² / |cos θ_light|). A delta light's "pdf" is 1 and its
//!   [`LightSample::radiance`] is then the irradiance it delivers (pbrt's convention), flagged by
//!   [`LightSample::delta`].
//! - Radiance is linear RGB in a [`Vec3`] (W m⁻² sr⁻¹ per channel in scene units; irradiance W m⁻²).
//! - Infinite lights ([`Distant`], [`Environment`]) are seen by escaping rays through [`Light::le`]; area lights
//!   by [`Light::intersect`]. Every method returns finite values for every input and allocates nothing.
//!
//! # Files
//!
//! - [`distribution`]: piecewise-constant 1-D/2-D distributions (importance sampling of maps, light selection).
//! - [`environment`]: a lat-long HDR environment map or a constant sky.
//! - [`distant`]: a directional light, delta or a sun-sized cone.
//! - [`area`]: quad, disk and sphere emitters.

pub mod area;
mod cone;
pub mod distant;
pub mod distribution;
pub mod environment;

use std::path::PathBuf;

use glam::Vec3;

use crate::image::ImageError;
use crate::ray::Ray;

pub use area::{AreaLight, Shape};
pub use distant::Distant;
pub use distribution::{Distribution1D, Distribution2D};
pub use environment::Environment;

/// A light source of the scene.
#[derive(Debug, Clone)]
pub enum Light {
    /// A directional light (a sun): delta, or a small cone.
    Distant(Distant),
    /// Light from infinitely far away in every direction: a lat-long map or a constant.
    Environment(Environment),
    /// An emitting quad, disk or sphere.
    Area(AreaLight),
}

/// One direction towards a light, drawn by [`Light::sample_li`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightSample {
    /// Unit direction from the shading point towards the light, world space.
    pub wi: Vec3,
    /// Radiance arriving at the shading point along −`wi` (for a delta light: the irradiance it delivers).
    pub radiance: Vec3,
    /// Density of `wi` per unit solid angle, > 0 (1 for a delta light).
    pub pdf: f32,
    /// Distance to the sampled point on the light: `f32::INFINITY` for distant and environment lights, the hit
    /// distance for area lights (a shadow ray must stop short of it).
    pub distance: f32,
    /// Whether `wi` was the only possible direction (a delta light): no MIS with BSDF sampling.
    pub delta: bool,
}

impl Light {
    /// Draws a direction towards the light as seen from `p`, from two uniform numbers in [0, 1). `None` when
    /// there is nothing to sample from `p` (the back of a one-sided emitter, `p` on the emitter, a zero pdf).
    #[inline]
    pub fn sample_li(&self, p: Vec3, u: [f32; 2]) -> Option<LightSample> {
        match self {
            Light::Distant(l) => l.sample_li(u),
            Light::Environment(l) => l.sample_li(u),
            Light::Area(l) => l.sample_li(p, u),
        }
    }

    /// The density per unit solid angle with which [`Light::sample_li`] at `p` draws `wi` (0 for a delta light,
    /// for directions that miss the light, and wherever `sample_li` would return `None`).
    #[inline]
    pub fn pdf_li(&self, p: Vec3, wi: Vec3) -> f32 {
        match self {
            Light::Distant(l) => l.pdf_li(wi),
            Light::Environment(l) => l.pdf_li(wi),
            Light::Area(l) => l.pdf_li(p, wi),
        }
    }

    /// Whether the light is a delta distribution in direction (only a [`Distant`] light of radius 0).
    #[inline]
    pub fn is_delta(&self) -> bool {
        match self {
            Light::Distant(l) => l.is_delta(),
            Light::Environment(_) | Light::Area(_) => false,
        }
    }

    /// Whether the light is at infinity, seen by rays that escape the scene through [`Light::le`].
    #[inline]
    pub fn is_infinite(&self) -> bool {
        matches!(self, Light::Distant(_) | Light::Environment(_))
    }

    /// For an infinite light, the radiance arriving from direction `dir` (world space; the direction the
    /// escaping ray travels) — 0 for a delta [`Distant`] light, which no ray can hit. 0 for area lights (use
    /// [`Light::intersect`]).
    #[inline]
    pub fn le(&self, dir: Vec3) -> Vec3 {
        match self {
            Light::Distant(l) => l.le(dir),
            Light::Environment(l) => l.le(dir),
            Light::Area(_) => Vec3::ZERO,
        }
    }

    /// ([`Light::le`], [`Light::pdf_li`]) of an infinite light for direction `dir`, the same values from one
    /// lookup of the direction (an environment map's texel and density share it).
    #[inline]
    pub fn le_and_pdf(&self, dir: Vec3) -> (Vec3, f32) {
        match self {
            Light::Environment(l) => l.le_and_pdf(dir),
            Light::Distant(l) => (l.le(dir), l.pdf_li(dir)),
            Light::Area(_) => (Vec3::ZERO, 0.0),
        }
    }

    /// [`Light::le`] when it is the same for every direction (a delta [`Distant`] light and an area light: 0; a
    /// constant environment: its radiance), else `None`. A camera ray that escapes a scene whose lights all have
    /// one sees their sum without a lookup per ray ([`crate::render::integrator::Integrator`]).
    #[inline]
    pub fn uniform_le(&self) -> Option<Vec3> {
        match self {
            Light::Distant(l) => l.is_delta().then_some(Vec3::ZERO),
            Light::Environment(l) => l.constant_radiance(),
            Light::Area(_) => Some(Vec3::ZERO),
        }
    }

    /// Whether a ray can hit the light ([`Light::intersect`] can be `Some`): area lights only.
    #[inline]
    pub fn intersects(&self) -> bool {
        matches!(self, Light::Area(_))
    }

    /// For an area light, the nearest hit of `ray` in [tnear, tfar]: its parameter t and the radiance leaving
    /// the light towards the ray's origin (0 from the back of a one-sided emitter). `None` for other lights.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<(f32, Vec3)> {
        match self {
            Light::Area(l) => l.intersect(ray),
            Light::Distant(_) | Light::Environment(_) => None,
        }
    }

    /// How often a light sample picks this light when each picks one (`lights = "one"`, and every vertex after
    /// the first), relative to the other lights: [`Light::power`], except that an environment counts the
    /// irradiance it gives a surface, π L̄, on the disk of radius `scene_radius` — the measure a distant light's
    /// power uses (E π r²) — instead of the flux through the whole bounding sphere (4 π² r² L̄, four times as
    /// much). A shading point sees an environment through a hemisphere of its surroundings, as it sees a sun,
    /// so light-for-light the two weigh alike: Mitsuba 3 and pbrt-v4's default (BVH) light sampler pick a sun
    /// and an environment with equal probability whatever their power. Measured on the peer scene (sun 3 +
    /// white environment 1, 256², 16 and 64 spp against a 256-spp reference, `lights = "one"`): picking by
    /// power (sun 19 %) gave RMSE 0.149 / 0.077, fireflies from the sun's TT lobe carrying 82 % of the squared
    /// error in 1 % of the pixels; this weight (sun 49 %) gives 0.098 / 0.055 with the same rays.
    ///
    /// With `material_finds_light` (MIS: material samples add the light they reach), a **constant** environment
    /// weighs 0 unless it is the only light: a material sample, drawn ∝ the fibre's scattering, is the better
    /// estimator of light that is the same from every direction, and a delta sun can be found by light samples
    /// only, so they all go to it (Cycles' world "Sampling: Auto" does the same: no light sampling of a constant
    /// background). Peer scene at 128², 16 spp, two seeds, against 256 spp: sun picked 50 % RMSE 0.092, 80 %
    /// 0.075 / 0.083, 100 % 0.072 / 0.077 (Cycles, clamp and glossy filter off: 0.079).
    pub fn selection_weight(&self, scene_radius: f32, material_finds_light: bool) -> f32 {
        match self {
            Light::Environment(e) if e.is_constant() && material_finds_light => 0.0,
            Light::Environment(_) => 0.25 * self.power(scene_radius),
            Light::Distant(_) | Light::Area(_) => self.power(scene_radius),
        }
    }

    /// An estimate of the emitted power as luminance (W in scene units), for choosing lights in proportion
    /// to power. Infinite lights count what falls on a disk of radius `scene_radius` (the scene's bounding
    /// sphere), as pbrt does.
    pub fn power(&self, scene_radius: f32) -> f32 {
        let power = match self {
            Light::Distant(l) => l.power(scene_radius),
            Light::Environment(l) => l.power(scene_radius),
            Light::Area(l) => l.power(),
        };
        if power.is_finite() {
            power.max(0.0)
        } else {
            f32::MAX
        }
    }
}

/// A light could not be built: a parameter out of range, or an environment map that could not be used.
#[derive(Debug, thiserror::Error)]
pub enum LightError {
    /// A numeric parameter out of its range.
    #[error("{light} light: {key} must be {requirement}, got {value}")]
    Parameter {
        /// The kind of light (`"distant"`, `"environment"`, `"quad"`, `"disk"`, `"sphere"`).
        light: &'static str,
        /// The parameter's name, as in the scene file.
        key: &'static str,
        /// What was expected, e.g. "> 0".
        requirement: &'static str,
        /// What was given (for vectors: the offending component, or the length).
        value: f32,
    },
    /// The environment map file could not be read (the message of [`ImageError`] names the file).
    #[error("environment map: {source}")]
    EnvironmentMap {
        /// The file asked for.
        path: PathBuf,
        /// Why it could not be read.
        source: ImageError,
    },
    /// The environment map file is not a regular file or cannot be opened.
    #[error("environment map {}: {source}", path.display())]
    EnvironmentFile {
        /// The file asked for.
        path: PathBuf,
        /// Why it cannot be opened.
        source: std::io::Error,
    },
    /// The environment map was read but cannot be used as one (no colour channel, no pixels).
    #[error("environment map {}: {message}", path.display())]
    EnvironmentContent {
        /// The file (or `<in-memory image>` for [`Environment::from_image`]).
        path: PathBuf,
        /// What is wrong, lower case.
        message: String,
    },
}

/// `Ok` if `ok`, else a [`LightError::Parameter`].
#[inline]
pub(crate) fn check(
    light: &'static str,
    key: &'static str,
    value: f32,
    requirement: &'static str,
    ok: bool,
) -> Result<(), LightError> {
    if ok {
        Ok(())
    } else {
        Err(LightError::Parameter {
            light,
            key,
            requirement,
            value,
        })
    }
}

/// Largest radiance or irradiance a light may have, per channel: 10¹⁰. The sun's disk, the brightest thing a scene
/// holds in physical units, is 1.6·10⁹ cd/m²; above this a value is a typo or a unit error, and it leaves 10²⁸ of
/// f32 headroom for BSDF values over sampling pdfs and sums over 65 536 samples, so no product overflows to
/// infinity (and then NaN) on the way to the film.
pub const MAX_RADIANCE: f32 = 1e10;

/// Checks an RGB radiance or irradiance: every channel finite, ≥ 0 and ≤ [`MAX_RADIANCE`].
pub(crate) fn check_color(
    light: &'static str,
    key: &'static str,
    c: Vec3,
) -> Result<(), LightError> {
    let worst = if c.is_finite() {
        if c.min_element() < 0.0 {
            c.min_element()
        } else {
            c.max_element()
        }
    } else {
        c.to_array()
            .into_iter()
            .find(|x| !x.is_finite())
            .unwrap_or(f32::NAN)
    };
    check(
        light,
        key,
        worst,
        "in [0, 1e10] in every channel",
        c.is_finite() && c.min_element() >= 0.0 && c.max_element() <= MAX_RADIANCE,
    )
}

/// Checks a direction-like vector (finite, non-zero) and returns it normalised.
pub(crate) fn check_direction(
    light: &'static str,
    key: &'static str,
    v: Vec3,
) -> Result<Vec3, LightError> {
    let len = v.length();
    check(
        light,
        key,
        len,
        "a finite, non-zero vector (length shown)",
        v.is_finite() && len.is_finite() && len > 0.0,
    )?;
    Ok(v / len)
}

/// Sample inputs clamped into [0, 1] (NaN → 0), so no input can make a sampler produce NaN.
#[inline]
pub(crate) fn clamp_u(u: [f32; 2]) -> [f32; 2] {
    u.map(|x| if x > 0.0 { x.min(1.0) } else { 0.0 })
}

/// A unit vector, or `None` for a zero, non-finite or overflowing input.
#[inline]
pub(crate) fn unit(v: Vec3) -> Option<Vec3> {
    let len = v.length();
    if len > 0.0 && len.is_finite() {
        let u = v / len;
        u.is_finite().then_some(u)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use std::f32::consts::PI;

    #[test]
    fn a_uniform_le_is_le_in_every_direction_and_only_there() {
        let sun = Light::Distant(distant::Distant::new(Vec3::NEG_Y, Vec3::splat(PI), 0.0).unwrap());
        let disk =
            Light::Distant(distant::Distant::new(Vec3::NEG_Y, Vec3::splat(PI), 0.27).unwrap());
        let sky = Light::Environment(
            environment::Environment::constant(Vec3::new(0.2, 0.5, 1.0)).unwrap(),
        );
        assert_eq!(sun.uniform_le(), Some(Vec3::ZERO));
        assert_eq!(sky.uniform_le(), Some(Vec3::new(0.2, 0.5, 1.0)));
        // A sun with a disk is seen only inside it (towards +y, against its travel): no uniform value.
        assert_eq!(disk.uniform_le(), None);
        assert!(disk.le(Vec3::Y).max_element() > 0.0 && disk.le(Vec3::X) == Vec3::ZERO);
        for k in 0..200 {
            let t = k as f32 * 0.37;
            let dir = Vec3::new(
                t.sin() * (2.0 * t).cos(),
                t.cos(),
                t.sin() * (2.0 * t).sin() + 0.1,
            ) * (1.0 + t);
            for light in [&sun, &sky] {
                assert_eq!(light.uniform_le(), Some(light.le(dir)), "{dir:?}");
            }
        }
    }

    /// A sun of irradiance π and a white environment of radiance 1 give a surface facing either the same
    /// irradiance, so a light sample picks them alike (their powers differ fourfold).
    #[test]
    fn a_sun_and_an_environment_of_equal_irradiance_are_picked_alike() {
        let r = 2.5;
        let sun = Light::Distant(distant::Distant::new(Vec3::NEG_Y, Vec3::splat(PI), 0.0).unwrap());
        let sky = Light::Environment(environment::Environment::constant(Vec3::ONE).unwrap());
        let (a, b) = (
            sun.selection_weight(r, false),
            sky.selection_weight(r, false),
        );
        assert!((a / b - 1.0).abs() < 1e-5, "{a} {b}");
        // Under MIS the material samples take a constant sky; the sun gets every light sample.
        assert_eq!(sky.selection_weight(r, true), 0.0);
        assert_eq!(sun.selection_weight(r, true), a);
        assert!((sky.power(r) / sun.power(r) - 4.0).abs() < 1e-5);
    }

    #[test]
    fn parameter_errors_name_light_key_and_value() {
        let e = Light::Area(
            AreaLight::new(
                Shape::Sphere {
                    center: Vec3::ZERO,
                    radius: 1.0,
                },
                Vec3::ONE,
                false,
            )
            .unwrap(),
        );
        assert!(!e.is_delta() && !e.is_infinite());
        let err = AreaLight::new(
            Shape::Disk {
                center: Vec3::ZERO,
                normal: Vec3::Y,
                radius: -1.0,
            },
            Vec3::ONE,
            false,
        )
        .unwrap_err();
        assert_eq!(
            err.to_string(),
            "disk light: radius must be > 0 and finite, got -1"
        );
        let err = check_color("quad", "radiance", Vec3::new(1.0, -2.0, 0.0)).unwrap_err();
        assert!(err.to_string().contains("got -2"), "{err}");
        let err = check_color("quad", "radiance", Vec3::new(1.0, f32::NAN, 0.0)).unwrap_err();
        assert!(err.to_string().contains("got NaN"), "{err}");
    }
}
