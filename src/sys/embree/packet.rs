//! Packet queries of a [`CommittedScene`]: `W` = 8 or 16 rays traced by one `rtcIntersect8/16` or
//! `rtcOccluded8/16` call, with a mask of active lanes, for the same query kinds as the single-ray queries (opaque
//! and stochastic closest hit, opaque and stochastic occlusion) and with the same results per lane.
//!
//! Every lane's ray passes the same validation as a single ray ([`Ray::check`], then the direction scaling of
//! `embree_ray`); a lane that fails it is masked off and reports its error, so an invalid ray never reaches Embree
//! and does not stop the packet's other lanes. Lanes without a ray are masked off too, and their results are left
//! untouched.

use std::ptr;

use glam::Vec3;

use super::ffi::*;
use super::filter::{stochastic_packet_filter, StochasticPacket};
use super::query::{embree_ray, RayHit};
use super::scene::CommittedScene;
use crate::ray::{InvalidRay, Ray};

/// The packet widths the queries take: 8 (Embree's AVX kernels) and 16 (its AVX-512 kernels). Embree runs either
/// width on any CPU, emulating a width its kernels for the CPU lack.
pub const PACKET_WIDTHS: [usize; 2] = [8, 16];

/// Instance levels of the hit records (`RTC_MAX_INSTANCE_LEVEL_COUNT`).
const LEVELS: usize = RTC_MAX_INSTANCE_LEVEL_COUNT as usize;

/// `RTCRayHit8` or `RTCRayHit16` (`rtcore_ray.h`, Embree 3 and 4) for `W` = 8 or 16 — a ray packet and its hit
/// packet, each a structure of arrays — written once for both widths, then room for
/// `RTCHitW.instPrimID[RTC_MAX_INSTANCE_LEVEL_COUNT][W]`, which Embree ≥ 4.3 built with instance arrays appends to
/// the hit (as for single rays: `ffi::intersect1`). The ray packet alone, at offset 0, is the `RTCRay8`/`RTCRay16`
/// of the occlusion queries. Aligned to 64 bytes, as `RTCRayHit16` (`RTCRayHit8` asks 32).
#[repr(C, align(64))]
#[derive(Debug, Clone, Copy)]
struct RayHitPacket<const W: usize> {
    org_x: [f32; W],
    org_y: [f32; W],
    org_z: [f32; W],
    tnear: [f32; W],
    dir_x: [f32; W],
    dir_y: [f32; W],
    dir_z: [f32; W],
    time: [f32; W],
    tfar: [f32; W],
    mask: [u32; W],
    id: [u32; W],
    flags: [u32; W],
    ng_x: [f32; W],
    ng_y: [f32; W],
    ng_z: [f32; W],
    u: [f32; W],
    v: [f32; W],
    prim_id: [u32; W],
    geom_id: [u32; W],
    inst_id: [[u32; W]; LEVELS],
    inst_prim_id: [[u32; W]; LEVELS],
}

/// The active-lane mask of a packet query: −1 traces the lane, 0 leaves it alone. Aligned as Embree asks (32 bytes
/// for 8 lanes, 64 for 16).
#[repr(C, align(64))]
#[derive(Debug, Clone, Copy)]
struct Valid<const W: usize>([i32; W]);

/// A packet ready for Embree: the rays of the active lanes, the mask, and each lane's direction scale
/// (`embree_ray`).
struct Loaded<const W: usize> {
    packet: RayHitPacket<W>,
    valid: Valid<W>,
    scale: [f32; W],
}

