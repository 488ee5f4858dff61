//! Sampling strategies: how many camera samples one pixel takes, and in what batches. The tile driver
//! ([`super::driver`]) calls one for every pixel of a tile: a fixed count (the film's spp) unless a
//! [`super::Request`] brings its own ([`super::Request::sampling`]). The image-level adaptive rule, which decides
//! between rounds from the whole region, runs its own rounds over the same tiles
//! ([`super::adaptive::render_rounds`]).

use super::camera_ray;
use super::driver::Context;
use super::film::Accumulate;
use super::integrator::{PathSample, RayCounts};
use super::sampler::{CameraSample, PixelSampler};
use super::wavefront;
use std::cell::Cell;
use std::ops::Range;

/// A pixel-by-pixel sampling strategy: takes the samples of one pixel from `source`, indices 0, 1, 2, … in order,
/// adds each to `sums` (the pixel's own sums, or its splats) and returns how many it took. A strategy whose decisions depend on the pixel's own samples
/// alone keeps the image independent of the thread count and the tile split.
pub trait PixelSampling: Sync {
    /// Takes the pixel's samples; returns how many.
    fn take(&self, source: &mut PixelSource<'_>, sums: &mut dyn Accumulate) -> u32;
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
        let (ray, film) = camera_ray(&c.camera, &c.placement, &sampler, self.x, self.y, i);
        let mut s = c.integrator.sample(&ray, &sampler, i, self.counts);
        s.film = film;
        s
    }

    /// The pixel's camera samples `samples`, each handed to `sink` in index order with the rays it traced: eight
    /// paths at a time through the wavefront ([`super::wavefront`]) under `integrator.shading = "lanes"`, else one
    /// by one through the scalar path; the same values either way.
    pub fn take(
        &mut self,
        samples: Range<u32>,
        mut sink: impl FnMut(u32, &PathSample, &RayCounts),
    ) {
        let c = self.context;
        if !c.lanes {
            for i in samples {
                let before = *self.counts;
                let s = self.sample(i);
                sink(i, &s, &self.counts.since(&before));
            }
            return;
        }
        let (x, y) = (self.x, self.y);
        let counts = &mut *self.counts;
        // Where each sample in flight passed in the pixel, by index modulo the ring: at most `wavefront::RING`
        // samples are started and not yet handed on.
        let film: [Cell<[f32; 2]>; FILM_RING] = std::array::from_fn(|_| Cell::new([0.0; 2]));
        wavefront::run(
            &c.integrator,
            &self.pixel,
            samples,
            |sampler, i| {
                let (ray, at) = camera_ray(&c.camera, &c.placement, sampler, x, y, i);
                film[i as usize % FILM_RING].set(at);
                ray
            },
            |i, s, rays, _: &()| {
                counts.add(rays);
                let mut s = *s;
                s.film = film[i as usize % FILM_RING].get();
                sink(i, &s, rays);
            },
        );
    }
}

/// Film positions a wavefront pixel keeps ([`PixelSource::take`]): more than the samples it has in flight.
const FILM_RING: usize = 64;
const _: () = assert!(wavefront::RING + crate::bsdf::lanes::LANES <= FILM_RING);

/// A fixed count per pixel (the film's spp).
pub(super) struct Fixed {
    pub spp: u32,
}

impl PixelSampling for Fixed {
    fn take(&self, source: &mut PixelSource<'_>, sums: &mut dyn Accumulate) -> u32 {
        source.take(0..self.spp, |_, s, _| sums.add(s));
        self.spp
    }
}
