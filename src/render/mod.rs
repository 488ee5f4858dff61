//! Rendering a frame: camera rays over tiles in parallel (rayon), shading at strand hits, self-shadowing through
//! the tracer's transmittance query, a Gaussian pixel filter, and a film with beauty and AOV channels.
//!
//! Lighting here is deliberately small (issue 3): Kajiya-Kay shading, distant lights and a constant environment
//! sampled uniformly over the sphere. Issue 5 replaces it with MIS over HDR environment and area lights.
//!
//! **Determinism**: every pixel depends only on its own sample stream ([`sampler::PixelSampler`], keyed by
//! pixel and seed) and sums its samples in a fixed order; tiles only decide which thread does the work. The same
//! scene and seed give bit-identical pixels with any thread count.

pub mod camera;
pub mod filter;
pub mod sampler;

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use crate::accel::{CurveKind, Hit, Tracer};
use crate::bsdf::frame::{sin_cos_theta, strand_noise, HairFrame};
use crate::bsdf::{Lobe, LobeValues};
use crate::hair::Strands;
use crate::image::Image;
use crate::ray::Ray;
use crate::scene::{LightConfig, Material, Scene, ShadowMode};

use camera::Camera;
use filter::GaussianFilter;
use sampler::{dim, PixelSampler};

/// Channels of the film, in order: beauty RGBA, then AOVs as `layer.channel` (EXR naming). The lobe layers
/// (`diffuse`, `R`, `TT`, `TRT`, `glint`) split the beauty of hair hits by [`Lobe`]: they add up to it, less the
/// background.
pub const CHANNELS: [&str; 24] = [
    "R",
    "G",
    "B",
    "A",
    "depth.Z",
    "tangent.X",
    "tangent.Y",
    "tangent.Z",
    "strand.id",
    "diffuse.R",
    "diffuse.G",
    "diffuse.B",
    "lobe_R.R",
    "lobe_R.G",
    "lobe_R.B",
    "lobe_TT.R",
    "lobe_TT.G",
    "lobe_TT.B",
    "lobe_TRT.R",
    "lobe_TRT.G",
    "lobe_TRT.B",
    "lobe_glint.R",
    "lobe_glint.G",
    "lobe_glint.B",
];

/// Side of the square tiles rendered as one unit of parallel work.
const TILE: u32 = 32;

/// Counters of one render, for the summary line and for tests.
#[derive(Debug, Default, Clone, Copy)]
pub struct RenderStats {
    /// Wall time of the pixel loop, seconds.
    pub seconds: f64,
    /// Camera rays traced (including the one unfiltered AOV ray per pixel).
    pub camera_rays: u64,
    /// Shadow (transmittance) rays traced.
    pub shadow_rays: u64,
    /// Rays rejected by validation (never traced); should be 0.
    pub rejected_rays: u64,
}

/// A distant light, resolved: direction towards the light and irradiance per channel.
#[derive(Debug, Clone, Copy)]
struct Distant {
    wi: Vec3,
    irradiance: Vec3,
}

/// What the shading of one hit needs, resolved once per frame from the scene.
struct Shading<'a> {
    strands: &'a Strands,
    tracer: &'a dyn Tracer,
    /// The fibre model (local hair frame).
    material: Material,
    /// How hits' frames are built: round tubes from Embree's normal, ribbons from a per-strand noise vector.
    curves: CurveKind,
    distant: Vec<Distant>,
    environment: Vec3,
    shadows: ShadowMode,
}

/// Counters accumulated per tile, merged atomically (integers: order-independent).
#[derive(Default)]
struct Counters {
    camera_rays: AtomicU64,
    shadow_rays: AtomicU64,
    rejected_rays: AtomicU64,
}

