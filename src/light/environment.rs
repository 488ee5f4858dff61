//! Light from infinitely far away in every direction: a lat-long (equirectangular) HDR map, or a constant sky.
//!
//! # Direction convention
//!
//! The map has its own frame x′, y′, z′ with y′ = `up` (world +Y by default). A unit direction d′ in that frame
//! has polar angle θ = acos(d′_y) from up and azimuth φ = atan2(d′_x, −d′_z) ∈ [−π, π], and is looked up at
//!
//! u = 1/2 + φ / 2π (columns, left → right),   v = θ / π (rows, top → bottom),
//!
//! so the **top row looks up**, the bottom row down, the **centre column looks towards −z′** (a default camera's
//! view direction), u = 3/4 towards +x′ (to the right, as seen from inside the sphere with up at the top) and the
//! left/right edge towards +z′. Inversely d′ = (sin θ sin φ, cos θ, −sin θ cos φ).
//!
//! The map frame is the world frame turned so +Y goes to `up` (shortest arc), then rotated by `rotation_deg` about
//! `up`: positive is **counter-clockwise seen from above** (right-handed about `up`), so a feature of the map at
//! world direction d moves to R_up(rotation) d.
//!
//! # Radiance, sampling, pdf
//!
//! [`Environment::le`] is a **nearest-texel** lookup (no filtering), so the radiance a sample carries and the
//! value an escaping ray sees at that direction are the same texel, and the importance density below is exactly
//! proportional to it within each texel (up to the sin θ of the texel centre). Negative texel values (DWAB
//! compression leaves tiny negatives) are replaced by 0 and counted ([`Environment::clamped_texels`], which a render
//! reports); a NaN or infinite texel refuses the map as damaged. `intensity` scales the whole map.
//!
//! Directions are importance sampled with a [`Distribution2D`](super::distribution::Distribution2D) over the texel
//! weights luminance(texel) · sin θ_c (θ_c at the texel's centre: the sin θ of the lat-long Jacobian, so rows near
//! the poles, which cover little solid angle, are drawn less). The density per unit solid angle of a direction at (u,
//! v) is
//!
//! p_ω = p_uv(u, v) / (2π² sin θ),   since dω = sin θ dθ dφ = 2π² sin θ du dv,
//!
//! and 0 where sin θ = 0 (the poles, a set of measure zero). A map that is black everywhere has nothing to
//! sample: [`Environment::sample_li`] returns `None` and [`Environment::pdf_li`] 0.
//!
//! A constant environment (radiance L everywhere) is sampled uniformly on the sphere, pdf 1/4π.

mod latlong;
mod load;

pub use latlong::{direction_to_uv, uv_to_direction};
pub use load::{MAX_MAP_BYTES, MAX_MAP_DECODED_BYTES};

use latlong::LatLong;
use std::f32::consts::PI;

use glam::{Mat3, Vec3};

use super::{check_color, clamp_u, unit, LightError, LightSample};
use crate::util::color::luminance;
use crate::util::sampling::{uniform_sphere, UNIFORM_SPHERE_PDF};

/// Light from infinitely far away: a lat-long map or a constant (see the module docs for the conventions).
#[derive(Debug, Clone)]
pub struct Environment {
    source: Source,
    /// Map frame → world (columns x′, y′ = up, z′).
    to_world: Mat3,
    /// World → map frame (the transpose of `to_world`).
    to_map: Mat3,
}

/// What the environment emits.
#[derive(Debug, Clone)]
enum Source {
    Constant(Vec3),
    Map(LatLong),
}

impl Environment {
    /// A sky of constant `radiance` (RGB, every channel finite and ≥ 0) in every direction.
    pub fn constant(radiance: Vec3) -> Result<Environment, LightError> {
        check_color("environment", "radiance", radiance)?;
        Ok(Environment {
            source: Source::Constant(radiance),
            to_world: Mat3::IDENTITY,
            to_map: Mat3::IDENTITY,
        })
    }
    /// (width, height) of the map; `None` for a constant environment.
    pub fn size(&self) -> Option<(usize, usize)> {
        match &self.source {
            Source::Constant(_) => None,
            Source::Map(m) => Some((m.width, m.height)),
        }
    }

    /// How many texel channel values were negative in the image and read as 0.
    pub fn clamped_texels(&self) -> usize {
        match &self.source {
            Source::Constant(_) => 0,
            Source::Map(m) => m.clamped,
        }
    }

