//! Small shared tools below the physics, each with its own tests (as pbrt-v4's `util/hash.h`, `util/sampling.h`
//! sit under its BxDFs): every layer above may import them, and they import nothing of this crate.
//!
//! - [`atomic_file`]: a temporary file beside the target, renamed over it only when complete.
//! - [`exact_array`]: fixed-size arrays in scene files that must have exactly their length.
//! - [`input_file`]: reading user-named files with a size bound, regular files only.
//! - [`report`]: an error and its causes on one line, each said once.
//! - [`hash`]: SplitMix64's finaliser and the SplitMix64 generator (strand presence, the sampler's scrambling
//!   seeds, per-strand noise, procedural hair).
//! - [`color`]: Rec. 709 luminance.
//! - [`real`]: the number type shading code is written over once, for one value (`f32`) or eight lanes (`f32x8`).
//! - [`sampling`]: uniform sampling of the sphere.
//! - [`stats`]: Pearson's χ² test with pbrt-v4's pooling, and Šidák's correction (BSDF and light tests,
//!   `plot-bsdf`).

pub mod atomic_file;
pub mod color;
pub mod exact_array;
pub mod hash;
pub mod input_file;
pub mod lanes;
pub mod real;
pub mod report;
pub mod sampling;
pub mod stats;
#[cfg(test)]
pub(crate) mod test_data;
