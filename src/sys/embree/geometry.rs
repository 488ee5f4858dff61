//! [`StrandTable`] (segment → strand → opacity, what the filters read) and [`CurveGeometry`] (B-spline curves that
//! carry one as their Embree user data).

use std::ffi::c_void;
use std::fmt;
use std::ptr;
use std::sync::Arc;

use super::device::{Device, DeviceHandle};
use super::error::{EmbreeError, ErrorCode};
use super::ffi::*;
#[cfg(doc)]
use super::scene::Scene;

/// Marks "no strand" in `TransmittanceQuery::ignore_strand`; [`StrandTable::new`] keeps real ids below it.
pub(super) const NO_STRAND: u32 = u32::MAX;

/// Per-geometry shading data the shadow filter needs: which strand each segment (Embree `primID`) belongs to, and
/// each strand's opacity. Strand ids are scene-wide: two geometries in one scene should not reuse them.
#[derive(Debug, Clone, PartialEq)]
pub struct StrandTable {
    segment_strand: Vec<u32>,
    opacity: Vec<f32>,
}

impl StrandTable {
    /// Checks that every segment names an existing strand and every opacity is in [0, 1].
    pub fn new(segment_strand: Vec<u32>, opacity: Vec<f32>) -> Result<StrandTable, EmbreeError> {
        if opacity.len() >= NO_STRAND as usize {
            return Err(EmbreeError::invalid_argument(format!(
                "strand table: {} strands, at most {} are supported",
                opacity.len(),
                NO_STRAND - 1
            )));
        }
        if let Some((segment, strand)) = segment_strand
            .iter()
            .enumerate()
            .find(|(_, s)| **s as usize >= opacity.len())
        {
            return Err(EmbreeError::invalid_argument(format!(
                "strand table: segment {segment} belongs to strand {strand}, but there are only {} strands",
                opacity.len()
            )));
        }
        if let Some((strand, a)) = opacity
            .iter()
            .enumerate()
            .find(|(_, a)| !(0.0..=1.0).contains(*a))
        {
            return Err(EmbreeError::invalid_argument(format!(
                "strand table: strand {strand} has opacity {a} (must be in [0, 1])"
            )));
        }
        Ok(StrandTable {
            segment_strand,
            opacity,
        })
    }

    /// Heap bytes of the table.
    pub fn bytes(&self) -> usize {
        std::mem::size_of_val(self.segment_strand.as_slice())
            + std::mem::size_of_val(self.opacity.as_slice())
    }

    /// Number of segments (Embree primitives).
    pub fn segment_count(&self) -> usize {
        self.segment_strand.len()
    }

    /// Number of strands.
    pub fn strand_count(&self) -> usize {
        self.opacity.len()
    }

    /// The strand segment `segment` belongs to.
    pub fn strand_of(&self, segment: u32) -> Option<u32> {
        self.segment_strand.get(segment as usize).copied()
    }

    /// The opacity of strand `strand`.
    pub fn opacity(&self, strand: u32) -> Option<f32> {
        self.opacity.get(strand as usize).copied()
    }

    /// (strand, opacity) of a segment.
    pub(super) fn lookup(&self, segment: u32) -> Option<(u32, f32)> {
        let strand = self.strand_of(segment)?;
        Some((strand, self.opacity(strand)?))
    }
}

/// Which Embree curve type strands become.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CurveBasis {
    /// `RTC_GEOMETRY_TYPE_ROUND_BSPLINE_CURVE`: a swept circle of varying radius (a true tube).
    RoundBSpline,
    /// `RTC_GEOMETRY_TYPE_FLAT_BSPLINE_CURVE`: a ribbon that always faces the ray.
    FlatBSpline,
}

/// Uniform cubic B-spline curves with their strand table, committed and ready to attach to a [`Scene`].
pub struct CurveGeometry {
    pub(super) raw: RTCGeometry,
    device: Arc<DeviceHandle>,
    strands: Arc<StrandTable>,
}

// SAFETY: a committed Embree geometry has no thread affinity, and this wrapper offers no mutation after creation;
// the strand table is immutable.
unsafe impl Send for CurveGeometry {}

impl fmt::Debug for CurveGeometry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("CurveGeometry")
            .field("segments", &self.strands.segment_count())
            .field("strands", &self.strands.strand_count())
            .finish()
    }
}

