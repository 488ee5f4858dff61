//! The eight-lane path of the first vertex ([`Integrator::sample_lanes`], steps 1–2 of `docs/design/wavefront.md`):
//! a batch of camera samples whose first vertices are shaded one f32×8 vector at a time through the material's
//! lane form ([`crate::bsdf::PreparedLanes`]); apart from the scalar path it reproduces bit for bit.

use glam::Vec3;
use wide::f32x8;

use crate::bsdf::frame::HairFrame;
use crate::bsdf::lanes::{directions, LANES};
use crate::bsdf::PreparedLanes;
use crate::light::LightSample;
use crate::ray::Ray;

use super::super::sampler::{dim, CameraSample};
use super::super::settings::LightSelection;
use super::trace::Found;
use super::{fcos, Draw, Integrator, PathSample, RayCounts, Surface, Vertex};

/// A lane on a fibre: its vertex, hair frame and diffuse tint.
type OnFibre<'v, 'a> = Option<(&'v Vertex<'a>, HairFrame, Vec3)>;

impl<'a> Integrator<'a> {
    /// [`Integrator::sample`] of eight camera samples (`rays[k]` with `samplers[k]`, sample `indices[k]`), their
    /// first vertices shaded together where they are on fibres: the light samples' f and pdf by
    /// [`PreparedLanes::eval`], the material samples by [`PreparedLanes::sample`], everything else (light choice,
    /// rays, MIS, the deeper vertices) per sample as [`Integrator::sample`] does it, in the same order, so that each
    /// lane's result is the scalar path's bit for bit.
    pub fn sample_lanes(
        &self,
        rays: &[Ray; LANES],
        samplers: &[CameraSample; LANES],
        indices: &[u32; LANES],
        counts: &mut RayCounts,
    ) -> [PathSample; LANES] {
        let found: [Found; LANES] = std::array::from_fn(|k| {
            counts.camera += 1;
            self.find_with(&rays[k], None, counts, false)
        });
        let mut outs: [PathSample; LANES] = std::array::from_fn(|k| match &found[k] {
            Found::Surface(_) => PathSample {
                alpha: 1.0,
                ..PathSample::default()
            },
            other => self.seen_directly(&rays[k], other),
        });
        let on_fibre = |k: usize| match &found[k] {
            Found::Surface(v) => match &v.surface {
                Surface::Hair { frame, tint, .. } => Some((v, *frame, *tint)),
                _ => None,
            },
            _ => None,
        };
        let lanes: [OnFibre; LANES] = std::array::from_fn(on_fibre);
        if lanes.iter().any(Option::is_some) {
            // The views in lanes (empty lanes take h = 0 and ωo across the fibre, their results unused).
            let h = f32x8::new(std::array::from_fn(|k| match &found[k] {
                Found::Surface(v) => match v.surface {
                    Surface::Hair { h, .. } => h,
                    _ => 0.0,
                },
                _ => 0.0,
            }));
            let wo_l: [Vec3; LANES] =
                lanes.map(|l| l.map_or(Vec3::Y, |(v, frame, _)| frame.to_local(v.wo)));
            let views = self.material.prepare_lanes(h, directions(&wo_l));
            let batch = Batch {
                lanes: &lanes,
                views: &views,
                samplers,
                indices,
            };
            self.light_samples_lanes(&batch, &mut outs, counts);
            self.material_samples_lanes(&batch, &mut outs, counts);
        }
        // A lane on another surface: shaded alone, as `sample` does.
        for (k, out) in outs.iter_mut().enumerate() {
            if let (Found::Surface(v), None) = (&found[k], &lanes[k]) {
                let before = *counts;
                self.shade_first(v, (&samplers[k], indices[k]), out, counts, &mut (), &before);
            }
        }
        outs
    }

    /// The first vertices' light samples in the scalar path's order ([`Integrator::shade_first`]'s step 2): per
    /// light under `lights = "all"`, per sample with its light choice under `lights = "one"`.
    fn light_samples_lanes(
        &self,
        batch: &Batch,
        outs: &mut [PathSample; LANES],
        counts: &mut RayCounts,
    ) {
        let mis = &self.first;
        match mis.selection {
            LightSelection::All => {
                for (j, light) in self.lights.iter().enumerate() {
                    let delta = light.is_delta();
                    if !mis.samples_light(delta) {
                        continue;
                    }
                    let samples = mis.samples_per_light(delta);
                    let count = mis.light_count(delta, 1.0);
                    for s in 0..samples {
                        let choose = |k: usize| {
                            let draw = batch.draw(k, samples, s, j as u32);
                            Some((j, count, draw))
                        };
                        self.light_slot_lanes(batch, choose, outs, counts);
                    }
                }
            }
            LightSelection::One if !self.lights.is_empty() => {
                let n_l = mis.light_samples;
                for s in 0..n_l {
                    let choose = |k: usize| {
                        let draw = batch.draw(k, n_l, s, 0);
                        let u_select = draw.get(dim::vertex(0, dim::LIGHT_SELECT));
                        let (j, p_select, _) = self.select.sample_discrete(u_select);
                        let delta = self.lights[j].is_delta();
                        if p_select <= 0.0 || !mis.samples_light(delta) {
                            return None;
                        }
                        Some((j, mis.light_count(delta, p_select), draw))
                    };
                    self.light_slot_lanes(batch, choose, outs, counts);
                }
            }
            LightSelection::One => {}
        }
    }

    /// One light sample per lane on a fibre: `choose` gives lane k's light, its expected sample count and its
    /// draw (or nothing); directions per lane, f and the pdf in lanes, the rest per lane.
    fn light_slot_lanes<'s>(
        &self,
        batch: &Batch<'_, 's, '_>,
        choose: impl Fn(usize) -> Option<(usize, f32, Draw<'s>)>,
        outs: &mut [PathSample; LANES],
        counts: &mut RayCounts,
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
                    counts,
                );
            }
        }
    }

    /// The first vertices' material samples, drawn in lanes, finished per lane, then each lane's path continued
    /// ([`Integrator::shade_first`]'s steps 3 and on).
    fn material_samples_lanes(
        &self,
        batch: &Batch,
        outs: &mut [PathSample; LANES],
        counts: &mut RayCounts,
    ) {
        let n_m = self.first.material_samples;
        let d = dim::vertex(0, dim::MATERIAL);
        let mut next: [_; LANES] = std::array::from_fn(|_| None);
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
                        counts,
                        &mut next[k],
                    );
                }
            }
        }
        for (k, lane) in batch.lanes.iter().enumerate() {
            if lane.is_some() {
                let before = *counts;
                let at = (&batch.samplers[k], batch.indices[k]);
                self.finish_path(&mut outs[k], &next[k], at, counts, &mut (), &before);
            }
        }
    }
}

/// The eight lanes' state shared by the first vertex's steps.
struct Batch<'l, 's, 'a> {
    lanes: &'l [OnFibre<'l, 'a>; LANES],
    views: &'l PreparedLanes<'a>,
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
