//! `[[light]]`, `[environment]` and `[[shape]]`: what lights the hair and what else is in the scene, as the user
//! writes it, and how it becomes [`Light`]s and [`Shapes`].
//!
//! ```toml
//! [[light]]
//! kind = "distant"            # the sun: light travels along `direction`
//! direction = [1.0, -1.0, 1.0]
//! irradiance = 3.0
//! angular_radius = 0.27       # degrees; 0 (default) = a delta light
//!
//! [[light]]
//! kind = "quad"               # also "disk" (center, normal, radius) and "sphere" (center, radius)
//! corner = [-1.0, 3.0, -1.0]
//! edge_u = [2.0, 0.0, 0.0]
//! edge_v = [0.0, 0.0, 2.0]    # emits towards edge_u × edge_v unless two_sided
//! radiance = 5.0
//!
//! [environment]
//! map = "../shared/data/envmaps/city.exr"   # lat-long HDR, relative to the scene file; or `radiance = [r, g, b]`
//! intensity = 1.0
//! rotation = 90.0             # degrees about `up`, counter-clockwise seen from above
//!
//! [[shape]]
//! kind = "quad"               # or "box" (min, max, open = ["+z"])
//! corner = [-5.0, 0.0, -5.0]
//! edge_u = [0.0, 0.0, 10.0]
//! edge_v = [10.0, 0.0, 0.0]
//! albedo = [0.5, 0.5, 0.5]
//! ```
//!
//! Parameters are checked when the scene is parsed (messages name `light[i].key`); an environment map is read
//! when the lights are built, and a missing or unreadable map is an error naming the file.

use std::path::PathBuf;

use glam::Vec3;
use serde::Deserialize;

use super::{Scene, SceneError};
use crate::light::{AreaLight, Distant, Environment, Light, LightError, Shape};
use crate::shape::{Quad, Shapes};

/// One `[[light]]`, tagged by `kind`. Radiance and irradiance are a scalar times an RGB `color`.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum LightConfig {
    /// A light at infinity (the sun).
    Distant {
        /// The direction light travels, world space (need not be unit length).
        direction: [f32; 3],
        /// Irradiance on a surface facing the light.
        #[serde(default = "one")]
        irradiance: f32,
        /// Linear RGB tint, multiplied by `irradiance`.
        #[serde(default = "white")]
        color: [f32; 3],
        /// Angular radius of the sun disk, degrees; 0 = a delta light (the real sun: 0.27°).
        #[serde(default)]
        angular_radius: f32,
    },
    /// An emitting parallelogram `corner + s edge_u + t edge_v`.
    Quad {
        /// A corner.
        corner: [f32; 3],
        /// First edge.
        edge_u: [f32; 3],
        /// Second edge; the quad emits towards edge_u × edge_v.
        edge_v: [f32; 3],
        /// Emitted radiance.
        #[serde(default = "one")]
        radiance: f32,
        /// Linear RGB tint.
        #[serde(default = "white")]
        color: [f32; 3],
        /// Emit on both sides.
        #[serde(default)]
        two_sided: bool,
    },
    /// An emitting disk.
    Disk {
        /// Centre.
        center: [f32; 3],
        /// The side that emits.
        normal: [f32; 3],
        /// Radius.
        radius: f32,
        /// Emitted radiance.
        #[serde(default = "one")]
        radiance: f32,
        /// Linear RGB tint.
        #[serde(default = "white")]
        color: [f32; 3],
        /// Emit on both sides.
        #[serde(default)]
        two_sided: bool,
    },
    /// An emitting sphere.
    Sphere {
        /// Centre.
        center: [f32; 3],
        /// Radius.
        radius: f32,
        /// Emitted radiance.
        #[serde(default = "one")]
        radiance: f32,
        /// Linear RGB tint.
        #[serde(default = "white")]
        color: [f32; 3],
    },
}

fn one() -> f32 {
    1.0
}

fn white() -> [f32; 3] {
    [1.0; 3]
}

fn y_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

