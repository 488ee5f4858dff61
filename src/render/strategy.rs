//! Sampling strategies: how many camera samples one pixel takes, and in what batches. The tile driver
//! ([`super::driver`]) calls one for every pixel of a tile: a fixed count (the film's spp) unless a
//! [`super::Request`] brings its own ([`super::Request::sampling`]). The image-level adaptive rule, which decides
//! between rounds from the whole region, runs its own rounds over the same tiles
//! ([`super::adaptive::render_rounds`]).

use super::camera_ray;
use super::driver::Context;
use super::film::PixelSums;
use super::integrator::{PathSample, RayCounts};
use super::sampler::{CameraSample, PixelSampler};
use crate::bsdf::lanes::LANES;
use crate::ray::Ray;

/// A pixel-by-pixel sampling strategy: takes the samples of one pixel from `source`, indices 0, 1, 2, … in order,
/// adds each to `sums` and returns how many it took. A strategy whose decisions depend on the pixel's own samples
/// alone keeps the image independent of the thread count and the tile split.
pub trait PixelSampling: Sync {
    /// Takes the pixel's samples; returns how many.
    fn take(&self, source: &mut PixelSource<'_>, sums: &mut PixelSums) -> u32;
}

/// One pixel's camera samples, as a strategy draws them; their rays are counted in the render's statistics.
pub struct PixelSource<'s> {
    x: u32,
    y: u32,
    pixel: PixelSampler,
    context: &'s Context<'s>,
    counts: &'s mut RayCounts,
}

impl<'s> PixelSource<'s> {
    pub(super) fn new(x: u32, y: u32, context: &'s Context<'s>, counts: &'s mut RayCounts) -> Self {
        PixelSource {
            x,
            y,
            pixel: PixelSampler::new(x, y, context.seed),
            context,
            counts,
        }
    }

    /// The pixel's camera sample `i`.
    pub fn sample(&mut self, i: u32) -> PathSample {
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

/// A fixed count per pixel (the film's spp); with `lanes`, the first vertices of eight samples at a time
/// (`integrator.shading = "lanes"`, `docs/design/wavefront.md` step 2), the rest one by one.
pub(super) struct Fixed {
    pub spp: u32,
    pub lanes: bool,
}

impl PixelSampling for Fixed {
    fn take(&self, source: &mut PixelSource<'_>, sums: &mut PixelSums) -> u32 {
        let mut i = 0;
        if self.lanes {
            while i + LANES as u32 <= self.spp {
                for s in source.sample_lanes(i) {
                    sums.add(&s);
                }
                i += LANES as u32;
            }
        }
        for i in i..self.spp {
            sums.add(&source.sample(i));
        }
        self.spp
    }
}
