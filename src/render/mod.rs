//! Rendering a frame: camera rays over tiles in parallel (rayon), the path tracer of [`integrator`] at each
//! camera sample, a Gaussian pixel filter, and a film with beauty and AOV channels.
//!
//! **Determinism**: every pixel depends only on its own sample streams ([`sampler::PixelSampler`], keyed by
//! pixel and seed, and the per-ray keys derived from them) and sums its samples in a fixed order; tiles only decide
//! which thread does the work. The same scene and seed give bit-identical pixels with any thread count.

pub mod camera;
pub mod filter;
pub mod integrator;
pub mod sampler;

use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use crate::accel::Tracer;
use crate::bsdf::{Lobe, LobeValues};
use crate::hair::Strands;
use crate::image::Image;
use crate::light::Light;
use crate::scene::{Scene, ShadowMode, Strategy};
use crate::shadow::ShadowMaps;

use camera::Camera;
use filter::GaussianFilter;
use integrator::{Integrator, PathSample, RayCounts, Settings};
use sampler::{dim, PixelSampler};

/// Channels of the film, in order: beauty RGBA, then AOVs as `layer.channel` (EXR naming).
///
/// - `diffuse`, `specular` and the lobe layers `lobe_R`, `lobe_TT`, `lobe_TRT`, `lobe_glint` split the light
///   leaving the first shading point by the lobe it went through (Lambert shapes count as diffuse):
///   R + TT + TRT + glint = specular, and diffuse + specular = direct + indirect.
/// - `direct` (light scattered once) and `indirect` (more than once); beauty = direct + indirect + what the camera
///   sees of emitters and the background.
/// - `shadow.Y`: the fraction of the first shading point's light-sample contributions that its shadow rays let
///   through (1 where nothing was lit or nothing was hit).
/// - `albedo`: a one-sample estimate of the first shading point's directional albedo (f cos θ / pdf).
/// - `depth.Z`, `tangent`, `strand.id`: from one unfiltered ray through the pixel centre (a depth or id averaged
///   across an edge would name no real surface); depth is +∞, tangent 0 and id −1 where it misses.
pub const CHANNELS: [&str; 37] = [
    "R",
    "G",
    "B",
    "A",
    "diffuse.R",
    "diffuse.G",
    "diffuse.B",
    "specular.R",
    "specular.G",
    "specular.B",
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
    "direct.R",
    "direct.G",
    "direct.B",
    "indirect.R",
    "indirect.G",
    "indirect.B",
    "shadow.Y",
    "albedo.R",
    "albedo.G",
    "albedo.B",
    "depth.Z",
    "tangent.X",
    "tangent.Y",
    "tangent.Z",
    "strand.id",
];

/// Side of the square tiles rendered as one unit of parallel work.
const TILE: u32 = 32;

/// Counters of one render, for the summary line and for tests.
#[derive(Debug, Default, Clone, Copy)]
pub struct RenderStats {
    /// Wall time of the pixel loop, seconds.
    pub seconds: f64,
    /// Rays traced, by kind.
    pub rays: RayCounts,
    /// Wall time of building shadow maps (deep-opacity mode; 0 otherwise), seconds, not included in `seconds`.
    pub shadow_build_seconds: f64,
    /// Memory held by the shadow maps, bytes.
    pub shadow_map_bytes: usize,
}

/// Overrides a renderer user may set on the command line, on top of the scene.
#[derive(Debug, Clone, Copy, Default)]
pub struct Options {
    /// Show a progress bar on stderr.
    pub progress: bool,
}

/// The film accumulators of one pixel (sums over its camera samples).
#[derive(Default)]
struct PixelSums {
    beauty: Vec3,
    alpha: f32,
    lobes: LobeValues,
    direct: Vec3,
    indirect: Vec3,
    lit: f32,
    unshadowed: f32,
    albedo: Vec3,
}

impl PixelSums {
    fn add(&mut self, s: &PathSample) {
        self.beauty += s.beauty;
        self.alpha += s.alpha;
        for lobe in Lobe::ALL {
            *self.lobes.get_mut(lobe) += s.lobes.get(lobe);
        }
        self.direct += s.direct;
        self.indirect += s.indirect;
        self.lit += s.lit;
        self.unshadowed += s.unshadowed;
        self.albedo += s.albedo;
    }

    /// Writes the averaged pixel into `out` (the AOV-ray channels are written by the caller).
    fn write(&self, spp: u32, out: &mut [f32]) {
        let k = 1.0 / spp as f32;
        let l = self.lobes.scaled(k);
        let specular = l.r + l.tt + l.trt + l.glint;
        let shadow = if self.unshadowed > 0.0 {
            self.lit / self.unshadowed
        } else {
            1.0
        };
        let b = self.beauty * k;
        let mut o = 0;
        let mut put = |v: &[f32]| {
            out[o..o + v.len()].copy_from_slice(v);
            o += v.len();
        };
        put(&[b.x, b.y, b.z, self.alpha * k]);
        for v in [
            l.diffuse,
            specular,
            l.r,
            l.tt,
            l.trt,
            l.glint,
            self.direct * k,
            self.indirect * k,
        ] {
            put(&v.to_array());
        }
        put(&[shadow]);
        put(&(self.albedo * k).to_array());
    }
}

/// Index of the first AOV-ray channel (`depth.Z`) in [`CHANNELS`].
const AOV_RAY_CHANNELS: usize = 32;