/// `[environment]`: light from every direction, a constant `radiance` or a lat-long `map` (not both).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EnvironmentConfig {
    /// Constant radiance, linear RGB (ignored when `map` is given; must then be left out).
    pub radiance: Option<[f32; 3]>,
    /// A lat-long HDR map (EXR, HDR, anything OpenImageIO reads), relative to the scene file.
    pub map: Option<PathBuf>,
    /// Multiplies the map.
    pub intensity: f32,
    /// Turns the map about `up`, degrees, counter-clockwise seen from above.
    pub rotation: f32,
    /// The world direction of the map's top row.
    pub up: [f32; 3],
    /// Show the environment behind the hair (alpha stays 0 there either way).
    pub visible: bool,
}

impl Default for EnvironmentConfig {
    fn default() -> Self {
        EnvironmentConfig {
            radiance: None,
            map: None,
            intensity: 1.0,
            rotation: 0.0,
            up: y_up(),
            visible: true,
        }
    }
}

/// One `[[shape]]`: non-hair geometry with a two-sided Lambert material.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum ShapeConfig {
    /// A parallelogram.
    Quad {
        /// A corner.
        corner: [f32; 3],
        /// First edge.
        edge_u: [f32; 3],
        /// Second edge.
        edge_v: [f32; 3],
        /// Lambert albedo in [0, 1].
        #[serde(default = "grey")]
        albedo: [f32; 3],
    },
    /// An axis-aligned box of six quads, some left open.
    Box {
        /// Lower corner.
        min: [f32; 3],
        /// Upper corner.
        max: [f32; 3],
        /// Lambert albedo in [0, 1].
        #[serde(default = "grey")]
        albedo: [f32; 3],
        /// Faces left out: any of "+x", "-x", "+y", "-y", "+z", "-z".
        #[serde(default)]
        open: Vec<String>,
    },
}

fn grey() -> [f32; 3] {
    [0.5; 3]
}

/// The message of a light that fails to build, naming the table.
fn named(i: usize, e: LightError) -> String {
    format!("light[{i}]: {e}")
}

impl LightConfig {
    /// The light, with parameters checked (no files are read for these).
    pub fn build(&self) -> Result<Light, LightError> {
        let rgb = |s: f32, c: &[f32; 3]| Vec3::from(*c) * s;
        Ok(match self {
            LightConfig::Distant {
                direction,
                irradiance,
                color,
                angular_radius,
            } => Light::Distant(Distant::new(
                Vec3::from(*direction),
                rgb(*irradiance, color),
                angular_radius.to_radians(),
            )?),
            LightConfig::Quad {
                corner,
                edge_u,
                edge_v,
                radiance,
                color,
                two_sided,
            } => Light::Area(AreaLight::new(
                Shape::Quad {
                    corner: (*corner).into(),
                    edge_u: (*edge_u).into(),
                    edge_v: (*edge_v).into(),
                },
                rgb(*radiance, color),
                *two_sided,
            )?),
            LightConfig::Disk {
                center,
                normal,
                radius,
                radiance,
                color,
                two_sided,
            } => Light::Area(AreaLight::new(
                Shape::Disk {
                    center: (*center).into(),
                    normal: (*normal).into(),
                    radius: *radius,
                },
                rgb(*radiance, color),
                *two_sided,
            )?),
            LightConfig::Sphere {
                center,
                radius,
                radiance,
                color,
            } => Light::Area(AreaLight::new(
                Shape::Sphere {
                    center: (*center).into(),
                    radius: *radius,
                },
                rgb(*radiance, color),
                false,
            )?),
        })
    }
}

