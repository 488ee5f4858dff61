//! The kinds of `cuticle study` built on [`super::framework`]: each function returns the [`Kind`] —
//! references, variants, the pairs read out — for full or `--quick` runs. Materials are each model's paper
//! defaults (`[material] model = "…"` alone) plus the keys a kind varies, so results do not depend on the scene's
//! own material; everything else (hair, lights, camera, path length) is the scene's.
//!
//! # Budgets (full runs; `--quick` renders the whole tiny film at the study's reference spp)
//!
//! `cuticle study all scenes/furball.toml --res 256x256` has to finish in 20 minutes on 2 cores, and a reference
//! is only useful if its own noise is well below the sweep's errors. So each kind has a ray budget
//! ([`Budget`]): a centred crop of the study's film (same pixels, same view: [`super::framework::crop_overrides`])
//! and references of [`REFERENCE_FACTOR`] × the sweep's largest spp, not a fixed spp. Every reference is rendered
//! as two halves with other seeds, whose difference gives its RMSE against a second reference; the read-outs
//! print it beside the smallest RMSE of its variants (`<kind>-readouts.txt`).
//!
//! - spp sweeps (`sampling`, `lobes`, `hery`, `models`, `backends`, `shadows`): 1, 2, 4, 8 spp on the centred
//!   [`SWEEP_CROP`]² window (96²), references at 8 × 8 = 64 spp.
//! - [`samples`]: the sweep is over light and material samples per shading point, so everything else is made
//!   noise-free: 1 spp, the pixel filter shrunk to 0.001 px (every seed's camera ray goes through the pixel
//!   centre), `integrator.path_length = 0` (one bounce of indirect light is one sample per camera sample, a noise
//!   no light or material sample count reduces) and `hair.opacity = 1` (stochastic transparency of shadow rays
//!   adds noise of its own). Measured on the fur ball's 32² centre: at 1 spp with the scene's filter, 16 and 1024
//!   light samples had the same RMSE (0.177 and 0.177: pixel sampling dominates); with these settings 0.0155
//!   and 0.0043. The references are (2048 light, 2048 material) samples at [`SAMPLES_REFERENCE_SPP`] = 16 spp on
//!   the centred [`SAMPLES_CROP`]² = 12² window. Why so many samples: with MIS the error keeps falling as *either*
//!   count grows (the balance heuristic shifts weight to the strategy with more samples), so the sweep's last
//!   points are nearly as good as a 2048 × 2048 render. Measured on the fur ball (32² window, loaded machine):
//!   2-spp references were only 1.2–1.3× below the sweep's smallest RMSE (marschner 2.7e-3 against 3.3e-3); 16 spp
//!   has 8× the samples, so √8 ≈ 2.8× less noise. Why so few pixels: under an environment map each sample costs
//!   more; `scenes/study/straight-city.toml` on the 16² window (load 8–9 on 2 cores) took 145, 179 and 141 s per
//!   reference and 12.4 min for the kind (159 s of CPU), references 7.4× (marschner), 7.3× (ishair) and 1.4×
//!   (chiang) below the smallest RMSE of their sweep. The window's pixel count sets the cost, not the noise per
//!   pixel, so 12² (144 pixels, 0.56× the rays) is the cut, not fewer reference samples (they would have put
//!   chiang's at 1.0×). Measured at 12² in `study all` there (load 9–10): references 7.5×, 7.0× and 7.1× below
//!   (chiang's 1.4× at 16² came from pixels outside the 12² window). Costs: references 3 × 16 × 4096 samples per
//!   pixel, the sweep 3 models × 2 series × 8 counts × 3 seeds, ~8·10⁴ samples per pixel (the 64 × 64 point of
//!   both series is one render); on 144 pixels.
//! - [`curves`]: the strands' radius scaled (`hair.radius_scale` 0.5, 1, 2: their width in pixels ×0.5 to ×2)
//!   at a fixed film, 4 spp on the [`SWEEP_CROP`]² window, references at 32 spp.
//! - `stress` ([`super::stress`]): 8 spp on the centred 48² window, references at 64 spp (7–10 cases × 4 methods,
//!   each with its own reference).
//!
//! # The kinds
//!
//! - [`samples`]: the thesis' table 3 — light samples 16…2048 at 64 material samples and material samples
//!   16…2048 at 64 light samples, for `marschner`, `ishair`, `chiang`. `--quick`: 1, 2, 4 at 4.
//! - [`sampling`]: importance against uniform BSDF sampling (`material.sampling`) for `kajiya-kay`, `marschner`,
//!   `ishair` and `chiang`, material samples only (`integrator.strategy = "material"`, so the sampling strategy is
//!   what is measured) over spp; equal-time and equal-error read-outs.
//! - [`lobes`]: ISHair's lobe selection, `uniform` against `by-energy`, material samples only, over spp.
//! - [`hery`]: Marschner sampled as Hery & Ramamoorthi published it (`published`, clamp-and-flip) against the exact
//!   pdf (`importance`), material samples only, over spp, against an MIS reference: the published sampler's error
//!   levels off at its bias (`mean_diff` in the CSV is the bias of the image mean).
//! - [`models`]: `marschner` and `ishair` each against a `chiang` reference **at matched colour**: Chiang's σa
//!   chosen so that its single-fibre albedo equals that model's per channel ([`crate::measure::albedo`], which says
//!   why the albedo rather than the image mean), with that matched `chiang` itself as the control; over spp. The
//!   error that does not fall with spp is the models' difference.
//! - [`curves`]: round tubes against flat ribbons per model, each against a round reference at the same radius
//!   scale; times include set-up (the BVH differs).
//! - [`backends_with`]: Embree against the pure-Rust BVH, per curve type, the same seeds on both, so
//!   besides time (set-up included: the BVH build differs) and error the two images are compared directly
//!   ([`Kind::differences`]: `backends-differences.csv`, `backends-diff-bvh-<curves>-vs-embree-<curves>.png`).
//! - [`shadows_with`]: deep opacity maps against ray-traced shadows: no shadows, ray tracing with
//!   stochastic and with exact transmittance, maps over layers and over resolution, against a ray-traced
//!   reference with exact transmittance; the maps' build time and memory in `maps_s` and `map_mb`, the error over
//!   the shadowed pixels in `rmse_shadowed`.
//!
//! `cuticle study backends|shadows` run the same kinds with the sweep of their flags ([`BackendsSweep`],
//! [`ShadowsSweep`]) on the whole film; `all` runs them with [`BackendsSweep::for_all`] and
//! [`ShadowsSweep::for_all`] on the budget of the spp sweeps.