impl Shading<'_> {
    /// Transmittance towards `wi` from the hit, or 1 without shadows.
    #[inline]
    fn visibility(&self, p: Vec3, wi: Vec3, strand: u32, counters: &mut (u64, u64)) -> f32 {
        if self.shadows == ShadowMode::None {
            return 1.0;
        }
        counters.0 += 1;
        match self.tracer.transmittance(&Ray::new(p, wi), Some(strand)) {
            Ok(t) => t,
            Err(_) => {
                counters.1 += 1;
                1.0
            }
        }
    }

    /// Radiance leaving `hit` towards the camera ray's origin, split by lobe.
    fn shade(
        &self,
        ray: &Ray,
        hit: &Hit,
        sampler: &PixelSampler,
        index: u32,
        counters: &mut (u64, u64),
    ) -> LobeValues {
        let point = self.strands.eval(hit.segment, hit.u);
        let wo = -ray.dir.normalize();
        // A degenerate strand (repeated points) has no tangent: shade it as a fibre perpendicular to the view.
        let tangent = point
            .tangent
            .try_normalize()
            .unwrap_or_else(|| wo.any_orthonormal_vector());
        let frame = match self.curves {
            CurveKind::Round => HairFrame::from_round_curve(tangent, hit.ng),
            CurveKind::Flat => HairFrame::from_ribbon(tangent, strand_noise(hit.strand)),
        };
        let p = ray.at(hit.t);
        let tint = if self.material.tint_diffuse_by_strand {
            Vec3::from(self.strands.color[hit.strand as usize])
        } else {
            Vec3::ONE
        };
        let wo_local = frame.to_local(wo);
        let f = |wi: Vec3| {
            let mut lobes = self.material.bsdf.eval_lobes(wo_local, frame.to_local(wi));
            lobes.diffuse *= tint;
            lobes
        };
        let mut radiance = LobeValues::default();
        let mut add = |lobes: LobeValues, scale: Vec3| {
            for lobe in Lobe::ALL {
                *radiance.get_mut(lobe) += lobes.get(lobe) * scale;
            }
        };
        for light in &self.distant {
            let cos_i = sin_cos_theta(frame.to_local(light.wi)).1;
            let lobes = f(light.wi);
            if lobes.sum().max_element() > 0.0 {
                let v = self.visibility(p, light.wi, hit.strand, counters);
                add(lobes, light.irradiance * cos_i * v);
            }
        }
        if self.environment.max_element() > 0.0 {
            // One direction per camera sample, uniform over the sphere: pdf = 1 / 4π.
            let (u1, u2) = sampler.get_2d(index, dim::ENVIRONMENT);
            let wi = uniform_sphere(u1, u2);
            let cos_i = sin_cos_theta(frame.to_local(wi)).1;
            let v = self.visibility(p, wi, hit.strand, counters);
            add(
                f(wi),
                self.environment * cos_i * (4.0 * std::f32::consts::PI) * v,
            );
        }
        radiance
    }
}

