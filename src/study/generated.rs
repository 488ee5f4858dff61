//! Random test scenes for judging `--quality auto` on scenes it was never tuned on (`cuticle study scenes`).
//!
//! Each scene is drawn from its own stream of one seed (`Pcg32::new(seed, index)`), so scene k is the same whatever
//! the count; the same seed gives the same files. What varies, each over the range a user's scenes span:
//!
//! - **groom**: a procedural fur ball or wavy patch (strand count, fibre radius, curl, waves, translucency), or,
//!   when a data folder is given, one of its real models (`hair/*.hair`, `hair/*.tfx`);
//! - **strand width on screen**: from the fibre radius and the camera's framing (`camera.margin` from 0.35, a
//!   close-up, to 1.3) and view direction, from well under a pixel to several pixels;
//! - **fibre model and absorption**: Chiang, Marschner, ISHair or Kajiya-Kay, the colour from near-black to
//!   white-blond;
//! - **light**: a sun from the side, a sun behind the hair (light through it dominating), a small disk light near a
//!   fur ball, an environment alone (a map from the data folder, rotated, or a constant sky), each with or without
//!   a dim sky.
//!
//! **No constant of auto may be tuned on these scenes**: they are the held-out set its promise is judged on
//! (`docs/measured/auto.md` says which set tuned what).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use rand::Rng;
use rand_pcg::Pcg32;

/// One generated scene: a file stem, its TOML, a one-line description of what was drawn.
#[derive(Debug, Clone, PartialEq)]
pub struct GeneratedScene {
    /// File stem, `gen-SEED-INDEX`.
    pub name: String,
    /// The scene file's text (paths absolute, so it loads from anywhere).
    pub toml: String,
    /// What was drawn, for the set's index.
    pub summary: String,
}

/// The real models and maps a data folder offers (sorted, so the draw does not depend on the listing's order).
#[derive(Debug, Clone, Default)]
pub struct DataFiles {
    /// `.hair` and `.tfx` models.
    pub models: Vec<PathBuf>,
    /// Lat-long `.exr` maps.
    pub maps: Vec<PathBuf>,
}

impl DataFiles {
    /// The models in `dir/hair` and the EXR maps in `dir/envmaps` (none where a folder is missing).
    pub fn scan(dir: &Path) -> DataFiles {
        let list = |sub: &str, exts: &[&str]| {
            let mut v: Vec<PathBuf> = std::fs::read_dir(dir.join(sub))
                .into_iter()
                .flatten()
                .flatten()
                .map(|e| e.path())
                .filter(|p| {
                    p.extension()
                        .and_then(|e| e.to_str())
                        .is_some_and(|e| exts.contains(&e))
                })
                .map(|p| std::fs::canonicalize(&p).unwrap_or(p))
                .collect();
            v.sort();
            v
        };
        DataFiles {
            models: list("hair", &["hair", "tfx"]),
            maps: list("envmaps", &["exr"]),
        }
    }
}

/// `count` scenes drawn from `seed`, with the real models and maps of `data`.
pub fn generate(seed: u64, count: usize, data: &DataFiles) -> Vec<GeneratedScene> {
    (0..count).map(|k| scene(seed, k, data)).collect()
}

/// A TOML string literal of a path.
fn quoted(p: &Path) -> String {
    let s = p.to_string_lossy();
    format!("\"{}\"", s.replace('\\', "\\\\").replace('"', "\\\""))
}

/// A unit vector drawn uniformly on the sphere.
fn direction(rng: &mut Pcg32) -> [f32; 3] {
    let z: f32 = rng.random_range(-1.0..1.0);
    let phi: f32 = rng.random_range(0.0..std::f32::consts::TAU);
    let r = (1.0 - z * z).max(0.0).sqrt();
    [r * phi.cos(), r * phi.sin(), z]
}

/// x drawn log-uniformly in [lo, hi].
fn log_uniform(rng: &mut Pcg32, lo: f32, hi: f32) -> f32 {
    (rng.random_range(lo.ln()..hi.ln())).exp()
}

/// An RGB triple as TOML.
fn rgb(c: [f32; 3]) -> String {
    format!("[{:.4}, {:.4}, {:.4}]", c[0], c[1], c[2])
}