use super::framework::{Budget, Kind, Overrides, Reference, Variant};
use crate::bsdf::chiang::ChiangParams;
use crate::measure::albedo;
use crate::scene::MaterialConfig;

/// References render this many times the sweep's largest spp (or samples per point).
pub const REFERENCE_FACTOR: u32 = 8;
/// Side of the centred window the spp sweeps render, pixels.
pub const SWEEP_CROP: u32 = 96;
/// Side of the centred window `samples` renders, pixels.
pub const SAMPLES_CROP: u32 = 12;
/// Samples per pixel of `samples`' references (of [`SAMPLES_MAX`] light and material samples each).
pub const SAMPLES_REFERENCE_SPP: u32 = 16;
/// The most samples per shading point `samples` sweeps (the thesis' table 3).
pub const SAMPLES_MAX: u32 = 2048;

/// The budget of an spp sweep: the crop and references at [`REFERENCE_FACTOR`] × its largest spp (`--quick`: the
/// study's defaults).
pub fn sweep_budget(quick: bool) -> Budget {
    if quick {
        Budget::default()
    } else {
        Budget {
            crop: Some(SWEEP_CROP),
            reference_spp: spp_sweep(false).last().map(|s| s * REFERENCE_FACTOR),
        }
    }
}

/// Samples per pixel of the sweeps over spp.
fn spp_sweep(quick: bool) -> Vec<u32> {
    if quick {
        vec![1, 2, 4]
    } else {
        vec![1, 2, 4, 8]
    }
}

fn int(v: u32) -> toml::Value {
    toml::Value::Integer(i64::from(v))
}

fn string(v: &str) -> toml::Value {
    toml::Value::String(v.to_owned())
}

/// A `[material]` table: `model` with `extra` keys.
fn material(model: &str, extra: &[(&str, &str)]) -> (String, toml::Value) {
    let mut t = toml::Table::new();
    t.insert("model".into(), string(model));
    for (k, v) in extra {
        t.insert((*k).into(), string(v));
    }
    ("material".into(), toml::Value::Table(t))
}

fn key(k: &str, v: toml::Value) -> (String, toml::Value) {
    (k.to_owned(), v)
}

