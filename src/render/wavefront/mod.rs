//! The wavefront integrator: one pixel's camera samples as eight paths in flight, every path vertex shaded for the
//! eight together in f32×8 lanes, lanes that end refilled from the pixel's remaining samples (`docs/design/
//! wavefront.md`). Beside the scalar path integrator ([`super::integrator`]), not inside it: both run the same
//! halves of each vertex (the light sample's draw and finish, the material sample's finish, the step to the next
//! vertex), and only what lies between them — the prepared fibre, f and the pdf at the light directions, the
//! material samples — runs in lanes here. Every fibre model is one generic implementation whose functions are the
//! same on one lane and on eight ([`crate::util::real`]), so the two integrators give the same image bit for bit
//! (tested for every model, shadow mode and light selection); the scalar one stays the reference
//! (`integrator.shading = "scalar"`).
//!
//! # One round
//!
//! Each round: idle lanes take the next sample indices; lanes new to a sample trace their camera ray (one query
//! each) and either finish (background, emitter) or reach their first vertex; lanes at a first vertex shade it
//! together ([`first`]); lanes at a deeper vertex shade it together ([`deeper`]), whichever bounce each is at. A
//! lane whose path ends is refilled in the next round, so a lane ended early by Russian roulette or an escaped
//! ray does not idle while the others go on.
//!
//! # Order and determinism
//!
//! Each sample draws the same Sobol dimensions as on the scalar path and keeps its own ray counts and recorder, so
//! its result and its rays do not depend on which lane or round served it. Results reach the caller in sample
//! order (a ring of [`RING`] finished samples), so sums over a pixel's samples add in the same order as the
//! scalar path's: the same bits for any thread count and tile split.

mod deeper;
mod first;

use std::ops::Range;

use crate::bsdf::lanes::LANES;
use crate::ray::Ray;

use super::integrator::{
    end_first_vertex, end_path, BounceRecorder, Found, Integrator, PathSample, RayCounts, Vertex,
    Walk,
};
use super::sampler::{CameraSample, PixelSampler};

/// The most finished samples held back for order: a lane may start sample i only while sample i − `RING` has been
/// handed on. Deep enough that refills rarely wait (a path of the peer frame ends within two rounds), small enough
/// for the stack with a pilot's recorder per sample.
pub const RING: usize = 32;

