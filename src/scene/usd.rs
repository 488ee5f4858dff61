//! `cuticle render groom.usd`: a scene made for a USD stage with defaults, so a groom renders without a TOML file.
//!
//! The scene is written as TOML text and parsed like any scene file, so it is checked by the same rules and
//! `--print-scene`-style debugging needs nothing new: the stage's curves are the hair, its meshes the shapes, its
//! first camera the camera (auto-framed when it has none), its distant and dome lights the lights (a sun and a
//! sky like the default scene's when it has none; the default camera and sun stand up along the stage's `upAxis`),
//! and the material Chiang et al.'s reference fibre (brown).

use std::fmt::Write as _;
use std::path::Path;

use crate::usd::{UsdLight, UsdStage};

use super::{Scene, SceneError};

/// The default scene's sun and sky, for a stage without lights: the sun's direction (Y up) and the rest.
const DEFAULT_SUN: [f32; 3] = [-1.0, -1.0, -0.6];
const DEFAULT_LIGHTS: &str = "irradiance = 3.0\ncolor = [1.0, 0.93, 0.82]\n\n[environment]\n\
                              radiance = [0.25, 0.32, 0.45]\n";

/// The default camera's view direction (Y up: looking along −z, slightly down).
const DEFAULT_VIEW: [f32; 3] = [0.3, -0.3, -1.0];

/// A Y-up direction in a stage whose `upAxis` is `axis`: for "Z", turned +90° about x, (x, y, z) → (x, −z, y), so
/// the default camera and sun keep their places relative to the ground.
fn upright(v: [f32; 3], axis: &str) -> glam::Vec3 {
    if axis == "Z" {
        glam::Vec3::new(v[0], -v[2], v[1])
    } else {
        glam::Vec3::from_array(v)
    }
}

/// A TOML string literal of `text` (quoted and escaped as TOML wants).
fn quoted(text: &str) -> String {
    toml::Value::String(text.to_owned()).to_string()
}

/// A TOML array of three floats.
fn triple(v: glam::Vec3) -> String {
    format!("[{:?}, {:?}, {:?}]", v.x, v.y, v.z)
}

/// The scene text for `stage`, read from `file` (named relative to the scene's directory as `name`).
fn scene_text(name: &str, stage: &UsdStage) -> String {
    let file = quoted(name);
    let mut text = format!(
        "# The USD stage {file} with cuticle's defaults (`cuticle render` of a USD file).\n\n[hair]\nfile = {file}\n\n"
    );
    if stage.camera.is_some() {
        let _ = write!(text, "[camera]\nusd = {file}\n\n");
    } else {
        let _ = write!(
            text,
            "[camera]\nview = {}\nup = {}\nmargin = 0.9\n\n",
            triple(upright(DEFAULT_VIEW, &stage.up_axis)),
            triple(upright([0.0, 1.0, 0.0], &stage.up_axis)),
        );
    }
    text.push_str("[material]\nmodel = \"chiang\"\n\n");
    if stage.mesh_prims > 0 {
        let _ = write!(text, "[[shape]]\nkind = \"usd\"\nfile = {file}\n\n");
    }
    let mut lit = false;
    let mut dome = false;
    for light in &stage.lights {
        match light {
            UsdLight::Distant {
                direction_to_light,
                color,
                intensity,
                exposure,
                angle_degrees,
            } => {
                let _ = write!(
                    text,
                    "[[light]]\nkind = \"distant\"\ndirection = {}\nirradiance = {:?}\ncolor = {}\n\
                     angular_radius = {:?}\n\n",
                    triple(-*direction_to_light),
                    intensity * exposure.exp2(),
                    triple(*color),
                    (0.5 * angle_degrees).clamp(0.0, 90.0),
                );
                lit = true;
            }
            // One environment: the first dome.
            UsdLight::Dome {
                color,
                intensity,
                exposure,
                texture,
            } if !dome => {
                let scale = intensity * exposure.exp2();
                match texture {
                    Some(map) => {
                        let _ = write!(
                            text,
                            "[environment]\nmap = {}\nintensity = {scale:?}\n\n",
                            quoted(&map.to_string_lossy())
                        );
                    }
                    None => {
                        let _ = write!(
                            text,
                            "[environment]\nradiance = {}\n\n",
                            triple(*color * scale)
                        );
                    }
                }
                dome = true;
                lit = true;
            }
            UsdLight::Dome { .. } => {}
        }
    }
    if !lit {
        let _ = write!(
            text,
            "[[light]]\nkind = \"distant\"\ndirection = {}\n{DEFAULT_LIGHTS}",
            triple(upright(DEFAULT_SUN, &stage.up_axis))
        );
    }
    text
}

