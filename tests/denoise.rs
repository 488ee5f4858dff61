//! `--denoise`: Open Image Denoise over the beauty (`scripts/oidn.sh` installs the library; the README's set-up
//! does). The denoised frame is closer to a converged reference than the noisy one but smears the fur ball's fine
//! strands (a number shows it), is the same for any thread count and tile split (tiles are merged, then
//! denoised), and without the library the render fails before anything is loaded, naming where it looked.

mod common;

use std::path::Path;
use std::process::{Command, Output};

use common::listing;
use cuticle::image::{self, Image};

const EXE: &str = env!("CARGO_BIN_EXE_cuticle");

fn cuticle(args: &[&str]) -> Output {
    Command::new(EXE).args(args).output().expect("run cuticle")
}

fn ok(o: Output) -> Output {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    o
}

/// The default scene at 96x72, `spp` samples, `extra` arguments, written to `out`.
fn render(out: &Path, spp: u32, extra: &[&str]) -> Image {
    let spp = spp.to_string();
    let mut args = vec![
        "render",
        "-q",
        "-o",
        out.to_str().unwrap(),
        "--res",
        "96x72",
        "--spp",
        &spp,
    ];
    args.extend_from_slice(extra);
    ok(cuticle(&args));
    image::read(out).unwrap()
}

/// The RGB of channels `names` of every pixel.
fn rgb(image: &Image, names: [&str; 3]) -> Vec<f32> {
    image
        .triples(names)
        .unwrap_or_else(|| panic!("no {names:?} in {:?}", image.channels))
}

fn rmse(a: &[f32], b: &[f32]) -> f64 {
    let sum: f64 = a.iter().zip(b).map(|(x, y)| f64::from(x - y).powi(2)).sum();
    (sum / a.len() as f64).sqrt()
}

const BEAUTY: [&str; 3] = ["R", "G", "B"];
const DENOISED: [&str; 3] = ["denoised.R", "denoised.G", "denoised.B"];

#[test]
fn the_denoised_frame_is_closer_to_the_reference_and_the_same_for_any_threads_and_tiles() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The reference in two halves of other seeds: their mean for the error, both for the detail kept.
    let halves = [
        render(
            &d.join("ref-a.exr"),
            128,
            &["--aovs", "none", "--seed", "1001"],
        ),
        render(
            &d.join("ref-b.exr"),
            128,
            &["--aovs", "none", "--seed", "2002"],
        ),
    ];
    let mut reference = halves[0].clone();
    for (r, b) in reference.data.iter_mut().zip(&halves[1].data) {
        *r = 0.5 * (*r + b);
    }
    let noisy = render(&d.join("noisy.exr"), 4, &["--denoise", "--threads", "2"]);
    let truth = rgb(&reference, BEAUTY);
    let (before, after) = (
        rmse(&rgb(&noisy, BEAUTY), &truth),
        rmse(&rgb(&noisy, DENOISED), &truth),
    );
    eprintln!("RMSE against 256 spp: noisy {before:.4}, denoised {after:.4}");
    assert!(after < 0.7 * before, "noisy {before}, denoised {after}");
    // It smears the fur ball's sub-pixel strands: the denoised frame keeps well under half of the reference's
    // detail around the hair where the noisy one keeps about all of it (study denoise: 0.18-0.31 at 128x96).
    let window = cuticle::study::figures::hair_window(&reference, 64);
    let as_rgb = |names: [&str; 3]| {
        let mut im = Image::new(96, 72, BEAUTY.map(String::from).to_vec());
        im.data = rgb(&noisy, names);
        im
    };
    let kept = |x: &Image| {
        cuticle::measure::pixels::detail(x, [&halves[0], &halves[1]], window)
            .unwrap()
            .kept
    };
    let (kept_noisy, kept_denoised) = (kept(&as_rgb(BEAUTY)), kept(&as_rgb(DENOISED)));
    eprintln!("detail kept: noisy {kept_noisy:.3}, denoised {kept_denoised:.3}");
    assert!(kept_noisy > 0.7, "noisy keeps {kept_noisy}");
    assert!(kept_denoised < 0.5, "denoised keeps {kept_denoised}");
    // The prefiltered albedo guide runs too (two filter passes).
    let guided = render(&d.join("guided.exr"), 4, &["--denoise=albedo-prefiltered"]);
    let guided_rmse = rmse(&rgb(&guided, DENOISED), &truth);
    assert!(guided_rmse < 0.7 * before, "guided {guided_rmse}");
    // The beauty is kept as rendered: the same as a render without --denoise by filter importance sampling, which
    // --denoise chooses (Open Image Denoise cannot remove a splat's noise, shared by neighbouring pixels).
    let plain = render(
        &d.join("plain.exr"),
        4,
        &["--threads", "2", "--reconstruction", "importance"],
    );
    assert_eq!(rgb(&plain, BEAUTY), rgb(&noisy, BEAUTY));

    // One thread, and two tiles merged then denoised: the same denoised frame, bit for bit.
    let one = render(&d.join("one.exr"), 4, &["--denoise", "--threads", "1"]);
    assert_eq!(rgb(&one, DENOISED), rgb(&noisy, DENOISED));
    let t0 = d.join("t0.exr");
    let t1 = d.join("t1.exr");
    let importance = ["--reconstruction", "importance"];
    render(&t0, 4, &[&["--tile", "0/2"][..], &importance].concat());
    render(&t1, 4, &[&["--tile", "1/2"][..], &importance].concat());
    // Splatted tiles (the default film) are refused: their noise is shared by neighbouring pixels.
    let (s0, s1) = (d.join("s0.exr"), d.join("s1.exr"));
    render(&s0, 4, &["--tile", "0/2"]);
    render(&s1, 4, &["--tile", "1/2"]);
    let refused = cuticle(&[
        "merge",
        "--denoise",
        "-o",
        d.join("refused.exr").to_str().unwrap(),
        s0.to_str().unwrap(),
        s1.to_str().unwrap(),
    ]);
    let message = String::from_utf8_lossy(&refused.stderr);
    assert!(
        !refused.status.success() && message.contains("--reconstruction importance"),
        "{message}"
    );
    assert!(!d.join("refused.exr").exists());
    let merged = d.join("merged.exr");
    ok(cuticle(&[
        "merge",
        "--denoise",
        "-o",
        merged.to_str().unwrap(),
        t0.to_str().unwrap(),
        t1.to_str().unwrap(),
    ]));
    let merged = image::read(&merged).unwrap();
    assert_eq!(rgb(&merged, DENOISED), rgb(&noisy, DENOISED));

    // The preview shows the denoised frame.
    let png = image::read(d.join("noisy.png")).unwrap();
    let want: Vec<f32> = rgb(&noisy, DENOISED)
        .iter()
        .map(|&v| f32::from(image::linear_to_srgb8(v)) / 255.0)
        .collect();
    // Within a tenth of a code value: OpenImageIO's 8-bit to float conversion rounds apart from v / 255.
    let got = rgb(&png, BEAUTY);
    let worst = got
        .iter()
        .zip(&want)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(worst < 0.1 / 255.0, "worst {worst}");
}