impl CurveGeometry {
    /// B-spline curves: `control_points` are `(x, y, z, radius)` (`RTC_FORMAT_FLOAT4`); segment `k` uses control
    /// points `segment_first[k] .. segment_first[k] + 4` (`RTC_FORMAT_UINT` index buffer). `strands` must have
    /// one entry per segment. Every index is checked here, because Embree reads the vertex buffer unchecked.
    pub fn bspline(
        device: &Device,
        basis: CurveBasis,
        control_points: &[[f32; 4]],
        segment_first: &[u32],
        strands: Arc<StrandTable>,
    ) -> Result<CurveGeometry, EmbreeError> {
        if segment_first.len() != strands.segment_count() {
            return Err(EmbreeError::invalid_argument(format!(
                "curve geometry: {} segments but the strand table has {}",
                segment_first.len(),
                strands.segment_count()
            )));
        }
        // Embree counts buffer items in 32 bits.
        if control_points.len() > u32::MAX as usize {
            return Err(EmbreeError::invalid_argument(format!(
                "curve geometry: {} control points, at most {} are supported",
                control_points.len(),
                u32::MAX
            )));
        }
        if let Some((k, first)) = segment_first
            .iter()
            .enumerate()
            .find(|(_, f)| **f as usize + 3 >= control_points.len())
        {
            return Err(EmbreeError::invalid_argument(format!(
                "curve geometry: segment {k} starts at control point {first}, but a cubic segment needs 4 of \
                 the {} control points",
                control_points.len()
            )));
        }
        if let Some((i, p)) = control_points
            .iter()
            .enumerate()
            .find(|(_, p)| !(p.iter().all(|c| c.is_finite()) && p[3] >= 0.0))
        {
            return Err(EmbreeError::invalid_argument(format!(
                "curve geometry: control point {i} is {p:?} (needs finite coordinates and radius >= 0)"
            )));
        }
        let kind = match basis {
            CurveBasis::RoundBSpline => RTC_GEOMETRY_TYPE_ROUND_BSPLINE_CURVE,
            CurveBasis::FlatBSpline => RTC_GEOMETRY_TYPE_FLAT_BSPLINE_CURVE,
        };
        let handle = &device.inner;
        let raw = new_geometry(handle, kind, "create curve geometry")?;
        // From here on `Drop` releases `raw` on every error path.
        let geometry = CurveGeometry {
            raw,
            device: Arc::clone(handle),
            strands,
        };
        fill_buffer(
            &geometry.device,
            raw,
            RTC_BUFFER_TYPE_VERTEX,
            RTC_FORMAT_FLOAT4,
            control_points,
            "vertex",
        )?;
        fill_buffer(
            &geometry.device,
            raw,
            RTC_BUFFER_TYPE_INDEX,
            RTC_FORMAT_UINT,
            segment_first,
            "index",
        )?;
        let user = Arc::as_ptr(&geometry.strands).cast_mut().cast::<c_void>();
        geometry.device.call("commit curve geometry", || {
            // SAFETY: `raw` is live; the table behind `user` is kept alive by `geometry.strands` for as long as
            // the geometry exists, and a scene keeps every geometry attached to it (`Scene::geometries`).
            unsafe { rtcSetGeometryUserData(raw, user) };
            // SAFETY: `raw` is live and both of its buffers are set.
            unsafe { rtcCommitGeometry(raw) };
        })?;
        Ok(geometry)
    }

    /// The strand table this geometry carries.
    pub fn strands(&self) -> &Arc<StrandTable> {
        &self.strands
    }
}

/// A new geometry of `kind` (a geometry type from the header) on the device, its failure an error saying `what`
/// was being done. The caller owns the handle and releases it (its type's `Drop`).
pub(super) fn new_geometry(
    handle: &Arc<DeviceHandle>,
    kind: RTCGeometryType,
    what: &str,
) -> Result<RTCGeometry, EmbreeError> {
    let raw = handle.call(what, || {
        // SAFETY: `handle.raw` is a live device and `kind` a geometry type from the header.
        unsafe { rtcNewGeometry(handle.raw, kind) }
    })?;
    if raw.is_null() {
        return Err(EmbreeError {
            code: ErrorCode::Unknown,
            message: format!("{what}: embree returned no geometry"),
        });
    }
    Ok(raw)
}

/// Copies `data` into a new Embree-owned buffer of `kind` (slot 0) in `format`, which must describe `T`, of the
/// live geometry `raw` created on `device`.
pub(super) fn fill_buffer<T: Copy>(
    device: &DeviceHandle,
    raw: RTCGeometry,
    kind: RTCBufferType,
    format: RTCFormat,
    data: &[T],
    name: &str,
) -> Result<(), EmbreeError> {
    let stride = std::mem::size_of::<T>();
    let dst = device.call(&format!("create {name} buffer"), || {
        // SAFETY: `raw` is live; Embree allocates (and owns) a buffer of `data.len()` items of `stride` bytes,
        // padded for its SIMD loads, or returns null after reporting an error.
        unsafe { rtcSetNewGeometryBuffer(raw, kind, 0, format, stride, data.len()) }
    })?;
    if data.is_empty() {
        return Ok(());
    }
    if dst.is_null() {
        return Err(EmbreeError {
            code: ErrorCode::OutOfMemory,
            message: format!("create {name} buffer: embree returned no buffer"),
        });
    }
    // SAFETY: `dst` is a fresh Embree allocation of `data.len()` items of `T`'s size, aligned for `T` (Embree
    // aligns buffers to at least 16 bytes), and cannot overlap `data`.
    unsafe { ptr::copy_nonoverlapping(data.as_ptr(), dst.cast::<T>(), data.len()) };
    Ok(())
}

impl Drop for CurveGeometry {
    fn drop(&mut self) {
        self.device.release("release curve geometry", || {
            // SAFETY: we own one reference to `raw` and give it up exactly once; a scene it is attached to holds
            // its own reference.
            unsafe { rtcReleaseGeometry(self.raw) }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn strand_table_rejects_bad_input() {
        assert!(StrandTable::new(vec![0, 1], vec![0.5]).is_err());
        assert!(StrandTable::new(vec![0], vec![1.5]).is_err());
        assert!(StrandTable::new(vec![0], vec![f32::NAN]).is_err());
        let t = StrandTable::new(vec![0, 0, 1], vec![0.5, 0.25]).unwrap();
        assert_eq!(t.lookup(2), Some((1, 0.25)));
        assert_eq!(t.lookup(3), None);
    }
}
