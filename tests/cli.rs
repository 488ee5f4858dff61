//! The command line as a user drives it: renders to EXR + PNG (read back by `oiiotool`), `info`, and the errors a
//! user sees for bad input (one readable message, exit code 2, no output file left behind).

use std::path::Path;
use std::process::{Command, Output};

mod common;

use common::data;

const EXE: &str = env!("CARGO_BIN_EXE_cuticle");

fn cuticle(args: &[&str]) -> Output {
    Command::new(EXE).args(args).output().expect("run cuticle")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Renders `scene` (None = default) small and fast, checks the EXR channels with oiiotool and the PNG exists.
fn render_and_check(scene: Option<&Path>, extra: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let exr = dir.path().join("frame.exr");
    let mut args = vec![
        "render",
        "-q",
        "-o",
        exr.to_str().unwrap(),
        "--res",
        "96x72",
        "--spp",
        "2",
    ];
    let scene_str;
    if let Some(s) = scene {
        scene_str = s.to_str().unwrap().to_owned();
        args.insert(1, &scene_str);
    }
    args.extend_from_slice(extra);
    let out = cuticle(&args);
    assert!(
        out.status.success(),
        "cuticle {args:?} failed: {}",
        stderr(&out)
    );
    assert!(
        exr.exists() && dir.path().join("frame.png").exists(),
        "{:?}",
        std::fs::read_dir(dir.path())
    );
    let info = Command::new("oiiotool")
        .args(["--info", "-v", exr.to_str().unwrap()])
        .output()
        .expect("oiiotool not found: install the Debian package openimageio-tools");
    assert!(
        info.status.success(),
        "{}",
        String::from_utf8_lossy(&info.stderr)
    );
    let text = String::from_utf8_lossy(&info.stdout);
    let words = text.split_whitespace().collect::<Vec<_>>().join(" ");
    assert!(
        words.contains(&format!(
            "96 x 72, {} channel, float openexr",
            cuticle::render::CHANNELS.len()
        )),
        "{text}"
    );
    for channel in cuticle::render::CHANNELS {
        assert!(
            text.contains(channel),
            "channel {channel} missing from:\n{text}"
        );
    }
    // Nothing but the two outputs: no temporary files left behind.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
}

#[test]
fn renders_the_default_scene() {
    render_and_check(None, &[]);
}

#[test]
fn renders_the_default_scene_with_flat_curves() {
    render_and_check(None, &["--curves", "flat"]);
}

#[test]
fn the_scalar_integrator_is_one_option_away_and_gives_the_same_image() {
    let dir = tempfile::tempdir().unwrap();
    let render = |name: &str, extra: &[&str]| {
        let exr = dir.path().join(name);
        let mut args = vec!["render", "-q", "-o", exr.to_str().unwrap()];
        args.extend_from_slice(&["--res", "48x36", "--spp", "8", "--path-length", "2"]);
        args.extend_from_slice(extra);
        let out = cuticle(&args);
        assert!(out.status.success(), "{}", stderr(&out));
        exr
    };
    // Every channel of every pixel the same (idiff, zero tolerance; the headers differ in their date and job).
    let same = |a: &Path, b: &Path| {
        let out = Command::new("idiff")
            .args(["-q", "-a"])
            .args([a, b])
            .output()
            .expect("idiff not found: install the Debian package openimageio-tools");
        out.status.success()
    };
    let default = render("default.exr", &[]);
    assert!(same(
        &default,
        &render("lanes.exr", &["--shading", "lanes"])
    ));
    assert!(same(
        &default,
        &render("scalar.exr", &["--shading", "scalar"])
    ));
    assert!(
        !same(&default, &render("other.exr", &["--seed", "2"])),
        "idiff tells images apart"
    );
    let out = cuticle(&["render", "--shading", "wide", "-o", "x.exr"]);
    assert!(
        !out.status.success() && stderr(&out).contains("wide"),
        "{}",
        stderr(&out)
    );
}

#[test]
fn renders_straight_hair() {
    let dir = tempfile::tempdir().unwrap();
    render_and_check(
        Some(&data::scene_copy("scenes/straight.toml", dir.path())),
        &[],
    );
}

#[test]
fn renders_the_fur_ball() {
    let dir = tempfile::tempdir().unwrap();
    render_and_check(
        Some(&data::scene_copy("scenes/furball.toml", dir.path())),
        &[],
    );
}

#[test]
fn info_describes_a_real_file() {
    let out = cuticle(&["info", data::file("hair/furball.hair").to_str().unwrap()]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("strands:      30367"), "{text}");
    assert!(text.contains("points:       485872"), "{text}");
}

#[test]
fn unwritable_output_is_a_clear_error_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let blocker = dir.path().join("not-a-directory");
    std::fs::write(&blocker, b"x").unwrap();
    let target = blocker.join("frame.exr");
    let out = cuticle(&[
        "render",
        "-q",
        "-o",
        target.to_str().unwrap(),
        "--res",
        "16x16",
        "--spp",
        "1",
    ]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(
        err.contains("frame.exr"),
        "the message names the file: {err}"
    );
    assert_eq!(err.trim().lines().count(), 1, "one readable message: {err}");
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "only the blocker file remains"
    );
}

