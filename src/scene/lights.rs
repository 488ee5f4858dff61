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
use crate::light::{AreaLight, Distant, Environment, Light, LightError, Shape, MAX_RADIANCE};
use crate::ray::MAX_SCENE_COORD;
use crate::shape::{Quad, Shapes};

/// One `[[light]]`, tagged by `kind`. Radiance and irradiance are a scalar times an RGB `color`.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum LightConfig {
    /// A light at infinity (the sun).
    Distant {
        /// The direction light travels, world space (need not be unit length).
        #[serde(deserialize_with = "crate::util::exact_array::array")]
        direction: [f32; 3],
        /// Irradiance on a surface facing the light.
        #[serde(default = "one")]
        irradiance: f32,
        /// Linear RGB tint, multiplied by `irradiance`.
        #[serde(default = "white")]
        #[serde(deserialize_with = "crate::util::exact_array::array")]
        color: [f32; 3],
        /// Angular radius of the sun disk, degrees; 0 = a delta light (the real sun: 0.27°).
        #[serde(default)]
        angular_radius: f32,
    },
    /// An emitting parallelogram `corner + s edge_u + t edge_v`.
    Quad {
        /// A corner.
        #[serde(deserialize_with = "crate::util::exact_array::array")]
        corner: [f32; 3],
        /// First edge.
        #[serde(deserialize_with = "crate::util::exact_array::array")]
        edge_u: [f32; 3],
        /// Second edge; the quad emits towards edge_u × edge_v.
        #[serde(deserialize_with = "crate::util::exact_array::array")]
        edge_v: [f32; 3],
        /// Emitted radiance.
        #[serde(default = "one")]
        radiance: f32,
        /// Linear RGB tint.
        #[serde(default = "white")]
        #[serde(deserialize_with = "crate::util::exact_array::array")]
        color: [f32; 3],
        /// Emit on both sides.
        #[serde(default)]
        two_sided: bool,
    },
    /// An emitting disk.
    Disk {
        /// Centre.
        #[serde(deserialize_with = "crate::util::exact_array::array")]
        center: [f32; 3],
        /// The side that emits.
        #[serde(deserialize_with = "crate::util::exact_array::array")]
        normal: [f32; 3],
        /// Radius.
        radius: f32,
        /// Emitted radiance.
        #[serde(default = "one")]
        radiance: f32,
        /// Linear RGB tint.
        #[serde(default = "white")]
        #[serde(deserialize_with = "crate::util::exact_array::array")]
        color: [f32; 3],
        /// Emit on both sides.
        #[serde(default)]
        two_sided: bool,
    },
    /// An emitting sphere.
    Sphere {
        /// Centre.
        #[serde(deserialize_with = "crate::util::exact_array::array")]
        center: [f32; 3],
        /// Radius.
        radius: f32,
        /// Emitted radiance.
        #[serde(default = "one")]
        radiance: f32,
        /// Linear RGB tint.
        #[serde(default = "white")]
        #[serde(deserialize_with = "crate::util::exact_array::array")]
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
    #[serde(default, deserialize_with = "crate::util::exact_array::option_array")]
    pub radiance: Option<[f32; 3]>,
    /// A lat-long HDR map (EXR, HDR, anything OpenImageIO reads), relative to the scene file.
    pub map: Option<PathBuf>,
    /// Multiplies the map.
    pub intensity: f32,
    /// Turns the map about `up`, degrees, counter-clockwise seen from above.
    pub rotation: f32,
    /// The world direction of the map's top row.
    #[serde(deserialize_with = "crate::util::exact_array::array")]
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
        #[serde(deserialize_with = "crate::util::exact_array::array")]
        corner: [f32; 3],
        /// First edge.
        #[serde(deserialize_with = "crate::util::exact_array::array")]
        edge_u: [f32; 3],
        /// Second edge.
        #[serde(deserialize_with = "crate::util::exact_array::array")]
        edge_v: [f32; 3],
        /// Lambert albedo in [0, 1].
        #[serde(default = "grey")]
        #[serde(deserialize_with = "crate::util::exact_array::array")]
        albedo: [f32; 3],
    },
    /// An axis-aligned box of six quads, some left open.
    Box {
        /// Lower corner.
        #[serde(deserialize_with = "crate::util::exact_array::array")]
        min: [f32; 3],
        /// Upper corner.
        #[serde(deserialize_with = "crate::util::exact_array::array")]
        max: [f32; 3],
        /// Lambert albedo in [0, 1].
        #[serde(default = "grey")]
        #[serde(deserialize_with = "crate::util::exact_array::array")]
        albedo: [f32; 3],
        /// Faces left out: any of "+x", "-x", "+y", "-y", "+z", "-z".
        #[serde(default)]
        open: Vec<String>,
    },
    /// The `Mesh` prims of a USD stage (a head under a groom), triangulated, in world space.
    Usd {
        /// The stage, relative to the scene file.
        file: std::path::PathBuf,
        /// The prim whose subtree's meshes are read (default: every mesh of the stage).
        prim: Option<String>,
        /// Lambert albedo in [0, 1] replacing the file's colours (`displayColor`, a `UsdPreviewSurface`'s
        /// `diffuseColor`; 0.5 grey where it gives none).
        #[serde(default, deserialize_with = "crate::util::exact_array::option_array")]
        albedo: Option<[f32; 3]>,
    },
}

