//! Hostile inputs: nothing a user feeds cuticle may exhaust the machine, hang it, print
//! an error twice, blame the wrong key, or end with exit 0 and a wrong or non-finite image. Each case is tiny.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

use cuticle::hair::{self, yuksel, HairModel};
use cuticle::render::film::channel;
use cuticle::render::CHANNELS;
use cuticle::scene::Scene;
use glam::Vec3;

const EXE: &str = env!("CARGO_BIN_EXE_cuticle");

fn cuticle(args: &[&str]) -> Output {
    Command::new(EXE).args(args).output().expect("run cuticle")
}

/// The error line of a failed run: exit code 2, exactly one line, starting "cuticle: error: ".
fn error_of(out: &Output) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "one line expected: {stderr}");
    assert!(lines[0].starts_with("cuticle: error: "), "{stderr}");
    lines[0].to_owned()
}

/// A small valid model: `n` straight strands of 4 points along y, radius 0.01, colour `color`.
fn model(n: usize, color: [f32; 3]) -> HairModel {
    let mut m = HairModel {
        strand_offsets: vec![0],
        format: yuksel::FORMAT.to_owned(),
        ..Default::default()
    };
    for s in 0..n {
        for k in 0..4 {
            m.points
                .push(Vec3::new(0.1 * s as f32, 0.3 * k as f32, 0.0));
            m.radius.push(0.01);
            m.transparency.push(0.0);
            m.color.push(color);
        }
        m.strand_offsets.push(m.points.len() as u32);
    }
    m
}

/// Writes `bytes` as `name` in `dir`.
fn put(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

// ---- reading: special files, lying headers, size bounds ----

#[cfg(unix)]
fn fifo(dir: &Path, name: &str) -> PathBuf {
    let path = dir.join(name);
    let ok = Command::new("mkfifo")
        .arg(&path)
        .status()
        .unwrap()
        .success();
    assert!(ok, "mkfifo {}", path.display());
    path
}

#[cfg(unix)]
#[test]
fn fifos_devices_and_directories_are_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let start = Instant::now();
    for (path, want) in [
        (fifo(dir.path(), "a.hair"), "named pipe"),
        (fifo(dir.path(), "a.tfx"), "named pipe"),
        (dir.path().join("sub.hair"), "a directory"),
    ] {
        if want == "a directory" {
            std::fs::create_dir(&path).unwrap();
        }
        let e = hair::load(&path).unwrap_err().to_string();
        assert!(e.contains(want), "{}: {e}", path.display());
    }
    // /dev/zero as a hair file needs an extension to be read as one: through a symbolic link.
    let zero = dir.path().join("zero.hair");
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    let e = hair::load(&zero).unwrap_err().to_string();
    assert!(e.contains("character device"), "{e}");
    for scene in [fifo(dir.path(), "s.toml"), PathBuf::from("/dev/zero")] {
        let e = Scene::load(&scene).unwrap_err().to_string();
        assert!(e.contains("not a regular file"), "{e}");
    }
    let env = fifo(dir.path(), "map.exr");
    let e = cuticle::light::Environment::load(&env, 1.0, 0.0, Vec3::Y)
        .unwrap_err()
        .to_string();
    assert!(e.contains("named pipe"), "{e}");
    assert!(
        start.elapsed() < Duration::from_secs(5),
        "a special file blocked"
    );
}

#[test]
fn a_header_asking_for_2_pow_32_strands_is_refused_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let mut h = vec![0u8; yuksel::HEADER_SIZE];
    h[..4].copy_from_slice(b"HAIR");
    h[4..8].copy_from_slice(&u32::MAX.to_le_bytes());
    h[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
    h[12..16].copy_from_slice(&yuksel::HAS_POINTS.to_le_bytes());
    // With default segments 0 the counts agree (2³² − 1 one-point strands), so only the size can refuse it.
    let e = hair::load(&put(dir.path(), "big.hair", &h))
        .unwrap_err()
        .to_string();
    assert!(e.contains("truncated in the points array"), "{e}");
    // With a segments array the sum over the (absent) array is never taken.
    h[12..16].copy_from_slice(&(yuksel::HAS_POINTS | yuksel::HAS_SEGMENTS).to_le_bytes());
    let e = yuksel::parse(Path::new("big.hair"), &h)
        .unwrap_err()
        .to_string();
    assert!(e.contains("truncated in the segments array"), "{e}");
}

