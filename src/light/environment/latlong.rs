//! The lat-long map's texels and its mapping between directions and (u, v) ([`direction_to_uv`],
//! [`uv_to_direction`]): the equirectangular convention of the module docs, apart from the light that samples it.

use std::f32::consts::{PI, TAU};

use glam::Vec3;

use super::super::distribution::Distribution2D;

/// A lat-long map, with its sampling distribution.
#[derive(Debug, Clone)]
pub(super) struct LatLong {
    pub(super) width: usize,
    pub(super) height: usize,
    /// Radiance (intensity applied, cleaned), row 0 at the top.
    pub(super) texels: Vec<Vec3>,
    /// Over luminance · sin θ_c.
    pub(super) distribution: Distribution2D,
    /// Mean radiance over the sphere (solid-angle weighted).
    pub(super) average: Vec3,
    /// Texel channel values replaced by 0 (negative in the file).
    pub(super) clamped: usize,
    /// The magnitude of those values over the magnitude of all values.
    pub(super) negative_share: f64,
}

impl LatLong {
    /// The texel containing `uv` ∈ [0, 1]² (edges clamped).
    #[inline]
    pub(super) fn texel(&self, uv: [f32; 2]) -> Vec3 {
        let col = ((uv[0] * self.width as f32) as usize).min(self.width - 1);
        let row = ((uv[1] * self.height as f32) as usize).min(self.height - 1);
        self.texels[row * self.width + col]
    }
}

/// (u, v) ∈ [0, 1]² of a unit direction in the map frame: u = 1/2 + φ/2π with φ = atan2(x, −z), v = θ/π with θ
/// the angle from +y (computed with atan2, exact near the poles).
#[inline]
pub fn direction_to_uv(d: Vec3) -> [f32; 2] {
    let theta = (d.x * d.x + d.z * d.z).sqrt().atan2(d.y);
    let phi = d.x.atan2(-d.z);
    [
        (0.5 + phi / TAU).clamp(0.0, 1.0),
        (theta / PI).clamp(0.0, 1.0),
    ]
}

/// The unit map-frame direction at `uv` and its sin θ: θ = πv, φ = 2π(u − 1/2),
/// d = (sin θ sin φ, cos θ, −sin θ cos φ).
#[inline]
pub fn uv_to_direction(uv: [f32; 2]) -> (Vec3, f32) {
    let (sin_theta, cos_theta) = (PI * uv[1]).sin_cos();
    let (sin_phi, cos_phi) = (TAU * (uv[0] - 0.5)).sin_cos();
    let sin_theta = sin_theta.max(0.0);
    (
        Vec3::new(sin_theta * sin_phi, cos_theta, -sin_theta * cos_phi),
        sin_theta,
    )
}
