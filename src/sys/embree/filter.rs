//! The filter functions Embree calls for every candidate hit, and the per-query payloads they read and write: the
//! exact transmittance of [`CommittedScene::transmittance1`] and the stochastic presence of
//! [`CommittedScene::intersect1_stochastic`] / [`CommittedScene::occluded1_stochastic`].

use super::ffi::*;
use super::geometry::{StrandTable, NO_STRAND};
#[cfg(doc)]
use super::scene::CommittedScene;

/// Why a transmittance query ended early with transmittance 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum Cutoff {
    /// A hit on a geometry or segment without strand data, treated as opaque.
    Opaque,
    /// The transmittance fell below [`TRANSMITTANCE_CUTOFF`] (this includes crossing a strand of opacity 1).
    Dark,
    /// More than [`SEEN_STRANDS`] distinct strands were crossed; see [`SEEN_STRANDS`] for why this ends the ray.
    SeenListFull,
}

/// Transmittance below which a shadow ray stops and reports 0 (the light it would still carry is invisible
/// at 16-bit precision and saves most of the traversal through dense hair).
pub const TRANSMITTANCE_CUTOFF: f32 = 1e-4;

/// Capacity of the per-ray list of strands already counted.
///
/// Strands of opacity 0 are not remembered (they change nothing). When a ray crosses more distinct
/// semi-transparent strands than this, the query stops with transmittance 0. The alternatives —
/// forgetting old entries or counting without de-duplication — would double-count strands and make the result
/// depend on Embree's traversal order. Stopping is biased dark by at most the transmittance at that point,
/// ∏ (1 − aᵢ) over 64 strands: below 1e-4 for opacities ≥ 0.14, and 0.04 for opacity 0.05. The count of such rays
/// is reported ([`Cutoff::SeenListFull`]) so that a scene where it matters can be found.
pub const SEEN_STRANDS: usize = 64;

/// The shadow-ray payload: Embree's query context first (so Embree's context pointer is also a pointer to this
/// struct), then what the filter function accumulates. Lives on the querying thread's stack for one query.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub(super) struct TransmittanceQuery {
    pub(super) context: QueryContext,
    ignore_strand: u32,
    pub(super) transmittance: f32,
    pub(super) cutoff: Option<Cutoff>,
    pub(super) seen_len: u32,
    /// 0: a transmittance query. Otherwise a count of the strands crossed, whatever their opacity (above 0),
    /// which stops once it reaches this many.
    count_limit: u32,
    seen: [u32; SEEN_STRANDS],
}

// The filter casts Embree's context pointer to the payload: the context must sit at offset 0.
const _: () = assert!(std::mem::offset_of!(TransmittanceQuery, context) == 0);

/// What the filter tells Embree about one hit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Verdict {
    /// Reject the hit (`valid[i] = 0`): traversal continues.
    Continue,
    /// Accept the hit: the occlusion query ends.
    Stop,
}

impl TransmittanceQuery {
    /// A payload whose context carries [`transmittance_filter`] (Embree 3; Embree 4 takes the filter in the query
    /// arguments).
    /// With `count_limit` > 0 the query counts strands instead, up to that many (at most [`SEEN_STRANDS`]).
    pub(super) fn new(ignore_strand: Option<u32>, count_limit: u32) -> Self {
        #[allow(unused_mut)]
        let mut context = init_query_context();
        #[cfg(not(embree4))]
        {
            context.filter = Some(transmittance_filter);
        }
        TransmittanceQuery {
            context,
            ignore_strand: ignore_strand.unwrap_or(NO_STRAND),
            transmittance: 1.0,
            cutoff: None,
            seen_len: 0,
            count_limit: count_limit.min(SEEN_STRANDS as u32),
            seen: [NO_STRAND; SEEN_STRANDS],
        }
    }

    /// Accounts for one reported hit on `strand` = (strand id, opacity), or on a primitive without strand data.
    fn on_hit(&mut self, strand: Option<(u32, f32)>) -> Verdict {
        let Some((strand, opacity)) = strand else {
            return self.stop(Cutoff::Opaque);
        };
        // A fully transparent strand changes nothing and need not be remembered.
        let seen = &self.seen[..self.seen_len as usize];
        if opacity == 0.0 || strand == self.ignore_strand || seen.contains(&strand) {
            return Verdict::Continue;
        }
        if self.seen_len as usize == SEEN_STRANDS {
            return self.stop(Cutoff::SeenListFull);
        }
        self.seen[self.seen_len as usize] = strand;
        self.seen_len += 1;
        if self.count_limit > 0 {
            return if self.seen_len >= self.count_limit {
                Verdict::Stop
            } else {
                Verdict::Continue
            };
        }
        self.transmittance *= 1.0 - opacity;
        if self.transmittance < TRANSMITTANCE_CUTOFF {
            return self.stop(Cutoff::Dark);
        }
        Verdict::Continue
    }

