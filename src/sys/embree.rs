//! Safe wrappers over Embree: the only place in cuticle that calls into `libembree`.
//!
//! Embree 3.13 (Debian 12) is the version this module is built and tested against. When `build.rs` finds Embree 4
//! it sets `cfg(embree4)`; the Embree 4 paths below (`#[cfg(embree4)]`) follow the Embree 4 headers
//! (`rtcore_common.h`, `rtcore_ray.h`, `rtcore_scene.h`) but have **never been compiled** on the machines this crate
//! is developed on, which have no Embree 4: expect to fix small type mismatches the first time they are built.
//!
//! # Objects and who owns what
//! - [`Device`]: one Embree device. Its error callback and memory monitor write into a boxed state that the device
//!   owns and frees only after unregistering both callbacks. Cloning a `Device` shares the handle; scenes and
//!   geometries hold it too, so the device outlives them.
//! - [`CurveGeometry`]: B-spline curves (round tubes or flat ribbons) from `float4` control points `(x, y, z, r)`
//!   and one `u32` per segment (its first control point). Embree copies both arrays into buffers it owns. Each
//!   geometry carries a [`StrandTable`] (segment → strand, strand → opacity) as its Embree user data, which is
//!   what the transparent-shadow filter reads.
//! - [`Scene`] (being built) → [`Scene::commit`] → [`CommittedScene`]: only a committed scene answers queries
//!   (Embree does not check this in release builds), and it is `Send + Sync`.
//!
//! # Queries
//! [`CommittedScene::intersect1`] finds the closest hit. [`CommittedScene::transmittance1`] runs an occlusion query
//! whose filter function rejects every hit (so traversal continues) and multiplies the transmittance by
//! `1 − opacity` once per **strand** — round curves report one crossing several times (front and back of the
//! tube, and both segments at a joint), so neither primitive ids nor distances de-duplicate correctly.
//!
//! Every query first validates its ray with [`Ray::check`]: Debian's libembree3 has assertions on and aborts the
//! process on a NaN/Inf ray, a negative `tnear` or an origin beyond ~1.8e18.
//!
//! # Errors
//! Embree reports errors through the device's error callback; every wrapper call that can fail checks for an error
//! recorded on the calling thread (and clears Embree's per-thread error code) and returns it as an
//! [`EmbreeError`].
#![warn(unsafe_op_in_unsafe_fn)]

use std::ffi::{c_char, c_void, CStr, CString};
use std::fmt;
use std::ptr;
use std::sync::atomic::{AtomicIsize, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::{self, ThreadId};

use glam::Vec3;

use crate::ray::{InvalidRay, Ray, MAX_ORIGIN};

/// The bindgen output for `ffi/embree.h` (see `build.rs`), with its layout tests.
#[allow(
    non_upper_case_globals,
    non_camel_case_types,
    non_snake_case,
    dead_code,
    missing_docs,
    unsafe_op_in_unsafe_fn,
    clippy::all,
    clippy::pedantic
)]
mod bindings {
    include!(concat!(env!("OUT_DIR"), "/embree_bindings.rs"));
}

use bindings::*;

// ---------------------------------------------------------------------------------------------------------------
// Hand-written replacements for what bindgen cannot translate (macros that cast, and inline functions).

/// `RTC_INVALID_GEOMETRY_ID` from `rtcore_common.h` (Embree 3 and 4): `((unsigned int)-1)`, a cast macro bindgen
/// skips.
const RTC_INVALID_GEOMETRY_ID: u32 = u32::MAX;

/// The query context Embree hands to filter functions: `RTCIntersectContext` in Embree 3.
#[cfg(not(embree4))]
type QueryContext = RTCIntersectContext;
/// The query context Embree hands to filter functions: `RTCRayQueryContext` in Embree 4.
#[cfg(embree4)]
type QueryContext = RTCRayQueryContext;

/// Mirrors `rtcInitIntersectContext` (`embree3/rtcore_common.h`, an inline function).
///
/// Starting from the zeroed `Default` also sets `instStackSize` and `minWidthDistanceFactor` to 0 in builds that
/// have them (`RTC_MAX_INSTANCE_LEVEL_COUNT > 1`, `RTC_MIN_WIDTH`), as the header does.
#[cfg(not(embree4))]
#[allow(clippy::field_reassign_with_default)] // which fields exist depends on Embree's build options
fn init_query_context() -> QueryContext {
    let mut context = RTCIntersectContext::default();
    context.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
    context.filter = None;
    context.instID.fill(RTC_INVALID_GEOMETRY_ID);
    context
}

/// Mirrors `rtcInitRayQueryContext` (`embree4/rtcore_common.h`, an inline function).
///
/// Embree ≥ 4.3 built with instance arrays also has `instPrimID[]`, which the header sets to
/// `RTC_INVALID_GEOMETRY_ID`; it is left zeroed here because only instance-array traversal reads it and cuticle
/// creates no instances. (Not compiled on Embree 3 machines; see the module docs.)
#[cfg(embree4)]
#[allow(clippy::field_reassign_with_default)] // which fields exist depends on Embree's build options
fn init_query_context() -> QueryContext {
    let mut context = RTCRayQueryContext::default();
    context.instID.fill(RTC_INVALID_GEOMETRY_ID);
    context
}

/// Mirrors `rtcInitOccludedArguments` (`embree4/rtcore_scene.h`, an inline function): incoherent rays, all
/// features, no context, no filter, no user-geometry callback, `minWidthDistanceFactor` 0 (zeroed by `Default`).
/// (Not compiled on Embree 3 machines; see the module docs.)
#[cfg(embree4)]
#[allow(clippy::field_reassign_with_default)] // which fields exist depends on Embree's build options
fn init_occluded_arguments() -> RTCOccludedArguments {
    let mut args = RTCOccludedArguments::default();
    args.flags = RTC_RAY_QUERY_FLAG_INCOHERENT;
    args.feature_mask = RTC_FEATURE_FLAG_ALL;
    args
}