#[test]
fn tfx_counts_that_overflow_blame_the_counts() {
    let mut h = vec![0u8; cuticle::hair::tfx::HEADER_SIZE];
    h[..4].copy_from_slice(&4.0f32.to_le_bytes());
    h[4..8].copy_from_slice(&u32::MAX.to_le_bytes());
    h[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
    h[12..16].copy_from_slice(&0xffff_fff0u32.to_le_bytes());
    let e = cuticle::hair::tfx::parse(Path::new("x.tfx"), &h)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("4294967295 strands × 4294967295 vertices per strand")
            && e.contains("vertex position array larger than any file"),
        "{e}"
    );
}

#[test]
fn a_huge_file_is_refused_by_its_size_without_being_read() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = yuksel::encode(Path::new("m.hair"), &model(2, [0.5; 3])).unwrap();
    let path = put(dir.path(), "sparse.hair", &bytes);
    // 4 GiB of trailing zeros, sparse: no disk space, and reading it would take seconds and 4 GiB.
    let f = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
    f.set_len(4 << 30).unwrap();
    let start = Instant::now();
    let e = hair::load(&path).unwrap_err().to_string();
    assert!(e.contains("bytes of trailing data"), "{e}");
    assert!(
        start.elapsed() < Duration::from_secs(1),
        "{:?}",
        start.elapsed()
    );
    let scene = put(dir.path(), "big.toml", b"[hair]\n");
    std::fs::OpenOptions::new()
        .write(true)
        .open(&scene)
        .unwrap()
        .set_len(17 << 20)
        .unwrap();
    let e = Scene::load(&scene).unwrap_err().to_string();
    assert!(e.contains("more than the 16 MiB"), "{e}");
}

// ---- messages ----

#[test]
fn an_os_error_is_printed_once() {
    let e = error_of(&cuticle(&["render", "/nonexistent/scene.toml"]));
    assert_eq!(e.matches("os error 2").count(), 1, "{e}");
    let e = error_of(&cuticle(&["info", "/nonexistent/x.hair"]));
    assert_eq!(e.matches("os error 2").count(), 1, "{e}");
}

fn scene_error(body: &str) -> String {
    let text = format!("[hair]\nprocedural = {{ kind = \"fur-ball\", strands = 10 }}\n{body}");
    Scene::parse(&text, Path::new("t.toml"), Path::new("."))
        .unwrap_err()
        .to_string()
}

#[test]
fn keys_are_blamed_by_name_in_the_units_written() {
    for (body, want) in [
        (
            "[[light]]\nkind = \"distant\"\ndirection = [0, -1, 0]\ncolor = [-1, 1, 1]",
            "light[0].color must be in [0, 1e10] per channel",
        ),
        (
            "[[light]]\nkind = \"quad\"\ncorner = [0, 2, 0]\nedge_u = [1, 0, 0]\nedge_v = [0, 0, 1]\nradiance = -1",
            "light[0].radiance must be in [0, 1e10], got -1",
        ),
        (
            "[[light]]\nkind = \"distant\"\ndirection = [0, -1, 0]\nangular_radius = 120",
            "light[0].angular_radius must be in [0, 90] degrees, got 120",
        ),
        (
            "[material]\nmodel = \"marschner\"\nalpha_1 = 50",
            "material.alpha_1 must be in [-45, 45] degrees, got 50",
        ),
        (
            "[material]\nmodel = \"ishair\"\nphi_g = 100",
            "material.phi_g must be in [0, 90] degrees, got 100",
        ),
        ("[film]\nresolution = [64, 64, \"junk\"]", "invalid type: string \"junk\""),
        ("[film]\nresolution = [64, 64, 64]", "invalid length 3"),
        ("[camera]\nup = [0, 1]", "invalid length 2"),
    ] {
        let e = scene_error(body);
        assert!(e.contains(want), "{body}\n=> {e}");
    }
}

// ---- no wrong image with exit 0: coordinates and the camera ----

