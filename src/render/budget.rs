//! A frame's memory, estimated before anything big is allocated, and the limit it must fit.
//!
//! Settings inside their accepted ranges can still ask for more memory than the machine has (deep opacity maps
//! of 8192² × 256 layers want 64 GiB, 2.7·10⁸ procedural strands ~50 GB, a 32768² film 160 GiB); the allocator
//! then aborts the process with no useful message. [`estimate`] adds up what a frame holds at its peak from the
//! scene alone (a hair file's counts come from its header: [`hair_counts`]), and [`MemoryEstimate::check`] refuses
//! a frame over the limit with the estimate, its largest part and the limit in the message. The estimate, not a hard
//! cap, is what bounds procedural strand and point counts.
//!
//! The per-item constants were measured on this machine class (Debian 12, Embree 3.13.5, release build) with
//! `/usr/bin/time -f %M cuticle render` on procedural fur balls of 1, 50 000 and 200 000 strands × 16 points at
//! 64²: see [`ACCEL_BYTES_PER_SEGMENT`] and [`BASE_BYTES`]. They are upper estimates (the larger measurement,
//! rounded up; the 200 000-strand Embree frame, measured 645 MB, is estimated at 760 MB), so a frame refused is
//! one that would come close.

use crate::accel::{Backend, CurveKind};
use crate::hair::{HairError, HairSource};

use super::settings::{RenderSettings, ShadowMode};

/// Peak bytes per curve segment of the acceleration structure while it is built, including the curve buffers
/// the tracer copies, indexed by (backend, curves). Measured (peak RSS of `render --res 64x64 --spp 1 --threads 2`
/// on procedural fur balls of 16 points per strand, less the 1-strand render's 140 MB and the strands' own
/// [`STRAND_BYTES_PER_POINT`]): Embree 3.13 round and flat 119 B (50 000 strands) and 107 B (200 000); the Rust
/// BVH 144 B and 145 B, round and flat alike (it keeps each segment's four control points in its leaves; its lean
/// build holds the primitive references, the wide nodes and the leaves at its peak; `groom-1m.toml` with
/// `strands` set, `--backend bvh`). Rounded up.
pub const ACCEL_BYTES_PER_SEGMENT: [(Backend, CurveKind, u64); 4] = [
    (Backend::Embree, CurveKind::Round, 140),
    (Backend::Embree, CurveKind::Flat, 140),
    (Backend::Bvh, CurveKind::Round, 160),
    (Backend::Bvh, CurveKind::Flat, 160),
];

/// Peak bytes per pixel of adaptive sampling's state beyond a fixed-spp frame's: each pixel's film sums and
/// convergence statistics kept between rounds, the statistics copied for the round's decision and that decision's
/// per-pixel vectors ([`super::adaptive`]). Measured: peak RSS of the default scene rendered with `--quality auto`
/// against a fixed-spp render of the same film, 168 B per pixel at 1024² and 175 at 2048²; rounded up.
pub const ADAPTIVE_BYTES_PER_PIXEL: u64 = 192;

/// Peak bytes per pixel a splatting film adds to adaptive sampling's state, fixed and per value summed per target
/// ([`super::splat::Summed`]) and target reached ((2 · reach + 1)²): each source pixel's splats, f32, its count and
/// coordinates, kept between rounds ([`super::adaptive`]). Measured: peak RSS of the default scene at 1024² with
/// `--quality auto`, splat less importance, 164 B per pixel with the beauty alone (5 values; this bound: 196) and
/// 1 080 with every AOV (31; this bound: 1 132), each including the fixed-spp splat's edge sums.
pub const ADAPTIVE_SPLAT_BYTES_PER_PIXEL: u64 = 16;
/// See [`ADAPTIVE_SPLAT_BYTES_PER_PIXEL`].
pub const ADAPTIVE_SPLAT_BYTES_PER_PIXEL_PER_VALUE: u64 = 4;

/// Bytes per point of the model as read ([`crate::hair::HairModel`]: position 12, radius 4, transparency 4,
/// colour 12) plus the B-spline strands made from it (control point 16, segment tables 8): both are alive while
/// the strands are converted.
pub const STRAND_BYTES_PER_POINT: u64 = 32 + 16 + 8;