#[test]
fn a_tile_or_crop_is_not_denoised_alone_and_a_missing_library_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("t.exr");
    let o = cuticle(&[
        "render",
        "-q",
        "-o",
        out.to_str().unwrap(),
        "--tile",
        "0/2",
        "--denoise",
    ]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("cuticle merge --denoise"), "{e}");

    let empty = tempfile::tempdir().unwrap();
    let o = Command::new(EXE)
        .args(["render", "-q", "-o", out.to_str().unwrap(), "--denoise"])
        .env("CUTICLE_OIDN", empty.path())
        .env("XDG_DATA_HOME", empty.path())
        .env_remove("LD_LIBRARY_PATH")
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(
        e.contains("--denoise: Open Image Denoise is not installed")
            && e.contains("scripts/oidn.sh"),
        "{e}"
    );
    assert!(!e.contains("strands"), "refused before loading: {e}");
    assert!(listing(dir.path()).is_empty());
}

/// On the peer scene (Chiang, a sun and a sky) the denoised frame has no NaN or infinite value and keeps the
/// beauty's mean within 1 %: the filter moves noise, not energy.
#[test]
fn the_denoised_peer_frame_is_finite_and_keeps_the_mean() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("peer.exr");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/furball-peer.toml");
    ok(cuticle(&[
        "render",
        scene.to_str().unwrap(),
        "-q",
        "-o",
        out.to_str().unwrap(),
        "--res",
        "128x128",
        "--spp",
        "4",
        "--denoise",
    ]));
    let image = image::read(&out).unwrap();
    let (beauty, denoised) = (rgb(&image, BEAUTY), rgb(&image, DENOISED));
    assert!(denoised.iter().all(|v| v.is_finite()));
    let mean = |v: &[f32]| v.iter().map(|&x| f64::from(x)).sum::<f64>() / v.len() as f64;
    let (a, b) = (mean(&beauty), mean(&denoised));
    eprintln!("peer frame mean: beauty {a:.5}, denoised {b:.5}");
    assert!((b / a - 1.0).abs() < 0.01, "beauty {a}, denoised {b}");
}

