//! `cuticle bench build`: how acceleration-structure builds scale with the groom. For procedural fur
//! balls of each strand count (16 points each, the `scenes/groom-1m.toml` groom): generation time, then for each
//! backend and curve type the build's wall and CPU time, bytes per segment and the peak resident memory the build
//! adds, and — so that a cheaper build is never compared without what it costs later — the closest-hit throughput
//! of [`PROBE_RAYS`] rays through the result, with their hit count (equal work, equal hits).
//!
//! Peak memory per build is measured in one process by resetting the kernel's high-water mark (`VmHWM`) before each
//! build (`echo 5 > /proc/self/clear_refs`, Linux ≥ 4.0) and reading it after; where that is unavailable the column
//! shows the process peak so far (marked `*`). CPU time is the process's user + system time ([`crate::sys::clock`]),
//! so it counts Embree's TBB workers and rayon's alike: CPU ÷ wall shows whether a build ran in parallel, and whether
//! it was starved on a shared machine.

use std::fmt;
use std::time::Instant;

use rayon::prelude::*;

use super::BenchError;
use crate::accel::bvh_tracer::BvhTracer;
use crate::accel::embree::{BuildQuality, Device, EmbreeTracer, Layout};
use crate::accel::{Backend, CurveKind, Tracer};
use crate::hair::procedural::{FurBall, Procedural};
use crate::hair::{HairError, Strands};
use crate::ray::Ray;
use crate::util::hash::{hash64, unit_f32};
use crate::util::sampling::uniform_sphere;

/// Rays traced through each build: enough for a throughput figure to a few percent on 10⁶ strands, few enough
/// (about a second there) not to dominate the benchmark.
pub const PROBE_RAYS: usize = 1 << 16;

/// Fibre radius of the benchmark grooms, model units: `scenes/groom-1m.toml`'s, thin enough that 10⁶ strands on
/// the unit sphere read as a pelt rather than a solid shell.
pub const GROOM_FIBER_RADIUS: f32 = 0.0015;

/// Control points per strand of the benchmark grooms (16 points each).
pub const GROOM_POINTS: u32 = 16;

/// What to measure.
#[derive(Debug, Clone, PartialEq)]
pub struct BuildConfig {
    /// Strand counts, one groom each.
    pub strands: Vec<u32>,
    /// Backends to build.
    pub backends: Vec<Backend>,
    /// Curve types to build.
    pub kinds: Vec<CurveKind>,
    /// Embree build qualities to measure (the renderer uses [`BuildQuality::Medium`]).
    pub embree_qualities: Vec<BuildQuality>,
    /// Embree leaf layouts to measure (the renderer uses [`Layout::Fast`]).
    pub embree_layouts: Vec<Layout>,
    /// Threads of the rayon pool the builds run in (the Rust BVH's parallelism; Embree's TBB uses every core).
    pub threads: usize,
}

/// One build.
#[derive(Debug, Clone, PartialEq)]
pub struct BuildRow {
    /// Strands in the groom.
    pub strands: u32,
    /// Curve segments (Embree primitives).
    pub segments: usize,
    /// Backend built.
    pub backend: Backend,
    /// Curve type built.
    pub kind: CurveKind,
    /// Embree's build quality and leaf layout (`None` for the Rust BVH).
    pub quality: Option<(BuildQuality, Layout)>,
    /// Wall time of the build, seconds (the tracer's own figure: geometry + BVH).
    pub build_seconds: f64,
    /// Process CPU time (user + system, all threads) during the build, seconds; `None` off Linux.
    pub cpu_seconds: Option<f64>,
    /// The tracer's memory (BVH, copied curve data, strand tables) per segment.
    pub bytes_per_segment: f64,
    /// Peak resident memory during the build above the resident memory before it, bytes; `None` off Linux.
    pub peak_added_bytes: Option<u64>,
    /// Whether `peak_added_bytes` is exact (the high-water mark could be reset) or an upper bound.
    pub peak_exact: bool,
    /// Closest-hit throughput of the probe rays ([`probe_ray`]), millions of rays per second.
    pub probe_mrays: f64,
    /// How many probe rays hit (the same for every build of one groom and curve type, up to curve numerics).
    pub probe_hits: usize,
}