#[test]
fn coordinates_that_would_make_rays_invalid_are_refused_at_load() {
    let dir = tempfile::tempdir().unwrap();
    let mut far = model(2, [0.5; 3]);
    far.points[5].x = 1e20;
    let path = put(
        dir.path(),
        "far.hair",
        &yuksel::encode(Path::new("far.hair"), &model(2, [0.5; 3])).unwrap(),
    );
    // Patch point 5's x in the file (the encoder refuses it, as the reader must).
    let mut bytes = std::fs::read(&path).unwrap();
    let at = yuksel::HEADER_SIZE + 5 * 12;
    bytes[at..at + 4].copy_from_slice(&1e20f32.to_le_bytes());
    std::fs::write(&path, &bytes).unwrap();
    let e = hair::load(&path).unwrap_err().to_string();
    assert!(e.contains("far.hair: point 5") && e.contains("1e15"), "{e}");
    assert!(yuksel::encode(&path, &far).is_err());

    for (body, want) in [
        ("[camera]\nposition = [1e30, 0, 0]", "camera.position must be finite"),
        ("[camera]\nlook_at = [nan, 0, 0]", "camera.look_at must be finite"),
        (
            "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 5]",
            "camera.look_at must differ from camera.position",
        ),
        (
            "[camera]\nposition = [0, 5, 0]\nlook_at = [0, 0, 0]",
            "camera.up [0.0, 1.0, 0.0] is parallel to the view direction",
        ),
        ("[camera]\nview = [0, 2, 0]", "is parallel to camera.view"),
        (
            "[[shape]]\nkind = \"quad\"\ncorner = [0, 1e20, 0]\nedge_u = [1, 0, 0]\nedge_v = [0, 0, 1]",
            "shape[0].corner must be finite and within 1e15",
        ),
    ] {
        let e = scene_error(body);
        assert!(e.contains(want), "{body}\n=> {e}");
    }
}

/// Loads the frame of `text` and returns the camera check's result, as `render` runs it after loading.
fn camera_check(text: &str) -> Result<(), String> {
    let scene =
        Scene::parse(text, Path::new("t.toml"), Path::new(".")).map_err(|e| e.to_string())?;
    let frame =
        cuticle::render::Frame::load(scene.resolve().unwrap()).map_err(|e| e.to_string())?;
    let [w, h] = frame.settings.film.resolution;
    frame
        .settings
        .camera
        .camera(frame.strands.bounds(), w, h)
        .map(|_| ())
}

#[test]
fn sizes_scales_and_auto_framing_that_break_rays_are_refused_naming_the_key() {
    let furball = "[hair]\nprocedural = { kind = \"fur-ball\", strands = 50 }\n";
    let e = camera_check(&format!("{furball}radius_scale = 1e30\n")).unwrap_err();
    assert!(e.contains("hair.radius_scale = 1e30"), "{e}");
    let e = camera_check(
        "[hair]\nprocedural = { kind = \"fur-ball\", strands = 50, sphere_radius = 1e20 }\n",
    )
    .unwrap_err();
    assert!(e.contains("sphere_radius must be at most 6.25e13"), "{e}");
    let e = camera_check(&format!("{furball}[camera]\nfov = 1e-30\n")).unwrap_err();
    assert!(e.contains("the auto-framed camera (camera.fov"), "{e}");
    let e = camera_check(&format!("{furball}[camera]\nmargin = 1e30\n")).unwrap_err();
    assert!(e.contains("farther than 1e18 from the origin"), "{e}");
    assert_eq!(camera_check(furball), Ok(()));
}

#[test]
fn a_model_near_the_coordinate_bound_still_renders_hair() {
    // 6e13 units across, 1/20 of the bound: rays must still hit (not "only background, exit 0").
    let text = "[hair]\nprocedural = { kind = \"fur-ball\", strands = 2000, sphere_radius = 6e13, length = 3e13, \
                fiber_radius = 2.4e11 }\n[film]\nresolution = [32, 32]\nspp = 1\n\
                [[light]]\nkind = \"distant\"\ndirection = [1, -1, -1]\n";
    let scene = Scene::parse(text, Path::new("far.toml"), Path::new(".")).unwrap();
    let image = common::render_scene(&scene, 2);
    let covered = image
        .data
        .chunks(CHANNELS.len())
        .filter(|p| p[channel("A")] > 0.5)
        .count();
    assert!(covered > 32 * 32 / 20, "hair covers {covered} pixels");
}

// ---- no NaN or Inf in outputs: parameters at their bounds render finite ----

fn assert_finite(text: &str, base: &Path) {
    let scene = Scene::parse(text, Path::new("t.toml"), base).unwrap();
    let image = common::render_scene(&scene, 2);
    let bad = image.data.iter().filter(|v| !v.is_finite()).count();
    // depth.Z is +∞ where the centre ray misses, by definition; every other channel must be finite.
    let depth_inf = image
        .data
        .chunks(CHANNELS.len())
        .filter(|p| p[channel("depth.Z")].is_infinite())
        .count();
    assert_eq!(bad, depth_inf, "{bad} non-finite values in\n{text}");
}

