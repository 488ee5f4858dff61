//! The C side of the wrapper: bindgen's output for `ffi/embree.h` (see `build.rs`) and hand-written replacements for
//! what bindgen cannot translate (macros that cast, and inline functions), each naming the header it mirrors.

/// The bindgen output for `ffi/embree.h` (see `build.rs`), with its layout tests.
#[allow(
    non_upper_case_globals,
    non_camel_case_types,
    non_snake_case,
    dead_code,
    missing_docs,
    unsafe_op_in_unsafe_fn,
    clippy::all,
    clippy::pedantic
)]
mod bindings {
    include!(concat!(env!("OUT_DIR"), "/embree_bindings.rs"));
}

pub(super) use bindings::*;

/// `RTC_INVALID_GEOMETRY_ID` from `rtcore_common.h` (Embree 3 and 4): `((unsigned int)-1)`, a cast macro bindgen
/// skips.
pub(super) const RTC_INVALID_GEOMETRY_ID: u32 = u32::MAX;

/// The query context Embree hands to filter functions: `RTCIntersectContext` in Embree 3.
#[cfg(not(embree4))]
pub(super) type QueryContext = RTCIntersectContext;
/// Mirrors `rtcInitIntersectContext` (`embree3/rtcore_common.h`, an inline function).
///
/// Starting from the zeroed `Default` also sets `instStackSize` and `minWidthDistanceFactor` to 0 in builds that
/// have them (`RTC_MAX_INSTANCE_LEVEL_COUNT > 1`, `RTC_MIN_WIDTH`), as the header does.
#[cfg(not(embree4))]
#[allow(clippy::field_reassign_with_default)] // which fields exist depends on Embree's build options
pub(super) fn init_query_context() -> QueryContext {
    let mut context = RTCIntersectContext::default();
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
    context.filter = None;
    context.instID.fill(RTC_INVALID_GEOMETRY_ID);
    context
}

/// The query context Embree hands to filter functions: `RTCRayQueryContext` in Embree 4, followed by room for the
/// `instPrimID[RTC_MAX_INSTANCE_LEVEL_COUNT]` that Embree ≥ 4.3 built with instance arrays appends to it.
///
/// Headers older than the library (4.2's with a 4.4 library, as `scripts/embree4.sh` lays out) lack that field,
/// but the library reads it when it records a hit; with this layout it reads cuticle's own
/// `RTC_INVALID_GEOMETRY_ID`s, not the payload that follows the context. With headers that have the field it is
/// spare.
#[cfg(embree4)]
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub(super) struct QueryContext {
    raw: RTCRayQueryContext,
    inst_prim_id: [u32; RTC_MAX_INSTANCE_LEVEL_COUNT as usize],
}

/// Mirrors `rtcInitRayQueryContext` (`embree4/rtcore_common.h`, an inline function): every `instID` (and, in
/// Embree ≥ 4.3 with instance arrays, every `instPrimID`) `RTC_INVALID_GEOMETRY_ID`. Starting from the zeroed
/// `Default` also sets `instStackSize` to 0 in builds that have it (`RTC_MAX_INSTANCE_LEVEL_COUNT > 1`).
#[cfg(embree4)]
#[allow(clippy::field_reassign_with_default)] // which fields exist depends on Embree's build options
pub(super) fn init_query_context() -> QueryContext {
    let mut raw = RTCRayQueryContext::default();
    raw.instID.fill(RTC_INVALID_GEOMETRY_ID);
    QueryContext {
        raw,
        inst_prim_id: [RTC_INVALID_GEOMETRY_ID; RTC_MAX_INSTANCE_LEVEL_COUNT as usize],
    }
}

/// Mirrors `rtcInitIntersectArguments` (`embree4/rtcore_scene.h`, an inline function): incoherent rays, all
/// features, no context, no filter, no user-geometry callback, `minWidthDistanceFactor` 0 (zeroed by `Default`).
#[cfg(embree4)]
#[allow(clippy::field_reassign_with_default)] // which fields exist depends on Embree's build options
pub(super) fn init_intersect_arguments() -> RTCIntersectArguments {
    let mut args = RTCIntersectArguments::default();
    args.flags = RTC_RAY_QUERY_FLAG_INCOHERENT;
    args.feature_mask = RTC_FEATURE_FLAG_ALL;
    args
}

/// Mirrors `rtcInitOccludedArguments` (`embree4/rtcore_scene.h`, an inline function): as
/// [`init_intersect_arguments`].
#[cfg(embree4)]
#[allow(clippy::field_reassign_with_default)] // which fields exist depends on Embree's build options
pub(super) fn init_occluded_arguments() -> RTCOccludedArguments {
    let mut args = RTCOccludedArguments::default();
    args.flags = RTC_RAY_QUERY_FLAG_INCOHERENT;
    args.feature_mask = RTC_FEATURE_FLAG_ALL;
    args
}