/// The groom of one strand count.
#[derive(Debug, Clone, PartialEq)]
pub struct GroomRow {
    /// Strands.
    pub strands: u32,
    /// Wall time to generate the model and convert it to B-spline strands, seconds.
    pub generate_seconds: f64,
    /// Bytes of the B-spline strands (control points, indices, tables).
    pub strand_bytes: usize,
}

/// Everything `bench build` measured.
#[derive(Debug, Clone, PartialEq)]
pub struct BuildReport {
    /// One row per groom.
    pub grooms: Vec<GroomRow>,
    /// One row per build.
    pub builds: Vec<BuildRow>,
    /// Threads of the rayon pool.
    pub threads: usize,
    /// Peak resident memory of the whole process, bytes.
    pub process_peak_bytes: Option<u64>,
}

/// Why a groom could not be made.
#[derive(Debug, thiserror::Error)]
pub enum BuildBenchError {
    /// The generator refused the parameters.
    #[error(transparent)]
    Hair(#[from] HairError),
    /// A backend or the thread pool failed.
    #[error(transparent)]
    Bench(#[from] BenchError),
}

/// The benchmark groom of `strands` strands: the default fur ball with [`GROOM_POINTS`] points per strand and
/// fibres of [`GROOM_FIBER_RADIUS`].
pub fn groom(strands: u32) -> Procedural {
    Procedural::FurBall(FurBall {
        strands,
        points: GROOM_POINTS,
        fiber_radius: GROOM_FIBER_RADIUS,
        ..FurBall::default()
    })
}

/// Runs the benchmark.
pub fn build(config: &BuildConfig) -> Result<BuildReport, BuildBenchError> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(config.threads)
        .build()
        .map_err(|source| BenchError::ThreadPool {
            threads: config.threads,
            source,
        })?;
    let device = Device::new().map_err(BenchError::from)?;
    let mut report = BuildReport {
        grooms: Vec::new(),
        builds: Vec::new(),
        threads: config.threads,
        process_peak_bytes: None,
    };
    for &n in &config.strands {
        let start = Instant::now();
        let strands = pool.install(|| groom(n).generate().map(|m| Strands::from_model(&m)))?;
        report.grooms.push(GroomRow {
            strands: n,
            generate_seconds: start.elapsed().as_secs_f64(),
            strand_bytes: strands.bytes(),
        });
        let variants = config.backends.iter().flat_map(|&backend| match backend {
            Backend::Embree => config
                .embree_qualities
                .iter()
                .flat_map(|&q| {
                    config
                        .embree_layouts
                        .iter()
                        .map(move |&l| (backend, Some((q, l))))
                })
                .collect::<Vec<_>>(),
            Backend::Bvh => vec![(backend, None)],
        });
        for (backend, quality) in variants {
            for &kind in &config.kinds {
                let peak_exact = reset_peak_rss();
                let rss_before = crate::measure::status_kb("VmRSS:");
                let cpu_before = crate::sys::clock::process_cpu_seconds();
                let (build_seconds, memory, probe) =
                    pool.install(|| -> Result<_, BenchError> {
                        let tracer: Box<dyn Tracer> = match quality {
                            Some((q, l)) => {
                                Box::new(EmbreeTracer::with_build(&device, &strands, kind, q, l)?)
                            }
                            None => Box::new(BvhTracer::new(&strands, kind)),
                        };
                        let cpu = crate::sys::clock::process_cpu_seconds();
                        let peak = crate::measure::status_kb("VmHWM:");
                        let start = Instant::now();
                        let hits = (0..PROBE_RAYS)
                            .into_par_iter()
                            .filter(|&i| matches!(tracer.intersect(&probe_ray(i)), Ok(Some(_))))
                            .count();
                        let probe = (
                            PROBE_RAYS as f64 / start.elapsed().as_secs_f64() / 1e6,
                            hits,
                        );
                        Ok((
                            (tracer.build_seconds(), cpu, peak),
                            tracer.memory_bytes(),
                            probe,
                        ))
                    })?;
                let (build_seconds, cpu_after, peak_after) = build_seconds;
                let cpu = cpu_after.zip(cpu_before).map(|(a, b)| a - b);
                let peak = peak_after
                    .zip(rss_before)
                    .map(|(peak, before)| peak.saturating_sub(before) * 1024);
                report.builds.push(BuildRow {
                    strands: n,
                    segments: strands.segment_count(),
                    backend,
                    kind,
                    quality,
                    build_seconds,
                    cpu_seconds: cpu,
                    bytes_per_segment: memory as f64 / strands.segment_count().max(1) as f64,
                    peak_added_bytes: peak,
                    peak_exact,
                    probe_mrays: probe.0,
                    probe_hits: probe.1,
                });
            }
        }
    }
    report.process_peak_bytes = crate::measure::peak_rss_bytes();
    Ok(report)
}

/// The name of a build quality on the command line: `low`, `medium` or `high`.
pub fn quality_name(quality: BuildQuality) -> &'static str {
    match quality {
        BuildQuality::Low => "low",
        BuildQuality::Medium => "medium",
        BuildQuality::High => "high",
    }
}

