//! Building a map environment: reading the file within the size limits ([`MAX_MAP_BYTES`],
//! [`MAX_MAP_DECODED_BYTES`]), cleaning and scaling its texels, and the sampling distribution and rotation
//! ([`Environment::load`], [`Environment::from_image`]); set-up, apart from the per-ray queries.

use std::f32::consts::PI;
use std::path::{Path, PathBuf};

use glam::{Mat3, Quat, Vec3};

use super::super::distribution::Distribution2D;
use super::super::{check, check_direction, LightError};
use super::latlong::LatLong;
use super::{Environment, Source};
use crate::image::{read_at_most, Image};
use crate::util::color::luminance;

/// The label used in errors for [`Environment::from_image`], which has no file.
const IN_MEMORY: &str = "<in-memory image>";

/// Largest environment map file read: 1 GiB. A 16K × 8K lat-long map in half-float RGB is 768 MiB uncompressed;
/// anything larger is not a map a frame can use (its decoded texels and sampling tables would exceed a machine's
/// memory before the render starts).
pub const MAX_MAP_BYTES: u64 = 1 << 30;

/// Largest decoded environment map: 4 GiB of `f32` texels (a 16K × 8K RGBA map is 2 GiB), checked from the file's
/// header before any pixel is decoded, since a small compressed file can declare any size.
pub const MAX_MAP_DECODED_BYTES: u64 = 4 << 30;

impl Environment {
    /// The lat-long map in `image` (channels R, G, B, or a single channel read as grey), scaled by `intensity`
    /// (finite, ≥ 0), turned by `rotation_deg` degrees counter-clockwise about `up` (see the module docs).
    pub fn from_image(
        image: &Image,
        intensity: f32,
        rotation_deg: f32,
        up: Vec3,
    ) -> Result<Environment, LightError> {
        Environment::build(image, Path::new(IN_MEMORY), intensity, rotation_deg, up)
    }

    /// Reads the lat-long map at `path` (any format [`crate::image::read`] reads: EXR, Radiance HDR, ...) and
    /// builds it as [`Environment::from_image`] does. Errors name the file.
    pub fn load(
        path: impl AsRef<Path>,
        intensity: f32,
        rotation_deg: f32,
        up: Vec3,
    ) -> Result<Environment, LightError> {
        let path = path.as_ref();
        // Before OpenImageIO sees it: a FIFO would block its open forever and `/dev/zero` never ends.
        let (_, len) = crate::util::input_file::open_regular(path).map_err(|source| {
            LightError::EnvironmentFile {
                path: path.to_path_buf(),
                source,
            }
        })?;
        if len > MAX_MAP_BYTES {
            return Err(LightError::EnvironmentContent {
                path: path.to_path_buf(),
                message: format!(
                    "the file is {}, more than the {} an environment map may be",
                    crate::util::input_file::human_bytes(len),
                    crate::util::input_file::human_bytes(MAX_MAP_BYTES)
                ),
            });
        }
        let image = read_at_most(path, MAX_MAP_DECODED_BYTES).map_err(|source| {
            LightError::EnvironmentMap {
                path: path.to_path_buf(),
                source,
            }
        })?;
        Environment::build(&image, path, intensity, rotation_deg, up)
    }

