//! `--quality auto`: the decisions auto must make on scenes built to require them, and an auto render
//! that meets its error target against a converged reference.

use std::path::Path;
use std::process::Command;

use cuticle::accel::CurveKind;
use cuticle::measure::metrics;
use cuticle::quality::delivered::delivered;
use cuticle::quality::{self, Fixed, QualityConfig};
use cuticle::render::{thread_pool, Frame, Request};
use cuticle::scene::{Scene, ShadowMode};

mod common;

const EXE: &str = env!("CARGO_BIN_EXE_cuticle");

fn scene(text: &str) -> Scene {
    Scene::parse(text, Path::new("<test>"), Path::new(".")).unwrap()
}

/// A small procedural fur ball; `extra` appends tables.
fn fur(model: &str, film: &str, extra: &str) -> Scene {
    scene(&format!(
        "[hair]\nprocedural = {{ kind = \"fur-ball\", strands = 1500 }}\nopacity = 0.5\n\
         [material]\nmodel = \"{model}\"\n[film]\n{film}\n{extra}"
    ))
}

const SUN: &str =
    "[[light]]\nkind = \"distant\"\ndirection = [-1.0, -1.0, -0.6]\nirradiance = 3.0\n";
const SKY: &str = "[environment]\nradiance = [0.6, 0.7, 0.9]\n";

fn curves_for(s: &Scene) -> (CurveKind, String) {
    let spec = s.resolve().unwrap();
    let strands = spec.hair.load().unwrap();
    let (kind, d) = quality::plan_curves(
        &strands,
        &spec.material,
        &spec.settings.camera,
        spec.settings.film.resolution,
    );
    (kind, d.to_string())
}

#[test]
fn auto_chooses_ribbons_for_sub_pixel_strands_and_tubes_for_a_close_up_of_an_offset_model() {
    // Chiang reads the offset h across the fibre. The whole ball in 64x48 pixels: strands far below a pixel.
    let far = fur("chiang", "resolution = [64, 48]", SUN);
    let (kind, why) = curves_for(&far);
    assert_eq!(kind, CurveKind::Flat, "{why}");
    // A 1° field of view at 640x480 on a twentieth of the ball: strands pixels wide.
    let near = fur(
        "chiang",
        "resolution = [640, 480]",
        &format!("{SUN}[camera]\nfov = 1.0\nmargin = 0.05\n"),
    );
    let (kind, why) = curves_for(&near);
    assert_eq!(kind, CurveKind::Round, "{why}");
    // A model that does not read h gets ribbons even in the close-up.
    let near_kk = fur(
        "kajiya-kay",
        "resolution = [640, 480]",
        &format!("{SUN}[camera]\nfov = 1.0\nmargin = 0.05\n"),
    );
    let (kind, why) = curves_for(&near_kk);
    assert_eq!(kind, CurveKind::Flat, "{why}");
}

fn planned_shadows(s: &Scene) -> (ShadowMode, Vec<String>) {
    let frame = Frame::load(s.resolve().unwrap()).unwrap();
    let q = QualityConfig {
        target: 0.2,
        ..QualityConfig::default()
    };
    let pool = thread_pool(Some(2)).unwrap();
    let p = pool.install(|| quality::plan_frame(&frame, &frame.settings, &q, Fixed::default()));
    (
        p.settings.shadows.mode,
        p.decisions.iter().map(ToString::to_string).collect(),
    )
}

#[test]
fn auto_chooses_deep_opacity_maps_under_a_sun_and_rays_under_an_environment() {
    let (mode, why) = planned_shadows(&fur("kajiya-kay", "resolution = [32, 24]", SUN));
    assert_eq!(mode, ShadowMode::DeepOpacity, "{why:#?}");
    let (mode, why) = planned_shadows(&fur("kajiya-kay", "resolution = [32, 24]", SKY));
    assert_eq!(mode, ShadowMode::Raytraced, "{why:#?}");
}

/// The auto render of a small scene against a converged reference (1024 spp, 4 bounces): its relative RMSE (the
/// measure the target is stated in) is within the target, and a tighter target takes more samples.
const LOOSE: f32 = 0.04;
const TIGHT: f32 = 0.02;

