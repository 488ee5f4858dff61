//! Naming and writing the files of a study.
//!
//! A converged reference render takes minutes, so studies keep it on disk under a name derived from everything that
//! decides its pixels: [`Fnv1a`] (64-bit FNV-1a, Fowler–Noll–Vo) is stable across runs, platforms and Rust versions,
//! unlike `std`'s `DefaultHasher`, whose algorithm is unspecified. What goes into the key is the caller's choice
//! (see [`super::framework`]); files the scene refers to (hair, environment maps) are *not* hashed, nor is the
//! renderer's code: delete the cached file after changing either.
//!
//! Text outputs are written like images ([`crate::util::atomic_file`]): to a temporary file in the same directory, then
//! renamed over the target, so a reader never sees half a table.

use std::path::Path;

use super::{SceneFile, StudyError};
use crate::util::atomic_file;

/// 64-bit FNV-1a.
#[derive(Debug, Clone, Copy)]
pub struct Fnv1a(u64);

impl Default for Fnv1a {
    fn default() -> Self {
        Fnv1a(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv1a {
    /// Mixes in `bytes`.
    pub fn write(&mut self, bytes: &[u8]) -> &mut Self {
        for &b in bytes {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
        self
    }

    /// Mixes in a string and a separator byte (0xff, which UTF-8 never contains), so ("ab", "c") ≠ ("a", "bc").
    pub fn field(&mut self, text: &str) -> &mut Self {
        self.write(text.as_bytes()).write(&[0xff])
    }

    /// The hash so far.
    pub fn finish(&self) -> u64 {
        self.0
    }
}

/// The cache key of a render of `text`, a scene (or a variant of it) from `scene`: `format` (a recipe version), where
/// the scene lives ([`SceneFile::key_dir`]: a file's canonical directory, or the default scene's name, so the two
/// never share a key), the text as parsed and re-serialised (sorted keys, no comments) without the tables named in
/// `drop_tables` (those the study overrides), and `extra` (the settings the study sets: resolution, spp, seed,
/// mode…).
pub fn scene_key(
    format: &str,
    text: &str,
    scene: &SceneFile,
    drop_tables: &[&str],
    extra: &str,
) -> u64 {
    let dir = scene.key_dir();
    let canonical = toml::from_str::<toml::Table>(text)
        .ok()
        .and_then(|mut table| {
            for name in drop_tables {
                table.remove(*name);
            }
            toml::to_string(&table).ok()
        })
        .unwrap_or_else(|| text.to_owned());
    let mut h = Fnv1a::default();
    h.field(format).field(&dir).field(&canonical).field(extra);
    h.finish()
}

/// Writes `text` to `path` atomically ([`crate::util::atomic_file`]: temporary file in the same directory, then rename).
pub fn write_text(path: &Path, text: &str) -> Result<(), StudyError> {
    atomic_file::write(path, text.as_bytes()).map_err(|e| StudyError::Io {
        path: path.to_path_buf(),
        context: e.context,
        source: e.source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The published FNV-1a 64 test vectors (draft-eastlake-fnv): "" and "a" and "foobar".
    #[test]
    fn fnv1a_matches_the_reference_vectors() {
        assert_eq!(Fnv1a::default().finish(), 0xcbf2_9ce4_8422_2325);
        assert_eq!(Fnv1a::default().write(b"a").finish(), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(
            Fnv1a::default().write(b"foobar").finish(),
            0x8594_4171_f739_67e8
        );
        let ab_c = Fnv1a::default().field("ab").field("c").finish();
        let a_bc = Fnv1a::default().field("a").field("bc").finish();
        assert_ne!(ab_c, a_bc);
    }

    /// A file's key is the recipe over its canonical directory (so keys of files written before the default scene
    /// was accepted still match); the default scene's names no directory, and differs from the same text in a file.
    #[test]
    fn scene_keys_are_stable_for_files_and_distinct_for_the_default_scene() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("default.toml");
        std::fs::write(&path, crate::scene::DEFAULT_SCENE).unwrap();
        let file = SceneFile::read(&path).unwrap();
        let default = SceneFile::default_scene();
        let text = "[film]\nspp = 4\n";
        let canonical = std::fs::canonicalize(dir.path()).unwrap();
        let by_recipe = Fnv1a::default()
            .field("v1")
            .field(&canonical.to_string_lossy())
            .field(text)
            .field("extra")
            .finish();
        assert_eq!(scene_key("v1", text, &file, &[], "extra"), by_recipe);
        assert_ne!(
            scene_key("v1", text, &default, &[], "extra"),
            scene_key("v1", text, &file, &[], "extra")
        );
        assert_eq!(
            scene_key("v1", text, &default, &[], "extra"),
            scene_key("v1", text, &SceneFile::load(None).unwrap(), &[], "extra")
        );
    }
}
