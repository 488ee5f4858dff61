//! Rays, and the validation every ray passes before it may reach a native tracer.
//!
//! Debian's libembree3 is built with assertions on: a NaN/Inf component, a negative `tnear` or an origin with
//! |x| ≥ 1e19 aborts the whole process. [`Ray::check`] rejects all of those (and a zero direction, which Embree
//! treats as a miss but which has no meaning for us) so that a bad ray becomes an error, not a crash.

use glam::Vec3;

/// Origins farther than this from the world origin are rejected (Embree 3 asserts at 1e19; leave headroom).
pub const MAX_ORIGIN: f32 = 1e18;

/// Largest |coordinate| a scene may place anything a ray starts from or ends at (hair points plus their radius,
/// light and shape corners, the camera): [`MAX_ORIGIN`] / 1000. Rays start on surfaces and are offset from them by
/// small multiples of the scene's size, so a scene inside this bound never produces an origin [`Ray::check`]
/// rejects; scenes are refused at load beyond it (naming the file or key) instead of rendering only background.
pub const MAX_SCENE_COORD: f32 = 1e15;

/// A ray segment: points `origin + t·dir` for `t` in `[tnear, tfar]`. `dir` need not be unit length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    /// Ray origin, world space.
    pub origin: Vec3,
    /// Ray direction, world space.
    pub dir: Vec3,
    /// Start of the valid interval (≥ 0).
    pub tnear: f32,
    /// End of the valid interval (> tnear, may be +∞).
    pub tfar: f32,
}

/// Why a ray was rejected before tracing.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum InvalidRay {
    /// Origin or direction has a NaN or infinite component.
    #[error("ray origin or direction is not finite")]
    NotFinite,
    /// The origin is too far away for single-precision tracing.
    #[error("ray origin is too far from the world origin (|x| >= {MAX_ORIGIN:e})")]
    OriginTooFar,
    /// The direction is the zero vector.
    #[error("ray direction is zero")]
    ZeroDirection,
    /// `tnear` is negative or NaN, or `tfar` is NaN or not greater than `tnear`.
    #[error("ray interval [tnear, tfar] is empty or invalid")]
    BadInterval,
}

impl Ray {
    /// A ray from `origin` along `dir` over `[0, ∞)`.
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Ray {
            origin,
            dir,
            tnear: 0.0,
            tfar: f32::INFINITY,
        }
    }

    /// A ray over `[tnear, tfar]`.
    pub fn segment(origin: Vec3, dir: Vec3, tnear: f32, tfar: f32) -> Self {
        Ray {
            origin,
            dir,
            tnear,
            tfar,
        }
    }

    /// The point at parameter `t`.
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + t * self.dir
    }

    /// Accepts only rays Embree can trace without tripping its assertions.
    pub fn check(&self) -> Result<(), InvalidRay> {
        if !(self.origin.is_finite() && self.dir.is_finite()) {
            return Err(InvalidRay::NotFinite);
        }
        if self.origin.abs().max_element() >= MAX_ORIGIN {
            return Err(InvalidRay::OriginTooFar);
        }
        if self.dir == Vec3::ZERO {
            return Err(InvalidRay::ZeroDirection);
        }
        // Written so that NaN in either bound is rejected too.
        let interval_ok = self.tnear >= 0.0 && self.tfar > self.tnear;
        if !interval_ok {
            return Err(InvalidRay::BadInterval);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_what_embree_would_abort_on() {
        let ok = Ray::new(Vec3::ZERO, Vec3::X);
        assert_eq!(ok.check(), Ok(()));
        let bad = [
            (
                Ray::new(Vec3::new(f32::NAN, 0.0, 0.0), Vec3::X),
                InvalidRay::NotFinite,
            ),
            (
                Ray::new(Vec3::ZERO, Vec3::new(0.0, f32::INFINITY, 0.0)),
                InvalidRay::NotFinite,
            ),
            (
                Ray::new(Vec3::new(2e19, 0.0, 0.0), Vec3::X),
                InvalidRay::OriginTooFar,
            ),
            (Ray::new(Vec3::ZERO, Vec3::ZERO), InvalidRay::ZeroDirection),
            (
                Ray::segment(Vec3::ZERO, Vec3::X, -1.0, 1.0),
                InvalidRay::BadInterval,
            ),
            (
                Ray::segment(Vec3::ZERO, Vec3::X, 0.0, f32::NAN),
                InvalidRay::BadInterval,
            ),
            (
                Ray::segment(Vec3::ZERO, Vec3::X, 2.0, 1.0),
                InvalidRay::BadInterval,
            ),
        ];
        for (ray, why) in bad {
            assert_eq!(ray.check(), Err(why), "{ray:?}");
        }
    }
}
