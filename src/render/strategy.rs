//! Sampling strategies: how many camera samples one pixel takes, and in what batches. The tile driver
//! ([`super::driver`]) calls one for every pixel of a tile; the image-level adaptive rule, which decides between
//! rounds from the whole region, runs its own rounds over the same tiles ([`super::adaptive::render_rounds`]).

use super::adaptive::{Convergence, Schedule};
use super::driver::PixelSource;
use super::film::PixelSums;
use crate::bsdf::chiang::LANES;

/// A pixel-by-pixel strategy: takes the samples of one pixel from `source`, indices 0, 1, 2, … in order, adds
/// each to `sums` and returns how many it took. Every decision depends on the pixel's own samples, so the image
/// does not depend on the thread count or the tile split.
pub(super) trait PixelStrategy: Sync {
    fn take(&self, source: &mut PixelSource<'_>, sums: &mut PixelSums) -> u32;
}

/// A fixed count per pixel (the film's spp); with `lanes`, the first vertices of eight samples at a time
/// (`integrator.lanes`, `docs/design/wavefront.md` step 2), the rest one by one.
pub(super) struct Fixed {
    pub spp: u32,
    pub lanes: bool,
}

impl PixelStrategy for Fixed {
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

/// The per-pixel adaptive rule ([`super::adaptive::Rule::Pixel`]): rounds of samples, in index order, until the
/// pixel's own estimate of its error is under the target. It is the baseline the image-level rule is measured
/// against (unit tests on synthetic pixels and frame tests alike), so it is a strategy here rather than a copy in
/// each test.
pub(super) struct PerPixel {
    pub schedule: Schedule,
}

impl PixelStrategy for PerPixel {
    fn take(&self, source: &mut PixelSource<'_>, sums: &mut PixelSums) -> u32 {
        let mut convergence = Convergence::default();
        let mut i = 0;
        while let Some(total) = self.schedule.next_total(i, &convergence) {
            while i < total {
                let s = source.sample(i);
                if s.beauty.is_finite() {
                    convergence.add(s.beauty);
                }
                sums.add(&s);
                i += 1;
            }
        }
        i
    }
}
