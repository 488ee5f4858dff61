//! [`TriangleGeometry`]: triangle meshes as Embree `RTC_GEOMETRY_TYPE_TRIANGLE` geometries.

use std::fmt;
use std::sync::Arc;

use super::device::{Device, DeviceHandle};
use super::error::EmbreeError;
use super::ffi::*;
use super::geometry::{fill_buffer, new_geometry};
#[cfg(doc)]
use super::scene::Scene;

/// A triangle mesh, committed and ready to attach to a [`Scene`] (robust scenes, [`Scene::robust`], trace it with
/// Embree's watertight test). Its hits report the index of the triangle in the index buffer as `primID` and the
/// barycentrics (u, v) of the point a + u (b − a) + v (c − a).
pub struct TriangleGeometry {
    pub(super) raw: RTCGeometry,
    device: Arc<DeviceHandle>,
    triangles: usize,
}

// SAFETY: a committed Embree geometry has no thread affinity, and this wrapper offers no mutation after creation.
unsafe impl Send for TriangleGeometry {}

impl fmt::Debug for TriangleGeometry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("TriangleGeometry")
            .field("triangles", &self.triangles)
            .finish()
    }
}

impl TriangleGeometry {
    /// A mesh of `triangles` (indices into `positions`, `RTC_FORMAT_UINT3`) over `positions` (`RTC_FORMAT_FLOAT3`,
    /// 12-byte stride). Embree copies both into buffers it owns; `rtcSetNewGeometryBuffer` pads a vertex buffer so
    /// that its last `float3` can be read with a 16-byte SIMD load, which is what Embree's triangle kernels do, so
    /// no padding is needed on this side. Every index and position is checked here, because Embree reads the
    /// vertex buffer unchecked and aborts on a non-finite vertex.
    pub fn new(
        device: &Device,
        positions: &[[f32; 3]],
        triangles: &[[u32; 3]],
    ) -> Result<TriangleGeometry, EmbreeError> {
        // Embree counts buffer items in 32 bits.
        if positions.len() > u32::MAX as usize || triangles.len() > u32::MAX as usize {
            return Err(EmbreeError::invalid_argument(format!(
                "triangle geometry: {} points and {} triangles, at most {} of each are supported",
                positions.len(),
                triangles.len(),
                u32::MAX
            )));
        }
        if let Some((t, tri)) = triangles
            .iter()
            .enumerate()
            .find(|(_, tri)| tri.iter().any(|&i| i as usize >= positions.len()))
        {
            return Err(EmbreeError::invalid_argument(format!(
                "triangle geometry: triangle {t} is {tri:?}, but there are {} points",
                positions.len()
            )));
        }
        if let Some((i, p)) = positions
            .iter()
            .enumerate()
            .find(|(_, p)| !p.iter().all(|c| c.is_finite()))
        {
            return Err(EmbreeError::invalid_argument(format!(
                "triangle geometry: point {i} is {p:?} (needs finite coordinates)"
            )));
        }
        let handle = &device.inner;
        let raw = new_geometry(
            handle,
            RTC_GEOMETRY_TYPE_TRIANGLE,
            "create triangle geometry",
        )?;
        // From here on `Drop` releases `raw` on every error path.
        let geometry = TriangleGeometry {
            raw,
            device: Arc::clone(handle),
            triangles: triangles.len(),
        };
        fill_buffer(
            &geometry.device,
            raw,
            RTC_BUFFER_TYPE_VERTEX,
            RTC_FORMAT_FLOAT3,
            positions,
            "vertex",
        )?;
        fill_buffer(
            &geometry.device,
            raw,
            RTC_BUFFER_TYPE_INDEX,
            RTC_FORMAT_UINT3,
            triangles,
            "index",
        )?;
        geometry.device.call("commit triangle geometry", || {
            // SAFETY: `raw` is live and both of its buffers are set.
            unsafe { rtcCommitGeometry(raw) };
        })?;
        Ok(geometry)
    }

    /// Number of triangles (Embree primitives).
    pub fn triangle_count(&self) -> usize {
        self.triangles
    }
}

impl Drop for TriangleGeometry {
    fn drop(&mut self) {
        self.device.release("release triangle geometry", || {
            // SAFETY: we own one reference to `raw` and give it up exactly once; a scene it is attached to holds
            // its own reference.
            unsafe { rtcReleaseGeometry(self.raw) }
        });
    }
}
