//! A pinhole camera with look-at and vertical field of view, and auto-framing from a model's bounds.

use glam::Vec3;

use serde::Deserialize;

use crate::ray::{Ray, MAX_ORIGIN, MAX_SCENE_COORD};

/// `[camera]`: a pinhole camera. Without `position` the camera is placed automatically so the model's bounding
/// sphere fills the frame, looking along `view` at the model's centre.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraConfig {
    /// Vertical field of view, degrees, in (0, 180).
    pub fov: f32,
    /// Eye position, world space.
    #[serde(default, deserialize_with = "crate::util::exact_array::option_array")]
    pub position: Option<[f32; 3]>,
    /// Point looked at (default: the model's bounding-box centre).
    #[serde(default, deserialize_with = "crate::util::exact_array::option_array")]
    pub look_at: Option<[f32; 3]>,
    /// Up vector.
    #[serde(deserialize_with = "crate::util::exact_array::array")]
    pub up: [f32; 3],
    /// Viewing direction used by auto-framing (from the eye towards the model).
    #[serde(deserialize_with = "crate::util::exact_array::array")]
    pub view: [f32; 3],
    /// Auto-framing margin: 1 fits the bounding sphere exactly, larger zooms out.
    pub margin: f32,
    /// Turntable: degrees the eye turns about the `up` axis through the look-at point per animation frame
    /// (`render --frames`), counter-clockwise seen from above; frame 0 is the camera as placed. 0: no orbit.
    pub orbit_degrees_per_frame: f32,
    /// A USD stage whose first `Camera` prim places the camera (position, view, up, fov), relative to the scene
    /// file; read when the scene is resolved ([`crate::scene::Scene::resolve`]). Excludes `position`, `look_at`
    /// and `fov`.
    pub usd: Option<std::path::PathBuf>,
    /// The animation frame the camera is placed for (set by `render --frames`; not a scene key).
    #[serde(skip)]
    pub frame: i32,
}

impl Default for CameraConfig {
    fn default() -> Self {
        CameraConfig {
            fov: 40.0,
            position: None,
            look_at: None,
            up: [0.0, 1.0, 0.0],
            view: [0.0, 0.0, -1.0],
            margin: 1.05,
            orbit_degrees_per_frame: 0.0,
            usd: None,
            frame: 0,
        }
    }
}

