//! The light transport of one camera sample: a path tracer with next-event estimation, combining light samples
//! and material (BSDF) samples by multiple importance sampling (Veach's power heuristic), as the thesis' RenderMan
//! setup did with its "light samples" and "material samples" (§3, §5.3, table 3).
//!
//! # Estimator
//!
//! At the **first** shading point every light gets `light_samples` samples (`lights = "all"`, RenderMan's and the
//! thesis' semantics; or, with `lights = "one"`, each of the `light_samples` samples goes to one light chosen in
//! proportion to its selection weight, [`Light::selection_weight`]: power, an environment counted by the irradiance
//! it gives) and the material gets `material_samples` samples; a material sample that reaches a light (escapes to an
//! infinite light, or hits an area light) is weighted against that light's strategy with the power heuristic over the
//! *counts* times the densities, w = (n_m p_m)² / ((n_m p_m)² + (n_l p_l)²) (Veach 1997, §9.2.4). Deeper vertices
//! take one light, chosen the same way, and one material sample. The first material sample at each vertex also
//! continues the path (`path_length` bounces; 0 = direct light only), with Russian roulette before each vertex after
//! the second; the last vertex keeps MIS (its material ray only looks for a light; see `mis`).
//!
//! # Hair transparency
//!
//! The thesis' per-strand opacity is honoured by every ray that carries light towards a shading point: a strand of
//! opacity a is *present* for such a ray with probability a ([`crate::accel::strand_present`], keyed per ray).
//! Light samples either use that stochastic test (`transmittance = "stochastic"`, one any-hit query) or the exact
//! product ∏(1 − a) (`"exact"`, a full traversal); both have the same expectation, so MIS stays unbiased.
//! Material samples and path continuations use the stochastic closest hit, so a material sample that escapes
//! through absent strands sees the environment. Camera rays see every strand as opaque. With opacity 1 this is
//! plain path tracing; with opacity < 1 and `path_length` > 0 light that passes a strand is counted both as
//! transmitted (the opacity model) and, at the bounce, as scattered by TT — the thesis' approximation, kept
//! because a hair file's transparency is what its author tuned. Use opacity 1 for a strictly physical render.
//!
//! # Passes
//!
//! Each sample returns its beauty and the AOVs of [`PathSample`]. The lobe passes split everything that leaves the
//! *first* vertex by the lobe of the first vertex's BSDF it went through (R, TT, TRT, glint, diffuse; Lambert
//! shapes count as diffuse), for direct and indirect light alike, so that R + TT + TRT + glint = specular and
//! specular + diffuse = direct + indirect. Beauty = direct + indirect + emitters and background seen directly.

use glam::{Vec3, Vec3A};

use crate::accel::{CurveKind, Tracer};
use crate::bsdf::dual::{DualForm, DualScattering};
use crate::bsdf::frame::{h_from_normal, h_from_ribbon};
use crate::bsdf::frame::{sin_cos_theta, strand_noise, HairFrame};
use crate::bsdf::{Lobe, LobeValues, Material, PreparedBsdf};
use crate::hair::strands::tube_exit;
use crate::hair::Strands;
use crate::light::{Distribution1D, Light};
use crate::ray::Ray;
use crate::shadow::ShadowMaps;
use crate::shape::Shapes;

use super::sampler::{dim, CameraSample};
use super::settings::{LightSelection, RenderSettings, ShadowMode, Strategy, TransmittanceMode};
use super::Frame;

mod first;
mod indirect;
mod mis;
mod trace;

pub(in crate::render) use indirect::{DeeperLight, Step, Walk};
pub(in crate::render) use mis::Mis;
pub(in crate::render) use trace::Found;

/// The largest `path_length` the sample dimensions allow: path vertices 0..=`path_length` each take a block of
/// [`dim::PER_VERTEX`] dimensions.
pub const MAX_PATH_LENGTH: u32 = dim::MAX_VERTICES - 1;

