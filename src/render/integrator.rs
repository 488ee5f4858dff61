//! The light transport of one camera sample: a path tracer with next-event estimation, combining light samples
//! and material (BSDF) samples by multiple importance sampling (Veach's power heuristic), as the thesis' RenderMan
//! setup did with its "light samples" and "material samples" (§3, §5.3, table 3).
//!
//! # Estimator
//!
//! At the **first** shading point every light gets `light_samples` samples (`lights = "all"`, RenderMan's and the
//! thesis' semantics; or, with `lights = "one"`, each of the `light_samples` samples goes to one light chosen in
//! proportion to power, as pbrt-v4 and Cycles do) and the material gets `material_samples` samples; a material sample that reaches a light (escapes to an infinite light, or hits an
//! area light) is weighted against that light's strategy with the power heuristic over the *counts* times the
//! densities, w = (n_m p_m)² / ((n_m p_m)² + (n_l p_l)²) (Veach 1997, §9.2.4). Deeper vertices take one light,
//! chosen in proportion to power, and one material sample. The first material sample at each vertex also
//! continues the path (`path_length` bounces; 0 = direct light only), with Russian roulette before each vertex after
//! the second; at the last vertex under MIS the light sample takes the whole weight and no material ray is traced.
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

use glam::Vec3;

use crate::accel::{CurveKind, Tracer};
use crate::bsdf::frame::{sin_cos_theta, strand_noise, HairFrame};
use crate::bsdf::{luminance, Lobe, LobeValues};
use crate::hair::Strands;
use crate::light::{Distribution1D, Light};
use crate::ray::Ray;
use crate::scene::{LightSelection, Material, ShadowMode, Strategy, TransmittanceMode};
use crate::shadow::ShadowMaps;
use crate::shape::Shapes;

use super::sampler::{dim, PixelSampler};

/// The largest `path_length` the sample dimensions allow: path vertices 0..=`path_length` each take a block of
/// [`dim::PER_VERTEX`] dimensions.
pub const MAX_PATH_LENGTH: u32 = dim::MAX_VERTICES - 1;

/// Light-transport settings of one render.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// Light samples per light at the first vertex.
    pub light_samples: u32,
    /// Material samples at the first vertex.
    pub material_samples: u32,
    /// Indirect bounces (0 = direct light only).
    pub path_length: u32,
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
}

impl RayCounts {
    /// Adds another tile's counts.
    pub fn add(&mut self, o: &RayCounts) {
        self.camera += o.camera;
        self.shadow += o.shadow;
        self.material += o.material;
        self.rejected += o.rejected;
        self.map_lookups += o.map_lookups;
    }

    /// Every ray traced.
    pub fn total(&self) -> u64 {
        self.camera + self.shadow + self.material
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
}

/// A shading point's scattering: a hair fibre (hair frame, strand tint on the diffuse lobe) or a two-sided Lambert
/// surface.
#[derive(Debug, Clone, Copy)]
enum Surface {
    Hair {
        frame: HairFrame,
        /// Multiplies the diffuse lobe (the strand colour, or 1).
        tint: Vec3,
        strand: u32,
        /// Fibre radius at the hit.
        radius: f32,
    },
    Lambert {
        /// The normal on the side the light leaves towards (facing ωo).
        normal: Vec3,
        albedo: Vec3,
    },
}

/// A point being shaded.
#[derive(Debug, Clone, Copy)]
struct Vertex {
    p: Vec3,
    wo: Vec3,
    surface: Surface,
}

/// What a ray found first.
enum Found {
    Surface(Vertex),
    /// An area light's radiance towards the ray origin, with the light's index.
    Emitter(Vec3, usize),
    /// Nothing: the ray left the scene.
    Escaped,
}

/// Per-frame state of the path tracer, shared by all threads.
pub struct Integrator<'a> {
    strands: &'a Strands,
    tracer: &'a dyn Tracer,
    shapes: &'a Shapes,
    lights: &'a [Light],
    material: &'a Material,
    curves: CurveKind,
    settings: Settings,
    /// Light selection ∝ power, for vertices after the first.
    select: Distribution1D,
    /// Offset of shadow-ray origins off Lambert surfaces (hair rays skip their own strand instead).
    epsilon: f32,
    /// Whether camera rays that escape see the infinite lights.
    background_visible: bool,
    /// Deep opacity maps, in `shadows = "deep-opacity"` mode.
    maps: Option<&'a ShadowMaps>,
    /// Whether a material sample can add direct light: false when the strategy is light-only or every light is a
    /// delta light (then material samples are traced only to continue paths).
    material_finds_light: bool,
}