fn grey() -> [f32; 3] {
    [0.5; 3]
}

/// The message of a light that fails to build, naming the table.
fn named(i: usize, e: LightError) -> String {
    format!("light[{i}]: {e}")
}

/// `light[i].key` (a scalar radiance or irradiance) in [0, MAX_RADIANCE].
fn check_scalar(i: usize, key: &str, v: f32) -> Result<(), String> {
    if (0.0..=MAX_RADIANCE).contains(&v) {
        Ok(())
    } else {
        Err(format!(
            "light[{i}].{key} must be in [0, {MAX_RADIANCE:e}], got {v}"
        ))
    }
}

/// `light[i].color` (a tint) in [0, MAX_RADIANCE] per channel.
fn check_tint(i: usize, c: &[f32; 3]) -> Result<(), String> {
    if c.iter().all(|x| (0.0..=MAX_RADIANCE).contains(x)) {
        Ok(())
    } else {
        Err(format!(
            "light[{i}].color must be in [0, {MAX_RADIANCE:e}] per channel, got {c:?}"
        ))
    }
}

/// `key` (a position, an edge or a radius) within [`MAX_SCENE_COORD`] on every axis: points on lights and shapes
/// start shadow and bounce rays, which [`crate::ray::Ray::check`] refuses beyond it.
fn check_coords(key: &str, v: &[f32]) -> Result<(), String> {
    if v.iter().all(|x| x.abs() <= MAX_SCENE_COORD) {
        Ok(())
    } else {
        Err(format!(
            "{key} must be finite and within {MAX_SCENE_COORD:e} of 0 on every axis, got {v:?} (rays from \
             farther away cannot be traced in single precision)"
        ))
    }
}

