//! `cuticle study stress [SCENE]`: adversarial cases rendered with every method
//! (`kajiya-kay`, `marschner`, `ishair`, `chiang`, each with its paper defaults plus the keys a case changes), each
//! case and method against its own converged reference (the same case and method at the study's reference spp), so
//! the error is the method's noise and instability, not the case's difference from the scene.
//!
//! The cases are scene-key overrides built from the scene file ([`cases`]); a case the scene cannot express is
//! skipped and the report says why:
//!
//! | case | what changes |
//! |---|---|
//! | `control` | nothing (the scene at the study's spp) |
//! | `grazing` | the camera auto-framed looking straight down (−y, the direction most strands hang or, on the fur ball's top, grow): views along the strands, θ → ±90° |
//! | `narrow-lobes` | β = 0.5° (marschner `beta_1`/`beta_2`, ishair `beta_r`/`beta_tt`/`beta_trt`); chiang `beta_m` = `beta_n` = 0.012 (a longitudinal spread of ≈ 0.5°); kajiya-kay `exponent` = 10⁴, the largest allowed |
//! | `wide-lobes` | β = 60°; chiang `beta_m` = `beta_n` = 1; kajiya-kay `exponent` = 1 |
//! | `sun-32000` | a sun added: a distant disk of angular radius 0.27° and radiance 32,000 (the `city` map's clamped sun) |
//! | `thin-strands` | `hair.radius_scale` × 0.02: strands far thinner than a pixel |
//! | `1-spp` | one sample per pixel (its reference is the control's) |
//! | `light-inside` | a small sphere light (radius 1 % of the ball's, radiance 2,000) among the strands in front of the fur ball; procedural `fur-ball` only |
//! | `scale-1e-3`, `scale-1e3` | the fur ball's `sphere_radius`, `length`, `fiber_radius`, every positioned light and any camera position scaled by 10⁻³ / 10³ (the image should not change: its reference's mean is compared with the control's); procedural `fur-ball` only, no `[[shape]]` |
//!
//! Written beside the framework's files (`stress.csv`: one row per case, method and seed, `settings` naming the case;
//! `stress-summary.csv`; bar charts per case and method, `stress-rmse` and `stress-time`; crops): `stress.md`, a table per case and method of NaN/Inf pixels, fireflies,
//! RMSE, relMSE and the mean's difference, then every **failure**: a method with any NaN/Inf pixel or with more
//! than [`FIREFLY_FAIL_FRACTION`] of its pixels fireflies (mean over seeds), or a scale case whose reference mean is
//! more than [`SCALE_FAIL`] from the control's, named with its numbers. The failure lines are also the kind's
//! read-outs (`stress-readouts.txt`, the `all` report's headline table), or one line saying there are none.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::cache::write_text;
use super::framework::{
    run_kind, Budget, Kind, KindReport, Overrides, Reference, StudyConfig, Variant,
};
use super::{SceneFile, StudyError};
use crate::image;
use crate::measure::pixels;

/// The methods every case is rendered with.
pub const METHODS: [&str; 4] = ["kajiya-kay", "marschner", "ishair", "chiang"];
/// A method fails a case with more than this fraction of its pixels fireflies (mean over seeds).
pub const FIREFLY_FAIL_FRACTION: f64 = 0.01;
/// A scale case fails when its reference's mean luminance differs from the control's by more than this fraction.
pub const SCALE_FAIL: f64 = 0.05;
/// Samples per pixel of the cases (full runs; `--quick`: 4).
pub const SPP: u32 = 8;
/// Side of the centred window the cases render (full runs), pixels: 7–10 cases × 4 methods each with its own
/// reference must fit the 20 minutes of `study all` (see [`super::kinds`], "Budgets").
pub const CROP: u32 = 48;
/// Samples per pixel of the cases' references (full runs): [`super::kinds::REFERENCE_FACTOR`] × [`SPP`].
pub const REFERENCE_SPP: u32 = super::kinds::REFERENCE_FACTOR * SPP;
/// The scales of the `scale-*` cases.
const SCALES: [(f64, &str); 2] = [(1e-3, "scale-1e-3"), (1e3, "scale-1e3")];