/// Bytes per strand: offsets in the model and the strands, per-strand opacity and colour, the two phantom control
/// points.
pub const STRAND_BYTES_PER_STRAND: u64 = 4 + 4 + 4 + 12 + 2 * 16;

/// Peak bytes per pixel a splatting film ([`super::splat`]) adds, per value each target sums
/// ([`super::splat::Summed`]: the quantities the kept channels read, and the weight), and fixed: the fixed-point
/// sums of the pixels along the work tiles' shared edges, kept until the region is assembled. Measured: peak RSS of
/// the default scene at 2048², 1 spp, splat against importance, 44.6 B per pixel with the beauty alone (5 values),
/// 66.1 with `shadow,albedo` (10), 115 with every AOV (31), at the default filter's reach of 1 px; this bound is
/// above all three. The edge pixels per pixel grow with the reach r as 8r / 32 (a 32² work tile's edge band
/// ((32 + 2r)² − (32 − 2r)²) / 32²), so the bound is multiplied by r.
pub const SPLAT_BYTES_PER_PIXEL: u64 = 32;
/// See [`SPLAT_BYTES_PER_PIXEL`].
pub const SPLAT_BYTES_PER_PIXEL_PER_VALUE: u64 = 4;

/// Copies of the film alive at the end of a render: the finished tiles, the assembled [`crate::image::Image`], and
/// the conversion OpenImageIO's writer makes (each the channels the film keeps, f32 per pixel).
pub const FILM_COPIES: u64 = 3;

/// Per worker thread: its stack (Rust's default for spawned threads, 2 MiB) and scratch.
pub const BYTES_PER_THREAD: u64 = 4 << 20;

/// Fixed costs: the executable with Embree's, TBB's and OpenImageIO's libraries mapped, measured as the peak RSS
/// of a 1-strand, 64×64 render (140 MB), rounded up. An environment map's decoded texels are not counted: their
/// size is only known once OpenImageIO has read the file (whose size is bounded, see
/// [`crate::light::environment::MAX_MAP_BYTES`]).
pub const BASE_BYTES: u64 = 144 << 20;

/// How many strands and points a hair source holds, known before it is read or generated: a file's header (a few
/// hundred bytes read; errors as the readers report them), or a procedural model's parameters.
pub fn hair_counts(source: &HairSource) -> Result<(u64, u64), HairError> {
    match source {
        HairSource::File(path) => crate::hair::declared_counts(path),
        HairSource::Procedural(p) => Ok(p.counts()),
        HairSource::Usd { path, .. } => usd_counts(path),
    }
}

/// Bytes of a USD file per point [`usd_counts`] assumes: measured on `scripts/usd-test-data.py --big`'s `.usdc`
/// (1.6 M points with per-point widths in 19.2 MB: 12.0 bytes a point, its width compressed away); a `.usda` takes
/// 15 or more characters a point, so it is over-counted. Points per strand: 16, the real grooms' typical count
/// (furball.hair 16, straight.hair 25).
const USD_BYTES_PER_POINT: u64 = 12;

/// The strands and points a USD file holds, estimated from its size before it is read ([`USD_BYTES_PER_POINT`]):
/// the stage is read once, by the frame's load, and a stage's curves are not counted without reading it. An
/// estimate, not a bound: a stage of mostly meshes is over-counted, a compressed or instanced one under-counted, so
/// [`super::Frame::load_adjusted`] checks the frame again with the counts read, before the tracer is built.
fn usd_counts(path: &std::path::Path) -> Result<(u64, u64), HairError> {
    let len = std::fs::metadata(path)
        .map_err(|source| HairError::Io {
            path: path.to_path_buf(),
            source,
        })?
        .len();
    let points = (len / USD_BYTES_PER_POINT).max(4);
    Ok(((points / 16).max(1), points))
}

/// What a frame needs at its peak, bytes, by part.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MemoryEstimate {
    /// The hair model and its B-spline strands.
    pub strands: u64,
    /// The acceleration structure, at its build peak.
    pub accel: u64,
    /// Triangle meshes (read when the scene was resolved) and their tracer ([`mesh_bytes`]).
    pub meshes: u64,
    /// The film (all channels) and its copies.
    pub film: u64,
    /// Deep opacity maps (0 unless the shadow mode uses them).
    pub shadow_maps: u64,
    /// Adaptive sampling's per-pixel state (0 for a fixed spp).
    pub adaptive: u64,
    /// Worker threads.
    pub threads: u64,
    /// Fixed costs ([`BASE_BYTES`]).
    pub base: u64,
}