/// `samples` (see the module docs).
pub fn samples(quick: bool) -> Kind {
    let (counts, fixed, reference): (Vec<u32>, u32, u32) = if quick {
        (vec![1, 2, 4], 4, 4)
    } else {
        (
            vec![16, 32, 64, 128, 256, 512, 1024, SAMPLES_MAX],
            64,
            SAMPLES_MAX,
        )
    };
    // Noise the sample counts do not reduce, removed (see the module docs, "Budgets").
    let quiet = || {
        vec![
            key("film.filter_width", toml::Value::Float(0.001)),
            key("integrator.path_length", int(0)),
            key("hair.opacity", toml::Value::Float(1.0)),
        ]
    };
    let models = ["marschner", "ishair", "chiang"];
    let mut references = Vec::new();
    let mut variants = Vec::new();
    for (r, model) in models.iter().enumerate() {
        let mut overrides = vec![
            material(model, &[]),
            key("integrator.light_samples", int(reference)),
            key("integrator.material_samples", int(reference)),
        ];
        overrides.extend(quiet());
        references.push(Reference {
            label: format!("{model}, MIS, {reference} light × {reference} material samples"),
            overrides,
        });
        for (what, other) in [("light", "material"), ("material", "light")] {
            for &n in &counts {
                variants.push(Variant {
                    series: format!("{model} {what} samples"),
                    method: model.to_string(),
                    settings: format!("{what}_samples={n} {other}_samples={fixed}"),
                    x: f64::from(n),
                    overrides: [
                        material(model, &[]),
                        key(&format!("integrator.{what}_samples"), int(n)),
                        key(&format!("integrator.{other}_samples"), int(fixed)),
                    ]
                    .into_iter()
                    .chain(quiet())
                    .collect(),
                    reference: r,
                });
            }
        }
    }
    let compare = models
        .iter()
        .map(|m| {
            (
                format!("{m} light samples"),
                format!("{m} material samples"),
            )
        })
        .collect();
    Kind {
        name: "samples".into(),
        title: "light samples against material samples (thesis table 3, figure 17)".into(),
        x_label: "samples per shading point".into(),
        time_includes_setup: false,
        references,
        variants,
        compare,
        bias_readout: false,
        equal_setting: true,
        budget: if quick {
            Budget::default()
        } else {
            Budget {
                crop: Some(SAMPLES_CROP),
                reference_spp: Some(SAMPLES_REFERENCE_SPP),
            }
        },
        differences: Vec::new(),
        categories: Vec::new(),
    }
}

/// Variants over spp of `series` with `overrides`, material samples only.
fn spp_series(
    series: &str,
    method: &str,
    settings: &str,
    overrides: &Overrides,
    reference: usize,
    quick: bool,
) -> Vec<Variant> {
    spp_sweep(quick)
        .into_iter()
        .map(|spp| {
            let mut o = overrides.clone();
            o.push(key("integrator.strategy", string("material")));
            o.push(key("film.spp", int(spp)));
            Variant {
                series: series.to_owned(),
                method: method.to_owned(),
                settings: format!("{settings} strategy=material spp={spp}"),
                x: f64::from(spp),
                overrides: o,
                reference,
            }
        })
        .collect()
}

/// A converged reference of `model` with its exact importance sampling and MIS.
fn mis_reference(model: &str) -> Reference {
    Reference {
        label: format!("{model}, importance sampling, MIS"),
        overrides: vec![material(model, &[])],
    }
}

/// `sampling` (see the module docs).
pub fn sampling(quick: bool) -> Kind {
    let models = ["kajiya-kay", "marschner", "ishair", "chiang"];
    let mut variants = Vec::new();
    let mut compare = Vec::new();
    for (r, model) in models.iter().enumerate() {
        for mode in ["importance", "uniform"] {
            variants.extend(spp_series(
                &format!("{model} {mode}"),
                model,
                &format!("sampling={mode}"),
                &vec![material(model, &[("sampling", mode)])],
                r,
                quick,
            ));
        }
        compare.push((format!("{model} importance"), format!("{model} uniform")));
    }
    Kind {
        name: "sampling".into(),
        title: "importance against uniform BSDF sampling, material samples only".into(),
        x_label: "samples per pixel".into(),
        time_includes_setup: false,
        references: models.iter().map(|m| mis_reference(m)).collect(),
        variants,
        compare,
        bias_readout: false,
        equal_setting: true,
        budget: sweep_budget(quick),
        differences: Vec::new(),
        categories: Vec::new(),
    }
}

