//! Where a frame's hair comes from and how it is adjusted before tracing: a file or a generator, then the scene's
//! radius scale and opacity override.

use std::path::PathBuf;

use super::procedural::Procedural;
use super::{HairError, HairModel, Strands};

/// Where the hair comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum HairSource {
    /// A `.hair` or `.tfx` file (a path already resolved against the scene's directory).
    File(PathBuf),
    /// A generated model.
    Procedural(Procedural),
}

impl HairSource {
    /// The file, or `procedural:<kind>`: how errors name this source.
    pub fn name(&self) -> PathBuf {
        match self {
            HairSource::File(path) => path.clone(),
            HairSource::Procedural(p) => p.source(),
        }
    }

    /// Reads or generates the model.
    pub fn model(&self) -> Result<HairModel, HairError> {
        match self {
            HairSource::File(path) => super::load(path),
            HairSource::Procedural(p) => p.generate(),
        }
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
        let mut model = self.source.model()?;
        let zero_length = model.drop_zero_length();
        if model.strand_count() == 0 {
            return Err(HairError::invalid(
                &self.source.name(),
                format!(
                    "all {zero_length} strands have zero length (every point of each at one place)"
                ),
            ));
        }
        if self.radius_scale != 1.0 {
            super::check_extent(
                &self.source.name(),
                &model.points,
                &model.radius,
                self.radius_scale,
                &format!(" with hair.radius_scale = {:e}", self.radius_scale),
            )?;
        }
        let mut strands = Strands::from_model(&model);
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
