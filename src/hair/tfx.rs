//! Reader (stub: being written).
use super::{HairError, HairModel};
use std::path::Path;

/// Reads a hair model from `path`.
pub fn read(path: &Path) -> Result<HairModel, HairError> {
    Err(HairError::invalid(path, "reader not written yet"))
}