/// One adversarial case.
#[derive(Debug, Clone, PartialEq)]
pub struct Case {
    /// Its name (the CSV's `settings`).
    pub name: String,
    /// What it changes, one line.
    pub what: String,
    /// Scene keys it changes for every method.
    pub overrides: Overrides,
    /// The samples per pixel of its renders (the reference's are the study's).
    pub spp: u32,
    /// Scales the scene by this factor (the reference's mean is checked against the control's).
    pub scale: Option<f64>,
}

/// A case the scene cannot express.
#[derive(Debug, Clone, PartialEq)]
pub struct Skipped {
    /// The case.
    pub case: String,
    /// Why.
    pub reason: String,
}

/// What [`run`] measured and wrote.
#[derive(Debug, Clone)]
pub struct StressReport {
    /// The framework's report (variants in case-major, [`METHODS`] order).
    pub report: KindReport,
    /// The cases rendered.
    pub cases: Vec<Case>,
    /// The cases skipped.
    pub skipped: Vec<Skipped>,
    /// The failure lines (also the report's read-outs; without any, the read-out says so).
    pub failures: Vec<String>,
    /// `stress.md`.
    pub markdown: PathBuf,
}

fn float(v: f64) -> toml::Value {
    toml::Value::Float(v)
}

fn key(k: &str, v: toml::Value) -> (String, toml::Value) {
    (k.to_owned(), v)
}

fn vec3(v: [f64; 3]) -> toml::Value {
    toml::Value::Array(v.iter().map(|&x| float(x)).collect())
}

fn number(v: Option<&toml::Value>) -> Option<f64> {
    v.and_then(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64)))
}

/// `v` (a number or an array of numbers) times `s`.
fn scaled(v: &toml::Value, s: f64) -> toml::Value {
    match v {
        toml::Value::Array(a) => toml::Value::Array(a.iter().map(|x| scaled(x, s)).collect()),
        other => number(Some(other)).map_or_else(|| other.clone(), |x| float(x * s)),
    }
}

/// The `[material]` table of `model` for `case` (paper defaults plus the case's lobe widths).
fn material(model: &str, case: &str) -> toml::Value {
    let mut t = toml::Table::new();
    t.insert("model".into(), toml::Value::String(model.into()));
    let widths: &[&str] = match model {
        "marschner" => &["beta_1", "beta_2"],
        "ishair" => &["beta_r", "beta_tt", "beta_trt"],
        "chiang" => &["beta_m", "beta_n"],
        _ => &["exponent"],
    };
    let value = match (model, case) {
        ("chiang", "narrow-lobes") => Some(0.012),
        ("chiang", "wide-lobes") => Some(1.0),
        ("kajiya-kay", "narrow-lobes") => Some(f64::from(crate::scene::material::MAX_KK_EXPONENT)),
        ("kajiya-kay", "wide-lobes") => Some(1.0),
        (_, "narrow-lobes") => Some(0.5),
        (_, "wide-lobes") => Some(60.0),
        _ => None,
    };
    if let Some(v) = value {
        for w in widths {
            t.insert((*w).into(), float(v));
        }
    }
    toml::Value::Table(t)
}

/// The scene's procedural fur ball table, if its hair is one.
fn fur_ball(base: &toml::Table) -> Option<&toml::Table> {
    let hair = base.get("hair")?.as_table()?;
    if hair.contains_key("file") {
        return None;
    }
    let p = hair.get("procedural")?.as_table()?;
    (p.get("kind")?.as_str()? == "fur-ball").then_some(p)
}

/// The scene's `[[light]]` array (empty if none).
fn lights(base: &toml::Table) -> Vec<toml::Value> {
    base.get("light")
        .and_then(|l| l.as_array())
        .cloned()
        .unwrap_or_default()
}

