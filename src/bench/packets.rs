//! Embree's packet queries on a frame's own rays (`cuticle bench replay SCENE --packets 8,16`): whether
//! `rtcIntersect8/16` and `rtcOccluded8/16` trace the renderer's batches faster than one ray at a time.
//!
//! Method: one frame is rendered with every tracer query recorded ([`super::replay::record`]), with the thread that
//! issued it. A fresh Embree tracer is built for the frame's strands and curve type, and every recorded camera,
//! material and shadow query (`intersect`, `intersect_stochastic`, `occluded_stochastic`; exact transmittance has
//! no packet form and is left out) is traced through it in two ways:
//! - one by one, as the renderer does today ([`Tracer`]'s single-ray queries);
//! - grouped as the renderer's batches would issue them: per thread, in that thread's order, consecutive queries of
//!   the same kind in groups of up to `W`, each group one packet call
//!   ([`EmbreeTracer::intersect_packet`] and its siblings; unused lanes masked off). Camera queries are grouped by
//!   at most [`LANES`], the renderer's batch: a pixel's camera samples come eight at a time, and two pixels' rays
//!   never meet in one batch.
//!
//! Both run on the same rayon pool in chunks of consecutive rays (groups), per query kind, the variants taking turns
//! within each of `repetitions` rounds after one untimed pass, medians reported. The untimed pass also checks
//! agreement: a packet's hit agrees with the single ray's when both miss or both hit the same strand and segment
//! with |Δt| ≤ [`T_RELATIVE`]·t (occlusion: the same answer); "identical" counts bit-identical hit records.

use std::fmt;
use std::time::Instant;

use rayon::prelude::*;

use crate::accel::embree::EmbreeTracer;
use crate::accel::{Hit, Tracer};
use crate::bsdf::lanes::LANES;
use crate::measure::Timing;
use crate::ray::Ray;
use crate::render::{thread_pool, Frame, Request};
use crate::scene::Scene;

use super::frame::FrameBenchError;
use super::replay::{record, Query, TracedRay};

/// Relative hit-distance tolerance under which a packet's hit agrees with the single ray's.
pub const T_RELATIVE: f32 = 1e-4;

/// Groups (packets) per rayon task; single rays are chunked by the same groups, so both variants split the work
/// alike.
const GROUPS_PER_TASK: usize = 512;

/// The query kinds with a packet form, named by the rays the renderer traces with them.
const KINDS: [(Query, &str); 3] = [
    (Query::Intersect, "camera"),
    (Query::IntersectStochastic, "material"),
    (Query::OccludedStochastic, "shadow"),
];

/// One query kind at one packet width.
#[derive(Debug, Clone)]
pub struct PacketRow {
    /// Query kind: camera, material or shadow.
    pub kind: &'static str,
    /// Packet width.
    pub width: usize,
    /// Recorded queries of this kind.
    pub queries: u64,
    /// Packets they were grouped into.
    pub packets: u64,
    /// Wall time of the queries one by one.
    pub single: Timing,
    /// Wall time of the same queries in packets.
    pub packet: Timing,
    /// Queries whose packet result agrees with the single ray's.
    pub agree: u64,
    /// Queries whose packet result is bit for bit the single ray's.
    pub identical: u64,
}

impl PacketRow {
    /// Rays per second one by one (median).
    pub fn single_rays_per_s(&self) -> f64 {
        self.queries as f64 / self.single.median
    }

    /// Rays per second in packets (median).
    pub fn packet_rays_per_s(&self) -> f64 {
        self.queries as f64 / self.packet.median
    }
}

/// The result of [`packets`].
#[derive(Debug, Clone)]
pub struct PacketReport {
    /// Scene source.
    pub scene: String,
    /// Resolution.
    pub resolution: [u32; 2],
    /// Camera samples per pixel.
    pub spp: u32,
    /// Threads used.
    pub threads: usize,
    /// Curve type.
    pub curves: crate::accel::CurveKind,
    /// Embree's version.
    pub embree: (u32, u32, u32),
    /// Packet widths Embree has native kernels for on this CPU, of those measured.
    pub native: Vec<usize>,
    /// Exact-transmittance queries, which have no packet form and were not replayed.
    pub transmittance: u64,
    /// Per kind and width.
    pub rows: Vec<PacketRow>,
}

