//! The integrator's rays: what a camera or material ray finds first (hair, a shape, an area light, or nothing),
//! the visibility along a light sample's shadow ray, and the MIS-weighted light a material sample brings back.

use glam::Vec3;

use crate::bsdf::dual::Crossed;
use crate::light::LightSample;
use crate::ray::Ray;
use crate::shape::ShapeHit;

use super::mis::Mis;
use super::{Integrator, RayCounts, ShadowMode, Surface, TransmittanceMode, Vertex};

/// What a ray found first.
#[allow(clippy::large_enum_variant)] // a stack value for one path step, like `Surface`
pub(in crate::render) enum Found<'a> {
    Surface(Vertex<'a>),
    /// An area light's radiance towards the ray origin, with the light's index.
    Emitter(Vec3, usize),
    /// Nothing: the ray left the scene.
    Escaped,
}

impl Found<'_> {
    /// What the ray reached, without the shading point (a few bytes to pass around instead of a vertex).
    #[inline]
    pub(super) fn reached(&self) -> Reached {
        match *self {
            Found::Surface(_) => Reached::Surface,
            Found::Emitter(radiance, j) => Reached::Emitter(radiance, j),
            Found::Escaped => Reached::Escaped,
        }
    }
}

/// [`Found`] without the shading point: what the light a material sample brings back depends on.
#[derive(Debug, Clone, Copy)]
pub(super) enum Reached {
    Surface,
    Emitter(Vec3, usize),
    Escaped,
}

impl Reached {
    /// What a ray reached when hair is left out: a shape, an area light, or nothing.
    #[inline]
    fn without_hair(other: Option<NonHair>) -> Reached {
        match other {
            Some(NonHair::Shape(_)) => Reached::Surface,
            Some(NonHair::Emitter(radiance, j)) => Reached::Emitter(radiance, j),
            None => Reached::Escaped,
        }
    }
}

/// What a ray meets besides hair: a shape (its hit) or an area light (its radiance towards the ray and index).
#[derive(Debug, Clone, Copy)]
enum NonHair {
    Shape(ShapeHit),
    Emitter(Vec3, usize),
}

