//! The eight-lane path of the first vertex ([`Integrator::sample_lanes`], steps 1–2 of `docs/design/wavefront.md`):
//! a batch of camera samples whose first vertices are shaded one f32×8 vector at a time through the material's
//! lane form ([`crate::bsdf::PreparedLanes`]); apart from the scalar path it reproduces.

use glam::Vec3;
use wide::f32x8;

use crate::bsdf::frame::HairFrame;
use crate::bsdf::lanes::{directions, LANES};
use crate::light::LightSample;
use crate::ray::Ray;

use super::super::sampler::{dim, CameraSample};
use super::super::settings::LightSelection;
use super::trace::Found;
use super::{fcos, Draw, Integrator, PathSample, RayCounts, Surface, Vertex};

impl<'a> Integrator<'a> {
    /// Whether [`Integrator::sample_lanes`] can shade this frame's first vertices in lanes: a material with a lane
    /// form, one light chosen per sample (`lights = "one"`) with one light and one material sample.
    pub fn lanes_fit(&self) -> bool {
        self.material.has_lanes()
            && !self.lights.is_empty()
            && self.first.selection == LightSelection::One
            && self.first.light_samples == 1
            && self.first.material_samples == 1
    }

    /// [`Integrator::sample`] of eight camera samples (`rays[k]` with `samplers[k]`, sample `indices[k]`), their
    /// first vertices shaded together where they are on fibres: the light samples' f and pdf by
    /// [`PreparedLanes::eval`](crate::bsdf::PreparedLanes::eval), the material samples by
    /// [`PreparedLanes::sample`](crate::bsdf::PreparedLanes::sample), everything else (light choice, rays, MIS,
    /// the deeper vertices) per sample as [`Integrator::sample`] does it. Step 2 of `docs/design/wavefront.md`,
    /// experimental: the lanes draw the same samples with f32 arithmetic, so images differ from
    /// [`Integrator::sample`]'s by its rounding. Needs [`Integrator::lanes_fit`].
    // One piece: the eight samples' lane state carries through every step, as in the scalar `sample`.
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
        // The lanes on a fibre: (vertex, frame, tint, h).
        let hair = |k: usize| match &found[k] {
            Found::Surface(v) => match &v.surface {
                Surface::Hair { frame, tint, h, .. } => Some((v, *frame, *tint, *h)),
                _ => None,
            },
            _ => None,
        };
        let lanes: [Option<(&Vertex, HairFrame, Vec3, f32)>; LANES] = std::array::from_fn(hair);
        // A lane on another surface (or none): shaded alone, as `sample` does.
        let shade_alone = |k: usize, out: &mut PathSample, counts: &mut RayCounts| {
            if let Found::Surface(v) = &found[k] {
                let before = *counts;
                let at = (&samplers[k], indices[k]);
                self.shade_first(v, at, out, counts, &mut (), &before);
            }
        };
        if lanes.iter().all(Option::is_none) {
            // No lane on a fibre: nothing to shade together.
            for (k, out) in outs.iter_mut().enumerate() {
                shade_alone(k, out, counts);
            }
            return outs;
        }
        // The views in lanes (empty lanes take h = 0 and ωo across the fibre, their results unused).
        let h = f32x8::new(lanes.map(|l| l.map_or(0.0, |l| l.3)));
        let wo_l: [Vec3; LANES] =
            lanes.map(|l| l.map_or(Vec3::Y, |(v, frame, ..)| frame.to_local(v.wo)));
        let views = self
            .material
            .prepare_lanes(h, directions(&wo_l))
            .expect("lanes_fit: a material with a lane form");
        let draw = |k: usize| Draw {
            sampler: &samplers[k],
            index: indices[k],
            salt: 0,
        };
        // Light samples: the light and its direction per lane, f and pdf in lanes.
        let mis = &self.first;
        let light: [Option<(usize, f32, LightSample)>; LANES] = std::array::from_fn(|k| {
            let (v, ..) = lanes[k]?;
            let u_select = draw(k).get(dim::vertex(0, dim::LIGHT_SELECT));
            let (j, p_select, _) = self.select.sample_discrete(u_select);
            let delta = self.lights[j].is_delta();
            if p_select <= 0.0 || !mis.samples_light(delta) {
                return None;
            }
            let ls = self.first_vertex_light_draw(v, j, draw(k))?;
            Some((j, mis.light_count(delta, p_select), ls))
        });
        let wi_l: [Vec3; LANES] = std::array::from_fn(|k| match (&lanes[k], &light[k]) {
            (Some(l), Some((_, _, ls))) => l.1.to_local(ls.wi),
            _ => Vec3::X,
        });
        let evals = views.eval(directions(&wi_l));
        for k in 0..LANES {
            if let (Some((v, _, tint, _)), Some((j, count, ls))) = (&lanes[k], &light[k]) {
                let (lobes, pdf) = evals.lane(k);
                let fcos = fcos(lobes, *tint, wi_l[k]);
                self.first_vertex_light_finish(
                    v,
                    *j,
                    *count,
                    draw(k),
                    ls,
                    fcos,
                    pdf,
                    &mut outs[k],
                    counts,
                );
            }
        }
        // Material samples, drawn in lanes.
        let u: [[f32; 3]; LANES] = std::array::from_fn(|k| match lanes[k] {
            Some(_) => draw(k).get_3(dim::vertex(0, dim::MATERIAL)),
            None => [0.5; 3],
        });
        let drawn = views.sample(std::array::from_fn(|c| f32x8::new(u.map(|u| u[c]))));
        for k in 0..LANES {
            let Some((v, frame, tint, _)) = &lanes[k] else {
                shade_alone(k, &mut outs[k], counts);
                continue;
            };
            let mut next = None;
            let (lobes, pdf) = drawn.eval.lane(k);
            if pdf > 0.0 && pdf.is_finite() {
                let wi_l = drawn.wi(k);
                let sample = (
                    frame.to_world(wi_l).normalize(),
                    fcos(lobes, *tint, wi_l),
                    pdf,
                );
                self.first_vertex_material_finish(
                    v,
                    0,
                    draw(k),
                    sample,
                    &mut outs[k],
                    counts,
                    &mut next,
                );
            }
            let before = *counts;
            self.finish_path(
                &mut outs[k],
                &next,
                (&samplers[k], indices[k]),
                counts,
                &mut (),
                &before,
            );
        }
        outs
    }
}
