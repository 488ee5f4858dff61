//! The first vertex of a path (steps 2–3 of [`Integrator::sample`]): what the camera ray sees directly, the
//! light samples and the material samples at the first hair or surface vertex, each MIS-weighted and split by
//! lobe; apart from the vertices beyond it.

use glam::Vec3;

use crate::bsdf::dual::{DualForm, DualScattering};
use crate::bsdf::LobeValues;
use crate::light::LightSample;
use crate::ray::Ray;
use crate::util::color::luminance;

use super::super::sampler::{dim, CameraSample};
use super::super::settings::LightSelection;
use super::trace::Found;
use super::{add_lobes, BounceRecorder, Draw, Integrator, PathSample, RayCounts, Surface, Vertex};

impl<'a> Integrator<'a> {
    /// [`Integrator::sample`]'s steps 2–5 for a camera ray that found the surface `v` (`out` as it starts; the
    /// ray counts were `before` at the camera ray).
    #[inline]
    pub(in crate::render) fn shade_first<R: BounceRecorder>(
        &self,
        v: &Vertex,
        (sampler, index): (&CameraSample, u32),
        out: &mut PathSample,
        counts: &mut RayCounts,
        record: &mut R,
        before: &RayCounts,
    ) {
        self.first_vertex_light_samples(v, sampler, index, out, counts);
        let next = self.first_vertex_material_samples(v, sampler, index, out, counts);
        self.finish_path(out, &next, (sampler, index), counts, record, before);
    }

    /// Step 1, a camera ray that found no surface (`found` is an emitter or nothing): the area light's L_e, with
    /// alpha 1; or the background, Σ L_e of the infinite lights (black unless the environment is visible), with
    /// alpha 0.
    pub(in crate::render) fn seen_directly(&self, ray: &Ray, found: &Found) -> PathSample {
        let mut out = PathSample::default();
        match *found {
            Found::Emitter(radiance, _) => {
                out.beauty = radiance;
                out.alpha = 1.0;
            }
            Found::Escaped if self.background_visible => {
                out.beauty = self
                    .uniform_background
                    .unwrap_or_else(|| self.lights.iter().map(|l| l.le(ray.dir.normalize())).sum());
            }
            Found::Escaped | Found::Surface(_) => {}
        }
        out
    }

    /// Step 2, next-event estimation at the first vertex `v` (the thesis' "light samples"). With `lights = "all"`
    /// every light gets `light_samples` samples (a delta light one), each from its own scrambling; with `lights =
    /// "one"` each of the `light_samples` samples first picks one light ∝ its selection weight
    /// ([`Light::selection_weight`](crate::light::Light::selection_weight)). Under material-only sampling only delta
    /// lights are light-sampled ([`Mis::samples_light`](super::mis::Mis::samples_light)).
    pub(in crate::render) fn first_vertex_light_samples(
        &self,
        v: &Vertex,
        sampler: &CameraSample,
        index: u32,
        out: &mut PathSample,
        counts: &mut RayCounts,
    ) {
        self.first_light_slots(|n, k, salt, light| {
            let draw = Draw {
                sampler,
                index: index * n + k,
                salt,
            };
            if let Some((j, count)) = light.or_else(|| self.choose_first_light(draw)) {
                self.first_vertex_light_sample(v, j, count, draw, out, counts);
            }
        });
    }

