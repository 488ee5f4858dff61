//! Procedural hair models (stub: being written).
