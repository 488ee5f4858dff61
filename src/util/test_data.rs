//! Where the unit tests find the third-party data (hair models, environment maps; see docs/data.md): the folder
//! named by the environment variable `CUTICLE_DATA`, by default `../shared/data` beside the repository. A test
//! whose data is missing fails naming the file; it never passes without it.

use std::path::PathBuf;

/// The data folder: `$CUTICLE_DATA`, or `<repository>/../shared/data`.
pub(crate) fn dir() -> PathBuf {
    match std::env::var_os("CUTICLE_DATA") {
        Some(d) if !d.is_empty() => PathBuf::from(d),
        _ => PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data")),
    }
}

/// `rel` (e.g. `hair/straight.hair`) in the data folder. Panics naming the file when it is missing.
#[track_caller]
pub(crate) fn file(rel: &str) -> PathBuf {
    let path = dir().join(rel);
    assert!(path.exists(), "{}", missing(&path));
    path
}

/// The failure of a test whose data file or folder `path` is missing.
pub(crate) fn missing(path: &std::path::Path) -> String {
    format!(
        "missing test data {}: set CUTICLE_DATA to a folder holding it (see docs/data.md)",
        path.display()
    )
}