    /// The first vertex's light-sample slots in order, each as `slot(n, k, salt, light)`: sample k of n per camera
    /// sample, drawn with `salt`, going to `light` = (j, n_j) — under `lights = "all"` each light's own samples
    /// (a delta light one), under `lights = "one"` `None`, the light chosen from the draw
    /// ([`Integrator::choose_first_light`]). Under material-only sampling only delta lights get slots.
    #[inline]
    pub(in crate::render) fn first_light_slots(
        &self,
        mut slot: impl FnMut(u32, u32, u32, Option<(usize, f32)>),
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
                    for k in 0..samples {
                        slot(samples, k, j as u32, Some((j, count)));
                    }
                }
            }
            LightSelection::One if !self.lights.is_empty() => {
                for k in 0..mis.light_samples {
                    slot(mis.light_samples, k, 0, None);
                }
            }
            LightSelection::One => {}
        }
    }

    /// Under `lights = "one"`: the light a first-vertex light sample drawn with `draw` goes to, ∝ its selection
    /// weight, and its expected sample count n_j; `None` if it has no probability or is not light-sampled.
    #[inline]
    pub(in crate::render) fn choose_first_light(&self, draw: Draw) -> Option<(usize, f32)> {
        let mis = &self.first;
        let u_select = draw.get(dim::vertex(0, dim::LIGHT_SELECT));
        let (j, p_select, _) = self.select.sample_discrete(u_select);
        let delta = self.lights[j].is_delta();
        if p_select <= 0.0 || !mis.samples_light(delta) {
            return None;
        }
        Some((j, mis.light_count(delta, p_select)))
    }

    /// One light sample of light `j` at the first vertex `v`, where the light expects `count` samples (n_j,
    /// [`Mis::light_count`](super::mis::Mis::light_count)): Veach's multi-sample estimate w_l L_e f cos θi / (n_j
    /// p_l) (§9.2.2), added lobe by lobe times the shadow ray's visibility. The shadow pass sums its luminance with
    /// and without the visibility.
    fn first_vertex_light_sample(
        &self,
        v: &Vertex,
        j: usize,
        count: f32,
        draw: Draw,
        out: &mut PathSample,
        counts: &mut RayCounts,
    ) {
        let Some(ls) = self.first_vertex_light_draw(v, j, draw) else {
            return;
        };
        let (fcos, pdf_m) = self.eval(v, ls.wi);
        self.first_vertex_light_finish(v, j, count, draw, &ls, fcos, pdf_m, out, counts);
    }

    /// The light sample's direction: [`Light::sample_li`](crate::light::Light::sample_li) of light `j` at `v` with
    /// the draw's numbers.
    #[inline]
    pub(in crate::render) fn first_vertex_light_draw(
        &self,
        v: &Vertex,
        j: usize,
        draw: Draw,
    ) -> Option<LightSample> {
        self.lights[j].sample_li(v.p, draw.get_2(dim::vertex(0, dim::LIGHT)))
    }

    /// The rest of [`Integrator::first_vertex_light_sample`] once f · cos θi per lobe (`fcos`) and the material's
    /// pdf (`pdf_m`) at the light sample `ls` are known.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub(in crate::render) fn first_vertex_light_finish(
        &self,
        v: &Vertex,
        j: usize,
        count: f32,
        draw: Draw,
        ls: &LightSample,
        fcos: LobeValues,
        pdf_m: f32,
        out: &mut PathSample,
        counts: &mut RayCounts,
    ) {
        let d = dim::vertex(0, dim::LIGHT);
        let w = self.first.light_weight(ls, count, pdf_m);
        let scale = ls.radiance * (w / (ls.pdf * count));
        let contribution = fcos.sum() * scale;
        let unshadowed = luminance(contribution);
        if unshadowed <= 0.0 {
            return;
        }
        out.unshadowed += unshadowed;
        let u = || draw.get(dim::vertex(0, dim::LIGHT_TERMINATE));
        let Some(kept) = self.light_roulette(contribution, u) else {
            return;
        };
        let vis = kept
            * match self.dual {
                Some(dual) => {
                    self.dual_light_sample(dual, v, j, ls, kept / (ls.pdf * count), out, counts)
                }
                None => self.visibility(j, v, ls.wi, ls.distance, draw.key(d), counts),
            };
        out.lit += unshadowed * vis;
        if vis > 0.0 {
            add_lobes(&mut out.lobes, &fcos, scale * vis);
        }
    }

    /// Dual scattering's part of a first-vertex light sample `ls` of light `j` (whose estimate is scaled by
    /// `scale`, the roulette's factor over the density and the light's count): the strands crossed towards the light
    /// and behind the point ([`Integrator::strands_crossed`]: two counting queries, or one deep-opacity-map lookup);
    /// the multiple-scattered light, light-sampled alone (no material sample estimates it, so weight 1, not the MIS
    /// weight), goes to `out.indirect`. Returns the visibility of the direct light.
    #[allow(clippy::too_many_arguments)]
    fn dual_light_sample(
        &self,
        (dual, form): (&DualScattering, DualForm),
        v: &Vertex,
        j: usize,
        ls: &LightSample,
        scale: f32,
        out: &mut PathSample,
        counts: &mut RayCounts,
    ) -> f32 {
        let limits = dual.strand_limits(form);
        let Some(crossed) = self.strands_crossed(j, v, ls, limits, counts) else {
            return 0.0;
        };
        if let Surface::Hair { frame, .. } = v.surface {
            let f = dual.fcos(form, frame.to_local(v.wo), frame.to_local(ls.wi), crossed);
            out.indirect += f * ls.radiance * scale;
        }
        crossed.direct
    }

    /// Light-sample Russian roulette ([`Settings::light_threshold`](super::Settings::light_threshold), Cycles' light
    /// threshold): a light sample whose unshadowed `contribution` (without the path's throughput) has its largest
    /// channel c under the threshold t traces its shadow ray with probability p = c / t, deciding with the uniform
    /// number `u` (read only then). The factor its visibility is multiplied by: 1 at or above t, 1/p if kept, `None`
    /// if dropped (no ray; the estimate stays unbiased, E = p · 1/p).
    #[inline]
    pub(in crate::render) fn light_roulette(
        &self,
        contribution: Vec3,
        u: impl FnOnce() -> f32,
    ) -> Option<f32> {
        let t = self.settings.light_threshold;
        if t <= 0.0 {
            return Some(1.0);
        }
        let p = contribution.max_element() / t;
        if p >= 1.0 {
            Some(1.0)
        } else if u() < p {
            Some(1.0 / p)
        } else {
            None
        }
    }

    /// Step 3, the first vertex's material samples (the thesis' "material samples"): each of the n_m adds Veach's
    /// multi-sample estimate f cos θi / p_m · w_m L_e / n_m of the light it reaches
    /// ([`Mis::material_weight`](super::mis::Mis::material_weight)) lobe by lobe. The first also gives the albedo
    /// pass (f cos θi / p_m) and, if `path_length` > 0, continues the path: it returns the second vertex with the
    /// first's f cos θi / p_m per lobe. A sample that can neither add light (light-only strategy, only delta lights)
    /// nor continue traces no ray.
    pub(in crate::render) fn first_vertex_material_samples(
        &self,
        v: &Vertex,
        sampler: &CameraSample,
        index: u32,
        out: &mut PathSample,
        counts: &mut RayCounts,
    ) -> Option<(Vertex<'a>, LobeValues)> {
        let n_m = self.first.material_samples;
        let d = dim::vertex(0, dim::MATERIAL);
        let mut next = None;
        for k in 0..n_m {
            let draw = Draw {
                sampler,
                index: index * n_m + k,
                salt: 0,
            };
            let Some((wi, fcos, pdf)) = self.sample_material(v, draw.get_3(d)) else {
                continue;
            };
            let sample = (wi, fcos, pdf);
            self.first_vertex_material_finish(v, k, draw, sample, out, counts, &mut next, true);
        }
        next
    }

    /// The rest of material sample `k` of [`Integrator::first_vertex_material_samples`] once its direction
    /// (world space), f · cos θi per lobe and pdf are drawn: the albedo pass, the ray, the light it finds, and the
    /// second vertex into `next` if it continues the path (a hair vertex with its view prepared only if `view`).
    // The sample's state and the path's three outputs, as `first_vertex_light_finish` takes them.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub(in crate::render) fn first_vertex_material_finish(
        &self,
        v: &Vertex,
        k: u32,
        draw: Draw,
        (wi, fcos, pdf): (Vec3, LobeValues, f32),
        out: &mut PathSample,
        counts: &mut RayCounts,
        next: &mut Option<(Vertex<'a>, LobeValues)>,
        view: bool,
    ) {
        let d = dim::vertex(0, dim::MATERIAL);
        let weights = fcos.scaled(1.0 / pdf);
        if k == 0 {
            out.albedo = weights.sum();
        }
        let continues = k == 0 && self.settings.path_length > 0;
        if !self.material_finds_light && !continues {
            return;
        }
        let le = if continues {
            let (le, found) =
                self.trace_material_sample(v, &self.first, wi, pdf, draw.key(d), counts, view);
            if let Found::Surface(second) = found {
                *next = Some((second, weights));
            }
            le
        } else {
            self.trace_material_light(v, &self.first, wi, pdf, draw.key(d), counts)
        };
        if le.max_element() > 0.0 {
            add_lobes(
                &mut out.lobes,
                &weights,
                le / self.first.material_samples as f32,
            );
        }
    }
}