/// The light-transport settings of `scene`.
pub fn settings(scene: &Scene) -> Settings {
    let i = &scene.integrator;
    Settings {
        light_samples: i.light_samples,
        material_samples: i.material_samples,
        path_length: i.path_length,
        clamp: i.clamp,
        shadows: scene.shadows.mode,
        transmittance: scene.shadows.transmittance,
        // Maps replace the shadow queries of light samples; a material sample's ray would see the hair itself, so
        // in deep-opacity mode material samples only continue paths and light samples carry all direct light.
        strategy: if scene.shadows.mode == ShadowMode::DeepOpacity {
            Strategy::Light
        } else {
            i.strategy
        },
        light_selection: i.lights,
    }
}

/// Renders `scene` with `strands` traced by `tracer`, lit by `lights` ([`Scene::build_lights`]). Runs on the
/// current rayon pool.
pub fn render(
    scene: &Scene,
    strands: &Strands,
    tracer: &dyn Tracer,
    lights: &[Light],
    options: Options,
) -> (Image, RenderStats) {
    let [width, height] = scene.film.resolution;
    let bounds = strands.bounds();
    let camera = Camera::from_config(&scene.camera, bounds, width, height);
    let filter = GaussianFilter::new(scene.film.filter_width);
    let material = scene
        .material
        .build()
        .expect("Scene::parse validated the material");
    let shapes = scene.build_shapes();
    let scene_radius = scene_radius(bounds, &shapes);
    let build_start = Instant::now();
    let maps = (scene.shadows.mode == ShadowMode::DeepOpacity)
        .then(|| ShadowMaps::build(strands, lights, &scene.shadows.deep_opacity));
    let shadow_build_seconds = build_start.elapsed().as_secs_f64();
    let integrator = Integrator::new(
        strands,
        tracer,
        &shapes,
        lights,
        &material,
        scene.hair.curves,
        settings(scene),
        scene_radius,
        scene.environment.visible,
        maps.as_ref(),
    );

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

    let start = Instant::now();
    let spp = scene.film.spp;
    let seed = scene.film.seed;
    let nc = CHANNELS.len();
    let tiles: Vec<(u32, u32)> = (0..tiles_y)
        .flat_map(|ty| (0..tiles_x).map(move |tx| (tx, ty)))
        .collect();
    let rendered: Vec<(Vec<f32>, RayCounts)> = tiles
        .par_iter()
        .map(|&(tx, ty)| {
            let (x0, y0) = (tx * TILE, ty * TILE);
            let (x1, y1) = ((x0 + TILE).min(width), (y0 + TILE).min(height));
            let mut out = vec![0.0f32; ((x1 - x0) * (y1 - y0)) as usize * nc];
            let mut counts = RayCounts::default();
            for y in y0..y1 {
                for x in x0..x1 {
                    let sampler = PixelSampler::new(x, y, seed);
                    let mut sums = PixelSums::default();
                    for i in 0..spp {
                        let (dx, dy) = filter.sample(sampler.get_2d(i, dim::FILTER));
                        let ray = camera.ray(x as f32 + 0.5 + dx, y as f32 + 0.5 + dy);
                        sums.add(&integrator.sample(&ray, &sampler, i, &mut counts));
                    }
                    let o = (((y - y0) * (x1 - x0) + (x - x0)) as usize) * nc;
                    sums.write(spp, &mut out[o..o + AOV_RAY_CHANNELS]);
                    let centre = camera.ray(x as f32 + 0.5, y as f32 + 0.5);
                    counts.camera += 1;
                    let hit = tracer.intersect(&centre).unwrap_or(None);
                    let (depth, tangent, id) = match hit {
                        Some(h) => (
                            h.t * centre.dir.dot(camera.forward),
                            strands.eval(h.segment, h.u).tangent.normalize_or_zero(),
                            h.strand as f32,
                        ),
                        None => (f32::INFINITY, Vec3::ZERO, -1.0),
                    };
                    out[o + AOV_RAY_CHANNELS..o + nc]
                        .copy_from_slice(&[depth, tangent.x, tangent.y, tangent.z, id]);
                }
            }
            progress.inc(1);
            (out, counts)
        })
        .collect();
    progress.finish_and_clear();

    let mut image = Image::new(
        width as usize,
        height as usize,
        CHANNELS.iter().map(|c| c.to_string()).collect(),
    );
    let mut rays = RayCounts::default();
    for (&(tx, ty), (tile, counts)) in tiles.iter().zip(&rendered) {
        rays.add(counts);
        let (x0, y0) = (tx * TILE, ty * TILE);
        let tw = ((x0 + TILE).min(width) - x0) as usize;
        for (row, chunk) in tile.chunks(tw * nc).enumerate() {
            let o = ((y0 as usize + row) * width as usize + x0 as usize) * nc;
            image.data[o..o + chunk.len()].copy_from_slice(chunk);
        }
    }
    let stats = RenderStats {
        seconds: start.elapsed().as_secs_f64(),
        rays,
        shadow_build_seconds,
        shadow_map_bytes: maps.as_ref().map_or(0, ShadowMaps::bytes),
    };
    (image, stats)
}

/// Radius of a sphere around the hair and the shapes (sizes infinite lights' power and ray offsets).
fn scene_radius(bounds: (Vec3, Vec3), shapes: &crate::shape::Shapes) -> f32 {
    let (mut lo, mut hi) = bounds;
    for q in shapes.quads() {
        for p in [
            q.corner,
            q.corner + q.edge_u,
            q.corner + q.edge_v,
            q.corner + q.edge_u + q.edge_v,
        ] {
            lo = lo.min(p);
            hi = hi.max(p);
        }
    }
    let r = 0.5 * (hi - lo).length();
    if r.is_finite() && r > 0.0 {
        r
    } else {
        1.0
    }
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