/// The longest path a tail ([`Settings::tail`]) continues to: past [`MAX_PATH_LENGTH`] its vertices draw hashed
/// independent numbers ([`super::sampler::PixelSampler::get_salted`]); Russian roulette ends paths long before
/// (a path this long has survived a roulette of ≤ 0.95 per vertex ~10²² times over), the bound keeps a path
/// finite whatever the scene.
pub const MAX_TAIL_LENGTH: u32 = 1000;

/// Light-transport settings of one render.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// Light samples per light at the first vertex.
    pub light_samples: u32,
    /// Material samples at the first vertex.
    pub material_samples: u32,
    /// Indirect bounces (0 = direct light only).
    pub path_length: u32,
    /// (bounce b, probability p): after vertex b a path goes on only with probability p on top of Russian
    /// roulette, weighted by 1 / p ([`crate::render::settings::IntegratorConfig::tail`]; `path_length` is then
    /// [`MAX_TAIL_LENGTH`]).
    pub tail: Option<(u32, f32)>,
    /// Largest channel value of one indirect contribution; 0 = no clamping (the default: clamping is biased).
    pub clamp: f32,
    /// Self-shadowing.
    pub shadows: ShadowMode,
    /// How light samples evaluate strand transparency.
    pub transmittance: TransmittanceMode,
    /// Which sampling strategies estimate direct light.
    pub strategy: Strategy,
    /// Which lights the first vertex's light samples go to.
    pub light_selection: LightSelection,
    /// Light-sample Russian roulette below this unshadowed contribution; 0 = off
    /// ([`crate::render::settings::IntegratorConfig::light_threshold`]).
    pub light_threshold: f32,
    /// Dual scattering at the first vertex's light samples, in this form ([`crate::bsdf::dual`]; `path_length` is
    /// then 0).
    pub dual: Option<DualForm>,
}

/// Counters of rays, kept per tile and summed.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct RayCounts {
    /// Camera rays (including the pixel-centre AOV ray).
    pub camera: u64,
    /// Shadow rays of light samples.
    pub shadow: u64,
    /// Material-sample and continuation rays.
    pub material: u64,
    /// Rays refused by validation (never traced; should stay 0).
    pub rejected: u64,
    /// Shadow-map lookups made instead of shadow rays (deep-opacity mode).
    pub map_lookups: u64,
    /// Of the shadow and material rays, those traced at the third path vertex and beyond (bounce 2 onwards): they
    /// start deep in the hair and cost more each ([`RayCost::deep`]).
    pub deep: u64,
    /// Strand-counting queries of dual scattering (all-hits traversals, towards a light or behind the point), with
    /// their light sample and dual shading.
    pub counted: u64,
    /// Strands those queries counted, together: a count's traversal grows with them.
    pub crossed: u64,
}

impl RayCounts {
    /// Adds another tile's counts.
    pub fn add(&mut self, o: &RayCounts) {
        self.camera += o.camera;
        self.shadow += o.shadow;
        self.material += o.material;
        self.rejected += o.rejected;
        self.map_lookups += o.map_lookups;
        self.deep += o.deep;
        self.counted += o.counted;
        self.crossed += o.crossed;
    }

    /// The rays counted since `earlier`, an earlier reading of the same counters.
    pub fn since(&self, earlier: &RayCounts) -> RayCounts {
        RayCounts {
            camera: self.camera - earlier.camera,
            shadow: self.shadow - earlier.shadow,
            material: self.material - earlier.material,
            rejected: self.rejected - earlier.rejected,
            map_lookups: self.map_lookups - earlier.map_lookups,
            deep: self.deep - earlier.deep,
            counted: self.counted - earlier.counted,
            crossed: self.crossed - earlier.crossed,
        }
    }

    /// Every ray traced (strand counts included).
    pub fn total(&self) -> u64 {
        self.camera + self.shadow + self.material + self.counted
    }
}