/// `lobes` (see the module docs).
pub fn lobes(quick: bool) -> Kind {
    let mut variants = Vec::new();
    for selection in ["uniform", "by-energy"] {
        variants.extend(spp_series(
            &format!("ishair {selection} lobes"),
            "ishair",
            &format!("selection={selection}"),
            &vec![material("ishair", &[("selection", selection)])],
            0,
            quick,
        ));
    }
    Kind {
        name: "lobes".into(),
        title: "ISHair lobe selection: uniform against by energy, material samples only".into(),
        x_label: "samples per pixel".into(),
        time_includes_setup: false,
        references: vec![mis_reference("ishair")],
        variants,
        compare: vec![(
            "ishair by-energy lobes".into(),
            "ishair uniform lobes".into(),
        )],
        bias_readout: false,
        equal_setting: true,
        budget: sweep_budget(quick),
        differences: Vec::new(),
        categories: Vec::new(),
    }
}

/// `hery` (see the module docs).
pub fn hery(quick: bool) -> Kind {
    let mut variants = Vec::new();
    for (mode, name) in [("importance", "exact"), ("published", "published")] {
        variants.extend(spp_series(
            &format!("marschner {name} sampler"),
            "marschner",
            &format!("sampling={mode}"),
            &vec![material("marschner", &[("sampling", mode)])],
            0,
            quick,
        ));
    }
    Kind {
        name: "hery".into(),
        title: "Hery & Ramamoorthi sampling: published (clamp and flip) against the exact pdf"
            .into(),
        x_label: "samples per pixel".into(),
        time_includes_setup: false,
        references: vec![mis_reference("marschner")],
        variants,
        compare: vec![(
            "marschner exact sampler".into(),
            "marschner published sampler".into(),
        )],
        bias_readout: true,
        equal_setting: true,
        budget: sweep_budget(quick),
        differences: Vec::new(),
        categories: Vec::new(),
    }
}

/// Chiang's σa whose fibre albedo matches `model`'s paper defaults ([`albedo`]), with the albedos: (σa, the
/// model's albedo, chiang's at that σa).
pub fn matched_chiang(model: &str) -> Result<([f32; 3], [f32; 3]), String> {
    let config = MaterialConfig::named(model).ok_or_else(|| format!("no model {model}"))?;
    let target = albedo::fibre_albedo(&config.build()?);
    let sigma_a = albedo::chiang_sigma_a_for_albedo(ChiangParams::default(), target)?;
    Ok((sigma_a.to_array(), target.to_array()))
}

/// A `[material]` table of `chiang` with `sigma_a`.
fn chiang_with(sigma_a: [f32; 3]) -> (String, toml::Value) {
    let mut t = toml::Table::new();
    t.insert("model".into(), string("chiang"));
    t.insert(
        "sigma_a".into(),
        toml::Value::try_from(sigma_a.map(f64::from)).expect("array"),
    );
    ("material".into(), toml::Value::Table(t))
}

/// `models` (see the module docs).
pub fn models(quick: bool) -> Result<Kind, String> {
    let mut references = Vec::new();
    let mut variants = Vec::new();
    let mut compare = Vec::new();
    for (r, model) in ["marschner", "ishair"].iter().enumerate() {
        let (sigma_a, target) = matched_chiang(model)?;
        let fmt = |v: [f32; 3]| format!("{:.3} {:.3} {:.3}", v[0], v[1], v[2]);
        references.push(Reference {
            label: format!(
                "chiang at {model}'s fibre albedo ({}; σa {})",
                fmt(target),
                fmt(sigma_a)
            ),
            overrides: vec![chiang_with(sigma_a)],
        });
        let control = format!("chiang as {model}");
        for (series, m) in [
            ((*model).to_owned(), material(model, &[])),
            (control.clone(), chiang_with(sigma_a)),
        ] {
            variants.extend(spp_sweep(quick).into_iter().map(|spp| Variant {
                series: series.clone(),
                method: series.clone(),
                settings: format!("spp={spp}"),
                x: f64::from(spp),
                overrides: vec![m.clone(), key("film.spp", int(spp))],
                reference: r,
            }));
        }
        compare.push(((*model).to_owned(), control));
    }
    Ok(Kind {
        name: "models".into(),
        title: "the thesis models against the energy-conserving chiang at matched fibre albedo"
            .into(),
        x_label: "samples per pixel".into(),
        time_includes_setup: false,
        references,
        variants,
        compare,
        bias_readout: true,
        equal_setting: true,
        budget: sweep_budget(quick),
        differences: Vec::new(),
        categories: Vec::new(),
    })
}

