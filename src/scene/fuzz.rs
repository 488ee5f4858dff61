//! Entry points of the fuzz targets (`fuzz/`, cargo-fuzz) and of the corpus replay test (`tests/fuzz_corpus.rs`):
//! each takes arbitrary bytes, runs a reader or the scene parser and validation on them in memory (no files), and
//! returns whether they were accepted. Any input may be rejected; none may panic, hang, or allocate much more
//! than its own size.

use std::path::Path;

use crate::hair::{tfx, yuksel, Strands};

use super::Scene;

/// The `.hair` reader; an accepted model is also converted to B-spline strands, as a render would.
pub fn hair(data: &[u8]) -> bool {
    yuksel::parse(Path::new("fuzz.hair"), data)
        .map(|m| Strands::from_model(&m))
        .is_ok()
}

/// The `.tfx` reader; an accepted model is also converted to B-spline strands.
pub fn tfx(data: &[u8]) -> bool {
    tfx::parse(Path::new("fuzz.tfx"), data)
        .map(|m| Strands::from_model(&m))
        .is_ok()
}

/// Scene parsing and validation (as [`Scene::load`] after reading the file, with the same size bound, [`super::MAX_SCENE_BYTES`]), then the
/// settings a render would run with.
pub fn scene(data: &[u8]) -> bool {
    Scene::parse_bytes(data, Path::new("fuzz.toml"), Path::new("."))
        .map(|s| s.render_settings())
        .is_ok()
}