/// Why a frame was refused before it was built.
#[derive(Debug, thiserror::Error)]
pub enum BudgetError {
    /// The estimate exceeds the limit.
    #[error(
        "this frame needs about {} ({}), more than the memory limit of {} ({}); lower the largest part or raise \
         --max-memory",
        human(estimate.total()),
        estimate.parts(),
        human(*limit),
        limit_source
    )]
    TooBig {
        /// The estimate.
        estimate: MemoryEstimate,
        /// The limit, bytes.
        limit: u64,
        /// Where the limit came from ("--max-memory", "3/4 of the 8.0 GiB of this machine").
        limit_source: String,
    },
}

fn human(n: u64) -> String {
    crate::util::input_file::human_bytes(n)
}

impl MemoryEstimate {
    /// The sum of the parts, saturating (a sum past u64 is over any limit anyway).
    pub fn total(&self) -> u64 {
        [
            self.strands,
            self.accel,
            self.meshes,
            self.film,
            self.shadow_maps,
            self.adaptive,
            self.threads,
            self.base,
        ]
        .iter()
        .fold(0u64, |a, &b| a.saturating_add(b))
    }

    /// The non-zero parts, largest first: "acceleration structure 3.0 GiB, strands 840 MiB, film 25 MiB".
    pub fn parts(&self) -> String {
        let mut parts = [
            ("strands", self.strands),
            ("acceleration structure", self.accel),
            ("meshes", self.meshes),
            ("film and AOVs", self.film),
            ("deep opacity maps", self.shadow_maps),
            ("adaptive sampling", self.adaptive),
            ("threads", self.threads),
            ("program", self.base),
        ];
        parts.sort_by_key(|p| std::cmp::Reverse(p.1));
        parts
            .iter()
            .filter(|(_, n)| *n > 0)
            .map(|(name, n)| format!("{name} {}", human(*n)))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// `Ok` when the estimate fits `limit`; `limit_source` says where the limit came from, for the message.
    pub fn check(&self, limit: u64, limit_source: &str) -> Result<(), BudgetError> {
        if self.total() <= limit {
            Ok(())
        } else {
            Err(BudgetError::TooBig {
                estimate: *self,
                limit,
                limit_source: limit_source.to_owned(),
            })
        }
    }
}

/// The estimate for a frame of `strands` strands holding `points` points in all, traced by `backend` as
/// `curves`, rendered with `settings` on `threads` workers, with `maps` deep opacity maps' worth of texels in
/// deep-opacity mode ([`map_count`]); `adaptive`: whether it samples adaptively (`settings.adaptive`, or `--quality auto`, which
/// sets that after the frame is loaded). Saturating arithmetic throughout: inputs come from files and users.
pub fn estimate(
    (strands, points): (u64, u64),
    backend: Backend,
    curves: CurveKind,
    settings: &RenderSettings,
    maps: usize,
    threads: usize,
    adaptive: bool,
) -> MemoryEstimate {
    // Segments: control points (points + 2 phantoms per strand) − 3 per strand = points − strands.
    let segments = points.saturating_sub(strands);
    let [w, h] = settings.film.resolution;
    let pixels = u64::from(w) * u64::from(h);
    // The tiles and the image hold the channels the film keeps ([`super::film::Layout`]), not all of CHANNELS.
    let channels = super::film::Layout::new(&settings.film).len() as u64;
    let layout = super::film::Layout::new(&settings.film);
    let values = super::splat::Summed::new(&layout).width() as u64;
    let reach = u64::from(super::splat::SplatFilter::new(settings.film.filter_width).reach());
    let splat = if settings.splats() {
        pixels.saturating_mul(
            (SPLAT_BYTES_PER_PIXEL + SPLAT_BYTES_PER_PIXEL_PER_VALUE * values) * reach,
        )
    } else {
        0
    };
    let adaptive = adaptive || settings.adaptive.is_some();
    // Under adaptive sampling a splatting film keeps every source pixel's splats between rounds.
    let adaptive_splat = if adaptive && settings.splats() {
        let side = 2 * reach + 1;
        pixels.saturating_mul(
            ADAPTIVE_SPLAT_BYTES_PER_PIXEL
                + ADAPTIVE_SPLAT_BYTES_PER_PIXEL_PER_VALUE * values * side * side,
        )
    } else {
        0
    };
    let film = pixels
        .saturating_mul(channels * 4)
        .saturating_mul(FILM_COPIES)
        .saturating_add(splat);
    let shadow_maps = if settings.shadows.mode == ShadowMode::DeepOpacity {
        map_bytes(settings, maps.max(1))
    } else {
        0
    };
    MemoryEstimate {
        strands: points
            .saturating_mul(STRAND_BYTES_PER_POINT)
            .saturating_add(strands.saturating_mul(STRAND_BYTES_PER_STRAND)),
        accel: accel_bytes(segments, backend, curves),
        meshes: 0,
        film,
        shadow_maps,
        adaptive: if adaptive {
            pixels
                .saturating_mul(ADAPTIVE_BYTES_PER_PIXEL)
                .saturating_add(adaptive_splat)
        } else {
            0
        },
        threads: (threads as u64).saturating_mul(BYTES_PER_THREAD),
        base: BASE_BYTES,
    }
}

/// Bytes of one copy of the film `settings` render: every pixel's kept channels, f32 each.
pub fn film_copy_bytes(settings: &RenderSettings) -> u64 {
    let [w, h] = settings.film.resolution;
    let channels = super::film::Layout::new(&settings.film).len() as u64;
    (u64::from(w) * u64::from(h)).saturating_mul(channels * 4)
}

/// Bytes of `backend`'s acceleration structure over `segments` curve segments as `curves`, at its build peak
/// ([`ACCEL_BYTES_PER_SEGMENT`]).
pub fn accel_bytes(segments: u64, backend: Backend, curves: CurveKind) -> u64 {
    let per_segment = ACCEL_BYTES_PER_SEGMENT
        .iter()
        .find(|(b, c, _)| *b == backend && *c == curves)
        .map_or(200, |e| e.2);
    segments.saturating_mul(per_segment)
}

/// Bytes of `count` deep opacity maps as `settings` build them (`shadows.deep_opacity`'s resolution² texels and
/// layers): per texel the cumulative layers, z0 and the layer bounds ([`crate::shadow::deep_opacity`]), f32 each,
/// and as many strand counts again under dual scattering.
pub fn map_bytes(settings: &RenderSettings, count: usize) -> u64 {
    let d = &settings.shadows.deep_opacity;
    let texels = u64::from(d.resolution) * u64::from(d.resolution);
    let per_texel = if settings.integrator.dual() {
        2 * u64::from(d.layers) + 2
    } else {
        u64::from(d.layers) + 2
    };
    texels
        .saturating_mul(per_texel * 4)
        .saturating_mul(count as u64)
}

/// The estimate for the frame `spec` describes, rendered with its own settings on `threads` workers (`adaptive` as
/// in [`estimate`]). Reads only a hair file's header.
pub fn estimate_frame(
    spec: &super::FrameSpec,
    threads: usize,
    adaptive: bool,
) -> Result<MemoryEstimate, HairError> {
    let counts = hair_counts(&spec.hair.source)?;
    Ok(estimate_frame_of(spec, counts, threads, adaptive))
}

/// [`estimate_frame`] for hair of `counts` (strands, points): a USD stage's counts once it is read, which its
/// file's size does not bound (a point instancer places its prototypes any number of times).
pub fn estimate_frame_of(
    spec: &super::FrameSpec,
    counts: (u64, u64),
    threads: usize,
    adaptive: bool,
) -> MemoryEstimate {
    MemoryEstimate {
        meshes: mesh_bytes(&spec.shapes),
        ..estimate(
            counts,
            spec.backend,
            spec.curves,
            &spec.settings,
            map_count(&spec.lights, &spec.settings),
            threads,
            adaptive,
        )
    }
}

/// Bytes per triangle of a mesh tracer at its build peak. Measured after the build on a 100 352-triangle sphere
/// (`MeshTracer::memory_bytes`): Embree 89, the Rust BVH 81 (leaves of 4); doubled for the build's scratch,
/// which is not measured on its own.
pub const MESH_ACCEL_BYTES_PER_TRIANGLE: u64 = 180;

/// Bytes of `shapes`' meshes (their data and textures, already in memory) and of the tracer built over them
/// ([`MESH_ACCEL_BYTES_PER_TRIANGLE`]).
pub fn mesh_bytes(shapes: &crate::shape::Shapes) -> u64 {
    let meshes = shapes
        .meshes()
        .iter()
        .map(|m| {
            (m.bytes() as u64).saturating_add(
                (m.triangles.len() as u64).saturating_mul(MESH_ACCEL_BYTES_PER_TRIANGLE),
            )
        })
        .fold(0, u64::saturating_add);
    // Textures are shared between meshes (and a point instancer's copies): each counted once.
    let mut seen = std::collections::HashSet::new();
    let textures = shapes
        .meshes()
        .iter()
        .filter_map(|m| m.texture.as_ref())
        .filter(|t| seen.insert(std::sync::Arc::as_ptr(&t.image)))
        .map(|t| t.image.bytes() as u64)
        .fold(0, u64::saturating_add);
    meshes.saturating_add(textures)
}

/// How many deep opacity maps of `shadows.deep_opacity.resolution` `lights` get under `settings`, in texels: one
/// per light, and for an environment light one per direction of its partition (`environment_directions`, up to
/// 256) at [`environment_resolution`](crate::shadow::deep_opacity::environment_resolution) (a quarter of the
/// texels), rounded up. A 64² frame counted one map for an environment that built 16–256, and grew past 9 GB after
/// it was admitted.
pub fn map_count(lights: &[crate::light::Light], settings: &RenderSettings) -> usize {
    let d = &settings.shadows.deep_opacity;
    let full = u64::from(d.resolution).pow(2);
    let environment = u64::from(crate::shadow::deep_opacity::environment_resolution(
        d.resolution,
    ))
    .pow(2)
        * u64::from(d.environment_directions);
    lights
        .iter()
        .map(|l| match l {
            crate::light::Light::Environment(_) => environment.div_ceil(full.max(1)) as usize,
            _ => 1,
        })
        .sum()
}

/// The estimate for reading a hair file or model of `strands` strands and `points` points alone (`cuticle info`):
/// the model and its strands, and the program.
pub fn estimate_model((strands, points): (u64, u64)) -> MemoryEstimate {
    MemoryEstimate {
        strands: points
            .saturating_mul(STRAND_BYTES_PER_POINT)
            .saturating_add(strands.saturating_mul(STRAND_BYTES_PER_STRAND)),
        accel: 0,
        meshes: 0,
        film: 0,
        shadow_maps: 0,
        adaptive: 0,
        threads: 0,
        base: BASE_BYTES,
    }
}

/// Fraction of physical memory a frame may use by default: 3/4, leaving room for the system and the other
/// processes of a shared machine (the OOM killer acts before 100 %).
pub const DEFAULT_FRACTION: (u64, u64) = (3, 4);

/// The machine's physical memory in bytes (`MemTotal` of `/proc/meminfo`), if it can be read.
pub fn physical_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    parse_mem_total(&text)
}