#[test]
fn auto_meets_its_target_and_a_tighter_target_takes_more_samples() {
    let s = fur("marschner", "resolution = [96, 72]", &format!("{SUN}{SKY}"));
    let frame = Frame::load(s.resolve().unwrap()).unwrap();
    let pool = thread_pool(Some(2)).unwrap();
    let plan = |target: f32| {
        let q = QualityConfig {
            target,
            max_spp: 4096,
            ..QualityConfig::default()
        };
        pool.install(|| quality::plan_frame(&frame, &frame.settings, &q, Fixed::default()))
    };
    let loose = plan(LOOSE);
    let tight = plan(TIGHT);
    assert!(tight.settings.film.spp > loose.settings.film.spp);

    let render = |settings: &cuticle::render::RenderSettings,
                  maps: Option<&cuticle::shadow::ShadowMaps>| {
        pool.install(|| frame.render(Request::new(settings).maps(maps, 0.0)).image)
    };
    for planned in [&loose, &tight] {
        let rendered = pool.install(|| {
            frame.render(Request::new(&planned.settings).maps(planned.maps.as_ref(), 0.0))
        });
        let image = rendered.image;
        let mut reference = planned.settings.clone();
        reference.film.spp = 1024;
        reference.adaptive = None;
        reference.film.seed = 991;
        // Converged in light transport too: the bounces auto left out count against it.
        reference.integrator.path_length = 4;
        let reference = render(&reference, planned.maps.as_ref());
        let mask = vec![false; image.width * image.height];
        let e = metrics::errors(&image, &reference, &mask).unwrap();
        let rel_rmse = e.relmse.sqrt();
        let target = if std::ptr::eq(planned, &loose) {
            LOOSE
        } else {
            TIGHT
        };
        assert!(
            rel_rmse <= f64::from(target),
            "relative RMSE {rel_rmse} over the target {target}"
        );
        // Adaptive sampling: the background (alpha 0) stops at the schedule's minimum, the hair takes more.
        let schedule = planned.settings.adaptive.expect("auto samples adaptively");
        let (a, n) = (
            image.channel_index("A").unwrap(),
            image.channel_index("spp").unwrap(),
        );
        let (mut background, mut hair) = (Vec::new(), Vec::new());
        for p in image.data.chunks_exact(image.channels.len()) {
            if p[a] == 0.0 {
                &mut background
            } else {
                &mut hair
            }
            .push(p[n]);
        }
        let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len().max(1) as f32;
        // The splatted frame may meet the loose target at the schedule's minimum everywhere, with no round after
        // the first: the samples' spread is checked where rounds ran, and the tight target must run them.
        let rounds_ran = hair
            .iter()
            .chain(&background)
            .any(|&s| s > schedule.min as f32);
        assert!(rounds_ran || target == LOOSE, "no rounds at {target}");
        if rounds_ran {
            // Background pixels next to the hair borrow their neighbours' variance (render::adaptive), the rest
            // keep the minimum.
            let at_min = background
                .iter()
                .filter(|&&s| s == schedule.min as f32)
                .count();
            assert!(
                at_min * 10 > background.len() * 9,
                "{at_min} of {}",
                background.len()
            );
            assert!(mean(&hair) > 1.5 * mean(&background));
        }
        // The prediction is a prediction: within a factor 2 of what was measured.
        let predicted = planned.pilot.predicted_noise;
        assert!(
            rel_rmse < 2.0 * predicted && rel_rmse > 0.5 * predicted,
            "predicted noise {predicted}, measured {rel_rmse}"
        );
        // What the render says it delivered (the stop's reading and the pilots' bias) is what was measured, within
        // 20 % (the bound; the reference's own noise, 1024 spp, is ~1 % of the frame's).
        let said = delivered(&planned.pilot, target, rendered.stats.noise.as_ref());
        assert!(said.read_from_frame);
        eprintln!(
            "estimated {} measured {rel_rmse} ({})",
            said.error,
            said.line()
        );
        assert!(
            (said.error / rel_rmse - 1.0).abs() <= 0.2,
            "estimated {} against measured {rel_rmse}: {}",
            said.error,
            said.line()
        );
        assert!(said.shortfall().is_none(), "{:?}", said.shortfall());
    }
    // Held at a cap too low for the target: the estimate is over it, and says why.
    let q = QualityConfig {
        target: TIGHT,
        max_spp: 4,
        min_spp: 2,
        ..QualityConfig::default()
    };
    let capped =
        pool.install(|| quality::plan_frame(&frame, &frame.settings, &q, Fixed::default()));
    let rendered = pool
        .install(|| frame.render(Request::new(&capped.settings).maps(capped.maps.as_ref(), 0.0)));
    let said = delivered(&capped.pilot, TIGHT, rendered.stats.noise.as_ref());
    let why = said
        .shortfall()
        .expect("a 4-spp cap cannot meet the tight target");
    assert!(why.contains("stopped at the cap of 4 spp"), "{why}");
}

#[test]
fn render_quality_auto_prints_its_decisions_and_is_the_same_at_1_and_2_threads() {
    let dir = tempfile::tempdir().unwrap();
    let scene_path = dir.path().join("s.toml");
    std::fs::write(
        &scene_path,
        format!(
            "[hair]\nprocedural = {{ kind = \"fur-ball\", strands = 800 }}\n[film]\nresolution = [40, 30]\n\
             [quality]\nmode = \"auto\"\ntarget = 0.2\n{SUN}"
        ),
    )
    .unwrap();
    let mut images = Vec::new();
    for threads in ["1", "2"] {
        let out = dir.path().join(format!("t{threads}.exr"));
        let o = Command::new(EXE)
            .args(["render", scene_path.to_str().unwrap(), "-o"])
            .arg(&out)
            .args(["--threads", threads, "-q"])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{err}");
        for key in [
            "auto: hair.curves = ",
            "auto: shadows.mode = ",
            "auto: integrator.path_length = ",
            "auto: film.spp = ",
            "predicted render",
        ] {
            assert!(err.contains(key), "no {key:?} in\n{err}");
        }
        images.push(cuticle::image::read(&out).unwrap());
    }
    assert_eq!(images[0].data.len(), images[1].data.len());
    for (a, b) in images[0].data.iter().zip(&images[1].data) {
        assert_eq!(a.to_bits(), b.to_bits());
    }
    // A bad target names the key.
    let o = Command::new(EXE)
        .args([
            "render",
            scene_path.to_str().unwrap(),
            "--target",
            "0",
            "-q",
        ])
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("quality.target"));
}