/// Mirrors `RTCHitN_primID` (`rtcore_ray.h`, Embree 3 and 4; a C++-only inline accessor): the hit packet of width
/// `n` is stored as structure-of-arrays and `primID` is its sixth field.
///
/// # Safety
/// `hit` must point at a hit packet of width `n` (as passed to a filter function), and `i < n`.
unsafe fn hit_n_prim_id(hit: *const RTCHitN, n: u32, i: u32) -> u32 {
    let index = 5 * n as usize + i as usize;
    // SAFETY: the caller guarantees a packet of width `n`, whose sixth row of `n` u32s holds primID, and `i < n`.
    unsafe { *hit.cast::<u32>().add(index) }
}

/// Scene flags for every scene: per-query filter functions on (the transparent-shadow filter is passed with the
/// query); robust traversal off (it costs speed, and the brute-force tests in `tests/embree.rs` match without it);
/// not dynamic (hair is built once); not compact (compact layouts trade speed for memory).
#[cfg(not(embree4))]
const SCENE_FLAGS: RTCSceneFlags = RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION;
/// Scene flags for every scene (Embree 4 spelling; see the Embree 3 constant for the reasons).
#[cfg(embree4)]
const SCENE_FLAGS: RTCSceneFlags = RTC_SCENE_FLAG_FILTER_FUNCTION_IN_ARGUMENTS;

// ---------------------------------------------------------------------------------------------------------------
// Errors.

/// The kind of an [`EmbreeError`]: Embree's `RTCError` codes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ErrorCode {
    /// `RTC_ERROR_UNKNOWN` (also used for codes this wrapper does not know).
    Unknown,
    /// `RTC_ERROR_INVALID_ARGUMENT`; also used by this wrapper for input it rejects before calling Embree.
    InvalidArgument,
    /// `RTC_ERROR_INVALID_OPERATION`.
    InvalidOperation,
    /// `RTC_ERROR_OUT_OF_MEMORY`.
    OutOfMemory,
    /// `RTC_ERROR_UNSUPPORTED_CPU`.
    UnsupportedCpu,
    /// `RTC_ERROR_CANCELLED`.
    Cancelled,
}

impl ErrorCode {
    fn from_raw(code: RTCError) -> Self {
        match code {
            RTC_ERROR_INVALID_ARGUMENT => ErrorCode::InvalidArgument,
            RTC_ERROR_INVALID_OPERATION => ErrorCode::InvalidOperation,
            RTC_ERROR_OUT_OF_MEMORY => ErrorCode::OutOfMemory,
            RTC_ERROR_UNSUPPORTED_CPU => ErrorCode::UnsupportedCpu,
            RTC_ERROR_CANCELLED => ErrorCode::Cancelled,
            _ => ErrorCode::Unknown,
        }
    }
}

impl fmt::Display for ErrorCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ErrorCode::Unknown => "unknown error",
            ErrorCode::InvalidArgument => "invalid argument",
            ErrorCode::InvalidOperation => "invalid operation",
            ErrorCode::OutOfMemory => "out of memory",
            ErrorCode::UnsupportedCpu => "unsupported cpu",
            ErrorCode::Cancelled => "cancelled",
        })
    }
}

/// An error reported by Embree (through the device's error callback), or input this wrapper refused to pass on.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("embree: {code}: {message}")]
pub struct EmbreeError {
    /// What kind of error.
    pub code: ErrorCode,
    /// What failed, then what Embree said.
    pub message: String,
}

impl EmbreeError {
    fn invalid_argument(message: impl Into<String>) -> Self {
        EmbreeError {
            code: ErrorCode::InvalidArgument,
            message: message.into(),
        }
    }
}

// ---------------------------------------------------------------------------------------------------------------
// Device.

/// State written by the device's callbacks. Boxed and owned by [`DeviceHandle`], so its address is stable for as
/// long as Embree holds it as the callbacks' user pointer.
#[derive(Debug, Default)]
struct DeviceState {
    /// The last error Embree reported on each thread that has not yet been collected (at most one per thread).
    pending: Mutex<Vec<(ThreadId, EmbreeError)>>,
    /// Bytes Embree has currently allocated (memory monitor callback).
    bytes: AtomicIsize,
    /// The most bytes Embree has had allocated at once.
    peak_bytes: AtomicIsize,
}

impl DeviceState {
    fn record(&self, error: EmbreeError) {
        let id = thread::current().id();
        let mut pending = self.pending.lock().unwrap_or_else(PoisonError::into_inner);
        pending.retain(|(t, _)| *t != id);
        pending.push((id, error));
    }

    fn take(&self) -> Option<EmbreeError> {
        let id = thread::current().id();
        let mut pending = self.pending.lock().unwrap_or_else(PoisonError::into_inner);
        let at = pending.iter().position(|(t, _)| *t == id)?;
        Some(pending.swap_remove(at).1)
    }
}

/// Embree's error callback. Embree calls it on the thread whose API call failed, before that call returns.
unsafe extern "C" fn on_error(user: *mut c_void, code: RTCError, message: *const c_char) {
    // SAFETY: `user` is the `DeviceState` registered in `Device::create`; it outlives the registration.
    let Some(state) = (unsafe { user.cast_const().cast::<DeviceState>().as_ref() }) else {
        return;
    };
    let message = if message.is_null() {
        String::new()
    } else {
        // SAFETY: Embree passes a NUL-terminated message that is valid for the duration of the callback.
        unsafe { CStr::from_ptr(message) }
            .to_string_lossy()
            .into_owned()
    };
    state.record(EmbreeError {
        code: ErrorCode::from_raw(code),
        message,
    });
}