fn parse_mem_total(meminfo: &str) -> Option<u64> {
    let line = meminfo.lines().find(|l| l.starts_with("MemTotal:"))?;
    let mut fields = line["MemTotal:".len()..].split_whitespace();
    let value: u64 = fields.next()?.parse().ok()?;
    match fields.next() {
        Some("kB") => value.checked_mul(1024),
        None => Some(value),
        Some(_) => None,
    }
}

/// The default limit and its description: [`DEFAULT_FRACTION`] of [`physical_memory`], or 4 GiB when it
/// cannot be read (not Linux).
pub fn default_limit() -> (u64, String) {
    let (num, den) = DEFAULT_FRACTION;
    match physical_memory() {
        Some(total) => (
            total / den * num,
            format!("{num}/{den} of the {} of this machine", human(total)),
        ),
        None => (
            4 << 30,
            "the default when physical memory is unknown".to_owned(),
        ),
    }
}

/// Parses a `--max-memory` value: bytes, or a number with a binary suffix `K`, `M`, `G`, `T` (optionally
/// followed by `iB` or `B`, all powers of 1024): `512M`, `8G`, `1.5GiB`.
pub fn parse_size(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let scale: u64 = match unit.trim().to_ascii_uppercase().as_str() {
        "" | "B" => 1,
        "K" | "KB" | "KIB" => 1 << 10,
        "M" | "MB" | "MIB" => 1 << 20,
        "G" | "GB" | "GIB" => 1 << 30,
        "T" | "TB" | "TIB" => 1 << 40,
        _ => return Err(format!("expected a size like 512M or 8G, got `{s}`")),
    };
    let value: f64 = number
        .parse()
        .map_err(|_| format!("expected a size like 512M or 8G, got `{s}`"))?;
    let bytes = value * scale as f64;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(format!("a memory size must be at least 1 byte, got `{s}`"));
    }
    Ok(bytes as u64)
}

