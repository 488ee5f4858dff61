//! The maps of every light of a scene: one per distant or area light, one per Fibonacci cell of an environment
//! (see "Lights" in the [module docs](super)).

use glam::Vec3;

use super::{DeepOpacityMap, MapFrame, Raster};
use crate::hair::Strands;
use crate::light::Light;
use crate::shadow::DeepOpacityConfig;
use crate::util::color::luminance;

/// The least depth counting maps' layers cover, in bounding-sphere radii: its diameter.
pub const COUNTED_DEPTH: f32 = 2.0;

/// What stands in for a shadow ray towards light j.
#[derive(Debug, Clone)]
enum LightMaps {
    /// One map for every direction of the light.
    One(Box<DeepOpacityMap>),
    /// An environment: cell directions (Fibonacci points) and one map per cell.
    Cells {
        centres: Vec<Vec3>,
        maps: Vec<DeepOpacityMap>,
    },
    /// No map could be framed (an area light inside the hair's bounding sphere): ray-traced shadows instead.
    Raytraced,
}

/// The deep opacity maps of every light of a scene.
#[derive(Debug, Clone)]
pub struct ShadowMaps {
    lights: Vec<LightMaps>,
}

/// Texels along a side of each of an environment's maps, for maps of `resolution` elsewhere: half (at least 16),
/// since an environment gets one map per direction.
pub fn environment_resolution(resolution: u32) -> u32 {
    (resolution / 2).max(16)
}