/// The cases `base` (a scene file's table) can express, in order, and the ones it cannot.
pub fn cases(base: &toml::Table, quick: bool) -> (Vec<Case>, Vec<Skipped>) {
    // One piece: a flat list of the cases, each a name, what it tests and its overrides, in the report's order.
    let spp = if quick { 4 } else { SPP };
    let mut cases = Vec::new();
    let mut skipped = Vec::new();
    let mut case = |name: &str, what: &str, overrides: Overrides| {
        cases.push(Case {
            name: name.into(),
            what: what.into(),
            overrides,
            spp,
            scale: None,
        })
    };
    case("control", "the scene as it is", Vec::new());

    let mut camera = base
        .get("camera")
        .and_then(|c| c.as_table())
        .cloned()
        .unwrap_or_default();
    camera.remove("position");
    camera.remove("look_at");
    camera.insert("view".into(), vec3([0.0, -1.0, 0.0]));
    camera.insert("up".into(), vec3([0.0, 0.0, -1.0]));
    case(
        "grazing",
        "camera auto-framed looking straight down (−y): views along the strands",
        vec![key("camera", toml::Value::Table(camera))],
    );
    case(
        "narrow-lobes",
        "lobe widths β = 0.5° (chiang β = 0.012, kajiya-kay exponent 10⁴)",
        Vec::new(),
    );
    case(
        "wide-lobes",
        "lobe widths β = 60° (chiang β = 1, kajiya-kay exponent 1)",
        Vec::new(),
    );

    let angular_radius = 0.27f64;
    let mut sun = toml::Table::new();
    sun.insert("kind".into(), toml::Value::String("distant".into()));
    sun.insert("direction".into(), vec3([-0.5, -1.0, -0.4]));
    sun.insert("angular_radius".into(), float(angular_radius));
    // Irradiance of a disk of radiance L and angular radius r: L π sin² r.
    let irradiance = 32_000.0 * std::f64::consts::PI * angular_radius.to_radians().sin().powi(2);
    sun.insert("irradiance".into(), float(irradiance));
    let mut with_sun = lights(base);
    with_sun.push(toml::Value::Table(sun));
    case(
        "sun-32000",
        "a sun of radiance 32,000, angular radius 0.27°, added to the scene's lights",
        vec![key("light", toml::Value::Array(with_sun))],
    );

    let radius_scale = base
        .get("hair")
        .and_then(|h| number(h.get("radius_scale")))
        .unwrap_or(1.0);
    case(
        "thin-strands",
        "hair.radius_scale × 0.02: strands far thinner than a pixel",
        vec![key("hair.radius_scale", float(radius_scale * 0.02))],
    );
    cases.push(Case {
        name: "1-spp".into(),
        what: "one sample per pixel".into(),
        overrides: Vec::new(),
        spp: 1,
        scale: None,
    });

    let ball = fur_ball(base);
    let r = ball
        .and_then(|b| number(b.get("sphere_radius")))
        .unwrap_or(1.0);
    let len = ball.and_then(|b| number(b.get("length"))).unwrap_or(0.5);
    let fibre = ball
        .and_then(|b| number(b.get("fiber_radius")))
        .unwrap_or(0.004);
    match ball {
        Some(_) => {
            let mut light = toml::Table::new();
            light.insert("kind".into(), toml::Value::String("sphere".into()));
            light.insert("center".into(), vec3([0.0, 0.0, r + 0.4 * len]));
            light.insert("radius".into(), float(0.01 * r));
            light.insert("radiance".into(), float(2000.0));
            let mut all = lights(base);
            all.push(toml::Value::Table(light));
            cases.push(Case {
                name: "light-inside".into(),
                what: "a sphere light (radius 1 % of the ball's, radiance 2,000) among the strands".into(),
                overrides: vec![key("light", toml::Value::Array(all))],
                spp,
                scale: None,
            });
        }
        None => skipped.push(Skipped {
            case: "light-inside".into(),
            reason: "the hair is not a procedural fur-ball, so where the strands are is not known from the scene file"
                .into(),
        }),
    }

    let shapes = base.contains_key("shape");
    for (s, name) in SCALES {
        if ball.is_none() || shapes {
            skipped.push(Skipped {
                case: name.into(),
                reason: if shapes {
                    "the scene has [[shape]]s, which have no scale key".into()
                } else {
                    "no scene-scale key: only a procedural fur-ball's sizes can be scaled (hair files have radius_scale only)"
                        .into()
                },
            });
            continue;
        }
        let mut ball = ball.cloned().unwrap_or_default();
        ball.insert("sphere_radius".into(), float(r * s));
        ball.insert("length".into(), float(len * s));
        ball.insert("fiber_radius".into(), float(fibre * s));
        let mut overrides = vec![key("hair.procedural", toml::Value::Table(ball))];
        let lights: Vec<toml::Value> = lights(base)
            .into_iter()
            .map(|l| match l {
                toml::Value::Table(mut t) => {
                    for k in ["center", "corner", "edge_u", "edge_v", "radius"] {
                        if let Some(v) = t.get(k).map(|v| scaled(v, s)) {
                            t.insert(k.into(), v);
                        }
                    }
                    toml::Value::Table(t)
                }
                other => other,
            })
            .collect();
        if !lights.is_empty() {
            overrides.push(key("light", toml::Value::Array(lights)));
        }
        if let Some(c) = base.get("camera").and_then(|c| c.as_table()) {
            let mut c = c.clone();
            for k in ["position", "look_at"] {
                if let Some(v) = c.get(k).map(|v| scaled(v, s)) {
                    c.insert(k.into(), v);
                }
            }
            overrides.push(key("camera", toml::Value::Table(c)));
        }
        cases.push(Case {
            name: name.into(),
            what: format!("the fur ball, its positioned lights and camera scaled by {s:e}"),
            overrides,
            spp,
            scale: Some(s),
        });
    }
    (cases, skipped)
}

