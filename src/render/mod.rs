//! Rendering a frame: camera rays over tiles in parallel (rayon), the path tracer of [`integrator`] at each
//! camera sample, a Gaussian pixel filter, and the [`film`] with beauty and AOV channels.
//!
//! A [`Frame`] ([`frame`]) holds what a render needs, built once; [`settings`] holds what a render runs with.
//!
//! **Determinism**: every pixel depends only on its own sample streams ([`sampler::PixelSampler`], keyed by
//! pixel and seed, and the per-ray keys derived from them) and sums its samples in a fixed order; tiles only decide
//! which thread does the work. The same scene and seed give bit-identical pixels with any thread count. With
//! adaptive sampling's image-level rule ([`adaptive`]) how many samples a pixel takes is decided
//! between rounds from all the region's pixels, in row-major order: still the same for any thread count and work
//! tile size, but a `--crop`/`--tile` region decides from its own pixels (see [`adaptive`]).

pub mod adaptive;
pub mod budget;
pub mod camera;
mod driver;
pub mod film;
pub mod filter;
pub mod frame;
pub mod integrator;
pub mod sampler;
pub mod settings;
pub mod splat;
pub mod strategy;
pub mod tiles;
mod wavefront;

use std::sync::atomic::AtomicUsize;
use std::sync::Arc;

use glam::Vec3;

use crate::image::Image;
use crate::ray::Ray;
use crate::shadow::ShadowMaps;

use camera::Camera;
use filter::GaussianFilter;
use integrator::{Integrator, PathSample, RayCounts};
use sampler::{dim, CameraSample, PixelSampler};

pub use film::CHANNELS;
pub use frame::{thread_pool, Frame, FrameError, FrameSpec, ThreadPoolError};
pub use settings::{
    FilmConfig, IntegratorConfig, LightSelection, MultipleScattering, Reconstruction,
    RenderSettings, Shading, ShadowConfig, ShadowMode, Strategy, TransmittanceMode,
};
pub use strategy::{PixelSampling, PixelSource};
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
    /// Under adaptive sampling, the noise the region delivered as the stop read it after the last round.
    pub noise: Option<adaptive::NoiseEstimate>,
}

/// What to render of a [`Frame`] ([`Frame::render`]): the settings, and optionally deep opacity maps built
/// beforehand, a region of the film, a cancel flag, a progress bar, the work tiles' size. Built from
/// [`Request::new`] and the setters; everything not set has the whole-film default.
#[derive(Clone, Copy)]
pub struct Request<'a> {
    pub(crate) settings: &'a RenderSettings,
    pub(crate) maps: Option<(&'a ShadowMaps, f64)>,
    pub(crate) region: Option<Region>,
    pub(crate) cancel: Option<&'a AtomicUsize>,
    pub(crate) progress: bool,
    pub(crate) tile_side: u32,
    pub(crate) sampling: Option<&'a dyn PixelSampling>,
}

impl<'a> Request<'a> {
    /// The whole film at `settings`, maps built when the settings use them, no progress bar.
    pub fn new(settings: &'a RenderSettings) -> Self {
        Request {
            settings,
            maps: None,
            region: None,
            cancel: None,
            progress: false,
            tile_side: TILE,
            sampling: None,
        }
    }

    /// Deep opacity maps built beforehand (e.g. also written to disk, or shared by several renders), whose build
    /// took `build_seconds`; `None` leaves them to the render. Used only in deep-opacity mode.
    pub fn maps(mut self, maps: Option<&'a ShadowMaps>, build_seconds: f64) -> Self {
        self.maps = maps.map(|m| (m, build_seconds));
        self
    }

    /// Only `region` of the film (inside `settings.film.resolution`): its pixels equal the full frame's there, bit
    /// for bit, except under adaptive sampling's image-level rule, where a region decides its sample counts from
    /// its own pixels and meets the target by itself ([`adaptive`]).
    pub fn region(mut self, region: Region) -> Self {
        self.region = Some(region);
        self
    }

    /// Stop early once `cancel` holds a non-zero value: tiles not yet started are left at zero and
    /// [`RegionRender::is_complete`] is false.
    pub fn cancel(mut self, cancel: &'a AtomicUsize) -> Self {
        self.cancel = Some(cancel);
        self
    }

    /// Show a progress bar on stderr.
    pub fn progress(mut self, show: bool) -> Self {
        self.progress = show;
        self
    }

    /// Each pixel's samples taken by `sampling` instead of the film's spp or the settings' adaptive rule: a
    /// strategy of the caller's own (the tests run the per-pixel adaptive rule this way).
    pub fn sampling(mut self, sampling: &'a dyn PixelSampling) -> Self {
        self.sampling = Some(sampling);
        self
    }

    /// Work tiles of `side`² pixels instead of 32²: the image does not depend on it (tests check that).
    pub fn tile_side(mut self, side: u32) -> Self {
        self.tile_side = side.max(1);
        self
    }
}

