//! The deeper vertices of the lanes in one round, whichever bounce each lane is at: light choice and direction
//! drawn per lane, f and the pdf at the light directions in lanes, the light samples finished per lane, the
//! material samples drawn in lanes and finished per lane (their rays, the next vertex), then each lane's step on
//! or its end — the scalar path's halves ([`Integrator::deeper_vertex`]) with the fibre's part in lanes between
//! them. A lane on another surface is shaded alone.

use glam::Vec3;
use wide::f32x8;

use crate::bsdf::lanes::{directions, LANES};

use super::super::integrator::{
    end_path, fcos, BounceRecorder, DeeperLight, Draw, Integrator, Mis, Step, Walk,
};
use super::super::sampler::dim;
use super::first::fibres;
use super::{Lanes, Stage};

impl<'a> Integrator<'a> {
    /// The lanes at a deeper vertex ([`Stage::Deeper`]): shaded as [`Integrator::deeper_vertex`], each lane's values
    /// and rays the scalar path's bit for bit, then on to the next vertex or done.
    pub(super) fn deeper_vertices<R: BounceRecorder + Default>(&self, l: &mut Lanes<'_, 'a, R>) {
        let at = l.stage.each_ref().map(|s| match s {
            Stage::Deeper(v, walk) => Some((v, *walk)),
            _ => None,
        });
        if at.iter().all(Option::is_none) {
            return;
        }
        let before = l.counts;
        let vertices = at.map(|a| a.map(|(v, _)| v));
        let b = at.map(|a| a.map_or(1, |(_, walk)| walk.b));
        let mis: [Mis; LANES] = b.map(|b| self.deeper_mis(b));
        let draws: [Draw; LANES] = std::array::from_fn(|k| Draw {
            sampler: &l.sampler[k],
            index: l.index[k],
            salt: 0,
        });
        let fibres = fibres(self, vertices);
        let on_fibre = |k: usize| fibres.as_ref().and_then(|(lanes, _)| lanes[k]);

        // The light samples: drawn per lane, f and the pdf in lanes, finished per lane.
        let light: [Option<DeeperLight>; LANES] =
            std::array::from_fn(|k| self.deeper_light_draw(vertices[k]?, b[k], draws[k]));
        let mut radiance = [Vec3::ZERO; LANES];
        let wi_l: [Vec3; LANES] = std::array::from_fn(|k| match (on_fibre(k), &light[k]) {
            (Some((_, frame, _)), Some(light)) => frame.to_local(light.ls.wi),
            _ => Vec3::X,
        });
        let evals = fibres
            .as_ref()
            .filter(|_| (0..LANES).any(|k| on_fibre(k).is_some() && light[k].is_some()))
            .map(|(_, views)| views.eval(directions(&wi_l)));
        for k in 0..LANES {
            let (Some(v), Some(light)) = (vertices[k], &light[k]) else {
                continue;
            };
            let f = match (on_fibre(k), &evals) {
                (Some((_, _, tint)), Some(evals)) => {
                    let (lobes, pdf) = evals.lane(k);
                    (fcos(lobes, tint, wi_l[k]), pdf)
                }
                _ => self.eval(v, light.ls.wi),
            };
            let counts = &mut l.counts[k];
            self.deeper_light_finish(
                v,
                &mis[k],
                b[k],
                draws[k],
                light,
                f,
                &mut radiance[k],
                counts,
            );
        }

        // The material samples: drawn in lanes (a lane on another surface alone), finished per lane.
        let wants = |k: usize| vertices[k].is_some() && !mis[k].light_only();
        let u: [[f32; 3]; LANES] = std::array::from_fn(|k| match wants(k) {
            true => draws[k].get_3(dim::vertex(b[k], dim::MATERIAL)),
            false => [0.5; 3],
        });
        let drawn = fibres
            .as_ref()
            .filter(|_| (0..LANES).any(|k| wants(k) && on_fibre(k).is_some()))
            .map(|(_, views)| views.sample(std::array::from_fn(|c| f32x8::new(u.map(|u| u[c])))));
        let steps: [Option<(Step<'a>, Walk)>; LANES] = std::array::from_fn(|k| {
            let (v, walk) = at[k]?;
            if !wants(k) {
                return Some(((radiance[k], None), walk));
            }
            let sample = match (on_fibre(k), &drawn) {
                (Some((_, frame, tint)), Some(drawn)) => {
                    let (lobes, pdf) = drawn.eval.lane(k);
                    let wi_l = drawn.wi(k);
                    (pdf > 0.0 && pdf.is_finite()).then(|| {
                        (
                            frame.to_world(wi_l).normalize(),
                            fcos(lobes, tint, wi_l),
                            pdf,
                        )
                    })
                }
                _ => self.sample_material(v, u[k]),
            };
            let step = match sample {
                Some(sample) => {
                    let counts = &mut l.counts[k];
                    let (m, bk, draw) = (&mis[k], b[k], draws[k]);
                    self.deeper_material_finish(v, m, bk, draw, sample, radiance[k], counts, false)
                }
                None => (radiance[k], None),
            };
            Some((step, walk))
        });

        // Each lane on to its next vertex, or done.
        for (k, step) in steps.into_iter().enumerate() {
            let Some((step, mut walk)) = step else {
                continue;
            };
            let at = (&l.sampler[k], l.index[k]);
            let (counts, record) = (&mut l.counts[k], &mut l.record[k]);
            l.stage[k] = match self.after_vertex(&mut walk, step, at, counts, &before[k], record) {
                Some(next) => Stage::Deeper(next, walk),
                None => {
                    end_path(&mut l.out[k], Some(&walk.indirect));
                    Stage::Done
                }
            };
        }
    }
}
