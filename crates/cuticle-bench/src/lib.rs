//! Criterion benchmarks of cuticle: `benches/bsdf.rs` (ns per eval / sample / pdf of each hair BSDF) and
//! `benches/curves.rs` (ns per round / flat ray–segment test). This package holds no code of its own; it exists so
//! that criterion stays out of the renderer's dependency graph (see its `Cargo.toml`).
