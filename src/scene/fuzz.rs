//! Entry points of the fuzz targets (`fuzz/`, cargo-fuzz) and of the corpus replay test (`tests/fuzz_corpus.rs`):
//! each takes arbitrary bytes, runs a reader or the scene parser and validation on them in memory (no files; the
//! tile reader of `merge` goes through OpenImageIO and the USD reader through openusd, which read files, so their
//! bytes go to temporary ones), and
//! returns whether they were accepted. Any input may be rejected; none may panic, hang, or allocate much more
//! than its own size (or, for `merge`, than [`MERGE_MAX_BYTES`]).

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

/// The USD reader ([`crate::usd::read`]) on `data` as a file: its first byte picks the format the rest is named as
/// (`.usda`, `.usdc` or `.usdz`, by the byte modulo 3), since openusd reads files by name. An accepted stage's
/// strands and meshes are what a render would trace.
pub fn usd(data: &[u8]) -> bool {
    let Some((&kind, bytes)) = data.split_first() else {
        return false;
    };
    let Ok(dir) = tempfile::tempdir() else {
        return false;
    };
    let path = dir
        .path()
        .join(["fuzz.usda", "fuzz.usdc", "fuzz.usdz"][usize::from(kind % 3)]);
    if std::fs::write(&path, bytes).is_err() {
        return false;
    }
    crate::usd::read(&path, None, crate::usd::DEFAULT_RADIUS).is_ok()
}

/// What separates the tiles of one `merge` input: the bytes between are one tile file each (at most
/// [`MERGE_MAX_TILES`]).
pub const MERGE_SEPARATOR: &[u8] = b"\0cuticle-fuzz-tile\0";

/// The most tiles one `merge` input is split into.
pub const MERGE_MAX_TILES: usize = 4;

/// The bound on one decoded tile or frame in the `merge` target (the renderer's is a third of the memory limit).
pub const MERGE_MAX_BYTES: u64 = 64 << 20;

/// `cuticle merge`'s tile reader and checks: `data` split at [`MERGE_SEPARATOR`] into tile files (EXRs written by
/// `render --tile`, or anything else), merged in order as [`crate::farm::merge_within`] does.
pub fn merge(data: &[u8]) -> bool {
    let Ok(dir) = tempfile::tempdir() else {
        return false;
    };
    let mut tiles = Vec::new();
    let mut rest = data;
    while tiles.len() < MERGE_MAX_TILES {
        let (tile, next) = match find(rest, MERGE_SEPARATOR) {
            Some(at) => (&rest[..at], Some(&rest[at + MERGE_SEPARATOR.len()..])),
            None => (rest, None),
        };
        let path = dir.path().join(format!("tile{}.exr", tiles.len()));
        if std::fs::write(&path, tile).is_err() {
            return false;
        }
        tiles.push(path);
        match next {
            Some(next) => rest = next,
            None => break,
        }
    }
    crate::farm::merge_within(&tiles, MERGE_MAX_BYTES).is_ok()
}

/// Where `needle` first occurs in `haystack`.
fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}
