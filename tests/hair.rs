//! Hair readers and generators: the real files of the test data's `hair/` load with the counts their headers declare,
//! every kind of bad input gives an error that names the file and the problem, `.hair` files round-trip, and
//! procedural models are valid and deterministic.
//!
//! The real files are required (the data folder, `CUTICLE_DATA`: see docs/data.md): without them these tests fail
//! naming the file, they never skip.

mod common;

use std::path::{Path, PathBuf};

use common::data;
use cuticle::hair::procedural::{FurBall, Procedural, WavyPatch};
use cuticle::hair::{self, tfx, yuksel, HairError, HairModel, Strands};

/// The real files, in the data folder.
const STRAIGHT: &str = "hair/straight.hair";
const FURBALL: &str = "hair/furball.hair";
const MOHAWK: &str = "hair/Ratboy_mohawk.tfx";

/// Offsets into the real `.hair` files, from their headers (see SOURCES.md in the data folder).
const STRAIGHT_STRANDS: usize = 10_000;
const STRAIGHT_POINTS: usize = 160_000;
const FURBALL_STRANDS: usize = 30_367;
const FURBALL_POINTS: usize = 485_872;
const FURBALL_SEGMENTS_AT: usize = 128;
const FURBALL_POINTS_AT: usize = FURBALL_SEGMENTS_AT + 2 * FURBALL_STRANDS;
const FURBALL_THICKNESS_AT: usize = FURBALL_POINTS_AT + 12 * FURBALL_POINTS;
const MOHAWK_STRANDS: usize = 2228;
const MOHAWK_VERTICES: usize = 32;
const MOHAWK_POSITIONS_END: usize = 160 + 16 * MOHAWK_STRANDS * MOHAWK_VERTICES;

/// The path of the real data file `rel`; panics (fails the test) naming it when it is missing.
#[track_caller]
fn path(rel: &str) -> PathBuf {
    data::file(rel)
}