/// `study auto` end to end on a tiny scene: every file written, one row per method and target, auto's row
/// consistent (met = error within target), and the 24 fixed configurations fitted.
#[test]
fn study_auto_writes_its_table_and_fits() {
    let dir = tempfile::tempdir().unwrap();
    let scene_path = dir.path().join("tiny.toml");
    std::fs::write(
        &scene_path,
        format!(
            "[hair]\nprocedural = {{ kind = \"fur-ball\", strands = 600 }}\nopacity = 0.5\n\
             [shadows.deep_opacity]\nresolution = 64\n{SUN}"
        ),
    )
    .unwrap();
    let out = dir.path().join("study");
    let o = Command::new(EXE)
        .args(["study", "auto", scene_path.to_str().unwrap(), "-o"])
        .arg(&out)
        .args([
            "--res",
            "32x24",
            "--reference-spp",
            "64",
            "--targets",
            "0.2,0.1",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    let csv = std::fs::read_to_string(out.join("auto.csv")).unwrap();
    let fits = std::fs::read_to_string(out.join("auto-fits-tiny.csv")).unwrap();
    assert_eq!(fits.lines().count(), 25, "{fits}");
    let md = std::fs::read_to_string(out.join("auto.md")).unwrap();
    assert_eq!(
        md.lines().filter(|l| l.starts_with("| tiny |")).count(),
        2,
        "{md}"
    );
    let (mut autos, mut points) = (0, 0);
    for line in csv.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f.len(), 10, "{line}");
        let (target, rel, met): (f64, f64, bool) = (
            f[1].parse().unwrap(),
            f[6].parse().unwrap(),
            f[7].parse().unwrap(),
        );
        assert!(rel.is_finite() && rel >= 0.0, "{line}");
        // Every method is charged its process's load and build, inside its CPU seconds.
        let (cpu, setup): (f64, f64) = (f[8].parse().unwrap(), f[9].parse().unwrap());
        assert!(setup > 0.0 && setup < cpu, "{line}");
        assert_eq!(met, rel <= target, "{line}");
        autos += usize::from(f[2] == "auto");
        points += usize::from(f[2] == "auto point estimates");
    }
    assert_eq!((autos, points), (2, 2), "{csv}");
}

