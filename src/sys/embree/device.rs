//! [`Device`]: one Embree device, with its error callback and memory monitor.

use std::ffi::{c_char, c_void, CStr, CString};
use std::fmt;
use std::ptr;
use std::sync::atomic::{AtomicIsize, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::{self, ThreadId};

use super::error::{EmbreeError, ErrorCode};
use super::ffi::*;
#[cfg(doc)]
use super::scene::CommittedScene;

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
pub(super) struct DeviceHandle {
    pub(super) raw: RTCDevice,
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
    pub(super) fn check(&self, what: &str) -> Result<(), EmbreeError> {
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
    pub(super) inner: Arc<DeviceHandle>,
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