/// The bytes of the real data file `rel`; panics (fails the test) naming it when it is missing.
#[track_caller]
fn bytes(rel: &str) -> Vec<u8> {
    let path = path(rel);
    std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Writes `bytes` to a temporary file called `name`, loads it, and returns the error message. Asserts that loading
/// fails and that the message names the file.
fn load_error(name: &str, bytes: &[u8]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    let err = match hair::load(&path) {
        Ok(m) => panic!(
            "{name}: expected an error, loaded {} strands",
            m.strand_count()
        ),
        Err(e) => e.to_string(),
    };
    assert!(
        err.contains(&path.display().to_string()),
        "the message must name the file {}: {err}",
        path.display()
    );
    err
}

fn assert_contains(message: &str, expected: &[&str]) {
    for e in expected {
        assert!(message.contains(e), "expected {e:?} in: {message}");
    }
}

fn put_u32(b: &mut [u8], at: usize, v: u32) {
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

fn put_u16(b: &mut [u8], at: usize, v: u16) {
    b[at..at + 2].copy_from_slice(&v.to_le_bytes());
}

fn put_f32(b: &mut [u8], at: usize, v: f32) {
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

fn assert_same_model(a: &HairModel, b: &HairModel) {
    assert_eq!(a.strand_offsets, b.strand_offsets);
    assert_eq!(a.points, b.points);
    assert_eq!(a.radius, b.radius);
    assert_eq!(a.radius_from_file, b.radius_from_file);
    assert_eq!(a.transparency, b.transparency);
    assert_eq!(a.color, b.color);
    assert_eq!(a.info, b.info);
}

// ---------------------------------------------------------------------------------------------------------------
// Real files

#[test]
fn straight_hair_loads_with_its_declared_counts() {
    let bytes = bytes(STRAIGHT);
    let header = yuksel::Header::parse(&path(STRAIGHT), &bytes).unwrap();
    assert_eq!(header.flags, yuksel::HAS_POINTS | yuksel::HAS_COLORS);
    let m = hair::load(&path(STRAIGHT)).unwrap();
    assert_eq!(m.strand_count(), header.strand_count as usize);
    assert_eq!(m.points.len(), header.point_count as usize);
    assert_eq!(
        (m.strand_count(), m.points.len()),
        (STRAIGHT_STRANDS, STRAIGHT_POINTS)
    );
    assert!((0..m.strand_count()).all(|s| m.strand_range(s).len() == 16));
    // No thickness array: the default 0.1 is a diameter, and the B-spline conversion may taper it.
    assert!(!m.radius_from_file);
    assert!(m.radius.iter().all(|&r| r == 0.05));
    assert!(m.transparency.iter().all(|&t| (t - 0.3558).abs() < 1e-4));
    let c = m.color[1234];
    assert!(
        (c[0] - 1.0).abs() < 1e-3 && (c[1] - 0.925).abs() < 1e-3 && (c[2] - 0.569).abs() < 1e-3,
        "{c:?}"
    );
    assert!(m.info.contains("Cem Yuksel"), "{}", m.info);
    assert_eq!(m.format, yuksel::FORMAT);
    let (lo, hi) = m.bounds();
    assert!(lo.x < -32.0 && hi.z > 63.0, "bounds {lo} {hi}");
}

#[test]
fn furball_hair_loads_with_its_declared_counts() {
    let bytes = bytes(FURBALL);
    let header = yuksel::Header::parse(&path(FURBALL), &bytes).unwrap();
    assert_eq!(
        header.flags,
        yuksel::HAS_SEGMENTS | yuksel::HAS_POINTS | yuksel::HAS_THICKNESS
    );
    let m = hair::load(&path(FURBALL)).unwrap();
    assert_eq!(m.strand_count(), header.strand_count as usize);
    assert_eq!(m.points.len(), header.point_count as usize);
    assert_eq!(
        (m.strand_count(), m.points.len()),
        (FURBALL_STRANDS, FURBALL_POINTS)
    );
    assert!(m.radius_from_file);
    // Thickness in the file is the diameter 0.001875–0.01, so radii are half of that.
    let (rmin, rmax) = m
        .radius
        .iter()
        .fold((f32::MAX, 0f32), |(lo, hi), &r| (lo.min(r), hi.max(r)));
    assert!(
        (rmin - 0.0009375).abs() < 1e-6 && (rmax - 0.005).abs() < 1e-6,
        "{rmin} {rmax}"
    );
    assert!(m.info.starts_with("Embree furBall_A"), "{}", m.info);
    // Converts to B-spline strands: n points give n − 1 segments.
    let s = Strands::from_model(&m);
    assert_eq!(s.segment_count(), FURBALL_POINTS - FURBALL_STRANDS);
}

#[test]
fn mohawk_tfx_loads_with_its_declared_counts() {
    let bytes = bytes(MOHAWK);
    let header = tfx::Header::parse(&path(MOHAWK), &bytes).unwrap();
    assert_eq!(header.version, 4.0);
    let m = hair::load(&path(MOHAWK)).unwrap();
    assert_eq!(m.strand_count(), header.strand_count as usize);
    assert_eq!(
        m.points.len(),
        (header.strand_count * header.vertices_per_strand) as usize
    );
    assert_eq!(
        (m.strand_count(), m.points.len()),
        (MOHAWK_STRANDS, MOHAWK_STRANDS * MOHAWK_VERTICES)
    );
    assert_eq!(m.format, tfx::FORMAT);
    let (lo, hi) = m.bounds();
    assert!(
        (lo.y - 0.214).abs() < 0.001 && (hi.y - 1.110).abs() < 0.001,
        "y-up bounds {lo} {hi}"
    );
    // Default radius: 0.5 × the median segment length (0.00257) ≈ 0.0013, about 1/850 of the model.
    assert!(!m.radius_from_file);
    assert!((m.radius[0] - 0.00128).abs() < 0.00002, "{}", m.radius[0]);
    let size = (hi - lo).length();
    assert!(
        (size / 1000.0..size / 300.0).contains(&m.radius[0]),
        "radius {} for size {size}",
        m.radius[0]
    );
}

#[test]
fn unknown_extension_and_missing_file_are_errors_naming_the_file() {
    let e = load_error("model.obj", b"HAIR");
    assert_contains(&e, &["unknown hair format"]);
    let missing = Path::new("/nonexistent/dir/none.hair");
    let e = hair::load(missing).unwrap_err();
    assert!(matches!(e, HairError::Io { .. }), "{e:?}");
    assert!(e.to_string().contains("/nonexistent/dir/none.hair"), "{e}");
}

// ---------------------------------------------------------------------------------------------------------------
// Bad .hair input

#[test]
fn hair_empty_file() {
    assert_contains(&load_error("empty.hair", b""), &["empty file", "0 bytes"]);
}

#[test]
fn hair_bad_magic() {
    let mut b = bytes(STRAIGHT);
    b[..4].copy_from_slice(b"HAIX");
    assert_contains(&load_error("magic.hair", &b), &["magic", "HAIX"]);
    // A TressFX file under a .hair name is caught by the magic too.
    assert_contains(&load_error("renamed.hair", &bytes(MOHAWK)), &["magic"]);
}

#[test]
fn hair_truncated_header() {
    let b = bytes(STRAIGHT);
    assert_contains(
        &load_error("header.hair", &b[..100]),
        &["truncated header", "100 bytes", "128"],
    );
}

#[test]
fn hair_truncated_arrays() {
    let straight = bytes(STRAIGHT);
    let points_end = 128 + 12 * STRAIGHT_POINTS;
    assert_contains(
        &load_error("points.hair", &straight[..points_end - 5]),
        &[
            "truncated in the points array",
            &format!("file has {} bytes", points_end - 5),
            "3840128",
        ],
    );
    assert_contains(
        &load_error("colors.hair", &straight[..straight.len() - 1]),
        &["truncated in the colors array"],
    );
    let furball = bytes(FURBALL);
    assert_contains(
        &load_error("segments.hair", &furball[..FURBALL_SEGMENTS_AT + 100]),
        &["truncated in the segments array", "bytes 128..60862"],
    );
    assert_contains(
        &load_error("thickness.hair", &furball[..FURBALL_THICKNESS_AT + 8]),
        &["truncated in the thickness array"],
    );
}

#[test]
fn hair_trailing_garbage() {
    let mut b = bytes(STRAIGHT);
    b.extend_from_slice(b"garbage");
    assert_contains(
        &load_error("trailing.hair", &b),
        &["7 bytes of trailing data", "3840135", "3840128"],
    );
}

#[test]
fn hair_point_count_disagrees_with_segments() {
    // With a segments array: one strand one segment shorter, so the sum is one less than the header says.
    let mut b = bytes(FURBALL);
    put_u16(&mut b, FURBALL_SEGMENTS_AT + 2 * 10, 14);
    assert_contains(
        &load_error("segments-sum.hair", &b),
        &["point count mismatch", "485872", "485871", "segments array"],
    );
    // Without one: the header's point count against strands × (default segments + 1).
    let mut b = bytes(STRAIGHT);
    put_u32(&mut b, 8, 159_999);
    assert_contains(
        &load_error("default-segments.hair", &b),
        &[
            "point count mismatch",
            "159999",
            "10000 strands × (15 default segments + 1) = 160000",
        ],
    );
}

#[test]
fn hair_strand_with_zero_segments() {
    // Strand 3 gets 0 segments and strand 4 its 15 on top of its own, so the counts still agree.
    let mut b = bytes(FURBALL);
    put_u16(&mut b, FURBALL_SEGMENTS_AT + 2 * 3, 0);
    put_u16(&mut b, FURBALL_SEGMENTS_AT + 2 * 4, 30);
    assert_contains(
        &load_error("zero-segments.hair", &b),
        &["strand 3 has 1 point(s)", "at least 2"],
    );
}

#[test]
fn hair_non_finite_points() {
    for (name, v) in [
        ("nan.hair", f32::NAN),
        ("inf.hair", f32::INFINITY),
        ("neg-inf.hair", f32::NEG_INFINITY),
    ] {
        let mut b = bytes(FURBALL);
        put_f32(&mut b, FURBALL_POINTS_AT + 12 * 5 + 4, v);
        assert_contains(&load_error(name, &b), &["point 5 is not finite"]);
    }
}

#[test]
fn hair_bad_thickness() {
    for (name, v, shown) in [
        ("zero.hair", 0.0, "thickness 0"),
        ("negative.hair", -0.01, "thickness -0.01"),
        ("nan-thickness.hair", f32::NAN, "thickness NaN"),
    ] {
        let mut b = bytes(FURBALL);
        put_f32(&mut b, FURBALL_THICKNESS_AT + 4 * 7, v);
        assert_contains(&load_error(name, &b), &["point 7", shown, "must be > 0"]);
    }
    // No thickness array: the header default is used, and checked.
    let mut b = bytes(STRAIGHT);
    put_f32(&mut b, 20, 0.0);
    assert_contains(
        &load_error("default-thickness.hair", &b),
        &["default thickness is 0"],
    );
}

#[test]
fn hair_transparency_outside_unit_interval() {
    // Header default (straight.hair has no transparency array).
    let mut b = bytes(STRAIGHT);
    put_f32(&mut b, 24, 1.5);
    assert_contains(
        &load_error("default-transparency.hair", &b),
        &["default transparency is 1.5", "[0, 1]"],
    );
    // Per-point array: write a model that has one, then corrupt an entry.
    let mut m = hair::load(&path(STRAIGHT)).unwrap();
    m.transparency[3] = 0.5;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("with-transparency.hair");
    yuksel::write(&path, &m).unwrap();
    let mut b = std::fs::read(&path).unwrap();
    let header = yuksel::Header::parse(&path, &b).unwrap();
    assert_eq!(header.flags, yuksel::HAS_POINTS | yuksel::HAS_TRANSPARENCY);
    let transparency_at = 128 + 12 * STRAIGHT_POINTS;
    put_f32(&mut b, transparency_at + 4 * 9, -0.5);
    assert_contains(
        &load_error("transparency.hair", &b),
        &["point 9 has transparency -0.5", "[0, 1]"],
    );
}

// ---------------------------------------------------------------------------------------------------------------
// Bad .tfx input

#[test]
fn tfx_empty_and_truncated_header() {
    assert_contains(&load_error("empty.tfx", b""), &["empty file"]);
    let b = bytes(MOHAWK);
    assert_contains(
        &load_error("header.tfx", &b[..100]),
        &["truncated header", "100 bytes", "160"],
    );
    assert_contains(&load_error("tiny.tfx", &b[..3]), &["truncated header"]);
}

#[test]
fn tfx_bad_version() {
    // A Yuksel file under a .tfx name: its magic read as a version.
    assert_contains(
        &load_error("renamed.tfx", &bytes(STRAIGHT)),
        &["not a tressfx 4 .tfx file", "expected 4.0"],
    );
    let mut b = bytes(MOHAWK);
    put_f32(&mut b, 0, 3.0);
    assert_contains(&load_error("v3.tfx", &b), &["version field is 3"]);
}

#[test]
fn tfx_bad_counts() {
    let mut b = bytes(MOHAWK);
    put_u32(&mut b, 4, 0);
    assert_contains(&load_error("no-strands.tfx", &b), &["0 strands"]);
    let mut b = bytes(MOHAWK);
    put_u32(&mut b, 8, 1);
    assert_contains(
        &load_error("one-vertex.tfx", &b),
        &["1 vertices per strand", "at least 2"],
    );
    // More strands than the file holds: the positions run into the strand UVs.
    let mut b = bytes(MOHAWK);
    put_u32(&mut b, 4, 2229);
    assert_contains(
        &load_error("overlap.tfx", &b),
        &["vertex position array", "overlaps the strand uv array"],
    );
}

#[test]
fn tfx_truncated_arrays() {
    let b = bytes(MOHAWK);
    assert_contains(
        &load_error("positions.tfx", &b[..MOHAWK_POSITIONS_END - 16]),
        &[
            "truncated in the vertex position array",
            &format!("bytes 160..{MOHAWK_POSITIONS_END}"),
            "2228 strands × 32 vertices",
        ],
    );
    assert_contains(
        &load_error("uv.tfx", &b[..b.len() - 8]),
        &["truncated in the strand uv array"],
    );
}

#[test]
fn tfx_trailing_garbage() {
    let mut b = bytes(MOHAWK);
    b.extend_from_slice(&[0; 12]);
    assert_contains(
        &load_error("trailing.tfx", &b),
        &["12 bytes of trailing data", "1158732", "1158720"],
    );
}

#[test]
fn tfx_non_finite_point() {
    let mut b = bytes(MOHAWK);
    put_f32(&mut b, 160 + 16 * 40 + 8, f32::NAN);
    assert_contains(&load_error("nan.tfx", &b), &["point 40 is not finite"]);
}

/// A `.tfx` stores no thickness (its radius follows the points' spacing), so points too far out are blamed as
/// points, not as an infinite "thickness" (what a 10³⁰-scaled mohawk reported).
#[test]
fn tfx_points_too_far_out_are_blamed_as_points_not_as_a_thickness() {
    let mut b = bytes(MOHAWK);
    let h = cuticle::hair::tfx::Header::parse(Path::new("m.tfx"), &b).unwrap();
    let n = h.strand_count as usize * h.vertices_per_strand as usize;
    for k in 0..n * 4 {
        let at = 160 + 4 * k;
        let v = f32::from_le_bytes(b[at..at + 4].try_into().unwrap());
        put_f32(&mut b, at, v * 1e30);
    }
    let e = load_error("far.tfx", &b);
    assert_contains(&e, &["reaches farther than", "scale the model down"]);
    assert!(!e.contains("thickness") && !e.contains("radius"), "{e}");
}

// ---------------------------------------------------------------------------------------------------------------
// Round trips

#[test]
fn real_hair_files_round_trip_through_write() {
    let dir = tempfile::tempdir().unwrap();
    for src in [STRAIGHT, FURBALL] {
        let m = hair::load(&path(src)).unwrap();
        let out: PathBuf = dir.path().join("copy.hair");
        yuksel::write(&out, &m).unwrap();
        let back = hair::load(&out).unwrap();
        assert_same_model(&m, &back);
    }
}

#[test]
fn tfx_model_exports_to_hair() {
    let m = hair::load(&path(MOHAWK)).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("mohawk.hair");
    yuksel::write(&out, &m).unwrap();
    let back = yuksel::read(&out).unwrap();
    assert_same_model(&m, &back);
}

#[test]
fn writing_an_invalid_model_is_an_error_naming_the_destination() {
    let m = HairModel::default();
    let e = yuksel::write(Path::new("/tmp/never-written.hair"), &m)
        .unwrap_err()
        .to_string();
    assert_contains(&e, &["/tmp/never-written.hair", "no strands"]);
    assert!(!Path::new("/tmp/never-written.hair").exists());
}

// ---------------------------------------------------------------------------------------------------------------
// Procedural models

/// Points hashed bit for bit, to compare whole models cheaply.
fn fingerprint(m: &HairModel) -> Vec<u32> {
    m.points
        .iter()
        .flat_map(|p| p.to_array().map(f32::to_bits))
        .chain(m.radius.iter().map(|r| r.to_bits()))
        .collect()
}

#[test]
fn default_procedural_models_are_valid_and_hair_sized() {
    for p in [
        Procedural::default(),
        Procedural::WavyPatch(WavyPatch::default()),
    ] {
        let m = p.generate().unwrap();
        m.validate(Path::new("check")).unwrap();
        let (strands, points) = match &p {
            Procedural::FurBall(f) => (f.strands, f.points),
            Procedural::WavyPatch(w) => (w.strands, w.points),
        };
        assert_eq!(m.strand_count(), strands as usize);
        assert_eq!(m.points.len(), (strands * points) as usize);
        // A strand radius of 1/300–1/1000 of the model size reads as hair.
        let (lo, hi) = m.bounds();
        let size = (hi - lo).max_element();
        let root = m.radius[0];
        assert!(
            (size / 1000.0..=size / 300.0).contains(&root),
            "{}: root radius {root}, size {size}",
            p.kind()
        );
        assert!(m.radius[points as usize - 1] < root, "tapered");
        assert!(m.radius_from_file);
        let s = Strands::from_model(&m);
        assert_eq!(s.strand_count(), strands as usize);
    }
}

#[test]
fn default_fur_ball_is_a_ten_to_twenty_thousand_strand_model() {
    let Procedural::FurBall(f) = Procedural::default() else {
        panic!("the default procedural model is the fur ball");
    };
    assert!(
        (10_000..=20_000).contains(&f.strands) && f.points == 16,
        "{f:?}"
    );
}

#[test]
fn procedural_models_are_deterministic_from_the_seed() {
    let ball = |seed| {
        Procedural::FurBall(FurBall {
            seed,
            strands: 2000,
            ..FurBall::default()
        })
    };
    let patch = |seed| {
        Procedural::WavyPatch(WavyPatch {
            seed,
            strands: 1000,
            ..WavyPatch::default()
        })
    };
    for make in [&ball as &dyn Fn(u64) -> Procedural, &patch] {
        let a = fingerprint(&make(7).generate().unwrap());
        let b = fingerprint(&make(7).generate().unwrap());
        let c = fingerprint(&make(8).generate().unwrap());
        assert_eq!(a, b, "{}: same seed, same model", make(7).kind());
        assert_ne!(a, c, "{}: another seed, another model", make(7).kind());
    }
}

#[test]
fn procedural_strand_does_not_depend_on_the_strand_count() {
    // A patch strand is keyed by (seed, i) and its clump centres by (seed, j), so adding strands leaves the first
    // ones unchanged: a scene can raise the count without reshuffling the groom.
    let small = Procedural::WavyPatch(WavyPatch {
        strands: 10,
        ..WavyPatch::default()
    })
    .generate()
    .unwrap();
    let large = Procedural::WavyPatch(WavyPatch {
        strands: 100,
        ..WavyPatch::default()
    })
    .generate()
    .unwrap();
    let n = small.strand_range(0).len();
    assert_eq!(small.points[..n], large.points[..n]);
}

#[test]
fn procedural_config_deserialises_from_toml() {
    let p: Procedural = toml::from_str("kind = \"fur-ball\"\nstrands = 100\nseed = 3").unwrap();
    assert_eq!(
        p,
        Procedural::FurBall(FurBall {
            strands: 100,
            seed: 3,
            ..FurBall::default()
        })
    );
    let p: Procedural =
        toml::from_str("kind = \"wavy-patch\"\nclumps = 0\nwave_amplitude = 0.1").unwrap();
    assert_eq!(p.kind(), "wavy-patch");
    let e = toml::from_str::<Procedural>("kind = \"fur-ball\"\nstrand = 100")
        .unwrap_err()
        .to_string();
    assert!(e.contains("unknown field `strand`"), "{e}");
    let e = toml::from_str::<Procedural>("kind = \"fur-bal\"")
        .unwrap_err()
        .to_string();
    assert!(e.contains("fur-bal"), "{e}");
}

#[test]
fn procedural_bad_parameters_name_the_key() {
    let ball = |f: FurBall| Procedural::FurBall(f).generate().unwrap_err().to_string();
    let patch = |w: WavyPatch| Procedural::WavyPatch(w).generate().unwrap_err().to_string();
    let cases = [
        (
            ball(FurBall {
                strands: 0,
                ..FurBall::default()
            }),
            "strands must be >= 1",
        ),
        (
            ball(FurBall {
                points: 1,
                ..FurBall::default()
            }),
            "points must be >= 2",
        ),
        (
            ball(FurBall {
                length: -1.0,
                ..FurBall::default()
            }),
            "length must be > 0, got -1",
        ),
        (
            ball(FurBall {
                fiber_radius: 0.0,
                ..FurBall::default()
            }),
            "fiber_radius must be > 0",
        ),
        (
            ball(FurBall {
                sphere_radius: f32::NAN,
                ..FurBall::default()
            }),
            "sphere_radius must be > 0, got NaN",
        ),
        (
            ball(FurBall {
                taper: 0.0,
                ..FurBall::default()
            }),
            "taper",
        ),
        (
            ball(FurBall {
                strands: u32::MAX,
                ..FurBall::default()
            }),
            "more than",
        ),
        (
            patch(WavyPatch {
                wavelength: 0.0,
                ..WavyPatch::default()
            }),
            "wavelength must be > 0",
        ),
        (
            patch(WavyPatch {
                clump_strength: 1.5,
                ..WavyPatch::default()
            }),
            "clump_strength must be in [0, 1], got 1.5",
        ),
        (
            patch(WavyPatch {
                transparency: -0.1,
                ..WavyPatch::default()
            }),
            "transparency must be in [0, 1]",
        ),
        (
            patch(WavyPatch {
                length_variation: 1.0,
                ..WavyPatch::default()
            }),
            "length_variation must be in [0, 1)",
        ),
    ];
    for (message, expected) in cases {
        assert_contains(&message, &["procedural:", expected]);
    }
}

#[test]
fn procedural_model_exports_to_hair_and_reads_back() {
    let m = Procedural::FurBall(FurBall {
        strands: 500,
        ..FurBall::default()
    })
    .generate()
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ball.hair");
    yuksel::write(&out, &m).unwrap();
    let back = hair::load(&out).unwrap();
    assert_same_model(&m, &back);
}