/// Embree's memory monitor: `bytes` > 0 for an allocation, < 0 for a release. Always allows the allocation.
unsafe extern "C" fn on_memory(user: *mut c_void, bytes: isize, _post: bool) -> bool {
    // SAFETY: `user` is the `DeviceState` registered in `Device::create`; it outlives the registration.
    if let Some(state) = unsafe { user.cast_const().cast::<DeviceState>().as_ref() } {
        let now = state.bytes.fetch_add(bytes, Ordering::Relaxed) + bytes;
        state.peak_bytes.fetch_max(now, Ordering::Relaxed);
    }
    true
}

/// The owned device handle, shared (through `Arc`) by every object created on the device.
struct DeviceHandle {
    raw: RTCDevice,
    state: Box<DeviceState>,
}

// SAFETY: Embree's device API is thread-safe (any thread may create and release objects on a device); the state
// the callbacks write is behind a `Mutex` and atomics.
unsafe impl Send for DeviceHandle {}
// SAFETY: as for `Send`; no method mutates the handle itself.
unsafe impl Sync for DeviceHandle {}

impl DeviceHandle {
    /// Collects the error Embree reported on this thread since the last check, if any; `what` names the
    /// operation for the message.
    fn check(&self, what: &str) -> Result<(), EmbreeError> {
        // SAFETY: `raw` is a live device; this reads and clears the calling thread's error code.
        let code = unsafe { rtcGetDeviceError(self.raw) };
        match (self.state.take(), code) {
            (Some(error), _) => Err(EmbreeError {
                code: error.code,
                message: format!("{what}: {}", error.message),
            }),
            (None, RTC_ERROR_NONE) => Ok(()),
            (None, code) => Err(EmbreeError {
                code: ErrorCode::from_raw(code),
                message: what.to_string(),
            }),
        }
    }

    fn property(&self, property: RTCDeviceProperty) -> isize {
        // SAFETY: `raw` is a live device and `property` one of the header's property constants.
        unsafe { rtcGetDeviceProperty(self.raw, property) }
    }
}

impl Drop for DeviceHandle {
    fn drop(&mut self) {
        // Every scene and geometry holds an `Arc` to this handle and has released its Embree object already, so
        // no Embree call can still reach the callbacks; unregister them anyway before the state is freed.
        // SAFETY: `raw` is live; a null callback unregisters.
        unsafe { rtcSetDeviceErrorFunction(self.raw, None, ptr::null_mut()) };
        // SAFETY: as above.
        unsafe { rtcSetDeviceMemoryMonitorFunction(self.raw, None, ptr::null_mut()) };
        // SAFETY: we own one reference to `raw` and give it up exactly once.
        unsafe { rtcReleaseDevice(self.raw) };
    }
}

/// An Embree device: the factory for scenes and geometries, with error reporting and memory accounting.
#[derive(Clone)]
pub struct Device {
    inner: Arc<DeviceHandle>,
}

impl fmt::Debug for Device {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (major, minor, patch) = self.version();
        f.debug_struct("Device")
            .field("version", &format_args!("{major}.{minor}.{patch}"))
            .field("memory_bytes", &self.memory_bytes())
            .finish()
    }
}

impl Device {
    /// A device with Embree's default configuration (all cores for BVH builds).
    pub fn new() -> Result<Device, EmbreeError> {
        Self::create(None)
    }

    /// A device with an Embree configuration string, e.g. `"threads=2,verbose=1"` (see `rtcNewDevice`).
    pub fn with_config(config: &str) -> Result<Device, EmbreeError> {
        let config = CString::new(config).map_err(|_| {
            EmbreeError::invalid_argument(format!("device config {config:?} contains a NUL byte"))
        })?;
        Self::create(Some(&config))
    }

    fn create(config: Option<&CStr>) -> Result<Device, EmbreeError> {
        let config_ptr = config.map_or(ptr::null(), CStr::as_ptr);
        // SAFETY: `config_ptr` is null or a NUL-terminated string that outlives the call.
        let raw = unsafe { rtcNewDevice(config_ptr) };
        let what = match config {
            Some(c) => format!("create device with config {c:?}"),
            None => "create device".to_string(),
        };
        if raw.is_null() {
            // SAFETY: the header documents `rtcGetDeviceError(NULL)` for errors of a failed `rtcNewDevice`.
            let code = unsafe { rtcGetDeviceError(ptr::null_mut()) };
            return Err(EmbreeError {
                code: ErrorCode::from_raw(code),
                message: what,
            });
        }
        let state = Box::new(DeviceState::default());
        let user = ptr::from_ref::<DeviceState>(&state)
            .cast_mut()
            .cast::<c_void>();
        let handle = DeviceHandle { raw, state };
        // SAFETY: `raw` is live and `on_error` has the `RTCErrorFunction` signature; `user` points into the box
        // owned by `handle`, which unregisters the callback before freeing it (Drop).
        unsafe { rtcSetDeviceErrorFunction(raw, Some(on_error), user) };
        // SAFETY: as above, for the memory monitor.
        unsafe { rtcSetDeviceMemoryMonitorFunction(raw, Some(on_memory), user) };
        handle.check(&what)?;
        Ok(Device {
            inner: Arc::new(handle),
        })
    }

    /// Embree's version (major, minor, patch).
    pub fn version(&self) -> (u32, u32, u32) {
        let get = |p| u32::try_from(self.inner.property(p)).unwrap_or(0);
        (
            get(RTC_DEVICE_PROPERTY_VERSION_MAJOR),
            get(RTC_DEVICE_PROPERTY_VERSION_MINOR),
            get(RTC_DEVICE_PROPERTY_VERSION_PATCH),
        )
    }

    /// Whether this Embree build calls filter functions (needed by [`CommittedScene::transmittance1`]).
    pub fn supports_filter_functions(&self) -> bool {
        self.inner
            .property(RTC_DEVICE_PROPERTY_FILTER_FUNCTION_SUPPORTED)
            != 0
    }