/// Power heuristic with β = 2 for strategy densities already multiplied by their sample counts.
#[inline]
fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 && (a2 + b2).is_finite() {
        a2 / (a2 + b2)
    } else if a.is_infinite() {
        1.0
    } else {
        0.0
    }
}

/// Adds `weights ⊙ scale` lobe by lobe.
#[inline]
fn add_lobes(acc: &mut LobeValues, weights: &LobeValues, scale: Vec3) {
    for lobe in Lobe::ALL {
        *acc.get_mut(lobe) += weights.get(lobe) * scale;
    }
}

impl<'a> Integrator<'a> {
    /// The weight of a light sample of count-weighted density `p_light` against the material strategy's
    /// `p_material`.
    #[inline]
    fn light_weight(&self, p_light: f32, p_material: f32) -> f32 {
        match self.settings.strategy {
            Strategy::Mis => power_heuristic(p_light, p_material),
            Strategy::Light => 1.0,
            Strategy::Material => 0.0,
        }
    }

    /// The weight of a material sample that reached a light (the complement of [`Integrator::light_weight`]).
    #[inline]
    fn material_weight(&self, p_material: f32, p_light: f32) -> f32 {
        match self.settings.strategy {
            Strategy::Mis => power_heuristic(p_material, p_light),
            Strategy::Light => 0.0,
            Strategy::Material => 1.0,
        }
    }