    // One piece: one map's checks, cleaning, distribution and rotation, in order, on the same texels.
    fn build(
        image: &Image,
        path: &Path,
        intensity: f32,
        rotation_deg: f32,
        up: Vec3,
    ) -> Result<Environment, LightError> {
        check(
            "environment",
            "intensity",
            intensity,
            ">= 0 and finite",
            intensity >= 0.0 && intensity.is_finite(),
        )?;
        check(
            "environment",
            "rotation",
            rotation_deg,
            "finite (degrees)",
            rotation_deg.is_finite(),
        )?;
        let up = check_direction("environment", "up", up)?;
        let content = |message: String| LightError::EnvironmentContent {
            path: PathBuf::from(path),
            message,
        };
        let (width, height, nc) = (image.width, image.height, image.channels.len());
        if width == 0 || height == 0 {
            return Err(content(format!("the image is empty ({width} x {height})")));
        }
        if image.data.len() != width * height * nc {
            return Err(content(format!(
                "{width} x {height} pixels of {nc} channels need {} values, the image has {}",
                width * height * nc,
                image.data.len()
            )));
        }
        let rgb = match (
            image.channel_index("R"),
            image.channel_index("G"),
            image.channel_index("B"),
        ) {
            (Some(r), Some(g), Some(b)) => [r, g, b],
            _ if nc == 1 => [0, 0, 0],
            _ => {
                return Err(content(format!(
                    "needs channels R, G, B or a single channel, has {:?}",
                    image.channels
                )))
            }
        };
        // A NaN or infinite texel is a damaged file: refused, with where the first one is. A negative one is what
        // lossy compression (DWAB) leaves of a black texel: read as 0 and counted, for the render to report.
        if let Some(i) = image
            .data
            .chunks_exact(nc)
            .position(|px| rgb.iter().any(|&c| !px[c].is_finite()))
        {
            let count = image
                .data
                .chunks_exact(nc)
                .filter(|px| rgb.iter().any(|&c| !px[c].is_finite()))
                .count();
            return Err(content(format!(
                "{count} texels are NaN or infinite (the first at column {}, row {}): the map is damaged",
                i % width,
                i / width
            )));
        }
        let (mut clamped, mut negative, mut positive) = (0usize, 0.0f64, 0.0f64);
        let texels: Vec<Vec3> = image
            .data
            .chunks_exact(nc)
            .map(|px| {
                Vec3::from_array(rgb.map(|c| {
                    let x = px[c];
                    if x >= 0.0 {
                        positive += f64::from(x);
                        x
                    } else {
                        clamped += 1;
                        negative -= f64::from(x);
                        0.0
                    }
                })) * intensity
            })
            .collect();
        let negative_share = if negative > 0.0 {
            negative / (negative + positive)
        } else {
            0.0
        };
        let brightest = texels.iter().fold(0.0f32, |m, t| m.max(t.max_element()));
        if !(..=super::super::MAX_RADIANCE).contains(&brightest) {
            return Err(content(format!(
                "intensity {intensity} times the brightest texel is {brightest}, more than the {:e} a radiance may \
                 be (environment.intensity is probably in the wrong units)",
                super::super::MAX_RADIANCE
            )));
        }
        let mut weights = Vec::with_capacity(width * height);
        let mut average = glam::DVec3::ZERO;
        for row in 0..height {
            let theta_c = PI * (row as f32 + 0.5) / height as f32;
            // Exact solid angle of a texel of this row: (2π / width)(cos θ₀ − cos θ₁).
            let (t0, t1) = (
                std::f64::consts::PI * row as f64 / height as f64,
                std::f64::consts::PI * (row + 1) as f64 / height as f64,
            );
            let omega = std::f64::consts::TAU / width as f64 * (t0.cos() - t1.cos());
            for t in &texels[row * width..(row + 1) * width] {
                weights.push(luminance(*t) * theta_c.sin());
                average += t.as_dvec3() * omega;
            }
        }
        let average = (average / (4.0 * std::f64::consts::PI)).as_vec3();
        // Map frame → world: +Y to `up` by the shortest arc, then the rotation about `up`.
        let turn = Quat::from_axis_angle(up, rotation_deg.to_radians())
            * Quat::from_rotation_arc(Vec3::Y, up);
        let to_world = Mat3::from_quat(turn.normalize());
        Ok(Environment {
            source: Source::Map(LatLong {
                width,
                height,
                distribution: Distribution2D::new(&weights, width, height),
                texels,
                average,
                clamped,
                negative_share,
            }),
            to_world,
            to_map: to_world.transpose(),
        })
    }
}
