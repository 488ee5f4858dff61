//! `cuticle study` end to end on a tiny procedural scene (32×32 or 32×24, a few spp, maps of 16–32 texels): the
//! files each kind writes, the reference cache, the measures' sanity, `shadows` and `backends` with their own
//! flags, and the errors a user sees for bad input; and on the built-in default scene at `--quick`'s 32×24: no
//! scene argument, references in `OUT/cache/`, the files listed at the end, the stress cases as bar charts.

mod common;

use std::path::Path;
use std::process::Command;

use cuticle::study::framework::{run_kind, Budget, StudyConfig, DIFFERENCE_HEADER, POINT_HEADER};
use cuticle::study::kinds::{backends_with, shadows_with, BackendsSweep, ShadowsSweep};
use cuticle::study::{SceneFile, StudyError};

/// A small fur ball under one distant light, direct light only (no environment: one map per variant).
const TINY: &str = r#"
[hair]
procedural = { kind = "fur-ball", strands = 1500 }
opacity = 0.5

[camera]
margin = 0.9

[film]
resolution = [32, 32]
# Each pixel its own samples, as the measures' sanity checks below assume: a splat spreads the hair's alpha (and
# so the shadowed mask) over every pixel within 1.5 px of a strand.
reconstruction = "importance"

[material]
model = "kajiya-kay"

[[light]]
kind = "distant"
direction = [1.0, -1.0, 1.0]
irradiance = 3.0

[integrator]
path_length = 0
"#;

