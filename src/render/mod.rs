//! Rendering a frame: camera rays over tiles in parallel (rayon), the path tracer of [`integrator`] at each
//! camera sample, a Gaussian pixel filter, and the [`film`] with beauty and AOV channels.
//!
//! A [`Frame`] ([`frame`]) holds what a render needs, built once; [`settings`] holds what a render runs with.
//!
//! **Determinism**: every pixel depends only on its own sample streams ([`sampler::PixelSampler`], keyed by
//! pixel and seed, and the per-ray keys derived from them) and sums its samples in a fixed order; tiles only decide
//! which thread does the work. The same scene and seed give bit-identical pixels with any thread count. With
//! adaptive sampling's image-level rule ([`adaptive::Rule::Image`]) how many samples a pixel takes is decided
//! between rounds from all the region's pixels, in row-major order: still the same for any thread count and work
//! tile size, but a `--crop`/`--tile` region decides from its own pixels (see [`adaptive`]).

pub mod adaptive;
pub mod budget;
pub mod camera;
pub mod film;
pub mod filter;
pub mod frame;
pub mod integrator;
pub mod sampler;
pub mod settings;
pub mod tiles;

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use crate::bsdf::chiang::LANES;
use crate::image::Image;
use crate::ray::Ray;
use crate::shadow::ShadowMaps;

use camera::Camera;
use film::{PixelSums, Tile};
use filter::GaussianFilter;
use integrator::{Integrator, RayCounts};
use sampler::{dim, CameraSample, PixelSampler};

pub use film::CHANNELS;
pub use frame::{thread_pool, Frame, FrameError, FrameSpec, ThreadPoolError};
pub use settings::{
    FilmConfig, IntegratorConfig, LightSelection, RenderSettings, ShadowConfig, ShadowMode,
    Strategy, TransmittanceMode,
};
pub use tiles::Region;

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

/// How a render reports on itself.
#[derive(Debug, Clone, Copy, Default)]
pub struct Options {
    /// Show a progress bar on stderr.
    pub progress: bool,
}

/// What [`Frame::render_region`] made: the region's pixels and how many of its tiles were rendered.
#[derive(Debug, Clone)]
pub struct RegionRender {
    /// The region's pixels (its size, not the frame's); tiles never started are zero.
    pub image: Image,
    /// Counters of the render.
    pub stats: RenderStats,
    /// Tiles rendered.
    pub tiles_done: usize,
    /// Tiles in the region.
    pub tiles_total: usize,
}

impl RegionRender {
    /// Whether every tile was rendered (no cancellation).
    pub fn is_complete(&self) -> bool {
        self.tiles_done == self.tiles_total
    }
}

/// [`Frame::render_with_maps`] of the whole film with work tiles of `tile_side`² pixels instead of 32²: for
/// tests that the image does not depend on how the work is split.
#[doc(hidden)]
pub fn render_with_tile_side(
    frame: &Frame,
    settings: &RenderSettings,
    maps: Option<&ShadowMaps>,
    tile_side: u32,
) -> Image {
    let [width, height] = settings.film.resolution;
    let maps = maps.filter(|_| settings.shadows.mode == ShadowMode::DeepOpacity);
    let full = Region::full(width, height);
    render_tiles(
        frame,
        settings,
        maps,
        Options::default(),
        full,
        None,
        tile_side.max(1),
    )
    .image
}

/// Sample `i`'s camera ray through pixel (x, y): the pixel's centre offset by the reconstruction filter's draw from
/// `sampler`. The frame ([`render_tiles`]) and the pilots' cut renders ([`render_bounces`]) trace the same rays.
fn camera_ray(
    camera: &Camera,
    filter: &GaussianFilter,
    sampler: &CameraSample,
    x: u32,
    y: u32,
    i: u32,
) -> Ray {
    let (dx, dy) = filter.sample(sampler.get_2d(i, dim::FILTER));
    camera.ray(x as f32 + 0.5 + dx, y as f32 + 0.5 + dy)
}

/// What [`render_bounces`] made: every path length's estimate of a region from one render.
#[derive(Debug, Clone)]
pub struct BounceRender {
    /// `pixels[j][p]`: the beauty of pixel `p` (row-major in the region) cut at path length `j` (0 ..= the
    /// settings' path length): the camera sample's light from vertices 0 ..= j, averaged over the pixel's samples.
    pub pixels: Vec<Vec<Vec3>>,
    /// `variances[j][p]`: the sample variance (n − 1 in the denominator) of the samples `pixels[j][p]` is the mean
    /// of, per channel: what adaptive sampling reads of a pixel.
    pub variances: Vec<Vec<Vec3>>,
    /// `rays[j]`: the rays a render at path length `j` traces (those of vertices 0 ..= j).
    pub rays: Vec<RayCounts>,
}