impl<'a> Integrator<'a> {
    /// The nearest of hair, shapes and area lights along `ray`. `stochastic` = Some((key, ignore_strand)) for
    /// light-carrying rays (strands present with probability = opacity), `None` for camera rays (all opaque).
    #[inline(always)]
    pub(in crate::render) fn find(
        &self,
        ray: &Ray,
        stochastic: Option<(u64, Option<u32>)>,
        counts: &mut RayCounts,
    ) -> Found<'a> {
        self.find_with(ray, stochastic, counts, true)
    }

    /// [`Integrator::find`], a hair vertex with its material prepared for ωo only if `view` (the wavefront
    /// prepares eight at a time, [`crate::render::wavefront`]).
    #[inline(always)]
    pub(in crate::render) fn find_with(
        &self,
        ray: &Ray,
        stochastic: Option<(u64, Option<u32>)>,
        counts: &mut RayCounts,
        view: bool,
    ) -> Found<'a> {
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
            Some(h) => Found::Surface(self.hair_vertex(ray, &h, view)),
            None => Found::Escaped,
        }
    }

    /// The nearest area light or shape along `ray` before `tfar` (hair is the caller's business), if any.
    fn find_non_hair(&self, ray: &Ray, tfar: f32) -> Option<Found<'a>> {
        let other = self.nearest_non_hair(ray, tfar).1?;
        Some(self.non_hair_found(ray, other))
    }

    /// What `ray` found in a [`NonHair`]: an emitter, or the shading point on a shape.
    fn non_hair_found(&self, ray: &Ray, other: NonHair) -> Found<'a> {
        match other {
            NonHair::Emitter(radiance, i) => Found::Emitter(radiance, i),
            NonHair::Shape(s) => {
                let wo = -ray.dir.normalize();
                // The side the ray came from is the geometric normal's to decide; a smooth mesh's shading normal
                // can lean past the view direction at a silhouette.
                let normal = if s.geometric.dot(wo) >= 0.0 {
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
            }
        }
    }

    /// The nearest area light or shape along `ray` before `tfar`, and the distance it lies at (`tfar` if nothing).
    /// Returns at once in scenes with neither ([`Integrator::non_hair`]).
    #[inline]
    fn nearest_non_hair(&self, ray: &Ray, tfar: f32) -> (f32, Option<NonHair>) {
        if !self.non_hair {
            return (tfar, None);
        }
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
        match (emitter, shape) {
            (Some((radiance, i)), _) => (tmax, Some(NonHair::Emitter(radiance, i))),
            (None, shape) => (tmax, shape.map(NonHair::Shape)),
        }
    }

    /// Visibility along a light sample's shadow ray, in [0, 1].
    pub(in crate::render) fn visibility(
        &self,
        light: usize,
        v: &Vertex,
        wi: Vec3,
        distance: f32,
        key: u64,
        counts: &mut RayCounts,
    ) -> f32 {
        let (ray, ignore) = self.shadow_ray(v, wi, distance);
        let tfar = ray.tfar;
        if self.shapes.occluded(&ray, tfar) {
            counts.shadow += 1;
            return 0.0;
        }
        match self.settings.shadows {
            ShadowMode::None => return 1.0,
            ShadowMode::DeepOpacity => {
                if let Some(t) = self.map_transmittance(light, v, wi, counts) {
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

    /// A light sample's shadow ray from `v` along `wi` towards a light `distance` away (∞ for infinite lights)
    /// and the strand it leaves out.
    fn shadow_ray(&self, v: &Vertex, wi: Vec3, distance: f32) -> (Ray, Option<u32>) {
        let (origin, tnear, ignore) = self.spawn(v, wi);
        // Stop short of an area light's surface so the light itself does not occlude.
        let tfar = if distance.is_finite() {
            distance * (1.0 - 1e-4)
        } else {
            f32::INFINITY
        };
        // A light closer than the fibre's tube exit: ignore the strand instead.
        let (tnear, ignore) = match (tnear < tfar, v.surface) {
            (false, Surface::Hair { strand, .. }) => (0.0, Some(strand)),
            _ => (tnear, ignore),
        };
        (Ray::segment(origin, wi, tnear, tfar), ignore)
    }

    /// The strands light sample `ls` of light `j` crosses towards `v` and behind it, for dual scattering, at most
    /// `limits` (ahead, behind; `behind` 0 skips them): read from the light's deep opacity map in deep-opacity
    /// mode (where it has one), else counted along two rays; `None` when a shape blocks the light. Without shadows,
    /// none.
    pub(in crate::render) fn strands_crossed(
        &self,
        j: usize,
        v: &Vertex,
        ls: &LightSample,
        (ahead, behind): (u32, u32),
        counts: &mut RayCounts,
    ) -> Option<Crossed> {
        let (ray, ignore) = self.shadow_ray(v, ls.wi, ls.distance);
        if self.shapes.occluded(&ray, ray.tfar) {
            return None;
        }
        match self.settings.shadows {
            ShadowMode::None => return Some(Crossed::counted(0, 0)),
            ShadowMode::DeepOpacity => {
                let p = self.map_point(v, ls.wi);
                if let Some([n, m, direct]) = self.maps.and_then(|maps| maps.strands(j, p, ls.wi)) {
                    counts.map_lookups += 1;
                    return Some(Crossed {
                        ahead: n.min(ahead as f32),
                        // m ≥ 0, so a limit of 0 (no count behind) gives 0.
                        behind: m.min(behind as f32),
                        direct,
                    });
                }
            }
            ShadowMode::Raytraced => {}
        }
        let n = self.count_strands(&ray, ignore, ahead, counts);
        let m = if behind > 0 {
            self.strands_behind(v, ls.wi, behind, counts)
        } else {
            0
        };
        Some(Crossed::counted(n, m))
    }

    /// The strands behind `v` as seen from a light in direction `wi` (along −ωi, to infinity; shapes do not stop
    /// the count), up to `limit`, for the layered form of dual scattering.
    pub(in crate::render) fn strands_behind(
        &self,
        v: &Vertex,
        wi: Vec3,
        limit: u32,
        counts: &mut RayCounts,
    ) -> u32 {
        if self.settings.shadows == ShadowMode::None {
            return 0;
        }
        let (ray, ignore) = self.shadow_ray(v, -wi, f32::INFINITY);
        self.count_strands(&ray, ignore, limit, counts)
    }

    /// The tracer's strand count along `ray`, counted in `counts`.
    fn count_strands(
        &self,
        ray: &Ray,
        ignore: Option<u32>,
        limit: u32,
        counts: &mut RayCounts,
    ) -> u32 {
        counts.counted += 1;
        let n = self
            .tracer
            .strands_crossed(ray, ignore, limit)
            .unwrap_or_else(|_| {
                counts.rejected += 1;
                0
            });
        counts.crossed += u64::from(n);
        n
    }

    /// The deep opacity maps' transmittance from `v` towards light `light` along `wi`, or `None` outside
    /// deep-opacity mode or when the light has no map (it needs a shadow ray).
    #[inline]
    fn map_transmittance(
        &self,
        light: usize,
        v: &Vertex,
        wi: Vec3,
        counts: &mut RayCounts,
    ) -> Option<f32> {
        if self.settings.shadows != ShadowMode::DeepOpacity {
            return None;
        }
        let t = self.maps?.transmittance(light, self.map_point(v, wi), wi)?;
        counts.map_lookups += 1;
        Some(t)
    }

    /// Where a map lookup from `v` towards `wi` reads: a far-field fibre model treats the fibre's cross-section as
    /// one point, so the light is looked up where it enters the fibre (the side facing the light), not at the hit
    /// on the viewer's side.
    fn map_point(&self, v: &Vertex, wi: Vec3) -> Vec3 {
        match v.surface {
            Surface::Hair { radius, .. } => v.p + wi * radius,
            Surface::Lambert { .. } => v.p,
        }
    }

    /// The light a material sample along `ray` (from `v`, density `pdf` per sample) brings back in deep-opacity
    /// mode: what it reaches with hair left out (shapes still block), each light's MIS-weighted share times the
    /// maps' transmittance towards that light, the visibility a light sample of it gets. So the light and the
    /// material samples estimate the same integral, ∫ f L T_map cos, and MIS combines them; the hair the ray
    /// meets only continues the path. A light without a map (an area light inside the hair's bounds) is seen
    /// through the hair by a stochastic occlusion query, as its light samples' shadow rays are.
    fn mapped_light(
        &self,
        v: &Vertex,
        mis: &Mis,
        ray: &Ray,
        pdf: f32,
        (key, ignore): (u64, Option<u32>),
        counts: &mut RayCounts,
    ) -> Vec3 {
        let (t_end, other) = self.nearest_non_hair(ray, ray.tfar);
        let mut visibility = |j: usize| match self.map_transmittance(j, v, ray.dir, counts) {
            Some(t) => t,
            None => {
                let segment = Ray::segment(ray.origin, ray.dir, ray.tnear, t_end);
                if self.hair_blocks(&segment, ignore, key, counts) {
                    0.0
                } else {
                    1.0
                }
            }
        };
        self.emitted_along_with(
            v,
            mis,
            ray,
            Reached::without_hair(other),
            pdf,
            &mut visibility,
        )
    }

    /// Traces a material sample leaving `v` along `wi`, drawn with density `pdf` (per sample) at a vertex weighted
    /// by `mis`: (Σ_j w_m,j L_e,j of the lights it reaches, where the ray went; a hair vertex found there with its
    /// view prepared only if `view`).
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    pub(in crate::render) fn trace_material_sample(
        &self,
        v: &Vertex,
        mis: &Mis,
        wi: Vec3,
        pdf: f32,
        key: u64,
        counts: &mut RayCounts,
        view: bool,
    ) -> (Vec3, Found<'a>) {
        let (origin, tnear, ignore) = self.spawn(v, wi);
        let ray = Ray::segment(origin, wi, tnear, f32::INFINITY);
        counts.material += 1;
        if self.settings.shadows == ShadowMode::None {
            // No self-shadowing: the light a material sample sees ignores hair (shapes and emitters still count),
            // while the continuation still scatters at the hair it meets — a second ray, in this diagnostic mode.
            let lit = Reached::without_hair(self.nearest_non_hair(&ray, ray.tfar).1);
            let le = self.emitted_along(v, mis, &ray, lit, pdf);
            counts.material += 1;
            return (le, self.find_with(&ray, Some((key, ignore)), counts, view));
        }
        let found = self.find_with(&ray, Some((key, ignore)), counts, view);
        let le = if self.settings.shadows == ShadowMode::DeepOpacity {
            self.mapped_light(v, mis, &ray, pdf, (key, ignore), counts)
        } else {
            self.emitted_along(v, mis, &ray, found.reached(), pdf)
        };
        (le, found)
    }

    /// [`Integrator::trace_material_sample`] for a material sample that does not continue the path (it only looks
    /// for light, for MIS): the emitted light it reaches, found with an any-hit query for hair in front of the
    /// nearest shape or emitter instead of a closest hit. The same answer — a strand present for `key` blocks it
    /// exactly when the closest present strand is nearer — for fewer traversal steps (an occlusion query stops at
    /// the first strand it finds, and most such rays start inside the fur).
    pub(in crate::render) fn trace_material_light(
        &self,
        v: &Vertex,
        mis: &Mis,
        wi: Vec3,
        pdf: f32,
        key: u64,
        counts: &mut RayCounts,
    ) -> Vec3 {
        let (origin, tnear, ignore) = self.spawn(v, wi);
        let ray = Ray::segment(origin, wi, tnear, f32::INFINITY);
        counts.material += 1;
        if self.settings.shadows == ShadowMode::DeepOpacity {
            return self.mapped_light(v, mis, &ray, pdf, (key, ignore), counts);
        }
        let (t_end, other) = self.nearest_non_hair(&ray, ray.tfar);
        let reached = Reached::without_hair(other);
        if let Reached::Surface = reached {
            // A shape emits nothing: whatever hair lies before it, the sample brings no light.
            return Vec3::ZERO;
        }
        if self.settings.shadows != ShadowMode::None
            && t_end > tnear
            && self.hair_blocks(&Ray::segment(origin, wi, tnear, t_end), ignore, key, counts)
        {
            return Vec3::ZERO;
        }
        self.emitted_along(v, mis, &ray, reached, pdf)
    }

    /// Whether a strand present for `key` (strands present with probability = opacity; `ignore` left out) lies on
    /// `segment`: the any-hit query of a material sample looking for light. As [`Integrator::find`], a refused ray
    /// counts as rejected and finds nothing.
    fn hair_blocks(
        &self,
        segment: &Ray,
        ignore: Option<u32>,
        key: u64,
        counts: &mut RayCounts,
    ) -> bool {
        self.tracer
            .occluded_stochastic(segment, ignore, key)
            .unwrap_or_else(|_| {
                counts.rejected += 1;
                false
            })
    }

    /// The emitted radiance a material sample from `v` along `ray` (density `pdf` per sample) finds in `found`,
    /// each light's share weighted by [`Mis::material_weight`] against that light's own density for the direction:
    /// every non-delta infinite light if it escaped, the area light it hit, nothing at a surface.
    fn emitted_along(&self, v: &Vertex, mis: &Mis, ray: &Ray, reached: Reached, pdf: f32) -> Vec3 {
        self.emitted_along_with(v, mis, ray, reached, pdf, &mut |_| 1.0)
    }

    /// [`Integrator::emitted_along`] with each light's share times `visibility(j)` (deep-opacity mode's
    /// transmittance, [`Integrator::mapped_light`]); asked only of lights the sample reaches.
    fn emitted_along_with(
        &self,
        v: &Vertex,
        mis: &Mis,
        ray: &Ray,
        reached: Reached,
        pdf: f32,
        visibility: &mut dyn FnMut(usize) -> f32,
    ) -> Vec3 {
        let p_material = mis.material_density(pdf);
        let weight = |j: usize| {
            let p_light = mis.light_density(&self.lights[j], self.select.pmf(j), v.p, ray.dir);
            mis.material_weight(p_material, p_light)
        };
        match reached {
            // An infinite light's radiance and density from one lookup of the direction (a map's texel and its
            // sampling density share the uv).
            Reached::Escaped => self
                .lights
                .iter()
                .enumerate()
                .filter(|(_, l)| l.is_infinite() && !l.is_delta())
                .map(|(j, l)| {
                    let (le, pdf_li) = l.le_and_pdf(ray.dir);
                    let p_light = mis.light_count(false, self.select.pmf(j)) * pdf_li;
                    let w = mis.material_weight(p_material, p_light);
                    if le.max_element() > 0.0 && w > 0.0 {
                        le * w * visibility(j)
                    } else {
                        Vec3::ZERO
                    }
                })
                .fold(Vec3::ZERO, |a, b| a + b),
            Reached::Emitter(radiance, j) => {
                let w = weight(j);
                if w > 0.0 {
                    radiance * w * visibility(j)
                } else {
                    Vec3::ZERO
                }
            }
            Reached::Surface => Vec3::ZERO,
        }
    }
}