    fn stop(&mut self, why: Cutoff) -> Verdict {
        self.transmittance = 0.0;
        self.cutoff = Some(why);
        Verdict::Stop
    }
}

/// The occlusion filter of [`CommittedScene::transmittance1`]: rejects every hit so that traversal continues,
/// multiplying the payload's transmittance once per distinct strand, until a cutoff accepts a hit.
pub(super) unsafe extern "C" fn transmittance_filter(args: *const RTCFilterFunctionNArguments) {
    // SAFETY: Embree passes a valid argument struct for the duration of the call.
    let Some(args) = (unsafe { args.as_ref() }) else {
        return;
    };
    // SAFETY: only `transmittance1` installs this filter, and its context pointer is the first field of a live
    // `TransmittanceQuery` (repr(C), offset 0 asserted above), derived from a pointer to the whole struct; Embree
    // runs filters on the querying thread during the call, when nothing else touches the query.
    let query = unsafe { &mut *args.context.cast::<TransmittanceQuery>() };
    // SAFETY: `args` is the argument struct of this filter call, on cuticle's curve geometries.
    unsafe { filter_hits(args, |_, strand| query.on_hit(strand) == Verdict::Stop) };
}

/// The loop every filter function shares: for each valid lane `i` of the hit packet, looks up the strand of its
/// segment and passes both to `keep`; lanes for which `keep` returns `false` are rejected (`valid[i] = 0`), so
/// traversal goes on past them.
///
/// # Safety
/// `args` must be the argument struct Embree passed to the calling filter function, for a geometry whose user data
/// is null or `Arc::as_ptr` of its [`StrandTable`], kept alive by the committed scene.
unsafe fn filter_hits(
    args: &RTCFilterFunctionNArguments,
    mut keep: impl FnMut(u32, Option<(u32, f32)>) -> bool,
) {
    // SAFETY: the caller guarantees the user data is null or a live strand table.
    let table = unsafe {
        args.geometryUserPtr
            .cast_const()
            .cast::<StrandTable>()
            .as_ref()
    };
    for i in 0..args.N {
        // SAFETY: `valid` has `N` entries (the filter-function contract).
        let valid = unsafe { &mut *args.valid.add(i as usize) };
        if *valid == 0 {
            continue;
        }
        // SAFETY: `hit` is a packet of width `N` and `i < N`.
        let segment = unsafe { hit_n_prim_id(args.hit, args.N, i) };
        if !keep(i, table.and_then(|t| t.lookup(segment))) {
            *valid = 0;
        }
    }
}

/// The payload of the stochastic queries ([`CommittedScene::intersect1_stochastic`],
/// [`CommittedScene::occluded1_stochastic`]): Embree's context first, then the strand to ignore and the caller's
/// presence test `present(strand, opacity)`, which decides which strands exist for this ray.
///
/// Generic over the presence test, so that the filter, which runs once per candidate hit, calls it directly
/// (monomorphised and inlinable) rather than through a function pointer.
#[repr(C)]
pub(super) struct StochasticQuery<P> {
    context: QueryContext,
    ignore_strand: u32,
    present: P,
}

// The filter casts Embree's context pointer to the payload: the context must sit at offset 0. `repr(C)` lays the
// first field out first whatever `P` is, so one instance checks them all.
const _: () = assert!(std::mem::offset_of!(StochasticQuery<fn(u32, f32) -> bool>, context) == 0);

impl<P: Fn(u32, f32) -> bool> StochasticQuery<P> {
    /// A payload whose context carries [`stochastic_filter`] (Embree 3; Embree 4 takes the filter in the query
    /// arguments).
    pub(super) fn new(ignore_strand: Option<u32>, present: P) -> Self {
        #[allow(unused_mut)]
        let mut context = init_query_context();
        #[cfg(not(embree4))]
        {
            context.filter = Some(stochastic_filter::<P>);
        }
        StochasticQuery {
            context,
            ignore_strand: ignore_strand.unwrap_or(NO_STRAND),
            present,
        }
    }

    /// Whether a reported hit counts: primitives without strand data always do (opaque); a strand does unless it is
    /// the ignored one or the presence test says it is absent for this ray.
    #[inline]
    fn accepts(&self, strand: Option<(u32, f32)>) -> bool {
        match strand {
            None => true,
            Some((strand, opacity)) => {
                strand != self.ignore_strand && (self.present)(strand, opacity)
            }
        }
    }
}

