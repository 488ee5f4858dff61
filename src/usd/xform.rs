//! `xformOp`s composed into world transforms, and points and widths moved by them.

use glam::{DMat4, DVec3, Vec3};
use openusd::{sdf, usd};

use super::values::{quat, scalar, vec3};
use super::{prim_err, Reader, UsdError};

impl Reader<'_> {
    /// `parent` composed with the prim's `xformOpOrder`.
    pub(super) fn world_of(&mut self, prim: &usd::Prim, parent: DMat4) -> Result<DMat4, UsdError> {
        let order: Vec<String> = match self.get(prim, "xformOpOrder")? {
            None => return Ok(parent),
            Some(sdf::Value::TokenVec(v)) => v.iter().map(|t| t.as_str().to_owned()).collect(),
            Some(sdf::Value::StringVec(v)) => v,
            Some(_) => {
                return Err(prim_err(
                    self.path,
                    prim.path(),
                    "xformOpOrder is not a token array",
                ))
            }
        };
        let mut world = parent;
        let mut local = DMat4::IDENTITY;
        for (i, op) in order.iter().enumerate() {
            if op == "!resetXformStack!" {
                if i != 0 {
                    return Err(prim_err(
                        self.path,
                        prim.path(),
                        format!(
                            "!resetXformStack! at position {i} of xformOpOrder (only the first)"
                        ),
                    ));
                }
                world = DMat4::IDENTITY;
                continue;
            }
            let (invert, name) = match op.strip_prefix("!invert!") {
                Some(n) => (true, n),
                None => (false, op.as_str()),
            };
            let m = self.op_matrix(prim, name)?;
            let m = if invert {
                if m.determinant().abs() < 1e-300 {
                    return Err(prim_err(
                        self.path,
                        prim.path(),
                        format!("{op}: a singular op cannot be inverted"),
                    ));
                }
                m.inverse()
            } else {
                m
            };
            // USD applies the ops from the last to the first: the first op is outermost.
            local *= m;
        }
        Ok(world * local)
    }

    /// One `xformOp:<kind>[:suffix]` as a column-vector matrix.
    pub(super) fn op_matrix(&mut self, prim: &usd::Prim, name: &str) -> Result<DMat4, UsdError> {
        let kind = name
            .strip_prefix("xformOp:")
            .and_then(|k| k.split(':').next())
            .unwrap_or("");
        let bad = |what: &str| prim_err(self.path, prim.path(), format!("{name}: {what}"));
        let Some(v) = self.get(prim, name)? else {
            return Err(bad("named in xformOpOrder but has no value"));
        };
        let v3 = || vec3(&v).ok_or_else(|| bad("expected three numbers"));
        let s = || scalar(&v).ok_or_else(|| bad("expected a number"));
        let rot = |axis: char, deg: f64| match axis {
            'X' => DMat4::from_rotation_x(deg.to_radians()),
            'Y' => DMat4::from_rotation_y(deg.to_radians()),
            _ => DMat4::from_rotation_z(deg.to_radians()),
        };
        let m = match kind {
            "translate" => DMat4::from_translation(v3()?),
            "translateX" => DMat4::from_translation(DVec3::X * s()?),
            "translateY" => DMat4::from_translation(DVec3::Y * s()?),
            "translateZ" => DMat4::from_translation(DVec3::Z * s()?),
            "scale" => DMat4::from_scale(v3()?),
            "scaleX" => DMat4::from_scale(DVec3::new(s()?, 1.0, 1.0)),
            "scaleY" => DMat4::from_scale(DVec3::new(1.0, s()?, 1.0)),
            "scaleZ" => DMat4::from_scale(DVec3::new(1.0, 1.0, s()?)),
            "rotateX" | "rotateY" | "rotateZ" => rot(kind.as_bytes()[6] as char, s()?),
            "rotateXYZ" | "rotateXZY" | "rotateYXZ" | "rotateYZX" | "rotateZXY" | "rotateZYX" => {
                let a = v3()?;
                let angle = |c: char| match c {
                    'X' => a.x,
                    'Y' => a.y,
                    _ => a.z,
                };
                // rotateABC applies A first, then B, then C: R = R_C · R_B · R_A on column vectors.
                let axes: Vec<char> = kind[6..].chars().collect();
                rot(axes[2], angle(axes[2]))
                    * rot(axes[1], angle(axes[1]))
                    * rot(axes[0], angle(axes[0]))
            }
            "orient" => {
                let q = quat(&v).ok_or_else(|| bad("expected a quaternion"))?;
                DMat4::from_quat(q.normalize())
            }
            "transform" => match v {
                // USD's row-vector matrix, row-major, is the column-vector matrix, column-major.
                sdf::Value::Matrix4d(m) => DMat4::from_cols_array(&m.0),
                _ => return Err(bad("expected a matrix4d")),
            },
            _ => return Err(bad("unknown transform op")),
        };
        if !m.is_finite() {
            return Err(bad("not finite"));
        }
        Ok(m)
    }
}

/// Points moved by `m` (in f64, rounded once); the identity leaves them bit for bit.
pub(super) fn transform_points(points: &[Vec3], m: DMat4) -> Vec<Vec3> {
    if m == DMat4::IDENTITY {
        return points.to_vec();
    }
    points
        .iter()
        .map(|p| m.transform_point3(p.as_dvec3()).as_vec3())
        .collect()
}

/// The factor a transform scales widths by: the cube root of |det|, the mean scale (exact for uniform scale).
pub(super) fn world_radius_scale(m: DMat4) -> f32 {
    let d = m.determinant().abs();
    if (d - 1.0).abs() < 1e-12 {
        1.0
    } else {
        d.cbrt() as f32
    }
}