impl LightConfig {
    /// Checks each key on its own, in the units the user wrote (degrees), before [`LightConfig::build`] combines
    /// them (a negative colour must not be reported as a bad irradiance). `i` is the table's index.
    pub fn check_keys(&self, i: usize) -> Result<(), String> {
        let at = |key: &str| format!("light[{i}].{key}");
        match self {
            LightConfig::Distant {
                irradiance,
                color,
                angular_radius,
                ..
            } => {
                check_scalar(i, "irradiance", *irradiance)?;
                check_tint(i, color)?;
                if !(0.0..=90.0).contains(angular_radius) {
                    return Err(format!(
                        "light[{i}].angular_radius must be in [0, 90] degrees, got {angular_radius}"
                    ));
                }
            }
            LightConfig::Quad {
                corner,
                edge_u,
                edge_v,
                radiance,
                color,
                ..
            } => {
                check_scalar(i, "radiance", *radiance)?;
                check_tint(i, color)?;
                check_coords(&at("corner"), corner)?;
                check_coords(&at("edge_u"), edge_u)?;
                check_coords(&at("edge_v"), edge_v)?;
            }
            LightConfig::Disk {
                center,
                radius,
                radiance,
                color,
                ..
            }
            | LightConfig::Sphere {
                center,
                radius,
                radiance,
                color,
            } => {
                check_scalar(i, "radiance", *radiance)?;
                check_tint(i, color)?;
                check_coords(&at("center"), center)?;
                check_coords(&at("radius"), &[*radius])?;
            }
        }
        Ok(())
    }

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
    // One piece: a flat list of range checks, one per key, in the order the reference documents them.
    for (i, light) in scene.lights.iter().enumerate() {
        light.check_keys(i)?;
        light.build().map_err(|e| named(i, e))?;
    }
    let e = &scene.environment;
    if e.map.is_some() && e.radiance.is_some() {
        return Err("[environment] takes `map` or `radiance`, not both".into());
    }
    if let Some(r) = e.radiance {
        if !r.iter().all(|x| (0.0..=MAX_RADIANCE).contains(x)) {
            return Err(format!(
                "environment.radiance must be in [0, {MAX_RADIANCE:e}] per channel, got {r:?}"
            ));
        }
        Environment::constant(Vec3::from(r)).map_err(|e| format!("environment.{e}"))?;
    }
    if !(0.0..=MAX_RADIANCE).contains(&e.intensity) {
        return Err(format!(
            "environment.intensity must be in [0, {MAX_RADIANCE:e}], got {}",
            e.intensity
        ));
    }
    if let Some(r) = e.radiance {
        let product = Vec3::from(r) * e.intensity;
        if !(..=MAX_RADIANCE).contains(&product.max_element()) {
            return Err(format!(
                "environment.radiance {r:?} × environment.intensity {} exceeds {MAX_RADIANCE:e}",
                e.intensity
            ));
        }
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
        match shape {
            ShapeConfig::Quad {
                corner,
                edge_u,
                edge_v,
                ..
            } => {
                check_coords(&format!("shape[{i}].corner"), corner)?;
                check_coords(&format!("shape[{i}].edge_u"), edge_u)?;
                check_coords(&format!("shape[{i}].edge_v"), edge_v)?;
            }
            ShapeConfig::Box { min, max, .. } => {
                check_coords(&format!("shape[{i}].min"), min)?;
                check_coords(&format!("shape[{i}].max"), max)?;
            }
            ShapeConfig::Usd {
                file, prim, albedo, ..
            } => {
                if !super::is_usd(file) {
                    return Err(format!(
                        "shape[{i}].file {} is not a USD file (.usda, .usdc, .usdz or .usd)",
                        file.display()
                    ));
                }
                if let Some(prim) = prim {
                    super::check_prim_path(&format!("shape[{i}].prim"), prim)?;
                }
                if let Some(a) = albedo {
                    if a.iter().any(|a| !(0.0..=1.0).contains(a)) {
                        return Err(format!(
                            "shape[{i}].albedo must be in [0, 1] per channel, got {a:?}"
                        ));
                    }
                }
                continue;
            }
        }
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
            ShapeConfig::Usd { .. } => unreachable!("checked above"),
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

    /// The scene's `[[shape]]`s; a USD shape's stage is read here, errors naming the scene and the file.
    pub fn build_shapes(&self) -> Result<Shapes, SceneError> {
        let mut shapes = Shapes::new();
        for (i, shape) in self.shapes.iter().enumerate() {
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
                ShapeConfig::Usd { file, prim, albedo } => {
                    let path = self.base_dir.join(file);
                    let invalid = |message: String| SceneError::Invalid {
                        path: self.source.clone(),
                        message: format!("shape[{i}]: {message}"),
                    };
                    let stage = crate::usd::read_parts(
                        &path,
                        prim.as_deref(),
                        crate::usd::DEFAULT_RADIUS,
                        crate::usd::Parts {
                            curves: false,
                            meshes: true,
                        },
                    )
                    .map_err(|e| invalid(e.to_string()))?;
                    if stage.meshes.is_empty() {
                        return Err(invalid(format!(
                            "{} has no Mesh prims under {}",
                            path.display(),
                            prim.as_deref().unwrap_or("its root")
                        )));
                    }
                    for mut mesh in stage.meshes {
                        if let Some(a) = albedo {
                            mesh.albedo = (*a).into();
                            mesh.corner_albedo = None;
                        }
                        shapes.push_mesh(mesh);
                    }
                }
            }
        }
        Ok(shapes)
    }
}