/// Runs `cuticle ARGS` (no `-q`, no `-o`): its exit status, stdout and stderr.
fn run(args: &[&str]) -> (Option<i32>, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_cuticle"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The paths of the `wrote PATH` lines of `stdout`, in order, and its last line.
fn written(stdout: &str) -> (Vec<std::path::PathBuf>, &str) {
    let files = stdout
        .lines()
        .filter_map(|l| l.strip_prefix("wrote "))
        .map(std::path::PathBuf::from)
        .collect();
    (files, stdout.lines().last().unwrap_or_default())
}

/// The scene file at `path`, read now.
fn file(path: &Path) -> SceneFile {
    SceneFile::read(path).unwrap()
}

/// Runs `cuticle ARGS -q -o DIR/out`: its exit status and stderr.
fn cli(args: &[&str], dir: &Path) -> (Option<i32>, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_cuticle"))
        .args(args)
        .args(["-q", "-o"])
        .arg(dir.join("out"))
        .output()
        .unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The sweep of the old `study shadows` test: 2 ray-traced spp, maps of 2 and 4 layers at 32², of 16² and 32² at
/// 4 layers (4 layers at 32² is in both map series), 2 spp for the maps.
fn tiny_shadows() -> ShadowsSweep {
    ShadowsSweep {
        rt_spp: vec![1, 4],
        layers: vec![2, 4],
        layer_resolution: 32,
        resolutions: vec![16, 32],
        resolution_layers: 4,
        dom_spp: 2,
        backend: None,
    }
}

/// The whole film, references at `spp`.
fn whole(spp: u32) -> Budget {
    Budget {
        crop: None,
        reference_spp: Some(spp),
    }
}

fn tiny_config(out: &Path) -> StudyConfig {
    StudyConfig {
        seeds: 2,
        crop: 16,
        ..StudyConfig::new(out, false)
    }
}

/// `shadows` on the framework: every series the old module measured (no shadows, ray traced with stochastic and
/// exact transmittance, maps over layers and resolution with their build time and memory, the error over the
/// shadowed pixels), the reference cache and what its key leaves out.
#[test]
fn study_writes_its_files_and_reuses_the_cached_reference() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("tiny.toml");
    std::fs::write(&scene, TINY).unwrap();
    let out = dir.path().join("out");
    let config = tiny_config(&out);
    let kind = shadows_with(&tiny_shadows(), whole(8)).unwrap();

    let first = run_kind(&file(&scene), &kind, &config).unwrap();
    let reference = &first.references[0];
    assert!(!reference.cached && reference.path.is_file());
    // none, RT stochastic ×2, RT exact ×2, DOM 2L32, 4L32, 4L16, 4L32 again (rendered once, see below).
    let methods: Vec<&str> = kind.variants.iter().map(|v| v.method.as_str()).collect();
    assert_eq!(
        methods,
        [
            "none",
            "raytraced",
            "raytraced",
            "raytraced",
            "raytraced",
            "deep-opacity",
            "deep-opacity",
            "deep-opacity",
            "deep-opacity"
        ]
    );
    let csv = std::fs::read_to_string(out.join("shadows.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines[0], POINT_HEADER);
    assert_eq!(lines.len(), 1 + 9 * 2, "{csv}");
    assert!(
        lines[1].starts_with("shadows,no shadows,none,spp=2,"),
        "{}",
        lines[1]
    );
    for line in &lines[1..] {
        assert_eq!(
            line.split(',').count(),
            POINT_HEADER.split(',').count(),
            "{line}"
        );
    }
    for f in [
        "shadows-error-time.png",
        "shadows-error-time.svg",
        "shadows-crops.png",
    ] {
        assert!(out.join(f).is_file(), "{f}");
    }

    // Sanity of the measures: the reference against itself is exact, no shadows is not, and worst where the
    // reference is shadowed; only maps hold memory and take build time.
    assert_eq!(reference.self_rmse, 0.0);
    let none = &first.summaries[0];
    assert!(
        none.rmse.mean > 0.0 && none.rmse_shadowed.mean > none.rmse.mean,
        "{none:?}"
    );
    for p in &first.points {
        let maps = kind.variants[p.variant].method == "deep-opacity";
        assert!(p.rmse.is_finite() && p.relmse.is_finite() && p.rmse_shadowed.is_finite());
        assert_eq!(p.map_bytes > 0, maps, "{p:?}");
        assert_eq!(p.maps_s > 0.0, maps, "{p:?}");
        assert!(p.maps_s <= p.render_s, "{p:?}");
    }
    // 4 layers at 32² is one render, in both map series.
    let at = |i: usize| first.points.iter().find(|p| p.variant == i).unwrap();
    assert_eq!((at(6).rmse, at(6).render_s), (at(8).rmse, at(8).render_s));

    // Second run: the reference comes from the cache, and (deterministic renders) every error is the same.
    let second = run_kind(&file(&scene), &kind, &config).unwrap();
    assert!(second.references[0].cached);
    assert_eq!(second.references[0].path, reference.path);
    for (a, b) in first.points.iter().zip(&second.points) {
        assert_eq!(
            (a.rmse, a.rmse_shadowed),
            (b.rmse, b.rmse_shadowed),
            "{a:?}"
        );
    }

    // Map settings and comments in the scene do not touch the ray-traced reference: still cached. A different
    // reference spp is a different cache entry.
    let rt_only = shadows_with(
        &ShadowsSweep {
            layers: vec![],
            resolutions: vec![],
            rt_spp: vec![1],
            ..tiny_shadows()
        },
        whole(8),
    )
    .unwrap();
    std::fs::write(
        &scene,
        format!("# a comment\n{TINY}\n[shadows.deep_opacity]\nbias = 2.0\n"),
    )
    .unwrap();
    let third = run_kind(&file(&scene), &rt_only, &config).unwrap();
    assert!(third.references[0].cached);
    assert_eq!(third.references[0].path, reference.path);
    let fewer = shadows_with(&tiny_shadows(), whole(4)).unwrap();
    let fourth = run_kind(&file(&scene), &fewer, &config).unwrap();
    assert!(!fourth.references[0].cached);
    assert_ne!(fourth.references[0].path, reference.path);
}

#[test]
fn missing_scene_is_an_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("no-such-scene.toml");
    let err = SceneFile::read(&missing).unwrap_err();
    assert!(matches!(err, StudyError::SceneFile { .. }), "{err:?}");
    assert!(err.to_string().contains("no-such-scene.toml"), "{err}");

    let scene = dir.path().join("tiny.toml");
    std::fs::write(&scene, TINY).unwrap();
    for (args, needle) in [
        (
            vec!["shadows", missing.to_str().unwrap()],
            "no-such-scene.toml",
        ),
        (
            vec!["shadows", scene.to_str().unwrap(), "--rt-spp", "1,0"],
            "samples per pixel must be at least 1, got 0",
        ),
        (
            vec!["backends", scene.to_str().unwrap(), "--seeds", "0"],
            "--seeds must be at least 1",
        ),
    ] {
        let (code, stderr) = cli(&[&["study"], &args[..]].concat(), dir.path());
        assert_eq!(code, Some(2), "{args:?}");
        assert!(
            stderr.contains(needle)
                && stderr.contains("cuticle: error")
                && stderr.lines().count() == 1,
            "{args:?}: {stderr}"
        );
    }
    assert!(!dir.path().join("out").join("shadows.csv").exists());
}

/// `backends` on the framework: both backends over spp per curve type with the same seeds, their images compared
/// directly (`backends-differences.csv`, one difference image per curve type).
#[test]
fn backend_study_renders_both_backends_alike() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("tiny.toml");
    std::fs::write(&scene, TINY).unwrap();
    let out = dir.path().join("out");
    let sweep = BackendsSweep {
        spp: vec![1, 2],
        curves: vec!["round".into(), "flat".into()],
    };
    let kind = backends_with(&sweep, whole(8)).unwrap();
    let report = run_kind(&file(&scene), &kind, &tiny_config(&out)).unwrap();
    // 2 curve types × 2 backends × 2 spp × 2 seeds.
    assert_eq!(report.points.len(), 16);
    let csv = std::fs::read_to_string(out.join("backends-differences.csv")).unwrap();
    assert_eq!(csv.lines().next(), Some(DIFFERENCE_HEADER));
    assert_eq!(csv.lines().count(), 1 + 8, "{csv}");
    for c in ["round", "flat"] {
        let f = out.join(format!("backends-diff-bvh-{c}-vs-embree-{c}.png"));
        assert!(f.is_file(), "{}", f.display());
    }
    assert_eq!(report.differences.len(), 8);
    for d in &report.differences {
        assert_eq!(d.a.replace("bvh", "embree"), d.b);
        // Same samples on both backends: the images differ far less than either differs from the reference.
        assert!(d.rmse_a > 0.0 && d.rmse_a.is_finite(), "{d:?}");
        assert!(
            d.rmse < 0.25 * d.rmse_a.min(d.rmse_b),
            "backends differ by {} at rmse {} / {}",
            d.rmse,
            d.rmse_a,
            d.rmse_b
        );
    }
    assert!(report
        .readouts
        .iter()
        .any(|l| l.starts_with("bvh flat against embree flat, same seeds")));
    assert!(backends_with(
        &BackendsSweep {
            spp: vec![],
            ..sweep
        },
        whole(8)
    )
    .is_err());
}

/// `study all --quick` through the framework on the tiny scene (32×24): every kind writes its CSVs, charts (PNG
/// and SVG) and read-outs, every measure is finite, each reference against itself has zero error, and error falls
/// with samples where it must (chiang against its own reference, 1 → 4 spp).
#[test]
fn study_all_quick_writes_every_chart_and_sane_values() {
    use cuticle::study::framework::SUMMARY_HEADER;
    use cuticle::study::{kinds, report};
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("tiny.toml");
    std::fs::write(&scene, TINY).unwrap();
    let config = StudyConfig {
        reference_spp: 16,
        ..StudyConfig::new(dir.path().join("out"), true)
    };
    let all = report::run_all(&file(&scene), &config).unwrap();
    assert_eq!(all.kinds.len(), kinds::ALL.len());
    let md = std::fs::read_to_string(&all.markdown).unwrap();
    assert!(md.contains("## Headline read-outs"), "{md}");
    assert!(
        md.contains("## stress:") && md.contains("(stress.md)"),
        "{md}"
    );
    assert!(all.stress.markdown.is_file());
    // Every file is listed once, in the order written, report.md last; the references are in out/cache only.
    let expected: Vec<&std::path::PathBuf> = all
        .kinds
        .iter()
        .chain([&all.stress.report])
        .flat_map(|k| &k.files)
        .chain([&all.markdown])
        .collect();
    assert_eq!(all.files.iter().collect::<Vec<_>>(), expected);
    assert!(all.files.iter().all(|f| f.is_file()));
    let unique: std::collections::BTreeSet<_> = all.files.iter().collect();
    assert_eq!(unique.len(), all.files.len());
    assert!(common::listing(&dir.path().join("out"))
        .iter()
        .all(|n| !n.starts_with("reference-")));
    assert!(common::listing(&dir.path().join("out/cache"))
        .iter()
        .any(|n| n.starts_with("reference-")));
    for k in &all.kinds {
        let name = &k.kind.name;
        for suffix in [
            ".csv",
            "-summary.csv",
            "-error-time.png",
            "-error-time.svg",
            "-time.png",
            "-time.svg",
            "-readouts.txt",
        ] {
            let f = dir.path().join("out").join(format!("{name}{suffix}"));
            assert!(
                f.is_file() && std::fs::metadata(&f).unwrap().len() > 0,
                "{}",
                f.display()
            );
            if suffix.ends_with(".png") {
                assert!(
                    md.contains(&format!("({name}{suffix})")),
                    "{name}{suffix} not in the report"
                );
            }
        }
        let csv =
            std::fs::read_to_string(dir.path().join("out").join(format!("{name}.csv"))).unwrap();
        assert_eq!(csv.lines().next(), Some(POINT_HEADER));
        assert_eq!(csv.lines().count(), 1 + k.kind.variants.len() * 3, "{name}");
        let summary =
            std::fs::read_to_string(dir.path().join("out").join(format!("{name}-summary.csv")))
                .unwrap();
        assert_eq!(summary.lines().next(), Some(SUMMARY_HEADER));
        // One line per compared pair, and one per series where the kind reads out biases.
        let bias_lines = if k.kind.bias_readout {
            k.summaries
                .iter()
                .map(|s| &k.kind.variants[s.variant].series)
                .collect::<std::collections::BTreeSet<_>>()
                .len()
        } else {
            0
        };
        assert_eq!(
            k.readouts.len(),
            k.kind.compare.len() + bias_lines + k.kind.differences.len(),
            "{name}: {:?}",
            k.readouts
        );
        for r in &k.references {
            assert_eq!((r.self_rmse, r.self_fireflies), (0.0, 0), "{name}");
            assert!(r.seconds.is_some_and(|s| s > 0.0), "{name}");
            // Rendered in two halves: their difference gives the reference's noise, positive and finite.
            assert!(
                r.second_rmse.is_some_and(|e| e > 0.0 && e.is_finite()),
                "{name}: {r:?}"
            );
        }
        assert_eq!(k.reference_checks.len(), k.kind.references.len(), "{name}");
        assert_eq!(
            k.reference_spp, 16,
            "{name}: --quick keeps the study's reference spp"
        );
        for p in &k.points {
            assert!(
                p.rmse > 0.0 && p.rmse.is_finite() && p.relmse.is_finite(),
                "{name}: {p:?}"
            );
            assert!(p.ssim > 0.0 && p.ssim < 1.0, "{name}: {p:?}");
            assert_eq!(p.non_finite, 0, "{name}: {p:?}");
            assert!(
                p.render_s > 0.0 && p.setup_s > 0.0 && p.camera_rays > 0,
                "{name}: {p:?}"
            );
        }
    }
    let models = all.kinds.iter().find(|k| k.kind.name == "models").unwrap();
    let chiang = |spp: f64| {
        models
            .summaries
            .iter()
            .find(|s| {
                models.kind.variants[s.variant].series == "chiang as marschner"
                    && models.kind.variants[s.variant].x == spp
            })
            .unwrap()
            .rmse
            .mean
    };
    assert!(
        chiang(4.0) < 0.8 * chiang(1.0),
        "chiang rmse 1 spp {} 4 spp {}",
        chiang(1.0),
        chiang(4.0)
    );
    // The cached references are reused by a second run of one kind, with their recorded noise.
    let again =
        cuticle::study::framework::run_kind(&file(&scene), &kinds::lobes(true), &config).unwrap();
    assert!(again
        .references
        .iter()
        .all(|r| r.cached && r.seconds.is_some() && r.second_rmse.is_some()));
    // The sampling study has a chiang row, importance against uniform.
    let sampling = all
        .kinds
        .iter()
        .find(|k| k.kind.name == "sampling")
        .unwrap();
    assert!(sampling.readouts.iter().any(|l| l
        .starts_with("chiang importance reaches chiang uniform")
        || l.starts_with("chiang importance does not reach")));
}

/// The full runs' budgets: `samples` reaches 2048 samples per shading point on a small window with 16-spp
/// references of 2048 × 2048 samples; the spp sweeps crop and size their references by their largest spp;
/// `curves` sweeps the radius at a fixed film; `models` matches chiang's fibre albedo to each thesis model.
#[test]
fn full_kinds_have_budgets_and_the_sweeps_asked_for() {
    use cuticle::study::kinds;
    let samples = kinds::samples(false);
    assert_eq!(samples.budget.crop, Some(kinds::SAMPLES_CROP));
    assert_eq!(
        samples.budget.reference_spp,
        Some(kinds::SAMPLES_REFERENCE_SPP)
    );
    let xs: Vec<f64> = samples.variants.iter().map(|v| v.x).collect();
    assert!(xs.contains(&2048.0) && xs.contains(&16.0), "{xs:?}");
    for name in ["sampling", "lobes", "hery", "backends", "shadows"] {
        let k = kinds::by_name(name, false).unwrap().unwrap();
        assert_eq!(k.budget.crop, Some(kinds::SWEEP_CROP), "{name}");
        assert_eq!(
            k.budget.reference_spp,
            Some(8 * kinds::REFERENCE_FACTOR),
            "{name}"
        );
    }
    let curves = kinds::curves(false);
    assert!(curves.variants.iter().all(|v| v
        .overrides
        .iter()
        .any(|(k, _)| k == "hair.radius_scale")
        && !v.overrides.iter().any(|(k, _)| k == "film.resolution")));
    // Matched colour: chiang's σa reproduces marschner's fibre albedo, so its σa differs from chiang's default.
    let (sigma_a, albedo) = kinds::matched_chiang("marschner").unwrap();
    assert!(
        albedo.iter().all(|a| *a > 0.0 && *a < 1.0),
        "marschner's fibre albedo {albedo:?}"
    );
    assert!(
        sigma_a.iter().all(|s| s.is_finite() && *s > 0.0),
        "{sigma_a:?}"
    );
    assert!(kinds::matched_chiang("no-such-model").is_err());
}

/// A crop is the same pixels of the same view: the depth through each pixel centre (filter width 0.001 px) of
/// the centred 16² window of a 32² film equals the whole film's there, for a placed and an auto-framed camera.
#[test]
fn a_crop_shows_the_same_pixels_as_the_whole_film() {
    use cuticle::render::{Frame, Request};
    use cuticle::scene::Scene;
    use cuticle::study::framework::crop_overrides;
    for camera in [
        "margin = 0.9",
        "position = [0.3, 0.2, 3.0]\nlook_at = [0.0, 0.1, 0.0]\nfov = 30.0",
    ] {
        let text = TINY.replace("margin = 0.9", camera).replace(
            "resolution = [32, 32]",
            "resolution = [32, 24]\nfilter_width = 0.001",
        );
        let depth_of = |text: &str| {
            let scene = Scene::parse(text, Path::new("tiny.toml"), Path::new(".")).unwrap();
            let frame = Frame::load(scene.resolve().unwrap()).unwrap();
            let image = frame.render(Request::new(&scene.render_settings())).image;
            let z = image.channel_index("depth.Z").expect("a depth.Z AOV");
            let n = image.channels.len();
            let depth: Vec<f32> = image.data.chunks_exact(n).map(|p| p[z]).collect();
            (image.width, depth)
        };
        let (w, full) = depth_of(&text);
        let scene = Scene::parse(&text, Path::new("tiny.toml"), Path::new(".")).unwrap();
        let mut table: toml::Table = toml::from_str(&text).unwrap();
        for (k, v) in crop_overrides(&scene.camera, [32, 24], [16, 16]) {
            let (t, key) = k.split_once('.').unwrap();
            table
                .entry(t)
                .or_insert_with(|| toml::Value::Table(Default::default()))
                .as_table_mut()
                .unwrap()
                .insert(key.into(), v);
        }
        let (cw, crop) = depth_of(&toml::to_string(&table).unwrap());
        assert_eq!(cw, 16);
        let mut hits = 0;
        for y in 0..16 {
            for x in 0..16 {
                let (a, b) = (crop[y * 16 + x], full[(y + 4) * w + x + 8]);
                let same = (a - b).abs() <= 1e-3 * a.abs().max(b.abs())
                    || (a.is_infinite() && b.is_infinite());
                assert!(same, "{camera}: crop ({x}, {y}) depth {a}, whole film {b}");
                hits += usize::from(a.is_finite() && a > 0.0);
            }
        }
        assert!(
            hits > 20,
            "{camera}: only {hits} pixels of the crop hit hair"
        );
    }
}

/// The framework's kinds through the CLI: a bad study setting and a bad scene key are one line naming what is wrong,
/// exit status 2, before anything is rendered.
#[test]
fn framework_kinds_report_bad_input_once() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("tiny.toml");
    std::fs::write(&scene, TINY).unwrap();
    let bad = dir.path().join("bad.toml");
    std::fs::write(
        &bad,
        TINY.replace(
            "model = \"kajiya-kay\"",
            "model = \"kajiya-kay\"\nexponent = -1",
        ),
    )
    .unwrap();
    for (args, needle) in [
        (
            vec![
                "study",
                "lobes",
                scene.to_str().unwrap(),
                "--quick",
                "--seeds",
                "0",
            ],
            "--seeds must be at least 1",
        ),
        (
            vec!["study", "all", bad.to_str().unwrap(), "--quick"],
            "bad.toml",
        ),
    ] {
        let (code, stderr) = cli(&args, dir.path());
        assert_eq!(code, Some(2), "{args:?}");
        assert!(
            stderr.contains(needle) && stderr.lines().count() == 1,
            "{args:?}: {stderr}"
        );
    }
    assert!(!dir.path().join("out").join("lobes.csv").exists());
}

