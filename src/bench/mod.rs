//! Benchmarks (`cuticle bench …`): each prints a human-readable report plus, where scripts need them, one line per
//! measurement. `trace`: ray throughput of each backend per ray type; `frame`: a whole render; `replay`: a frame's rays
//! traced again by the tracer alone (`packets`: and through Embree's packet queries); `shadows`: the cost
//! of each self-shadowing mode; `build`: build time and memory of each backend on big procedural grooms.

pub mod build;
pub mod frame;
pub mod packets;
pub mod replay;
pub mod shadows;
pub mod trace;

pub use trace::{scene_config, trace, TraceConfig, TraceReport};

use crate::accel::embree::EmbreeError;

/// Why a benchmark could not run.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// Embree could not build the scene.
    #[error(transparent)]
    Embree(#[from] EmbreeError),
    /// The rayon thread pool could not be created.
    #[error("bench: could not create a pool of {threads} threads: {source}")]
    ThreadPool {
        /// The requested thread count.
        threads: usize,
        /// Rayon's error.
        source: rayon::ThreadPoolBuildError,
    },
}