/// The [`Kind`] of `cases`: one reference and one variant per case and method (case-major, [`METHODS`] order).
pub fn kind(cases: &[Case], quick: bool) -> Kind {
    let mut references = Vec::new();
    let mut variants = Vec::new();
    for (c, case) in cases.iter().enumerate() {
        for model in METHODS {
            let mut overrides = case.overrides.clone();
            overrides.push(key("material", material(model, &case.name)));
            references.push(Reference {
                label: format!("{model}, {}", case.name),
                overrides: overrides.clone(),
            });
            overrides.push(key("film.spp", toml::Value::Integer(i64::from(case.spp))));
            variants.push(Variant {
                series: model.into(),
                method: model.into(),
                settings: case.name.clone(),
                x: (c + 1) as f64,
                overrides,
                reference: references.len() - 1,
            });
        }
    }
    Kind {
        name: "stress".into(),
        title: "adversarial cases per method: NaN/Inf, fireflies and error against each case's reference".into(),
        x_label: "case".into(),
        time_includes_setup: false,
        references,
        variants,
        compare: Vec::new(),
        bias_readout: false,
        equal_setting: false,
        budget: if quick {
            Budget::default()
        } else {
            Budget {
                crop: Some(CROP),
                reference_spp: Some(REFERENCE_SPP),
            }
        },
        differences: Vec::new(),
        categories: cases.iter().map(|c| c.name.clone()).collect(),
    }
}

/// Mean luminance of the finite pixels of the image at `path`.
fn mean_luminance(path: &Path) -> Result<f64, StudyError> {
    let y = pixels::luminance(&image::read(path)?).map_err(StudyError::Config)?;
    let finite: Vec<f64> = y.into_iter().filter(|v| v.is_finite()).collect();
    Ok(finite.iter().sum::<f64>() / finite.len().max(1) as f64)
}

