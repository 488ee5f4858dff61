//! The `Camera` prim.

use glam::{DMat4, DVec3, Vec3};
use openusd::usd;

use super::values::scalar;
use super::{prim_err, Reader, UsdCamera, UsdError};

impl Reader<'_> {
    pub(super) fn camera(&mut self, prim: &usd::Prim, world: DMat4) -> Result<UsdCamera, UsdError> {
        let f = self
            .get_as(prim, "focalLength", "a number", scalar)?
            .unwrap_or(50.0);
        let h = self.get_as(prim, "horizontalAperture", "a number", scalar)?;
        let v = self.get_as(prim, "verticalAperture", "a number", scalar)?;
        let (hv, vv) = (h.unwrap_or(20.955), v.unwrap_or(15.2908));
        if !(f > 0.0 && vv > 0.0 && hv > 0.0) {
            return Err(prim_err(
                self.path,
                prim.path(),
                format!("focalLength {f} and apertures {hv} × {vv} must be > 0"),
            ));
        }
        let dir = |d: DVec3| world.transform_vector3(d).normalize_or_zero().as_vec3();
        let cam = UsdCamera {
            position: world.transform_point3(DVec3::ZERO).as_vec3(),
            forward: dir(DVec3::NEG_Z),
            up: dir(DVec3::Y),
            vertical_fov_degrees: (2.0 * (vv / (2.0 * f)).atan()).to_degrees() as f32,
            aspect: (h.is_some() || v.is_some()).then_some((hv / vv) as f32),
        };
        if cam.forward == Vec3::ZERO || cam.up == Vec3::ZERO || !cam.position.is_finite() {
            return Err(prim_err(
                self.path,
                prim.path(),
                "the camera's transform is degenerate",
            ));
        }
        Ok(cam)
    }
}
