//! Procedural hair models, so the default scene renders with no downloaded data.
//!
//! Two generators, chosen in a scene by `kind`:
//!
//! ```toml
//! [hair]
//! procedural = { kind = "fur-ball", strands = 12000, seed = 7 }
//! # or
//! procedural = { kind = "wavy-patch", clumps = 40, wave_amplitude = 0.06 }
//! ```
//!
//! Every key is optional (the defaults below render as hair) and unknown keys are errors. Lengths are in model
//! units; the defaults make models about 3 units across, with a fibre radius of about 1/750 of that, so strands
//! read as hair rather than as spaghetti (real hair: radius 0.02–0.06 mm on a 0.2 m head, about 1/5000; we thicken
//! it because a few thousand strands stand for a full head of ~100k).
//!
//! * [`FurBall`]: strands rooted on a sphere (an even Fibonacci lattice, jittered), growing along the normal, bent
//!   down by a gravity term that grows along the strand, with a helical curl and a linear taper.
//! * [`WavyPatch`]: strands rooted on a horizontal square (a scalp patch), hanging down (−y) with sinusoidal waves.
//!   Strands belong to the nearest of `clumps` clump centres, share that clump's wave phase and direction, and are
//!   pulled towards the clump centre near the tips, the way real hair forms locks.
//!
//! Generation is deterministic: the same parameters and `seed` give bit-identical points on one machine. Random
//! numbers come from [`SplitMix64`] (Steele, Lea & Flood 2014) keyed by (seed, stream, index), so strand `i` does not
//! depend on how many strands come before it; strands are generated in parallel (rayon), each into its own slice
//! of the point arrays, so the thread count changes nothing either (tested).
//!
//! Radii are explicit per point (the taper is part of the design), so models come out with `radius_from_file`
//! set: [`Strands::from_model`](super::Strands::from_model) uses them as they are.

use std::f32::consts::{PI, TAU};
use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use serde::Deserialize;

use super::{HairError, HairModel};
use crate::util::hash::SplitMix64;

/// A procedural hair model, as written in a scene's `[hair] procedural = { kind = ..., ... }`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Procedural {
    /// Fur on a sphere (`kind = "fur-ball"`).
    FurBall(FurBall),
    /// A square patch of wavy, clumped hair (`kind = "wavy-patch"`).
    WavyPatch(WavyPatch),
}

impl Default for Procedural {
    fn default() -> Self {
        Procedural::FurBall(FurBall::default())
    }
}

impl Procedural {
    /// The `kind` name, as written in scenes ("fur-ball", "wavy-patch").
    pub fn kind(&self) -> &'static str {
        match self {
            Procedural::FurBall(_) => "fur-ball",
            Procedural::WavyPatch(_) => "wavy-patch",
        }
    }

    /// The pseudo-path naming this model in errors: `procedural:<kind>`.
    pub fn source(&self) -> PathBuf {
        PathBuf::from(format!("procedural:{}", self.kind()))
    }

    /// Strands and points in all (strands × points per strand), known before generating: what
    /// [`crate::render::budget`] estimates a frame's memory from.
    pub fn counts(&self) -> (u64, u64) {
        let (strands, points) = match self {
            Procedural::FurBall(f) => (f.strands, f.points),
            Procedural::WavyPatch(w) => (w.strands, w.points),
        };
        (u64::from(strands), u64::from(strands) * u64::from(points))
    }

    /// Checks the parameters and generates the model. Errors name the offending key.
    pub fn generate(&self) -> Result<HairModel, HairError> {
        let path = self.source();
        let model = match self {
            Procedural::FurBall(f) => f.generate(&path)?,
            Procedural::WavyPatch(w) => w.generate(&path)?,
        };
        model.validate(&path)?;
        Ok(model)
    }
}

/// Fur on a sphere centred at the origin.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FurBall {
    /// Seed of every random choice (root jitter, length, curl phase).
    pub seed: u64,
    /// Number of strands, ≥ 1. Default 16,000.
    pub strands: u32,
    /// Points per strand, ≥ 2. Default 16.
    pub points: u32,
    /// Radius of the sphere the strands grow from, model units, > 0. Default 1. (The sphere is not rendered.)
    pub sphere_radius: f32,
    /// Mean strand length, model units, > 0. Default 0.5.
    pub length: f32,
    /// Relative spread of strand lengths in [0, 1): each length is `length · (1 ± length_variation)`. Default 0.25.
    pub length_variation: f32,
    /// Fibre radius at the root, model units, > 0. Default 0.004 (1/750 of the model's 3-unit diameter).
    pub fiber_radius: f32,
    /// Tip radius as a fraction of the root radius, in (0, 1]. Default 0.3.
    pub taper: f32,
    /// Droop, ≥ 0: the growth direction at fraction t of the strand is normalise(normal + gravity · t · (−y)).
    /// Default 0.6.
    pub gravity: f32,
    /// Radius of the helical curl as a fraction of the strand length, ≥ 0 (0 = straight). Default 0.04.
    pub curl: f32,
    /// Transparency of every point, in [0, 1]. Default 0.
    pub transparency: f32,
    /// Linear RGB colour, each channel in [0, 1]. Default a light brown.
    #[serde(deserialize_with = "crate::util::exact_array::array")]
    pub color: [f32; 3],
}

