//! The first vertices of the lanes in one round: their fibres' views taken in lanes, light choice and direction
//! drawn per lane as the scalar path draws them, f and the pdf at the light directions in lanes, the light samples
//! finished per lane (MIS weight, roulette, shadow ray), the material samples drawn in lanes and finished per lane
//! (their rays, the second vertex). A lane on another surface is shaded alone, as on the scalar path.

use glam::Vec3;
use wide::f32x8;

use crate::bsdf::frame::HairFrame;
use crate::bsdf::lanes::{directions, LANES};
use crate::bsdf::{LobeValues, PreparedLanes};
use crate::light::LightSample;

use super::super::integrator::{fcos, BounceRecorder, Draw, Integrator, Surface, Vertex};
use super::super::sampler::{dim, CameraSample};
use super::{Lanes, Stage};

/// A lane on a fibre: its vertex, hair frame and diffuse tint.
pub(super) type OnFibre<'v, 'a> = Option<(&'v Vertex<'a>, HairFrame, Vec3)>;

/// The lanes' fibre vertices among `vertices`, with the fibres' views prepared in lanes (empty lanes take h = 0
/// and ωo across the fibre, their results unused); `None` if no lane is on a fibre.
pub(super) fn fibres<'v, 'a>(
    integrator: &Integrator<'a>,
    vertices: [Option<&'v Vertex<'a>>; LANES],
) -> Option<([OnFibre<'v, 'a>; LANES], PreparedLanes<'a>)> {
    let lanes: [OnFibre; LANES] = vertices.map(|v| match v?.surface {
        Surface::Hair { frame, tint, .. } => Some((v?, frame, tint)),
        Surface::Lambert { .. } => None,
    });
    if lanes.iter().all(Option::is_none) {
        return None;
    }
    let h = f32x8::new(vertices.map(|v| match v.map(|v| v.surface) {
        Some(Surface::Hair { h, .. }) => h,
        _ => 0.0,
    }));
    let wo_l: [Vec3; LANES] =
        lanes.map(|l| l.map_or(Vec3::Y, |(v, frame, _)| frame.to_local(v.wo)));
    let views = integrator.material.prepare_lanes(h, directions(&wo_l));
    Some((lanes, views))
}

/// The first vertices' state shared by their steps: the lanes on fibres, their views, each lane's draws.
struct Batch<'l, 's, 'a> {
    lanes: [OnFibre<'l, 'a>; LANES],
    views: PreparedLanes<'a>,
    samplers: &'s [CameraSample<'s>; LANES],
    indices: &'l [u32; LANES],
}

impl<'s> Batch<'_, 's, '_> {
    /// Lane `k`'s draw of sample `s` of `n` per camera sample, with `salt`, as the scalar path numbers them.
    #[inline]
    fn draw(&self, k: usize, n: u32, s: u32, salt: u32) -> Draw<'s> {
        Draw {
            sampler: &self.samplers[k],
            index: self.indices[k] * n + s,
            salt,
        }
    }
}

