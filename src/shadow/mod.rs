//! Self-shadowing by shadow maps: the second shadow mode of the thesis (§5.4, §6.4), beside the ray-traced shadows of
//! [`crate::render::integrator`].
//!
//! - [`deep_opacity`]: Yuksel & Keyser 2008's deep opacity maps, one per shadow-casting light (several for an
//!   environment), built by rasterising the strands from the light.
//! - [`ShadowMaps`]: the maps of every light of a scene, and the lookup the integrator calls in place of a shadow
//!   ray (`shadows = "deep-opacity"`).

pub mod deep_opacity;

use serde::Deserialize;

pub use deep_opacity::{DeepOpacityMap, ShadowMaps};

/// How the layers of a deep opacity map are spaced behind the nearest strand z0.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LayerSpacing {
    /// Layers of equal thickness (Yuksel & Keyser's default).
    Uniform,
    /// Layer i is i + 1 times as thick as the first: thin layers near z0, where the shadow gradient is steepest,
    /// thick ones deep inside the hair (their suggestion for a fixed layer budget).
    #[default]
    Growing,
}

/// `[shadows.deep_opacity]`: the deep opacity maps of `shadows = "deep-opacity"`.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct DeepOpacityConfig {
    /// Texels along each side of a map.
    pub resolution: u32,
    /// Opacity layers behind z0 (the last layer reaches to infinity).
    pub layers: u32,
    /// Layer spacing.
    pub spacing: LayerSpacing,
    /// Depth covered by the layers, in multiples of the hair's bounding-sphere radius (0.25 ≈ the outer quarter of a
    /// fur ball: light rarely gets further).
    pub depth: f32,
    /// Strands thinner than this many texels are drawn this wide with their opacity scaled down by the same factor
    /// (RenderMan's `hair minwidth`, thesis §5.5), so coverage is kept and thin strands do not drop out of texels.
    pub min_width: f32,
    /// Radius, in texels, of the percentage-closer filter: the lookup averages the transmittance of the texels
    /// in a tent of radius r + 1, each against its own z0. 0 (the default) is the bilinear 2 × 2 footprint: the
    /// camera samples' jitter already averages lookups over a pixel, and each texel more costs an exp().
    pub filter: u32,
    /// Depth bias, in texels (a texel's world size at the lookup point): a lookup at depth z reads z − bias, so a
    /// strand does not shadow itself. The default, 2, removes the acne of a sheet of strands tilted 45° to the
    /// light with margin (a test in `deep_opacity/map.rs`: mean T 0.20 without bias, 0.96 at 1 texel, 1.00 from 1.5
    /// texels). A wider `filter` reaches further up a tilted strand and needs more.
    pub bias: f32,
    /// Maps for an environment light: one per cell of a Fibonacci partition of the sphere, looking along the
    /// cell's radiance-weighted mean direction.
    pub environment_directions: u32,
}

impl Default for DeepOpacityConfig {
    fn default() -> Self {
        DeepOpacityConfig {
            resolution: 1024,
            layers: 16,
            spacing: LayerSpacing::Growing,
            depth: 0.25,
            min_width: 1.0,
            filter: 0,
            bias: 2.0,
            environment_directions: 16,
        }
    }
}

/// The widest `min_width` a map may draw strands with, texels (see [`DeepOpacityConfig::validate`]).
pub const MAX_MIN_WIDTH: f32 = 16.0;

impl DeepOpacityConfig {
    /// Range checks; messages name the key.
    pub fn validate(&self) -> Result<(), String> {
        let key = "shadows.deep_opacity";
        if !(16..=8192).contains(&self.resolution) {
            return Err(format!(
                "{key}.resolution must be in [16, 8192], got {}",
                self.resolution
            ));
        }
        if !(1..=256).contains(&self.layers) {
            return Err(format!(
                "{key}.layers must be in [1, 256], got {}",
                self.layers
            ));
        }
        if !(self.depth.is_finite() && self.depth > 0.0) {
            return Err(format!("{key}.depth must be > 0, got {}", self.depth));
        }
        // Bounded, as the build's cost is: a strand drawn w texels wide covers w² / w = w times the texels of one
        // drawn 1 texel wide (10: 1 s, 100: 10 s, 1000: over 100 s for a 48² map); 16 is already a blur far past
        // RenderMan's minwidth of about a pixel.
        if !(self.min_width.is_finite() && (0.0..=MAX_MIN_WIDTH).contains(&self.min_width)) {
            return Err(format!(
                "{key}.min_width must be in [0, {MAX_MIN_WIDTH}] texels, got {}",
                self.min_width
            ));
        }
        if self.filter > 16 {
            return Err(format!(
                "{key}.filter must be in [0, 16] texels, got {}",
                self.filter
            ));
        }
        if !(self.bias.is_finite() && self.bias >= 0.0) {
            return Err(format!("{key}.bias must be >= 0 texels, got {}", self.bias));
        }
        if !(1..=256).contains(&self.environment_directions) {
            return Err(format!(
                "{key}.environment_directions must be in [1, 256], got {}",
                self.environment_directions
            ));
        }
        Ok(())
    }
}