    /// Bytes Embree currently has allocated on this device (BVHs and buffers), from its memory monitor.
    pub fn memory_bytes(&self) -> usize {
        usize::try_from(self.inner.state.bytes.load(Ordering::Relaxed)).unwrap_or(0)
    }

    /// The most bytes Embree has had allocated at once on this device.
    pub fn peak_memory_bytes(&self) -> usize {
        usize::try_from(self.inner.state.peak_bytes.load(Ordering::Relaxed)).unwrap_or(0)
    }
}

// ---------------------------------------------------------------------------------------------------------------
// Strand table and curve geometry.

/// Marks "no strand" in [`TransmittanceQuery::ignore_strand`]; [`StrandTable::new`] keeps real ids below it.
const NO_STRAND: u32 = u32::MAX;

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
    fn lookup(&self, segment: u32) -> Option<(u32, f32)> {
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
    raw: RTCGeometry,
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
        // SAFETY: `handle.raw` is a live device and `kind` a geometry type from the header.
        let raw = unsafe { rtcNewGeometry(handle.raw, kind) };
        if raw.is_null() {
            handle.check("create curve geometry")?;
            return Err(EmbreeError {
                code: ErrorCode::Unknown,
                message: "create curve geometry: embree returned no geometry".into(),
            });
        }
        // From here on `Drop` releases `raw` on every error path.
        let geometry = CurveGeometry {
            raw,
            device: Arc::clone(handle),
            strands,
        };
        geometry.fill_buffer(
            RTC_BUFFER_TYPE_VERTEX,
            RTC_FORMAT_FLOAT4,
            control_points,
            "vertex",
        )?;
        geometry.fill_buffer(
            RTC_BUFFER_TYPE_INDEX,
            RTC_FORMAT_UINT,
            segment_first,
            "index",
        )?;
        let user = Arc::as_ptr(&geometry.strands).cast_mut().cast::<c_void>();
        // SAFETY: `raw` is live; the table behind `user` is kept alive by `geometry.strands` for as long as the
        // geometry exists, and a scene keeps every geometry attached to it (`Scene::geometries`).
        unsafe { rtcSetGeometryUserData(raw, user) };
        // SAFETY: `raw` is live and both of its buffers are set.
        unsafe { rtcCommitGeometry(raw) };
        geometry.device.check("commit curve geometry")?;
        Ok(geometry)
    }

    /// Copies `data` into a new Embree-owned buffer of `kind` (slot 0) in `format`, which must describe `T`.
    fn fill_buffer<T: Copy>(
        &self,
        kind: RTCBufferType,
        format: RTCFormat,
        data: &[T],
        name: &str,
    ) -> Result<(), EmbreeError> {
        let stride = std::mem::size_of::<T>();
        // SAFETY: `self.raw` is live; Embree allocates (and owns) a buffer of `data.len()` items of `stride` bytes,
        // padded for its SIMD loads, or returns null after reporting an error.
        let dst = unsafe { rtcSetNewGeometryBuffer(self.raw, kind, 0, format, stride, data.len()) };
        self.device.check(&format!("create {name} buffer"))?;
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

    /// The strand table this geometry carries.
    pub fn strands(&self) -> &Arc<StrandTable> {
        &self.strands
    }
}

impl Drop for CurveGeometry {
    fn drop(&mut self) {
        // SAFETY: we own one reference to `raw` and give it up exactly once; a scene it is attached to holds its
        // own reference.
        unsafe { rtcReleaseGeometry(self.raw) };
    }
}

// ---------------------------------------------------------------------------------------------------------------
// Scenes.

/// BVH build quality (`RTCBuildQuality`): higher builds slower and traces faster.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BuildQuality {
    /// `RTC_BUILD_QUALITY_LOW`: Morton-code build, for geometry that changes every frame.
    Low,
    /// `RTC_BUILD_QUALITY_MEDIUM`: SAH build (Embree's default).
    #[default]
    Medium,
    /// `RTC_BUILD_QUALITY_HIGH`: SAH with spatial splits; suits long, diagonal strands.
    High,
}

impl BuildQuality {
    fn raw(self) -> RTCBuildQuality {
        match self {
            BuildQuality::Low => RTC_BUILD_QUALITY_LOW,
            BuildQuality::Medium => RTC_BUILD_QUALITY_MEDIUM,
            BuildQuality::High => RTC_BUILD_QUALITY_HIGH,
        }
    }
}

/// A scene being assembled. [`Scene::commit`] builds the BVH and turns it into a [`CommittedScene`].
pub struct Scene {
    raw: RTCScene,
    device: Arc<DeviceHandle>,
    /// Keeps every attached geometry, and so its strand table (the filter's user data), alive.
    geometries: Vec<CurveGeometry>,
}

// SAFETY: an Embree scene has no thread affinity; mutation needs `&mut self`.
unsafe impl Send for Scene {}

impl fmt::Debug for Scene {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Scene")
            .field("geometries", &self.geometries)
            .finish()
    }
}

impl Scene {
    /// An empty static scene with per-query filter functions enabled and robust traversal off.
    pub fn new(device: &Device, quality: BuildQuality) -> Result<Scene, EmbreeError> {
        let handle = &device.inner;
        // SAFETY: `handle.raw` is a live device.
        let raw = unsafe { rtcNewScene(handle.raw) };
        if raw.is_null() {
            handle.check("create scene")?;
            return Err(EmbreeError {
                code: ErrorCode::Unknown,
                message: "create scene: embree returned no scene".into(),
            });
        }
        let scene = Scene {
            raw,
            device: Arc::clone(handle),
            geometries: Vec::new(),
        };
        // SAFETY: `raw` is a live scene and `SCENE_FLAGS` a combination of the header's flags.
        unsafe { rtcSetSceneFlags(raw, SCENE_FLAGS) };
        // SAFETY: `raw` is a live scene and the quality one of the header's constants.
        unsafe { rtcSetSceneBuildQuality(raw, quality.raw()) };
        scene.device.check("configure scene")?;
        Ok(scene)
    }