#[test]
fn parameters_at_their_bounds_give_finite_pixels_and_beyond_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    // Strand colours: 1 (the bound) renders; 1e38 from a file is refused.
    let bright = yuksel::encode(Path::new("c.hair"), &{
        let mut m = model(30, [1.0; 3]);
        m.color[0] = [0.9, 1.0, 1.0]; // not uniform, so a colour array is stored
        m
    })
    .unwrap();
    put(dir.path(), "bright.hair", &bright);
    let small = "[film]\nresolution = [16, 16]\nspp = 2\n";
    let lit = "[[light]]\nkind = \"distant\"\ndirection = [0, -1, -1]\nirradiance = 1e10\n";
    assert_finite(
        &format!("[hair]\nfile = \"bright.hair\"\n{small}{lit}[environment]\nradiance = [1e10, 1e10, 1e10]\n"),
        dir.path(),
    );
    let mut hostile = bright.clone();
    let colors = hostile.len() - 30 * 4 * 12;
    hostile[colors..colors + 4].copy_from_slice(&1e38f32.to_le_bytes());
    let e = hair::load(&put(dir.path(), "hostile.hair", &hostile))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("point 0 has colour") && e.contains("[0, 1]"),
        "{e}"
    );

    let furball = "[hair]\nprocedural = { kind = \"fur-ball\", strands = 300 }\n";
    for material in [
        "[material]\nmodel = \"kajiya-kay\"\nexponent = 1e4\n",
        "[material]\nmodel = \"ishair\"\nglint = 100\n",
        "[material]\nmodel = \"ishair\"\ncolor = [1, 1, 1]\ncolor_r = [1, 1, 1]\ncolor_tt = [1, 1, 1]\ncolor_trt = [1, 1, 1]\n",
        "[material]\nmodel = \"marschner\"\ncolor = [1, 1, 1]\nk_s1 = [1, 1, 1]\nk_s2 = [1, 1, 1]\n",
        "[material]\nmodel = \"kajiya-kay\"\ncolor = [1, 1, 1]\n",
    ] {
        assert_finite(&format!("{furball}{small}{lit}{material}"), dir.path());
    }
    for (body, want) in [
        (
            "[material]\nmodel = \"kajiya-kay\"\nexponent = 1e30",
            "material.exponent must be in [1, 1e4]",
        ),
        (
            "[material]\nmodel = \"ishair\"\nglint = 1e30",
            "material.glint must be in [0, 100]",
        ),
        (
            "[shadows]\ndeep_opacity = { min_width = 1000 }",
            "shadows.deep_opacity.min_width must be in [0, 16] texels",
        ),
        (
            "[material]\nmodel = \"ishair\"\ncolor_tt = [3e38, 1, 1]",
            "material.color_tt must be in [0, 1] per channel",
        ),
        (
            "[material]\nmodel = \"marschner\"\ncolor = [2, 2, 2]",
            "material.color must be in [0, 1] per channel",
        ),
        (
            "[material]\nmodel = \"marschner\"\nk_s1 = [0.5, -1, 0.5]",
            "material.k_s1 must be in [0, 1] per channel",
        ),
        (
            "[material]\nmodel = \"kajiya-kay\"\ncolor = [1, 1, 1.5]",
            "material.color must be in [0, 1] per channel",
        ),
        (
            "[environment]\nradiance = [1e30, 1, 1]",
            "environment.radiance must be in [0, 1e10]",
        ),
        (
            "[environment]\nradiance = [1e9, 1, 1]\nintensity = 100",
            "exceeds 1e10",
        ),
    ] {
        let e = scene_error(body);
        assert!(e.contains(want), "{body}\n=> {e}");
    }
}

// ---- settings that would exhaust memory ----