/// Renders `region` once at `settings` (`film.spp` samples per pixel, no adaptive sampling, no AOVs) and returns
/// the beauty every shorter path length would have given ([`BounceRender`]), for the pilots of `--quality auto`.
///
/// A render at path length j traces the same paths as one at K > j up to vertex j (same sample streams; Russian
/// roulette acts only before a further vertex), so its pixel is the sum of the first j + 1 vertices' light of the
/// longer render's samples. Under light sampling alone the last vertex skips its material sample, so there the
/// cut estimate differs in its last vertex (the same light, another estimator); under MIS and material sampling
/// it is the same. The beauty is the mean of the pixel's samples with a finite beauty, as the film's.
pub fn render_bounces(
    frame: &Frame,
    settings: &RenderSettings,
    maps: Option<&ShadowMaps>,
    region: Region,
) -> BounceRender {
    /// One camera sample's light and rays by vertex.
    struct Vertices {
        radiance: [Vec3; integrator::MAX_PATH_LENGTH as usize + 1],
        rays: [RayCounts; integrator::MAX_PATH_LENGTH as usize + 1],
    }
    impl integrator::BounceRecorder for Vertices {
        #[inline]
        fn vertex(&mut self, b: u32, radiance: Vec3, rays: &RayCounts) {
            self.radiance[b as usize] += radiance;
            self.rays[b as usize].add(rays);
        }
    }
    let [width, height] = settings.film.resolution;
    let maps = maps.filter(|_| settings.shadows.mode == ShadowMode::DeepOpacity);
    let camera = Camera::from_config(&settings.camera, frame.hair_bounds(), width, height);
    let filter = GaussianFilter::shared(settings.film.filter_width);
    let integrator = Integrator::new(frame, settings, maps);
    let lengths = settings.integrator.path_length as usize + 1;
    let mut pixels = vec![Vec::with_capacity((region.width() * region.height()) as usize); lengths];
    let mut variances = pixels.clone();
    let mut counts = RayCounts::default();
    let mut v = Vertices {
        radiance: [Vec3::ZERO; integrator::MAX_PATH_LENGTH as usize + 1],
        rays: [RayCounts::default(); integrator::MAX_PATH_LENGTH as usize + 1],
    };
    let mut rays = vec![RayCounts::default(); lengths];
    for y in region.y0..region.y1 {
        for x in region.x0..region.x1 {
            let pixel = PixelSampler::new(x, y, settings.film.seed);
            // Σx and Σx² of each cut, in f64.
            let mut sums = vec![[[0.0f64; 3]; 2]; lengths];
            let mut kept = 0u32;
            for i in 0..settings.film.spp {
                let sampler = CameraSample::new(&pixel, i);
                let ray = camera_ray(&camera, &filter, &sampler, x, y, i);
                v.radiance[..lengths].fill(Vec3::ZERO);
                let s = integrator.sample_recording(&ray, &sampler, i, &mut counts, &mut v);
                if !s.beauty.is_finite() {
                    continue;
                }
                kept += 1;
                let mut prefix = Vec3::ZERO;
                for ([sum, squares], r) in sums.iter_mut().zip(&v.radiance[..lengths]) {
                    prefix += *r;
                    for (c, x) in prefix.to_array().into_iter().enumerate() {
                        sum[c] += f64::from(x);
                        squares[c] += f64::from(x) * f64::from(x);
                    }
                }
            }
            let k = f64::from(kept);
            for (j, [sum, squares]) in sums.into_iter().enumerate() {
                let mean = sum.map(|s| if kept > 0 { s / k } else { 0.0 });
                let variance = std::array::from_fn(|c| {
                    if kept > 1 {
                        ((squares[c] - sum[c] * mean[c]) / (k - 1.0)).max(0.0)
                    } else {
                        0.0
                    }
                });
                pixels[j].push(Vec3::from_array(mean.map(|m| m as f32)));
                variances[j].push(Vec3::from_array(variance.map(|v: f64| v as f32)));
            }
        }
    }
    let mut prefix = RayCounts::default();
    for (j, r) in rays.iter_mut().enumerate() {
        prefix.add(&v.rays[j]);
        *r = prefix;
    }
    BounceRender {
        pixels,
        variances,
        rays,
    }
}