impl Default for FurBall {
    fn default() -> Self {
        FurBall {
            seed: 0,
            strands: 16_000,
            points: 16,
            sphere_radius: 1.0,
            length: 0.5,
            length_variation: 0.25,
            fiber_radius: 0.004,
            taper: 0.3,
            gravity: 0.6,
            curl: 0.04,
            transparency: 0.0,
            color: DEFAULT_COLOR,
        }
    }
}

/// A square patch of wavy hair with clumps, hanging down (−y) from the square y = 0, |x|, |z| ≤ size/2.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WavyPatch {
    /// Seed of every random choice (roots, clump centres, phases, lengths).
    pub seed: u64,
    /// Number of strands, ≥ 1. Default 8,000.
    pub strands: u32,
    /// Points per strand, ≥ 2. Default 48 (about 10 per wave at the default wavelength).
    pub points: u32,
    /// Side of the square the roots lie on, model units, > 0. Default 1.
    pub size: f32,
    /// Mean strand length, model units, > 0. Default 2.
    pub length: f32,
    /// Relative spread of strand lengths in [0, 1). Default 0.15.
    pub length_variation: f32,
    /// Amplitude of the waves, model units, ≥ 0 (0 = straight). Default 0.05.
    pub wave_amplitude: f32,
    /// Wavelength along the strand, model units, > 0. Default 0.4.
    pub wavelength: f32,
    /// Number of clumps (0 = no clumping: every strand waves with its own phase). Default 60.
    pub clumps: u32,
    /// How far tips are pulled to their clump centre, in [0, 1] (1 = tips meet at the centre). Default 0.7.
    pub clump_strength: f32,
    /// Fibre radius at the root, model units, > 0. Default 0.003 (1/700 of the model's ~2-unit extent).
    pub fiber_radius: f32,
    /// Tip radius as a fraction of the root radius, in (0, 1]. Default 0.5.
    pub taper: f32,
    /// Transparency of every point, in [0, 1]. Default 0.
    pub transparency: f32,
    /// Linear RGB colour, each channel in [0, 1]. Default a light brown.
    #[serde(deserialize_with = "crate::util::exact_array::array")]
    pub color: [f32; 3],
}

impl Default for WavyPatch {
    fn default() -> Self {
        WavyPatch {
            seed: 0,
            strands: 8_000,
            points: 48,
            size: 1.0,
            length: 2.0,
            length_variation: 0.15,
            wave_amplitude: 0.05,
            wavelength: 0.4,
            clumps: 60,
            clump_strength: 0.7,
            fiber_radius: 0.003,
            taper: 0.5,
            transparency: 0.0,
            color: DEFAULT_COLOR,
        }
    }
}

/// Default colour of generated hair: a light brown (linear RGB), the same as the default scene's material.
const DEFAULT_COLOR: [f32; 3] = [0.55, 0.32, 0.16];

/// Turns of the fur ball's helical curl over a full strand: enough to read as curl with 16 points per strand
/// (about 10 points per turn), few enough that the polyline stays smooth.
const CURL_TURNS: f32 = 1.5;

/// Fraction of the lattice spacing by which fur-ball roots are jittered: breaks the visible Fibonacci spirals
/// while keeping the coverage even.
const ROOT_JITTER: f32 = 0.8;

/// Random phase spread (radians) of strands within one clump, so a clump does not move as a rigid sheet.
const CLUMP_PHASE_JITTER: f32 = 0.4;

/// Random-number streams: strand `i` of the fur ball and of the patch, and clump `j`, use disjoint keys.
const STREAM_STRAND: u64 = 0;
const STREAM_CLUMP: u64 = 1 << 40;