#[test]
fn frames_over_the_memory_limit_and_absurd_thread_counts_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.exr");
    let out = out.to_str().unwrap();
    let e = error_of(&cuticle(&[
        "render",
        "-q",
        "-o",
        out,
        "--res",
        "32768x32768",
    ]));
    assert!(
        e.contains("film and AOVs 612 GiB") && e.contains("raise --max-memory"),
        "{e}"
    );
    // The benchmarks load frames through the same check (Frame::load, default limit).
    let huge = put(
        dir.path(),
        "huge.toml",
        b"[hair]\nprocedural = { kind = \"fur-ball\", strands = 10 }\n[film]\nresolution = [32768, 32768]\n",
    );
    let e = error_of(&cuticle(&[
        "bench",
        "frame",
        huge.to_str().unwrap(),
        "--repetitions",
        "1",
    ]));
    assert!(e.contains("film and AOVs 612 GiB"), "{e}");
    let e = error_of(&cuticle(&[
        "render",
        "-q",
        "-o",
        out,
        "--max-memory",
        "100M",
    ]));
    assert!(
        e.contains("more than the memory limit of 100 MiB (--max-memory)"),
        "{e}"
    );
    let scene = put(
        dir.path(),
        "maps.toml",
        b"[hair]\nprocedural = { kind = \"fur-ball\", strands = 10 }\n[shadows]\nmode = \"deep-opacity\"\n\
          deep_opacity = { resolution = 8192, layers = 256 }\n[[light]]\nkind = \"distant\"\ndirection = [0, -1, 0]\n",
    );
    let e = error_of(&cuticle(&[
        "render",
        scene.to_str().unwrap(),
        "-q",
        "-o",
        out,
    ]));
    assert!(e.contains("deep opacity maps 64.5 GiB"), "{e}");
    let huge = put(
        dir.path(),
        "huge.toml",
        b"[hair]\nprocedural = { kind = \"fur-ball\", strands = 270000000, points = 16 }\n",
    );
    let e = error_of(&cuticle(&[
        "render",
        huge.to_str().unwrap(),
        "-q",
        "-o",
        out,
    ]));
    assert!(e.contains("acceleration structure"), "{e}");
    let e = error_of(&cuticle(&[
        "render",
        "-q",
        "-o",
        out,
        "--threads",
        "100000000",
    ]));
    assert!(e.contains("--threads 100000000 is more than 1024"), "{e}");
    assert!(!Path::new(out).exists());
}

/// An error quotes its input cut to a readable size: a 10⁶-element array and an 8 MiB string in a scene printed
/// 4 MB and 8 MB on stderr; now each message is under 4 KiB and still names the file and the problem.
#[test]
fn errors_quote_huge_values_cut_to_their_head_and_tail() {
    let dir = tempfile::tempdir().unwrap();
    let ones = vec!["1"; 1_000_000].join(",");
    let cases = [
        (
            format!("[film]\nresolution = [{ones}]\n"),
            "invalid length 1000000",
        ),
        (
            format!("[hair]\nfile = \"{}.hair\"\n", "a".repeat(8 << 20)),
            "bytes left out",
        ),
        (
            format!("[hair]\nfoo = \"{}\"\n", "a".repeat(8 << 20)),
            "unknown field `foo`",
        ),
    ];
    for (i, (text, expect)) in cases.iter().enumerate() {
        let scene = put(dir.path(), &format!("huge{i}.toml"), text.as_bytes());
        let out = cuticle(&["render", scene.to_str().unwrap(), "-o", "x.exr"]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "case {i}");
        assert!(stderr.len() < 4096, "case {i}: {} bytes", stderr.len());
        // The hair file's error names the hair file (cut), the others the scene.
        let names = if i == 1 {
            "a.hair".to_owned()
        } else {
            format!("huge{i}")
        };
        assert!(
            stderr.contains(&names) && stderr.contains(expect),
            "case {i}: {stderr}"
        );
    }
}

/// A crop or tile outside the frame is refused before anything is loaded or built: with a hair file that does not
/// exist, the error is the crop's, not the file's (the check came after a 27 s build at 3·10⁵ strands).
#[test]
fn crops_and_tiles_outside_the_frame_are_refused_before_loading() {
    let dir = tempfile::tempdir().unwrap();
    let scene = put(
        dir.path(),
        "s.toml",
        b"[hair]\nfile = \"nothere.hair\"\n[film]\nresolution = [64, 64]\n",
    );
    let s = scene.to_str().unwrap();
    let out = dir.path().join("x.exr");
    let o = out.to_str().unwrap();
    let e = error_of(&cuticle(&["render", s, "--crop", "0,0,100,100", "-o", o]));
    assert!(e.contains("outside the 64x64 frame"), "{e}");
    let e = error_of(&cuticle(&["render", s, "--tile", "70/64", "-o", o]));
    assert!(e.contains("--tile 70/64"), "{e}");
    // And without the bad region, the missing file is what is blamed.
    let e = error_of(&cuticle(&["render", s, "-o", o]));
    assert!(e.contains("nothere.hair"), "{e}");
}