/// What [`Frame::render`] made: the region's pixels and how many of its tiles were rendered.
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

/// Where a pixel's camera samples pass through it: drawn from the pixel filter (filter importance sampling) or
/// uniform in the pixel (a splatting film, [`splat`], weighs them by the filter afterwards).
#[derive(Clone)]
pub(super) enum Placement {
    /// Offsets from the pixel's centre drawn from the filter.
    Importance(Arc<GaussianFilter>),
    /// Uniform in the pixel.
    Uniform,
}

/// Sample `i`'s camera ray through pixel (x, y), and where it passes in the pixel (from its top-left corner):
/// placed by `placement` from `sampler`'s filter dimensions. The frame ([`driver`]) and the pilots' cut renders
/// ([`render_bounces`]) trace the same rays.
fn camera_ray(
    camera: &Camera,
    placement: &Placement,
    sampler: &CameraSample,
    x: u32,
    y: u32,
    i: u32,
) -> (Ray, [f32; 2]) {
    let u = sampler.get_2d(i, dim::FILTER);
    match placement {
        Placement::Importance(filter) => {
            let (dx, dy) = filter.sample(u);
            (
                camera.ray(x as f32 + 0.5 + dx, y as f32 + 0.5 + dy),
                [0.5 + dx, 0.5 + dy],
            )
        }
        Placement::Uniform => (camera.ray(x as f32 + u.0, y as f32 + u.1), [u.0, u.1]),
    }
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
    #[derive(Default)]
    struct Vertices {
        radiance: [Vec3; integrator::MAX_PATH_LENGTH as usize + 1],
        rays: [RayCounts; integrator::MAX_PATH_LENGTH as usize + 1],
    }
    impl integrator::BounceRecorder for Vertices {
        #[inline]
        fn vertex(&mut self, b: u32, radiance: Vec3, rays: &RayCounts) {
            // A tail's vertices past the longest path length add to the last cut.
            let b = (b as usize).min(integrator::MAX_PATH_LENGTH as usize);
            self.radiance[b] += radiance;
            self.rays[b].add(rays);
        }
    }
    let [width, height] = settings.film.resolution;
    let maps = maps.filter(|_| settings.shadows.mode == ShadowMode::DeepOpacity);
    let camera = Camera::from_config(&settings.camera, frame.hair_bounds(), width, height);
    // The pilots read each pixel's own samples, as filter importance sampling makes them.
    let placement = Placement::Importance(GaussianFilter::shared(settings.film.filter_width));
    let integrator = Integrator::new(frame, settings, maps);
    let lanes = settings.integrator.lanes();
    let lengths = settings.integrator.path_length as usize + 1;
    let mut pixels = vec![Vec::with_capacity((region.width() * region.height()) as usize); lengths];
    let mut variances = pixels.clone();
    // Every sample's rays by vertex.
    let mut rays = vec![RayCounts::default(); lengths];
    for y in region.y0..region.y1 {
        for x in region.x0..region.x1 {
            let pixel = PixelSampler::new(x, y, settings.film.seed);
            // Σx and Σx² of each cut, in f64.
            let mut sums = vec![[[0.0f64; 3]; 2]; lengths];
            let mut kept = 0u32;
            // The last cut holds every vertex from it on: a tail's deeper bounces belong to it.
            let last = lengths - 1;
            let mut add = |s: &PathSample, v: &Vertices| {
                for (b, r) in v.rays.iter().enumerate() {
                    rays[b.min(last)].add(r);
                }
                if !s.beauty.is_finite() {
                    return;
                }
                kept += 1;
                let mut prefix = Vec3::ZERO;
                for (b, [sum, squares]) in sums.iter_mut().enumerate() {
                    prefix += v.radiance[b];
                    if b == last {
                        prefix += v.radiance[lengths..].iter().copied().sum::<Vec3>();
                    }
                    for (c, x) in prefix.to_array().into_iter().enumerate() {
                        sum[c] += f64::from(x);
                        squares[c] += f64::from(x) * f64::from(x);
                    }
                }
            };
            let ray =
                |sampler: &CameraSample, i| camera_ray(&camera, &placement, sampler, x, y, i).0;
            if lanes {
                let samples = 0..settings.film.spp;
                wavefront::run(&integrator, &pixel, samples, ray, |_, s, _, v| add(s, v));
            } else {
                let mut counts = RayCounts::default();
                for i in 0..settings.film.spp {
                    let sampler = CameraSample::new(&pixel, i);
                    let mut v = Vertices::default();
                    let s = integrator.sample_recording(
                        &ray(&sampler, i),
                        &sampler,
                        i,
                        &mut counts,
                        &mut v,
                    );
                    add(&s, &v);
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
    for r in rays.iter_mut() {
        prefix.add(r);
        *r = prefix;
    }
    BounceRender {
        pixels,
        variances,
        rays,
    }
}