impl FurBall {
    fn check(&self, path: &Path) -> Result<(), HairError> {
        check_counts(path, self.strands, self.points)?;
        positive(path, "sphere_radius", self.sphere_radius)?;
        positive(path, "length", self.length)?;
        half_open_unit(path, "length_variation", self.length_variation)?;
        positive(path, "fiber_radius", self.fiber_radius)?;
        taper(path, self.taper)?;
        non_negative(path, "gravity", self.gravity)?;
        non_negative(path, "curl", self.curl)?;
        unit(path, "transparency", self.transparency)?;
        color(path, self.color)
    }

    fn generate(&self, path: &Path) -> Result<HairModel, HairError> {
        self.check(path)?;
        let (n, m) = (self.strands as usize, self.points as usize);
        let mut model = empty_model(n, m, "procedural fur ball");
        // Golden angle: successive lattice points turn by it, which spreads them evenly (Fibonacci sphere).
        let golden = PI * (3.0 - 5f32.sqrt());
        let down = Vec3::NEG_Y;
        let strand = |i: usize, points: &mut [Vec3], radius: &mut [f32]| {
            let mut rng = SplitMix64::new(self.seed, STREAM_STRAND + i as u64);
            // Fibonacci lattice: uniform in y (= uniform in area), jittered by a fraction of the spacing.
            let y = (1.0
                - 2.0 * (i as f32 + 0.5 + ROOT_JITTER * (rng.next_f32() - 0.5)) / n as f32)
                .clamp(-1.0, 1.0);
            let phi = i as f32 * golden + ROOT_JITTER * (rng.next_f32() - 0.5) * golden;
            let r = (1.0 - y * y).max(0.0).sqrt();
            let normal = Vec3::new(r * phi.cos(), y, r * phi.sin());
            let (u, v) = normal.any_orthonormal_pair();
            let len = self.length * (1.0 + self.length_variation * (2.0 * rng.next_f32() - 1.0));
            let step = len / (m - 1) as f32;
            let curl_radius = self.curl * len;
            let curl_phase = TAU * rng.next_f32();

            let mut stem = normal * self.sphere_radius;
            for k in 0..m {
                let t = k as f32 / (m - 1) as f32;
                if k > 0 {
                    // Direction at the middle of the step just taken: the normal bent down more towards the tip.
                    let t_mid = (k as f32 - 0.5) / (m - 1) as f32;
                    let dir = (normal + self.gravity * t_mid * down).normalize_or(normal);
                    stem += dir * step;
                }
                // Helix around the stem, in the root's tangent plane, growing from zero at the root.
                let angle = curl_phase + TAU * CURL_TURNS * t;
                let offset = curl_radius * t * (angle.cos() * u + angle.sin() * v);
                points[k] = stem + offset;
                radius[k] = tapered(self.fiber_radius, self.taper, t);
            }
        };
        fill_strands(&mut model, n, m, strand);
        finish(&mut model, self.transparency, self.color);
        Ok(model)
    }
}

impl WavyPatch {
    fn check(&self, path: &Path) -> Result<(), HairError> {
        check_counts(path, self.strands, self.points)?;
        positive(path, "size", self.size)?;
        positive(path, "length", self.length)?;
        half_open_unit(path, "length_variation", self.length_variation)?;
        non_negative(path, "wave_amplitude", self.wave_amplitude)?;
        positive(path, "wavelength", self.wavelength)?;
        unit(path, "clump_strength", self.clump_strength)?;
        positive(path, "fiber_radius", self.fiber_radius)?;
        taper(path, self.taper)?;
        unit(path, "transparency", self.transparency)?;
        color(path, self.color)
    }