/// An `RTCRayHit` followed by room for `RTCHit.instPrimID[RTC_MAX_INSTANCE_LEVEL_COUNT]`, the field Embree ≥ 4.3
/// built with instance arrays appends to the hit (`RTC_GEOMETRY_INSTANCE_ARRAY`, `rtcore_ray.h`).
#[cfg(embree4)]
#[repr(C)]
struct RayHitStorage {
    rayhit: RTCRayHit,
    inst_prim_id: [u32; RTC_MAX_INSTANCE_LEVEL_COUNT as usize],
}

/// `rtcIntersect1` on a copy of `rayhit` with room for `instPrimID` behind it, copied back after the call.
///
/// Measured: Embree 4.4 (the `embreex` wheel) writes `instPrimID[0]` at byte 80 of every hit record, right after the
/// 80-byte `RTCRayHit` of Embree 4.2's headers (the newest on crates.io); its own `RTCRayHit` is 96 bytes. Passing
/// a bare `RTCRayHit` would let it overwrite whatever follows on the caller's stack. `RayHitStorage` is 96 bytes
/// with 4.2's headers, and only larger than needed with headers that have the field.
///
/// # Safety
/// As `rtcIntersect1`: `scene` is a live committed scene, `args` null or valid arguments (with a context that lives
/// through the call), and the ray within Embree's limits.
#[cfg(embree4)]
pub(super) unsafe fn intersect1(
    scene: RTCScene,
    rayhit: &mut RTCRayHit,
    args: *mut RTCIntersectArguments,
) {
    let mut storage = RayHitStorage {
        rayhit: *rayhit,
        inst_prim_id: [RTC_INVALID_GEOMETRY_ID; RTC_MAX_INSTANCE_LEVEL_COUNT as usize],
    };
    // SAFETY: the caller's contract, and `storage` has room for every field Embree 4.x writes into a hit.
    unsafe { rtcIntersect1(scene, &mut storage.rayhit, args) };
    *rayhit = storage.rayhit;
}

/// Mirrors `RTCHitN_primID` (`rtcore_ray.h`, Embree 3 and 4; a C++-only inline accessor): the hit packet of width
/// `n` is stored as structure-of-arrays and `primID` is its sixth field.
///
/// # Safety
/// `hit` must point at a hit packet of width `n` (as passed to a filter function), and `i < n`.
pub(super) unsafe fn hit_n_prim_id(hit: *const RTCHitN, n: u32, i: u32) -> u32 {
    let index = 5 * n as usize + i as usize;
    // SAFETY: the caller guarantees a packet of width `n`, whose sixth row of `n` u32s holds primID, and `i < n`.
    unsafe { *hit.cast::<u32>().add(index) }
}

/// Mirrors `RTCRayN_id` (`rtcore_ray.h`, Embree 3 and 4; a C++-only inline accessor): the ray packet of width `n`
/// is stored as structure-of-arrays and `id` is its eleventh field (after origin, tnear, direction, time, tfar and
/// mask).
///
/// # Safety
/// `ray` must point at a ray packet of width `n` (as passed to a filter function), and `i < n`.
pub(super) unsafe fn ray_n_id(ray: *const RTCRayN, n: u32, i: u32) -> u32 {
    let index = 10 * n as usize + i as usize;
    // SAFETY: the caller guarantees a packet of width `n`, whose eleventh row of `n` u32s holds id, and `i < n`.
    unsafe { *ray.cast::<u32>().add(index) }
}

#[cfg(all(test, embree4))]
mod tests {
    use super::*;
    use std::mem::size_of;

    #[test]
    fn hit_and_context_have_room_for_inst_prim_id() {
        // Embree 4.4 built with instance arrays, one instance level: RTCRayHit is 96 bytes (a 48-byte ray and a
        // 36-byte hit padded to 48) and RTCRayQueryContext 8 (instID[1], instPrimID[1]).
        assert!(size_of::<RayHitStorage>() >= 96);
        assert!(size_of::<QueryContext>() >= size_of::<RTCRayQueryContext>() + 4);
        let context = init_query_context();
        assert_eq!(context.raw.instID, [RTC_INVALID_GEOMETRY_ID; 1]);
        assert_eq!(context.inst_prim_id, [RTC_INVALID_GEOMETRY_ID; 1]);
    }

    #[test]
    fn the_library_is_embree_4() {
        let device = super::super::Device::new().expect("device");
        assert_eq!(
            device.version().0,
            4,
            "built with Embree 4 headers, linked to {device:?}"
        );
    }
}
