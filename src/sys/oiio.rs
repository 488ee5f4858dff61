//! Safe wrappers over the OpenImageIO shim (stub: being written).