    /// Attaches `geometry` and returns its geometry id (Embree's `geomID`). The scene keeps the geometry.
    ///
    /// Embree itself rejects a geometry created on another device (`invalid argument`).
    pub fn attach(&mut self, geometry: CurveGeometry) -> Result<u32, EmbreeError> {
        // SAFETY: both handles are live; Embree checks that they belong to the same device.
        let id = unsafe { rtcAttachGeometry(self.raw, geometry.raw) };
        self.device.check("attach geometry")?;
        self.geometries.push(geometry);
        Ok(id)
    }

    /// Builds the BVH. Only a committed scene can be traced.
    pub fn commit(self) -> Result<CommittedScene, EmbreeError> {
        // SAFETY: `raw` is a live scene whose geometries are all committed.
        unsafe { rtcCommitScene(self.raw) };
        self.device.check("commit scene")?;
        Ok(CommittedScene { scene: self })
    }
}

impl Drop for Scene {
    fn drop(&mut self) {
        // SAFETY: we own one reference to `raw` and give it up exactly once, before the geometries (and their
        // strand tables) are dropped.
        unsafe { rtcReleaseScene(self.raw) };
    }
}

/// A committed scene: immutable, and safe to query from many threads at once.
#[derive(Debug)]
pub struct CommittedScene {
    scene: Scene,
}

// SAFETY: Embree allows concurrent `rtcIntersect1`/`rtcOccluded1` on a committed scene that nobody modifies, and
// `CommittedScene` offers no way to modify it; every query keeps its own context and ray on its own stack, and the
// shared strand tables are immutable.
unsafe impl Sync for CommittedScene {}

/// The closest hit of a ray, as Embree reports it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayHit {
    /// Ray parameter of the hit (in units of the caller's `dir`).
    pub t: f32,
    /// Geometry id ([`Scene::attach`]).
    pub geom_id: u32,
    /// Primitive id: the curve segment.
    pub prim_id: u32,
    /// Curve parameter along the segment, in [0, 1].
    pub u: f32,
    /// Round curves: 0. Flat curves: position across the ribbon, in [−1, 1].
    pub v: f32,
    /// Unnormalised geometric normal. Round curves: outward from the axis. Flat curves: the curve tangent.
    pub ng: Vec3,
}

/// Why a transmittance query ended early with transmittance 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum Cutoff {
    /// A hit on a geometry or segment without strand data, treated as opaque.
    Opaque,
    /// The transmittance fell below [`TRANSMITTANCE_CUTOFF`] (this includes crossing a strand of opacity 1).
    Dark,
    /// More than [`SEEN_STRANDS`] distinct strands were crossed; see [`SEEN_STRANDS`] for why this ends the ray.
    SeenListFull,
}

/// The result of [`CommittedScene::transmittance1`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transmittance {
    /// Fraction of light passing: ∏ (1 − opacity) over distinct strands crossed, or 0 after a cutoff.
    pub value: f32,
    /// Distinct strands counted before the query ended.
    pub strands: u32,
    /// Why the query ended early, if it did.
    pub cutoff: Option<Cutoff>,
}

/// Transmittance below which a shadow ray stops and reports 0 (the light it would still carry is invisible
/// at 16-bit precision and saves most of the traversal through dense hair).
pub const TRANSMITTANCE_CUTOFF: f32 = 1e-4;

/// Capacity of the per-ray list of strands already counted.
///
/// Strands of opacity 0 are not remembered (they change nothing). When a ray crosses more distinct
/// semi-transparent strands than this, the query stops with transmittance 0. The alternatives —
/// forgetting old entries or counting without de-duplication — would double-count strands and make the result
/// depend on Embree's traversal order. Stopping is biased dark by at most the transmittance at that point,
/// ∏ (1 − aᵢ) over 64 strands: below 1e-4 for opacities ≥ 0.14, and 0.04 for opacity 0.05. The count of such rays
/// is reported ([`Cutoff::SeenListFull`]) so that a scene where it matters can be found.
pub const SEEN_STRANDS: usize = 64;

/// The shadow-ray payload: Embree's query context first (so Embree's context pointer is also a pointer to this
/// struct), then what the filter function accumulates. Lives on the querying thread's stack for one query.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
struct TransmittanceQuery {
    context: QueryContext,
    ignore_strand: u32,
    transmittance: f32,
    cutoff: Option<Cutoff>,
    seen_len: u32,
    seen: [u32; SEEN_STRANDS],
}

// The filter casts Embree's context pointer to the payload: the context must sit at offset 0.
const _: () = assert!(std::mem::offset_of!(TransmittanceQuery, context) == 0);

/// What the filter tells Embree about one hit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Verdict {
    /// Reject the hit (`valid[i] = 0`): traversal continues.
    Continue,
    /// Accept the hit: the occlusion query ends.
    Stop,
}

impl TransmittanceQuery {
    fn new(ignore_strand: Option<u32>) -> Self {
        TransmittanceQuery {
            context: init_query_context(),
            ignore_strand: ignore_strand.unwrap_or(NO_STRAND),
            transmittance: 1.0,
            cutoff: None,
            seen_len: 0,
            seen: [NO_STRAND; SEEN_STRANDS],
        }
    }