/// A uniformly distributed direction on the unit sphere.
#[inline]
fn uniform_sphere(u1: f32, u2: f32) -> Vec3 {
    let z = 1.0 - 2.0 * u1;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = std::f32::consts::TAU * u2;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Overrides a renderer user may set on the command line, on top of the scene.
#[derive(Debug, Clone, Copy, Default)]
pub struct Options {
    /// Show a progress bar on stderr.
    pub progress: bool,
}

/// Renders `scene` with `strands` traced by `tracer`. Runs on the current rayon pool.
pub fn render(
    scene: &Scene,
    strands: &Strands,
    tracer: &dyn Tracer,
    options: Options,
) -> (Image, RenderStats) {
    let [width, height] = scene.film.resolution;
    let camera = Camera::from_config(&scene.camera, strands.bounds(), width, height);
    let filter = GaussianFilter::new(scene.film.filter_width);
    let shading = Shading {
        strands,
        tracer,
        material: scene
            .material
            .build()
            .expect("Scene::parse validated the material"),
        curves: scene.hair.curves,
        distant: scene
            .lights
            .iter()
            .map(|l| match l {
                LightConfig::Distant {
                    direction,
                    irradiance,
                    color,
                } => Distant {
                    wi: -Vec3::from(*direction).normalize(),
                    irradiance: *irradiance * Vec3::from(*color),
                },
            })
            .collect(),
        environment: Vec3::from(scene.environment.radiance),
        shadows: scene.shadows.mode,
    };
    let background = if scene.environment.visible {
        Vec3::from(scene.environment.radiance)
    } else {
        Vec3::ZERO
    };

    let tiles_x = width.div_ceil(TILE);
    let tiles_y = height.div_ceil(TILE);
    let progress = if options.progress {
        indicatif::ProgressBar::new(u64::from(tiles_x * tiles_y))
    } else {
        indicatif::ProgressBar::hidden()
    };
    progress.set_style(
        indicatif::ProgressStyle::with_template(
            "{prefix} [{bar:40}] {pos}/{len} tiles, {elapsed} (eta {eta})",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    progress.set_prefix("rendering");

    let counters = Counters::default();
    let start = Instant::now();
    let spp = scene.film.spp;
    let seed = scene.film.seed;
    let nc = CHANNELS.len();
    let tiles: Vec<(u32, u32)> = (0..tiles_y)
        .flat_map(|ty| (0..tiles_x).map(move |tx| (tx, ty)))
        .collect();
    let rendered: Vec<Vec<f32>> = tiles
        .par_iter()
        .map(|&(tx, ty)| {
            let (x0, y0) = (tx * TILE, ty * TILE);
            let (x1, y1) = ((x0 + TILE).min(width), (y0 + TILE).min(height));
            let mut out = vec![0.0f32; ((x1 - x0) * (y1 - y0)) as usize * nc];
            let (mut camera_rays, mut shadow) = (0u64, (0u64, 0u64));
            let mut rejected = 0u64;
            for y in y0..y1 {
                for x in x0..x1 {
                    let sampler = PixelSampler::new(x, y, seed);
                    let mut sum = Vec3::ZERO;
                    let mut lobes = LobeValues::default();
                    let mut coverage = 0u32;
                    for i in 0..spp {
                        let (dx, dy) = filter.sample(sampler.get_2d(i, dim::FILTER));
                        let ray = camera.ray(x as f32 + 0.5 + dx, y as f32 + 0.5 + dy);
                        camera_rays += 1;
                        match tracer.intersect(&ray) {
                            Ok(Some(hit)) => {
                                coverage += 1;
                                let l = shading.shade(&ray, &hit, &sampler, i, &mut shadow);
                                sum += l.sum();
                                for lobe in Lobe::ALL {
                                    *lobes.get_mut(lobe) += l.get(lobe);
                                }
                            }
                            Ok(None) => sum += background,
                            Err(_) => rejected += 1,
                        }
                    }
                    let beauty = sum / spp as f32;
                    let lobes = lobes.scaled(1.0 / spp as f32);
                    // AOVs come from one unfiltered ray through the pixel centre: a depth or id averaged across
                    // an edge would name no real surface.
                    let centre = camera.ray(x as f32 + 0.5, y as f32 + 0.5);
                    camera_rays += 1;
                    let hit = tracer.intersect(&centre).unwrap_or(None);
                    let (depth, tangent, id) = match hit {
                        Some(h) => (
                            h.t * centre.dir.dot(camera.forward),
                            strands.eval(h.segment, h.u).tangent.normalize_or_zero(),
                            h.strand as f32,
                        ),
                        None => (f32::INFINITY, Vec3::ZERO, -1.0),
                    };
                    let o = (((y - y0) * (x1 - x0) + (x - x0)) as usize) * nc;
                    out[o..o + 9].copy_from_slice(&[
                        beauty.x,
                        beauty.y,
                        beauty.z,
                        coverage as f32 / spp as f32,
                        depth,
                        tangent.x,
                        tangent.y,
                        tangent.z,
                        id,
                    ]);
                    for (k, lobe) in [Lobe::Diffuse, Lobe::R, Lobe::Tt, Lobe::Trt, Lobe::Glint]
                        .into_iter()
                        .enumerate()
                    {
                        let v = lobes.get(lobe);
                        out[o + 9 + 3 * k..o + 12 + 3 * k].copy_from_slice(&[v.x, v.y, v.z]);
                    }
                }
            }
            counters
                .camera_rays
                .fetch_add(camera_rays, Ordering::Relaxed);
            counters.shadow_rays.fetch_add(shadow.0, Ordering::Relaxed);
            counters
                .rejected_rays
                .fetch_add(rejected + shadow.1, Ordering::Relaxed);
            progress.inc(1);
            out
        })
        .collect();
    progress.finish_and_clear();

    let mut image = Image::new(
        width as usize,
        height as usize,
        CHANNELS.iter().map(|c| c.to_string()).collect(),
    );
    for (&(tx, ty), tile) in tiles.iter().zip(&rendered) {
        let (x0, y0) = (tx * TILE, ty * TILE);
        let tw = ((x0 + TILE).min(width) - x0) as usize;
        for (row, chunk) in tile.chunks(tw * nc).enumerate() {
            let o = ((y0 as usize + row) * width as usize + x0 as usize) * nc;
            image.data[o..o + chunk.len()].copy_from_slice(chunk);
        }
    }
    let stats = RenderStats {
        seconds: start.elapsed().as_secs_f64(),
        camera_rays: counters.camera_rays.into_inner(),
        shadow_rays: counters.shadow_rays.into_inner(),
        rejected_rays: counters.rejected_rays.into_inner(),
    };
    (image, stats)
}

/// Loads the scene's hair model and converts it to B-spline strands (with the scene's radius and opacity
/// overrides applied).
pub fn load_strands(scene: &Scene) -> Result<Strands, crate::hair::HairError> {
    let model = match scene.hair_source() {
        crate::scene::HairSource::File(path) => crate::hair::load(&path)?,
        crate::scene::HairSource::Procedural(p) => p.generate()?,
    };
    let mut strands = Strands::from_model(&model);
    if scene.hair.radius_scale != 1.0 {
        strands
            .control_points
            .iter_mut()
            .for_each(|c| c[3] *= scene.hair.radius_scale);
    }
    if let Some(o) = scene.hair.opacity {
        strands.set_opacity(o);
    }
    Ok(strands)
}