impl Scene {
    /// The scene `cuticle render groom.usd` renders: the stage at `path` with defaults ([`self`](super::usd)).
    /// Errors name the stage (and prim) as the USD reader reports them.
    pub fn from_usd(path: &Path) -> Result<Scene, SceneError> {
        // Camera, lights and counts only: the curves and meshes are read once each, by the scene's hair and shape.
        let stage = crate::usd::read_parts(
            path,
            None,
            crate::usd::DEFAULT_RADIUS,
            crate::usd::Parts::NONE,
        )
        .map_err(|e| SceneError::Invalid {
            path: path.to_path_buf(),
            message: e.without_file(),
        })?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        Scene::parse(&scene_text(&name, &stage), path, &base)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stage_becomes_a_scene_with_its_camera_meshes_and_lights() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/usd");
        let stage = crate::usd::read_parts(
            &dir.join("groom.usda"),
            None,
            0.005,
            crate::usd::Parts::NONE,
        )
        .unwrap();
        let text = scene_text("groom.usda", &stage);
        let scene = Scene::parse(&text, &dir.join("groom.usda"), &dir).unwrap();
        assert_eq!(scene.hair.file.as_deref(), Some(Path::new("groom.usda")));
        assert_eq!(scene.camera.usd.as_deref(), Some(Path::new("groom.usda")));
        assert_eq!(scene.shapes.len(), 1);
        // The stage's distant light travels away from the direction towards it.
        let Some(UsdLight::Distant {
            direction_to_light, ..
        }) = stage.lights.first()
        else {
            panic!(
                "the test stage's first light is distant: {:?}",
                stage.lights
            );
        };
        assert!(text.contains(&format!("direction = {}", triple(-*direction_to_light))));
        // Without lights or camera: the default sun and sky, an auto-framed camera.
        let bare = UsdStage {
            camera: None,
            lights: Vec::new(),
            mesh_prims: 0,
            ..stage
        };
        let scene = Scene::parse(&scene_text("a \"b\".usda", &bare), &dir.join("x"), &dir).unwrap();
        assert_eq!(scene.hair.file.as_deref(), Some(Path::new("a \"b\".usda")));
        assert!(scene.camera.usd.is_none() && scene.shapes.is_empty());
        assert_eq!(scene.lights.len(), 1);
        assert_eq!(scene.camera.up, [0.0, 1.0, 0.0]);
        // A Z-up stage: the default camera's up is +z, and it looks along +y, slightly down, as a Y-up stage's
        // looks along −z.
        let z_up = UsdStage {
            up_axis: "Z".into(),
            ..bare
        };
        let scene = Scene::parse(&scene_text("z.usda", &z_up), &dir.join("x"), &dir).unwrap();
        assert_eq!(scene.camera.up, [0.0, 0.0, 1.0]);
        assert_eq!(scene.camera.view, [0.3, 1.0, -0.3]);
    }

    #[test]
    fn a_bad_stage_is_one_error_naming_its_file_once() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bad.usdc");
        std::fs::write(&path, b"garbage").unwrap();
        let message = Scene::from_usd(&path).unwrap_err().to_string();
        let name = path.display().to_string();
        assert!(message.starts_with(&format!("{name}: ")), "{message}");
        assert_eq!(message.matches(&name).count(), 1, "{message}");
    }
}