/// Predicted seconds per ray (or map lookup) of each kind, the shading that comes with it included: a deterministic
/// cost model, so that decisions weighed by cost (adaptive sampling, `--quality auto`) never read the clock and are
/// the same for any thread count and load. The measured weights and how they were fitted are
/// `crate::quality::cost::WEIGHTS`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayCost {
    /// Per camera ray (the sample's setup, the first hit, or the background).
    pub camera: f64,
    /// Per shadow ray of a light sample (with the light sample and BSDF evaluation it serves).
    pub shadow: f64,
    /// Per material-sample or continuation ray (with the BSDF sample and the vertex it finds).
    pub material: f64,
    /// Per deep-opacity-map lookup made instead of a shadow ray (with its light sample and BSDF evaluation).
    pub map_lookup: f64,
    /// Added per shadow or material ray traced at bounce 2 or later ([`RayCounts::deep`]), over its kind's weight.
    pub deep: f64,
    /// Per strand-counting query of dual scattering ([`RayCounts::counted`]), with its shading.
    pub counted: f64,
    /// Per strand such a query counted ([`RayCounts::crossed`]).
    pub crossed: f64,
}

impl RayCost {
    /// The predicted CPU seconds of the work that traced `rays`.
    pub fn seconds(&self, rays: &RayCounts) -> f64 {
        self.camera * rays.camera as f64
            + self.shadow * rays.shadow as f64
            + self.material * rays.material as f64
            + self.map_lookup * rays.map_lookups as f64
            + self.deep * rays.deep as f64
            + self.counted * rays.counted as f64
            + self.crossed * rays.crossed as f64
    }
}

/// What one camera sample contributes to the film.
#[derive(Debug, Default, Clone, Copy)]
pub struct PathSample {
    /// Radiance along the camera ray.
    pub beauty: Vec3,
    /// 1 if the camera ray hit hair, a shape or an emitter.
    pub alpha: f32,
    /// Light leaving the first vertex, by lobe of the first vertex's BSDF.
    pub lobes: LobeValues,
    /// Light from emitters scattered once (at the first vertex).
    pub direct: Vec3,
    /// Light scattered more than once.
    pub indirect: Vec3,
    /// Σ luminance of the first vertex's light-sample contributions *with* their shadow ray's visibility...
    pub lit: f32,
    /// ...and without it: `lit / unshadowed` is the shadow pass.
    pub unshadowed: f32,
    /// A one-sample estimate of the first vertex's directional albedo (f cos θ / pdf of its first material sample).
    pub albedo: Vec3,
    /// Where the camera ray left the film, in pixels from its pixel's top-left corner: set by the pixel's sample
    /// source ([`crate::render::PixelSource`]), not the integrator; a splatting film weighs the sample by it.
    pub film: [f32; 2],
}

/// What [`Integrator::sample_recording`] reports of each path vertex: the light it adds to the beauty and the rays
/// traced for it. The pilots of `--quality auto` ([`crate::quality::pilot`]) read every path length's estimate from
/// one render this way; [`Integrator::sample`] records nothing (`()`, compiled away).
pub trait BounceRecorder {
    /// Vertex `b` (0: the camera ray and the first vertex, direct light; `b` ≥ 1: bounce `b`) added `radiance` to
    /// the beauty and traced `rays`.
    fn vertex(&mut self, b: u32, radiance: Vec3, rays: &RayCounts);
}

impl BounceRecorder for () {
    #[inline(always)]
    fn vertex(&mut self, _: u32, _: Vec3, _: &RayCounts) {}
}