/// An environment map with NaN or infinite texels is refused as damaged, naming the file; one whose negative texels
/// hold a visible share of its magnitude renders with those read as 0 and a warning with the count (the shipped
/// maps' compression negatives, at most 3e-7 of the magnitude, pass silently).
#[test]
fn environment_maps_with_non_finite_texels_are_refused_and_large_negatives_reported() {
    let dir = tempfile::tempdir().unwrap();
    let map = |name: &str, bad: f32| {
        let mut m = cuticle::image::Image::new(8, 4, ["R", "G", "B"].map(String::from).to_vec());
        m.data.fill(0.5);
        m.data[3 * 9 + 1] = bad;
        m.data[3 * 10] = bad;
        let path = dir.path().join(name);
        cuticle::image::write(&path, &m).unwrap();
        path
    };
    let scene = |map: &Path| {
        put(
            dir.path(),
            "env.toml",
            format!(
                "[hair]\nprocedural = {{ kind = \"fur-ball\", strands = 50 }}\n[film]\nresolution = [8, 8]\nspp = 1\n\
                 [environment]\nmap = \"{}\"\n",
                map.display()
            )
            .as_bytes(),
        )
    };
    let out = dir.path().join("x.exr");
    let o = out.to_str().unwrap();
    for bad in [f32::NAN, f32::INFINITY] {
        let s = scene(&map("bad.exr", bad));
        let e = error_of(&cuticle(&["render", s.to_str().unwrap(), "-q", "-o", o]));
        assert!(
            e.contains("bad.exr")
                && e.contains("2 texels are NaN or infinite (the first at column 1, row 1)"),
            "{e}"
        );
        assert!(!out.exists());
    }
    let s = scene(&map("negative.exr", -5.0));
    let run = cuticle(&["render", s.to_str().unwrap(), "-o", o]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    assert!(
        stderr.contains("warning: the environment map had 2 negative texel values, read as 0"),
        "{stderr}"
    );
}

/// `cuticle info` checks what a hair file's header asks for against the memory limit before reading it: a sparse
/// file whose header declares 2³¹ points and matches its apparent size (24 GiB) aborted in the allocator.
#[test]
fn info_refuses_a_model_larger_than_memory_before_reading_it() {
    let dir = tempfile::tempdir().unwrap();
    let points: u32 = 1 << 31;
    let mut h = vec![0u8; yuksel::HEADER_SIZE];
    h[..4].copy_from_slice(b"HAIR");
    h[4..8].copy_from_slice(&1u32.to_le_bytes());
    h[8..12].copy_from_slice(&points.to_le_bytes());
    h[12..16].copy_from_slice(&yuksel::HAS_POINTS.to_le_bytes());
    h[16..20].copy_from_slice(&(points - 1).to_le_bytes());
    h[20..24].copy_from_slice(&0.01f32.to_le_bytes());
    let path = put(dir.path(), "sparse.hair", &h);
    std::fs::OpenOptions::new()
        .write(true)
        .open(&path)
        .unwrap()
        .set_len(yuksel::HEADER_SIZE as u64 + 12 * u64::from(points))
        .unwrap();
    let start = Instant::now();
    let e = error_of(&cuticle(&["info", path.to_str().unwrap()]));
    assert!(
        e.contains("sparse.hair") && e.contains("more than the memory limit"),
        "{e}"
    );
    assert!(
        start.elapsed() < Duration::from_secs(5),
        "{:?}",
        start.elapsed()
    );
}

/// The memory estimate a frame is admitted by bounds what it uses: over a grid of settings (deep opacity maps of a
/// sun and of an environment's directions, layers, film size, strands), the peak RSS `render -v` reports is at most
/// the estimate, and the estimate at most 8× the peak (sparse maps leave most of their pages untouched: the fur
/// ball's 1024², 64-layer sun map estimated 264 MiB, its frame peaked at 187 MiB). An environment's 64 maps were
/// counted as one: 230 MiB estimated for a 459 MiB peak.
#[test]
#[cfg_attr(
    not(target_os = "linux"),
    ignore = "the peak is read from /proc/self/status: Linux only"
)]
fn the_memory_estimate_bounds_the_peak_over_a_grid_of_settings() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        "[hair]\nprocedural = { kind = \"fur-ball\", strands = 20000 }\n[film]\nresolution = [64, 64]\nspp = 1\n\
         [shadows]\nmode = \"deep-opacity\"\ndeep_opacity = { resolution = 1024, layers = 64 }\n",
        "[hair]\nprocedural = { kind = \"fur-ball\", strands = 20000 }\n[film]\nresolution = [64, 64]\nspp = 1\n\
         [environment]\nradiance = [1, 1, 1]\n[shadows]\nmode = \"deep-opacity\"\n\
         deep_opacity = { resolution = 512, layers = 16, environment_directions = 64 }\n",
        "[hair]\nprocedural = { kind = \"fur-ball\", strands = 200000 }\n[film]\nresolution = [512, 512]\nspp = 1\n",
        "[hair]\nprocedural = { kind = \"fur-ball\", strands = 2000 }\n[film]\nresolution = [32, 32]\nspp = 1\n",
    ];
    let mib = |s: &str| -> f64 {
        let (v, unit) = s.trim().split_once(' ').unwrap();
        let v: f64 = v.parse().unwrap();
        match unit.trim_end_matches(|c: char| !c.is_alphabetic()) {
            "KiB" => v / 1024.0,
            "MiB" => v,
            "GiB" => v * 1024.0,
            u => panic!("unit {u}"),
        }
    };
    for (i, text) in cases.iter().enumerate() {
        let scene = put(dir.path(), &format!("g{i}.toml"), text.as_bytes());
        let out = dir.path().join(format!("g{i}.exr"));
        let run = cuticle(&[
            "render",
            scene.to_str().unwrap(),
            "-v",
            "-o",
            out.to_str().unwrap(),
        ]);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(run.status.success(), "{stderr}");
        let line = stderr
            .lines()
            .find(|l| l.starts_with("memory: estimated "))
            .unwrap_or_else(|| panic!("no memory line: {stderr}"));
        let estimated = mib(&line["memory: estimated ".len()..line.find(" (").unwrap()]);
        let peak = mib(&line[line.rfind("peak ").unwrap() + 5..]);
        assert!(
            peak <= estimated && estimated <= 8.0 * peak,
            "case {i}: {line}"
        );
    }
}

