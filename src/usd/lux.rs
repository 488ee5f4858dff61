//! `UsdLux` distant and dome lights.

use glam::{DMat4, DVec3, Vec3};
use openusd::{sdf, usd};

use super::values::{scalar, vec3};
use super::{prim_err, Reader, UsdError, UsdLight};

impl Reader<'_> {
    pub(super) fn light(
        &mut self,
        prim: &usd::Prim,
        ty: &str,
        world: DMat4,
    ) -> Result<UsdLight, UsdError> {
        let num = |s: &mut Self, name: &str, default: f64| -> Result<f32, UsdError> {
            let v = match s.get_as(prim, &format!("inputs:{name}"), "a number", scalar)? {
                Some(v) => Some(v),
                None => s.get_as(prim, name, "a number", scalar)?,
            };
            Ok(v.unwrap_or(default) as f32)
        };
        let intensity = num(self, "intensity", 1.0)?;
        let exposure = num(self, "exposure", 0.0)?;
        let color = match self.get_as(prim, "inputs:color", "a colour", vec3)? {
            Some(c) => Some(c),
            None => self.get_as(prim, "color", "a colour", vec3)?,
        }
        .map_or(Vec3::ONE, |c| c.as_vec3());
        if ty == "DistantLight" {
            let angle = num(self, "angle", 0.53)?;
            let d = world
                .transform_vector3(DVec3::Z)
                .normalize_or_zero()
                .as_vec3();
            if d == Vec3::ZERO {
                return Err(prim_err(
                    self.path,
                    prim.path(),
                    "the light's transform is degenerate",
                ));
            }
            Ok(UsdLight::Distant {
                direction_to_light: d,
                color,
                intensity,
                exposure,
                angle_degrees: angle,
            })
        } else {
            let texture = match self.get(prim, "inputs:texture:file")? {
                Some(sdf::Value::AssetPath(a)) if !a.as_str().is_empty() => {
                    Some(self.asset_file(a.resolved_path().unwrap_or(a.as_str())))
                }
                _ => None,
            };
            if world
                .transform_vector3(DVec3::Y)
                .normalize_or_zero()
                .dot(DVec3::Y)
                < 1.0 - 1e-9
                && texture.is_some()
            {
                self.warn(
                    prim.path(),
                    "the dome's rotation is not applied to its texture",
                );
            }
            Ok(UsdLight::Dome {
                color,
                intensity,
                exposure,
                texture,
            })
        }
    }
}