impl<const W: usize> Loaded<W> {
    /// The packet for `rays`: a lane with a ray that passes validation is active, with `id` = its lane index (what
    /// the stochastic packet filter reads); a lane with an invalid ray gets its error in `out` and stays inactive;
    /// a lane without a ray stays inactive and its `out` untouched. Inactive lanes hold a harmless ray with
    /// `tfar` = −∞, as Embree's own stream code fills them. `None` when no lane is active.
    fn new<T>(rays: &[Option<Ray>; W], out: &mut [Result<T, InvalidRay>; W]) -> Option<Self> {
        const {
            assert!(
                W == 8 || W == 16,
                "Embree's packets used here have 8 or 16 lanes"
            )
        };
        let mut loaded = Loaded {
            packet: RayHitPacket {
                org_x: [0.0; W],
                org_y: [0.0; W],
                org_z: [0.0; W],
                tnear: [0.0; W],
                dir_x: [0.0; W],
                dir_y: [0.0; W],
                dir_z: [1.0; W],
                time: [0.0; W],
                tfar: [f32::NEG_INFINITY; W],
                mask: [u32::MAX; W],
                id: [0; W],
                flags: [0; W],
                ng_x: [0.0; W],
                ng_y: [0.0; W],
                ng_z: [0.0; W],
                u: [0.0; W],
                v: [0.0; W],
                prim_id: [RTC_INVALID_GEOMETRY_ID; W],
                geom_id: [RTC_INVALID_GEOMETRY_ID; W],
                inst_id: [[RTC_INVALID_GEOMETRY_ID; W]; LEVELS],
                inst_prim_id: [[RTC_INVALID_GEOMETRY_ID; W]; LEVELS],
            },
            valid: Valid([0; W]),
            scale: [1.0; W],
        };
        let mut active = false;
        for (k, ray) in rays.iter().enumerate() {
            let Some(ray) = ray else { continue };
            let (rtc, scale) = match embree_ray(ray) {
                Ok(r) => r,
                Err(e) => {
                    out[k] = Err(e);
                    continue;
                }
            };
            let p = &mut loaded.packet;
            (p.org_x[k], p.org_y[k], p.org_z[k]) = (rtc.org_x, rtc.org_y, rtc.org_z);
            (p.dir_x[k], p.dir_y[k], p.dir_z[k]) = (rtc.dir_x, rtc.dir_y, rtc.dir_z);
            (p.tnear[k], p.tfar[k], p.time[k]) = (rtc.tnear, rtc.tfar, rtc.time);
            (p.mask[k], p.flags[k]) = (rtc.mask, rtc.flags);
            p.id[k] = k as u32;
            loaded.scale[k] = scale;
            loaded.valid.0[k] = -1;
            active = true;
        }
        active.then_some(loaded)
    }

    /// The closest hits of the active lanes into `out`, as [`CommittedScene::intersect1`] reports them.
    fn hits(&self, out: &mut [Result<Option<RayHit>, InvalidRay>; W]) {
        let p = &self.packet;
        for k in (0..W).filter(|&k| self.valid.0[k] != 0) {
            out[k] = Ok((p.geom_id[k] != RTC_INVALID_GEOMETRY_ID).then(|| RayHit {
                t: p.tfar[k] / self.scale[k],
                geom_id: p.geom_id[k],
                prim_id: p.prim_id[k],
                u: p.u[k],
                v: p.v[k],
                ng: Vec3::new(p.ng_x[k], p.ng_y[k], p.ng_z[k]),
            }));
        }
    }

    /// Whether each active lane was occluded, into `out`: Embree marks an occluded ray by setting tfar to −∞.
    fn occluded(&self, out: &mut [Result<bool, InvalidRay>; W]) {
        for k in (0..W).filter(|&k| self.valid.0[k] != 0) {
            out[k] = Ok(self.packet.tfar[k] == f32::NEG_INFINITY);
        }
    }
}

/// Which Embree query a packet runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Intersect,
    Occluded,
}

/// A filter for a packet query: the context pointer (the first field of a live payload) and the filter function that
/// reads that payload (Embree 4 takes it in the query arguments; Embree 3 finds it in the context).
type PacketFilter = (*mut QueryContext, RTCFilterFunctionN);

impl CommittedScene {
    /// [`CommittedScene::intersect1`] for up to `W` rays at once (`W` = 8 or 16): each lane's closest hit, every
    /// strand opaque, into `hits`. Lanes without a ray are left untouched; an invalid ray gets its error and never
    /// reaches Embree.
    pub fn intersect_packet<const W: usize>(
        &self,
        rays: &[Option<Ray>; W],
        hits: &mut [Result<Option<RayHit>, InvalidRay>; W],
    ) {
        if let Some(mut loaded) = Loaded::new(rays, hits) {
            self.trace_packet(Kind::Intersect, &mut loaded, None);
            loaded.hits(hits);
        }
    }