// ---- a property: no accepted scene puts NaN or Inf in the film ----

/// A value in [lo, hi]: one of the bounds a third of the time each way (the extremes are where non-finite values
/// hide), else uniform.
fn draw(rng: &mut rand_pcg::Pcg32, lo: f32, hi: f32) -> f32 {
    use rand::Rng;
    match rng.random_range(0..6) {
        0 => lo,
        1 => hi,
        _ => rng.random_range(lo..=hi),
    }
}

fn rgb(rng: &mut rand_pcg::Pcg32, lo: f32) -> String {
    let [r, g, b] = [0; 3].map(|_| draw(rng, lo, 1.0));
    format!("[{r}, {g}, {b}]")
}

/// 48 scenes drawn (seeded) from the accepted ranges of every model's parameters, with lights at their radiance
/// bound and grazing or back light: every output channel of every one is finite (depth.Z aside where the centre
/// ray misses, by definition).
#[test]
fn scenes_drawn_from_the_accepted_ranges_give_finite_outputs_for_every_model() {
    use rand::{Rng, SeedableRng};
    let dir = tempfile::tempdir().unwrap();
    let mut rng = rand_pcg::Pcg32::seed_from_u64(49);
    for i in 0..48 {
        let r = &mut rng;
        let material = match i % 4 {
            0 => {
                let diffuse = draw(r, 0.0, 1.0);
                format!(
                    "model = \"kajiya-kay\"\ncolor = {}\ndiffuse = {diffuse}\nspecular = {}\nexponent = {}\n",
                    rgb(r, 0.0),
                    draw(r, 0.0, 1.0 - diffuse),
                    draw(r, 1.0, 1e4)
                )
            }
            1 => {
                let balance = ["user", "fresnel", "sum"][r.random_range(0..3)];
                format!(
                    "model = \"marschner\"\ncolor = {}\nk_s1 = {}\nk_s2 = {}\nalpha_1 = {}\nalpha_2 = {}\n\
                     beta_1 = {}\nbeta_2 = {}\nbalance = \"{balance}\"\nspecular = {}\neta = {}\n",
                    rgb(r, 0.0),
                    rgb(r, 0.0),
                    rgb(r, 0.0),
                    draw(r, -45.0, 45.0),
                    draw(r, -45.0, 45.0),
                    draw(r, 0.0058, 90.0),
                    draw(r, 0.0058, 90.0),
                    draw(r, 0.0, 1.0),
                    draw(r, 1.001, 10.0)
                )
            }
            2 => format!(
                "model = \"ishair\"\ncolor = {}\ncolor_r = {}\ncolor_tt = {}\ncolor_trt = {}\nglint = {}\n\
                 alpha_r = {}\nalpha_tt = {}\nalpha_trt = {}\nbeta_r = {}\nbeta_tt = {}\nbeta_trt = {}\n\
                 gamma_tt = {}\ngamma_g = {}\nphi_g = {}\n",
                rgb(r, 0.0),
                rgb(r, 0.0),
                rgb(r, 0.0),
                rgb(r, 0.0),
                draw(r, 0.0, 100.0),
                draw(r, -45.0, 45.0),
                draw(r, -45.0, 45.0),
                draw(r, -45.0, 45.0),
                draw(r, 0.0058, 90.0),
                draw(r, 0.0058, 90.0),
                draw(r, 0.0058, 90.0),
                draw(r, 0.0058, 360.0),
                draw(r, 0.0058, 360.0),
                draw(r, 0.0, 90.0)
            ),
            _ => format!(
                "model = \"chiang\"\ncolor = {}\nbeta_m = {}\nbeta_n = {}\nalpha = {}\neta = {}\n",
                rgb(r, 0.001),
                draw(r, 0.001, 1.0),
                draw(r, 0.001, 1.0),
                draw(r, -22.5, 22.5),
                draw(r, 1.001, 10.0)
            ),
        };
        let d = [0; 3].map(|_| r.random_range(-1.0f32..1.0));
        let opacity = draw(r, 0.0, 1.0);
        let text = format!(
            "[hair]\nprocedural = {{ kind = \"fur-ball\", strands = 200 }}\nopacity = {opacity}\n\
             [film]\nresolution = [8, 8]\nspp = 2\n[integrator]\npath_length = 3\n\
             [[light]]\nkind = \"distant\"\ndirection = [{}, {}, {}]\nirradiance = 1e10\n\
             [environment]\nradiance = [1e10, 1e10, 1e10]\n[material]\n{material}",
            d[0],
            d[1] + 1e-3,
            d[2]
        );
        assert_finite(&text, dir.path());
    }
}