#[test]
fn scene_errors_name_the_key_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("bad.toml");
    std::fs::write(
        &scene,
        "[hair]\nprocedural = { kind = \"fur-ball\" }\n\n[camera]\nfov2 = 3.0\n",
    )
    .unwrap();
    let out = cuticle(&[
        "render",
        scene.to_str().unwrap(),
        "-o",
        dir.path().join("x.exr").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let err = stderr(&out);
    assert!(
        err.contains("bad.toml") && err.contains("fov2") && err.contains("line 5"),
        "{err}"
    );

    std::fs::write(
        &scene,
        "[hair]\nprocedural = { kind = \"fur-ball\" }\n[camera]\nfov = \"wide\"\n",
    )
    .unwrap();
    let out = cuticle(&["render", scene.to_str().unwrap()]);
    let err = stderr(&out);
    assert!(err.contains("fov") && err.contains("line 4"), "{err}");

    std::fs::write(
        &scene,
        "[hair]\nprocedural = { kind = \"fur-ball\" }\n[camera]\nfov = 0.0\n",
    )
    .unwrap();
    let err = stderr(&cuticle(&["render", scene.to_str().unwrap()]));
    assert!(err.contains("camera.fov"), "{err}");
}

#[test]
fn bad_hair_file_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let hair = dir.path().join("broken.hair");
    let real = std::fs::read(data::file("hair/straight.hair")).unwrap();
    std::fs::write(&hair, &real[..1000]).unwrap();
    let scene = dir.path().join("s.toml");
    std::fs::write(&scene, "[hair]\nfile = \"broken.hair\"\n").unwrap();
    let exr = dir.path().join("out.exr");
    let out = cuticle(&[
        "render",
        scene.to_str().unwrap(),
        "-o",
        exr.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let err = stderr(&out);
    assert!(err.contains("broken.hair"), "{err}");
    assert!(!exr.exists());
    let out = cuticle(&["info", dir.path().join("missing.hair").to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("missing.hair"));
}

/// `--aovs` keeps the beauty bit for bit and only the layers asked for; without `depth`, `tangent` and `strand`
/// no pixel-centre ray is traced (one camera ray per pixel fewer, read from the render's summary line).
#[test]
fn aovs_choose_the_exr_layers_and_leave_the_beauty_alone() {
    let dir = tempfile::tempdir().unwrap();
    let render = |name: &str, aovs: Option<&str>| {
        let exr = dir.path().join(format!("{name}.exr"));
        let mut args = vec!["render", "-q", "-o", exr.to_str().unwrap()];
        args.extend(["--res", "40x30", "--spp", "2"]);
        if let Some(a) = aovs {
            args.extend(["--aovs", a]);
        }
        let out = cuticle(&args);
        assert!(out.status.success(), "{}", stderr(&out));
        let camera: u64 = stderr(&out)
            .split(" camera")
            .next()
            .and_then(|s| s.rsplit(' ').next())
            .and_then(|n| n.parse().ok())
            .expect("camera ray count in the summary");
        (cuticle::image::read(&exr).unwrap(), camera)
    };
    let (all, all_rays) = render("all", None);
    let (none, none_rays) = render("none", Some("none"));
    let (some, some_rays) = render("some", Some("depth,albedo"));
    assert_eq!(all.channels.len(), cuticle::render::CHANNELS.len());
    assert_eq!(none.channels, ["R", "G", "B", "A"]);
    assert_eq!(
        some.channels,
        ["R", "G", "B", "A", "albedo.R", "albedo.G", "albedo.B", "depth.Z"]
    );
    let pick = |img: &cuticle::image::Image, name: &str| -> Vec<u32> {
        let c = img.channel_index(name).unwrap();
        (0..img.height)
            .flat_map(|y| (0..img.width).map(move |x| (x, y)))
            .map(|(x, y)| img.get(x, y, c).to_bits())
            .collect()
    };
    for name in ["R", "G", "B", "A"] {
        assert_eq!(pick(&all, name), pick(&none, name), "{name}");
    }
    assert_eq!(pick(&all, "depth.Z"), pick(&some, "depth.Z"));
    assert_eq!(pick(&all, "albedo.G"), pick(&some, "albedo.G"));
    let pixels = 40 * 30;
    assert_eq!(all_rays, 2 * pixels + pixels);
    assert_eq!(some_rays, all_rays);
    assert_eq!(none_rays, 2 * pixels);

    let bad = cuticle(
        &[
            "render",
            "-q",
            "-o",
            dir.path().join("x.exr").to_str().unwrap(),
        ]
        .into_iter()
        .chain(["--res", "8x8", "--aovs", "depth,normals"])
        .collect::<Vec<_>>(),
    );
    assert_eq!(bad.status.code(), Some(2));
    let message = stderr(&bad);
    assert!(
        message.contains("film.aovs") && message.contains("\"normals\""),
        "{message}"
    );
    assert!(!dir.path().join("x.exr").exists());
}

/// OpenImageIO is loaded on first use (src/sys/oiio.rs), not linked: its ~260 dependencies cost every process about
/// half a second before `main`. The binary's own dynamic section must therefore not name it (the embedded shim
/// does, inside its bytes, which `readelf -d` does not read).
#[test]
fn the_binary_does_not_link_openimageio_at_start_up() {
    let out = Command::new("readelf")
        .args(["-d", EXE])
        .output()
        .expect("readelf (binutils) runs");
    assert!(out.status.success(), "readelf -d failed: {}", stderr(&out));
    let dynamic = String::from_utf8_lossy(&out.stdout);
    let needed: Vec<&str> = dynamic.lines().filter(|l| l.contains("(NEEDED)")).collect();
    assert!(
        needed.iter().any(|l| l.contains("libembree")),
        "readelf output has no Embree NEEDED entry, so it was not read: {needed:?}"
    );
    assert!(
        !needed.iter().any(|l| l.contains("OpenImageIO")),
        "the binary links OpenImageIO at start-up: {needed:?}"
    );
}

/// `--quality auto` prints one short line per decision, and warns when the settings the user fixed cannot meet
/// the target; `--verbose` adds the reasons.
#[test]
fn auto_prints_short_decisions_and_warns_when_fixed_settings_miss_the_target() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("a.exr");
    let base = ["render", "-q", "--res", "32x24", "--quality", "auto"];
    let run = |extra: &[&str]| {
        let mut args = base.to_vec();
        args.extend_from_slice(&["-o", out.to_str().unwrap()]);
        args.extend_from_slice(extra);
        let o = cuticle(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        stderr(&o)
    };
    let fixed = run(&["--spp", "4", "--target", "0.01"]);
    let auto_lines: Vec<&str> = fixed.lines().filter(|l| l.starts_with("auto:")).collect();
    assert!(auto_lines.len() >= 3, "{fixed}");
    for l in &auto_lines {
        assert!(l.chars().count() <= 120, "line over 120 characters: {l}");
    }
    assert!(
        fixed.contains("warning: --spp 4 cannot meet --target 0.01"),
        "{fixed}"
    );
    // The last auto line: the error the frame estimates it delivered.
    assert!(
        auto_lines
            .last()
            .unwrap()
            .starts_with("auto: estimated error "),
        "{fixed}"
    );
    let free = run(&["--target", "0.2"]);
    assert!(!free.contains("warning"), "{free}");
    let last = free.lines().rfind(|l| l.starts_with("auto:")).unwrap();
    assert!(
        last.starts_with("auto: estimated error ") && last.contains("from the frame"),
        "{free}"
    );
    assert!(
        last.chars().count() <= 120,
        "line over 120 characters: {last}"
    );
    let verbose = run(&["--target", "0.2", "--verbose"]);
    assert!(verbose.lines().count() > free.lines().count(), "{verbose}");
}

/// `--target` without `--quality auto` does nothing, and says so.
#[test]
fn target_without_auto_warns() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("a.png");
    let o = cuticle(&[
        "render",
        "-q",
        "--res",
        "16x12",
        "--spp",
        "1",
        "--target",
        "0.05",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("warning: --target is read only by --quality auto"),
        "{}",
        stderr(&o)
    );
}

/// The frame benchmark takes the film's size and samples from the command line.
#[test]
fn bench_frame_takes_res_and_spp() {
    let o = cuticle(&[
        "bench",
        "frame",
        "--res",
        "16x16",
        "--spp",
        "1",
        "--repetitions",
        "1",
        "--threads",
        "1",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let report = String::from_utf8_lossy(&o.stdout);
    assert!(
        report.contains("16x16") && report.contains("1 spp"),
        "{report}"
    );
}