/// Where a lane's path stands between rounds.
// A vertex carries its prepared fibre (a few hundred bytes): the lanes' stages live in one array per render call,
// and boxing them would allocate per vertex.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy)]
enum Stage<'a> {
    /// No sample: waits for the next.
    Idle,
    /// A new sample: its camera ray is next.
    Camera,
    /// At its first vertex.
    First(Vertex<'a>),
    /// At a deeper vertex (`walk.b`).
    Deeper(Vertex<'a>, Walk),
    /// Its path has ended; handed on at the end of the round.
    Done,
}

/// The eight lanes, as arrays by field so that a stage can read the lanes' vertices while it writes their
/// outputs and counts.
struct Lanes<'p, 'a, R> {
    stage: [Stage<'a>; LANES],
    /// Each lane's sample index and its Sobol draws.
    index: [u32; LANES],
    sampler: [CameraSample<'p>; LANES],
    out: [PathSample; LANES],
    /// The rays each lane's current sample traced.
    counts: [RayCounts; LANES],
    record: [R; LANES],
}

/// One finished sample waiting in the ring.
struct Finished<R> {
    out: PathSample,
    counts: RayCounts,
    record: R,
}

/// Traces samples `samples` of `pixel` through `integrator` in lanes, the camera ray of sample i being `ray(&draws,
/// i)`, and hands each to `sink` in index order: (its index, its result, the rays it traced, what it reported to
/// its own recorder, a fresh `R::default()` per sample).
pub fn run<R: BounceRecorder + Default>(
    integrator: &Integrator<'_>,
    pixel: &PixelSampler,
    samples: Range<u32>,
    ray: impl Fn(&CameraSample, u32) -> Ray,
    mut sink: impl FnMut(u32, &PathSample, &RayCounts, &R),
) {
    let mut lanes = Lanes {
        stage: [Stage::Idle; LANES],
        index: [0; LANES],
        sampler: std::array::from_fn(|_| CameraSample::new(pixel, samples.start)),
        out: [PathSample::default(); LANES],
        counts: [RayCounts::default(); LANES],
        record: std::array::from_fn(|_| R::default()),
    };
    let mut ring: [Option<Finished<R>>; RING] = std::array::from_fn(|_| None);
    let (mut issued, mut handed) = (samples.start, samples.start);
    loop {
        for k in 0..LANES {
            if matches!(lanes.stage[k], Stage::Idle)
                && issued < samples.end
                && issued < handed + RING as u32
            {
                lanes.start(k, pixel, issued);
                issued += 1;
            }
        }
        if lanes.stage.iter().all(|s| matches!(s, Stage::Idle)) {
            break;
        }
        lanes.cameras(integrator, &ray);
        integrator.first_vertices(&mut lanes);
        integrator.deeper_vertices(&mut lanes);
        for k in 0..LANES {
            if !matches!(lanes.stage[k], Stage::Done) {
                continue;
            }
            lanes.stage[k] = Stage::Idle;
            let index = lanes.index[k];
            if index == handed {
                // The next in order (most samples): handed on at once, without a stay in the ring.
                sink(index, &lanes.out[k], &lanes.counts[k], &lanes.record[k]);
                handed += 1;
            } else {
                ring[index as usize % RING] = Some(Finished {
                    out: lanes.out[k],
                    counts: lanes.counts[k],
                    record: std::mem::take(&mut lanes.record[k]),
                });
            }
            while let Some(f) = ring[handed as usize % RING].take() {
                sink(handed, &f.out, &f.counts, &f.record);
                handed += 1;
            }
        }
    }
}

impl<'p, 'a, R: BounceRecorder + Default> Lanes<'p, 'a, R> {
    /// Lane `k` takes sample `index` of `pixel`.
    fn start(&mut self, k: usize, pixel: &'p PixelSampler, index: u32) {
        self.stage[k] = Stage::Camera;
        self.index[k] = index;
        self.sampler[k] = CameraSample::new(pixel, index);
        self.out[k] = PathSample::default();
        self.counts[k] = RayCounts::default();
        self.record[k] = R::default();
    }

    /// The camera rays of the lanes new to a sample, one query each: a lane that finds no surface is done (it sees
    /// an emitter or the background, as [`Integrator::sample`]'s step 1), the others are at their first vertex
    /// (their fibres' views left to the lanes).
    fn cameras(&mut self, integrator: &Integrator<'a>, ray: &impl Fn(&CameraSample, u32) -> Ray) {
        for k in 0..LANES {
            if !matches!(self.stage[k], Stage::Camera) {
                continue;
            }
            let r = ray(&self.sampler[k], self.index[k]);
            let counts = &mut self.counts[k];
            counts.camera += 1;
            match integrator.find_with(&r, None, counts, false) {
                Found::Surface(v) => {
                    self.out[k].alpha = 1.0;
                    self.stage[k] = Stage::First(v);
                }
                other => {
                    self.out[k] = integrator.seen_directly(&r, &other);
                    self.record[k].vertex(0, self.out[k].beauty, counts);
                    self.stage[k] = Stage::Done;
                }
            }
        }
    }

    /// Lane `k`'s first vertex is shaded: the direct pass; the path goes on from `next` (the second vertex and the
    /// first vertex's weights) or ends.
    fn first_done(&mut self, k: usize, next: Option<(Vertex<'a>, crate::bsdf::LobeValues)>) {
        end_first_vertex(&mut self.out[k], &self.counts[k], &mut self.record[k]);
        self.stage[k] = match next {
            Some((second, weights)) => Stage::Deeper(second, Walk::new(weights)),
            None => {
                end_path(&mut self.out[k], None);
                Stage::Done
            }
        };
    }
}