/// The filter of the stochastic queries, for intersection and occlusion alike: rejects hits on strands that are
/// absent for this ray, so traversal goes on past them. One instance per presence type `P`.
pub(super) unsafe extern "C" fn stochastic_filter<P: Fn(u32, f32) -> bool>(
    args: *const RTCFilterFunctionNArguments,
) {
    // SAFETY: Embree passes a valid argument struct for the duration of the call.
    let Some(args) = (unsafe { args.as_ref() }) else {
        return;
    };
    // SAFETY: only the stochastic queries install this filter, each with the `P` of its own payload, and their
    // context pointer is the first field of a live `StochasticQuery<P>` (repr(C), offset 0 asserted above); the
    // filter only reads it.
    let query = unsafe { &*args.context.cast::<StochasticQuery<P>>() };
    // SAFETY: `args` is the argument struct of this filter call, on cuticle's curve geometries.
    unsafe { filter_hits(args, |_, strand| query.accepts(strand)) };
}

/// The payload of the stochastic packet queries ([`CommittedScene::intersect_packet_stochastic`],
/// [`CommittedScene::occluded_packet_stochastic`]): Embree's context first, then per packet lane the strand to
/// ignore, and the caller's presence test `present(lane, strand, opacity)`.
///
/// The filter finds a hit's packet lane from the ray's `id`, which the packet queries set to the lane index: Embree
/// may hand the filter the whole packet or a part of it, so the position in the filter's packet is not enough.
#[repr(C)]
pub(super) struct StochasticPacket<P, const W: usize> {
    context: QueryContext,
    ignore_strand: [u32; W],
    present: P,
}

// As for `StochasticQuery`: the context must sit at offset 0, whatever `P` and `W` are.
const _: () =
    assert!(std::mem::offset_of!(StochasticPacket<fn(usize, u32, f32) -> bool, 16>, context) == 0);

impl<P: Fn(usize, u32, f32) -> bool, const W: usize> StochasticPacket<P, W> {
    /// A payload whose context carries [`stochastic_packet_filter`] (Embree 3; Embree 4 takes the filter in the
    /// query arguments).
    pub(super) fn new(ignore_strand: &[Option<u32>; W], present: P) -> Self {
        #[allow(unused_mut)]
        let mut context = init_query_context();
        #[cfg(not(embree4))]
        {
            context.filter = Some(stochastic_packet_filter::<P, W>);
        }
        StochasticPacket {
            context,
            ignore_strand: ignore_strand.map(|s| s.unwrap_or(NO_STRAND)),
            present,
        }
    }

    /// [`StochasticQuery::accepts`] for packet lane `lane`; a lane outside the packet (which no query of this
    /// payload creates) keeps its hit.
    #[inline]
    fn accepts(&self, lane: u32, strand: Option<(u32, f32)>) -> bool {
        let lane = lane as usize;
        match (strand, self.ignore_strand.get(lane)) {
            (Some((strand, opacity)), Some(&ignore)) => {
                strand != ignore && (self.present)(lane, strand, opacity)
            }
            _ => true,
        }
    }
}

/// The filter of the stochastic packet queries: [`stochastic_filter`] with the presence test and the ignored strand
/// of each hit's own packet lane (its ray's `id`).
pub(super) unsafe extern "C" fn stochastic_packet_filter<
    P: Fn(usize, u32, f32) -> bool,
    const W: usize,
