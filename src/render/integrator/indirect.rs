//! The path beyond the first vertex (step 4 of [`Integrator::sample`]): each deeper vertex's light, the
//! throughput back to the first vertex, Russian roulette and the clamp of indirect light. Each vertex is split in
//! halves — the light sample's draw and finish ([`Integrator::deeper_light_draw`],
//! [`Integrator::deeper_light_finish`]), the material sample's finish ([`Integrator::deeper_material_finish`]) and
//! the step to the next vertex ([`Integrator::after_vertex`]) — which the scalar path here and the wavefront
//! ([`crate::render::wavefront`], f and the pdf in lanes between them) both run, so both give the same bits.

use glam::Vec3;

use crate::bsdf::LobeValues;
use crate::light::LightSample;
use crate::util::color::luminance;

use super::super::sampler::{dim, CameraSample};
use super::mis::Mis;
use super::trace::Found;
use super::{add_lobes, BounceRecorder, Draw, Integrator, RayCounts, Vertex};

/// The walk of a path beyond its first vertex: the vertex being shaded, the throughput after the first vertex, the
/// indirect light gathered so far split by the first vertex's lobes.
#[derive(Clone, Copy)]
pub(in crate::render) struct Walk {
    /// The vertex being shaded (1: the second vertex).
    pub b: u32,
    /// Path throughput after the first vertex; the first vertex's own weight stays split by lobe.
    rest: Vec3,
    /// The first vertex's f cos θi / p_m per lobe.
    first_weights: LobeValues,
    /// Indirect light gathered so far, by the first vertex's lobes.
    pub indirect: LobeValues,
}

impl Walk {
    /// A walk from the second vertex, the first vertex's weights being `first_weights`.
    pub(in crate::render) fn new(first_weights: LobeValues) -> Walk {
        Walk {
            b: 1,
            rest: Vec3::ONE,
            first_weights,
            indirect: LobeValues::default(),
        }
    }
}

/// A deeper vertex's light sample, drawn before f and the pdf at its direction are known: the light chosen, its
/// selection probability, the selection draw's remainder (the light threshold's uniform number) and the sample.
pub(in crate::render) struct DeeperLight {
    j: usize,
    p_select: f32,
    u_rest: f32,
    pub ls: LightSample,
}

/// The outcome of one deeper vertex: the radiance it sends back along ωo, and the continuation (the next vertex and
/// f cos θi / p_m) if its material sample found a surface and the path may go on.
pub(in crate::render) type Step<'a> = (Vec3, Option<(Vertex<'a>, Vec3)>);

impl<'a> Integrator<'a> {
    /// Step 4, the path beyond the first vertex, from the second vertex `v`: the light each deeper vertex sends
    /// back ([`Integrator::deeper_vertex`]) times the throughput between it and the first vertex, split by the
    /// first vertex's lobes (`first_weights`, its f cos θi / p_m) and clamped ([`Integrator::add_indirect`]). The
    /// path ends after `path_length` bounces, where a vertex has no continuation, or by Russian roulette
    /// ([`roulette`]) before each further vertex.
    pub(super) fn indirect<R: BounceRecorder>(
        &self,
        second: &Vertex,
        first_weights: &LobeValues,
        sampler: &CameraSample,
        index: u32,
        counts: &mut RayCounts,
        record: &mut R,
    ) -> LobeValues {
        let mut walk = Walk::new(*first_weights);
        // The vertex being shaded: the second by reference (no copy of a few hundred bytes per path), deeper ones
        // kept in `deeper`.
        let mut v = second;
        let mut deeper;
        loop {
            let before = *counts;
            let step = self.deeper_vertex(v, walk.b, sampler, index, counts);
            let at = (sampler, index);
            match self.after_vertex(&mut walk, step, at, counts, &before, record) {
                Some(next) => {
                    deeper = next;
                    v = &deeper;
                }
                None => break,
            }
        }
        walk.indirect
    }