/// The image-level rule (what auto uses) against the per-pixel rule it replaced, on the quick scene of
/// [`auto_meets_its_target_and_a_tighter_target_takes_more_samples`] at the loose target: both meet it, the image
/// rule with fewer samples. And its image is the same at 1 and 2 threads and with 32² or 7² work tiles.
#[test]
fn the_image_rule_meets_the_target_with_fewer_samples_than_the_per_pixel_rule_and_is_deterministic()
{
    use cuticle::render::adaptive::{Convergence, Schedule};
    use cuticle::render::film::Accumulate;
    use cuticle::render::{PixelSampling, PixelSource};

    /// The per-pixel rule ([`Schedule::next_total`]) as a sampling strategy: rounds of samples, in index order,
    /// until the pixel's own bound on its error is under the target. The renderer runs only the image rule; this
    /// test brings the per-pixel one to compare.
    struct PerPixel(Schedule);
    impl PixelSampling for PerPixel {
        fn take(&self, source: &mut PixelSource<'_>, sums: &mut dyn Accumulate) -> u32 {
            let mut convergence = Convergence::default();
            let mut i = 0;
            while let Some(total) = self.0.next_total(i, &convergence) {
                while i < total {
                    let s = source.sample(i);
                    if s.beauty.is_finite() {
                        convergence.add(s.beauty);
                    }
                    sums.add(&s);
                    i += 1;
                }
            }
            i
        }
    }

    let s = fur("marschner", "resolution = [96, 72]", &format!("{SUN}{SKY}"));
    let frame = Frame::load(s.resolve().unwrap()).unwrap();
    let pool = thread_pool(Some(2)).unwrap();
    let q = QualityConfig {
        target: LOOSE,
        max_spp: 4096,
        ..QualityConfig::default()
    };
    let planned =
        pool.install(|| quality::plan_frame(&frame, &frame.settings, &q, Fixed::default()));
    let image_rule = planned.settings.adaptive.expect("auto samples adaptively");
    let mut reference = planned.settings.clone();
    reference.film.spp = 1024;
    reference.adaptive = None;
    reference.film.seed = 991;
    reference.integrator.path_length = 4;
    let maps = planned.maps.as_ref();
    let reference = pool.install(|| frame.render(Request::new(&reference).maps(maps, 0.0)).image);
    // The per-pixel rule as auto used it: each pixel to √0.75 of the target, a quarter to 4× the pilots' spp.
    let spp = planned.settings.film.spp;
    let per_pixel = PerPixel(Schedule {
        min: (spp / 4).max(4),
        max: spp * 4,
        target: 0.75f64.sqrt() * f64::from(LOOSE),
        cost: None,
        sampler_gain: 1.0,
    });
    let measure = |sampling: Option<&dyn PixelSampling>| {
        let request = Request::new(&planned.settings).maps(maps, 0.0);
        let request = match sampling {
            Some(s) => request.sampling(s),
            None => request,
        };
        let image = pool.install(|| frame.render(request).image);
        let mask = vec![false; image.width * image.height];
        let e = metrics::errors(&image, &reference, &mask).unwrap();
        let n = image.channel_index("spp").unwrap();
        let samples: f64 = image
            .data
            .chunks_exact(image.channels.len())
            .map(|p| f64::from(p[n]))
            .sum();
        let mean = samples / (image.width * image.height) as f64;
        (image, e.relmse.sqrt(), mean)
    };
    assert!(image_rule.max > image_rule.min, "{image_rule:?}");
    let (image, image_error, image_spp) = measure(None);
    let (_, pixel_error, pixel_spp) = measure(Some(&per_pixel));
    assert!(image_error <= f64::from(LOOSE), "{image_error}");
    assert!(pixel_error <= f64::from(LOOSE), "{pixel_error}");
    // Measured: 4.7 spp (0.0278) against 5.7 (0.0262); the per-pixel rule is held back by its 4x-spp maximum.
    assert!(image_spp < pixel_spp, "{image_spp} against {pixel_spp}");

    // Determinism: 1 thread and 7² tiles against 2 threads and 32² tiles.
    let one = thread_pool(Some(1)).unwrap();
    let small_tiles = one.install(|| {
        frame
            .render(Request::new(&planned.settings).maps(maps, 0.0).tile_side(7))
            .image
    });
    assert_eq!(image.data.len(), small_tiles.data.len());
    assert!(image
        .data
        .iter()
        .zip(&small_tiles.data)
        .all(|(a, b)| a.to_bits() == b.to_bits()));
}

/// Camera samples per pixel of each calibration render: 16 makes the shortest renders ~0.5 CPU s.
const CALIBRATION_SPP: u32 = 16;

/// Measures what calibrated [`quality::cost`]'s weights: CPU time of the pixel loop against the ray counts, one
/// thread, over the shipped scenes × curves × shadows × path length × light/material candidates. Writes CSV to
/// `target/tmp/cost_calibration.csv` (the test target's temporary directory) and checks nothing.
/// `cargo test --release --test quality calibrate_cost_model -- --ignored`
#[test]
#[ignore = "a measurement (minutes), not a check: its output calibrated quality::cost"]
fn calibrate_cost_model() {
    use std::fmt::Write as _;
    let pool = thread_pool(Some(1)).unwrap();
    let mut csv = String::from(
        "scene,curves,shadows,path,light,material,spp,camera,shadow,material_rays,map_lookups,cpu_seconds\n",
    );
    for path in [
        "scenes/default.toml",
        "scenes/thesis/straight-sunset-marschner.toml",
        "scenes/thesis/cornell-box.toml",
        "scenes/thesis/straight-city-marschner.toml",
    ] {
        let mut s = common::data::load_scene(path);
        s.film.resolution = [128, 128];
        let s = s.revalidate().unwrap();
        for curves in [CurveKind::Flat, CurveKind::Round] {
            let mut spec = s.resolve().unwrap();
            spec.curves = curves;
            let frame = Frame::load(spec).unwrap();
            for shadows in [ShadowMode::Raytraced, ShadowMode::DeepOpacity] {
                for path_length in 0..4 {
                    for (l, m) in [(1, 1), (1, 4), (4, 1), (4, 4)] {
                        let mut settings = frame.settings.clone();
                        settings.shadows.mode = shadows;
                        settings.integrator.path_length = path_length;
                        settings.integrator.light_samples = l;
                        settings.integrator.material_samples = m;
                        settings.film.spp = CALIBRATION_SPP;
                        let maps = (shadows == ShadowMode::DeepOpacity)
                            .then(|| pool.install(|| frame.shadow_maps(&settings)));
                        let cpu = cuticle::sys::clock::process_cpu_seconds().unwrap();
                        let stats = pool.install(|| {
                            frame
                                .render(Request::new(&settings).maps(maps.as_ref(), 0.0))
                                .stats
                        });
                        let cpu = cuticle::sys::clock::process_cpu_seconds().unwrap() - cpu;
                        let r = stats.rays;
                        writeln!(
                            csv,
                            "{path},{},{shadows:?},{path_length},{l},{m},{CALIBRATION_SPP},{},{},{},{},{cpu:.4}",
                            curves.name(),
                            r.camera,
                            r.shadow,
                            r.material,
                            r.map_lookups
                        )
                        .unwrap();
                    }
                }
            }
        }
    }
    let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cost_calibration.csv");
    std::fs::write(&out, csv).unwrap_or_else(|e| panic!("{}: {e}", out.display()));
}

