//! The tile driver: a region cut into work tiles rendered in parallel on the current rayon pool, with a progress
//! bar and cancellation, then assembled into the region's image. What happens inside a pixel is a sampling
//! strategy's ([`super::strategy`]); the image-level adaptive rule runs its rounds over the same tiles
//! ([`super::adaptive::render_rounds`]).

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use super::adaptive;
use super::camera::Camera;
use super::film::{self, PixelSums, Tile};
use super::filter::GaussianFilter;
use super::integrator::{Integrator, RayCounts};
use super::splat::{self, Edge, SplatFilter};
use super::strategy::{Fixed, PixelSampling, PixelSource};
use super::{Frame, Placement, Region, RegionRender, RenderSettings, RenderStats};
use crate::shadow::ShadowMaps;

/// What every pixel of a render shares: the camera, where samples pass in a pixel, the integrator, the seed.
pub(super) struct Context<'f> {
    pub(super) camera: Camera,
    pub(super) placement: Placement,
    pub(super) integrator: Integrator<'f>,
    pub(super) seed: u32,
    /// Whether pixels take their samples through the wavefront (`integrator.shading = "lanes"`).
    pub(super) lanes: bool,
}

/// Renders `region` of `frame` with `settings` (and `maps` in deep-opacity mode) on the current rayon pool, in
/// work tiles of `tile_side`² pixels, each pixel sampled by `sampling` if given (else by the film's spp, or by the
/// image-level adaptive rule when the settings say so). Once `cancel` holds a non-zero value no new tile starts
/// (tiles already running finish).
#[allow(clippy::too_many_arguments)]
pub(super) fn render_tiles(
    frame: &Frame,
    settings: &RenderSettings,
    maps: Option<&ShadowMaps>,
    progress: bool,
    region: Region,
    cancel: Option<&AtomicUsize>,
    tile_side: u32,
    sampling: Option<&dyn PixelSampling>,
) -> RegionRender {
    let [width, height] = settings.film.resolution;
    let splat = settings
        .splats()
        .then(|| SplatFilter::new(settings.film.filter_width));
    let context = Context {
        camera: Camera::from_config(&settings.camera, frame.hair_bounds(), width, height),
        placement: match splat {
            Some(_) => Placement::Uniform,
            None => Placement::Importance(GaussianFilter::shared(settings.film.filter_width)),
        },
        integrator: Integrator::new(frame, settings, maps),
        seed: settings.film.seed,
        lanes: settings.integrator.lanes(),
    };

    let tiles_x = region.width().div_ceil(tile_side);
    let tiles_y = region.height().div_ceil(tile_side);
    let bar = progress_bar(progress, u64::from(tiles_x * tiles_y));
    let start = Instant::now();
    let tiles: Vec<(u32, u32)> = (0..tiles_y)
        .flat_map(|ty| (0..tiles_x).map(move |tx| (tx, ty)))
        .collect();
    // Whether the film keeps a centre-ray layer: decided once, not per pixel.
    let centre_ray = settings.film.traces_centre_ray();
    let centre = |x: u32, y: u32, pixel: &mut [f32], counts: &mut RayCounts| {
        if centre_ray {
            write_centre(frame, &context.camera, x, y, pixel, counts);
        }
    };
    let layout = film::Layout::new(&settings.film);
    let summed = splat::Summed::new(&layout);
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
    let pixel_by_pixel = |strategy: &dyn PixelSampling| -> Vec<Rendered> {
        tiles
            .par_iter()
            .map_init(splat::Scratch::default, |scratch, &(tx, ty)| {
                if cancelled() {
                    return None;
                }
                let mut tile = new_tile(tx, ty);
                let mut counts = RayCounts::default();
                let mut edges = Vec::new();
                if let Some(filter) = splat {
                    let counts = std::cell::RefCell::new(&mut counts);
                    edges = splat::render_tile(
                        scratch,
                        &mut tile,
                        region,
                        [width, height],
                        filter,
                        &summed,
                        |x, y, sums| {
                            let mut counts = counts.borrow_mut();
                            let mut source = PixelSource::new(x, y, &context, &mut counts);
                            strategy.take(&mut source, sums)
                        },
                        |x, y, taken, pixel| {
                            pixel[film::channel("spp")] = taken as f32;
                            centre(x, y, pixel, &mut counts.borrow_mut());
                        },
                    );
                } else {
                    for y in tile.y0..tile.y1 {
                        for x in tile.x0..tile.x1 {
                            let mut sums = PixelSums::default();
                            let mut source = PixelSource::new(x, y, &context, &mut counts);
                            let taken = strategy.take(&mut source, &mut sums);
                            tile.set_pixel(x, y, |pixel| {
                                sums.write(taken, pixel);
                                centre(x, y, pixel, &mut counts);
                            });
                        }
                    }
                }
                bar.inc(1);
                Some((tile, counts, edges))
            })
            .flatten()
            .collect()
    };
    let rendered = match (sampling, settings.adaptive) {
        (Some(strategy), _) => (pixel_by_pixel(strategy), None),
        (None, Some(schedule)) => {
            let sample = |x: u32, y: u32, samples, counts: &mut RayCounts, sink: adaptive::Sink| {
                PixelSource::new(x, y, &context, counts).take(samples, sink)
            };
            let splatting = splat.map(|filter| adaptive::Splatting {
                filter,
                summed: &summed,
                shares: filter.noise_shares([width, height]),
                size: [width, height],
            });
            adaptive::render_rounds(
                &tiles,
                region,
                schedule,
                splatting.as_ref(),
                &bar,
                &new_tile,
                &sample,
                &centre,
                &cancelled,
            )
        }
        (None, None) => (
            pixel_by_pixel(&Fixed {
                spp: settings.film.spp,
            }),
            None,
        ),
    };
    bar.finish_and_clear();
    assemble(
        rendered,
        region,
        (&layout, &summed),
        start,
        tiles_x * tiles_y,
    )
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

/// The centre-ray channels of pixel (x, y): depth, tangent and strand id of one unfiltered camera ray (depth of
/// the nearest surface, hair or shape; tangent and id of the hair it sees, none behind a shape).
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
    // A shape in front of the hair (a head, a wall) hides it: its depth, no tangent and no strand.
    let shape = frame
        .shapes
        .intersect(&centre, hit.map_or(centre.tfar, |h| h.t));
    let (depth, tangent, id) = match (shape, hit) {
        (Some(s), _) => (s.t * centre.dir.dot(camera.forward), Vec3::ZERO, -1.0),
        (None, Some(h)) => (
            h.t * centre.dir.dot(camera.forward),
            frame
                .strands
                .eval(h.segment, h.u)
                .tangent
                .normalize_or_zero(),
            h.strand as f32,
        ),
        (None, None) => (f32::INFINITY, Vec3::ZERO, -1.0),
    };
    film::write_centre(depth, tangent, id, pixel);
}