    /// Resolves the per-frame state. `scene_radius` sizes infinite lights' power and the surface offset.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        strands: &'a Strands,
        tracer: &'a dyn Tracer,
        shapes: &'a Shapes,
        lights: &'a [Light],
        material: &'a Material,
        curves: CurveKind,
        settings: Settings,
        scene_radius: f32,
        background_visible: bool,
        maps: Option<&'a ShadowMaps>,
    ) -> Self {
        let powers: Vec<f32> = lights.iter().map(|l| l.power(scene_radius)).collect();
        Integrator {
            strands,
            tracer,
            shapes,
            lights,
            material,
            curves,
            settings,
            select: Distribution1D::new(&powers),
            epsilon: 1e-4 * scene_radius.max(1e-3),
            background_visible,
            maps,
            material_finds_light: settings.strategy != Strategy::Light
                && lights.iter().any(|l| !l.is_delta()),
        }
    }

    /// The shading point of a strand hit.
    fn hair_vertex(&self, ray: &Ray, hit: &crate::accel::Hit) -> Vertex {
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
        let tint = if self.material.tint_diffuse_by_strand {
            Vec3::from(self.strands.color[hit.strand as usize])
        } else {
            Vec3::ONE
        };
        Vertex {
            p: ray.at(hit.t),
            wo,
            surface: Surface::Hair {
                frame,
                tint,
                strand: hit.strand,
                radius: point.radius,
            },
        }
    }

    /// The nearest of hair, shapes and area lights along `ray`. `stochastic` = Some((key, ignore_strand)) for
    /// light-carrying rays (strands present with probability = opacity), `None` for camera rays (all opaque).
    fn find(
        &self,
        ray: &Ray,
        stochastic: Option<(u64, Option<u32>)>,
        counts: &mut RayCounts,
    ) -> Found {
        let hair = match stochastic {
            None => self.tracer.intersect(ray),
            Some((key, ignore)) => self.tracer.intersect_stochastic(ray, ignore, key),
        };
        let hair = match hair {
            Ok(h) => h,
            Err(_) => {
                counts.rejected += 1;
                return Found::Escaped;
            }
        };
        if let Some(found) = self.find_non_hair(ray, hair.map_or(ray.tfar, |h| h.t)) {
            return found;
        }
        match hair {
            Some(h) => Found::Surface(self.hair_vertex(ray, &h)),
            None => Found::Escaped,
        }
    }

    /// The nearest area light or shape along `ray` before `tfar` (hair is the caller's business), if any.
    fn find_non_hair(&self, ray: &Ray, tfar: f32) -> Option<Found> {
        let mut tmax = tfar;
        let shape = self.shapes.intersect(ray, tmax);
        if let Some(s) = shape {
            tmax = s.t;
        }
        let mut emitter = None;
        for (i, light) in self.lights.iter().enumerate() {
            if let Some((t, radiance)) =
                light.intersect(&Ray::segment(ray.origin, ray.dir, ray.tnear, tmax))
            {
                if t < tmax {
                    tmax = t;
                    emitter = Some((radiance, i));
                }
            }
        }
        if let Some((radiance, i)) = emitter {
            return Some(Found::Emitter(radiance, i));
        }
        shape.map(|s| {
            let wo = -ray.dir.normalize();
            let normal = if s.normal.dot(wo) >= 0.0 {
                s.normal
            } else {
                -s.normal
            };
            Found::Surface(Vertex {
                p: ray.at(s.t),
                wo,
                surface: Surface::Lambert {
                    normal,
                    albedo: s.albedo,
                },
            })
        })
    }

    /// f · cos θi per lobe of the hair material, in the local frame, the diffuse lobe tinted.
    #[inline]
    fn hair_fcos(&self, tint: Vec3, wo_l: Vec3, wi_l: Vec3) -> LobeValues {
        let mut lobes = self.material.bsdf.eval_lobes(wo_l, wi_l);
        lobes.diffuse *= tint;
        lobes.scaled(sin_cos_theta(wi_l).1)
    }

    /// f · cos θi per lobe, and the material's sampling pdf, for light leaving `v` along ωo arriving from `wi`.
    #[inline]
    fn eval(&self, v: &Vertex, wi: Vec3) -> (LobeValues, f32) {
        match v.surface {
            Surface::Hair { frame, tint, .. } => {
                let (wo_l, wi_l) = (frame.to_local(v.wo), frame.to_local(wi));
                (
                    self.hair_fcos(tint, wo_l, wi_l),
                    self.material.bsdf.pdf(wo_l, wi_l),
                )
            }
            Surface::Lambert { normal, albedo } => {
                let cos = normal.dot(wi);
                if cos <= 0.0 {
                    return (LobeValues::default(), 0.0);
                }
                let lobes = LobeValues {
                    diffuse: albedo * (cos * std::f32::consts::FRAC_1_PI),
                    ..LobeValues::default()
                };
                (lobes, cos * std::f32::consts::FRAC_1_PI)
            }
        }
    }

    /// A material sample at `v`: (ωi, f · cos θi per lobe, pdf).
    #[inline]
    fn sample_material(&self, v: &Vertex, u: [f32; 3]) -> Option<(Vec3, LobeValues, f32)> {
        match v.surface {
            Surface::Hair { frame, tint, .. } => {
                let wo_l = frame.to_local(v.wo);
                let s = self.material.bsdf.sample(wo_l, u)?;
                // The sample's pdf is the mixture pdf already; only the per-lobe split (and the tint) is new.
                let lobes = self.hair_fcos(tint, wo_l, s.wi);
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

    /// Origin and strand to skip for rays leaving `v` along `wi`.
    #[inline]
    fn spawn(&self, v: &Vertex, wi: Vec3) -> (Vec3, Option<u32>) {
        match v.surface {
            Surface::Hair { strand, .. } => (v.p, Some(strand)),
            Surface::Lambert { normal, .. } => {
                let side = if normal.dot(wi) >= 0.0 {
                    normal
                } else {
                    -normal
                };
                (v.p + side * self.epsilon, None)
            }
        }
    }

    /// Visibility along a light sample's shadow ray, in [0, 1].
    fn visibility(
        &self,
        light: usize,
        v: &Vertex,
        wi: Vec3,
        distance: f32,
        key: u64,
        counts: &mut RayCounts,
    ) -> f32 {
        let (origin, ignore) = self.spawn(v, wi);
        // Stop short of an area light's surface so the light itself does not occlude.
        let tfar = if distance.is_finite() {
            distance * (1.0 - 1e-4)
        } else {
            f32::INFINITY
        };
        let ray = Ray::segment(origin, wi, 0.0, tfar);
        if self.shapes.occluded(&ray, tfar) {
            counts.shadow += 1;
            return 0.0;
        }
        match self.settings.shadows {
            ShadowMode::None => return 1.0,
            ShadowMode::DeepOpacity => {
                // A far-field fibre model treats the fibre's cross-section as one point: look the light up where it
                // enters the fibre (the side facing the light), not at the hit on the viewer's side.
                let p = match v.surface {
                    Surface::Hair { radius, .. } => v.p + wi * radius,
                    Surface::Lambert { .. } => v.p,
                };
                if let Some(t) = self.maps.and_then(|m| m.transmittance(light, p, wi)) {
                    counts.map_lookups += 1;
                    return t;
                }
            }
            ShadowMode::Raytraced => {}
        }
        counts.shadow += 1;
        let result = match self.settings.transmittance {
            TransmittanceMode::Stochastic => self
                .tracer
                .occluded_stochastic(&ray, ignore, key)
                .map(|o| if o { 0.0 } else { 1.0 }),
            TransmittanceMode::Exact => self.tracer.transmittance(&ray, ignore),
        };
        result.unwrap_or_else(|_| {
            counts.rejected += 1;
            1.0
        })
    }

    /// Radiance a material-sampled direction sees of the lights: (Σ_j w_j Le_j, where the ray went).
    /// `light_density(j, wi)` is the light strategy's count-weighted density for light j.
    fn trace_material_sample(
        &self,
        v: &Vertex,
        wi: Vec3,
        pdf_m: f32,
        light_density: &dyn Fn(usize, Vec3) -> f32,
        key: u64,
        counts: &mut RayCounts,
    ) -> (Vec3, Found) {
        let (origin, ignore) = self.spawn(v, wi);
        let ray = Ray::new(origin, wi);
        counts.material += 1;
        if self.settings.shadows == ShadowMode::None {
            // No self-shadowing: the light a material sample sees ignores hair (shapes and emitters still count),
            // while the continuation still scatters at the hair it meets — a second ray, in this diagnostic mode.
            let lit = self.find_non_hair(&ray, ray.tfar).unwrap_or(Found::Escaped);
            let le = self.emitted_along(&ray, &lit, pdf_m, light_density);
            counts.material += 1;
            return (le, self.find(&ray, Some((key, ignore)), counts));
        }
        let found = self.find(&ray, Some((key, ignore)), counts);
        (
            self.emitted_along(&ray, &found, pdf_m, light_density),
            found,
        )
    }

    /// MIS-weighted emitted radiance for a material sample of density `pdf_m` (count-weighted) that found `found`.
    fn emitted_along(
        &self,
        ray: &Ray,
        found: &Found,
        pdf_m: f32,
        light_density: &dyn Fn(usize, Vec3) -> f32,
    ) -> Vec3 {
        match *found {
            Found::Escaped => self
                .lights
                .iter()
                .enumerate()
                .filter(|(_, l)| l.is_infinite() && !l.is_delta())
                .map(|(j, l)| {
                    l.le(ray.dir) * self.material_weight(pdf_m, light_density(j, ray.dir))
                })
                .fold(Vec3::ZERO, |a, b| a + b),
            Found::Emitter(radiance, j) => {
                radiance * self.material_weight(pdf_m, light_density(j, ray.dir))
            }
            Found::Surface(_) => Vec3::ZERO,
        }
    }

    /// One camera sample: `ray` from the camera, sample `index` of the pixel's `sampler`.
    pub fn sample(
        &self,
        ray: &Ray,
        sampler: &PixelSampler,
        index: u32,
        counts: &mut RayCounts,
    ) -> PathSample {
        let mut out = PathSample::default();
        counts.camera += 1;
        let first = match self.find(ray, None, counts) {
            Found::Escaped => {
                if self.background_visible {
                    out.beauty = self.lights.iter().map(|l| l.le(ray.dir.normalize())).sum();
                }
                return out;
            }
            Found::Emitter(radiance, _) => {
                out.beauty = radiance;
                out.alpha = 1.0;
                return out;
            }
            Found::Surface(v) => v,
        };
        out.alpha = 1.0;
        let s = &self.settings;

        // ---- First vertex: light_samples light samples (for every light, or each for one light chosen ∝ power),
        // and material_samples material samples. ----
        let (n_l, n_m) = (s.light_samples.max(1), s.material_samples.max(1));
        let mut direct = LobeValues::default();
        let mut light_sample =
            |j: usize, count: f32, idx: u32, salt: u32, counts: &mut RayCounts| {
                // `count` = expected number of samples light j receives here (its samples, or n_l × its selection
                // probability): the light strategy's density for MIS is count × pdf, its estimate Le f cos / (count pdf).
                let light = &self.lights[j];
                let u = [
                    sampler.get_salted(idx, dim::vertex(0, dim::LIGHT), salt),
                    sampler.get_salted(idx, dim::vertex(0, dim::LIGHT) + 1, salt),
                ];
                let Some(ls) = light.sample_li(first.p, u) else {
                    return;
                };
                let (fcos, pdf_m) = self.eval(&first, ls.wi);
                let w = if ls.delta {
                    1.0
                } else {
                    self.light_weight(count * ls.pdf, n_m as f32 * pdf_m)
                };
                let scale = ls.radiance * (w / (ls.pdf * count));
                let unshadowed = luminance(fcos.sum() * scale);
                if unshadowed <= 0.0 {
                    return;
                }
                let key = sampler.key(idx, dim::vertex(0, dim::LIGHT), salt);
                let vis = self.visibility(j, &first, ls.wi, ls.distance, key, counts);
                out.unshadowed += unshadowed;
                out.lit += unshadowed * vis;
                if vis > 0.0 {
                    add_lobes(&mut direct, &fcos, scale * vis);
                }
            };
        match s.light_selection {
            LightSelection::All => {
                for (j, light) in self.lights.iter().enumerate() {
                    let samples = if light.is_delta() {
                        1
                    } else if s.strategy == Strategy::Material {
                        continue; // every non-delta light is found by material samples only
                    } else {
                        n_l
                    };
                    for k in 0..samples {
                        light_sample(j, samples as f32, index * samples + k, j as u32, counts);
                    }
                }
            }
            LightSelection::One if !self.lights.is_empty() => {
                for k in 0..n_l {
                    let idx = index * n_l + k;
                    let (j, p_select, _) = self
                        .select
                        .sample_discrete(sampler.get(idx, dim::vertex(0, dim::LIGHT_SELECT)));
                    let light = &self.lights[j];
                    if p_select <= 0.0 || (!light.is_delta() && s.strategy == Strategy::Material) {
                        continue;
                    }
                    light_sample(j, n_l as f32 * p_select, idx, 0, counts);
                }
            }
            LightSelection::One => {}
        }
        // Count-weighted light density of light j in direction wi, at the first vertex.
        let first_light_density = |j: usize, wi: Vec3| {
            let l = &self.lights[j];
            if l.is_delta() {
                0.0
            } else {
                let count = match s.light_selection {
                    LightSelection::All => n_l as f32,
                    LightSelection::One => n_l as f32 * self.select.pmf(j),
                };
                count * l.pdf_li(first.p, wi)
            }
        };
        let mut next: Option<(Vertex, LobeValues)> = None;
        for k in 0..n_m {
            let idx = index * n_m + k;
            let d = dim::vertex(0, dim::MATERIAL);
            let u = [
                sampler.get(idx, d),
                sampler.get(idx, d + 1),
                sampler.get(idx, d + 2),
            ];
            let Some((wi, fcos, pdf)) = self.sample_material(&first, u) else {
                continue;
            };
            let weights = fcos.scaled(1.0 / pdf);
            if k == 0 {
                out.albedo = weights.sum();
            }
            let continues = k == 0 && s.path_length > 0;
            if !self.material_finds_light && !continues {
                continue; // no light to add and no path to continue: no ray
            }
            let key = sampler.key(idx, d, 0);
            let (le, found) = self.trace_material_sample(
                &first,
                wi,
                n_m as f32 * pdf,
                &first_light_density,
                key,
                counts,
            );
            if le.max_element() > 0.0 {
                add_lobes(&mut direct, &weights, le / n_m as f32);
            }
            if k == 0 && s.path_length > 0 {
                if let Found::Surface(v) = found {
                    next = Some((v, weights));
                }
            }
        }
        out.direct = direct.sum();
        out.lobes = direct;

        // ---- Deeper vertices: one light chosen ∝ power, one material sample that also continues the path. ----
        if let Some((mut v, first_weights)) = next {
            // Path throughput after the first vertex; the first vertex's own weight stays split by lobe.
            let mut rest = Vec3::ONE;
            let mut indirect = LobeValues::default();
            for b in 1..=s.path_length {
                // At the path's last vertex a material sample could only add MIS's share of light hits; under MIS
                // (and light-only sampling) the light sample takes the whole weight there instead and no material
                // ray is traced (still unbiased; saves one ray per path).
                let light_only = b == s.path_length && s.strategy != Strategy::Material;
                let mut radiance = Vec3::ZERO;
                let select_u = sampler.get(index, dim::vertex(b, dim::LIGHT_SELECT));
                if !self.lights.is_empty() {
                    let (j, p_select, _) = self.select.sample_discrete(select_u);
                    let light = &self.lights[j];
                    let u = [
                        sampler.get(index, dim::vertex(b, dim::LIGHT)),
                        sampler.get(index, dim::vertex(b, dim::LIGHT) + 1),
                    ];
                    if let Some(ls) = light.sample_li(v.p, u).filter(|_| p_select > 0.0) {
                        let (fcos, pdf_m) = self.eval(&v, ls.wi);
                        let f = fcos.sum();
                        if f.max_element() > 0.0 {
                            let w = if ls.delta || light_only {
                                1.0
                            } else {
                                self.light_weight(p_select * ls.pdf, pdf_m)
                            };
                            let key = sampler.key(index, dim::vertex(b, dim::LIGHT), 0);
                            let vis = self.visibility(j, &v, ls.wi, ls.distance, key, counts);
                            radiance += f * ls.radiance * (vis * w / (p_select * ls.pdf));
                        }
                    }
                }
                if light_only {
                    self.add_indirect(&mut indirect, &first_weights, rest * radiance);
                    break;
                }
                let d = dim::vertex(b, dim::MATERIAL);
                let u = [
                    sampler.get(index, d),
                    sampler.get(index, d + 1),
                    sampler.get(index, d + 2),
                ];
                let Some((wi, fcos, pdf)) = self.sample_material(&v, u) else {
                    self.add_indirect(&mut indirect, &first_weights, rest * radiance);
                    break;
                };
                let weight = fcos.sum() / pdf;
                let density = |j: usize, w: Vec3| {
                    let l = &self.lights[j];
                    if l.is_delta() {
                        0.0
                    } else {
                        self.select.pmf(j) * l.pdf_li(v.p, w)
                    }
                };
                let key = sampler.key(index, d, 0);
                let (le, found) = self.trace_material_sample(&v, wi, pdf, &density, key, counts);
                radiance += weight * le;
                self.add_indirect(&mut indirect, &first_weights, rest * radiance);
                let Found::Surface(nv) = found else {
                    break;
                };
                if b == s.path_length {
                    break;
                }
                rest *= weight;
                // Russian roulette before every further vertex, on the whole path throughput (hair albedos of
                // 0.3-0.7 end most paths early at no bias).
                {
                    let q = luminance(first_weights.sum() * rest).clamp(0.05, 1.0);
                    if sampler.get(index, dim::vertex(b, dim::ROULETTE)) >= q {
                        break;
                    }
                    rest /= q;
                }
                if !rest.is_finite() || rest.max_element() <= 0.0 {
                    break;
                }
                v = nv;
            }
            out.indirect = indirect.sum();
            add_lobes(&mut out.lobes, &indirect, Vec3::ONE);
        }
        out.beauty = out.direct + out.indirect;
        out
    }

    /// Adds light `l` (already multiplied by the throughput after the first vertex) arriving through the first
    /// vertex, split by its lobes, clamped per [`Settings::clamp`].
    #[inline]
    fn add_indirect(&self, acc: &mut LobeValues, first_weights: &LobeValues, l: Vec3) {
        let mut scale = l;
        if self.settings.clamp > 0.0 {
            let c = (first_weights.sum() * l).max_element();
            if c > self.settings.clamp {
                scale *= self.settings.clamp / c;
            }
        }
        if scale.is_finite() {
            add_lobes(acc, first_weights, scale);
        }
    }
}