impl CameraConfig {
    /// Range checks; messages name the `camera.*` key.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.fov > 0.0 && self.fov < 180.0) {
            return Err(format!(
                "camera.fov must be in (0, 180) degrees, got {}",
                self.fov
            ));
        }
        if !(self.margin.is_finite() && self.margin > 0.0) {
            return Err(format!("camera.margin must be > 0, got {}", self.margin));
        }
        if self.usd.is_some() && (self.position.is_some() || self.look_at.is_some()) {
            return Err(
                "camera.usd places the camera: leave camera.position and camera.look_at out".into(),
            );
        }
        if !self.orbit_degrees_per_frame.is_finite() {
            return Err(format!(
                "camera.orbit_degrees_per_frame must be finite, got {}",
                self.orbit_degrees_per_frame
            ));
        }
        for (key, v) in [("camera.up", self.up), ("camera.view", self.view)] {
            if !Vec3::from(v).is_finite() || Vec3::from(v).length_squared() == 0.0 {
                return Err(format!("{key} must be a non-zero finite vector, got {v:?}"));
            }
        }
        for (key, p) in [
            ("camera.position", self.position),
            ("camera.look_at", self.look_at),
        ] {
            if let Some(p) = p {
                let max = MAX_SCENE_COORD;
                if !p.iter().all(|x| x.abs() <= max) {
                    return Err(format!(
                        "{key} must be finite and within {max:e} of the origin on every axis, got {p:?} (rays \
                         from farther away cannot be traced in single precision)"
                    ));
                }
            }
        }
        if let (Some(p), Some(l)) = (self.position, self.look_at) {
            if p == l {
                return Err(format!(
                    "camera.look_at must differ from camera.position, both are {p:?}"
                ));
            }
        }
        // Without look_at, a placed camera looks at the model's centre: checked by `camera`, with the bounds.
        let forward = match (self.position, self.look_at) {
            (Some(p), Some(l)) => Some((
                Vec3::from(l) - Vec3::from(p),
                "the view direction (camera.look_at - camera.position)",
            )),
            (None, _) => Some((Vec3::from(self.view), "camera.view")),
            (Some(_), None) => None,
        };
        if let Some((forward, along)) = forward.filter(|(f, _)| parallel(*f, Vec3::from(self.up))) {
            return Err(format!(
                "camera.up {:?} is parallel to {along} {:?}: the image's vertical is undefined",
                self.up,
                forward.to_array()
            ));
        }
        Ok(())
    }

    /// The camera of a frame whose hair has `bounds` (min, max), as [`Camera::from_config`] places it, refused
    /// when its position would make camera rays invalid ([`crate::ray::Ray::check`]: an auto-framed eye moves
    /// far away for a tiny `fov` or a huge `margin`), when the view direction is undefined (a position equal to
    /// the model's centre), or when `up` is parallel to it. Messages name the keys.
    pub fn camera(&self, bounds: (Vec3, Vec3), width: u32, height: u32) -> Result<Camera, String> {
        self.validate()?;
        let camera = Camera::from_config(self, bounds, width, height);
        let keys = if self.position.is_some() {
            "camera.position"
        } else {
            "the auto-framed camera (camera.fov, camera.margin and the model's size)"
        };
        if !(..MAX_ORIGIN).contains(&camera.position.abs().max_element()) {
            return Err(format!(
                "{keys} puts the eye at {:?}, farther than {MAX_ORIGIN:e} from the origin: no camera ray could be \
                 traced",
                camera.position.to_array()
            ));
        }
        let centre = 0.5 * (bounds.0 + bounds.1);
        let look_at = self.look_at.map(Vec3::from).unwrap_or(centre);
        let forward = look_at - camera.position;
        if !forward.is_finite() || forward.length_squared() <= 0.0 {
            return Err(format!(
                "camera.position {:?} is the point looked at (camera.look_at, or the model's centre without it)",
                camera.position.to_array()
            ));
        }
        if parallel(forward, Vec3::from(self.up)) {
            return Err(format!(
                "camera.up {:?} is parallel to the view direction {:?}: the image's vertical is undefined",
                self.up,
                forward.to_array()
            ));
        }
        Ok(camera)
    }
}

/// Whether `a` and `b` (non-zero) are parallel within a float tolerance: the cross product of the unit vectors is
/// shorter than 1e-6 (an angle under 0.2 arc seconds).
fn parallel(a: Vec3, b: Vec3) -> bool {
    match (a.try_normalize(), b.try_normalize()) {
        (Some(a), Some(b)) => a.cross(b).length() < 1e-6,
        _ => false,
    }
}

/// A pinhole camera. Pixel (0, 0) is the top-left corner of the image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub position: Vec3,
    /// Unit viewing direction.
    pub forward: Vec3,
    right: Vec3,
    up: Vec3,
    /// tan(fov/2): half the image-plane height at distance 1.
    tan_half_fov: f32,
    width: f32,
    height: f32,
}

impl Camera {
    /// A camera at `position` looking at `look_at`, with `up` and vertical `fov_degrees`, for a `width`×`height` image.
    pub fn look_at(
        position: Vec3,
        look_at: Vec3,
        up: Vec3,
        fov_degrees: f32,
        width: u32,
        height: u32,
    ) -> Camera {
        let forward = (look_at - position).try_normalize().unwrap_or(Vec3::NEG_Z);
        // If up is parallel to the view direction, pick any perpendicular.
        let right = forward
            .cross(up)
            .try_normalize()
            .unwrap_or_else(|| forward.any_orthonormal_vector());
        let up = right.cross(forward);
        Camera {
            position,
            forward,
            right,
            up,
            tan_half_fov: (0.5 * fov_degrees.to_radians()).tan(),
            width: width as f32,
            height: height as f32,
        }
    }