/// `n` points spread evenly over the sphere (the spherical Fibonacci lattice).
pub fn fibonacci_sphere(n: u32) -> Vec<Vec3> {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - (2.0 * i as f32 + 1.0) / n as f32;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = golden * i as f32;
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

#[inline]
fn nearest(centres: &[Vec3], w: Vec3) -> usize {
    let mut best = (0, f32::NEG_INFINITY);
    for (i, c) in centres.iter().enumerate() {
        let d = c.dot(w);
        if d > best.1 {
            best = (i, d);
        }
    }
    best.0
}

impl ShadowMaps {
    /// Builds the maps of `lights` for `strands`; with `count`, each map also counts the strands per layer
    /// ([`ShadowMaps::strands`], for dual scattering) and its layers reach through the whole hair (at least a
    /// bounding-sphere diameter, whatever `config.depth` says), since the strands behind a point count as much as
    /// those in front of it.
    pub fn build(
        strands: &Strands,
        lights: &[Light],
        config: &DeepOpacityConfig,
        count: bool,
    ) -> ShadowMaps {
        let (lo, hi) = strands.bounds();
        let center = 0.5 * (lo + hi);
        let radius = (0.5 * (hi - lo).length()).max(1e-6);
        let depth = if count {
            config.depth.max(COUNTED_DEPTH)
        } else {
            config.depth
        } * radius;
        let raster = Raster {
            min_width: config.min_width,
            keep_coverage: true,
        };
        let map = |frame| DeepOpacityMap::build(strands, frame, config, depth, raster, count);
        let lights = lights
            .iter()
            .map(|light| match light {
                Light::Distant(d) => LightMaps::One(Box::new(map(MapFrame::fit_orthographic(
                    -d.to_sun(),
                    strands,
                    config.resolution,
                )))),
                Light::Area(a) => {
                    match MapFrame::perspective(
                        a.shape().center(),
                        center,
                        radius,
                        config.resolution,
                    ) {
                        Some(frame) => LightMaps::One(Box::new(map(frame))),
                        None => LightMaps::Raytraced,
                    }
                }
                Light::Environment(_) => {
                    let centres = fibonacci_sphere(config.environment_directions);
                    let directions = environment_directions(light, &centres);
                    let resolution = environment_resolution(config.resolution);
                    let maps = directions
                        .iter()
                        .map(|&to_light| {
                            map(MapFrame::fit_orthographic(-to_light, strands, resolution))
                        })
                        .collect();
                    LightMaps::Cells { centres, maps }
                }
            })
            .collect();
        ShadowMaps { lights }
    }

    /// The map a lookup towards light `light` along `wi` (towards the light) reads: the light's own, or its
    /// environment cell's; `None` when this light has no map and needs rays.
    #[inline]
    fn map_towards(&self, light: usize, wi: Vec3) -> Option<&DeepOpacityMap> {
        match &self.lights[light] {
            LightMaps::One(m) => Some(m),
            LightMaps::Cells { centres, maps } => Some(&maps[nearest(centres, wi)]),
            LightMaps::Raytraced => None,
        }
    }

    /// Transmittance towards light `light` from `p` along `wi` (towards the light); `None` when this light has no
    /// map and needs a shadow ray.
    #[inline]
    pub fn transmittance(&self, light: usize, p: Vec3, wi: Vec3) -> Option<f32> {
        Some(self.map_towards(light, wi)?.transmittance(p))
    }

    /// The strands ahead of `p` towards light `light` along `wi`, those behind it, and the share of light that
    /// crosses none ([`DeepOpacityMap::strands`]); `None` when this light has no map or the maps do not count.
    #[inline]
    pub fn strands(&self, light: usize, p: Vec3, wi: Vec3) -> Option<[f32; 3]> {
        self.map_towards(light, wi)?.strands(p)
    }

    /// Memory held by all maps, bytes.
    pub fn bytes(&self) -> usize {
        self.lights
            .iter()
            .map(|l| match l {
                LightMaps::One(m) => m.bytes(),
                LightMaps::Cells { maps, .. } => maps.iter().map(DeepOpacityMap::bytes).sum(),
                LightMaps::Raytraced => 0,
            })
            .sum()
    }

    /// Every map with a name (`light0`, `light1.cell3`, …), for inspection.
    pub fn maps(&self) -> Vec<(String, &DeepOpacityMap)> {
        let mut out = Vec::new();
        for (j, l) in self.lights.iter().enumerate() {
            match l {
                LightMaps::One(m) => out.push((format!("light{j}"), m.as_ref())),
                LightMaps::Cells { maps, .. } => {
                    for (c, m) in maps.iter().enumerate() {
                        out.push((format!("light{j}.cell{c}"), m));
                    }
                }
                LightMaps::Raytraced => {}
            }
        }
        out
    }
}

/// Radiance-weighted mean direction (towards the light) of each Fibonacci cell of an environment, estimated from
/// stratified importance samples; a cell no sample reached keeps its centre.
fn environment_directions(light: &Light, centres: &[Vec3]) -> Vec<Vec3> {
    const PER_SIDE: u32 = 128;
    let mut sums = vec![Vec3::ZERO; centres.len()];
    for i in 0..PER_SIDE {
        for j in 0..PER_SIDE {
            let u = [
                (i as f32 + 0.5) / PER_SIDE as f32,
                (j as f32 + 0.5) / PER_SIDE as f32,
            ];
            let Some(ls) = light.sample_li(Vec3::ZERO, u) else {
                continue;
            };
            let weight = luminance(ls.radiance) / ls.pdf;
            if weight.is_finite() && weight > 0.0 {
                sums[nearest(centres, ls.wi)] += weight * ls.wi;
            }
        }
    }
    sums.iter()
        .zip(centres)
        .map(|(s, c)| s.try_normalize().unwrap_or(*c))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn environment_cells_follow_the_light() {
        let centres = fibonacci_sphere(16);
        assert!(centres.iter().all(|c| (c.length() - 1.0).abs() < 1e-5));
        // A constant environment: every cell's mean direction stays inside its own cell.
        let env = Light::Environment(crate::light::Environment::constant(Vec3::ONE).unwrap());
        let dirs = environment_directions(&env, &centres);
        for (i, d) in dirs.iter().enumerate() {
            assert_eq!(
                nearest(&centres, *d),
                i,
                "cell {i}: mean direction {d} left its cell"
            );
        }
    }
}