impl fmt::Display for PacketReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [w, h] = self.resolution;
        let (major, minor, patch) = self.embree;
        writeln!(
            f,
            "packet replay: {} ({w}x{h}, {} spp, {} curves); embree {major}.{minor}.{patch} (native packets: {:?}); {} threads; median (min-max) after 1 untimed pass",
            self.scene, self.spp, self.curves.name(), self.native, self.threads
        )?;
        if self.transmittance > 0 {
            writeln!(
                f,
                "{} exact-transmittance queries not replayed (no packet form)",
                self.transmittance
            )?;
        }
        writeln!(
            f,
            "{:<9} {:>5} {:>9} {:>12} {:>14} {:>14} {:>7} {:>8} {:>9}",
            "kind",
            "width",
            "queries",
            "lanes/packet",
            "single Mray/s",
            "packet Mray/s",
            "ratio",
            "agree",
            "identical"
        )?;
        for r in &self.rows {
            let n = r.queries.max(1) as f64;
            writeln!(
                f,
                "{:<9} {:>5} {:>9} {:>12.2} {:>14.3} {:>14.3} {:>7.3} {:>8.5} {:>9.5}",
                r.kind,
                r.width,
                r.queries,
                r.queries as f64 / r.packets.max(1) as f64,
                r.single_rays_per_s() / 1e6,
                r.packet_rays_per_s() / 1e6,
                r.packet_rays_per_s() / r.single_rays_per_s(),
                r.agree as f64 / n,
                r.identical as f64 / n,
            )?;
        }
        for (i, r) in self.rows.iter().enumerate() {
            if i > 0 {
                writeln!(f)?;
            }
            write!(
                f,
                "packets {} w{} single_rays_per_s {:.0} packet_rays_per_s {:.0} ratio {:.4} agree {:.5} identical {:.5} single_s {:.3} ({:.3}-{:.3}) packet_s {:.3} ({:.3}-{:.3})",
                r.kind,
                r.width,
                r.single_rays_per_s(),
                r.packet_rays_per_s(),
                r.packet_rays_per_s() / r.single_rays_per_s(),
                r.agree as f64 / r.queries.max(1) as f64,
                r.identical as f64 / r.queries.max(1) as f64,
                r.single.median,
                r.single.min,
                r.single.max,
                r.packet.median,
                r.packet.min,
                r.packet.max,
            )?;
        }
        Ok(())
    }
}

/// The recorded queries of one kind in replay order (thread by thread, each in its own order), and their groups
/// for one width as ranges of that list.
struct KindRays<'a> {
    rays: &'a [TracedRay],
    groups: &'a [std::ops::Range<usize>],
}

/// Groups `rays` (one kind, in replay order, `thread` saying whose) into runs of consecutive queries of the same
/// thread, each cut into groups of at most `cap`.
///
/// The runs are taken over the thread's whole sequence before the kinds are separated, so a query of another kind
/// in between ends a run; `breaks[i]` says whether such a query (or another thread's) came between `rays[i - 1]`
/// and `rays[i]`.
fn groups(breaks: &[bool], cap: usize) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut start = 0;
    for i in 1..=breaks.len() {
        if i == breaks.len() || breaks[i] || i - start == cap {
            if i > start {
                out.push(start..i);
            }
            start = i;
        }
    }
    out
}