/// The pilots' renders ([`cuticle::render::render_bounces`]): one render at path length 3, cut after each vertex,
/// gives what a render at each shorter path length gives — the same pixels (to float rounding) and the same rays.
/// Opaque strands, so that the cut's last vertex (a closest-hit ray that may go on) and the short render's (a
/// visibility ray that only looks for light) see the same light.
#[test]
fn one_render_cut_after_each_vertex_equals_the_renders_at_each_path_length() {
    let s = scene(&format!(
        "[hair]\nprocedural = {{ kind = \"fur-ball\", strands = 4000 }}\nopacity = 1.0\n\
         [film]\nresolution = [24, 16]\nspp = 4\naovs = []\nreconstruction = \"importance\"\n\
         [integrator]\npath_length = 3\n{SUN}{SKY}"
    ));
    let frame = Frame::load(s.resolve().unwrap()).unwrap();
    let pool = thread_pool(Some(2)).unwrap();
    let region = cuticle::render::Region::full(24, 16);
    let cut =
        pool.install(|| cuticle::render::render_bounces(&frame, &frame.settings, None, region));
    assert_eq!(cut.pixels.len(), 4);
    for j in 0..4u32 {
        let mut settings = frame.settings.clone();
        settings.integrator.path_length = j;
        let r = pool.install(|| frame.render(Request::new(&settings).region(region)));
        assert_eq!(
            cut.rays[j as usize], r.stats.rays,
            "rays at path length {j}"
        );
        for (p, c) in cut.pixels[j as usize].iter().enumerate() {
            let (x, y) = (p % 24, p / 24);
            for ch in 0..3 {
                let want = r.image.get(x, y, ch);
                let d = (c[ch] - want).abs() / (want.abs() + 1e-3);
                assert!(
                    d < 1e-4,
                    "path {j} pixel ({x}, {y}) channel {ch}: {} against {want}",
                    c[ch]
                );
            }
        }
    }
    // The bounces matter in this scene: the cuts differ.
    let mean = |j: usize| cut.pixels[j].iter().map(|p| p.x).sum::<f32>();
    assert!(
        mean(1) > 1.01 * mean(0) && mean(2) > mean(1),
        "{} {} {}",
        mean(0),
        mean(1),
        mean(2)
    );
}

/// The relMSE an approximation adds as bias, measured from two independent renders of each choice: the mean over
/// pixels and RGB of (a₁ − e₁)(a₂ − e₂) / (ē² + 0.01), ē the exact renders' mean (unbiased whatever the noise).
fn bias_product(approx: [&cuticle::image::Image; 2], exact: [&cuticle::image::Image; 2]) -> f64 {
    let c = |img: &cuticle::image::Image, name: &str| img.channel_index(name).unwrap();
    let stride = approx[0].channels.len();
    let (mut sum, mut n) = (0.0f64, 0usize);
    for p in 0..approx[0].width * approx[0].height {
        for ch in ["R", "G", "B"] {
            let v = |img: &cuticle::image::Image| f64::from(img.data[p * stride + c(img, ch)]);
            let e = 0.5 * (v(exact[0]) + v(exact[1]));
            sum += (v(approx[0]) - v(exact[0])) * (v(approx[1]) - v(exact[1])) / (e * e + 0.01);
            n += 1;
        }
    }
    sum / n as f64
}

/// Renders `settings` at a fixed `spp` with two seeds (with `maps` in deep-opacity mode).
fn two_seeds(
    frame: &Frame,
    settings: &cuticle::render::RenderSettings,
    maps: Option<&cuticle::shadow::ShadowMaps>,
    spp: u32,
) -> [cuticle::image::Image; 2] {
    let pool = thread_pool(Some(2)).unwrap();
    [71, 72].map(|seed| {
        let mut s = settings.clone();
        s.film.spp = spp;
        s.film.seed = seed;
        s.adaptive = None;
        pool.install(|| frame.render(Request::new(&s).maps(maps, 0.0)).image)
    })
}

fn flat_frame(s: &Scene) -> Frame {
    let mut spec = s.resolve().unwrap();
    spec.curves = CurveKind::Flat;
    Frame::load(spec).unwrap()
}

/// A sparse wavy patch (3 000 strands 0.09 px wide at 64²) of Kajiya-Kay hair under a sun: every approximation
/// auto may choose applies, with a bias the pilots can resolve.
fn sparse_patch() -> Scene {
    scene(&format!(
        "[hair]\nprocedural = {{ kind = \"wavy-patch\", seed = 4242, strands = 3000, fiber_radius = 0.003, \
         wave_amplitude = 0.1 }}\n[film]\nresolution = [64, 64]\n[material]\nmodel = \"kajiya-kay\"\n{SUN}"
    ))
}