/// Range checks of lights, environment and shapes (no files read). Messages name the key.
pub(super) fn validate(scene: &Scene) -> Result<(), String> {
    for (i, light) in scene.lights.iter().enumerate() {
        light.build().map_err(|e| named(i, e))?;
    }
    let e = &scene.environment;
    if e.map.is_some() && e.radiance.is_some() {
        return Err("[environment] takes `map` or `radiance`, not both".into());
    }
    if let Some(r) = e.radiance {
        Environment::constant(Vec3::from(r)).map_err(|e| format!("environment.{e}"))?;
    }
    if !(e.intensity.is_finite() && e.intensity >= 0.0) {
        return Err(format!(
            "environment.intensity must be >= 0, got {}",
            e.intensity
        ));
    }
    if !e.rotation.is_finite() {
        return Err(format!(
            "environment.rotation must be finite, got {}",
            e.rotation
        ));
    }
    let up = Vec3::from(e.up);
    if !up.is_finite() || up.length_squared() == 0.0 {
        return Err(format!(
            "environment.up must be a non-zero finite vector, got {:?}",
            e.up
        ));
    }
    for (i, shape) in scene.shapes.iter().enumerate() {
        let albedo = match shape {
            ShapeConfig::Quad {
                corner,
                edge_u,
                edge_v,
                albedo,
            } => {
                if Quad::new(
                    (*corner).into(),
                    (*edge_u).into(),
                    (*edge_v).into(),
                    Vec3::ONE,
                )
                .is_none()
                {
                    return Err(format!(
                        "shape[{i}]: a quad needs finite, non-parallel edges, got edge_u {edge_u:?}, edge_v {edge_v:?}"
                    ));
                }
                albedo
            }
            ShapeConfig::Box {
                min,
                max,
                albedo,
                open,
            } => {
                if !(Vec3::from(*min).cmplt(Vec3::from(*max)).all()) {
                    return Err(format!(
                        "shape[{i}]: box min {min:?} must be below max {max:?} on every axis"
                    ));
                }
                if let Some(bad) = open
                    .iter()
                    .find(|f| !["+x", "-x", "+y", "-y", "+z", "-z"].contains(&f.as_str()))
                {
                    return Err(format!(
                        "shape[{i}].open: unknown face {bad:?} (expected \"+x\", \"-x\", \"+y\", \"-y\", \"+z\" or \"-z\")"
                    ));
                }
                albedo
            }
        };
        if albedo.iter().any(|a| !(0.0..=1.0).contains(a)) {
            return Err(format!(
                "shape[{i}].albedo must be in [0, 1] per channel, got {albedo:?}"
            ));
        }
    }
    Ok(())
}

impl Scene {
    /// Every light of the scene: the `[[light]]`s, then the environment (when it has a map or a non-zero
    /// radiance). Reads the environment map; errors name the scene and the map file.
    pub fn build_lights(&self) -> Result<Vec<Light>, SceneError> {
        let invalid = |message: String| SceneError::Invalid {
            path: self.source.clone(),
            message,
        };
        let mut lights = Vec::with_capacity(self.lights.len() + 1);
        for (i, light) in self.lights.iter().enumerate() {
            lights.push(light.build().map_err(|e| invalid(named(i, e)))?);
        }
        let e = &self.environment;
        if let Some(map) = &e.map {
            let path = self.base_dir.join(map);
            let env = Environment::load(&path, e.intensity, e.rotation, Vec3::from(e.up))
                .map_err(|err| invalid(err.to_string()))?;
            lights.push(Light::Environment(env));
        } else if let Some(r) = e.radiance.filter(|r| r.iter().any(|&x| x > 0.0)) {
            let env = Environment::constant(Vec3::from(r) * e.intensity)
                .map_err(|err| invalid(err.to_string()))?;
            lights.push(Light::Environment(env));
        }
        Ok(lights)
    }

    /// The scene's `[[shape]]`s.
    pub fn build_shapes(&self) -> Shapes {
        let mut shapes = Shapes::new();
        for shape in &self.shapes {
            match shape {
                ShapeConfig::Quad {
                    corner,
                    edge_u,
                    edge_v,
                    albedo,
                } => {
                    if let Some(q) = Quad::new(
                        (*corner).into(),
                        (*edge_u).into(),
                        (*edge_v).into(),
                        (*albedo).into(),
                    ) {
                        shapes.push(q);
                    }
                }
                ShapeConfig::Box {
                    min,
                    max,
                    albedo,
                    open,
                } => {
                    let open: Vec<&str> = open.iter().map(String::as_str).collect();
                    shapes.push_box((*min).into(), (*max).into(), (*albedo).into(), &open);
                }
            }
        }
        shapes
    }
}
