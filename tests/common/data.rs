//! Where the integration tests find the third-party data (hair models, environment maps; see docs/data.md): the
//! folder named by the environment variable `CUTICLE_DATA`, by default `../shared/data` beside the repository.
//! A test whose data is missing fails naming the file; it never passes without it.
//!
//! Shipped scenes name their data relative to the scene file (`../../shared/data/hair/furball.hair`):
//! [`load_scene`] and [`scene_copy`] point those paths into the data folder.

use std::path::{Component, Path, PathBuf};

use cuticle::scene::Scene;

/// The data folder: `$CUTICLE_DATA`, or `<repository>/../shared/data`.
pub fn dir() -> PathBuf {
    match std::env::var_os("CUTICLE_DATA") {
        Some(d) if !d.is_empty() => PathBuf::from(d),
        _ => PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data")),
    }
}

/// `rel` (e.g. `hair/straight.hair`) in the data folder. Panics naming the file when it is missing.
#[track_caller]
pub fn file(rel: &str) -> PathBuf {
    existing(dir().join(rel))
}

/// `path`, which the test needs; panics naming it, and saying where data is looked for, when it is missing.
#[track_caller]
pub fn existing(path: PathBuf) -> PathBuf {
    assert!(
        path.exists(),
        "missing test data {}: set CUTICLE_DATA to a folder holding it (see docs/data.md)",
        path.display()
    );
    path
}

/// A path of a shipped scene that goes through a `shared/data` folder, moved into the data folder (the part after
/// `shared/data`); `None` for any other path.
fn in_data(path: &Path) -> Option<PathBuf> {
    let parts: Vec<Component> = path.components().collect();
    let at = parts.windows(2).position(|w| {
        w[0] == Component::Normal("shared".as_ref()) && w[1] == Component::Normal("data".as_ref())
    })?;
    Some(dir().join(parts[at + 2..].iter().collect::<PathBuf>()))
}

/// The scene file at `path` (relative to the repository) with its hair file and environment map taken from the
/// data folder; panics naming a missing one.
#[track_caller]
pub fn load_scene(path: &str) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(path);
    let mut scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    if let Some(file) = scene.hair.file.as_deref().and_then(in_data) {
        scene.hair.file = Some(existing(file));
    }
    if let Some(map) = scene.environment.map.as_deref().and_then(in_data) {
        scene.environment.map = Some(existing(map));
    }
    scene
}

/// Writes a copy of the scene file at `path` (relative to the repository) into `into`, with its hair file and
/// environment map taken from the data folder (absolute paths), for tests that hand a scene file to the `cuticle`
/// command. Returns the copy's path; panics naming a missing data file.
#[track_caller]
pub fn scene_copy(path: &str, into: &Path) -> PathBuf {
    let source = Path::new(env!("CARGO_MANIFEST_DIR")).join(path);
    let text = std::fs::read_to_string(&source).unwrap_or_else(|e| panic!("{path}: {e}"));
    let mut table: toml::Table = text.parse().unwrap_or_else(|e| panic!("{path}: {e}"));
    for (section, key) in [("hair", "file"), ("environment", "map")] {
        let Some(value) = table
            .get_mut(section)
            .and_then(|s| s.as_table_mut())
            .and_then(|s| s.get_mut(key))
        else {
            continue;
        };
        if let Some(moved) = value.as_str().map(Path::new).and_then(in_data) {
            let moved = existing(moved);
            *value = toml::Value::String(moved.to_str().expect("a UTF-8 data path").to_owned());
        }
    }
    let copy = into.join(source.file_name().unwrap());
    std::fs::write(&copy, toml::to_string(&table).unwrap()).unwrap();
    copy
}