#[test]
fn auto_keeps_an_approximation_only_with_its_measured_bias_and_drops_it_for_a_tight_target() {
    let frame = flat_frame(&sparse_patch());
    let pool = thread_pool(Some(2)).unwrap();
    let plan = |target: f32| {
        let q = QualityConfig {
            target,
            ..QualityConfig::default()
        };
        pool.install(|| quality::plan_frame(&frame, &frame.settings, &q, Fixed::default()))
    };
    // A loose target: ribbons and maps kept, each with its bias, and the noise budget pays for them. (At 0.2 the
    // 64² frame is too cheap for maps: rays cost less than the noise the maps' bias takes from the budget.)
    let loose = plan(0.25);
    let why: Vec<String> = loose.decisions.iter().map(ToString::to_string).collect();
    assert!(loose.frame.is_none(), "{why:#?}");
    assert_eq!(
        loose.settings.shadows.mode,
        ShadowMode::DeepOpacity,
        "{why:#?}"
    );
    let approx = &loose.pilot.approximations;
    assert_eq!(approx.len(), 2, "{approx:#?}");
    assert!(
        approx.iter().all(|a| a.bias > 0.0 && a.bias >= a.point),
        "{approx:#?}"
    );
    let left = loose.pilot.bias_left.unwrap();
    let spent: f64 = loose.pilot.noise_budget.powi(2)
        + left * left
        + approx.iter().map(|a| a.bias * a.bias).sum::<f64>();
    let target2 = f64::from(0.25f32).powi(2);
    assert!(
        (spent - target2).abs() < 1e-9,
        "noise² + bias² = {spent}, target² {target2}"
    );
    // The frame's estimate of its error carries the approximations' bias.
    let said = delivered(&loose.pilot, 0.25, None);
    assert!((said.bias.unwrap().powi(2) - (spent - loose.pilot.noise_budget.powi(2))).abs() < 1e-9);
    assert!(said.line().contains("2 approx."), "{}", said.line());
    // The maps' bias the pilots measured (point estimate) against two independent 64-spp renders of the whole
    // film with the maps kept and with ray-traced shadows, at the pilots' path length.
    let mut with_maps = loose.settings.clone();
    with_maps.integrator.path_length = 3;
    let mut rays = with_maps.clone();
    rays.shadows.mode = ShadowMode::Raytraced;
    let m = two_seeds(&frame, &with_maps, loose.maps.as_ref(), 64);
    let r = two_seeds(&frame, &rays, None, 64);
    let measured = bias_product([&m[0], &m[1]], [&r[0], &r[1]]).max(0.0).sqrt();
    let maps = approx
        .iter()
        .find(|a| a.what.starts_with("deep opacity"))
        .unwrap();
    assert!(
        (0.5..2.0).contains(&(maps.point / measured)),
        "the pilots' maps bias {} against {measured} measured",
        maps.point
    );
    // A tight target: neither approximation fits the bias budget; tubes and ray-traced shadows, nothing to pay.
    let tight = plan(0.05);
    let why: Vec<String> = tight.decisions.iter().map(ToString::to_string).collect();
    assert_eq!(
        tight.frame.as_ref().map(|f| f.curves),
        Some(CurveKind::Round),
        "{why:#?}"
    );
    assert_eq!(
        tight.settings.shadows.mode,
        ShadowMode::Raytraced,
        "{why:#?}"
    );
    assert!(tight.maps.is_none() && tight.pilot.approximations.is_empty());
    // What the user fixes is not measured.
    let fixed = pool.install(|| {
        quality::plan_frame(
            &frame,
            &frame.settings,
            &QualityConfig {
                target: 0.05,
                ..QualityConfig::default()
            },
            Fixed {
                curves: true,
                ..Fixed::default()
            },
        )
    });
    assert!(fixed.frame.is_none());
    assert!(!fixed.decisions.iter().any(|d| d.key == "hair.curves"));
}