/// The pixel loop: renders `region` of `frame` with `settings` (and `maps` in deep-opacity mode) on the current
/// rayon pool, in work tiles of `tile_side`² pixels ([`TILE`] but in tests). Once `cancel` holds a non-zero value
/// no new tile starts (tiles already running finish).
fn render_tiles(
    frame: &Frame,
    settings: &RenderSettings,
    maps: Option<&ShadowMaps>,
    options: Options,
    region: Region,
    cancel: Option<&AtomicUsize>,
    tile_side: u32,
) -> RegionRender {
    let [width, height] = settings.film.resolution;
    let strands = &frame.strands;
    let tracer = frame.tracer.as_ref();
    let bounds = frame.hair_bounds();
    let camera = Camera::from_config(&settings.camera, bounds, width, height);
    let filter = GaussianFilter::shared(settings.film.filter_width);
    let integrator = Integrator::new(frame, settings, maps);

    let tiles_x = region.width().div_ceil(tile_side);
    let tiles_y = region.height().div_ceil(tile_side);
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
    let spp = settings.film.spp;
    let adaptive = settings.adaptive;
    let seed = settings.film.seed;
    let centre_ray = settings.film.traces_centre_ray();
    // Experimental (`integrator.lanes`, docs/design/wavefront.md, step 2): first vertices shaded eight at a time.
    let lanes = settings.integrator.lanes && integrator.lanes_fit();
    let tiles: Vec<(u32, u32)> = (0..tiles_y)
        .flat_map(|ty| (0..tiles_x).map(move |tx| (tx, ty)))
        .collect();
    let sample_pixel = |x: u32, y: u32, i: u32, counts: &mut RayCounts| {
        let pixel = PixelSampler::new(x, y, seed);
        let sampler = CameraSample::new(&pixel, i);
        let ray = camera_ray(&camera, &filter, &sampler, x, y, i);
        integrator.sample(&ray, &sampler, i, counts)
    };
    let write_centre = |x: u32, y: u32, pixel: &mut [f32], counts: &mut RayCounts| {
        if !centre_ray {
            return;
        }
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
        film::write_centre(depth, tangent, id, pixel);
    };
    let layout = film::Layout::new(&settings.film);
    let new_tile = |tx: u32, ty: u32| {
        let (x0, y0) = (region.x0 + tx * tile_side, region.y0 + ty * tile_side);
        Tile::new(
            x0,
            y0,
            (x0 + tile_side).min(region.x1),
            (y0 + tile_side).min(region.y1),
            &layout,
        )
    };
    let cancelled = || cancel.is_some_and(|c| c.load(Ordering::Relaxed) != 0);
    let rendered: Vec<(Tile, RayCounts)> = match adaptive {
        Some(schedule) if schedule.rule == adaptive::Rule::Image => adaptive::render_rounds(
            &tiles,
            region,
            schedule,
            &progress,
            &new_tile,
            &sample_pixel,
            &write_centre,
            &cancelled,
        ),
        _ => tiles
            .par_iter()
            .filter_map(|&(tx, ty)| {
                if cancelled() {
                    return None;
                }
                let mut tile = new_tile(tx, ty);
                let mut counts = RayCounts::default();
                for y in tile.y0..tile.y1 {
                    for x in tile.x0..tile.x1 {
                        let mut sums = PixelSums::default();
                        let taken = match adaptive {
                            None => {
                                let mut i = 0;
                                if lanes {
                                    let pixel = PixelSampler::new(x, y, seed);
                                    while i + LANES as u32 <= spp {
                                        let indices: [u32; LANES] =
                                            std::array::from_fn(|k| i + k as u32);
                                        let samplers =
                                            indices.map(|j| CameraSample::new(&pixel, j));
                                        let rays: [Ray; LANES] = std::array::from_fn(|k| {
                                            camera_ray(
                                                &camera,
                                                &filter,
                                                &samplers[k],
                                                x,
                                                y,
                                                indices[k],
                                            )
                                        });
                                        for s in integrator.sample_lanes(
                                            &rays,
                                            &samplers,
                                            &indices,
                                            &mut counts,
                                        ) {
                                            sums.add(&s);
                                        }
                                        i += LANES as u32;
                                    }
                                }
                                for i in i..spp {
                                    sums.add(&sample_pixel(x, y, i, &mut counts));
                                }
                                spp
                            }
                            // Rounds of samples, in index order, until the pixel's own estimate of its error is
                            // under the target (render::adaptive): the count depends on this pixel's samples alone.
                            Some(schedule) => {
                                let mut convergence = adaptive::Convergence::default();
                                let mut i = 0;
                                while let Some(total) = schedule.next_total(i, &convergence) {
                                    while i < total {
                                        let s = sample_pixel(x, y, i, &mut counts);
                                        if s.beauty.is_finite() {
                                            convergence.add(s.beauty);
                                        }
                                        sums.add(&s);
                                        i += 1;
                                    }
                                }
                                i
                            }
                        };
                        tile.set_pixel(x, y, |pixel| {
                            sums.write(taken, pixel);
                            write_centre(x, y, pixel, &mut counts);
                        });
                    }
                }
                progress.inc(1);
                Some((tile, counts))
            })
            .collect(),
    };
    progress.finish_and_clear();

    let mut rays = RayCounts::default();
    for (_, counts) in &rendered {
        rays.add(counts);
    }
    let tiles_done = rendered.len();
    // Tiles were rendered in frame coordinates; the image holds the region alone.
    let tiles: Vec<Tile> = rendered
        .into_iter()
        .map(|(mut t, _)| {
            (t.x0, t.x1, t.y0, t.y1) = (
                t.x0 - region.x0,
                t.x1 - region.x0,
                t.y0 - region.y0,
                t.y1 - region.y0,
            );
            t
        })
        .collect();
    let image = film::assemble(region.width(), region.height(), &tiles, &layout);
    let stats = RenderStats {
        seconds: start.elapsed().as_secs_f64(),
        rays,
        shadow_build_seconds: 0.0,
        shadow_map_bytes: 0,
    };
    RegionRender {
        image,
        stats,
        tiles_done,
        tiles_total: tiles_x as usize * tiles_y as usize,
    }
}