    /// After deeper vertex `walk.b` gave `step` (its rays counted since `before`): its light into the walk's
    /// indirect light, reported to `record`; then the next vertex if the path goes on (`walk.b` advanced, the
    /// throughput through Russian roulette), or `None` where it ends.
    #[inline]
    pub(in crate::render) fn after_vertex<R: BounceRecorder>(
        &self,
        walk: &mut Walk,
        step: Step<'a>,
        (sampler, index): (&CameraSample, u32),
        counts: &mut RayCounts,
        before: &RayCounts,
        record: &mut R,
    ) -> Option<Vertex<'a>> {
        let b = walk.b;
        if b >= 2 {
            counts.deep += counts.shadow + counts.material - (before.shadow + before.material);
        }
        let added = self.add_indirect(&mut walk.indirect, &walk.first_weights, walk.rest * step.0);
        record.vertex(b, added, &counts.since(before));
        if b == self.settings.path_length {
            return None;
        }
        let (next, weight) = step.1?;
        let u = sampler.get(index, dim::vertex(b, dim::ROULETTE));
        let thin = match self.settings.tail {
            Some((from, p)) if b == from => p,
            _ => 1.0,
        };
        walk.rest = roulette(&walk.first_weights, walk.rest * weight, u, thin)?;
        walk.b += 1;
        Some(next)
    }

    /// The weights of deeper vertex `b`'s strategies ([`Mis::deeper_vertex`]).
    #[inline]
    pub(in crate::render) fn deeper_mis(&self, b: u32) -> Mis {
        Mis::deeper_vertex(self.settings.strategy, b == self.settings.path_length)
    }

    /// Step 4 at one deeper vertex `v` (number `b` ≥ 1): one light chosen ∝ its selection weight and one material
    /// sample, weighted by [`Mis::deeper_vertex`](super::mis::Mis::deeper_vertex) (at the last vertex under light
    /// sampling alone, the light sample only).
    pub(in crate::render) fn deeper_vertex(
        &self,
        v: &Vertex,
        b: u32,
        sampler: &CameraSample,
        index: u32,
        counts: &mut RayCounts,
    ) -> Step<'a> {
        let mis = self.deeper_mis(b);
        let draw = Draw {
            sampler,
            index,
            salt: 0,
        };
        let mut radiance = Vec3::ZERO;
        if let Some(light) = self.deeper_light_draw(v, b, draw) {
            let (fcos, pdf_m) = self.eval(v, light.ls.wi);
            self.deeper_light_finish(
                v,
                &mis,
                b,
                draw,
                &light,
                (fcos, pdf_m),
                &mut radiance,
                counts,
            );
        }
        if mis.light_only() {
            return (radiance, None);
        }
        let d = dim::vertex(b, dim::MATERIAL);
        let Some(sample) = self.sample_material(v, draw.get_3(d)) else {
            return (radiance, None);
        };
        self.deeper_material_finish(v, &mis, b, draw, sample, radiance, counts, true)
    }

    /// Next-event estimation at deeper vertex `v` (number `b`), its draw: one light j chosen with probability P(j)
    /// ∝ its selection weight and one sample of it (`None` without lights or sample).
    #[inline]
    pub(in crate::render) fn deeper_light_draw(
        &self,
        v: &Vertex,
        b: u32,
        draw: Draw,
    ) -> Option<DeeperLight> {
        if self.lights.is_empty() {
            return None;
        }
        // The selection draw's remainder within the chosen light's bin is a fresh uniform number, independent of
        // the light sample's dimensions: the light threshold's roulette reads it, so that a deeper vertex needs no
        // Sobol set beyond its light and material dimensions' (dimension 9 + 8b would start a fifth at b = 1).
        let (j, p_select, u_rest) = self
            .select
            .sample_discrete(draw.get(dim::vertex(b, dim::LIGHT_SELECT)));
        let ls = self.lights[j]
            .sample_li(v.p, draw.get_2(dim::vertex(b, dim::LIGHT)))
            .filter(|_| p_select > 0.0)?;
        Some(DeeperLight {
            j,
            p_select,
            u_rest,
            ls,
        })
    }

    /// The rest of the light sample `light` at deeper vertex `v` once f · cos θi per lobe and the material's pdf
    /// are known: w_l L_e f cos θi / (P(j) p_l) with w_l from `mis`
    /// ([`Mis::light_weight`](super::mis::Mis::light_weight)), times the shadow ray's visibility, added to
    /// `radiance`.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub(in crate::render) fn deeper_light_finish(
        &self,
        v: &Vertex,
        mis: &Mis,
        b: u32,
        draw: Draw,
        light: &DeeperLight,
        (fcos, pdf_m): (LobeValues, f32),
        radiance: &mut Vec3,
        counts: &mut RayCounts,
    ) {
        let DeeperLight {
            j,
            p_select,
            u_rest,
            ref ls,
        } = *light;
        let f = fcos.sum();
        if f.max_element() > 0.0 {
            // n_j = P(j): one sample, of the chosen light.
            let count = mis.light_count(ls.delta, p_select);
            let w = mis.light_weight(ls, count, pdf_m);
            let contribution = f * ls.radiance * (w / (count * ls.pdf));
            if let Some(kept) = self.light_roulette(contribution, || u_rest) {
                let key = draw.key(dim::vertex(b, dim::LIGHT));
                let vis = kept * self.visibility(j, v, ls.wi, ls.distance, key, counts);
                // Not `contribution * vis`: this order of operations keeps every image without a threshold bit
                // for bit what it was (fractional visibilities round differently the other way).
                *radiance += f * ls.radiance * (vis * w / (count * ls.pdf));
            }
        }
    }

    /// The rest of deeper vertex `v`'s material sample (ωi in world space, f · cos θi per lobe, pdf) once drawn:
    /// its ray and the light it finds, added to `radiance`; the next vertex (a hair vertex with its view prepared
    /// only if `view`) if the path may go on.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub(in crate::render) fn deeper_material_finish(
        &self,
        v: &Vertex,
        mis: &Mis,
        b: u32,
        draw: Draw,
        (wi, fcos, pdf): (Vec3, LobeValues, f32),
        mut radiance: Vec3,
        counts: &mut RayCounts,
        view: bool,
    ) -> Step<'a> {
        let d = dim::vertex(b, dim::MATERIAL);
        let weight = fcos.sum() / pdf;
        if b == self.settings.path_length {
            // The last vertex's material sample only looks for light: an any-hit query is enough.
            let le = self.trace_material_light(v, mis, wi, pdf, draw.key(d), counts);
            return (radiance + weight * le, None);
        }
        let (le, found) = self.trace_material_sample(v, mis, wi, pdf, draw.key(d), counts, view);
        radiance += weight * le;
        match found {
            Found::Surface(next) => (radiance, Some((next, weight))),
            Found::Emitter(..) | Found::Escaped => (radiance, None),
        }
    }

    /// Adds light `l` (already multiplied by the throughput after the first vertex) arriving through the first
    /// vertex, split by its lobes, clamped per [`Settings::clamp`](super::Settings::clamp).
    /// Returns what it added to the beauty (the sum over lobes).
    #[inline]
    fn add_indirect(&self, acc: &mut LobeValues, first_weights: &LobeValues, l: Vec3) -> Vec3 {
        let mut scale = l;
        let weight = first_weights.sum();
        if self.settings.clamp > 0.0 {
            let c = (weight * l).max_element();
            if c > self.settings.clamp {
                scale *= self.settings.clamp / c;
            }
        }
        if scale.is_finite() {
            add_lobes(acc, first_weights, scale);
            weight * scale
        } else {
            Vec3::ZERO
        }
    }
}

/// Russian roulette (Arvo & Kirk 1990; pbrt-v4 §2.2.4) before a further path vertex: the path goes on with
/// probability q = clamp(luminance of its whole throughput, 0.05, 1) × `thin` (the tail's thinning past
/// `path_length`, [`Settings::tail`](super::Settings::tail), else 1), decided by `u`, and its throughput after the
/// first vertex, `rest`, is divided by q so the estimate stays unbiased (hair albedos of 0.3–0.7 end most paths
/// early). Returns the new `rest`, or `None` if the path ends (also when `rest` is no longer finite and positive).
#[inline]
fn roulette(first_weights: &LobeValues, rest: Vec3, u: f32, thin: f32) -> Option<Vec3> {
    let q = luminance(first_weights.sum() * rest).clamp(0.05, 1.0) * thin;
    if u >= q {
        return None;
    }
    let rest = rest / q;
    (rest.is_finite() && rest.max_element() > 0.0).then_some(rest)
}