/// A rendered work tile: its pixels, its rays, and the splats it gave pixels it could not finish.
pub(super) type Rendered = (Tile, RayCounts, Vec<Edge>);

/// The rendered tiles as the region's image (splatted pixels across tiles finished), with the render's counters.
fn assemble(
    (rendered, noise): (Vec<Rendered>, Option<adaptive::NoiseEstimate>),
    region: Region,
    (layout, summed): (&film::Layout, &splat::Summed),
    start: Instant,
    tiles_total: u32,
) -> RegionRender {
    let mut rays = RayCounts::default();
    for (_, counts, _) in &rendered {
        rays.add(counts);
    }
    let tiles_done = rendered.len();
    let done: Vec<Region> = rendered
        .iter()
        .map(|(t, _, _)| Region {
            x0: t.x0,
            y0: t.y0,
            x1: t.x1,
            y1: t.y1,
        })
        .collect();
    let mut edges = Vec::new();
    // Tiles were rendered in frame coordinates; the image holds the region alone.
    let tiles: Vec<Tile> = rendered
        .into_iter()
        .map(|(mut t, _, e)| {
            edges.extend(e);
            (t.x0, t.x1, t.y0, t.y1) = (
                t.x0 - region.x0,
                t.x1 - region.x0,
                t.y0 - region.y0,
                t.y1 - region.y0,
            );
            t
        })
        .collect();
    let mut image = film::assemble(region.width(), region.height(), &tiles, layout);
    splat::finish_edges(&mut image, region, layout, summed, edges, &done);
    RegionRender {
        image,
        stats: RenderStats {
            seconds: start.elapsed().as_secs_f64(),
            rays,
            shadow_build_seconds: 0.0,
            shadow_map_bytes: 0,
            noise,
        },
        tiles_done,
        tiles_total: tiles_total as usize,
    }
}