    /// [`CommittedScene::intersect1_stochastic`] for up to `W` rays at once: lane k ignores `ignore_strand[k]` and
    /// sees the strands for which `present(k, strand, opacity)` holds (the same contract as the single-ray
    /// presence test, per lane). Lanes as in [`CommittedScene::intersect_packet`].
    pub fn intersect_packet_stochastic<const W: usize, P: Fn(usize, u32, f32) -> bool>(
        &self,
        rays: &[Option<Ray>; W],
        ignore_strand: &[Option<u32>; W],
        present: P,
        hits: &mut [Result<Option<RayHit>, InvalidRay>; W],
    ) {
        if let Some(mut loaded) = Loaded::new(rays, hits) {
            let mut query = StochasticPacket::new(ignore_strand, present);
            let context = ptr::addr_of_mut!(query).cast::<QueryContext>();
            let filter: RTCFilterFunctionN = Some(stochastic_packet_filter::<P, W>);
            self.trace_packet(Kind::Intersect, &mut loaded, Some((context, filter)));
            loaded.hits(hits);
        }
    }

    /// [`CommittedScene::occluded1`] for up to `W` rays at once. Lanes as in [`CommittedScene::intersect_packet`].
    pub fn occluded_packet<const W: usize>(
        &self,
        rays: &[Option<Ray>; W],
        occluded: &mut [Result<bool, InvalidRay>; W],
    ) {
        if let Some(mut loaded) = Loaded::new(rays, occluded) {
            self.trace_packet(Kind::Occluded, &mut loaded, None);
            loaded.occluded(occluded);
        }
    }

    /// [`CommittedScene::occluded1_stochastic`] for up to `W` rays at once, with the per-lane ignored strands and
    /// presence test of [`CommittedScene::intersect_packet_stochastic`].
    pub fn occluded_packet_stochastic<const W: usize, P: Fn(usize, u32, f32) -> bool>(
        &self,
        rays: &[Option<Ray>; W],
        ignore_strand: &[Option<u32>; W],
        present: P,
        occluded: &mut [Result<bool, InvalidRay>; W],
    ) {
        if let Some(mut loaded) = Loaded::new(rays, occluded) {
            let mut query = StochasticPacket::new(ignore_strand, present);
            let context = ptr::addr_of_mut!(query).cast::<QueryContext>();
            let filter: RTCFilterFunctionN = Some(stochastic_packet_filter::<P, W>);
            self.trace_packet(Kind::Occluded, &mut loaded, Some((context, filter)));
            loaded.occluded(occluded);
        }
    }