// ---- degenerate grooms ----

/// Strands of zero length (every point at one place) are left out and counted: 20 000 of them at one point made
/// every camera ray there test all 20 000 (24 ms per ray, 24 s for a 32² frame at 1 spp). A model of nothing else
/// is refused by name.
#[test]
fn strands_of_zero_length_are_left_out_and_counted() {
    let dir = tempfile::tempdir().unwrap();
    let mut m = model(1, [0.5, 0.4, 0.3]);
    let one = model(1, [0.5, 0.4, 0.3]);
    for _ in 0..20_000 {
        for k in 0..4 {
            m.points.push(Vec3::new(0.5, 0.5, 0.5));
            m.radius.push(0.01);
            m.transparency.push(0.0);
            m.color.push(one.color[k]);
        }
        m.strand_offsets.push(m.points.len() as u32);
    }
    let hair = dir.path().join("tuft.hair");
    yuksel::write(&hair, &m).unwrap();
    let scene = put(
        dir.path(),
        "tuft.toml",
        b"[hair]\nfile = \"tuft.hair\"\n[film]\nresolution = [32, 32]\nspp = 1\n",
    );
    let out = dir.path().join("tuft.exr");
    let o = cuticle(&[
        "render",
        scene.to_str().unwrap(),
        "-q",
        "-o",
        out.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert!(stderr.contains("1 strands (round curves"), "{stderr}");
    assert!(
        stderr.contains(
            "warning: 20000 strands of zero length (every point at one place) were left out"
        ),
        "{stderr}"
    );

    let mut only = m.clone();
    only.points.drain(..4);
    only.radius.drain(..4);
    only.transparency.drain(..4);
    only.color.drain(..4);
    only.strand_offsets = (0..=20_000u32).map(|s| 4 * s).collect();
    yuksel::write(&hair, &only).unwrap();
    let e = error_of(&cuticle(&[
        "render",
        scene.to_str().unwrap(),
        "-q",
        "-o",
        out.to_str().unwrap(),
    ]));
    assert!(
        e.contains("tuft.hair: all 20000 strands have zero length"),
        "{e}"
    );
}
