//! The command line's pieces, one file per command family: [`render`] (render, merge), [`bench`], [`study`],
//! [`tools`] (info, plot-bsdf, plot-csv). Each parses with clap, calls the library and prints; none renders.
//! This module holds the parsers they share.

pub mod bench;
pub mod render;
pub mod study;
pub mod tools;

use std::path::Path;

use anyhow::Result;
use serde::de::DeserializeOwned;

use cuticle::scene::Scene;

/// `WxH` (e.g. `640x480`), both at least 1.
pub fn parse_resolution(s: &str) -> Result<[u32; 2], String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("expected WxH, e.g. 640x480, got `{s}`"))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<u32>()
            .map_err(|_| format!("expected WxH, e.g. 640x480, got `{s}`"))
    };
    let (w, h) = (parse(w)?, parse(h)?);
    if w == 0 || h == 0 {
        return Err(format!("resolution must be at least 1x1, got `{s}`"));
    }
    Ok([w, h])
}

/// Parses a value the way the scene file spells it (`deep-opacity`, `flat`, ...), so the command line and the
/// TOML accept the same names and the library's types need no command-line derive.
pub fn scene_name<T: DeserializeOwned>(s: &str) -> Result<T, String> {
    T::deserialize(serde::de::value::StrDeserializer::<serde::de::value::Error>::new(s))
        .map_err(|e| e.to_string())
}

/// The scene file at `path` (a USD stage becomes a scene with defaults: [`Scene::from_usd`]), or the built-in
/// default scene (a procedural fur ball) without one.
pub fn load_scene(path: Option<&Path>) -> Result<Scene> {
    Ok(match path {
        Some(p) if cuticle::scene::is_usd(p) => Scene::from_usd(p)?,
        Some(p) => Scene::load(p)?,
        None => Scene::default_scene(),
    })
}

/// `--threads`: the count asked for, or one per core; at least 1.
pub fn threads(asked: Option<usize>) -> Result<usize> {
    match asked {
        Some(n) => cuticle::render::budget::check_threads(n).map_err(anyhow::Error::msg),
        None => Ok(std::thread::available_parallelism().map_or(1, |n| n.get())),
    }
}