    fn generate(&self, path: &Path) -> Result<HairModel, HairError> {
        self.check(path)?;
        let (n, m) = (self.strands as usize, self.points as usize);
        let half = 0.5 * self.size;
        let in_square = |rng: &mut SplitMix64| {
            Vec2::new(
                (2.0 * rng.next_f32() - 1.0) * half,
                (2.0 * rng.next_f32() - 1.0) * half,
            )
        };
        // A clump: its centre on the square, its wave phase and its wave direction in the xz-plane.
        struct Clump {
            centre: Vec2,
            phase: f32,
            direction: Vec3,
        }
        let random_clump = |rng: &mut SplitMix64| {
            let centre = in_square(rng);
            let phase = TAU * rng.next_f32();
            let angle = TAU * rng.next_f32();
            Clump {
                centre,
                phase,
                direction: Vec3::new(angle.cos(), 0.0, angle.sin()),
            }
        };
        let clumps: Vec<Clump> = (0..self.clumps)
            .map(|j| random_clump(&mut SplitMix64::new(self.seed, STREAM_CLUMP + u64::from(j))))
            .collect();

        let mut model = empty_model(n, m, "procedural wavy patch");
        let two_pi_over_wavelength = TAU / self.wavelength;
        let strand = |i: usize, points: &mut [Vec3], radius: &mut [f32]| {
            let mut rng = SplitMix64::new(self.seed, STREAM_STRAND + i as u64);
            let root = in_square(&mut rng);
            let len = self.length * (1.0 + self.length_variation * (2.0 * rng.next_f32() - 1.0));
            // The nearest clump centre (a Voronoi partition of the square); without clumps, a clump of one.
            let (target, phase, direction, strength) = match clumps.iter().min_by(|a, b| {
                a.centre
                    .distance_squared(root)
                    .total_cmp(&b.centre.distance_squared(root))
            }) {
                Some(c) => (
                    c.centre,
                    c.phase + CLUMP_PHASE_JITTER * (rng.next_f32() - 0.5),
                    c.direction,
                    self.clump_strength,
                ),
                None => {
                    let own = random_clump(&mut rng);
                    (root, own.phase, own.direction, 0.0)
                }
            };
            for k in 0..m {
                let t = k as f32 / (m - 1) as f32;
                let s = t * len;
                // Pulled to the clump centre quadratically, so roots stay spread and tips gather.
                let xz = root.lerp(target, strength * t * t);
                // Waves fade in over the first wavelength, so the hair leaves the scalp straight.
                let ramp = smoothstep(s / self.wavelength);
                let wave = self.wave_amplitude * ramp * (two_pi_over_wavelength * s + phase).sin();
                points[k] = Vec3::new(xz.x, -s, xz.y) + wave * direction;
                radius[k] = tapered(self.fiber_radius, self.taper, t);
            }
        };
        fill_strands(&mut model, n, m, strand);
        finish(&mut model, self.transparency, self.color);
        Ok(model)
    }
}

/// Radius at fraction `t` of a strand: linear from `root` to `root · taper`.
fn tapered(root: f32, taper: f32, t: f32) -> f32 {
    root * (1.0 - (1.0 - taper) * t)
}

/// Cubic smoothstep on [0, 1], clamped outside.
fn smoothstep(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// A model with room for `n` strands of `m` points and the first strand offset.
fn empty_model(n: usize, m: usize, format: &str) -> HairModel {
    let mut strand_offsets = Vec::with_capacity(n + 1);
    strand_offsets.push(0);
    HairModel {
        points: Vec::with_capacity(n * m),
        strand_offsets,
        radius: Vec::with_capacity(n * m),
        radius_from_file: true,
        transparency: Vec::new(),
        color: Vec::new(),
        format: format.to_owned(),
        info: String::new(),
    }
}

/// Generates `n` strands of `m` points in parallel: `strand(i, points, radius)` writes strand `i` into its own
/// `m`-long slices, so the result does not depend on the thread count or order. Sets the strand offsets.
fn fill_strands(
    model: &mut HairModel,
    n: usize,
    m: usize,
    strand: impl Fn(usize, &mut [Vec3], &mut [f32]) + Sync,
) {
    model.points.resize(n * m, Vec3::ZERO);
    model.radius.resize(n * m, 0.0);
    model
        .points
        .par_chunks_mut(m)
        .zip(model.radius.par_chunks_mut(m))
        .enumerate()
        .for_each(|(i, (points, radius))| strand(i, points, radius));
    // `check_counts` keeps n · m within u32.
    model.strand_offsets.extend((1..=n).map(|i| (i * m) as u32));
}

/// Fills the uniform per-point arrays.
fn finish(model: &mut HairModel, transparency: f32, color: [f32; 3]) {
    model.transparency = vec![transparency; model.points.len()];
    model.color = vec![color; model.points.len()];
}

fn check_counts(path: &Path, strands: u32, points: u32) -> Result<(), HairError> {
    if strands < 1 {
        return Err(HairError::invalid(path, "strands must be >= 1, got 0"));
    }
    if points < 2 {
        return Err(HairError::invalid(
            path,
            format!("points must be >= 2 (points per strand), got {points}"),
        ));
    }
    // Offsets are u32 (Embree's index format).
    let total = u64::from(strands) * u64::from(points);
    if total > u64::from(u32::MAX) {
        return Err(HairError::invalid(
            path,
            format!(
                "strands × points = {strands} × {points} = {total} points, more than the {} a model can hold",
                u32::MAX
            ),
        ));
    }
    Ok(())
}

/// Every positive parameter is a length in model units. A model is a few such lengths across (sphere + length ×
/// (1 + curl), patch size + length), so bounding each by [`crate::ray::MAX_SCENE_COORD`] / 16 keeps the generated points
/// inside what rays can be traced from (checked again on the points by [`HairModel::validate`]).
fn positive(path: &Path, key: &str, v: f32) -> Result<(), HairError> {
    let max = crate::ray::MAX_SCENE_COORD / 16.0;
    if !(v.is_finite() && v > 0.0) {
        Err(HairError::invalid(
            path,
            format!("{key} must be > 0, got {v}"),
        ))
    } else if v > max {
        Err(HairError::invalid(
            path,
            format!("{key} must be at most {max:e} model units, got {v:e}"),
        ))
    } else {
        Ok(())
    }
}

fn non_negative(path: &Path, key: &str, v: f32) -> Result<(), HairError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(HairError::invalid(
            path,
            format!("{key} must be >= 0, got {v}"),
        ))
    }
}