/// Parses [`quality_name`]'s names (for the command line).
pub fn parse_quality(name: &str) -> Result<BuildQuality, String> {
    [BuildQuality::Low, BuildQuality::Medium, BuildQuality::High]
        .into_iter()
        .find(|&q| quality_name(q) == name)
        .ok_or_else(|| format!("unknown build quality {name:?} (expected low, medium or high)"))
}

/// The name of a leaf layout on the command line: `fast` or `compact`.
pub fn layout_name(layout: Layout) -> &'static str {
    match layout {
        Layout::Fast => "fast",
        Layout::Compact => "compact",
    }
}

/// Parses [`layout_name`]'s names (for the command line).
pub fn parse_layout(name: &str) -> Result<Layout, String> {
    [Layout::Fast, Layout::Compact]
        .into_iter()
        .find(|&l| layout_name(l) == name)
        .ok_or_else(|| format!("unknown leaf layout {name:?} (expected fast or compact)"))
}

/// The backend column: `embree/<quality>/<layout>` or `bvh`.
fn backend_label(row: &BuildRow) -> String {
    match row.quality {
        Some((q, l)) => format!(
            "{}/{}/{}",
            row.backend.name(),
            quality_name(q),
            layout_name(l)
        ),
        None => row.backend.name().to_string(),
    }
}

/// Probe ray `i`: from a point on the sphere of radius 3 around the groom (a fur ball of radius ≈ 1.5) towards a
/// point in the ball of radius 1, so that most rays cross the fur and many reach the (unrendered) inner sphere.
pub fn probe_ray(i: usize) -> Ray {
    let h = |k: u64| unit_f32(hash64((i as u64) << 3 | k));
    let origin = 3.0 * uniform_sphere(h(0), h(1));
    let target = h(2).cbrt() * uniform_sphere(h(3), h(4));
    Ray::new(origin, target - origin)
}

/// Resets the process's peak resident memory to its current value (Linux `clear_refs` 5); whether it worked.
fn reset_peak_rss() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}