/// The colours of `multiple-scattering`: blond, brown and black as Chiang's eq. 9 colour (the colour of a whole
/// volume of such hair after multiple scattering).
pub const HAIR_COLOURS: [(&str, [f64; 3]); 3] = [
    ("blond", [0.85, 0.65, 0.4]),
    ("brown", [0.42, 0.26, 0.13]),
    ("black", [0.06, 0.04, 0.03]),
];

/// The path lengths `multiple-scattering` sweeps beside dual scattering, up to the longest a path length may be
/// ([`crate::render::integrator::MAX_PATH_LENGTH`], 30 bounces: 31 shading points). The reference goes on past it
/// with Russian roulette alone (`integrator.tail = 1`, up to [`crate::render::integrator::MAX_TAIL_LENGTH`]
/// bounces): light hair in a dense fur ball still gains tens of per cent between 16 and 30 bounces.
pub const MULTIPLE_SCATTERING_PATHS: [u32; 6] = [1, 2, 4, 8, 16, 30];

/// Texels along a side of the deep opacity maps `multiple-scattering`'s "dual maps" counts strands with (an
/// environment's maps take half): about two texels per pixel of its 256-pixel frames.
pub const MULTIPLE_SCATTERING_MAP_RESOLUTION: u32 = 512;

/// References of `multiple-scattering` render this many times its sweep's largest spp.
pub const MULTIPLE_SCATTERING_REFERENCE_FACTOR: u32 = 32;

/// `multiple-scattering`: path tracing at each of [`MULTIPLE_SCATTERING_PATHS`] and dual scattering in both forms
/// (layered, published; the layered form also with its counts from deep opacity maps), over spp,
/// for each of [`HAIR_COLOURS`] (Chiang's model, opaque strands, ray-traced shadows), against path tracing to
/// convergence in path length (30 bounces and a tail ended by Russian roulette alone). The bias read-out is each
/// method's remaining error at convergence. Not part of `all` (its references trace every bounce).
pub fn multiple_scattering(quick: bool) -> Kind {
    let colours: &[(&str, [f64; 3])] = if quick {
        &HAIR_COLOURS[..1]
    } else {
        &HAIR_COLOURS
    };
    let paths: &[u32] = if quick {
        &[1, 30]
    } else {
        &MULTIPLE_SCATTERING_PATHS
    };
    let spp: Vec<u32> = if quick {
        vec![1, 2]
    } else {
        vec![1, 2, 4, 8, 16]
    };
    let reference_length = *MULTIPLE_SCATTERING_PATHS.last().expect("not empty");
    let mut references = Vec::new();
    let mut variants = Vec::new();
    let mut compare = Vec::new();
    for (r, (name, colour)) in colours.iter().enumerate() {
        let base = [
            material("chiang", &[]),
            key(
                "material.color",
                toml::Value::try_from(*colour).expect("an array"),
            ),
            key("hair.opacity", toml::Value::Float(1.0)),
            key("shadows.mode", string("raytraced")),
        ];
        let with = |extra: Vec<(String, toml::Value)>| -> Overrides {
            base.iter().cloned().chain(extra).collect()
        };
        references.push(Reference {
            label: format!(
                "chiang {name}, path tracing, {reference_length} bounces and Russian roulette's tail"
            ),
            overrides: with(vec![
                key("integrator.path_length", int(reference_length)),
                key("integrator.tail", toml::Value::Float(1.0)),
            ]),
        });
        let mut methods: Vec<(String, Vec<(String, toml::Value)>)> = paths
            .iter()
            .map(|&n| {
                (
                    format!("{name} path {n}"),
                    vec![key("integrator.path_length", int(n))],
                )
            })
            .collect();
        for (label, form) in [("dual", "dual"), ("dual published", "dual-published")] {
            methods.push((
                format!("{name} {label}"),
                vec![key("integrator.multiple_scattering", string(form))],
            ));
        }
        // The layered form with its strand counts from deep opacity maps (their build in each render's time).
        methods.push((
            format!("{name} dual maps"),
            vec![
                key("integrator.multiple_scattering", string("dual")),
                key("shadows.mode", string("deep-opacity")),
                key(
                    "shadows.deep_opacity.resolution",
                    int(MULTIPLE_SCATTERING_MAP_RESOLUTION),
                ),
            ],
        ));
        for (series, extra) in &methods {
            variants.extend(spp.iter().map(|&s| {
                Variant {
                    series: series.clone(),
                    method: series.clone(),
                    settings: format!("spp={s}"),
                    x: f64::from(s),
                    overrides: with(
                        extra
                            .iter()
                            .cloned()
                            .chain([key("film.spp", int(s))])
                            .collect(),
                    ),
                    reference: r,
                }
            }));
        }
        // Both ways: whether dual scattering reaches the longest paths' error, and how long those paths take to
        // reach dual scattering's (its bias level).
        let longest = format!("{name} path {}", paths[paths.len() - 1]);
        for dual in ["dual", "dual maps"] {
            compare.push((format!("{name} {dual}"), longest.clone()));
            compare.push((longest.clone(), format!("{name} {dual}")));
        }
    }
    // References of 32 × the sweep's largest spp: light hair's deep paths are rare and bright, and at 8 × (128 spp)
    // two blond references under the city map differed by 0.25 relative RMSE, as much as the variants' errors.
    let budget = if quick {
        Budget::default()
    } else {
        Budget {
            crop: Some(SWEEP_CROP),
            reference_spp: spp.last().map(|s| s * MULTIPLE_SCATTERING_REFERENCE_FACTOR),
        }
    };
    Kind {
        name: "multiple-scattering".into(),
        title: "dual scattering against path tracing by path length (chiang; blond, brown, black)"
            .into(),
        x_label: "samples per pixel".into(),
        time_includes_setup: false,
        references,
        variants,
        compare,
        bias_readout: true,
        equal_setting: false,
        budget,
        differences: Vec::new(),
        categories: Vec::new(),
    }
}