/// `study stress --quick` on the tiny fur ball (32×24, 3 seeds, references at 64 spp): every case the fur ball can
/// express is rendered with every method, no pixel of any render is NaN/Inf, and the exact samplers (marschner,
/// ishair, chiang) stay under 24 fireflies per render (3 % of the 768 pixels). Measured when written: at most 12
/// (chiang, grazing), 9 (marschner, narrow lobes), 6 (ishair, thin strands); 24 is twice the worst.
#[test]
fn stress_quick_has_no_nan_and_few_fireflies_on_the_tiny_scene() {
    use cuticle::study::stress;
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("tiny.toml");
    std::fs::write(&scene, TINY).unwrap();
    let config = StudyConfig::new(dir.path().join("out"), true);
    let s = stress::run(&file(&scene), &config).unwrap();
    assert!(s.skipped.is_empty(), "{:?}", s.skipped);
    let names: Vec<&str> = s.cases.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "control",
            "grazing",
            "narrow-lobes",
            "wide-lobes",
            "sun-32000",
            "thin-strands",
            "1-spp",
            "light-inside",
            "scale-1e-3",
            "scale-1e3"
        ]
    );
    let r = &s.report;
    assert_eq!(r.points.len(), names.len() * stress::METHODS.len() * 3);
    for p in &r.points {
        let v = &r.kind.variants[p.variant];
        assert_eq!(
            p.non_finite, 0,
            "{} {} seed {}",
            v.method, v.settings, p.seed
        );
        assert!(
            p.rmse.is_finite() && p.rmse > 0.0,
            "{} {}",
            v.method,
            v.settings
        );
        if v.method != "kajiya-kay" {
            assert!(
                p.fireflies <= 24,
                "{} {} seed {}: {} fireflies",
                v.method,
                v.settings,
                p.seed,
                p.fireflies
            );
        }
    }
    // The failures named are exactly the summaries over the firefly limit (none has NaN/Inf), and the report
    // lists them and every case.
    let pixels = 32.0 * 24.0;
    let over = r
        .summaries
        .iter()
        .filter(|x| x.fireflies.mean / pixels > stress::FIREFLY_FAIL_FRACTION)
        .count();
    let scale_failures = s
        .failures
        .iter()
        .filter(|f| f.contains("the control's"))
        .count();
    assert_eq!(s.failures.len(), over + scale_failures, "{:?}", s.failures);
    assert_eq!(scale_failures, 0, "{:?}", s.failures);
    let md = std::fs::read_to_string(&s.markdown).unwrap();
    for f in &s.failures {
        assert!(md.contains(f.as_str()), "{f}");
    }
    for n in names {
        assert!(md.contains(&format!("| {n} | marschner |")), "{n}: {md}");
    }
    let csv = std::fs::read_to_string(dir.path().join("out/stress.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + r.points.len());
}

/// A scene whose hair is a file cannot place a light inside the hair or scale itself: those cases are skipped,
/// with the reason, and the others remain.
#[test]
fn stress_skips_what_a_hair_file_scene_cannot_express() {
    use cuticle::study::stress;
    let base: toml::Table = toml::from_str(
        "[hair]\nfile = \"x.hair\"\nradius_scale = 2.0\n[camera]\nposition = [0, 0, 5]\n",
    )
    .unwrap();
    let (cases, skipped) = stress::cases(&base, true);
    let skipped: Vec<&str> = skipped.iter().map(|s| s.case.as_str()).collect();
    assert_eq!(skipped, ["light-inside", "scale-1e-3", "scale-1e3"]);
    assert_eq!(cases.len(), 7);
    let thin = cases.iter().find(|c| c.name == "thin-strands").unwrap();
    assert_eq!(thin.overrides[0].1.as_float(), Some(0.04));
    // The grazing camera drops the scene's position so it is auto-framed along −y.
    let grazing = cases.iter().find(|c| c.name == "grazing").unwrap();
    let camera = grazing.overrides[0].1.as_table().unwrap();
    assert!(!camera.contains_key("position"));
}

/// `study samples --quick` with no scene renders the built-in default scene, caches its references in `OUT/cache/`
/// (not beside the results), and ends by listing every file it wrote, each once and in order, then the cache
/// folder; `--cache-dir` puts the references elsewhere and a second run reuses them.
#[test]
fn study_without_a_scene_uses_the_default_scene_caches_in_a_folder_and_lists_its_files() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let out_arg = out.to_str().unwrap();
    let (code, stdout, stderr) = run(&["study", "samples", "--quick", "-q", "-o", out_arg]);
    assert_eq!(code, Some(0), "{stderr}");
    let (files, last) = written(&stdout);
    let expected: Vec<_> = [
        "samples.csv",
        "samples-summary.csv",
        "samples-error-time.png",
        "samples-error-time.svg",
        "samples-time.png",
        "samples-time.svg",
        "samples-crops.png",
        "samples-readouts.txt",
    ]
    .iter()
    .map(|f| out.join(f))
    .collect();
    assert_eq!(files, expected, "{stdout}");
    for f in &files {
        assert!(std::fs::metadata(f).unwrap().len() > 0, "{}", f.display());
    }
    let cache = out.join("cache");
    assert_eq!(last, format!("references cached in {}", cache.display()));
    let mut listed: Vec<String> = files
        .iter()
        .map(|f| f.file_name().unwrap().to_string_lossy().into_owned())
        .chain(["cache".to_owned()])
        .collect();
    listed.sort();
    assert_eq!(
        common::listing(&out),
        listed,
        "only the listed files and the cache"
    );
    let cached = common::listing(&cache);
    assert!(
        cached.len() >= 2 && cached.iter().all(|n| n.starts_with("reference-")),
        "{cached:?}"
    );

    // Elsewhere with --cache-dir (nothing in OUT/cache); that cache is reused by the next run.
    let other = dir.path().join("refs");
    let out2 = dir.path().join("out2");
    let args = [
        "study",
        "samples",
        "--quick",
        "-q",
        "-o",
        out2.to_str().unwrap(),
        "--cache-dir",
        other.to_str().unwrap(),
    ];
    let (code, _, stderr) = run(&args);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(!out2.join("cache").exists());
    assert_eq!(
        common::listing(&other),
        cached,
        "the same keys as in OUT/cache"
    );
    let modified = |d: &Path| -> Vec<std::time::SystemTime> {
        common::listing(d)
            .iter()
            .map(|n| std::fs::metadata(d.join(n)).unwrap().modified().unwrap())
            .collect()
    };
    let before = modified(&other);
    let (code, _, stderr) = run(&args);
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(
        modified(&other),
        before,
        "the references are reused, not rendered again"
    );
}