#[test]
fn ribbons_that_the_pilots_measure_too_biased_for_the_target_are_replaced_by_tubes() {
    // A Chiang patch whose strands are 0.2 px wide: the rule takes ribbons (under a pixel a pixel averages all of
    // h), but their image differs from the tubes' by far more than 0.1 relative RMSE.
    let s = scene(&format!(
        "[hair]\nprocedural = {{ kind = \"wavy-patch\", seed = 825510, strands = 4106, fiber_radius = 0.007, \
         wave_amplitude = 0.101 }}\nopacity = 0.68\n[camera]\nmargin = 1.022\nview = [-0.808, 0.1394, -0.5725]\n\
         [film]\nresolution = [64, 64]\n[material]\nmodel = \"chiang\"\ncolor = [0.371, 0.3251, 0.2641]\n\
         [environment]\nradiance = [0.8, 0.8, 0.8]\n{SUN}"
    ));
    let (kind, why) = curves_for(&s);
    assert_eq!(kind, CurveKind::Flat, "{why}");
    let frame = flat_frame(&s);
    let pool = thread_pool(Some(2)).unwrap();
    let q = QualityConfig {
        target: 0.1,
        ..QualityConfig::default()
    };
    let planned =
        pool.install(|| quality::plan_frame(&frame, &frame.settings, &q, Fixed::default()));
    let why: Vec<String> = planned.decisions.iter().map(ToString::to_string).collect();
    let tubes = planned.frame.as_ref().expect("tubes");
    assert_eq!(tubes.curves, CurveKind::Round, "{why:#?}");
    // The decision is right: two independent 64-spp renders of each geometry at path 3 put the ribbons' bias over
    // the whole bias budget of the approximations (half of target²), and their noise alone does not.
    let mut settings = planned.settings.clone();
    settings.integrator.path_length = 3;
    let f = two_seeds(&frame, &settings, None, 64);
    let r = two_seeds(tubes, &settings, None, 64);
    let bias2 = bias_product([&f[0], &f[1]], [&r[0], &r[1]]);
    let null = bias_product([&f[0], &r[0]], [&f[1], &r[1]]);
    assert!(bias2 > 0.5 * 0.01, "ribbons' bias² {bias2}");
    assert!(
        null.abs() < 0.5 * bias2,
        "noise's product {null} against the bias² {bias2}"
    );
}

/// Auto builds no maps and no second tracer that the memory limit cannot hold beside the frame: with no room left
/// past the frame's own estimate, the rule's maps give way to ray-traced shadows and the ribbons stand unmeasured,
/// each decision saying why. (Finer maps and the tubes' tracer were outside the estimate the frame was admitted
/// by.)
#[test]
fn auto_builds_nothing_the_memory_limit_cannot_hold() {
    let pool = thread_pool(Some(2)).unwrap();
    let q = QualityConfig {
        target: 0.25,
        ..QualityConfig::default()
    };
    let planned = |room: u64| {
        pool.install(|| {
            let mut spec = sparse_patch().resolve().unwrap();
            spec.curves = CurveKind::Flat;
            let estimate =
                cuticle::render::budget::estimate_frame(&spec, rayon::current_num_threads(), true)
                    .unwrap();
            let frame =
                Frame::load_adjusted(spec, estimate.total() + room, "test", true, |_, _| {})
                    .unwrap();
            let p = quality::plan_frame(&frame, &frame.settings, &q, Fixed::default());
            let why: Vec<String> = p.decisions.iter().map(ToString::to_string).collect();
            (p.settings.shadows.mode, p.frame.is_some(), why.join("\n"))
        })
    };
    // Room for everything: the loose target keeps the ribbons (measured against tubes) and maps.
    let (mode, tubes, why) = planned(1 << 30);
    assert_eq!(mode, ShadowMode::DeepOpacity, "{why}");
    assert!(!tubes && why.contains("ribbons against tubes"), "{why}");
    // No room: nothing is built.
    let (mode, tubes, why) = planned(0);
    assert_eq!(mode, ShadowMode::Raytraced, "{why}");
    assert!(!tubes, "{why}");
    assert!(
        why.contains("do not fit the memory limit beside the frame (0 bytes left)"),
        "{why}"
    );
    assert!(
        why.contains("tubes not measured against the ribbons: their tracer"),
        "{why}"
    );
}

/// Blond Chiang straight hair under the city map (`scenes/study/straight-city.toml`, opaque strands), 96×128: auto
/// measures dual scattering against path tracing to every bounce on its pilots and keeps it where its bias fits the
/// target's share for approximations and its frame is predicted cheaper (a loose target, 0.3: measured bias 0.13,
/// frame 0.22 against 1.26 CPU s), and path tracing where the bias does not fit (0.1); the decision names its
/// numbers, and a dual frame gets no path length search and no tail.
#[test]
fn auto_chooses_dual_scattering_where_its_bias_fits_and_it_is_cheaper() {
    let frame = auto_frame(&format!(
        "[hair]\nfile = {:?}\nopacity = 1.0\n[camera]\nfov = 35.0\nup = [0.0, 0.0, 1.0]\n\
         view = [0.0, 1.0, 0.0]\n[film]\nresolution = [96, 128]\n[material]\nmodel = \"chiang\"\n\
         color = [0.85, 0.65, 0.4]\n[environment]\nmap = {:?}\nup = [0.0, 0.0, 1.0]\n",
        common::data::file("hair/straight.hair"),
        common::data::file("envmaps/city.exr"),
    ));
    for (target, dual) in [(0.3f32, true), (0.1, false)] {
        let (p, why) = plan_at(&frame, target);
        let decision = why
            .iter()
            .find(|d| d.contains("integrator.multiple_scattering"))
            .unwrap_or_else(|| panic!("no multiple-scattering decision: {why:#?}"));
        assert!(decision.contains("dual's bias"), "{decision}");
        assert_eq!(
            p.settings.integrator.dual(),
            dual,
            "target {target}: {why:#?}"
        );
        if dual {
            assert_eq!(p.settings.integrator.tail, 0.0, "{why:#?}");
            assert!(
                !why.iter().any(|d| d.contains("integrator.path_length =")),
                "{why:#?}"
            );
        }
    }
}