/// Renders `scene` once with its queries recorded and measures them one by one against packets of each of
/// `widths` (8 or 16), as described in the module docs.
pub fn packets(
    scene: &Scene,
    threads: usize,
    repetitions: usize,
    widths: &[usize],
) -> Result<PacketReport, FrameBenchError> {
    let pool = thread_pool(Some(threads))?;
    let mut frame = Frame::load(scene.resolve()?)?;
    let repetitions = repetitions.max(1);
    pool.install(|| frame.render(Request::new(&frame.settings)));
    let (_, mut rays) = pool.install(|| record(&mut frame));
    let tracer = EmbreeTracer::new(&frame.strands, frame.curves)?;
    let transmittance = rays
        .iter()
        .filter(|r| r.query == Query::Transmittance)
        .count() as u64;
    // Thread by thread, each thread's queries in the order it issued them (the sort is stable).
    rays.sort_by_key(|r| r.thread);
    let mut per_kind = Vec::new();
    for (query, name) in KINDS {
        // Whether something else came between this kind's consecutive queries.
        let mut kept = Vec::new();
        let mut breaks = Vec::new();
        let mut previous: Option<(usize, u16)> = None;
        for (i, r) in rays.iter().enumerate() {
            if r.query != query {
                continue;
            }
            breaks.push(previous.is_none_or(|(j, thread)| j + 1 != i || thread != r.thread));
            previous = Some((i, r.thread));
            kept.push(*r);
        }
        let cap = |width: usize| match query {
            Query::Intersect => width.min(LANES),
            _ => width,
        };
        let by_width: Vec<Vec<std::ops::Range<usize>>> =
            widths.iter().map(|&w| groups(&breaks, cap(w))).collect();
        per_kind.push((name, kept, by_width));
    }
    drop(rays);

    let mut rows = Vec::new();
    let mut times: Vec<(Vec<f64>, Vec<f64>)> = Vec::new();
    for (name, kept, by_width) in &per_kind {
        for (w, groups) in widths.iter().zip(by_width) {
            let kind_rays = &KindRays { rays: kept, groups };
            let (agree, identical) = pool.install(|| check(&tracer, *w, kind_rays));
            rows.push(PacketRow {
                kind: name,
                width: *w,
                queries: kept.len() as u64,
                packets: kind_rays.groups.len() as u64,
                single: Timing::from_samples(Vec::new()),
                packet: Timing::from_samples(Vec::new()),
                agree,
                identical,
            });
            times.push((Vec::new(), Vec::new()));
        }
    }
    for _ in 0..repetitions {
        let mut row = 0;
        for (_, kept, by_width) in &per_kind {
            for (w, groups) in widths.iter().zip(by_width) {
                let kind_rays = &KindRays { rays: kept, groups };
                let t = Instant::now();
                std::hint::black_box(pool.install(|| trace_single(&tracer, kind_rays)));
                times[row].0.push(t.elapsed().as_secs_f64());
                let t = Instant::now();
                std::hint::black_box(pool.install(|| trace_packets(&tracer, *w, kind_rays)));
                times[row].1.push(t.elapsed().as_secs_f64());
                row += 1;
            }
        }
    }
    for (row, (single, packet)) in rows.iter_mut().zip(times) {
        row.single = Timing::from_samples(single);
        row.packet = Timing::from_samples(packet);
    }
    Ok(PacketReport {
        scene: scene.source.display().to_string(),
        resolution: scene.film.resolution,
        spp: scene.film.spp,
        threads: pool.current_num_threads(),
        curves: frame.curves,
        embree: tracer.device().version(),
        native: widths
            .iter()
            .copied()
            .filter(|&w| tracer.device().native_packet(w))
            .collect(),
        transmittance,
        rows,
    })
}

/// The single-ray results of `rays`: hits of the closest-hit queries, occlusion as a hit-or-miss.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Answer {
    Hit(Option<Hit>),
    Occluded(bool),
}

fn single(tracer: &EmbreeTracer, r: &TracedRay) -> Answer {
    let (ray, ignore, key) = (&r.ray, r.ignore_strand, r.key);
    match r.query {
        Query::Intersect => Answer::Hit(tracer.intersect(ray).unwrap_or(None)),
        Query::IntersectStochastic => Answer::Hit(
            tracer
                .intersect_stochastic(ray, ignore, key)
                .unwrap_or(None),
        ),
        _ => Answer::Occluded(
            tracer
                .occluded_stochastic(ray, ignore, key)
                .unwrap_or(false),
        ),
    }
}

/// The packet results of one group (at most `W` queries of one kind).
fn packet<const W: usize>(tracer: &EmbreeTracer, group: &[TracedRay]) -> [Answer; W] {
    let rays: [Option<Ray>; W] = std::array::from_fn(|k| group.get(k).map(|r| r.ray));
    let ignore: [Option<u32>; W] =
        std::array::from_fn(|k| group.get(k).and_then(|r| r.ignore_strand));
    let keys: [u64; W] = std::array::from_fn(|k| group.get(k).map_or(0, |r| r.key));
    match group[0].query {
        Query::Intersect | Query::IntersectStochastic => {
            let mut hits = [Ok(None); W];
            if group[0].query == Query::Intersect {
                tracer.intersect_packet(&rays, &mut hits);
            } else {
                tracer.intersect_stochastic_packet(&rays, &ignore, &keys, &mut hits);
            }
            hits.map(|h| Answer::Hit(h.unwrap_or(None)))
        }
        _ => {
            let mut occluded = [Ok(false); W];
            tracer.occluded_stochastic_packet(&rays, &ignore, &keys, &mut occluded);
            occluded.map(|o| Answer::Occluded(o.unwrap_or(false)))
        }
    }
}

