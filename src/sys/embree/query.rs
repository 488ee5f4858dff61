//! The queries of a [`CommittedScene`]: closest hit (opaque or stochastic), stochastic occlusion and exact
//! transmittance, each validating its ray before it reaches Embree.

use std::ptr;

use glam::Vec3;

use super::ffi::*;
#[cfg(doc)]
use super::filter::TRANSMITTANCE_CUTOFF;
#[cfg(embree4)]
use super::filter::{stochastic_filter, transmittance_filter};
use super::filter::{Cutoff, StochasticQuery, TransmittanceQuery, SEEN_STRANDS};
use super::scene::CommittedScene;
#[cfg(doc)]
use super::scene::Scene;
use crate::ray::{InvalidRay, Ray, MAX_ORIGIN};

/// The closest hit of a ray, as Embree reports it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayHit {
    /// Ray parameter of the hit (in units of the caller's `dir`).
    pub t: f32,
    /// Geometry id ([`Scene::attach`]).
    pub geom_id: u32,
    /// Primitive id: the curve segment, or the triangle.
    pub prim_id: u32,
    /// Curve parameter along the segment, in [0, 1]. Triangles: the barycentric weight of the second corner.
    pub u: f32,
    /// Round curves: 0. Flat curves: position across the ribbon, in [−1, 1]. Triangles: the weight of the third
    /// corner (the point is a + u (b − a) + v (c − a)).
    pub v: f32,
    /// Unnormalised geometric normal. Round curves: outward from the axis. Flat curves: the curve tangent.
    /// Triangles: (b − a) × (c − a).
    pub ng: Vec3,
}

/// The result of [`CommittedScene::transmittance1`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transmittance {
    /// Fraction of light passing: ∏ (1 − opacity) over distinct strands crossed, or 0 after a cutoff.
    pub value: f32,
    /// Distinct strands counted before the query ended.
    pub strands: u32,
    /// Why the query ended early, if it did.
    pub cutoff: Option<Cutoff>,
}

/// An Embree ray for a validated `ray`, and the factor by which its direction was scaled down.
///
/// Embree's own validity test (`RayK::valid`, `kernels/common/ray.h`) also requires every direction component to be
/// below ~1.8e18, which [`Ray::check`] does not ask: such a direction is scaled down, with the interval scaled up,
/// so the same points are traced; hit distances are divided back by the returned factor.
pub(super) fn embree_ray(ray: &Ray) -> Result<(RTCRay, f32), InvalidRay> {
    ray.check()?;
    let longest = ray.dir.abs().max_element();
    let (dir, scale) = if longest >= MAX_ORIGIN {
        (ray.dir / longest, longest)
    } else {
        (ray.dir, 1.0)
    };
    let rtc = RTCRay {
        org_x: ray.origin.x,
        org_y: ray.origin.y,
        org_z: ray.origin.z,
        tnear: ray.tnear * scale,
        dir_x: dir.x,
        dir_y: dir.y,
        dir_z: dir.z,
        time: 0.0,
        tfar: ray.tfar * scale,
        mask: u32::MAX,
        id: 0,
        flags: 0,
    };
    Ok((rtc, scale))
}

impl CommittedScene {
    /// The closest hit along `ray` within `[tnear, tfar]`, every strand opaque. Rays failing [`Ray::check`] never
    /// reach Embree.
    pub fn intersect1(&self, ray: &Ray) -> Result<Option<RayHit>, InvalidRay> {
        // No payload, so the presence type is only a placeholder.
        self.intersect_with(ray, None::<&mut StochasticQuery<fn(u32, f32) -> bool>>)
    }

    /// The closest hit along `ray` among the strands *present* for this ray: `present(strand, opacity)` says
    /// whether a strand exists for this ray, and must give the same answer for the same strand throughout the query
    /// (Embree reports a strand several times, in no fixed order). `ignore_strand` is never hit; primitives without
    /// strand data are always hit. `present` runs inside Embree's filter callback, once per candidate hit: it
    /// must be cheap and must not panic. (The tracer passes `accel::strand_present` under the ray's key: strand
    /// s present with probability equal to its opacity.)
    pub fn intersect1_stochastic<P: Fn(u32, f32) -> bool>(
        &self,
        ray: &Ray,
        ignore_strand: Option<u32>,
        present: P,
    ) -> Result<Option<RayHit>, InvalidRay> {
        let mut query = StochasticQuery::new(ignore_strand, present);
        self.intersect_with(ray, Some(&mut query))
    }

