//! Image output and input through OpenImageIO (stub: being written).