/// Runs the stress cases on `scene` (a scene file or the default scene) and writes `stress.md` (see the module
/// docs).
pub fn run(scene: &SceneFile, config: &StudyConfig) -> Result<StressReport, StudyError> {
    // One piece: render the cases, judge each method's summaries, then write the report from the same summaries.
    let base = scene.table()?;
    let (cases, skipped) = cases(&base, config.quick);
    let kind = kind(&cases, config.quick);
    let mut report = run_kind(scene, &kind, config)?;
    let [w, h] = report.resolution;
    let pixels = f64::from(w) * f64::from(h);

    let mut failures = Vec::new();
    for s in &report.summaries {
        let v = &kind.variants[s.variant];
        let fraction = s.fireflies.mean / pixels;
        if s.non_finite > 0 || fraction > FIREFLY_FAIL_FRACTION {
            failures.push(format!(
                "{} fails {}: {} NaN/Inf pixels over {} seeds, {:.1} fireflies ({:.2} % of pixels), RMSE {:.3e}, relMSE {:.3e}",
                v.method,
                v.settings,
                s.non_finite,
                s.seeds,
                s.fireflies.mean,
                100.0 * fraction,
                s.rmse.mean,
                s.relmse.mean
            ));
        }
    }
    // Scale invariance: each scale case's reference against the control's, per method.
    let mut scale_rows = Vec::new();
    for (c, case) in cases.iter().enumerate() {
        let Some(scale) = case.scale else { continue };
        for (m, model) in METHODS.iter().enumerate() {
            let control = mean_luminance(&report.references[m].path)?;
            let scaled = mean_luminance(&report.references[c * METHODS.len() + m].path)?;
            let diff = if control > 0.0 {
                (scaled - control) / control
            } else {
                0.0
            };
            if diff.is_nan() || diff.abs() > SCALE_FAIL {
                failures.push(format!(
                    "{model} fails {}: the reference's mean luminance is {scaled:.4e}, the control's {control:.4e} \
                     ({:+.1} %) at scale {scale:e}",
                    case.name,
                    100.0 * diff
                ));
            }
            scale_rows.push((case.name.clone(), *model, scaled, control, diff));
        }
    }
    report.readouts = if failures.is_empty() {
        vec![format!(
            "no failures: no NaN/Inf pixel and fireflies on at most {:.0} % of the pixels in every case and method{}",
            100.0 * FIREFLY_FAIL_FRACTION,
            if scale_rows.is_empty() {
                String::new()
            } else {
                format!(
                    ", the scaled scenes' reference means within {:.0} % of the control's",
                    100.0 * SCALE_FAIL
                )
            }
        )]
    } else {
        failures.clone()
    };
    let readouts_path = config.out_dir.join("stress-readouts.txt");
    write_text(&readouts_path, &(report.readouts.join("\n") + "\n"))?;

    let mut md = String::new();
    let _ = writeln!(md, "# cuticle study stress: {scene}\n");
    let _ = writeln!(
        md,
        "{w}×{h}, {} seeds per point, references at {} spp (each case and method against its own reference). \
         Fails: any NaN/Inf pixel, or fireflies above {:.0} % of the pixels (mean over seeds), or a scale case's \
         reference mean more than {:.0} % from the control's. Every number is in `stress.csv` / \
         `stress-summary.csv`.\n",
        config.seeds,
        report.reference_spp,
        100.0 * FIREFLY_FAIL_FRACTION,
        100.0 * SCALE_FAIL
    );
    let _ = writeln!(md, "## Failures\n");
    if failures.is_empty() {
        let _ = writeln!(md, "None.");
    }
    for f in &failures {
        let _ = writeln!(md, "- {f}");
    }
    let _ = writeln!(md, "\n## Cases\n\n| case | spp | what |\n|---|---|---|");
    for c in &cases {
        let _ = writeln!(md, "| {} | {} | {} |", c.name, c.spp, c.what);
    }
    for s in &skipped {
        let _ = writeln!(md, "| {} | — | skipped: {} |", s.case, s.reason);
    }
    let _ = writeln!(
        md,
        "\n## Per case and method\n\n| case | method | NaN/Inf | fireflies | RMSE | relMSE | mean diff | render s |\n\
         |---|---|---|---|---|---|---|---|"
    );
    for s in &report.summaries {
        let v = &kind.variants[s.variant];
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.1} | {:.3e} | {:.3e} | {:+.2} % | {:.3} |",
            v.settings,
            v.method,
            s.non_finite,
            s.fireflies.mean,
            s.rmse.mean,
            s.relmse.mean,
            100.0 * s.mean_diff.mean,
            s.render_s.mean
        );
    }
    if !scale_rows.is_empty() {
        let _ = writeln!(
            md,
            "\n## Scale invariance (reference means)\n\n| case | method | mean | control's | difference |\n|---|---|---|---|---|"
        );
        for (case, model, scaled, control, diff) in &scale_rows {
            let _ = writeln!(
                md,
                "| {case} | {model} | {scaled:.4e} | {control:.4e} | {:+.2} % |",
                100.0 * diff
            );
        }
    }
    let markdown = config.out_dir.join("stress.md");
    write_text(&markdown, &md)?;
    report.files.push(markdown.clone());
    Ok(StressReport {
        report,
        cases,
        skipped,
        failures,
        markdown,
    })
}