/// Scene `k` of `seed`.
fn scene(seed: u64, k: usize, data: &DataFiles) -> GeneratedScene {
    let mut rng = Pcg32::new(seed, k as u64);
    let mut toml = String::new();
    let mut summary = Vec::new();

    // Groom. Procedural grooms are centred at the origin (the fur ball's sphere of radius 1), so only they take a
    // positioned light.
    let groom = rng.random_range(0..if data.models.is_empty() { 2 } else { 3 });
    let fur_ball = groom == 0;
    let opacity: f32 = if rng.random_bool(0.7) {
        1.0
    } else {
        rng.random_range(0.3..0.9)
    };
    match groom {
        0 => {
            let strands = rng.random_range(1500..16000);
            let radius = log_uniform(&mut rng, 0.0015, 0.02);
            let curl: f32 = rng.random_range(0.0..0.12);
            let length: f32 = rng.random_range(0.3..0.9);
            let _ = writeln!(
                toml,
                "[hair]\nprocedural = {{ kind = \"fur-ball\", seed = {}, strands = {strands}, fiber_radius = {radius:.5}, \
                 curl = {curl:.3}, length = {length:.3} }}\nopacity = {opacity:.2}\n",
                rng.random_range(0..1_000_000u32)
            );
            summary.push(format!("fur ball {strands} strands r {radius:.4}"));
        }
        1 => {
            let strands = rng.random_range(1500..10000);
            let radius = log_uniform(&mut rng, 0.002, 0.02);
            let waves: f32 = rng.random_range(0.0..0.12);
            let _ = writeln!(
                toml,
                "[hair]\nprocedural = {{ kind = \"wavy-patch\", seed = {}, strands = {strands}, fiber_radius = {radius:.5}, \
                 wave_amplitude = {waves:.3} }}\nopacity = {opacity:.2}\n",
                rng.random_range(0..1_000_000u32)
            );
            summary.push(format!("wavy patch {strands} strands r {radius:.4}"));
        }
        _ => {
            let model = &data.models[rng.random_range(0..data.models.len())];
            let _ = writeln!(
                toml,
                "[hair]\nfile = {}\nopacity = {opacity:.2}\n",
                quoted(model)
            );
            let name = model
                .file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
            summary.push(name);
        }
    }

    // Camera: framing from a close-up to the whole groom with room, from any side.
    let margin = log_uniform(&mut rng, 0.35, 1.3);
    let mut view = direction(&mut rng);
    if view[1].abs() > 0.9 {
        // Nearly along `up`: tilt it off so the image's up is defined.
        view[0] += 0.5;
    }
    let _ = writeln!(
        toml,
        "[camera]\nmargin = {margin:.3}\nview = {}\n\n[film]\nresolution = [128, 128]\nspp = 16\n",
        rgb(view)
    );
    summary.push(format!("margin {margin:.2}"));

    // Fibre model and colour, from near-black to white-blond.
    let models = ["chiang", "marschner", "ishair", "kajiya-kay"];
    let model = models[rng.random_range(0..models.len())];
    let t: f32 = rng.random_range(0.0..1.0);
    let (dark, blond) = ([0.04, 0.025, 0.015], [0.95, 0.85, 0.7]);
    let color: [f32; 3] = std::array::from_fn(|c| dark[c] + t * (blond[c] - dark[c]));
    let _ = writeln!(
        toml,
        "[material]\nmodel = \"{model}\"\ncolor = {}\n",
        rgb(color)
    );
    summary.push(format!("{model} lightness {t:.2}"));

    // Light.
    let sky: f32 = if rng.random_bool(0.5) {
        rng.random_range(0.05..0.6)
    } else {
        0.0
    };
    let kinds = if fur_ball { 4 } else { 3 };
    match rng.random_range(0..kinds) {
        arm @ (0 | 1) => {
            // A sun from anywhere, or behind the hair: travelling towards the camera (against the view direction),
            // a little off axis.
            let (d, e, what) = if arm == 0 {
                let d = direction(&mut rng);
                (d, rng.random_range(1.0f32..6.0), "sun")
            } else {
                let j = direction(&mut rng);
                let d: [f32; 3] = std::array::from_fn(|c| -view[c] + 0.3 * j[c]);
                (d, rng.random_range(2.0f32..8.0), "back-lit sun")
            };
            let _ = writeln!(
                toml,
                "[[light]]\nkind = \"distant\"\ndirection = {}\nirradiance = {e:.2}\n",
                rgb(d)
            );
            summary.push(format!("{what} {e:.1}"));
        }
        2 => {
            if data.maps.is_empty() || rng.random_bool(0.25) {
                let l: f32 = rng.random_range(0.5..2.0);
                let _ = writeln!(toml, "[environment]\nradiance = {}\n", rgb([l; 3]));
                summary.push(format!("constant sky {l:.2}"));
            } else {
                let map = &data.maps[rng.random_range(0..data.maps.len())];
                let rotation: f32 = rng.random_range(0.0..360.0);
                let _ = writeln!(
                    toml,
                    "[environment]\nmap = {}\nrotation = {rotation:.1}\n",
                    quoted(map)
                );
                let name = map
                    .file_stem()
                    .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
                summary.push(format!("map {name}"));
            }
        }
        _ => {
            // A small disk light near the fur ball, facing it.
            let d = direction(&mut rng);
            let distance: f32 = rng.random_range(2.2..4.0);
            let centre = d.map(|c| c * distance);
            let radius = log_uniform(&mut rng, 0.05, 0.4);
            // Radiance so that the disk's irradiance at the origin is about 1–5: E ≈ L π r² / d².
            let e: f32 = rng.random_range(1.0..5.0);
            let l = e * distance * distance / (std::f32::consts::PI * radius * radius);
            let _ = writeln!(
                toml,
                "[[light]]\nkind = \"disk\"\ncenter = {}\nnormal = {}\nradius = {radius:.3}\nradiance = {l:.2}\n",
                rgb(centre),
                rgb(d.map(|c| -c))
            );
            summary.push(format!("disk r {radius:.2} at {distance:.1}"));
        }
    }
    if sky > 0.0 && !toml.contains("[environment]") {
        let _ = writeln!(toml, "[environment]\nradiance = {}\n", rgb([sky; 3]));
        summary.push(format!("sky {sky:.2}"));
    }
    GeneratedScene {
        name: format!("gen-{seed}-{k:02}"),
        toml: format!(
            "# Generated by `cuticle study scenes --seed {seed}` (scene {k}): {}. Held out: no constant is tuned on it.\n\n{toml}",
            summary.join(", ")
        ),
        summary: summary.join(", "),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;

    #[test]
    fn the_same_seed_gives_the_same_scenes_and_every_scene_loads() {
        let data = DataFiles::default();
        let a = generate(7, 24, &data);
        assert_eq!(a, generate(7, 24, &data));
        // Scene k does not depend on the count.
        assert_eq!(a[..5], generate(7, 5, &data)[..]);
        assert_ne!(a, generate(8, 24, &data));
        for s in &a {
            let scene = Scene::parse(&s.toml, Path::new(&s.name), Path::new("."))
                .unwrap_or_else(|e| panic!("{}: {e}\n{}", s.name, s.toml));
            scene
                .resolve()
                .unwrap_or_else(|e| panic!("{}: {e}\n{}", s.name, s.toml));
        }
        // The set spans what it claims: every model, every kind of light, close-ups and wide shots.
        let all = a
            .iter()
            .map(|s| s.summary.clone())
            .collect::<Vec<_>>()
            .join("; ");
        for word in [
            "chiang",
            "marschner",
            "ishair",
            "kajiya-kay",
            "back-lit",
            "sun",
            "disk",
            "sky",
        ] {
            assert!(all.contains(word), "no {word} in {all}");
        }
        let margins: Vec<f32> = a
            .iter()
            .map(|s| {
                let m = s.summary.split("margin ").nth(1).unwrap();
                m.split(',').next().unwrap().parse().unwrap()
            })
            .collect();
        assert!(margins.iter().any(|&m| m < 0.6) && margins.iter().any(|&m| m > 1.0));
    }
}
