//! Safe wrappers over Embree (stub: being written).
/// An error reported by Embree.
#[derive(Debug, thiserror::Error)]
#[error("embree: {message}")]
pub struct EmbreeError {
    /// What Embree said.
    pub message: String,
}