    /// Accounts for one reported hit on `strand` = (strand id, opacity), or on a primitive without strand data.
    fn on_hit(&mut self, strand: Option<(u32, f32)>) -> Verdict {
        let Some((strand, opacity)) = strand else {
            return self.stop(Cutoff::Opaque);
        };
        // A fully transparent strand changes nothing and need not be remembered.
        let seen = &self.seen[..self.seen_len as usize];
        if opacity == 0.0 || strand == self.ignore_strand || seen.contains(&strand) {
            return Verdict::Continue;
        }
        if self.seen_len as usize == SEEN_STRANDS {
            return self.stop(Cutoff::SeenListFull);
        }
        self.seen[self.seen_len as usize] = strand;
        self.seen_len += 1;
        self.transmittance *= 1.0 - opacity;
        if self.transmittance < TRANSMITTANCE_CUTOFF {
            return self.stop(Cutoff::Dark);
        }
        Verdict::Continue
    }

    fn stop(&mut self, why: Cutoff) -> Verdict {
        self.transmittance = 0.0;
        self.cutoff = Some(why);
        Verdict::Stop
    }
}

/// The occlusion filter of [`CommittedScene::transmittance1`]: rejects every hit so that traversal continues,
/// multiplying the payload's transmittance once per distinct strand, until a cutoff accepts a hit.
unsafe extern "C" fn transmittance_filter(args: *const RTCFilterFunctionNArguments) {
    // SAFETY: Embree passes a valid argument struct for the duration of the call.
    let Some(args) = (unsafe { args.as_ref() }) else {
        return;
    };
    // SAFETY: only `transmittance1` installs this filter, and its context pointer is the first field of a live
    // `TransmittanceQuery` (repr(C), offset 0 asserted above), derived from a pointer to the whole struct; Embree
    // runs filters on the querying thread during the call, when nothing else touches the query.
    let query = unsafe { &mut *args.context.cast::<TransmittanceQuery>() };
    // SAFETY: `args` is the argument struct of this filter call, on cuticle's curve geometries.
    unsafe { filter_hits(args, |strand| query.on_hit(strand) == Verdict::Stop) };
}

/// The loop every filter function shares: for each valid lane of the hit packet, looks up the strand of its segment
/// and passes it to `keep`; lanes for which `keep` returns `false` are rejected (`valid[i] = 0`), so traversal goes
/// on past them.
///
/// # Safety
/// `args` must be the argument struct Embree passed to the calling filter function, for a geometry whose user data
/// is null or `Arc::as_ptr` of its [`StrandTable`], kept alive by the committed scene.
unsafe fn filter_hits(
    args: &RTCFilterFunctionNArguments,
    mut keep: impl FnMut(Option<(u32, f32)>) -> bool,
) {
    // SAFETY: the caller guarantees the user data is null or a live strand table.
    let table = unsafe {
        args.geometryUserPtr
            .cast_const()
            .cast::<StrandTable>()
            .as_ref()
    };
    for i in 0..args.N {
        // SAFETY: `valid` has `N` entries (the filter-function contract).
        let valid = unsafe { &mut *args.valid.add(i as usize) };
        if *valid == 0 {
            continue;
        }
        // SAFETY: `hit` is a packet of width `N` and `i < N`.
        let segment = unsafe { hit_n_prim_id(args.hit, args.N, i) };
        if !keep(table.and_then(|t| t.lookup(segment))) {
            *valid = 0;
        }
    }
}

/// The payload of the stochastic queries ([`CommittedScene::intersect1_stochastic`],
/// [`CommittedScene::occluded1_stochastic`]): Embree's context first, then the per-ray key that decides which strands
/// are present.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
struct StochasticQuery {
    context: QueryContext,
    ignore_strand: u32,
    key: u64,
}

const _: () = assert!(std::mem::offset_of!(StochasticQuery, context) == 0);

impl StochasticQuery {
    /// A payload whose context carries [`stochastic_filter`] (Embree 3; Embree 4 takes the filter in the query
    /// arguments).
    fn new(ignore_strand: Option<u32>, key: u64) -> Self {
        #[allow(unused_mut)]
        let mut context = init_query_context();
        #[cfg(not(embree4))]
        {
            context.filter = Some(stochastic_filter);
        }
        StochasticQuery {
            context,
            ignore_strand: ignore_strand.unwrap_or(NO_STRAND),
            key,
        }
    }

    /// Whether a reported hit counts: primitives without strand data always do (opaque); a strand does unless it is
    /// the ignored one or [`crate::accel::strand_present`] says it is absent for this ray.
    #[inline]
    fn accepts(&self, strand: Option<(u32, f32)>) -> bool {
        match strand {
            None => true,
            Some((strand, opacity)) => {
                strand != self.ignore_strand
                    && crate::accel::strand_present(self.key, strand, opacity)
            }
        }
    }
}

/// The filter of the stochastic queries, for intersection and occlusion alike: rejects hits on strands that are
/// absent for this ray, so traversal goes on past them.
unsafe extern "C" fn stochastic_filter(args: *const RTCFilterFunctionNArguments) {
    // SAFETY: Embree passes a valid argument struct for the duration of the call.
    let Some(args) = (unsafe { args.as_ref() }) else {
        return;
    };
    // SAFETY: only the stochastic queries install this filter, and their context pointer is the first field of a
    // live `StochasticQuery` (repr(C), offset 0 asserted above); the filter only reads it.
    let query = unsafe { &*args.context.cast::<StochasticQuery>() };
    // SAFETY: `args` is the argument struct of this filter call, on cuticle's curve geometries.
    unsafe { filter_hits(args, |strand| query.accepts(strand)) };
}