/// The default scene's references are keyed apart from a file holding the same text (a file's hair and maps
/// resolve in its directory), and the default scene takes the studies' overrides like a file: `lobes` replaces
/// its material, film and integrator keys.
#[test]
fn the_default_scene_has_its_own_cache_keys_and_takes_overrides() {
    use cuticle::study::kinds;
    let dir = tempfile::tempdir().unwrap();
    let config = StudyConfig {
        seeds: 1,
        ..StudyConfig::new(dir.path().join("out"), true)
    };
    let default = SceneFile::load(None).unwrap();
    assert_eq!(default.text, cuticle::scene::DEFAULT_SCENE);
    assert_eq!(default.name(), "default");
    let kind = kinds::lobes(true);
    let first = run_kind(&default, &kind, &config).unwrap();
    assert!(first.references.iter().all(|r| !r.cached));
    let again = run_kind(&default, &kind, &config).unwrap();
    assert!(again.references.iter().all(|r| r.cached));
    let path = dir.path().join("default.toml");
    std::fs::write(&path, cuticle::scene::DEFAULT_SCENE).unwrap();
    let as_file = run_kind(&file(&path), &kind, &config).unwrap();
    for (d, f) in first.references.iter().zip(&as_file.references) {
        assert!(
            !f.cached && d.path != f.path,
            "{} {}",
            d.path.display(),
            f.path.display()
        );
        assert_eq!(
            d.path.parent(),
            Some(dir.path().join("out/cache").as_path())
        );
    }
    // Deterministic renders of the same pixels: the same errors either way.
    for (a, b) in first.points.iter().zip(&as_file.points) {
        assert_eq!(a.rmse, b.rmse);
    }
}