/// `curves` (see the module docs).
pub fn curves(quick: bool) -> Kind {
    let scales: Vec<f64> = if quick {
        vec![1.0, 2.0]
    } else {
        vec![0.5, 1.0, 2.0]
    };
    let spp = if quick { 2 } else { 4 };
    let models = ["marschner", "chiang"];
    let mut references = Vec::new();
    let mut variants = Vec::new();
    for &scale in &scales {
        let radius = key("hair.radius_scale", toml::Value::Float(scale));
        for model in models {
            let r = references.len();
            references.push(Reference {
                label: format!("{model}, round, radius ×{scale}"),
                overrides: vec![
                    material(model, &[]),
                    key("hair.curves", string("round")),
                    radius.clone(),
                ],
            });
            for curves in ["round", "flat"] {
                variants.push(Variant {
                    series: format!("{model} {curves}"),
                    method: format!("{model} {curves}"),
                    settings: format!("curves={curves} radius_scale={scale} spp={spp}"),
                    x: scale,
                    overrides: vec![
                        material(model, &[]),
                        key("hair.curves", string(curves)),
                        radius.clone(),
                        key("film.spp", int(spp)),
                    ],
                    reference: r,
                });
            }
        }
    }
    Kind {
        name: "curves".into(),
        title: "round tubes against flat ribbons, per model and strand width (hair.radius_scale)"
            .into(),
        x_label: "strand radius scale (width in pixels ∝)".into(),
        time_includes_setup: true,
        references,
        variants,
        compare: models
            .iter()
            .map(|m| (format!("{m} flat"), format!("{m} round")))
            .collect(),
        bias_readout: true,
        equal_setting: true,
        budget: if quick {
            Budget::default()
        } else {
            Budget {
                crop: Some(SWEEP_CROP),
                reference_spp: Some(spp * REFERENCE_FACTOR),
            }
        },
        differences: Vec::new(),
        categories: Vec::new(),
    }
}

/// What `backends` sweeps: the flags of `cuticle study backends`, or [`BackendsSweep::for_all`].
#[derive(Debug, Clone, PartialEq)]
pub struct BackendsSweep {
    /// Samples per pixel of the compared renders.
    pub spp: Vec<u32>,
    /// Curve types (`round`, `flat`), each with its own Embree reference.
    pub curves: Vec<String>,
}

impl BackendsSweep {
    /// The sweep of `study all`: round and flat at the spp sweep.
    pub fn for_all(quick: bool) -> Self {
        BackendsSweep {
            spp: spp_sweep(quick),
            curves: vec!["round".into(), "flat".into()],
        }
    }
}

