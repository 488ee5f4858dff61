//! `sdf::Value`s converted to the numbers the reader uses; `None` for a value of another type.

use glam::{DQuat, DVec3, Vec3};
use openusd::sdf;

pub(super) fn scalar(v: &sdf::Value) -> Option<f64> {
    Some(match v {
        sdf::Value::Float(x) => f64::from(*x),
        sdf::Value::Double(x) => *x,
        sdf::Value::Half(x) => f64::from(x.to_f32()),
        sdf::Value::Int(x) => f64::from(*x),
        _ => return None,
    })
}

pub(super) fn token(v: &sdf::Value) -> Option<String> {
    match v {
        sdf::Value::Token(t) => Some(t.as_str().to_owned()),
        sdf::Value::String(s) => Some(s.clone()),
        _ => None,
    }
}

pub(super) fn vec3(v: &sdf::Value) -> Option<DVec3> {
    Some(match v {
        sdf::Value::Vec3f(a) => DVec3::new(a.x.into(), a.y.into(), a.z.into()),
        sdf::Value::Vec3d(a) => DVec3::new(a.x, a.y, a.z),
        sdf::Value::Vec3h(a) => DVec3::new(a.x.to_f64(), a.y.to_f64(), a.z.to_f64()),
        // A one-element colour array (`color3f[] displayColor = [(…)]`).
        sdf::Value::Vec3fVec(a) if a.len() == 1 => {
            DVec3::new(a[0].x.into(), a[0].y.into(), a[0].z.into())
        }
        _ => return None,
    })
}

pub(super) fn quat(v: &sdf::Value) -> Option<DQuat> {
    Some(match v {
        sdf::Value::Quatf(q) => DQuat::from_xyzw(q.x.into(), q.y.into(), q.z.into(), q.w.into()),
        sdf::Value::Quatd(q) => DQuat::from_xyzw(q.x, q.y, q.z, q.w),
        sdf::Value::Quath(q) => {
            DQuat::from_xyzw(q.x.to_f64(), q.y.to_f64(), q.z.to_f64(), q.w.to_f64())
        }
        _ => return None,
    })
}

pub(super) fn vec3s(v: &sdf::Value) -> Option<Vec<Vec3>> {
    Some(match v {
        sdf::Value::Vec3fVec(a) => a.iter().map(|p| Vec3::new(p.x, p.y, p.z)).collect(),
        sdf::Value::Vec3dVec(a) => a
            .iter()
            .map(|p| DVec3::new(p.x, p.y, p.z).as_vec3())
            .collect(),
        sdf::Value::Vec3hVec(a) => a
            .iter()
            .map(|p| Vec3::new(p.x.to_f32(), p.y.to_f32(), p.z.to_f32()))
            .collect(),
        _ => return None,
    })
}

pub(super) fn floats(v: &sdf::Value) -> Option<Vec<f32>> {
    Some(match v {
        sdf::Value::FloatVec(a) => a.clone(),
        sdf::Value::DoubleVec(a) => a.iter().map(|&x| x as f32).collect(),
        sdf::Value::HalfVec(a) => a.iter().map(|x| x.to_f32()).collect(),
        sdf::Value::Float(x) => vec![*x],
        _ => return None,
    })
}

pub(super) fn ints(v: &sdf::Value) -> Option<Vec<i64>> {
    Some(match v {
        sdf::Value::IntVec(a) => a.iter().map(|&x| i64::from(x)).collect(),
        sdf::Value::Int64Vec(a) => a.clone(),
        _ => return None,
    })
}

pub(super) fn quats(v: &sdf::Value) -> Option<Vec<DQuat>> {
    Some(match v {
        sdf::Value::QuathVec(a) => a
            .iter()
            .map(|q| DQuat::from_xyzw(q.x.to_f64(), q.y.to_f64(), q.z.to_f64(), q.w.to_f64()))
            .collect(),
        sdf::Value::QuatfVec(a) => a
            .iter()
            .map(|q| DQuat::from_xyzw(q.x.into(), q.y.into(), q.z.into(), q.w.into()))
            .collect(),
        sdf::Value::QuatdVec(a) => a
            .iter()
            .map(|q| DQuat::from_xyzw(q.x, q.y, q.z, q.w))
            .collect(),
        _ => return None,
    })
}

/// Texture coordinates (`texCoord2f[]`, `float2[]` and their double and half forms).
pub(super) fn vec2s(v: &sdf::Value) -> Option<Vec<glam::Vec2>> {
    Some(match v {
        sdf::Value::Vec2fVec(a) => a.iter().map(|p| glam::Vec2::new(p.x, p.y)).collect(),
        sdf::Value::Vec2dVec(a) => a
            .iter()
            .map(|p| glam::Vec2::new(p.x as f32, p.y as f32))
            .collect(),
        sdf::Value::Vec2hVec(a) => a
            .iter()
            .map(|p| glam::Vec2::new(p.x.to_f32(), p.y.to_f32()))
            .collect(),
        _ => return None,
    })
}

/// A `float4` (or `float3`, taken with alpha 1) as its first three components.
pub(super) fn rgb_of4(v: &sdf::Value) -> Option<Vec3> {
    Some(match v {
        sdf::Value::Vec4f(a) => Vec3::new(a.x, a.y, a.z),
        sdf::Value::Vec4d(a) => DVec3::new(a.x, a.y, a.z).as_vec3(),
        sdf::Value::Vec4h(a) => Vec3::new(a.x.to_f32(), a.y.to_f32(), a.z.to_f32()),
        other => vec3(other)?.as_vec3(),
    })
}