/// `--quality auto --denoise`: the samples per pixel are found in doubling rounds on the frame itself
/// (`quality::denoised`). The frame after the rounds holds N samples in every pixel, is the same for 1 and 2
/// threads, and its denoised beauty meets the target against a converged reference, with the rounds' point estimate
/// of its error within a factor of 1.5 of the measurement and their bound not far under it.
#[test]
fn auto_with_the_denoiser_meets_its_target_on_the_denoised_frame() {
    use cuticle::image::denoise::Guide;
    use cuticle::measure::metrics;
    use cuticle::quality::delivered::delivered_denoised;
    use cuticle::quality::denoised::{self, DenoisedSchedule};
    use cuticle::quality::{self, Fixed, QualityConfig};
    use cuticle::render::{thread_pool, Frame, Request};
    use cuticle::scene::Scene;

    const TARGET: f32 = 0.05;
    let scene = Scene::parse(
        "[hair]\nprocedural = { kind = \"fur-ball\", strands = 1500 }\nopacity = 0.5\n\
         [material]\nmodel = \"marschner\"\n[film]\nresolution = [96, 72]\n\
         [[light]]\nkind = \"distant\"\ndirection = [-1.0, -1.0, -0.6]\nirradiance = 3.0\n\
         [environment]\nradiance = [0.6, 0.7, 0.9]\n",
        Path::new("<test>"),
        Path::new("."),
    )
    .unwrap();
    let frame = Frame::load(scene.resolve().unwrap()).unwrap();
    let q = QualityConfig {
        target: TARGET,
        ..QualityConfig::default()
    };
    let run = |threads: usize| {
        let pool = thread_pool(Some(threads)).unwrap();
        pool.install(|| {
            let planned = quality::plan_frame(&frame, &frame.settings, &q, Fixed::default());
            let schedule = DenoisedSchedule::new(&planned.pilot, &q, Guide::Color);
            let request =
                Request::new(&planned.settings).maps(planned.maps.as_ref(), planned.maps_seconds);
            let d = denoised::render(&frame, request, &schedule, 2).unwrap();
            (planned, d)
        })
    };
    let (planned, d) = run(2);
    let (_, one) = run(1);
    assert_eq!(
        common::bit_differences(&d.render.image.data, &one.render.image.data),
        0,
        "1 and 2 threads differ"
    );
    let rounds = &d.rounds.rounds;
    let n = rounds.last().expect("a round").spp;
    for (i, r) in rounds.iter().enumerate() {
        assert_eq!(r.spp, rounds[0].spp << i, "rounds double: {rounds:?}");
    }
    let pool = thread_pool(Some(2)).unwrap();
    let spp = d.render.image.channel_index("spp").unwrap();
    assert!(d
        .render
        .image
        .data
        .chunks_exact(d.render.image.channels.len())
        .all(|p| p[spp] == n as f32));

    // Against a converged reference (the bounces auto left out count against it).
    let mut reference = planned.settings.clone();
    reference.adaptive = None;
    reference.film.spp = 1024;
    reference.film.seed = 991;
    reference.integrator.path_length = 4;
    let reference =
        pool.install(|| frame.render(Request::new(&reference).maps(planned.maps.as_ref(), 0.0)));
    let mut denoised_frame = d.render.image.clone();
    for (p, v) in denoised_frame
        .data
        .chunks_exact_mut(d.render.image.channels.len())
        .zip(rgb(&d.render.image, DENOISED).chunks_exact(3))
    {
        p[..3].copy_from_slice(v);
    }
    let mask = vec![false; denoised_frame.width * denoised_frame.height];
    let measured = metrics::errors(&denoised_frame, &reference.image, &mask)
        .unwrap()
        .relmse
        .sqrt();
    let noisy = metrics::errors(&d.render.image, &reference.image, &mask)
        .unwrap()
        .relmse
        .sqrt();
    let said = delivered_denoised(&planned.pilot, TARGET, &d.rounds);
    eprintln!(
        "rounds {} spp (pilots' undenoised {}): denoised {measured:.4}, noisy {noisy:.4}; {}",
        d.rounds.path(),
        planned.pilot.spp,
        said.line()
    );
    assert!(
        measured <= f64::from(TARGET),
        "denoised frame's error {measured} over {TARGET}"
    );
    // The rounds' point estimate predicts the error within a factor of 1.5; the bound the stop reads (the
    // estimate plus two standard errors, what the render prints) is not far under it.
    let bias2 = said.bias.map_or(0.0, |b| b * b);
    let point = (said.noise_range.0.powi(2) + bias2).sqrt();
    assert!(
        point < 1.5 * measured && point > measured / 1.5,
        "point estimate {point} against measured {measured}"
    );
    assert!(
        said.error >= point && said.error > measured / 1.25,
        "bound {} against measured {measured}",
        said.error
    );
}