    /// Whether any strand blocks `ray` within `[tnear, tfar]`, every strand opaque: a plain any-hit query without a
    /// filter, for scenes where the stochastic presence test cannot reject a hit (every opacity 1, no strand to
    /// ignore). Rays failing [`Ray::check`] never reach Embree.
    pub fn occluded1(&self, ray: &Ray) -> Result<bool, InvalidRay> {
        let (mut rtc_ray, _) = embree_ray(ray)?;
        #[cfg(not(embree4))]
        {
            let mut context = init_query_context();
            // SAFETY: the scene is committed; `context` is an initialised local context without a filter; the ray
            // passed `Ray::check` and is within Embree's limits; Embree uses both only during the call.
            unsafe { rtcOccluded1(self.raw(), &mut context, &mut rtc_ray) };
        }
        #[cfg(embree4)]
        {
            // SAFETY: as for Embree 3; null arguments select Embree's defaults (no filter).
            unsafe { rtcOccluded1(self.raw(), &mut rtc_ray, ptr::null_mut()) };
        }
        self.device().after_query();
        // Embree marks an occluded ray by setting tfar to −∞.
        Ok(rtc_ray.tfar == f32::NEG_INFINITY)
    }

    /// Whether any strand present for this ray (`present` as in [`CommittedScene::intersect1_stochastic`]) blocks
    /// `ray`. With a presence test that keeps each strand with probability equal to its opacity, this is an
    /// unbiased one-sample estimate of [`CommittedScene::transmittance1`] (E[not occluded] = ∏ (1 − opacity)) at
    /// the cost of an opaque shadow ray.
    pub fn occluded1_stochastic<P: Fn(u32, f32) -> bool>(
        &self,
        ray: &Ray,
        ignore_strand: Option<u32>,
        present: P,
    ) -> Result<bool, InvalidRay> {
        let (mut rtc_ray, _) = embree_ray(ray)?;
        let mut query = StochasticQuery::new(ignore_strand, present);
        let context = ptr::addr_of_mut!(query).cast::<QueryContext>();
        #[cfg(not(embree4))]
        {
            // SAFETY: the scene is committed with `RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION`; `context` points at the
            // payload, which outlives the call; the ray passed `Ray::check`.
            unsafe { rtcOccluded1(self.raw(), context, &mut rtc_ray) };
        }
        #[cfg(embree4)]
        {
            let mut args = init_occluded_arguments();
            args.context = context.cast::<RTCRayQueryContext>();
            args.filter = Some(stochastic_filter::<P>);
            args.flags |= RTC_RAY_QUERY_FLAG_INVOKE_ARGUMENT_FILTER;
            // SAFETY: as for Embree 3, with the filter passed in the arguments.
            unsafe { rtcOccluded1(self.raw(), &mut rtc_ray, &mut args) };
        }
        self.device().after_query();
        // Embree marks an occluded ray by setting tfar to −∞.
        Ok(rtc_ray.tfar == f32::NEG_INFINITY)
    }

    /// The closest-hit query, with the stochastic filter when `query` is given.
    fn intersect_with<P: Fn(u32, f32) -> bool>(
        &self,
        ray: &Ray,
        query: Option<&mut StochasticQuery<P>>,
    ) -> Result<Option<RayHit>, InvalidRay> {
        let (rtc_ray, scale) = embree_ray(ray)?;
        let mut rayhit = RTCRayHit {
            ray: rtc_ray,
            hit: RTCHit::default(),
        };
        rayhit.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rayhit.hit.primID = RTC_INVALID_GEOMETRY_ID;
        rayhit.hit.instID.fill(RTC_INVALID_GEOMETRY_ID);
        #[cfg(not(embree4))]
        {
            let mut plain = init_query_context();
            let context = match query {
                Some(q) => ptr::from_mut(q).cast::<QueryContext>(),
                None => ptr::addr_of_mut!(plain),
            };
            // SAFETY: the scene is committed; `context` is an initialised local context or the first field of a live
            // `StochasticQuery` whose filter reads only that payload; `rayhit` is an aligned local; Embree uses both
            // only during the call; the ray passed `Ray::check` and is within Embree's limits.
            unsafe { rtcIntersect1(self.raw(), context, &mut rayhit) };
        }
        #[cfg(embree4)]
        {
            match query {
                Some(q) => {
                    let mut args = init_intersect_arguments();
                    args.flags |= RTC_RAY_QUERY_FLAG_INVOKE_ARGUMENT_FILTER;
                    args.context = ptr::from_mut(q).cast::<RTCRayQueryContext>();
                    args.filter = Some(stochastic_filter::<P>);
                    // SAFETY: as for Embree 3, with the filter passed in the arguments.
                    unsafe { intersect1(self.raw(), &mut rayhit, &mut args) };
                }
                // SAFETY: as for Embree 3; null arguments select Embree's defaults (no filter).
                None => unsafe { intersect1(self.raw(), &mut rayhit, ptr::null_mut()) },
            }
        }
        self.device().after_query();
        let hit = rayhit.hit;
        if hit.geomID == RTC_INVALID_GEOMETRY_ID {
            return Ok(None);
        }
        Ok(Some(RayHit {
            t: rayhit.ray.tfar / scale,
            geom_id: hit.geomID,
            prim_id: hit.primID,
            u: hit.u,
            v: hit.v,
            ng: Vec3::new(hit.Ng_x, hit.Ng_y, hit.Ng_z),
        }))
    }

