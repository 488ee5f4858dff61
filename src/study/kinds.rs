//! The kinds of `cuticle study` built on [`super::framework`] (issue 17): each function returns the [`Kind`] —
//! references, variants, the pairs read out — for full or `--quick` runs. Materials are each model's paper
//! defaults (`[material] model = "…"` alone) plus the keys a kind varies, so results do not depend on the scene's
//! own material; everything else (hair, lights, camera, path length) is the scene's.
//!
//! - [`samples`]: the thesis' table 3 — light samples at 64 material samples and material samples at 64 light
//!   samples, for `marschner`, `ishair`, `chiang`, 1 spp. cuticle caps both counts at 1024
//!   (`integrator.*_samples`), so the thesis' 2048 is left out. `--quick`: 1, 2, 4 at 4.
//! - [`sampling`]: importance against uniform BSDF sampling (`material.sampling`) for `kajiya-kay`, `marschner`,
//!   `ishair` (`chiang` has no uniform mode), material samples only (`integrator.strategy = "material"`, so the
//!   sampling strategy is what is measured) over spp; equal-time and equal-error read-outs.
//! - [`lobes`]: ISHair's lobe selection, `uniform` against `by-energy`, material samples only, over spp.
//! - [`hery`]: Marschner sampled as Hery & Ramamoorthi published it (`published`, clamp-and-flip) against the exact
//!   pdf (`importance`), material samples only, over spp, against an MIS reference: the published sampler's error
//!   levels off at its bias (`mean_diff` in the CSV is the bias of the image mean).
//! - [`models`]: `marschner` and `ishair` against a `chiang` reference (with `chiang` itself as the control), over
//!   spp: the error that does not fall with spp is the models' difference. Colours are not matched.
//! - [`curves`]: round tubes against flat ribbons per model, against a round reference at each film width (the
//!   strands' width in pixels grows in proportion to it); times include set-up (the BVH differs).
//! - [`backends`], [`shadows`]: the studies of issues 13 and 6 as framework kinds, for `all` (seeds, SSIM,
//!   fireflies, read-outs). `cuticle study backends|shadows` keep their own modules ([`super::backends`],
//!   [`super::shadows`]) and options, with the image-difference maps and crop mosaic the framework does not draw.
//!   In `shadows` the map build is part of the render time.

use super::framework::{Kind, Overrides, Reference, Variant};