    /// The negative values' magnitude over all values' (0 to 1): how much of the map reading them as 0 left out.
    pub fn negative_share(&self) -> f64 {
        match &self.source {
            Source::Constant(_) => 0.0,
            Source::Map(m) => m.negative_share,
        }
    }

    /// The mean radiance over the sphere of directions, (1/4π) ∫ L dω (intensity included).
    pub fn average_radiance(&self) -> Vec3 {
        match &self.source {
            Source::Constant(l) => *l,
            Source::Map(m) => m.average,
        }
    }

    /// Whether the radiance is the same from every direction (no map).
    pub fn is_constant(&self) -> bool {
        matches!(self.source, Source::Constant(_))
    }

    /// Power entering a sphere of radius `scene_radius`: 4π · π r² · luminance(average radiance) (pbrt-v4).
    pub fn power(&self, scene_radius: f32) -> f32 {
        4.0 * PI * PI * scene_radius * scene_radius * luminance(self.average_radiance())
    }

    /// The radiance of a constant environment (what [`Environment::le`] gives for every valid direction), `None`
    /// for a map.
    pub fn constant_radiance(&self) -> Option<Vec3> {
        match &self.source {
            Source::Constant(l) => Some(*l),
            Source::Map(_) => None,
        }
    }

    /// The radiance arriving from direction `dir` (world space, any non-zero length; the direction an escaping ray
    /// travels), nearest texel. 0 for a zero or non-finite `dir`.
    #[inline]
    pub fn le(&self, dir: Vec3) -> Vec3 {
        let Some(w) = unit(dir) else {
            return Vec3::ZERO;
        };
        match &self.source {
            Source::Constant(l) => *l,
            Source::Map(m) => m.texel(direction_to_uv(self.to_map * w)),
        }
    }

    /// ([`Environment::le`], [`Environment::pdf_li`]) of `dir`: the same values, the map's uv computed once.
    #[inline]
    pub fn le_and_pdf(&self, dir: Vec3) -> (Vec3, f32) {
        let Some(w) = unit(dir) else {
            return (Vec3::ZERO, 0.0);
        };
        match &self.source {
            Source::Constant(l) => (*l, UNIFORM_SPHERE_PDF),
            Source::Map(m) => {
                let d = self.to_map * w;
                let uv = direction_to_uv(d);
                let pdf = if m.distribution.integral() <= 0.0 {
                    0.0
                } else {
                    map_pdf(m, d, uv)
                };
                (m.texel(uv), pdf)
            }
        }
    }

    /// A direction drawn in proportion to luminance (a map) or uniformly (a constant). `None` for a black map.
    #[inline]
    pub fn sample_li(&self, u: [f32; 2]) -> Option<LightSample> {
        let (wi, radiance, pdf) = match &self.source {
            Source::Constant(l) => {
                let [a, b] = clamp_u(u);
                (uniform_sphere(a, b), *l, UNIFORM_SPHERE_PDF)
            }
            Source::Map(m) => {
                if m.distribution.integral() <= 0.0 {
                    return None;
                }
                let (uv, _) = m.distribution.sample(u);
                let wi = self.to_world * uv_to_direction(uv).0;
                // pdf and radiance are looked up again from wi, not taken from uv: a uv on a texel edge may come
                // back from the direction in the neighbouring texel, and MIS needs sample_li, pdf_li and le to
                // agree exactly (all three read the texel at the unit direction's uv; the density drawn differs
                // from the one reported only on those edges, a set of relative measure ~1e-7).
                let d = self.to_map * unit(wi)?;
                let uv = direction_to_uv(d);
                let pdf = map_pdf(m, d, uv);
                if pdf <= 0.0 {
                    return None;
                }
                (wi, m.texel(uv), pdf)
            }
        };
        Some(LightSample {
            wi,
            radiance,
            pdf,
            distance: f32::INFINITY,
            delta: false,
        })
    }

