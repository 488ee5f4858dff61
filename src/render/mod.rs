//! Rendering (stub).