impl fmt::Display for BuildReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mb = |b: u64| b as f64 / (1024.0 * 1024.0);
        for g in &self.grooms {
            writeln!(
                f,
                "groom {} strands: generated and converted in {:.2} s, strands {:.1} MiB",
                g.strands,
                g.generate_seconds,
                mb(g.strand_bytes as u64)
            )?;
        }
        writeln!(
            f,
            "{:>9} {:>10} {:>6} {:>21} {:>9} {:>9} {:>8} {:>10} {:>14} {:>10}",
            "strands",
            "segments",
            "curve",
            "backend",
            "build s",
            "cpu s",
            "B/seg",
            "peak +MiB",
            "probe Mrays/s",
            "probe hits"
        )?;
        for r in &self.builds {
            let cpu = r.cpu_seconds.map_or("-".into(), |c| format!("{c:.2}"));
            let peak = r.peak_added_bytes.map_or("-".into(), |p| {
                format!("{:.0}{}", mb(p), if r.peak_exact { "" } else { "*" })
            });
            writeln!(
                f,
                "{:>9} {:>10} {:>6} {:>21} {:>9.2} {:>9} {:>8.1} {:>10} {:>14.3} {:>10}",
                r.strands,
                r.segments,
                r.kind.name(),
                backend_label(r),
                r.build_seconds,
                cpu,
                r.bytes_per_segment,
                peak,
                r.probe_mrays,
                r.probe_hits
            )?;
        }
        if let Some(p) = self.process_peak_bytes {
            writeln!(f, "peak memory (VmHWM) of the process: {:.0} MiB", mb(p))?;
        }
        // The same figures again, one per line for scripts.
        write!(
            f,
            "\nthe figures above, one per line for scripts (strands, curves, backend, build time, bytes per segment):"
        )?;
        for r in &self.builds {
            write!(
                f,
                "\nbuild {} {} {} {:.4} s {:.1} B/segment",
                r.strands,
                r.kind.name(),
                backend_label(r),
                r.build_seconds,
                r.bytes_per_segment
            )?;
        }
        write!(f, "\n{} rayon threads", self.threads)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_grooms_build_on_both_backends() {
        let config = BuildConfig {
            strands: vec![200],
            backends: vec![Backend::Embree, Backend::Bvh],
            kinds: vec![CurveKind::Round],
            embree_qualities: vec![BuildQuality::Medium],
            embree_layouts: vec![Layout::Fast, Layout::Compact],
            threads: 1,
        };
        let report = build(&config).unwrap();
        assert_eq!(report.grooms.len(), 1);
        assert_eq!(report.builds.len(), 3);
        for row in &report.builds {
            // 16 points + 2 phantom end points per strand: 15 cubic segments.
            assert_eq!(row.segments, 200 * 15, "{row:?}");
            assert!(row.bytes_per_segment > 16.0, "{row:?}");
            assert!(row.build_seconds > 0.0);
            assert!(row.probe_hits > 0, "{row:?}");
        }
        // The same rays through the same curves: the same hits from every build, up to curve numerics.
        let hits: Vec<_> = report.builds.iter().map(|r| r.probe_hits as f64).collect();
        assert!(
            hits.iter()
                .all(|h| (h - hits[0]).abs() <= 1e-3 * hits[0] + 2.0),
            "{hits:?}"
        );
        let text = report.to_string();
        assert!(
            text.contains("build 200 round embree/medium/fast"),
            "{text}"
        );
        assert!(
            text.contains("build 200 round embree/medium/compact"),
            "{text}"
        );
    }

    #[test]
    fn quality_names_round_trip() {
        for q in [BuildQuality::Low, BuildQuality::Medium, BuildQuality::High] {
            assert_eq!(parse_quality(quality_name(q)), Ok(q));
        }
        assert!(parse_quality("best").unwrap_err().contains("\"best\""));
        for l in [Layout::Fast, Layout::Compact] {
            assert_eq!(parse_layout(layout_name(l)), Ok(l));
        }
        assert!(parse_layout("tiny").is_err());
    }

    #[test]
    fn memory_fields_parse() {
        if cfg!(target_os = "linux") {
            assert!(crate::measure::status_kb("VmRSS:").is_some_and(|kb| kb > 0));
        }
    }
}