/// A shading point's scattering: a hair fibre (hair frame, strand tint on the diffuse lobe, the material prepared
/// for ωo) or a two-sided Lambert surface.
// The hair variant carries the prepared fibre (up to ~150 bytes): a vertex lives on the stack for one path step,
// and boxing it would allocate per vertex.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy)]
pub(in crate::render) enum Surface<'a> {
    Hair {
        frame: HairFrame,
        /// Multiplies the diffuse lobe (the strand colour, or 1).
        tint: Vec3,
        strand: u32,
        /// The fibre's axis point at the hit (the curve's centre line at the hit's u).
        axis: Vec3,
        /// Fibre radius at the hit.
        radius: f32,
        /// Offset h = sin γo of the hit across the fibre, for models that read it ([`Material::uses_offset`];
        /// 0 otherwise).
        h: f32,
        /// The material at this hit, prepared for ωo once for every light sample, material sample and pdf of the
        /// vertex ([`Material::prepare`]).
        bsdf: PreparedBsdf<'a>,
    },
    Lambert {
        /// The normal on the side the light leaves towards (facing ωo).
        normal: Vec3,
        albedo: Vec3,
    },
}

/// A point being shaded.
#[derive(Clone, Copy)]
pub(in crate::render) struct Vertex<'a> {
    pub p: Vec3,
    pub wo: Vec3,
    pub surface: Surface<'a>,
}

/// The random numbers of one sample of one strategy: sample `index` of the pixel's `sampler`, scrambled by `salt`
/// (0, or a light's index so that the samples of different lights are independent), in the dimensions of
/// [`dim`].
#[derive(Clone, Copy)]
pub(in crate::render) struct Draw<'s> {
    pub sampler: &'s CameraSample<'s>,
    pub index: u32,
    pub salt: u32,
}

impl Draw<'_> {
    #[inline]
    pub(in crate::render) fn get(&self, dimension: u32) -> f32 {
        self.sampler.get_salted(self.index, dimension, self.salt)
    }

    /// Dimensions `dimension` and `dimension + 1`.
    #[inline]
    fn get_2(&self, dimension: u32) -> [f32; 2] {
        self.sampler.get_n(self.index, dimension, self.salt)
    }

    /// Dimensions `dimension` to `dimension + 2`.
    #[inline]
    pub(in crate::render) fn get_3(&self, dimension: u32) -> [f32; 3] {
        self.sampler.get_n(self.index, dimension, self.salt)
    }

    /// The key of the ray drawn from `dimension` (its strands' stochastic presence).
    #[inline]
    fn key(&self, dimension: u32) -> u64 {
        self.sampler.key(self.index, dimension, self.salt)
    }
}

/// Per-frame state of the path tracer, shared by all threads.
pub struct Integrator<'a> {
    strands: &'a Strands,
    tracer: &'a dyn Tracer,
    shapes: &'a Shapes,
    pub(in crate::render) lights: &'a [Light],
    pub(in crate::render) material: &'a Material,
    curves: CurveKind,
    pub(in crate::render) settings: Settings,
    /// The first vertex's strategies and weights (from `settings`).
    pub(in crate::render) first: Mis,
    /// Light selection ∝ [`Light::selection_weight`], for `lights = "one"` and the vertices after the first.
    pub(in crate::render) select: Distribution1D,
    /// Offset of shadow-ray origins off Lambert surfaces (hair rays skip their own strand instead).
    epsilon: f32,
    /// Whether camera rays that escape see the infinite lights.
    background_visible: bool,
    /// What an escaping camera ray sees when every light's [`Light::le`] is the same in every direction (a
    /// constant environment, delta suns): their sum, taken once instead of two lookups with a normalisation each
    /// per background sample (~170 of a background sample's ~1 570 instructions on the peer frame). The same
    /// values in the same order, so the same bits.
    uniform_background: Option<Vec3>,
    /// Deep opacity maps, in `shadows = "deep-opacity"` mode.
    maps: Option<&'a ShadowMaps>,
    /// Whether a material sample can add direct light: false when the strategy is light-only or every light is a
    /// delta light (then material samples are traced only to continue paths).
    material_finds_light: bool,
    /// Every strand is opaque (opacity 1): rays leaving a fibre start past its local tube ([`tube_exit`]) instead
    /// of ignoring the whole strand, so that the tracer can trace them without a filter.
    skip_by_tube: bool,
    /// Dual scattering's tables, when the settings ask for it and the material has them.
    pub(in crate::render) dual: Option<(&'a DualScattering, DualForm)>,
    /// Whether a ray can meet anything besides hair: a shape or an area light. Without them (the fur ball under an
    /// environment and a sun) every ray skips the scan for them (0.5 % of the peer frame's instructions).
    non_hair: bool,
}

