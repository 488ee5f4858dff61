//! Deep opacity maps (Yuksel & Keyser 2008, "Deep Opacity Maps", Computer Graphics Forum 27(2)): the shadow maps
//! the thesis got its best hair images from (§5.4, §6.4), here per light of a cuticle scene.
//!
//! # The method
//!
//! Seen from the light, every texel stores
//! 1. **z0**, the depth of the nearest strand (pass 1), and
//! 2. **k layers** of opacity behind it (pass 2): layer i collects the strands whose depth z lies in
//!    [z0 + d_i, z0 + d_{i+1}), the last layer reaching to infinity.
//!
//! Because the layers start at each texel's own z0, they follow the hair's silhouette: few layers suffice where
//! opacity shadow maps (Kim & Neumann 2001), whose slices are planes, need hundreds. A lookup at depth z finds its
//! layer and interpolates linearly inside it, giving the optical depth Ω between the light and z; the transmittance
//! is exp(−Ω).
//!
//! # Opacity as optical depth
//!
//! A strand of opacity a (cuticle's per-strand opacity, the same the ray-traced mode uses) that covers a texel
//! centre adds σ = −ln(1 − a) to its layer, so n strands in front of a point give exp(−Σσ) = ∏(1 − a): the exact
//! transmittance of the ray-traced `transmittance = "exact"` mode, up to the map's sampling. Yuksel & Keyser
//! accumulate opacity additively and map it through exp(−κ Ω); with κ = 1 and σ as above the two agree.
//!
//! # Building: rasterised, not ray traced
//!
//! Each B-spline segment is cut into pieces about a texel long; each piece is a 2-D line of the strand's projected
//! width, and every texel whose *centre* it covers gets a fragment (point sampling, as a GPU rasterises lines).
//! A strand thinner than `min_width` texels is drawn `min_width` wide with opacity a · w / min_width (RenderMan's
//! `hair minwidth`, thesis §5.5): without it, strands thinner than a texel fall between texel centres and light
//! leaks through; drawn wider at full opacity they over-darken (both shown by a test in `raster.rs`).
//!
//! Rasterising was chosen over tracing one ray per texel through Embree: the fur ball's 455k segments rasterise into
//! a 1024² map in tens of milliseconds on 2 cores, whereas an all-hits ray per texel runs at ~0.2 Mrays/s inside
//! that fur (`cuticle bench trace`, exact transmittance), i.e. ≈5 s per map — and still aliases without several
//! rays per texel. Both passes run in parallel over strands; fragments are accumulated with integer atomics
//! (z0 by `fetch_min` on the float's bits, optical depth in fixed point by `fetch_add`), so the map is the same
//! whatever the thread count or order.
//!
//! # Lookup
//!
//! Percentage-closer filtering: the transmittance of each texel in a tent footprint of radius `filter + 1` texels is
//! computed against that texel's own z0 and the results are averaged. The lookup depth is moved towards the light by
//! `bias` texels (a texel's world size at the point) so a strand does not shadow itself.
//!
//! # Lights
//!
//! Distant lights get an orthographic map along their direction (a sun of finite size is treated as its centre
//! direction); area lights a perspective map from their centre (all points of the light share it: the map is a
//! point-light approximation, as the thesis' RenderMan maps were). An **environment** gets one orthographic map
//! per cell of a Fibonacci partition of the sphere into `environment_directions` cells, each looking along the
//! cell's radiance-weighted mean direction; a light sample from direction ω reads the map of ω's cell. The error of
//! that approximation (a direction up to a cell's radius, ≈ 2/√K rad, from its map) is measured by
//! `cuticle study shadows`. Environment maps use half the configured resolution (memory: K maps).
//!
//! # Files
//!
//! - `framing.rs`: [`MapFrame`], the light's projection (orthographic or perspective) and texel geometry.
//! - `raster.rs`: [`Raster`] and the rasteriser that turns strands into fragments at texel centres.
//! - `map.rs`: [`DeepOpacityMap`], its layers, the two build passes and the filtered lookup.
//! - `lights.rs`: [`ShadowMaps`], the maps of every light, with the environment's Fibonacci cells.
//! - `test_field.rs` (tests only): the synthetic strand field on which the failure-mode tests measure the method.

mod framing;
mod lights;
mod map;
mod raster;
#[cfg(test)]
mod test_field;

pub use framing::MapFrame;
pub use lights::{environment_resolution, fibonacci_sphere, ShadowMaps};
pub use map::DeepOpacityMap;
pub use raster::Raster;
