//! Framing: where a deep opacity map looks from and what it covers (orthographic for distant lights and environment
//! cells, perspective for area lights; see "Lights" in the [module docs](super)).

use glam::Vec3;

use crate::hair::Strands;
use crate::ray::Ray;

/// How a map projects world points: orthographic (distant lights, environment directions) or perspective (area
/// lights).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Projection {
    /// Parallel rays along `forward`; the map covers a square of half-side `half_extent` around `origin`.
    Orthographic { half_extent: f32 },
    /// Rays from `origin`; the map covers a square frustum of half-angle atan(`tan_half`).
    Perspective { tan_half: f32 },
}

/// Where a map looks from and what it covers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapFrame {
    pub(super) origin: Vec3,
    pub(super) right: Vec3,
    pub(super) up: Vec3,
    pub(super) forward: Vec3,
    pub(super) projection: Projection,
    pub(super) resolution: u32,
}

impl MapFrame {
    /// An orthographic map looking along `forward` at the sphere (`center`, `radius`), depth 0 a little in front of
    /// it, so that every point of the sphere has a positive depth.
    pub fn orthographic(forward: Vec3, center: Vec3, radius: f32, resolution: u32) -> MapFrame {
        let forward = forward.normalize();
        let (right, up) = forward.any_orthonormal_pair();
        MapFrame {
            origin: center - forward * (radius * 1.01),
            right,
            up,
            forward,
            projection: Projection::Orthographic {
                half_extent: radius * 1.01,
            },
            resolution,
        }
    }

    /// An orthographic map looking along `forward`, framing the strands' control points (which bound the curves)
    /// tightly: a square around their projection, depth 0 just in front of the nearest.
    pub fn fit_orthographic(forward: Vec3, strands: &Strands, resolution: u32) -> MapFrame {
        let forward = forward.normalize();
        let (right, up) = forward.any_orthonormal_pair();
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        let mut r_max = 0.0f32;
        for c in &strands.control_points {
            let p = Vec3::new(c[0], c[1], c[2]);
            let q = Vec3::new(p.dot(right), p.dot(up), p.dot(forward));
            lo = lo.min(q);
            hi = hi.max(q);
            r_max = r_max.max(c[3]);
        }
        if !(lo.is_finite() && hi.is_finite()) {
            return MapFrame::orthographic(forward, Vec3::ZERO, 1.0, resolution);
        }
        let mid = 0.5 * (lo + hi);
        let half_extent = (0.5 * (hi.x - lo.x).max(hi.y - lo.y) + r_max).max(1e-6) * 1.01;
        let margin = r_max + 1e-3 * half_extent;
        MapFrame {
            origin: right * mid.x + up * mid.y + forward * (lo.z - margin),
            right,
            up,
            forward,
            projection: Projection::Orthographic { half_extent },
            resolution,
        }
    }

    /// A perspective map from `eye` framing the sphere (`center`, `radius`); `None` when `eye` is inside it.
    pub fn perspective(eye: Vec3, center: Vec3, radius: f32, resolution: u32) -> Option<MapFrame> {
        let to = center - eye;
        let distance = to.length();
        if distance.is_nan() || distance <= radius * 1.01 {
            return None;
        }
        let forward = to / distance;
        let (right, up) = forward.any_orthonormal_pair();
        let sin_half = radius * 1.01 / distance;
        let tan_half = sin_half / (1.0 - sin_half * sin_half).sqrt();
        Some(MapFrame {
            origin: eye,
            right,
            up,
            forward,
            projection: Projection::Perspective { tan_half },
            resolution,
        })
    }

    /// The ray from the light through the centre of texel (`tx`, `ty`) (orthographic maps: from the depth-0 plane
    /// along `forward`; perspective maps: from the eye). For measuring what a ray-traced build would cost.
    pub fn texel_ray(&self, tx: u32, ty: u32) -> Ray {
        let res = self.resolution as f32;
        let (sx, sy) = (
            2.0 * (tx as f32 + 0.5) / res - 1.0,
            2.0 * (ty as f32 + 0.5) / res - 1.0,
        );
        match self.projection {
            Projection::Orthographic { half_extent } => Ray::new(
                self.origin + (self.right * sx + self.up * sy) * half_extent,
                self.forward,
            ),
            Projection::Perspective { tan_half } => Ray::new(
                self.origin,
                (self.forward + (self.right * sx + self.up * sy) * tan_half).normalize(),
            ),
        }
    }

    /// Continuous texel coordinates (texel centres at i + 0.5) and depth of `p`; `None` behind a perspective eye.
    #[inline]
    pub(super) fn project(&self, p: Vec3) -> Option<(f32, f32, f32)> {
        let d = p - self.origin;
        let z = d.dot(self.forward);
        if matches!(self.projection, Projection::Perspective { .. }) && z <= 0.0 {
            return None;
        }
        let scale = self.half_side(z);
        let half_res = 0.5 * self.resolution as f32;
        Some((
            (d.dot(self.right) / scale + 1.0) * half_res,
            (d.dot(self.up) / scale + 1.0) * half_res,
            z,
        ))
    }

    /// World size of one texel at depth `z`.
    #[inline]
    pub(super) fn texel_size(&self, z: f32) -> f32 {
        2.0 * self.half_side(z.max(0.0)) / self.resolution as f32
    }

    /// Half the side of the square the map covers at depth `z` ≥ 0, world units (constant for orthographic maps).
    #[inline]
    fn half_side(&self, z: f32) -> f32 {
        match self.projection {
            Projection::Orthographic { half_extent } => half_extent,
            Projection::Perspective { tan_half } => z * tan_half,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texel_rays_project_back_to_their_texels() {
        let frames = [
            MapFrame::orthographic(Vec3::new(1.0, -1.0, 1.0), Vec3::new(0.0, 0.5, 0.0), 2.0, 64),
            MapFrame::perspective(Vec3::new(0.0, 5.0, 1.0), Vec3::ZERO, 1.5, 64).unwrap(),
        ];
        for frame in frames {
            for (tx, ty) in [(0, 0), (17, 40), (63, 63)] {
                let ray = frame.texel_ray(tx, ty);
                let (x, y, _) = frame.project(ray.at(2.5)).unwrap();
                assert!(
                    (x - (tx as f32 + 0.5)).abs() < 1e-3 && (y - (ty as f32 + 0.5)).abs() < 1e-3
                );
            }
        }
        assert!(MapFrame::perspective(Vec3::ZERO, Vec3::ZERO, 1.0, 64).is_none());
    }
}