>(
    args: *const RTCFilterFunctionNArguments,
) {
    // SAFETY: Embree passes a valid argument struct for the duration of the call.
    let Some(args) = (unsafe { args.as_ref() }) else {
        return;
    };
    // SAFETY: only the stochastic packet queries install this filter, each with the `P` and `W` of its own payload,
    // and their context pointer is the first field of a live `StochasticPacket<P, W>` (repr(C), offset 0 asserted
    // above); the filter only reads it.
    let query = unsafe { &*args.context.cast::<StochasticPacket<P, W>>() };
    let (ray, n) = (args.ray.cast_const(), args.N);
    let lane_of = |i: u32| {
        debug_assert!(i < n);
        // SAFETY: `ray` is this call's ray packet of width `n`, and `filter_hits` passes only lanes `i < n`.
        unsafe { ray_n_id(ray, n, i) }
    };
    // SAFETY: `args` is the argument struct of this filter call, on cuticle's curve geometries.
    unsafe { filter_hits(args, |i, strand| query.accepts(lane_of(i), strand)) };
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{align_of, offset_of, size_of};

    #[test]
    fn transmittance_query_layout() {
        let context = size_of::<QueryContext>();
        assert_eq!(offset_of!(TransmittanceQuery, context), 0);
        assert_eq!(offset_of!(TransmittanceQuery, ignore_strand), context);
        assert_eq!(offset_of!(TransmittanceQuery, transmittance), context + 4);
        assert_eq!(size_of::<Option<Cutoff>>(), 4, "niche-packed into the u32");
        assert_eq!(offset_of!(TransmittanceQuery, cutoff), context + 8);
        assert_eq!(offset_of!(TransmittanceQuery, seen_len), context + 12);
        assert_eq!(offset_of!(TransmittanceQuery, count_limit), context + 16);
        assert_eq!(offset_of!(TransmittanceQuery, seen), context + 20);
        assert_eq!(
            align_of::<TransmittanceQuery>(),
            align_of::<QueryContext>().max(4)
        );
        #[cfg(not(embree4))]
        {
            // Debian's Embree 3.13: flags (4) + padding (4) + filter pointer (8) + instID[1] (4) + padding (4).
            assert_eq!(context, 24);
            // The fields after the context, then 4 bytes of padding to the context's 8-byte alignment.
            assert_eq!(
                size_of::<TransmittanceQuery>(),
                24 + 20 + 4 * SEEN_STRANDS + 4
            );
        }
    }

    #[test]
    fn a_count_counts_distinct_strands_of_any_opacity_up_to_its_limit() {
        let mut q = TransmittanceQuery::new(Some(9), 3);
        assert_eq!(q.on_hit(Some((7, 1.0))), Verdict::Continue);
        assert_eq!(q.on_hit(Some((7, 1.0))), Verdict::Continue);
        assert_eq!(
            q.on_hit(Some((9, 1.0))),
            Verdict::Continue,
            "the ignored strand"
        );
        assert_eq!(
            q.on_hit(Some((4, 0.0))),
            Verdict::Continue,
            "opacity 0 is no strand"
        );
        assert_eq!(q.on_hit(Some((3, 0.2))), Verdict::Continue);
        assert_eq!(q.seen_len, 2);
        assert_eq!(q.transmittance, 1.0, "a count multiplies nothing");
        assert_eq!(
            q.on_hit(Some((5, 1.0))),
            Verdict::Stop,
            "the third strand reaches the limit"
        );
        assert_eq!(q.seen_len, 3);
    }

    #[test]
    fn each_strand_counts_once() {
        let mut q = TransmittanceQuery::new(None, 0);
        assert_eq!(q.on_hit(Some((7, 0.5))), Verdict::Continue);
        assert_eq!(q.on_hit(Some((7, 0.5))), Verdict::Continue);
        assert_eq!(q.on_hit(Some((3, 0.5))), Verdict::Continue);
        assert_eq!(q.on_hit(Some((7, 0.5))), Verdict::Continue);
        assert_eq!(q.transmittance, 0.25);
        assert_eq!(q.seen_len, 2);
        assert_eq!(q.cutoff, None);
    }

    #[test]
    fn ignored_strand_is_transparent() {
        let mut q = TransmittanceQuery::new(Some(4), 0);
        assert_eq!(q.on_hit(Some((4, 1.0))), Verdict::Continue);
        assert_eq!(q.transmittance, 1.0);
        assert_eq!(q.seen_len, 0);
    }

    #[test]
    fn stops_dark_opaque_and_full() {
        let mut q = TransmittanceQuery::new(None, 0);
        assert_eq!(q.on_hit(Some((1, 1.0))), Verdict::Stop);
        assert_eq!((q.transmittance, q.cutoff), (0.0, Some(Cutoff::Dark)));

        let mut q = TransmittanceQuery::new(None, 0);
        assert_eq!(q.on_hit(None), Verdict::Stop);
        assert_eq!((q.transmittance, q.cutoff), (0.0, Some(Cutoff::Opaque)));

        let mut q = TransmittanceQuery::new(None, 0);
        for s in 0..SEEN_STRANDS as u32 {
            assert_eq!(q.on_hit(Some((s, 1e-6))), Verdict::Continue);
        }
        assert_eq!(q.on_hit(Some((0, 1e-6))), Verdict::Continue, "already seen");
        assert_eq!(q.on_hit(Some((999, 0.0))), Verdict::Continue, "transparent");
        assert_eq!(q.seen_len as usize, SEEN_STRANDS);
        assert_eq!(q.on_hit(Some((999, 1e-6))), Verdict::Stop);
        assert_eq!(
            (q.transmittance, q.cutoff),
            (0.0, Some(Cutoff::SeenListFull))
        );
    }

    #[test]
    fn stochastic_query_asks_the_presence_test() {
        let q = StochasticQuery::new(Some(4), |strand, opacity| strand % 2 == 0 && opacity > 0.5);
        assert!(q.accepts(None), "primitives without strand data are opaque");
        assert!(q.accepts(Some((2, 0.9))));
        assert!(!q.accepts(Some((2, 0.1))), "absent by opacity");
        assert!(!q.accepts(Some((3, 0.9))), "absent by strand");
        assert!(
            !q.accepts(Some((4, 0.9))),
            "the ignored strand, present or not"
        );
    }
}
