//! The Embree strand tracer (stub: being written).
use super::{CurveKind, Hit, Tracer};
use crate::hair::Strands;
use crate::ray::{InvalidRay, Ray};

/// Strands in an Embree scene as native curves.
pub struct EmbreeTracer {
    _kind: CurveKind,
}

impl EmbreeTracer {
    /// Builds an Embree scene for `strands` with curves of type `kind`.
    pub fn new(
        _strands: &Strands,
        kind: CurveKind,
    ) -> Result<Self, crate::sys::embree::EmbreeError> {
        Ok(EmbreeTracer { _kind: kind })
    }
}

impl Tracer for EmbreeTracer {
    fn intersect(&self, ray: &Ray) -> Result<Option<Hit>, InvalidRay> {
        ray.check()?;
        todo!("issue 3: embree intersect")
    }
    fn transmittance(&self, ray: &Ray, _ignore_strand: Option<u32>) -> Result<f32, InvalidRay> {
        ray.check()?;
        todo!("issue 3: embree transmittance")
    }
}