/// `study temporal` on a tiny film: a fixed seed on a still camera renders the same frame every time (flicker
/// exactly 0), a seed per frame flickers, more samples lower both the still error and the flicker, and the denoiser
/// lowers the flicker at equal spp.
#[test]
fn study_temporal_measures_flicker_beside_the_still_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("temporal");
    ok(cuticle(&[
        "study",
        "temporal",
        "-o",
        out.to_str().unwrap(),
        "--res",
        "40x30",
        "--frames",
        "3",
        "--spp",
        "2,16",
        "--reference-spp",
        "64",
    ]));
    let csv = std::fs::read_to_string(out.join("temporal.csv")).unwrap();
    let md = std::fs::read_to_string(out.join("temporal.md")).unwrap();
    assert!(md.contains("flickers least"), "{md}");
    // scene,camera,seeds,method,spp,denoised,series,still_error,flicker,seconds
    let rows: Vec<Vec<String>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(str::to_owned).collect())
        .collect();
    assert_eq!(rows.len(), 2 * 2 * 3 * 2 * 2, "{csv}");
    let value = |camera: &str,
                 seeds: &str,
                 method: &str,
                 spp: &str,
                 denoised: &str,
                 column: usize| {
        let r = rows
            .iter()
            .find(|r| {
                r[1] == camera && r[2] == seeds && r[3] == method && r[4] == spp && r[5] == denoised
            })
            .unwrap_or_else(|| panic!("no row {camera} {seeds} {method} {spp} {denoised}"));
        r[column].parse::<f64>().unwrap()
    };
    for method in ["rt-stochastic", "rt-exact", "deep-opacity"] {
        for denoised in ["false", "true"] {
            assert_eq!(value("static", "fixed", method, "2", denoised, 8), 0.0);
        }
        let (few, many) = (
            value("static", "per-frame", method, "2", "false", 8),
            value("static", "per-frame", method, "16", "false", 8),
        );
        assert!(
            few > 0.0 && many < few,
            "{method}: flicker {few} at 2 spp, {many} at 16"
        );
        let (still_few, still_many) = (
            value("turntable", "per-frame", method, "2", "false", 7),
            value("turntable", "per-frame", method, "16", "false", 7),
        );
        assert!(
            still_many < still_few,
            "{method}: still error {still_few} → {still_many}"
        );
        let clean = value("static", "per-frame", method, "2", "true", 8);
        assert!(
            clean < few,
            "{method}: denoised flicker {clean} against {few}"
        );
    }
}

/// The denoised rounds hold two more copies of the film: under a memory limit that leaves no room for them, auto
/// keeps its adaptive rule (the target on the frame before denoising) and says why; with room, it runs the rounds.
#[test]
fn auto_with_the_denoiser_runs_its_rounds_only_within_the_memory_limit() {
    use cuticle::image::denoise::Guide;
    use cuticle::job::{Job, Part, Request};
    use cuticle::quality::Fixed;
    use cuticle::render::budget;
    use cuticle::scene::Scene;

    let scene = Scene::parse(
        "[hair]\nprocedural = { kind = \"fur-ball\", strands = 300 }\n[film]\nresolution = [256, 256]\n\
         [quality]\nmode = \"auto\"\ntarget = 0.2\n",
        Path::new("<test>"),
        Path::new("."),
    )
    .unwrap();
    let estimate = budget::estimate_frame(&scene.resolve().unwrap(), 1, true)
        .unwrap()
        .total();
    let prepare = |max_memory: u64| {
        Job::prepare(Request {
            scene: scene.clone(),
            fixed: Fixed::default(),
            threads: Some(1),
            max_memory: Some(max_memory),
            part: Part::Full,
            frames: None,
            output: None,
            dump_shadow_maps: None,
            denoise: Some(Guide::Color),
            progress: false,
        })
        .unwrap()
    };
    let tight = prepare(estimate);
    assert!(tight.denoised.is_none());
    let auto = tight.auto.as_ref().unwrap();
    let why = auto
        .decisions
        .iter()
        .find(|d| d.key == "film.spp" && d.value.contains("denoised"))
        .expect("a decision naming the memory");
    assert!(why.reason.contains("memory limit"), "{}", why.reason);
    assert!(auto.decisions.iter().any(|d| d.key == "adaptive sampling"));
    let roomy = prepare(estimate + (1 << 30));
    assert!(roomy.denoised.is_some());
}
