//! A fibre material ready to shade: the scattering model of a scene's `[material]`, built once per frame.

use super::Bsdf;

/// A material ready to shade: the model and whether the strand colour tints its diffuse lobe.
pub struct Material {
    /// The scattering model, in the local hair frame.
    pub bsdf: Box<dyn Bsdf + Send + Sync>,
    /// `true` when the scene gave no diffuse `color`: the diffuse lobe is multiplied by each strand's colour.
    pub tint_diffuse_by_strand: bool,
    /// The model's scene name, for messages and summaries.
    pub name: &'static str,
}

impl std::fmt::Debug for Material {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Material")
            .field("name", &self.name)
            .field("tint_diffuse_by_strand", &self.tint_diffuse_by_strand)
            .finish()
    }
}
