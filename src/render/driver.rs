//! The tile driver: a region cut into work tiles rendered in parallel on the current rayon pool, with a progress
//! bar and cancellation, then assembled into the region's image. What happens inside a pixel is a sampling
//! strategy's ([`super::strategy`]); the image-level adaptive rule runs its rounds over the same tiles
//! ([`super::adaptive::render_rounds`]).

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use super::adaptive::{self, Rule};
use super::camera::Camera;
use super::film::{self, PixelSums, Tile};
use super::filter::GaussianFilter;
use super::integrator::{Integrator, PathSample, RayCounts};
use super::sampler::{CameraSample, PixelSampler};
use super::strategy::{Fixed, PerPixel, PixelStrategy};
use super::{camera_ray, Frame, Region, RegionRender, RenderSettings, RenderStats};
use crate::bsdf::chiang::LANES;
use crate::ray::Ray;
use crate::shadow::ShadowMaps;

/// One pixel's camera samples, as a strategy draws them: sample `i` through the pixel, rays counted in `counts`.
pub(super) struct PixelSource<'s> {
    x: u32,
    y: u32,
    pixel: PixelSampler,
    context: &'s Context<'s>,
    counts: &'s mut RayCounts,
}

/// What every pixel of a render shares: the camera, the pixel filter, the integrator, the seed.
struct Context<'f> {
    camera: Camera,
    filter: Arc<GaussianFilter>,
    integrator: Integrator<'f>,
    seed: u32,
}

impl<'f> Context<'f> {
    /// Pixel (x, y)'s samples, rays counted in `counts`.
    fn source<'s>(&'s self, x: u32, y: u32, counts: &'s mut RayCounts) -> PixelSource<'s> {
        PixelSource {
            x,
            y,
            pixel: PixelSampler::new(x, y, self.seed),
            context: self,
            counts,
        }
    }
}

impl PixelSource<'_> {
    /// The pixel's camera sample `i`.
    pub(super) fn sample(&mut self, i: u32) -> PathSample {
        let sampler = CameraSample::new(&self.pixel, i);
        let c = self.context;
        let ray = camera_ray(&c.camera, &c.filter, &sampler, self.x, self.y, i);
        c.integrator.sample(&ray, &sampler, i, self.counts)
    }

    /// The pixel's camera samples `first .. first + LANES`, their first vertices shaded together.
    pub(super) fn sample_lanes(&mut self, first: u32) -> [PathSample; LANES] {
        let indices: [u32; LANES] = std::array::from_fn(|k| first + k as u32);
        let samplers = indices.map(|j| CameraSample::new(&self.pixel, j));
        let c = self.context;
        let rays: [Ray; LANES] = std::array::from_fn(|k| {
            camera_ray(
                &c.camera,
                &c.filter,
                &samplers[k],
                self.x,
                self.y,
                indices[k],
            )
        });
        c.integrator
            .sample_lanes(&rays, &samplers, &indices, self.counts)
    }
}

/// Renders `region` of `frame` with `settings` (and `maps` in deep-opacity mode) on the current rayon pool, in
/// work tiles of `tile_side`² pixels. Once `cancel` holds a non-zero value no new tile starts (tiles already
/// running finish).
pub(super) fn render_tiles(
    frame: &Frame,
    settings: &RenderSettings,
    maps: Option<&ShadowMaps>,
    progress: bool,
    region: Region,
    cancel: Option<&AtomicUsize>,
    tile_side: u32,
) -> RegionRender {
    let [width, height] = settings.film.resolution;
    let context = Context {
        camera: Camera::from_config(&settings.camera, frame.hair_bounds(), width, height),
        filter: GaussianFilter::shared(settings.film.filter_width),
        integrator: Integrator::new(frame, settings, maps),
        seed: settings.film.seed,
    };

    let tiles_x = region.width().div_ceil(tile_side);
    let tiles_y = region.height().div_ceil(tile_side);
    let bar = progress_bar(progress, u64::from(tiles_x * tiles_y));
    let start = Instant::now();
    let tiles: Vec<(u32, u32)> = (0..tiles_y)
        .flat_map(|ty| (0..tiles_x).map(move |tx| (tx, ty)))
        .collect();
    let centre = |x: u32, y: u32, pixel: &mut [f32], counts: &mut RayCounts| {
        if settings.film.traces_centre_ray() {
            write_centre(frame, &context.camera, x, y, pixel, counts);
        }
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
    let pixel_by_pixel = |strategy: &dyn PixelStrategy| -> Vec<(Tile, RayCounts)> {
        tiles
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
                        let taken =
                            strategy.take(&mut context.source(x, y, &mut counts), &mut sums);
                        tile.set_pixel(x, y, |pixel| {
                            sums.write(taken, pixel);
                            centre(x, y, pixel, &mut counts);
                        });
                    }
                }
                bar.inc(1);
                Some((tile, counts))
            })
            .collect()
    };
    let rendered = match settings.adaptive {
        Some(schedule) if schedule.rule == Rule::Image => {
            let sample = |x: u32, y: u32, i: u32, counts: &mut RayCounts| {
                context.source(x, y, counts).sample(i)
            };
            adaptive::render_rounds(
                &tiles, region, schedule, &bar, &new_tile, &sample, &centre, &cancelled,
            )
        }
        Some(schedule) => pixel_by_pixel(&PerPixel { schedule }),
        None => pixel_by_pixel(&Fixed {
            spp: settings.film.spp,
            lanes: settings.integrator.lanes && context.integrator.lanes_fit(),
        }),
    };
    bar.finish_and_clear();
    assemble(rendered, region, &layout, start, tiles_x * tiles_y)
}

/// The progress bar of a render: tiles done, elapsed, estimated time left; hidden unless `show`.
fn progress_bar(show: bool, tiles: u64) -> indicatif::ProgressBar {
    let bar = if show {
        indicatif::ProgressBar::new(tiles)
    } else {
        indicatif::ProgressBar::hidden()
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{prefix} [{bar:40}] {pos}/{len} tiles, {elapsed} (eta {eta})",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar.set_prefix("rendering");
    bar
}

/// The centre-ray channels of pixel (x, y): depth, tangent and strand id of one unfiltered camera ray.
fn write_centre(
    frame: &Frame,
    camera: &Camera,
    x: u32,
    y: u32,
    pixel: &mut [f32],
    counts: &mut RayCounts,
) {
    let centre = camera.ray(x as f32 + 0.5, y as f32 + 0.5);
    counts.camera += 1;
    let hit = frame.tracer.intersect(&centre).unwrap_or(None);
    let (depth, tangent, id) = match hit {
        Some(h) => (
            h.t * centre.dir.dot(camera.forward),
            frame
                .strands
                .eval(h.segment, h.u)
                .tangent
                .normalize_or_zero(),
            h.strand as f32,
        ),
        None => (f32::INFINITY, Vec3::ZERO, -1.0),
    };
    film::write_centre(depth, tangent, id, pixel);
}

/// The rendered tiles as the region's image, with the render's counters.
fn assemble(
    rendered: Vec<(Tile, RayCounts)>,
    region: Region,
    layout: &film::Layout,
    start: Instant,
    tiles_total: u32,
) -> RegionRender {
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
    let image = film::assemble(region.width(), region.height(), &tiles, layout);
    RegionRender {
        image,
        stats: RenderStats {
            seconds: start.elapsed().as_secs_f64(),
            rays,
            shadow_build_seconds: 0.0,
            shadow_map_bytes: 0,
        },
        tiles_done,
        tiles_total: tiles_total as usize,
    }
}