/// An Embree ray for a validated `ray`, and the factor by which its direction was scaled down.
///
/// Embree's own validity test (`RayK::valid`, `kernels/common/ray.h`) also requires every direction component to be
/// below ~1.8e18, which [`Ray::check`] does not ask: such a direction is scaled down, with the interval scaled up,
/// so the same points are traced; hit distances are divided back by the returned factor.
fn embree_ray(ray: &Ray) -> Result<(RTCRay, f32), InvalidRay> {
    ray.check()?;
    let longest = ray.dir.abs().max_element();
    let (dir, scale) = if longest >= MAX_ORIGIN {
        (ray.dir / longest, longest)
    } else {
        (ray.dir, 1.0)
    };
    let rtc = RTCRay {
        org_x: ray.origin.x,
        org_y: ray.origin.y,
        org_z: ray.origin.z,
        tnear: ray.tnear * scale,
        dir_x: dir.x,
        dir_y: dir.y,
        dir_z: dir.z,
        time: 0.0,
        tfar: ray.tfar * scale,
        mask: u32::MAX,
        id: 0,
        flags: 0,
    };
    Ok((rtc, scale))
}

impl CommittedScene {
    fn raw(&self) -> RTCScene {
        self.scene.raw
    }

    /// The geometries in the scene, in the order they were attached.
    pub fn geometries(&self) -> &[CurveGeometry] {
        &self.scene.geometries
    }

    /// The closest hit along `ray` within `[tnear, tfar]`, every strand opaque. Rays failing [`Ray::check`] never
    /// reach Embree.
    pub fn intersect1(&self, ray: &Ray) -> Result<Option<RayHit>, InvalidRay> {
        self.intersect_with(ray, None)
    }

    /// The closest hit along `ray` among the strands *present* for this ray: strand s is present with probability
    /// equal to its opacity, decided by [`crate::accel::strand_present`]`(key, s, opacity)` (so the same key and
    /// strand always decide alike, whatever order Embree reports hits in). `ignore_strand` is never hit.
    pub fn intersect1_stochastic(
        &self,
        ray: &Ray,
        ignore_strand: Option<u32>,
        key: u64,
    ) -> Result<Option<RayHit>, InvalidRay> {
        let mut query = StochasticQuery::new(ignore_strand, key);
        self.intersect_with(ray, Some(&mut query))
    }

    /// Whether any strand present for this ray (see [`CommittedScene::intersect1_stochastic`]) blocks `ray`: an
    /// unbiased one-sample estimate of [`CommittedScene::transmittance1`] (E[not occluded] = ∏ (1 − opacity)) at
    /// the cost of an opaque shadow ray.
    pub fn occluded1_stochastic(
        &self,
        ray: &Ray,
        ignore_strand: Option<u32>,
        key: u64,
    ) -> Result<bool, InvalidRay> {
        let (mut rtc_ray, _) = embree_ray(ray)?;
        let mut query = StochasticQuery::new(ignore_strand, key);
        let context = ptr::addr_of_mut!(query).cast::<QueryContext>();
        #[cfg(not(embree4))]
        {
            // SAFETY: the scene is committed with `RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION`; `context` points at the
            // payload, which outlives the call; the ray passed `Ray::check`.
            unsafe { rtcOccluded1(self.raw(), context, &mut rtc_ray) };
        }
        #[cfg(embree4)]
        {
            let mut args = init_occluded_arguments();
            args.context = context;
            args.filter = Some(stochastic_filter);
            args.flags |= RTC_RAY_QUERY_FLAG_INVOKE_ARGUMENT_FILTER;
            // SAFETY: as for Embree 3, with the filter passed in the arguments.
            unsafe { rtcOccluded1(self.raw(), &mut rtc_ray, &mut args) };
        }
        // Embree marks an occluded ray by setting tfar to −∞.
        Ok(rtc_ray.tfar == f32::NEG_INFINITY)
    }

    /// The closest-hit query, with the stochastic filter when `query` is given.
    fn intersect_with(
        &self,
        ray: &Ray,
        query: Option<&mut StochasticQuery>,
    ) -> Result<Option<RayHit>, InvalidRay> {
        let (rtc_ray, scale) = embree_ray(ray)?;
        let mut rayhit = RTCRayHit {
            ray: rtc_ray,
            hit: RTCHit::default(),
        };
        rayhit.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rayhit.hit.primID = RTC_INVALID_GEOMETRY_ID;
        rayhit.hit.instID.fill(RTC_INVALID_GEOMETRY_ID);
        #[cfg(not(embree4))]
        {
            let mut plain = init_query_context();
            let context = match query {
                Some(q) => ptr::from_mut(q).cast::<QueryContext>(),
                None => ptr::addr_of_mut!(plain),
            };
            // SAFETY: the scene is committed; `context` is an initialised local context or the first field of a live
            // `StochasticQuery` whose filter reads only that payload; `rayhit` is an aligned local; Embree uses both
            // only during the call; the ray passed `Ray::check` and is within Embree's limits.
            unsafe { rtcIntersect1(self.raw(), context, &mut rayhit) };
        }
        #[cfg(embree4)]
        {
            match query {
                Some(q) => {
                    let mut args = RTCIntersectArguments::default();
                    args.flags =
                        RTC_RAY_QUERY_FLAG_INCOHERENT | RTC_RAY_QUERY_FLAG_INVOKE_ARGUMENT_FILTER;
                    args.feature_mask = RTC_FEATURE_FLAG_ALL;
                    args.context = ptr::from_mut(q).cast::<QueryContext>();
                    args.filter = Some(stochastic_filter);
                    // SAFETY: as for Embree 3, with the filter passed in the arguments.
                    unsafe { rtcIntersect1(self.raw(), &mut rayhit, &mut args) };
                }
                // SAFETY: as for Embree 3; null arguments select Embree's defaults (no filter).
                None => unsafe { rtcIntersect1(self.raw(), &mut rayhit, ptr::null_mut()) },
            }
        }
        let hit = rayhit.hit;
        if hit.geomID == RTC_INVALID_GEOMETRY_ID {
            return Ok(None);
        }
        Ok(Some(RayHit {
            t: rayhit.ray.tfar / scale,
            geom_id: hit.geomID,
            prim_id: hit.primID,
            u: hit.u,
            v: hit.v,
            ng: Vec3::new(hit.Ng_x, hit.Ng_y, hit.Ng_z),
        }))
    }