    /// The density per unit solid angle with which [`Environment::sample_li`] draws `wi` (0 at the poles of a
    /// map, for a black map, and for a zero or non-finite `wi`).
    #[inline]
    pub fn pdf_li(&self, wi: Vec3) -> f32 {
        let Some(w) = unit(wi) else {
            return 0.0;
        };
        match &self.source {
            Source::Constant(_) => UNIFORM_SPHERE_PDF,
            Source::Map(m) => {
                if m.distribution.integral() <= 0.0 {
                    return 0.0;
                }
                let d = self.to_map * w;
                map_pdf(m, d, direction_to_uv(d))
            }
        }
    }
}

/// The density per unit solid angle of map `m` at the unit map-frame direction `d` (whose uv is `uv`): p_uv / (2π²
/// sin θ), 0 at the poles and wherever it is not finite.
#[inline]
fn map_pdf(m: &LatLong, d: Vec3, uv: [f32; 2]) -> f32 {
    let sin_theta = (d.x * d.x + d.z * d.z).sqrt();
    if sin_theta <= 0.0 {
        return 0.0;
    }
    let pdf = m.distribution.pdf(uv) / (2.0 * PI * PI * sin_theta);
    if pdf.is_finite() {
        pdf
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::Image;
    use crate::light::Light;
    use crate::util::stats::chi_square;
    use glam::Quat;
    use rand::Rng;
    use rand_pcg::Pcg32;
    use std::path::PathBuf;
    use std::sync::OnceLock;

    #[test]
    fn a_small_file_declaring_a_huge_map_is_refused_before_decoding() {
        // A 60-byte Radiance header declaring 200 000 × 100 000 pixels (240 GB of f32 RGB) and no pixels.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("huge.hdr");
        std::fs::write(
            &path,
            "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 100000 +X 200000\n",
        )
        .unwrap();
        let e = Environment::load(&path, 1.0, 0.0, Vec3::Y)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("huge.hdr")
                && e.contains("200000 x 100000")
                && e.contains("more than the 4 GiB"),
            "{e}"
        );
    }

    /// The environment maps of the test data ([`crate::util::test_data`]). Without them the map tests fail, naming
    /// the directory (they never pass without testing).
    fn envmap_dir() -> PathBuf {
        crate::util::test_data::dir().join("envmaps")
    }
    /// Samples of the map chi-square test: ≈ 120 per cell of the 64 × 128 grid.
    const MAP_CHI2_SAMPLES: usize = 1_000_000;
    /// Equal-solid-angle chi-square grid: cos θ rows × φ columns.
    const CHI2_COS_ROWS: usize = 64;
    const CHI2_PHI_COLUMNS: usize = 128;
    /// Cells expecting fewer samples are pooled (the usual rule of thumb for Pearson's test).
    const MIN_EXPECTED: f64 = 5.0;
    /// Significance of each chi-square test.
    const ALPHA: f64 = 0.01;
    /// Quadrature of ∫ pdf dω over the sphere: θ rows × φ columns, midpoint rule (4 × 4 points per texel of a
    /// 1024 × 512 map, so the texel edges' errors average out well below the 1 % tolerance).
    const QUAD_THETA_ROWS: usize = 2048;
    const QUAD_PHI_COLUMNS: usize = 4096;
    /// Tolerance of ∫ pdf dω = 1.
    const PDF_TOLERANCE: f64 = 0.01;

    /// The smallest map in [`envmap_dir`] and its image, read once for all tests. Panics, naming the directory,
    /// when it is missing or holds no map.
    fn smallest_map() -> &'static (PathBuf, Image) {
        static MAP: OnceLock<(PathBuf, Image)> = OnceLock::new();
        MAP.get_or_init(|| {
            let dir = envmap_dir();
            let entries = std::fs::read_dir(&dir)
                .unwrap_or_else(|e| panic!("{} ({e})", crate::util::test_data::missing(&dir)));
            let smallest = entries
                .filter_map(|e| e.ok())
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|x| x == "exr" || x == "hdr"))
                .filter_map(|p| Some((std::fs::metadata(&p).ok()?.len(), p)))
                .min();
            let Some((_, path)) = smallest else {
                panic!(
                    "no .exr/.hdr in {}: the environment map tests need one",
                    dir.display()
                );
            };
            let image = crate::image::read(&path).unwrap_or_else(|e| panic!("{e}"));
            (path, image)
        })
    }

    /// A `width × height` RGB image from a function of (column, row).
    fn image(width: usize, height: usize, f: impl Fn(usize, usize) -> [f32; 3]) -> Image {
        let mut img = Image::new(width, height, ["R", "G", "B"].map(String::from).to_vec());
        for y in 0..height {
            for x in 0..width {
                img.pixel_mut(x, y).copy_from_slice(&f(x, y));
            }
        }
        img
    }

    /// 16 × 8: a distinct grey per texel, and one bright coloured texel at column 11, row 2.
    const BRIGHT: (usize, usize) = (11, 2);
    fn synthetic() -> Image {
        image(16, 8, |x, y| {
            if (x, y) == BRIGHT {
                [50.0, 40.0, 30.0]
            } else {
                [0.01 * (y * 16 + x + 1) as f32; 3]
            }
        })
    }

    /// The world direction of the centre of texel (col, row) of a `width × height` map, map frame = world.
    fn texel_direction(col: usize, row: usize, width: usize, height: usize) -> Vec3 {
        uv_to_direction([
            (col as f32 + 0.5) / width as f32,
            (row as f32 + 0.5) / height as f32,
        ])
        .0
    }

    /// ∫ pdf_li dω over the sphere, midpoint rule on a (θ, φ) grid about world +Y with dω = sin θ dθ dφ (pdf · sin θ
    /// is bounded on a lat-long map, so the poles need no special care).
    fn pdf_integral(env: &Environment) -> f64 {
        let mut sum = 0.0f64;
        for i in 0..QUAD_THETA_ROWS {
            let theta = std::f64::consts::PI * (i as f64 + 0.5) / QUAD_THETA_ROWS as f64;
            let (sin_t, cos_t) = theta.sin_cos();
            for j in 0..QUAD_PHI_COLUMNS {
                let phi = std::f64::consts::TAU * (j as f64 + 0.5) / QUAD_PHI_COLUMNS as f64;
                let w = Vec3::new(
                    (sin_t * phi.cos()) as f32,
                    cos_t as f32,
                    (sin_t * phi.sin()) as f32,
                );
                sum += env.pdf_li(w) as f64 * sin_t;
            }
        }
        sum * 2.0 * std::f64::consts::PI.powi(2) / (QUAD_THETA_ROWS * QUAD_PHI_COLUMNS) as f64
    }

    /// Samples `n` directions of `env` (built from `img` with intensity 1, no rotation); checks each against pdf_li,
    /// and le against the image texel that the sampling distribution picked for the same `u` (counting mismatches,
    /// which can only come from a uv on a texel edge); bins them on the equal-solid-angle grid. Returns
    /// (histogram, mismatches).
    fn sample_histogram(env: &Environment, img: &Image, n: usize, seed: u64) -> (Vec<f64>, usize) {
        let Source::Map(map) = &env.source else {
            panic!("not a map")
        };
        let (r, g, b) = (
            img.channel_index("R").unwrap(),
            img.channel_index("G").unwrap(),
            img.channel_index("B").unwrap(),
        );
        let mut rng = Pcg32::new(seed, 31);
        let mut hist = vec![0.0; CHI2_COS_ROWS * CHI2_PHI_COLUMNS];
        let mut mismatches = 0;
        for _ in 0..n {
            let u = rng.random();
            let s = env.sample_li(u).expect("a map with light");
            assert!((s.wi.length() - 1.0).abs() < 1e-5 && s.distance == f32::INFINITY && !s.delta);
            assert_eq!(s.pdf, env.pdf_li(s.wi), "sample pdf vs pdf_li at {}", s.wi);
            assert_eq!(
                s.radiance,
                env.le(s.wi),
                "sample radiance vs le at {}",
                s.wi
            );
            let (uv, _) = map.distribution.sample(u);
            let (col, row) = (
                (uv[0] * img.width as f32) as usize,
                (uv[1] * img.height as f32) as usize,
            );
            let px = img.pixel(col, row);
            if env.le(s.wi) != Vec3::new(px[r], px[g], px[b]).max(Vec3::ZERO) {
                mismatches += 1;
            }
            let i = (((1.0 - s.wi.y) * 0.5 * CHI2_COS_ROWS as f32) as usize).min(CHI2_COS_ROWS - 1);
            let j = ((direction_to_uv(s.wi)[0] * CHI2_PHI_COLUMNS as f32) as usize)
                .min(CHI2_PHI_COLUMNS - 1);
            hist[i * CHI2_PHI_COLUMNS + j] += 1.0;
        }
        (hist, mismatches)
    }

    /// Expected counts of [`sample_histogram`]'s cells for `n` samples, exact for a piecewise-constant pdf: each
    /// cell is cut along the texel edges, and each piece contributes pdf_li(centre) · 2π² sin θ_centre · Δu Δv
    /// (= p_uv Δu Δv, as pdf_li · sin θ is constant on a texel).
    fn expected_histogram(env: &Environment, n: usize) -> Vec<f64> {
        let (width, height) = env.size().unwrap();
        let mut expected = vec![0.0; CHI2_COS_ROWS * CHI2_PHI_COLUMNS];
        for i in 0..CHI2_COS_ROWS {
            let v0 = (1.0 - 2.0 * i as f64 / CHI2_COS_ROWS as f64).acos() / std::f64::consts::PI;
            let v1 = (1.0 - 2.0 * (i + 1) as f64 / CHI2_COS_ROWS as f64)
                .max(-1.0)
                .acos()
                / std::f64::consts::PI;
            for j in 0..CHI2_PHI_COLUMNS {
                let (u0, u1) = (
                    j as f64 / CHI2_PHI_COLUMNS as f64,
                    (j + 1) as f64 / CHI2_PHI_COLUMNS as f64,
                );
                let mut sum = 0.0;
                for row in (v0 * height as f64) as usize
                    ..((v1 * height as f64).ceil() as usize).min(height)
                {
                    let a0 = v0.max(row as f64 / height as f64);
                    let a1 = v1.min((row + 1) as f64 / height as f64);
                    if a1 <= a0 {
                        continue;
                    }
                    for col in (u0 * width as f64) as usize
                        ..((u1 * width as f64).ceil() as usize).min(width)
                    {
                        let b0 = u0.max(col as f64 / width as f64);
                        let b1 = u1.min((col + 1) as f64 / width as f64);
                        if b1 <= a0.min(b0) - 1.0 || b1 <= b0 {
                            continue;
                        }
                        let (uc, vc) = (0.5 * (b0 + b1), 0.5 * (a0 + a1));
                        let (d, sin_t) = uv_to_direction([uc as f32, vc as f32]);
                        let p_uv = env.pdf_li(d) as f64
                            * 2.0
                            * std::f64::consts::PI.powi(2)
                            * sin_t as f64;
                        sum += p_uv * (b1 - b0) * (a1 - a0);
                    }
                }
                expected[i * CHI2_PHI_COLUMNS + j] = sum * n as f64;
            }
        }
        expected
    }

    #[test]
    fn uv_convention() {
        let close = |a: Vec3, b: Vec3| (a - b).length() < 1e-6;
        assert!(
            close(uv_to_direction([0.5, 0.0]).0, Vec3::Y),
            "top row looks up"
        );
        assert!(
            close(uv_to_direction([0.3, 1.0]).0, -Vec3::Y),
            "bottom row looks down"
        );
        assert!(
            close(uv_to_direction([0.5, 0.5]).0, -Vec3::Z),
            "centre column looks towards -z"
        );
        assert!(
            close(uv_to_direction([0.75, 0.5]).0, Vec3::X),
            "u = 3/4 looks towards +x"
        );
        assert!(
            close(uv_to_direction([0.0, 0.5]).0, Vec3::Z),
            "the edges look towards +z"
        );
        let mut rng = Pcg32::new(2, 2);
        for _ in 0..1000 {
            let uv = rng.random();
            let back = direction_to_uv(uv_to_direction(uv).0);
            assert!(
                (back[0] - uv[0]).abs() < 1e-5 && (back[1] - uv[1]).abs() < 1e-5,
                "{uv:?} → {back:?}"
            );
        }
    }

    #[test]
    fn radiance_and_density_from_one_lookup_are_le_and_pdf_li() {
        // Rotated and tilted, so that the map frame is not the world's; unnormalised directions, the poles, zero.
        let env =
            Environment::from_image(&synthetic(), 1.5, 37.0, Vec3::new(0.3, 1.0, -0.2)).unwrap();
        let mut rng = Pcg32::new(9, 3);
        let mut dirs: Vec<Vec3> = (0..5000)
            .map(|_| uniform_sphere(rng.random(), rng.random()) * rng.random_range(0.1..10.0))
            .collect();
        dirs.extend([Vec3::ZERO, Vec3::Y, -Vec3::Y, Vec3::new(0.3, 1.0, -0.2)]);
        for d in dirs {
            let (le, pdf) = env.le_and_pdf(d);
            assert_eq!(
                (le, pdf.to_bits()),
                (env.le(d), env.pdf_li(d).to_bits()),
                "{d}"
            );
        }
    }

    #[test]
    fn synthetic_map_lookup_sampling_and_pdf() {
        let img = synthetic();
        let env = Environment::from_image(&img, 2.0, 0.0, Vec3::Y).unwrap();
        assert_eq!(env.size(), Some((16, 8)));
        // Nearest lookup: every texel centre returns that texel, times the intensity.
        for row in 0..8 {
            for col in 0..16 {
                let expected = Vec3::from_slice(img.pixel(col, row)) * 2.0;
                assert_eq!(
                    env.le(texel_direction(col, row, 16, 8)),
                    expected,
                    "texel ({col}, {row})"
                );
            }
        }
        // ∫ pdf dω = 1, and the bright texel's share of the samples is its weight's share.
        let integral = pdf_integral(&env);
        assert!((integral - 1.0).abs() < PDF_TOLERANCE, "∫ pdf = {integral}");
        let weight = |col: usize, row: usize| {
            luminance(Vec3::from_slice(img.pixel(col, row))) as f64
                * (std::f64::consts::PI * (row as f64 + 0.5) / 8.0).sin()
        };
        let total: f64 = (0..8)
            .flat_map(|r| (0..16).map(move |c| (c, r)))
            .map(|(c, r)| weight(c, r))
            .sum();
        let n = 200_000;
        let mut rng = Pcg32::new(4, 4);
        let mut observed = vec![0.0; 16 * 8];
        for _ in 0..n {
            let s = env.sample_li(rng.random()).unwrap();
            assert_eq!(
                env.le(s.wi),
                s.radiance,
                "le at a sampled direction is its texel"
            );
            assert!((s.pdf - env.pdf_li(s.wi)).abs() <= 1e-3 * s.pdf);
            let [u, v] = direction_to_uv(s.wi);
            observed[((v * 8.0) as usize).min(7) * 16 + ((u * 16.0) as usize).min(15)] += 1.0;
        }
        let expected: Vec<f64> = (0..8 * 16)
            .map(|k| weight(k % 16, k / 16) / total * n as f64)
            .collect();
        let bright = BRIGHT.1 * 16 + BRIGHT.0;
        assert!(
            expected[bright] > 0.3 * n as f64,
            "the bright texel should dominate"
        );
        let r = chi_square(&observed, &expected, MIN_EXPECTED);
        assert!(r.p_value > ALPHA && r.outside_support == 0.0, "{r:?}");
        // Average radiance: Σ L Ω / 4π with exact texel solid angles.
        let avg: f64 = (0..8 * 16)
            .map(|k| {
                let (c, r) = (k % 16, k / 16);
                let pi = std::f64::consts::PI;
                let omega = 2.0 * pi / 16.0
                    * ((pi * r as f64 / 8.0).cos() - (pi * (r + 1) as f64 / 8.0).cos());
                2.0 * img.pixel(c, r)[0] as f64 * omega / (4.0 * pi)
            })
            .sum();
        assert!((env.average_radiance().x as f64 / avg - 1.0).abs() < 1e-5);
        assert!(env.power(1.0) > 0.0);
    }

    #[test]
    fn synthetic_rotation_and_up() {
        let img = synthetic();
        let bright = Vec3::from_slice(img.pixel(BRIGHT.0, BRIGHT.1));
        let d0 = texel_direction(BRIGHT.0, BRIGHT.1, 16, 8);
        let base = Environment::from_image(&img, 1.0, 0.0, Vec3::Y).unwrap();
        assert_eq!(base.le(d0), bright);
        // +90°: counter-clockwise seen from above, i.e. right-handed about +Y (+x goes to −z).
        let turned = Environment::from_image(&img, 1.0, 90.0, Vec3::Y).unwrap();
        let r90 = Quat::from_rotation_y(90f32.to_radians());
        assert!((r90 * Vec3::X + Vec3::Z).length() < 1e-6);
        assert_eq!(turned.le(r90 * d0), bright);
        assert_ne!(turned.le(d0), bright);
        // up = +Z: the map turned by the shortest arc from +Y to +Z (a quarter turn about +X), so the top row
        // looks along +Z.
        let z_up = Environment::from_image(&img, 1.0, 0.0, Vec3::Z).unwrap();
        let rz = Quat::from_rotation_x(90f32.to_radians());
        for k in 0..16 * 8 {
            let d = texel_direction(k % 16, k / 16, 16, 8);
            assert_eq!(z_up.le(rz * d), base.le(d), "texel {k}");
            if k < 16 {
                assert!((rz * d).z > 0.98, "top row at {}", rz * d);
            }
        }
        // Sampling follows the rotation: the pdf peaks at the turned bright texel.
        assert!((turned.pdf_li(r90 * d0) - base.pdf_li(d0)).abs() < 1e-3 * base.pdf_li(d0));
    }

    #[test]
    fn clamps_bad_texels_reads_grey_and_rejects_bad_input() {
        let mut img = synthetic();
        img.pixel_mut(3, 3)[1] = -1e-4;
        img.pixel_mut(4, 4)[0] = -2.0;
        let env = Environment::from_image(&img, 1.0, 0.0, Vec3::Y).unwrap();
        assert_eq!(env.clamped_texels(), 2);
        assert_eq!(env.le(texel_direction(3, 3, 16, 8)).y, 0.0);
        assert_eq!(env.le(texel_direction(4, 4, 16, 8)).x, 0.0);
        assert!(env.average_radiance().is_finite());
        // NaN or infinite texels: the map is damaged, refused with the count and the first one's place.
        img.pixel_mut(5, 5)[2] = f32::INFINITY;
        img.pixel_mut(6, 6)[0] = f32::NAN;
        let e = Environment::from_image(&img, 1.0, 0.0, Vec3::Y)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("2 texels are NaN or infinite (the first at column 5, row 5)"),
            "{e}"
        );

        let mut grey = Image::new(4, 2, vec!["Y".to_owned()]);
        grey.data.fill(0.5);
        let env = Environment::from_image(&grey, 1.0, 0.0, Vec3::Y).unwrap();
        assert_eq!(env.le(Vec3::X), Vec3::splat(0.5));

        let two = Image::new(4, 2, vec!["A".to_owned(), "Z".to_owned()]);
        let e = Environment::from_image(&two, 1.0, 0.0, Vec3::Y)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("<in-memory image>") && e.contains("R, G, B"),
            "{e}"
        );
        let e = Environment::from_image(&synthetic(), -1.0, 0.0, Vec3::Y)
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "environment light: intensity must be >= 0 and finite, got -1"
        );
        assert!(Environment::from_image(&synthetic(), 1.0, f32::NAN, Vec3::Y).is_err());
        assert!(Environment::from_image(&synthetic(), 1.0, 0.0, Vec3::ZERO).is_err());
        assert!(Environment::constant(Vec3::new(1.0, -1.0, 0.0)).is_err());
        // A black map has nothing to sample.
        let black =
            Environment::from_image(&image(4, 2, |_, _| [0.0; 3]), 1.0, 0.0, Vec3::Y).unwrap();
        assert!(black.sample_li([0.5, 0.5]).is_none());
        assert_eq!(black.pdf_li(Vec3::X), 0.0);
        // Degenerate directions and sample inputs stay finite.
        let env =
            Environment::from_image(&synthetic(), 1.0, 30.0, Vec3::new(0.0, -1.0, 0.0)).unwrap();
        for d in [
            Vec3::ZERO,
            Vec3::NAN,
            Vec3::Y,
            -Vec3::Y,
            Vec3::splat(1e30),
            Vec3::splat(1e-30),
        ] {
            assert!(env.le(d).is_finite() && env.pdf_li(d).is_finite(), "{d}");
        }
        for u in [[0.0, 0.0], [1.0, 1.0], [f32::NAN, 0.5], [0.5, -3.0]] {
            if let Some(s) = env.sample_li(u) {
                assert!(
                    s.wi.is_finite() && s.pdf.is_finite() && s.pdf > 0.0,
                    "{u:?}: {s:?}"
                );
            }
        }
    }

    #[test]
    fn constant_environment_cosine_integral_is_pi_l() {
        let l = Vec3::new(0.5, 1.0, 2.0);
        let env = Light::Environment(Environment::constant(l).unwrap());
        assert!(env.is_infinite() && !env.is_delta());
        let n = Vec3::new(0.3, 0.9, 0.2).normalize();
        let samples = 200_000;
        let mut rng = Pcg32::new(8, 8);
        let (mut sum, mut sum2) = (0.0f64, 0.0f64);
        for _ in 0..samples {
            let s = env.sample_li(Vec3::ZERO, rng.random()).unwrap();
            assert_eq!(s.pdf, env.pdf_li(Vec3::ZERO, s.wi));
            assert_eq!(s.radiance, env.le(s.wi));
            let x = (s.radiance.y * n.dot(s.wi).max(0.0) / s.pdf) as f64;
            sum += x;
            sum2 += x * x;
        }
        let mean = sum / samples as f64;
        let se = ((sum2 / samples as f64 - mean * mean) / samples as f64).sqrt();
        let reference = std::f64::consts::PI * l.y as f64;
        assert!((mean - reference).abs() < 3.0 * se && (mean / reference - 1.0).abs() < 0.01);
        assert!((env.power(2.0) - 4.0 * PI * PI * 4.0 * luminance(l)).abs() < 1e-3);
    }

    #[test]
    fn map_pdf_integrates_to_one() {
        let (path, img) = smallest_map();
        let env = Environment::from_image(img, 1.0, 0.0, Vec3::Y).unwrap();
        let integral = pdf_integral(&env);
        assert!(
            (integral - 1.0).abs() < PDF_TOLERANCE,
            "{}: ∫ pdf = {integral}",
            path.display()
        );
    }

    #[test]
    fn map_chi_square_and_le_at_samples() {
        let (path, img) = smallest_map();
        let env = Environment::from_image(img, 1.0, 0.0, Vec3::Y).unwrap();
        let (observed, mismatches) = sample_histogram(&env, img, MAP_CHI2_SAMPLES, 1);
        let expected = expected_histogram(&env, MAP_CHI2_SAMPLES);
        let total: f64 = expected.iter().sum();
        let r = chi_square(&observed, &expected, MIN_EXPECTED);
        assert!(
            (total / MAP_CHI2_SAMPLES as f64 - 1.0).abs() < 1e-3,
            "expected counts sum to {total}"
        );
        assert!(
            r.p_value > ALPHA && r.outside_support == 0.0,
            "{}: {r:?}",
            path.display()
        );
        assert!(
            mismatches <= MAP_CHI2_SAMPLES / 10_000,
            "{mismatches} samples see another texel through le"
        );
    }

    #[test]
    fn map_rotation_moves_the_brightest_direction() {
        let (path, img) = smallest_map();
        let (w, h) = (img.width, img.height);
        let base = Environment::from_image(img, 1.0, 0.0, Vec3::Y).unwrap();
        let turned = Environment::from_image(img, 1.0, 90.0, Vec3::Y).unwrap();
        // The brightest texel-centre direction of each (scanning world directions on the map's own grid).
        let brightest = |env: &Environment| {
            (0..w * h)
                .map(|k| texel_direction(k % w, k / w, w, h))
                .max_by(|a, b| luminance(env.le(*a)).total_cmp(&luminance(env.le(*b))))
                .unwrap()
        };
        let (d0, d90) = (brightest(&base), brightest(&turned));
        let expected = Quat::from_rotation_y(90f32.to_radians()) * d0;
        let angle = crate::light::cone::tests::angle_between(d90, expected);
        // One texel of slack (the rotated grid does not land on texel centres).
        assert!(
            angle < 2.0 * std::f64::consts::PI / w as f64,
            "{}: brightest {d0} → {d90} after +90°, expected {expected}",
            path.display()
        );
        assert_eq!(luminance(turned.le(expected)), luminance(base.le(d0)));
    }

    #[test]
    fn missing_file_names_the_path() {
        let path = envmap_dir().join("no-such-map.exr");
        let e = Environment::load(&path, 1.0, 0.0, Vec3::Y).unwrap_err();
        assert!(matches!(e, LightError::EnvironmentFile { .. }));
        assert!(e.to_string().contains(&path.display().to_string()), "{e}");
        let (path, _) = smallest_map();
        let env = Environment::load(path, 1.0, 0.0, Vec3::Y).unwrap();
        assert!(env.average_radiance().min_element() > 0.0);
    }
}