/// Most worker threads a render starts. Threads beyond the cores only add switching; each costs a stack
/// ([`BYTES_PER_THREAD`]); and the operating system fails or stalls long before 10⁸ of them. 1024 is above
/// any machine a frame runs on today and far below where thread creation fails.
pub const MAX_THREADS: usize = 1024;

/// Checks a `--threads` value: refused above [`MAX_THREADS`] (a typo, not a wish: clamping would silently run
/// something else than asked) and at 0.
pub fn check_threads(threads: usize) -> Result<usize, String> {
    if threads == 0 {
        return Err("--threads must be at least 1".to_owned());
    }
    if threads > MAX_THREADS {
        return Err(format!(
            "--threads {threads} is more than {MAX_THREADS}: threads beyond the cores only add switching, and each \
             reserves a stack (this machine has {} cores)",
            std::thread::available_parallelism().map_or(1, |n| n.get())
        ));
    }
    Ok(threads)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::camera::CameraConfig;
    use crate::render::settings::{FilmConfig, IntegratorConfig, ShadowConfig};

    fn settings(w: u32, h: u32) -> RenderSettings {
        RenderSettings {
            camera: CameraConfig::default(),
            film: FilmConfig {
                resolution: [w, h],
                ..FilmConfig::default()
            },
            integrator: IntegratorConfig::default(),
            shadows: ShadowConfig::default(),
            adaptive: None,
            background_visible: true,
        }
    }

    #[test]
    fn sizes_parse_in_binary_units() {
        assert_eq!(parse_size("512M"), Ok(512 << 20));
        assert_eq!(parse_size("1.5GiB"), Ok(3 << 29));
        assert_eq!(parse_size("4096"), Ok(4096));
        assert!(parse_size("lots").is_err());
        assert!(parse_size("0").is_err());
    }

    #[test]
    fn mem_total_is_read_in_kilobytes() {
        let text = "MemTotal:        8000000 kB\nMemFree: 1 kB\n";
        assert_eq!(parse_mem_total(text), Some(8_000_000 * 1024));
        assert_eq!(parse_mem_total("MemFree: 1 kB"), None);
    }

    #[test]
    fn a_huge_film_or_map_is_refused_with_the_estimate_and_the_limit() {
        let small = estimate(
            (10_000, 160_000),
            Backend::Embree,
            CurveKind::Round,
            &settings(64, 64),
            1,
            2,
            false,
        );
        assert!(small.check(1 << 30, "test").is_ok(), "{small:?}");
        let big = estimate(
            (10_000, 160_000),
            Backend::Embree,
            CurveKind::Round,
            &settings(32768, 32768),
            1,
            2,
            false,
        );
        let e = big.check(8 << 30, "--max-memory").unwrap_err().to_string();
        assert!(
            e.contains("film and AOVs 612 GiB") && e.contains("8 GiB (--max-memory)"),
            "{e}"
        );
        let mut maps = settings(64, 64);
        maps.shadows.mode = ShadowMode::DeepOpacity;
        maps.shadows.deep_opacity.resolution = 8192;
        maps.shadows.deep_opacity.layers = 256;
        let e = estimate((1, 16), Backend::Bvh, CurveKind::Flat, &maps, 1, 1, false);
        assert_eq!(e.shadow_maps, 8192 * 8192 * 258 * 4);
    }

    /// A splatting film counts its edge sums, by the values its channels need, adaptive or not; filter importance
    /// sampling does not. Under adaptive sampling each source pixel's splats kept between rounds count too.
    #[test]
    fn a_splatting_film_counts_its_sums() {
        let bytes = |reconstruction, aovs: &[&str], adaptive| {
            let mut s = settings(1000, 1000);
            s.film.reconstruction = reconstruction;
            s.film.aovs = aovs.iter().map(|a| a.to_string()).collect();
            estimate(
                (1, 16),
                Backend::Embree,
                CurveKind::Flat,
                &s,
                1,
                2,
                adaptive,
            )
        };
        use crate::render::Reconstruction::{Importance, Splat};
        let pixels = 1_000_000;
        // A filter of 8 px reaches 4 px (the edge bands of the work tiles 4× as wide).
        let wide = |aovs: &[&str]| {
            let mut s = settings(1000, 1000);
            s.film.filter_width = 8.0;
            s.film.aovs = aovs.iter().map(|a| a.to_string()).collect();
            estimate((1, 16), Backend::Embree, CurveKind::Flat, &s, 1, 2, false).film
        };
        assert_eq!(
            wide(&[]),
            pixels * 4 * 4 * FILM_COPIES
                + pixels * 4 * (SPLAT_BYTES_PER_PIXEL + 5 * SPLAT_BYTES_PER_PIXEL_PER_VALUE)
        );
        for (aovs, values, channels) in [(&[][..], 5, 4), (&["all"][..], 31, 38)] {
            let plain = pixels * channels * 4 * FILM_COPIES;
            assert_eq!(bytes(Importance, aovs, false).film, plain);
            let splat =
                plain + pixels * (SPLAT_BYTES_PER_PIXEL + SPLAT_BYTES_PER_PIXEL_PER_VALUE * values);
            assert_eq!(bytes(Splat, aovs, false).film, splat);
            let adaptive = bytes(Splat, aovs, true);
            assert_eq!(adaptive.film, splat);
            assert_eq!(
                adaptive.adaptive,
                pixels
                    * (ADAPTIVE_BYTES_PER_PIXEL
                        + ADAPTIVE_SPLAT_BYTES_PER_PIXEL
                        + ADAPTIVE_SPLAT_BYTES_PER_PIXEL_PER_VALUE * values * 9)
            );
            assert_eq!(
                bytes(Importance, aovs, true).adaptive,
                pixels * ADAPTIVE_BYTES_PER_PIXEL
            );
        }
    }

    /// An adaptive frame (or one `--quality auto` will make adaptive) counts its per-pixel state: a 6144² film
    /// that fits a limit at a fixed spp is refused adaptive once the rounds' 46.5 GiB (6.8 of statistics, the rest
    /// every AOV's splats) are added, and the refusal names them.
    #[test]
    fn adaptive_sampling_state_is_counted() {
        let film = settings(6144, 6144);
        let fixed = estimate(
            (1, 16),
            Backend::Embree,
            CurveKind::Flat,
            &film,
            1,
            2,
            false,
        );
        assert_eq!(fixed.adaptive, 0);
        let limit = fixed.total() + (1 << 30);
        assert!(fixed.check(limit, "test").is_ok(), "{fixed:?}");
        let auto = estimate((1, 16), Backend::Embree, CurveKind::Flat, &film, 1, 2, true);
        // Every AOV's 30 quantities and the weight, towards 3 × 3 targets.
        let splat =
            ADAPTIVE_SPLAT_BYTES_PER_PIXEL + ADAPTIVE_SPLAT_BYTES_PER_PIXEL_PER_VALUE * 31 * 9;
        assert_eq!(
            auto.adaptive,
            6144 * 6144 * (ADAPTIVE_BYTES_PER_PIXEL + splat)
        );
        let e = auto.check(limit, "test").unwrap_err().to_string();
        assert!(e.contains("adaptive sampling 46.5 GiB"), "{e}");
        let mut scheduled = film.clone();
        scheduled.adaptive = Some(crate::quality::adaptive_schedule(
            16,
            0.1,
            1.0,
            1.0,
            &crate::quality::QualityConfig::default(),
        ));
        let e = estimate(
            (1, 16),
            Backend::Embree,
            CurveKind::Flat,
            &scheduled,
            1,
            2,
            false,
        );
        assert_eq!(e.adaptive, auto.adaptive);
    }

    #[test]
    fn absurd_thread_counts_are_refused() {
        assert_eq!(check_threads(2), Ok(2));
        assert!(check_threads(0).is_err());
        let e = check_threads(100_000_000).unwrap_err();
        assert!(e.contains("more than 1024"), "{e}");
    }
}