/// `backends` (see the module docs): per curve type an Embree reference, and Embree and the BVH over `sweep.spp`
/// with the same seeds, so their images differ only where the tracers disagree ([`Kind::differences`]).
pub fn backends_with(sweep: &BackendsSweep, budget: Budget) -> Result<Kind, String> {
    if sweep.spp.is_empty() || sweep.curves.is_empty() {
        return Err("nothing to compare: --spp and --curves must not be empty".into());
    }
    check_spp(&sweep.spp)?;
    let mut references = Vec::new();
    let mut variants = Vec::new();
    for curves in &sweep.curves {
        let r = references.len();
        references.push(Reference {
            label: format!("embree, {curves}"),
            overrides: vec![
                key("hair.curves", string(curves)),
                key("hair.backend", string("embree")),
            ],
        });
        for backend in ["embree", "bvh"] {
            for &spp in &sweep.spp {
                variants.push(Variant {
                    series: format!("{backend} {curves}"),
                    method: backend.to_owned(),
                    settings: format!("curves={curves} spp={spp}"),
                    x: f64::from(spp),
                    overrides: vec![
                        key("hair.curves", string(curves)),
                        key("hair.backend", string(backend)),
                        key("film.spp", int(spp)),
                    ],
                    reference: r,
                });
            }
        }
    }
    let pairs: Vec<(String, String)> = sweep
        .curves
        .iter()
        .map(|c| (format!("bvh {c}"), format!("embree {c}")))
        .collect();
    Ok(Kind {
        name: "backends".into(),
        title: "Embree against the pure-Rust BVH on the same frame".into(),
        x_label: "samples per pixel".into(),
        time_includes_setup: true,
        references,
        variants,
        compare: pairs.clone(),
        bias_readout: false,
        equal_setting: true,
        budget,
        differences: pairs,
        categories: Vec::new(),
    })
}

/// `backends` in `study all`.
pub fn backends(quick: bool) -> Kind {
    backends_with(&BackendsSweep::for_all(quick), sweep_budget(quick))
        .expect("the sweep of all is not empty")
}

/// What `shadows` sweeps: the flags of `cuticle study shadows`, or [`ShadowsSweep::for_all`].
#[derive(Debug, Clone, PartialEq)]
pub struct ShadowsSweep {
    /// Samples per pixel of the ray-traced series (stochastic and exact transmittance).
    pub rt_spp: Vec<u32>,
    /// Layer counts of the map series at `layer_resolution`.
    pub layers: Vec<u32>,
    /// Map resolution of the layer series.
    pub layer_resolution: u32,
    /// Map resolutions of the series at `resolution_layers`.
    pub resolutions: Vec<u32>,
    /// Layers of the resolution series.
    pub resolution_layers: u32,
    /// Samples per pixel of the map variants and of the no-shadow variant.
    pub dom_spp: u32,
    /// Strand tracer of the variants (`embree`, `bvh`; default: the scene's). The references keep the scene's.
    pub backend: Option<String>,
}

impl ShadowsSweep {
    /// The sweep of `study all`: ray traced at the spp sweep, maps over 4–64 layers at 1024² and over 256²–1024²
    /// at 16 layers, at 8 spp (`--quick`: 1–4 spp, 4–16 layers at 128², 64² and 128² at 16 layers, 2 spp).
    pub fn for_all(quick: bool) -> Self {
        if quick {
            ShadowsSweep {
                rt_spp: spp_sweep(true),
                layers: vec![4, 8, 16],
                layer_resolution: 128,
                resolutions: vec![64, 128],
                resolution_layers: 16,
                dom_spp: 2,
                backend: None,
            }
        } else {
            ShadowsSweep {
                rt_spp: spp_sweep(false),
                layers: vec![4, 8, 16, 32, 64],
                layer_resolution: 1024,
                resolutions: vec![256, 512, 1024],
                resolution_layers: 16,
                dom_spp: 8,
                backend: None,
            }
        }
    }
}

/// An error naming the first 0 of `spp`.
fn check_spp(spp: &[u32]) -> Result<(), String> {
    match spp.iter().find(|&&s| s == 0) {
        Some(s) => Err(format!("samples per pixel must be at least 1, got {s}")),
        None => Ok(()),
    }
}