    /// `rtcIntersect8/16` or `rtcOccluded8/16` on `loaded`, with `filter` when given. Embree 3 finds the filter in
    /// the payload's context (set by `StochasticPacket::new`); Embree 4 takes it in the query arguments.
    fn trace_packet<const W: usize>(
        &self,
        kind: Kind,
        loaded: &mut Loaded<W>,
        filter: Option<PacketFilter>,
    ) {
        let valid = loaded.valid.0.as_ptr();
        let scene = self.raw();
        let packet = ptr::addr_of_mut!(loaded.packet);
        #[cfg(not(embree4))]
        {
            let mut plain = init_query_context();
            let context = filter.map_or(ptr::addr_of_mut!(plain), |(context, _)| context);
            match (kind, W) {
                // SAFETY: the scene is committed (with `RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION`); `valid` and
                // `packet` are aligned locals laid out as Embree's 8-wide mask and `RTCRayHit8` (layout tested);
                // `context` is an initialised local context or the first field of a live payload whose filter
                // reads only that payload; every active lane passed `Ray::check`; Embree uses all of them only
                // during the call.
                (Kind::Intersect, 8) => unsafe {
                    rtcIntersect8(valid, scene, context, packet.cast())
                },
                // SAFETY: as for 8 lanes, with the 16-wide mask and `RTCRayHit16`.
                (Kind::Intersect, _) => unsafe {
                    rtcIntersect16(valid, scene, context, packet.cast())
                },
                // SAFETY: as for the intersection; the ray packet alone (offset 0) is an `RTCRay8`.
                (Kind::Occluded, 8) => unsafe {
                    rtcOccluded8(valid, scene, context, packet.cast())
                },
                // SAFETY: as for 8 lanes; the ray packet alone is an `RTCRay16`.
                (Kind::Occluded, _) => unsafe {
                    rtcOccluded16(valid, scene, context, packet.cast())
                },
            }
        }
        #[cfg(embree4)]
        match kind {
            Kind::Intersect => {
                let mut args = init_intersect_arguments();
                let args = match filter {
                    Some((context, filter)) => {
                        args.context = context.cast::<RTCRayQueryContext>();
                        args.filter = filter;
                        args.flags |= RTC_RAY_QUERY_FLAG_INVOKE_ARGUMENT_FILTER;
                        ptr::addr_of_mut!(args)
                    }
                    // Null arguments select Embree's defaults (no filter).
                    None => ptr::null_mut(),
                };
                match W {
                    // SAFETY: the scene is committed (with `RTC_SCENE_FLAG_FILTER_FUNCTION_IN_ARGUMENTS`); `valid`
                    // and `packet` are aligned locals laid out as Embree's 8-wide mask and `RTCRayHit8`, with room
                    // for `instPrimID` (layout tested); `args` is null or a local whose context is the first field
                    // of a live payload that its filter reads; every active lane passed `Ray::check`; Embree uses
                    // all of them only during the call.
                    8 => unsafe { rtcIntersect8(valid, scene, packet.cast(), args) },
                    // SAFETY: as for 8 lanes, with the 16-wide mask and `RTCRayHit16`.
                    _ => unsafe { rtcIntersect16(valid, scene, packet.cast(), args) },
                }
            }
            Kind::Occluded => {
                let mut args = init_occluded_arguments();
                let args = match filter {
                    Some((context, filter)) => {
                        args.context = context.cast::<RTCRayQueryContext>();
                        args.filter = filter;
                        args.flags |= RTC_RAY_QUERY_FLAG_INVOKE_ARGUMENT_FILTER;
                        ptr::addr_of_mut!(args)
                    }
                    None => ptr::null_mut(),
                };
                match W {
                    // SAFETY: as for the intersection; the ray packet alone (offset 0) is an `RTCRay8`.
                    8 => unsafe { rtcOccluded8(valid, scene, packet.cast(), args) },
                    // SAFETY: as for 8 lanes; the ray packet alone is an `RTCRay16`.
                    _ => unsafe { rtcOccluded16(valid, scene, packet.cast(), args) },
                }
            }
        }
        self.device().after_query();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{align_of, offset_of, size_of};

    #[test]
    fn packets_are_embree_ray_hits_with_room_for_inst_prim_id() {
        macro_rules! check {
            ($w:literal, $rayhit:ty, $ray:ty, $hit:ty) => {{
                type P = RayHitPacket<$w>;
                assert_eq!(offset_of!(P, org_x), offset_of!($ray, org_x));
                assert_eq!(offset_of!(P, tfar), offset_of!($ray, tfar));
                assert_eq!(offset_of!(P, id), offset_of!($ray, id));
                assert_eq!(offset_of!(P, flags), offset_of!($ray, flags));
                let hit = offset_of!($rayhit, hit);
                assert_eq!(offset_of!(P, ng_x), hit + offset_of!($hit, Ng_x));
                assert_eq!(offset_of!(P, u), hit + offset_of!($hit, u));
                assert_eq!(offset_of!(P, prim_id), hit + offset_of!($hit, primID));
                assert_eq!(offset_of!(P, geom_id), hit + offset_of!($hit, geomID));
                assert_eq!(offset_of!(P, inst_id), hit + offset_of!($hit, instID));
                assert!(size_of::<P>() >= size_of::<$rayhit>());
                // instPrimID[levels][W] right after instID, as Embree >= 4.3 writes it.
                assert_eq!(
                    offset_of!(P, inst_prim_id),
                    offset_of!(P, inst_id) + 4 * $w * LEVELS
                );
                assert!(align_of::<P>() >= align_of::<$rayhit>());
                assert!(align_of::<Valid<$w>>() >= 4 * $w);
            }};
        }
        check!(8, RTCRayHit8, RTCRay8, RTCHit8);
        check!(16, RTCRayHit16, RTCRay16, RTCHit16);
    }
}