fn unit(path: &Path, key: &str, v: f32) -> Result<(), HairError> {
    if (0.0..=1.0).contains(&v) {
        Ok(())
    } else {
        Err(HairError::invalid(
            path,
            format!("{key} must be in [0, 1], got {v}"),
        ))
    }
}

fn half_open_unit(path: &Path, key: &str, v: f32) -> Result<(), HairError> {
    if (0.0..1.0).contains(&v) {
        Ok(())
    } else {
        Err(HairError::invalid(
            path,
            format!("{key} must be in [0, 1), got {v}"),
        ))
    }
}

fn taper(path: &Path, v: f32) -> Result<(), HairError> {
    if v > 0.0 && v <= 1.0 {
        Ok(())
    } else {
        Err(HairError::invalid(
            path,
            format!("taper (tip radius / root radius) must be in (0, 1], got {v}"),
        ))
    }
}

fn color(path: &Path, c: [f32; 3]) -> Result<(), HairError> {
    if c.iter().all(|x| (0.0..=1.0).contains(x)) {
        Ok(())
    } else {
        Err(HairError::invalid(
            path,
            format!("color must be in [0, 1] per channel, got {c:?}"),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Parallel generation gives the same bits whatever the thread count (strand i depends only on i).
    #[test]
    fn generation_does_not_depend_on_the_thread_count() {
        let models = [
            Procedural::FurBall(FurBall {
                strands: 3000,
                ..FurBall::default()
            }),
            Procedural::WavyPatch(WavyPatch {
                strands: 1000,
                ..WavyPatch::default()
            }),
        ];
        for model in models {
            let with = |threads| {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                pool.install(|| model.generate().unwrap())
            };
            let (one, four) = (with(1), with(4));
            let bits = |m: &HairModel| -> Vec<u32> {
                m.points
                    .iter()
                    .flat_map(|p| p.to_array())
                    .chain(m.radius.iter().copied())
                    .map(f32::to_bits)
                    .collect()
            };
            assert_eq!(bits(&one), bits(&four), "{}", model.kind());
            assert_eq!(one.strand_offsets, four.strand_offsets);
            let m = one.points.len() / one.strand_count();
            assert_eq!(one.strand_offsets[1] as usize, m);
        }
    }

    #[test]
    fn fur_ball_roots_lie_on_the_sphere() {
        let f = FurBall {
            strands: 200,
            sphere_radius: 2.0,
            ..Default::default()
        };
        let m = Procedural::FurBall(f).generate().unwrap();
        for s in 0..m.strand_count() {
            let root = m.points[m.strand_range(s).start];
            assert!((root.length() - 2.0).abs() < 1e-4, "strand {s}: {root}");
        }
        assert!(m.radius_from_file);
    }

    #[test]
    fn taper_goes_from_root_to_tip_fraction() {
        assert_eq!(tapered(2.0, 0.25, 0.0), 2.0);
        assert_eq!(tapered(2.0, 0.25, 1.0), 0.5);
    }

    #[test]
    fn wavy_patch_roots_lie_on_the_square() {
        let w = WavyPatch {
            strands: 300,
            ..Default::default()
        };
        let m = Procedural::WavyPatch(w).generate().unwrap();
        for s in 0..m.strand_count() {
            let root = m.points[m.strand_range(s).start];
            assert_eq!(root.y, 0.0);
            assert!(root.x.abs() <= 0.5 && root.z.abs() <= 0.5, "{root}");
        }
    }

    #[test]
    fn patch_without_clumps_generates() {
        let w = WavyPatch {
            strands: 10,
            clumps: 0,
            ..Default::default()
        };
        assert_eq!(
            Procedural::WavyPatch(w).generate().unwrap().strand_count(),
            10
        );
    }
}
