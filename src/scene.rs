//! Scene description (stub).