/// Samples per pixel of the sweeps over spp.
fn spp_sweep(quick: bool) -> Vec<u32> {
    if quick {
        vec![1, 2, 4]
    } else {
        vec![1, 2, 4, 8, 16, 32, 64]
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
    let (counts, fixed): (Vec<u32>, u32) = if quick {
        (vec![1, 2, 4], 4)
    } else {
        (vec![16, 32, 64, 128, 256, 512, 1024], 64)
    };
    let models = ["marschner", "ishair", "chiang"];
    let mut references = Vec::new();
    let mut variants = Vec::new();
    for (r, model) in models.iter().enumerate() {
        references.push(Reference {
            label: format!("{model}, MIS, {fixed} light × {fixed} material samples"),
            overrides: vec![
                material(model, &[]),
                key("integrator.light_samples", int(fixed)),
                key("integrator.material_samples", int(fixed)),
            ],
        });
        for (what, other) in [("light", "material"), ("material", "light")] {
            for &n in &counts {
                variants.push(Variant {
                    series: format!("{model} {what} samples"),
                    method: model.to_string(),
                    settings: format!("{what}_samples={n} {other}_samples={fixed}"),
                    x: f64::from(n),
                    overrides: vec![
                        material(model, &[]),
                        key(&format!("integrator.{what}_samples"), int(n)),
                        key(&format!("integrator.{other}_samples"), int(fixed)),
                    ],
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
    let models = ["kajiya-kay", "marschner", "ishair"];
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
    }
}

/// `models` (see the module docs).
pub fn models(quick: bool) -> Kind {
    let variants = ["marschner", "ishair", "chiang"]
        .iter()
        .flat_map(|m| {
            spp_sweep(quick).into_iter().map(move |spp| Variant {
                series: (*m).to_owned(),
                method: (*m).to_owned(),
                settings: format!("spp={spp}"),
                x: f64::from(spp),
                overrides: vec![material(m, &[]), key("film.spp", int(spp))],
                reference: 0,
            })
        })
        .collect();
    Kind {
        name: "models".into(),
        title: "the thesis models against the energy-conserving chiang reference".into(),
        x_label: "samples per pixel".into(),
        time_includes_setup: false,
        references: vec![mis_reference("chiang")],
        variants,
        compare: vec![
            ("marschner".into(), "chiang".into()),
            ("ishair".into(), "chiang".into()),
        ],
        bias_readout: true,
        equal_setting: true,
    }
}

/// `curves` (see the module docs).
pub fn curves(quick: bool) -> Kind {
    let widths: Vec<u32> = if quick {
        vec![24, 48]
    } else {
        vec![128, 256, 512]
    };
    let spp = if quick { 2 } else { 16 };
    let models = ["marschner", "chiang"];
    let mut references = Vec::new();
    let mut variants = Vec::new();
    for &w in &widths {
        let film = key(
            "film.resolution",
            toml::Value::try_from([w, w]).expect("array"),
        );
        for model in models {
            let r = references.len();
            references.push(Reference {
                label: format!("{model}, round, {w}×{w}"),
                overrides: vec![
                    material(model, &[]),
                    key("hair.curves", string("round")),
                    film.clone(),
                ],
            });
            for curves in ["round", "flat"] {
                variants.push(Variant {
                    series: format!("{model} {curves}"),
                    method: format!("{model} {curves}"),
                    settings: format!("curves={curves} resolution={w} spp={spp}"),
                    x: f64::from(w),
                    overrides: vec![
                        material(model, &[]),
                        key("hair.curves", string(curves)),
                        film.clone(),
                        key("film.spp", int(spp)),
                    ],
                    reference: r,
                });
            }
        }
    }
    Kind {
        name: "curves".into(),
        title: "round tubes against flat ribbons, per model and film width (strand width in pixels ∝ film width)"
            .into(),
        x_label: "film width (px)".into(),
        time_includes_setup: true,
        references,
        variants,
        compare: models
            .iter()
            .map(|m| (format!("{m} flat"), format!("{m} round")))
            .collect(),
        bias_readout: false,
        equal_setting: true,
    }
}

/// `backends` through the framework (see the module docs).
pub fn backends(quick: bool) -> Kind {
    let mut references = Vec::new();
    let mut variants = Vec::new();
    for curves in ["round", "flat"] {
        let r = references.len();
        references.push(Reference {
            label: format!("embree, {curves}"),
            overrides: vec![
                key("hair.curves", string(curves)),
                key("hair.backend", string("embree")),
            ],
        });
        for backend in ["embree", "bvh"] {
            for spp in spp_sweep(quick) {
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
    Kind {
        name: "backends".into(),
        title: "Embree against the pure-Rust BVH on the same frame".into(),
        x_label: "samples per pixel".into(),
        time_includes_setup: true,
        references,
        variants,
        compare: ["round", "flat"]
            .iter()
            .map(|c| (format!("bvh {c}"), format!("embree {c}")))
            .collect(),
        bias_readout: false,
        equal_setting: true,
    }
}

/// `shadows` through the framework (see the module docs).
pub fn shadows(quick: bool) -> Kind {
    let (rt_spp, layers, dom_spp, map_res) = if quick {
        (vec![1, 2, 4], vec![4, 8, 16], 2, 128)
    } else {
        (vec![1, 4, 16, 64], vec![4, 8, 16, 32, 64], 16, 1024)
    };
    let mut variants: Vec<Variant> = rt_spp
        .iter()
        .map(|&spp| Variant {
            series: "ray traced".into(),
            method: "raytraced".into(),
            settings: format!("spp={spp}"),
            x: f64::from(spp),
            overrides: vec![
                key("shadows.mode", string("raytraced")),
                key("film.spp", int(spp)),
            ],
            reference: 0,
        })
        .collect();
    variants.extend(layers.iter().map(|&l| Variant {
        series: "deep opacity maps".into(),
        method: "deep-opacity".into(),
        settings: format!("layers={l} resolution={map_res} spp={dom_spp}"),
        x: f64::from(l),
        overrides: vec![
            key("shadows.mode", string("deep-opacity")),
            key("shadows.deep_opacity.layers", int(l)),
            key("shadows.deep_opacity.resolution", int(map_res)),
            key("film.spp", int(dom_spp)),
        ],
        reference: 0,
    }));
    Kind {
        name: "shadows".into(),
        title: "deep opacity maps against ray-traced shadows".into(),
        x_label: "spp (ray traced) or layers (maps)".into(),
        time_includes_setup: false,
        references: vec![Reference {
            label: "ray traced, exact transmittance".into(),
            overrides: vec![
                key("shadows.mode", string("raytraced")),
                key("shadows.transmittance", string("exact")),
            ],
        }],
        variants,
        compare: vec![("deep opacity maps".into(), "ray traced".into())],
        bias_readout: false,
        equal_setting: false,
    }
}

/// The kinds `all` runs, in order.
pub const ALL: [&str; 8] = [
    "samples", "sampling", "lobes", "hery", "models", "curves", "backends", "shadows",
];

/// The kind called `name`, or `None`.
pub fn by_name(name: &str, quick: bool) -> Option<Kind> {
    Some(match name {
        "samples" => samples(quick),
        "sampling" => sampling(quick),
        "lobes" => lobes(quick),
        "hery" => hery(quick),
        "models" => models(quick),
        "curves" => curves(quick),
        "backends" => backends(quick),
        "shadows" => shadows(quick),
        _ => return None,
    })
}