/// f · cos θi per lobe from f per lobe at local `wi_l`, the diffuse lobe tinted by `tint`.
#[inline]
pub(in crate::render) fn fcos(mut lobes: LobeValues, tint: Vec3, wi_l: Vec3) -> LobeValues {
    lobes.diffuse *= Vec3A::from(tint);
    lobes.scaled(sin_cos_theta(wi_l).1)
}

/// Adds `weights ⊙ scale` lobe by lobe.
#[inline]
fn add_lobes(acc: &mut LobeValues, weights: &LobeValues, scale: Vec3) {
    for lobe in Lobe::ALL {
        *acc.get_mut(lobe) += weights.get(lobe) * Vec3A::from(scale);
    }
}

impl<'a> Integrator<'a> {
    /// The path tracer of `frame` rendered with `settings` (and `maps` in deep-opacity mode). The frame's radius
    /// ([`Frame::radius`]) sizes infinite lights' power and the surface offset.
    pub fn new(frame: &'a Frame, settings: &RenderSettings, maps: Option<&'a ShadowMaps>) -> Self {
        let (lights, scene_radius) = (&frame.lights[..], frame.radius());
        let background_visible = settings.background_visible;
        let settings = settings.transport();
        // Under dual scattering only light samples carry the multiple-scattered light, so every light is chosen by
        // its power, a constant environment too (which MIS otherwise leaves to the material samples).
        let material_finds_light = settings.strategy == Strategy::Mis && settings.dual.is_none();
        let weights: Vec<f32> = lights
            .iter()
            .map(|l| l.selection_weight(scene_radius, material_finds_light))
            .collect();
        Integrator {
            strands: &frame.strands,
            tracer: frame.tracer.as_ref(),
            shapes: &frame.shapes,
            lights,
            material: &frame.material,
            curves: frame.curves,
            settings,
            first: Mis::first_vertex(&settings),
            select: Distribution1D::new(&weights),
            epsilon: 1e-4 * scene_radius.max(1e-3),
            background_visible,
            uniform_background: lights.iter().map(Light::uniform_le).sum(),
            non_hair: !frame.shapes.is_empty() || lights.iter().any(Light::intersects),
            maps,
            material_finds_light: settings.strategy != Strategy::Light
                && lights.iter().any(|l| !l.is_delta()),
            skip_by_tube: frame.strands.all_opaque(),
            dual: settings
                .dual
                .and_then(|form| Some((frame.material.dual()?, form))),
        }
    }

