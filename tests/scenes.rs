//! Every scene shipped in `scenes/` parses, its hair file exists and its lights (environment maps included) build.
//! Scenes that read third-party data take it from the data folder (`CUTICLE_DATA`, see docs/data.md): without it
//! this test fails, naming the missing file; it never passes without checking.

use std::path::{Path, PathBuf};

mod common;

use cuticle::hair::HairSource;

fn scene_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            scene_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "toml") {
            out.push(path);
        }
    }
}

#[test]
fn every_shipped_scene_parses_and_its_data_resolves() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = Vec::new();
    scene_files(&root.join("scenes"), &mut files);
    files.sort();
    assert!(files.len() >= 20, "{} scenes", files.len());
    for file in &files {
        let relative = file.strip_prefix(root).unwrap().to_str().unwrap();
        let scene = common::data::load_scene(relative);
        if let HairSource::File(hair) = scene.hair_source() {
            assert!(
                hair.exists(),
                "{}: hair file {} missing",
                file.display(),
                hair.display()
            );
        }
        scene
            .build_lights()
            .unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    }
}
