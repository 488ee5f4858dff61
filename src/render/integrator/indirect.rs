//! The path beyond the first vertex (step 4 of [`Integrator::sample`]): each deeper vertex's light, the
//! throughput back to the first vertex, Russian roulette and the clamp of indirect light.

use glam::Vec3;

use crate::bsdf::LobeValues;
use crate::util::color::luminance;

use super::super::sampler::{dim, CameraSample};
use super::mis::Mis;
use super::trace::Found;
use super::{add_lobes, BounceRecorder, Draw, Integrator, RayCounts, Vertex};

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
        let path_length = self.settings.path_length;
        // Path throughput after the first vertex; the first vertex's own weight stays split by lobe.
        let mut rest = Vec3::ONE;
        let mut indirect = LobeValues::default();
        // The vertex being shaded: the second by reference (no copy of a few hundred bytes per path), deeper ones
        // kept in `deeper`.
        let mut v = second;
        let mut deeper;
        for b in 1..=path_length {
            let before = *counts;
            // The step kept whole and its vertex moved out only to go on: destructuring it copied the
            // continuation (a few hundred bytes) at every vertex, the last one's included.
            let step = self.deeper_vertex(v, b, sampler, index, counts);
            if b >= 2 {
                counts.deep += counts.shadow + counts.material - (before.shadow + before.material);
            }
            let added = self.add_indirect(&mut indirect, first_weights, rest * step.0);
            record.vertex(b, added, &counts.since(&before));
            if b == path_length {
                break;
            }
            let Some((next, weight)) = step.1 else {
                break;
            };
            let u = sampler.get(index, dim::vertex(b, dim::ROULETTE));
            let Some(survivor) = roulette(first_weights, rest * weight, u) else {
                break;
            };
            rest = survivor;
            deeper = next;
            v = &deeper;
        }
        indirect
    }

    /// Step 4 at one deeper vertex `v` (number `b` ≥ 1): one light chosen ∝ its selection weight and one material
    /// sample, weighted by [`Mis::deeper_vertex`](super::mis::Mis::deeper_vertex) (at the last vertex under light
    /// sampling alone, the light sample only). Returns the radiance `v` sends back along ωo, and the continuation
    /// (the next vertex and f cos θi / p_m) if the material sample found a surface.
    fn deeper_vertex(
        &self,
        v: &Vertex,
        b: u32,
        sampler: &CameraSample,
        index: u32,
        counts: &mut RayCounts,
    ) -> (Vec3, Option<(Vertex<'a>, Vec3)>) {
        let mis = Mis::deeper_vertex(self.settings.strategy, b == self.settings.path_length);
        let draw = Draw {
            sampler,
            index,
            salt: 0,
        };
        let mut radiance = self.deeper_light_sample(v, &mis, b, draw, counts);
        if mis.light_only() {
            return (radiance, None);
        }
        let d = dim::vertex(b, dim::MATERIAL);
        let Some((wi, fcos, pdf)) = self.sample_material(v, draw.get_3(d)) else {
            return (radiance, None);
        };
        let weight = fcos.sum() / pdf;
        if b == self.settings.path_length {
            // The last vertex's material sample only looks for light: an any-hit query is enough.
            let le = self.trace_material_light(v, &mis, wi, pdf, draw.key(d), counts);
            return (radiance + weight * le, None);
        }
        let (le, found) = self.trace_material_sample(v, &mis, wi, pdf, draw.key(d), counts);
        radiance += weight * le;
        match found {
            Found::Surface(next) => (radiance, Some((next, weight))),
            Found::Emitter(..) | Found::Escaped => (radiance, None),
        }
    }

    /// Next-event estimation at deeper vertex `v` (number `b`): one light j chosen with probability P(j) ∝ its
    /// selection weight and one sample of it, w_l L_e f cos θi / (P(j) p_l) with w_l from `mis`
    /// ([`Mis::light_weight`](super::mis::Mis::light_weight)).
    fn deeper_light_sample(
        &self,
        v: &Vertex,
        mis: &Mis,
        b: u32,
        draw: Draw,
        counts: &mut RayCounts,
    ) -> Vec3 {
        let mut radiance = Vec3::ZERO;
        if self.lights.is_empty() {
            return radiance;
        }
        // The selection draw's remainder within the chosen light's bin is a fresh uniform number, independent of
        // the light sample's dimensions: the light threshold's roulette reads it, so that a deeper vertex needs no
        // Sobol set beyond its light and material dimensions' (dimension 9 + 8b would start a fifth at b = 1).
        let (j, p_select, u_rest) = self
            .select
            .sample_discrete(draw.get(dim::vertex(b, dim::LIGHT_SELECT)));
        let light = &self.lights[j];
        let d = dim::vertex(b, dim::LIGHT);
        let Some(ls) = light
            .sample_li(v.p, draw.get_2(d))
            .filter(|_| p_select > 0.0)
        else {
            return radiance;
        };
        let (fcos, pdf_m) = self.eval(v, ls.wi);
        let f = fcos.sum();
        if f.max_element() > 0.0 {
            // n_j = P(j): one sample, of the chosen light.
            let count = mis.light_count(ls.delta, p_select);
            let w = mis.light_weight(&ls, count, pdf_m);
            let contribution = f * ls.radiance * (w / (count * ls.pdf));
            if let Some(kept) = self.light_roulette(contribution, || u_rest) {
                let vis = kept * self.visibility(j, v, ls.wi, ls.distance, draw.key(d), counts);
                // Not `contribution * vis`: this order of operations keeps every image without a threshold bit
                // for bit what it was (fractional visibilities round differently the other way).
                radiance += f * ls.radiance * (vis * w / (count * ls.pdf));
            }
        }
        radiance
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
/// probability q = clamp(luminance of its whole throughput, 0.05, 1), decided by `u`, and its throughput after the
/// first vertex, `rest`, is divided by q so the estimate stays unbiased (hair albedos of 0.3–0.7 end most paths
/// early). Returns the new `rest`, or `None` if the path ends (also when `rest` is no longer finite and positive).
#[inline]
fn roulette(first_weights: &LobeValues, rest: Vec3, u: f32) -> Option<Vec3> {
    let q = luminance(first_weights.sum() * rest).clamp(0.05, 1.0);
    if u >= q {
        return None;
    }
    let rest = rest / q;
    (rest.is_finite() && rest.max_element() > 0.0).then_some(rest)
}
