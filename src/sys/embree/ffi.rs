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
/// The query context Embree hands to filter functions: `RTCRayQueryContext` in Embree 4.
#[cfg(embree4)]
pub(super) type QueryContext = RTCRayQueryContext;

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

/// Mirrors `rtcInitRayQueryContext` (`embree4/rtcore_common.h`, an inline function).
///
/// Embree ≥ 4.3 built with instance arrays also has `instPrimID[]`, which the header sets to
/// `RTC_INVALID_GEOMETRY_ID`; it is left zeroed here because only instance-array traversal reads it and cuticle
/// creates no instances. (Not compiled on Embree 3 machines; see the module docs.)
#[cfg(embree4)]
#[allow(clippy::field_reassign_with_default)] // which fields exist depends on Embree's build options
pub(super) fn init_query_context() -> QueryContext {
    let mut context = RTCRayQueryContext::default();
    context.instID.fill(RTC_INVALID_GEOMETRY_ID);
    context
}

/// Mirrors `rtcInitOccludedArguments` (`embree4/rtcore_scene.h`, an inline function): incoherent rays, all
/// features, no context, no filter, no user-geometry callback, `minWidthDistanceFactor` 0 (zeroed by `Default`).
/// (Not compiled on Embree 3 machines; see the module docs.)
#[cfg(embree4)]
#[allow(clippy::field_reassign_with_default)] // which fields exist depends on Embree's build options
pub(super) fn init_occluded_arguments() -> RTCOccludedArguments {
    let mut args = RTCOccludedArguments::default();
    args.flags = RTC_RAY_QUERY_FLAG_INCOHERENT;
    args.feature_mask = RTC_FEATURE_FLAG_ALL;
    args
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