/// Where auto keeps deep opacity maps for the shadows, dual scattering reads its strand counts from them: a blond
/// fur ball lit by a sun alone at 96², target 0.3, keeps the maps (bias 0.019 measured) and dual scattering (bias
/// 0.092), and the maps it hands to the render count strands (a lookup inside the fur finds strands ahead and
/// behind).
#[test]
fn auto_with_deep_opacity_maps_gives_dual_scattering_counting_maps() {
    let frame = auto_frame(
        "[hair]\nprocedural = { kind = \"fur-ball\", strands = 6000 }\nopacity = 1.0\n[film]\n\
         resolution = [96, 96]\n[material]\nmodel = \"chiang\"\ncolor = [0.85, 0.65, 0.4]\n[[light]]\n\
         kind = \"distant\"\ndirection = [0.3, -1.0, -1.0]\nirradiance = 3.0\n[shadows]\nmode = \"deep-opacity\"\n",
    );
    let (p, why) = plan_at(&frame, 0.3);
    assert_eq!(p.settings.shadows.mode, ShadowMode::DeepOpacity, "{why:#?}");
    assert!(p.settings.integrator.dual(), "{why:#?}");
    let maps = p.maps.as_ref().expect("the maps auto kept");
    let to_sun = -glam::Vec3::new(0.3, -1.0, -1.0).normalize();
    let (lo, hi) = frame.strands.bounds();
    // Half way out from the centre across the sun's direction: inside the fur, off the radial strands that point
    // at the sun (which project to dots).
    let across = to_sun.cross(glam::Vec3::X).normalize();
    let p = 0.5 * (lo + hi) + across * 0.25 * (hi - lo).length();
    let [ahead, behind, direct] = maps.strands(0, p, to_sun).expect("maps that count strands");
    assert!(
        ahead > 0.0 && behind > 0.0 && direct < 1.0,
        "{ahead} {behind} {direct}"
    );
}

/// The frame of scene `text` with `--quality auto`.
fn auto_frame(text: &str) -> Frame {
    let mut s = Scene::parse(text, Path::new("<test>"), Path::new(".")).unwrap();
    s.quality.mode = cuticle::quality::QualityMode::Auto;
    Frame::load(s.resolve().unwrap()).unwrap()
}

/// Auto's plan of `frame` for `target` on 2 threads, with its decisions as printed.
fn plan_at(frame: &Frame, target: f32) -> (quality::Planned, Vec<String>) {
    let q = QualityConfig {
        target,
        ..QualityConfig::default()
    };
    let pool = thread_pool(Some(2)).unwrap();
    let p = pool.install(|| quality::plan_frame(frame, &frame.settings, &q, Fixed::default()));
    let why = p.decisions.iter().map(ToString::to_string).collect();
    (p, why)
}

/// Where the pilots' 4-spp bound keeps ribbons out but a confirmation (4× the samples on a quarter of the windows)
/// may show them harmless at less than it saves, auto renders it and keeps the ribbons, and the bound it keeps holds
/// against two 64-spp renders of the whole film per geometry: the default scene (Marschner, strands a fifth of a
/// pixel wide) at 192², target 0.07.
#[test]
fn a_confirmation_with_more_samples_keeps_ribbons_within_the_bias_it_bounds() {
    let text = std::fs::read_to_string("scenes/default.toml")
        .unwrap()
        .replace("resolution = [640, 480]", "resolution = [192, 192]");
    let s = scene(&text);
    let (kind, why) = curves_for(&s);
    assert_eq!(kind, CurveKind::Flat, "{why}");
    let frame = flat_frame(&s);
    let (planned, why) = plan_at(&frame, 0.07);
    let curves = why
        .iter()
        .find(|d| d.contains("hair.curves"))
        .expect("a curve decision");
    assert!(
        planned.frame.is_none() && curves.contains("4 spp on") && curves.contains("16 spp on"),
        "{why:#?}"
    );
    let ribbons = planned
        .pilot
        .approximations
        .iter()
        .find(|a| a.what == "ribbons for tubes")
        .expect("the ribbons' bias is paid for");
    let tubes = frame.with_curves(CurveKind::Round).unwrap();
    let mut settings = planned.settings.clone();
    settings.integrator.path_length = 3;
    settings.film.reconstruction = cuticle::render::Reconstruction::Importance;
    let f = two_seeds(&frame, &settings, None, 64);
    let r = two_seeds(&tubes, &settings, None, 64);
    let measured = bias_product([&f[0], &f[1]], [&r[0], &r[1]]).max(0.0).sqrt();
    eprintln!(
        "ribbons' bias: kept {} (point {}), measured {measured}",
        ribbons.bias, ribbons.point
    );
    assert!(
        measured <= ribbons.bias,
        "the ribbons' bias measured {measured} over the bound kept {}",
        ribbons.bias
    );
}