/// `study stress --quick` with no scene: the ten fur-ball cases, drawn as bar charts per case (`stress-rmse`,
/// `stress-time`: PNG and SVG, the case names in the SVG) rather than curves through case numbers, and the files
/// listed at the end, `stress.md` last.
#[test]
fn stress_on_the_default_scene_draws_bars_per_case_and_lists_its_files() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let (code, stdout, stderr) = run(&[
        "study",
        "stress",
        "--quick",
        "--res",
        "16x12",
        "--seeds",
        "1",
        "-q",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    let (files, last) = written(&stdout);
    let names: Vec<String> = files
        .iter()
        .map(|f| f.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        [
            "stress.csv",
            "stress-summary.csv",
            "stress-rmse.png",
            "stress-rmse.svg",
            "stress-time.png",
            "stress-time.svg",
            "stress-crops.png",
            "stress-readouts.txt",
            "stress.md"
        ],
        "{stdout}"
    );
    assert!(files.iter().all(|f| f.is_file()));
    assert_eq!(
        last,
        format!("references cached in {}", out.join("cache").display())
    );
    assert!(!out.join("stress-error-time.png").exists());
    let svg = std::fs::read_to_string(out.join("stress-rmse.svg")).unwrap();
    for case in [
        "control",
        "grazing",
        "thin-strands",
        "light-inside",
        "scale-1e3",
    ] {
        assert!(svg.contains(case), "{case} not in stress-rmse.svg");
    }
    // The read-outs (failures, or the line saying there are none) come before the list of files.
    let first = stdout.lines().next().unwrap_or_default();
    assert!(
        first.starts_with("no failures") || first.contains(" fails "),
        "{stdout}"
    );
}

/// `--reference-spp` (the config's override) wins over a full kind's own budget, which wins over the study's
/// default; the film is still the kind's centred crop of the study's.
#[test]
fn an_explicit_reference_spp_overrides_the_kinds_budget() {
    use cuticle::study::kinds;
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("tiny.toml");
    std::fs::write(&scene, TINY).unwrap();
    let base = StudyConfig {
        seeds: 1,
        resolution: Some([16, 16]),
        ..StudyConfig::new(dir.path().join("out"), false)
    };
    let kind = kinds::lobes(false);
    let budget = kind.budget.reference_spp;
    assert_eq!(budget, Some(8 * kinds::REFERENCE_FACTOR));
    let config = StudyConfig {
        reference_spp_override: Some(4),
        ..base
    };
    let report = run_kind(&file(&scene), &kind, &config).unwrap();
    assert_eq!((report.reference_spp, report.resolution), (4, [16, 16]));
}

#[test]
fn the_generated_scenes_are_written_with_their_index_and_every_one_renders() {
    // The held-out set of `--quality auto`: with the real models and maps of the data folder, the same files for
    // the same seed, each one a scene the renderer takes (a small frame each).
    let dir = tempfile::tempdir().unwrap();
    let data = common::data::dir();
    let write = |out: &Path| {
        let (code, stdout, stderr) = run(&[
            "study",
            "scenes",
            "--count",
            "24",
            "--seed",
            "3",
            "--data",
            data.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, Some(0), "{stderr}");
        stdout
    };
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    write(&a);
    write(&b);
    let index = std::fs::read_to_string(a.join("scenes.md")).unwrap();
    let mut scenes: Vec<_> = std::fs::read_dir(&a)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    scenes.sort();
    assert_eq!(scenes.len(), 24, "{index}");
    let mut real = 0;
    for s in &scenes {
        let text = std::fs::read_to_string(s).unwrap();
        let name = s.file_stem().unwrap().to_str().unwrap();
        assert!(index.contains(name), "{name} missing from the index");
        assert_eq!(
            text,
            std::fs::read_to_string(b.join(s.file_name().unwrap())).unwrap()
        );
        real += usize::from(text.contains("file = "));
        let exr = dir.path().join(format!("{name}.exr"));
        let (code, _, stderr) = run(&[
            "render",
            s.to_str().unwrap(),
            "-q",
            "--res",
            "24x24",
            "--spp",
            "1",
            "--aovs",
            "none",
            "-o",
            exr.to_str().unwrap(),
        ]);
        assert_eq!(code, Some(0), "{name}: {stderr}\n{text}");
    }
    assert!(
        real > 0,
        "no scene took a real model from {}",
        data.display()
    );
}

#[test]
fn study_auto_alone_writes_met_and_its_estimate_per_scene_and_target() {
    // Two scenes of the generated set, tiny: the table has a row per scene and target with the measured error,
    // auto's own estimate and whether it met the target, and a headline that counts them.
    let dir = tempfile::tempdir().unwrap();
    let scenes = dir.path().join("scenes");
    let (code, _, stderr) = run(&[
        "study",
        "scenes",
        "--count",
        "2",
        "--seed",
        "5",
        "--data",
        "/nonexistent",
        "-o",
        scenes.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    let out = dir.path().join("out");
    let (code, stdout, stderr) = run(&[
        "study",
        "auto",
        "--auto-only",
        scenes.join("gen-5-00.toml").to_str().unwrap(),
        scenes.join("gen-5-01.toml").to_str().unwrap(),
        "--res",
        "16x16",
        "--reference-spp",
        "16",
        "--targets",
        "0.2",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(stdout.contains("rows met the target"), "{stdout}");
    let csv = std::fs::read_to_string(out.join("auto-held-out.csv")).unwrap();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let column = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .unwrap_or_else(|| panic!("no column {name} in {header:?}"))
    };
    let (target, measured, estimated, met) = (
        column("target"),
        column("measured"),
        column("estimated"),
        column("met"),
    );
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    assert_eq!(rows.len(), 2, "{csv}");
    for r in rows {
        let f: Vec<&str> = r.split(',').collect();
        let (m, e): (f64, f64) = (f[measured].parse().unwrap(), f[estimated].parse().unwrap());
        assert!(m > 0.0 && e > 0.0, "{r}");
        assert_eq!(
            f[met] == "true",
            m <= f[target].parse::<f64>().unwrap(),
            "{r}"
        );
    }
}