    /// The shading point of a strand hit.
    #[inline(always)]
    fn hair_vertex(&self, ray: &Ray, hit: &crate::accel::Hit, view: bool) -> Vertex<'a> {
        let wo = -ray.dir.normalize();
        let point = self.strands.eval(hit.segment, hit.u);
        // A degenerate strand (repeated points) has no tangent: shade it as a fibre perpendicular to the view.
        let tangent = point
            .tangent
            .try_normalize()
            .unwrap_or_else(|| wo.any_orthonormal_vector());
        let frame = match self.curves {
            CurveKind::Round => HairFrame::from_round_curve(tangent, hit.ng),
            CurveKind::Flat => HairFrame::from_ribbon(tangent, strand_noise(hit.strand)),
        };
        // h for Chiang et al. (bsdf::chiang's docs): round tubes from the outward normal (frame.v) and the view;
        // ribbons from Embree's v ∈ [−1, 1], which grows along D̂ × u = u × ωo across the ray-facing quad
        // (accel::curves::flat, steps 4-5: v = −1 on the p + w n side, n = (d_y, −d_x) in ray space), so
        // h = −v for the fibre the ribbon stands for (tested in tests/integrator.rs against a round tube).
        let h = if !self.material.uses_offset() {
            0.0
        } else {
            match self.curves {
                CurveKind::Round => h_from_normal(frame.u, frame.v, wo),
                CurveKind::Flat => {
                    h_from_ribbon(0.5 * (hit.v + 1.0), frame.u.cross(wo), frame.u, wo)
                }
            }
        };
        let tint = if self.material.tint_diffuse_by_strand {
            Vec3::from(self.strands.color[hit.strand as usize])
        } else {
            Vec3::ONE
        };
        let bsdf = self.material.prepare(h, frame.to_local(wo), view);
        Vertex {
            p: ray.at(hit.t),
            wo,
            surface: Surface::Hair {
                frame,
                bsdf,
                tint,
                strand: hit.strand,
                axis: point.position,
                radius: point.radius,
                h,
            },
        }
    }

    /// f · cos θi per lobe, and the material's sampling pdf, for light leaving `v` along ωo arriving from `wi`.
    #[inline]
    pub(in crate::render) fn eval(&self, v: &Vertex, wi: Vec3) -> (LobeValues, f32) {
        match v.surface {
            Surface::Hair {
                frame, tint, bsdf, ..
            } => {
                let wi_l = frame.to_local(wi);
                let (lobes, pdf) = bsdf.eval(wi_l);
                (fcos(lobes, tint, wi_l), pdf)
            }
            Surface::Lambert { normal, albedo } => {
                let cos = normal.dot(wi);
                if cos <= 0.0 {
                    return (LobeValues::default(), 0.0);
                }
                let lobes = LobeValues {
                    diffuse: (albedo * (cos * std::f32::consts::FRAC_1_PI)).into(),
                    ..LobeValues::default()
                };
                (lobes, cos * std::f32::consts::FRAC_1_PI)
            }
        }
    }

    /// A material sample at `v`: (ωi, f · cos θi per lobe, pdf).
    #[inline]
    pub(in crate::render) fn sample_material(
        &self,
        v: &Vertex,
        u: [f32; 3],
    ) -> Option<(Vec3, LobeValues, f32)> {
        match v.surface {
            Surface::Hair {
                frame, tint, bsdf, ..
            } => {
                let (s, lobes) = bsdf.sample(u)?;
                let lobes = fcos(lobes, tint, s.wi);
                Some((frame.to_world(s.wi).normalize(), lobes, s.pdf))
            }
            Surface::Lambert { normal, .. } => {
                // Cosine-weighted hemisphere about the facing normal.
                let r = u[0].sqrt();
                let phi = std::f32::consts::TAU * u[1];
                let local = Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u[0]).max(0.0).sqrt());
                let (t, b) = normal.any_orthonormal_pair();
                let wi = (t * local.x + b * local.y + normal * local.z).normalize();
                let (lobes, pdf) = self.eval(v, wi);
                (pdf > 0.0).then_some((wi, lobes, pdf))
            }
        }
    }

    /// Origin, tnear and strand to skip for rays leaving `v` along `wi`. A hair ray skips its own fibre: past the
    /// local tube when every strand is opaque and [`tube_exit`] is defined (the tracer then needs no filter; the
    /// strand can still shadow itself where it curls back, as in the peers), otherwise by ignoring the strand.
    #[inline]
    fn spawn(&self, v: &Vertex, wi: Vec3) -> (Vec3, f32, Option<u32>) {
        match v.surface {
            Surface::Hair {
                strand,
                frame,
                axis,
                radius,
                ..
            } => {
                let exit = if self.skip_by_tube {
                    tube_exit(v.p, wi, axis, frame.u, radius)
                } else {
                    None
                };
                match exit {
                    Some(t) => (v.p, t, None),
                    None => (v.p, 0.0, Some(strand)),
                }
            }
            Surface::Lambert { normal, .. } => {
                let side = if normal.dot(wi) >= 0.0 {
                    normal
                } else {
                    -normal
                };
                (v.p + side * self.epsilon, 0.0, None)
            }
        }
    }

    /// One camera sample: `ray` from the camera, sample `index` of the pixel's `sampler`. The steps, each a
    /// method below:
    ///
    /// 1. `seen_directly`: a camera ray that finds no surface sees an emitter or the background;
    /// 2. `first_vertex_light_samples`: the first vertex's light samples;
    /// 3. `first_vertex_material_samples`: its material samples, the first of which continues the path;
    /// 4. `indirect`: the deeper vertices (`deeper_vertex`), one light and one material sample each, with
    ///    Russian roulette (`roulette`);
    /// 5. the passes: direct = steps 2 and 3, indirect = step 4, beauty = direct + indirect.
    pub fn sample(
        &self,
        ray: &Ray,
        sampler: &CameraSample,
        index: u32,
        counts: &mut RayCounts,
    ) -> PathSample {
        self.sample_recording(ray, sampler, index, counts, &mut ())
    }

    /// [`Integrator::sample`], reporting each vertex's light and rays to `record` ([`BounceRecorder`]).
    #[inline]
    pub fn sample_recording<R: BounceRecorder>(
        &self,
        ray: &Ray,
        sampler: &CameraSample,
        index: u32,
        counts: &mut RayCounts,
        record: &mut R,
    ) -> PathSample {
        let before = *counts;
        counts.camera += 1;
        // Matched by reference: the vertex (a few hundred bytes with Chiang's view terms) is not moved out.
        let found = self.find(ray, None, counts);
        let Found::Surface(first) = &found else {
            let out = self.seen_directly(ray, &found);
            record.vertex(0, out.beauty, &counts.since(&before));
            return out;
        };
        let mut out = PathSample {
            alpha: 1.0,
            ..PathSample::default()
        };
        self.shade_first(first, (sampler, index), &mut out, counts, record, &before);
        out
    }

    /// Step 5 once the first vertex is shaded (`out`'s lobes hold its light, `next` the second vertex if the path
    /// goes on): the direct pass, the deeper vertices into the indirect pass, the beauty; vertex 0's light and rays
    /// (since `before`) reported to `record`.
    #[inline]
    fn finish_path<R: BounceRecorder>(
        &self,
        out: &mut PathSample,
        next: &Option<(Vertex<'a>, LobeValues)>,
        (sampler, index): (&CameraSample, u32),
        counts: &mut RayCounts,
        record: &mut R,
        before: &RayCounts,
    ) {
        end_first_vertex(out, &counts.since(before), record);
        if self.dual.is_some() {
            // The multiple-scattered light the light samples gathered in the indirect pass (light scattered more
            // than once), by lobe as diffuse: what the path's later vertices would have brought.
            out.lobes.diffuse += Vec3A::from(out.indirect);
        }
        // By reference: the second vertex is not moved out of `next`.
        let indirect = next.as_ref().map(|(second, first_weights)| {
            self.indirect(second, first_weights, sampler, index, counts, record)
        });
        end_path(out, indirect.as_ref());
    }
}

/// The first vertex shaded (`out`'s lobes hold its light, `rays` traced since the camera ray): the direct pass,
/// reported to `record` as vertex 0.
#[inline]
pub(in crate::render) fn end_first_vertex<R: BounceRecorder>(
    out: &mut PathSample,
    rays: &RayCounts,
    record: &mut R,
) {
    out.direct = out.lobes.sum();
    // With dual scattering the light samples also gathered the multiple-scattered light (in `indirect`, 0 otherwise
    // at this point): vertex 0 brings both.
    record.vertex(0, out.direct + out.indirect, rays);
}

/// The path ended: its `indirect` light (by the first vertex's lobes, if it went beyond the first vertex) into the
/// indirect pass and the lobes, and the beauty.
#[inline]
pub(in crate::render) fn end_path(out: &mut PathSample, indirect: Option<&LobeValues>) {
    if let Some(indirect) = indirect {
        out.indirect = indirect.sum();
        add_lobes(&mut out.lobes, indirect, Vec3::ONE);
    }
    out.beauty = out.direct + out.indirect;
}