/// [`packet`] for a width known at run time (8 or 16), as hits counted.
fn packet_hits(tracer: &EmbreeTracer, width: usize, group: &[TracedRay]) -> u64 {
    let hit = |a: &Answer| matches!(a, Answer::Hit(Some(_)) | Answer::Occluded(true));
    match width {
        8 => packet::<8>(tracer, group).iter().filter(|a| hit(a)).count() as u64,
        16 => packet::<16>(tracer, group)
            .iter()
            .filter(|a| hit(a))
            .count() as u64,
        _ => unreachable!("packet widths are checked by the caller"),
    }
}

/// Traces every query of `kind_rays` one by one, in chunks of its groups; how many hit.
fn trace_single(tracer: &EmbreeTracer, kind_rays: &KindRays) -> u64 {
    kind_rays
        .groups
        .par_chunks(GROUPS_PER_TASK)
        .map(|groups| {
            let range = groups[0].start..groups[groups.len() - 1].end;
            single_chunk(tracer, &kind_rays.rays[range])
        })
        .sum()
}

/// One task of [`trace_single`]. Not inlined, so that a profile (callgrind's inclusive cost) tells the two
/// variants' work apart.
#[inline(never)]
fn single_chunk(tracer: &EmbreeTracer, rays: &[TracedRay]) -> u64 {
    rays.iter()
        .filter(|r| {
            matches!(
                single(tracer, r),
                Answer::Hit(Some(_)) | Answer::Occluded(true)
            )
        })
        .count() as u64
}

/// Traces every group of `kind_rays` as one packet of `width`; how many hit.
fn trace_packets(tracer: &EmbreeTracer, width: usize, kind_rays: &KindRays) -> u64 {
    kind_rays
        .groups
        .par_chunks(GROUPS_PER_TASK)
        .map(|groups| packet_chunk(tracer, width, kind_rays.rays, groups))
        .sum()
}

/// One task of [`trace_packets`]; not inlined, as [`single_chunk`].
#[inline(never)]
fn packet_chunk(
    tracer: &EmbreeTracer,
    width: usize,
    rays: &[TracedRay],
    groups: &[std::ops::Range<usize>],
) -> u64 {
    groups
        .iter()
        .map(|g| packet_hits(tracer, width, &rays[g.clone()]))
        .sum()
}

/// Queries whose packet answer agrees with the single ray's, and those bit for bit the same.
fn check(tracer: &EmbreeTracer, width: usize, kind_rays: &KindRays) -> (u64, u64) {
    let compare = |group: &[TracedRay], answers: &[Answer]| -> (u64, u64) {
        let mut counts = (0, 0);
        for (r, a) in group.iter().zip(answers) {
            let s = single(tracer, r);
            counts.0 += u64::from(agrees(&s, a));
            counts.1 += u64::from(s == *a);
        }
        counts
    };
    kind_rays
        .groups
        .par_iter()
        .map(|g| {
            let group = &kind_rays.rays[g.clone()];
            match width {
                8 => compare(group, &packet::<8>(tracer, group)),
                _ => compare(group, &packet::<16>(tracer, group)),
            }
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
}

/// Whether a packet's answer agrees with the single ray's (module docs).
fn agrees(single: &Answer, packet: &Answer) -> bool {
    match (single, packet) {
        (Answer::Hit(Some(a)), Answer::Hit(Some(b))) => {
            a.strand == b.strand
                && a.segment == b.segment
                && (a.t - b.t).abs() <= T_RELATIVE * a.t.abs().max(b.t.abs())
        }
        (a, b) => a == b,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_follow_runs_and_caps() {
        // Runs: [0, 1, 2, 3, 4], [5], [6, 7].
        let breaks = [true, false, false, false, false, true, true, false];
        assert_eq!(groups(&breaks, 8), vec![0..5, 5..6, 6..8]);
        assert_eq!(groups(&breaks, 2), vec![0..2, 2..4, 4..5, 5..6, 6..8]);
        assert_eq!(groups(&[], 8), Vec::<std::ops::Range<usize>>::new());
    }
}