    /// Transmittance along `ray` within `[tnear, tfar]` through semi-transparent strands: ∏ (1 − opacity) over the
    /// distinct strands crossed, each counted once however often Embree reports it, leaving out `ignore_strand`.
    /// Stops with 0 at [`TRANSMITTANCE_CUTOFF`], on a primitive without strand data, or after [`SEEN_STRANDS`]
    /// strands. Rays failing [`Ray::check`] never reach Embree.
    pub fn transmittance1(
        &self,
        ray: &Ray,
        ignore_strand: Option<u32>,
    ) -> Result<Transmittance, InvalidRay> {
        let (query, tfar) = self.all_hits(ray, TransmittanceQuery::new(ignore_strand, 0))?;
        // Embree sets tfar to −∞ when a hit was accepted; only the filter accepts hits, and it zeroes the
        // transmittance when it does.
        debug_assert!(tfar != f32::NEG_INFINITY || query.transmittance == 0.0);
        Ok(Transmittance {
            value: query.transmittance,
            strands: query.seen_len,
            cutoff: query.cutoff,
        })
    }

    /// The distinct strands `ray` crosses within `[tnear, tfar]` (of opacity above 0, however often Embree reports
    /// each), leaving out `ignore_strand`, counted up to `limit` (at most [`SEEN_STRANDS`]; a primitive without
    /// strand data counts as the limit). Rays failing [`Ray::check`] never reach Embree.
    pub fn strands_crossed1(
        &self,
        ray: &Ray,
        ignore_strand: Option<u32>,
        limit: u32,
    ) -> Result<u32, InvalidRay> {
        let limit = limit.clamp(1, SEEN_STRANDS as u32);
        let (query, _) = self.all_hits(ray, TransmittanceQuery::new(ignore_strand, limit))?;
        Ok(match query.cutoff {
            Some(Cutoff::Opaque) => limit,
            _ => query.seen_len.min(limit),
        })
    }

    /// Runs `query`'s filter over every hit along `ray` (an occlusion query whose filter rejects hits until it
    /// stops); the payload afterwards and Embree's tfar.
    fn all_hits(
        &self,
        ray: &Ray,
        mut query: TransmittanceQuery,
    ) -> Result<(TransmittanceQuery, f32), InvalidRay> {
        let (mut rtc_ray, _) = embree_ray(ray)?;
        // Embree 3: the payload's context carries the filter from construction, so nothing writes to `query`
        // through the local while Embree and the filter use the pointer below (a write through the local would
        // invalidate that pointer under Stacked Borrows).
        // Derived from the whole payload (not from `query.context`) so the filter may reach every field.
        let context = ptr::addr_of_mut!(query).cast::<QueryContext>();
        #[cfg(not(embree4))]
        {
            // SAFETY: the scene is committed with `RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION`; `context` points at the
            // payload, which outlives the call and which only the filter touches during it; the ray passed
            // `Ray::check` and is within Embree's limits.
            unsafe { rtcOccluded1(self.raw(), context, &mut rtc_ray) };
        }
        #[cfg(embree4)]
        {
            let mut args = init_occluded_arguments();
            args.context = context.cast::<RTCRayQueryContext>();
            args.filter = Some(transmittance_filter);
            args.flags |= RTC_RAY_QUERY_FLAG_INVOKE_ARGUMENT_FILTER;
            // SAFETY: as for Embree 3, with the filter passed in the arguments (scene flag
            // `RTC_SCENE_FLAG_FILTER_FUNCTION_IN_ARGUMENTS`).
            unsafe { rtcOccluded1(self.raw(), &mut rtc_ray, &mut args) };
        }
        self.device().after_query();
        Ok((query, rtc_ray.tfar))
    }
}