impl<'a> Integrator<'a> {
    /// The lanes at their first vertex ([`Stage::First`]): shaded as [`Integrator::sample`]'s steps 2–3, each lane's
    /// values and rays the scalar path's bit for bit, then on to the second vertex or done.
    pub(super) fn first_vertices<R: BounceRecorder + Default>(&self, l: &mut Lanes<'_, 'a, R>) {
        let vertices = l.stage.each_ref().map(|s| match s {
            Stage::First(v) => Some(v),
            _ => None,
        });
        if vertices.iter().all(Option::is_none) {
            return;
        }
        let mut next: [Option<(Vertex<'a>, LobeValues)>; LANES] = [None; LANES];
        if let Some((lanes, views)) = fibres(self, vertices) {
            let batch = Batch {
                lanes,
                views,
                samplers: &l.sampler,
                indices: &l.index,
            };
            self.light_samples_lanes(&batch, &mut l.out, &mut l.counts);
            self.material_samples_lanes(&batch, &mut l.out, &mut l.counts, &mut next);
        }
        // A lane on another surface: shaded alone, as `sample` does.
        for (k, v) in vertices.iter().enumerate() {
            if let Some(
                v @ Vertex {
                    surface: Surface::Lambert { .. },
                    ..
                },
            ) = v
            {
                let (sampler, index) = (&l.sampler[k], l.index[k]);
                let (out, counts) = (&mut l.out[k], &mut l.counts[k]);
                self.first_vertex_light_samples(v, sampler, index, out, counts);
                next[k] = self.first_vertex_material_samples(v, sampler, index, out, counts);
            }
        }
        let at_first = vertices.map(|v| v.is_some());
        for (k, _) in at_first.iter().enumerate().filter(|(_, &f)| f) {
            l.first_done(k, next[k]);
        }
    }

    /// The first vertices' light samples in the scalar path's order ([`Integrator::shade_first`]'s step 2): per
    /// light under `lights = "all"`, per sample with its light choice under `lights = "one"`.
    fn light_samples_lanes(
        &self,
        batch: &Batch,
        outs: &mut [super::PathSample; LANES],
        counts: &mut [super::RayCounts; LANES],
    ) {
        self.first_light_slots(|n, s, salt, light| {
            let choose = |k: usize| {
                let draw = batch.draw(k, n, s, salt);
                let (j, count) = light.or_else(|| self.choose_first_light(draw))?;
                Some((j, count, draw))
            };
            self.light_slot_lanes(batch, choose, outs, counts);
        });
    }

    /// One light sample per lane on a fibre: `choose` gives lane k's light, its expected sample count and its
    /// draw (or nothing); directions per lane, f and the pdf in lanes, the rest per lane.
    fn light_slot_lanes<'s>(
        &self,
        batch: &Batch<'_, 's, '_>,
        choose: impl Fn(usize) -> Option<(usize, f32, Draw<'s>)>,
        outs: &mut [super::PathSample; LANES],
        counts: &mut [super::RayCounts; LANES],
    ) {
        let light: [Option<(usize, f32, Draw, LightSample)>; LANES] = std::array::from_fn(|k| {
            let (v, ..) = batch.lanes[k]?;
            let (j, count, draw) = choose(k)?;
            let ls = self.first_vertex_light_draw(v, j, draw)?;
            Some((j, count, draw, ls))
        });
        if light.iter().all(Option::is_none) {
            return;
        }
        let wi_l: [Vec3; LANES] = std::array::from_fn(|k| match (&batch.lanes[k], &light[k]) {
            (Some((_, frame, _)), Some((.., ls))) => frame.to_local(ls.wi),
            _ => Vec3::X,
        });
        let evals = batch.views.eval(directions(&wi_l));
        for k in 0..LANES {
            if let (Some((v, _, tint)), Some((j, count, draw, ls))) = (&batch.lanes[k], &light[k]) {
                let (lobes, pdf) = evals.lane(k);
                let fcos = fcos(lobes, *tint, wi_l[k]);
                self.first_vertex_light_finish(
                    v,
                    *j,
                    *count,
                    *draw,
                    ls,
                    fcos,
                    pdf,
                    &mut outs[k],
                    &mut counts[k],
                );
            }
        }
    }

    /// The first vertices' material samples, drawn in lanes and finished per lane; the second vertices (views not
    /// prepared: the deeper lanes take them) into `next`.
    fn material_samples_lanes(
        &self,
        batch: &Batch,
        outs: &mut [super::PathSample; LANES],
        counts: &mut [super::RayCounts; LANES],
        next: &mut [Option<(Vertex<'a>, LobeValues)>; LANES],
    ) {
        let n_m = self.first.material_samples;
        let d = dim::vertex(0, dim::MATERIAL);
        for s in 0..n_m {
            let u: [[f32; 3]; LANES] = std::array::from_fn(|k| match batch.lanes[k] {
                Some(_) => batch.draw(k, n_m, s, 0).get_3(d),
                None => [0.5; 3],
            });
            let drawn = batch
                .views
                .sample(std::array::from_fn(|c| f32x8::new(u.map(|u| u[c]))));
            for (k, lane) in batch.lanes.iter().enumerate() {
                let Some((v, frame, tint)) = lane else {
                    continue;
                };
                let (lobes, pdf) = drawn.eval.lane(k);
                if pdf > 0.0 && pdf.is_finite() {
                    let wi_l = drawn.wi(k);
                    let sample = (
                        frame.to_world(wi_l).normalize(),
                        fcos(lobes, *tint, wi_l),
                        pdf,
                    );
                    let draw = batch.draw(k, n_m, s, 0);
                    self.first_vertex_material_finish(
                        v,
                        s,
                        draw,
                        sample,
                        &mut outs[k],
                        &mut counts[k],
                        &mut next[k],
                        false,
                    );
                }
            }
        }
    }
}