    /// Transmittance along `ray` within `[tnear, tfar]` through semi-transparent strands: ∏ (1 − opacity) over the
    /// distinct strands crossed, each counted once however often Embree reports it, leaving out `ignore_strand`.
    /// Stops with 0 at [`TRANSMITTANCE_CUTOFF`], on a primitive without strand data, or after [`SEEN_STRANDS`]
    /// strands. Rays failing [`Ray::check`] never reach Embree.
    pub fn transmittance1(
        &self,
        ray: &Ray,
        ignore_strand: Option<u32>,
    ) -> Result<Transmittance, InvalidRay> {
        let (mut rtc_ray, _) = embree_ray(ray)?;
        let mut query = TransmittanceQuery::new(ignore_strand);
        // Derived from the whole payload (not from `query.context`) so the filter may reach every field.
        let context = ptr::addr_of_mut!(query).cast::<QueryContext>();
        #[cfg(not(embree4))]
        {
            query.context.filter = Some(transmittance_filter);
            // SAFETY: the scene is committed with `RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION`; `context` points at the
            // payload, which outlives the call and which only the filter touches during it; the ray passed
            // `Ray::check` and is within Embree's limits.
            unsafe { rtcOccluded1(self.raw(), context, &mut rtc_ray) };
        }
        #[cfg(embree4)]
        {
            let mut args = init_occluded_arguments();
            args.context = context;
            args.filter = Some(transmittance_filter);
            args.flags |= RTC_RAY_QUERY_FLAG_INVOKE_ARGUMENT_FILTER;
            // SAFETY: as for Embree 3, with the filter passed in the arguments (scene flag
            // `RTC_SCENE_FLAG_FILTER_FUNCTION_IN_ARGUMENTS`).
            unsafe { rtcOccluded1(self.raw(), &mut rtc_ray, &mut args) };
        }
        // Embree sets tfar to −∞ when a hit was accepted; only the filter accepts hits, and it zeroes the
        // transmittance when it does.
        debug_assert!(rtc_ray.tfar != f32::NEG_INFINITY || query.transmittance == 0.0);
        Ok(Transmittance {
            value: query.transmittance,
            strands: query.seen_len,
            cutoff: query.cutoff,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{align_of, offset_of, size_of};

    #[test]
    fn transmittance_query_layout() {
        let context = size_of::<QueryContext>();
        assert_eq!(offset_of!(TransmittanceQuery, context), 0);
        assert_eq!(offset_of!(TransmittanceQuery, ignore_strand), context);
        assert_eq!(offset_of!(TransmittanceQuery, transmittance), context + 4);
        assert_eq!(size_of::<Option<Cutoff>>(), 4, "niche-packed into the u32");
        assert_eq!(offset_of!(TransmittanceQuery, cutoff), context + 8);
        assert_eq!(offset_of!(TransmittanceQuery, seen_len), context + 12);
        assert_eq!(offset_of!(TransmittanceQuery, seen), context + 16);
        assert_eq!(
            align_of::<TransmittanceQuery>(),
            align_of::<QueryContext>().max(4)
        );
        #[cfg(not(embree4))]
        {
            // Debian's Embree 3.13: flags (4) + padding (4) + filter pointer (8) + instID[1] (4) + padding (4).
            assert_eq!(context, 24);
            assert_eq!(size_of::<TransmittanceQuery>(), 24 + 16 + 4 * SEEN_STRANDS);
        }
    }

    #[test]
    fn each_strand_counts_once() {
        let mut q = TransmittanceQuery::new(None);
        assert_eq!(q.on_hit(Some((7, 0.5))), Verdict::Continue);
        assert_eq!(q.on_hit(Some((7, 0.5))), Verdict::Continue);
        assert_eq!(q.on_hit(Some((3, 0.5))), Verdict::Continue);
        assert_eq!(q.on_hit(Some((7, 0.5))), Verdict::Continue);
        assert_eq!(q.transmittance, 0.25);
        assert_eq!(q.seen_len, 2);
        assert_eq!(q.cutoff, None);
    }

    #[test]
    fn ignored_strand_is_transparent() {
        let mut q = TransmittanceQuery::new(Some(4));
        assert_eq!(q.on_hit(Some((4, 1.0))), Verdict::Continue);
        assert_eq!(q.transmittance, 1.0);
        assert_eq!(q.seen_len, 0);
    }

    #[test]
    fn stops_dark_opaque_and_full() {
        let mut q = TransmittanceQuery::new(None);
        assert_eq!(q.on_hit(Some((1, 1.0))), Verdict::Stop);
        assert_eq!((q.transmittance, q.cutoff), (0.0, Some(Cutoff::Dark)));

        let mut q = TransmittanceQuery::new(None);
        assert_eq!(q.on_hit(None), Verdict::Stop);
        assert_eq!((q.transmittance, q.cutoff), (0.0, Some(Cutoff::Opaque)));

        let mut q = TransmittanceQuery::new(None);
        for s in 0..SEEN_STRANDS as u32 {
            assert_eq!(q.on_hit(Some((s, 1e-6))), Verdict::Continue);
        }
        assert_eq!(q.on_hit(Some((0, 1e-6))), Verdict::Continue, "already seen");
        assert_eq!(q.on_hit(Some((999, 0.0))), Verdict::Continue, "transparent");
        assert_eq!(q.seen_len as usize, SEEN_STRANDS);
        assert_eq!(q.on_hit(Some((999, 1e-6))), Verdict::Stop);
        assert_eq!(
            (q.transmittance, q.cutoff),
            (0.0, Some(Cutoff::SeenListFull))
        );
    }

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
