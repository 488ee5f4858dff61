//! Where a frame's hair comes from and how it is adjusted before tracing: a file or a generator, then the scene's
//! radius scale and opacity override.

use std::path::PathBuf;

use glam::Vec3;

use super::procedural::Procedural;
use super::{HairError, HairModel, Strands};

/// Where the hair comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum HairSource {
    /// A `.hair` or `.tfx` file (a path already resolved against the scene's directory).
    File(PathBuf),
    /// The `BasisCurves` of a USD stage (`.usda`, `.usdc`, `.usdz`, `.usd`), from the prim `prim` down (the whole
    /// stage when `None`), converted exactly to B-spline strands by [`crate::usd`].
    Usd {
        /// The stage's root layer (resolved against the scene's directory).
        path: PathBuf,
        /// The prim whose subtree is read.
        prim: Option<String>,
    },
    /// A generated model.
    Procedural(Procedural),
}

impl HairSource {
    /// The file, or `procedural:<kind>`: how errors name this source.
    pub fn name(&self) -> PathBuf {
        match self {
            HairSource::File(path) | HairSource::Usd { path, .. } => path.clone(),
            HairSource::Procedural(p) => p.source(),
        }
    }

    /// Reads or generates the model (polylines; a USD stage's curves are not polylines: see
    /// [`HairSource::strands`]).
    pub fn model(&self) -> Result<HairModel, HairError> {
        match self {
            HairSource::File(path) => super::load(path),
            HairSource::Procedural(p) => p.generate(),
            HairSource::Usd { path, .. } => Err(HairError::invalid(
                path,
                "a USD stage's curves are read as strands, not as polylines",
            )),
        }
    }

    /// The strands, and how many strands of zero length were left out: a polyline model converted
    /// ([`Strands::from_model`]), or a USD stage's curves as its reader converts them. Every point, inflated by its
    /// radius × `radius_scale`, is checked to lie within reach of single-precision rays ([`super::check_extent`]:
    /// the model's points, or a stage's control points).
    pub fn strands(&self, radius_scale: f32) -> Result<(Strands, usize), HairError> {
        let scaled = || format!(" with hair.radius_scale = {radius_scale:e}");
        if let HairSource::Usd { path, prim } = self {
            let curves = crate::usd::Parts {
                curves: true,
                meshes: false,
            };
            let stage =
                crate::usd::read_parts(path, prim.as_deref(), crate::usd::DEFAULT_RADIUS, curves)
                    .map_err(|e| HairError::invalid(path, e.without_file()))?;
            return match stage.strands {
                Some(s) if s.strand_count() > 0 => {
                    if radius_scale != 1.0 {
                        let points: Vec<Vec3> = s
                            .control_points
                            .iter()
                            .map(|c| Vec3::new(c[0], c[1], c[2]))
                            .collect();
                        let radius: Vec<f32> = s.control_points.iter().map(|c| c[3]).collect();
                        super::check_extent(path, &points, &radius, radius_scale, &scaled())?;
                    }
                    Ok((s, 0))
                }
                _ => Err(HairError::invalid(
                    path,
                    format!(
                        "no BasisCurves under {}",
                        prim.as_deref().unwrap_or("the stage's root")
                    ),
                )),
            };
        }
        let mut model = self.model()?;
        let zero_length = model.drop_zero_length();
        if model.strand_count() == 0 {
            return Err(HairError::invalid(
                &self.name(),
                format!(
                    "all {zero_length} strands have zero length (every point of each at one place)"
                ),
            ));
        }
        if radius_scale != 1.0 {
            super::check_extent(
                &self.name(),
                &model.points,
                &model.radius,
                radius_scale,
                &scaled(),
            )?;
        }
        Ok((Strands::from_model(&model), zero_length))
    }
}

/// A hair model with the adjustments a scene applies to it.
#[derive(Debug, Clone, PartialEq)]
pub struct HairSpec {
    /// The model.
    pub source: HairSource,
    /// Multiplies every strand radius.
    pub radius_scale: f32,
    /// Replaces every strand's opacity for light-carrying rays.
    pub opacity: Option<f32>,
}

impl HairSpec {
    /// Loads the model and converts it to B-spline strands with the radius scale and opacity applied.
    pub fn load(&self) -> Result<Strands, HairError> {
        self.load_counting().map(|(strands, _)| strands)
    }

    /// [`HairSpec::load`], leaving out the strands of zero length ([`HairModel::drop_zero_length`]), and how many
    /// there were. A model of nothing else is an error.
    pub fn load_counting(&self) -> Result<(Strands, usize), HairError> {
        let (mut strands, zero_length) = self.source.strands(self.radius_scale)?;
        if self.radius_scale != 1.0 {
            strands
                .control_points
                .iter_mut()
                .for_each(|c| c[3] *= self.radius_scale);
        }
        if let Some(o) = self.opacity {
            strands.set_opacity(o);
        }
        Ok((strands, zero_length))
    }
}