    /// Builds the camera of a scene: the configured eye, or one placed so that the bounding sphere of
    /// `bounds` (min, max) fills the narrower image axis, times `margin`.
    pub fn from_config(
        config: &CameraConfig,
        bounds: (Vec3, Vec3),
        width: u32,
        height: u32,
    ) -> Camera {
        let centre = 0.5 * (bounds.0 + bounds.1);
        let look_at = config.look_at.map(Vec3::from).unwrap_or(centre);
        let position = match config.position {
            Some(p) => Vec3::from(p),
            None => {
                let radius = 0.5 * (bounds.1 - bounds.0).length();
                let half_v = 0.5 * config.fov.to_radians();
                let half_h = (half_v.tan() * width as f32 / height as f32).atan();
                let distance = config.margin * radius / half_v.min(half_h).sin();
                let view = Vec3::from(config.view).normalize();
                look_at - distance * view
            }
        };
        // The turntable angle in f64 and reduced mod 360, so late frames keep their precision.
        let orbit = (f64::from(config.frame) * f64::from(config.orbit_degrees_per_frame)) % 360.0;
        let position = if orbit == 0.0 {
            position
        } else {
            let axis = Vec3::from(config.up).normalize();
            let turn = glam::Quat::from_axis_angle(axis, (orbit as f32).to_radians());
            look_at + turn * (position - look_at)
        };
        Camera::look_at(
            position,
            look_at,
            Vec3::from(config.up),
            config.fov,
            width,
            height,
        )
    }

    /// Image size in pixels (width, height).
    pub fn resolution(&self) -> (u32, u32) {
        (self.width as u32, self.height as u32)
    }

    /// One ray through each pixel centre, in scanline order (for benchmarks and tests).
    pub fn pixel_centre_rays(&self) -> Vec<Ray> {
        let (w, h) = self.resolution();
        (0..h)
            .flat_map(|y| (0..w).map(move |x| self.ray(x as f32 + 0.5, y as f32 + 0.5)))
            .collect()
    }

    /// The primary ray through film position (`x`, `y`) in pixels (continuous; pixel centres at +0.5).
    #[inline]
    pub fn ray(&self, x: f32, y: f32) -> Ray {
        let sx = (2.0 * x / self.width - 1.0) * self.tan_half_fov * self.width / self.height;
        let sy = (1.0 - 2.0 * y / self.height) * self.tan_half_fov;
        let dir = (self.forward + sx * self.right + sy * self.up).normalize();
        Ray::new(self.position, dir)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_pixel_looks_forward_and_corners_span_the_fov() {
        let cam = Camera::look_at(
            Vec3::new(0.0, 0.0, 5.0),
            Vec3::ZERO,
            Vec3::Y,
            90.0,
            200,
            100,
        );
        let centre = cam.ray(100.0, 50.0);
        assert!((centre.dir - Vec3::NEG_Z).length() < 1e-6);
        // Top edge centre: 45° up for a 90° vertical fov.
        let top = cam.ray(100.0, 0.0);
        assert!((top.dir.angle_between(Vec3::NEG_Z).to_degrees() - 45.0).abs() < 1e-3);
        assert!(top.dir.y > 0.0, "image y grows downwards");
        let right = cam.ray(200.0, 50.0);
        assert!(right.dir.x > 0.0);
    }

    #[test]
    fn auto_framing_fits_the_bounding_sphere() {
        let config = CameraConfig {
            fov: 60.0,
            margin: 1.0,
            ..Default::default()
        };
        let bounds = (Vec3::splat(-1.0), Vec3::splat(1.0));
        let cam = Camera::from_config(&config, bounds, 100, 100);
        // The sphere of radius √3 is tangent to the 30° half-angle cone: distance = √3 / sin 30°.
        assert!(
            (cam.position.length() - 3f32.sqrt() / 0.5).abs() < 1e-4,
            "{:?}",
            cam.position
        );
    }

    #[test]
    fn the_orbit_turns_the_eye_about_up_through_the_look_at_point() {
        let config = CameraConfig {
            position: Some([0.0, 1.0, 5.0]),
            look_at: Some([0.0, 1.0, 0.0]),
            orbit_degrees_per_frame: 10.0,
            frame: 9,
            ..Default::default()
        };
        let bounds = (Vec3::splat(-1.0), Vec3::splat(1.0));
        let cam = Camera::from_config(&config, bounds, 100, 100);
        // 90° counter-clockwise seen from +y: +z goes to +x.
        assert!(
            (cam.position - Vec3::new(5.0, 1.0, 0.0)).length() < 1e-5,
            "{:?}",
            cam.position
        );
        assert!((cam.forward - Vec3::NEG_X).length() < 1e-6);
        let still = CameraConfig { frame: 0, ..config };
        let cam = Camera::from_config(&still, bounds, 100, 100);
        assert_eq!(
            cam.position,
            Vec3::new(0.0, 1.0, 5.0),
            "frame 0 is as placed"
        );
    }
}