/// `shadows` (see the module docs): against a ray-traced reference with exact transmittance, no shadows at
/// `dom_spp`, ray tracing with stochastic and with exact transmittance over `rt_spp`, and deep opacity maps over
/// layers and over resolution (a setting in both map series is rendered once). The maps' build is part of the
/// render time and reported on its own (`maps_s`), with their memory (`map_mb`).
pub fn shadows_with(sweep: &ShadowsSweep, budget: Budget) -> Result<Kind, String> {
    if sweep.rt_spp.is_empty() && sweep.layers.is_empty() && sweep.resolutions.is_empty() {
        return Err(
            "nothing to compare: --rt-spp, --layers and --resolutions are all empty".into(),
        );
    }
    check_spp(&sweep.rt_spp)?;
    check_spp(&[sweep.dom_spp])?;
    let backend = || sweep.backend.iter().map(|b| key("hair.backend", string(b)));
    let variant = |series: &str, method: &str, settings: String, x: u32, o: Overrides| Variant {
        series: series.into(),
        method: method.into(),
        settings,
        x: f64::from(x),
        overrides: o.into_iter().chain(backend()).collect(),
        reference: 0,
    };
    let spp = |s: u32| key("film.spp", int(s));
    let mut variants = vec![variant(
        "no shadows",
        "none",
        format!("spp={}", sweep.dom_spp),
        sweep.dom_spp,
        vec![key("shadows.mode", string("none")), spp(sweep.dom_spp)],
    )];
    for transmittance in ["stochastic", "exact"] {
        variants.extend(sweep.rt_spp.iter().map(|&s| {
            variant(
                &format!("ray traced {transmittance}"),
                "raytraced",
                format!("transmittance={transmittance} spp={s}"),
                s,
                vec![
                    key("shadows.mode", string("raytraced")),
                    key("shadows.transmittance", string(transmittance)),
                    spp(s),
                ],
            )
        }));
    }
    let map = |series: &str, x: u32, layers: u32, resolution: u32| {
        variant(
            series,
            "deep-opacity",
            format!(
                "layers={layers} resolution={resolution} spp={}",
                sweep.dom_spp
            ),
            x,
            vec![
                key("shadows.mode", string("deep-opacity")),
                key("shadows.deep_opacity.layers", int(layers)),
                key("shadows.deep_opacity.resolution", int(resolution)),
                spp(sweep.dom_spp),
            ],
        )
    };
    variants.extend(
        sweep
            .layers
            .iter()
            .map(|&l| map("deep opacity layers", l, l, sweep.layer_resolution)),
    );
    variants.extend(
        sweep
            .resolutions
            .iter()
            .map(|&r| map("deep opacity resolution", r, sweep.resolution_layers, r)),
    );
    let has = |series: &str| variants.iter().any(|v| v.series == series);
    let compare = [
        ("deep opacity layers", "ray traced stochastic"),
        ("deep opacity resolution", "ray traced stochastic"),
        ("ray traced exact", "ray traced stochastic"),
    ]
    .into_iter()
    .filter(|(a, b)| has(a) && has(b))
    .map(|(a, b)| (a.to_owned(), b.to_owned()))
    .collect();
    Ok(Kind {
        name: "shadows".into(),
        title: "deep opacity maps against ray-traced shadows".into(),
        x_label: "spp (ray traced), layers or map resolution (maps)".into(),
        time_includes_setup: false,
        references: vec![Reference {
            label: "ray traced, exact transmittance".into(),
            overrides: vec![
                key("shadows.mode", string("raytraced")),
                key("shadows.transmittance", string("exact")),
            ],
        }],
        variants,
        compare,
        bias_readout: false,
        equal_setting: false,
        budget,
        differences: Vec::new(),
        categories: Vec::new(),
    })
}

/// `shadows` in `study all`.
pub fn shadows(quick: bool) -> Kind {
    shadows_with(&ShadowsSweep::for_all(quick), sweep_budget(quick))
        .expect("the sweep of all is not empty")
}

/// The kinds `all` runs, in order.
pub const ALL: [&str; 8] = [
    "samples", "sampling", "lobes", "hery", "models", "curves", "backends", "shadows",
];

/// The kind called `name`, or `None`; `Some(Err)` when it cannot be built (`models`' colour match).
pub fn by_name(name: &str, quick: bool) -> Option<Result<Kind, String>> {
    Some(Ok(match name {
        "samples" => samples(quick),
        "sampling" => sampling(quick),
        "lobes" => lobes(quick),
        "hery" => hery(quick),
        "models" => return Some(models(quick)),
        "curves" => curves(quick),
        "backends" => backends(quick),
        "shadows" => shadows(quick),
        "multiple-scattering" => multiple_scattering(quick),
        _ => return None,
    }))
}
