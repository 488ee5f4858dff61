//! [`Device`]: one Embree device, with its error callback and memory monitor.

use std::ffi::{c_char, c_void, CStr, CString};
use std::fmt;
use std::ptr::{self, NonNull};
use std::sync::atomic::{AtomicBool, AtomicIsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::{self, ThreadId};

use super::error::{EmbreeError, ErrorCode};
use super::ffi::*;
#[cfg(doc)]
use super::scene::CommittedScene;

/// State written by the device's callbacks. Owned by [`DeviceHandle`] through a [`CallbackState`], so its address
/// is stable for as long as Embree holds it as the callbacks' user pointer.
#[derive(Debug, Default)]
struct DeviceState {
    /// The last error Embree reported on each thread that has not yet been collected (at most one per thread).
    pending: Mutex<Vec<(ThreadId, EmbreeError)>>,
    /// Whether `pending` may hold an error: read after every ray query (one relaxed load) so that an error a
    /// query reported is collected there, not by the next checked call.
    any_pending: AtomicBool,
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
        self.any_pending.store(true, Ordering::Relaxed);
    }

    fn take(&self) -> Option<EmbreeError> {
        let id = thread::current().id();
        let mut pending = self.pending.lock().unwrap_or_else(PoisonError::into_inner);
        let at = pending.iter().position(|(t, _)| *t == id)?;
        let error = pending.swap_remove(at).1;
        self.any_pending
            .store(!pending.is_empty(), Ordering::Relaxed);
        Some(error)
    }
}

/// Owns a value whose address C holds as a callback's user pointer.
///
/// The pointer comes from [`Box::into_raw`] and is kept as a [`NonNull`], never re-derived from a reference to a
/// `Box` (a `Box` that moves, e.g. into an `Arc`, is re-asserted unique, which invalidates pointers derived from it
/// before the move under both of Miri's aliasing models). Rust reads the value only through shared references, and
/// the callbacks only through shared references too, so the value must do its writing through interior mutability
/// (`Mutex`, atomics). The value is freed by [`CallbackState::free`], which the owner calls after unregistering every
/// callback that holds the pointer; a `CallbackState` dropped without it leaks the value rather than risk a dangling
/// user pointer.
struct CallbackState<T> {
    ptr: NonNull<T>,
}

impl<T> CallbackState<T> {
    fn new(value: T) -> Self {
        CallbackState {
            // SAFETY: `Box::into_raw` never returns null.
            ptr: unsafe { NonNull::new_unchecked(Box::into_raw(Box::new(value))) },
        }
    }

    /// The user pointer to hand to C (the same pointer every time).
    fn user(&self) -> *mut c_void {
        self.ptr.as_ptr().cast()
    }

    fn get(&self) -> &T {
        // SAFETY: `ptr` came from `Box::into_raw` and is freed only by `free`, after which the owner never uses
        // `self` again; every access, ours and the callbacks', is shared.
        unsafe { self.ptr.as_ref() }
    }

    /// Frees the value (the owner's `Drop` calls this).
    ///
    /// # Safety
    /// No callback that was given [`CallbackState::user`] may still be registered or running, and `self` must not
    /// be used again (not even freed again).
    unsafe fn free(&mut self) {
        // SAFETY: `ptr` came from a `Box`; the caller guarantees it is freed once and that C no longer uses it.
        drop(unsafe { Box::from_raw(self.ptr.as_ptr()) });
    }
}

// SAFETY: `CallbackState<T>` hands out only `&T`, like an `Arc<T>`; sending or sharing it is sound when sharing `T`
// is.
unsafe impl<T: Sync + Send> Send for CallbackState<T> {}
// SAFETY: as for `Send`.
unsafe impl<T: Sync + Send> Sync for CallbackState<T> {}

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
///
/// # Threads
/// Embree documents two things as callable from many threads at once: ray queries on a committed scene
/// (`rtcIntersect1`/`rtcOccluded1`), and attaching geometries to one scene; its maintainers state that other calls on
/// one object are not thread-safe in general (RenderKit/embree#207), and `rtcCommitScene` may run concurrently only
/// from TBB worker threads. So every other call on this device and the objects created on it — creation, buffers,
/// flags, commits, releases, properties, callback registration — goes through [`DeviceHandle::call`], which holds
/// one lock per device (`api`) for the call and the collection of its error. Ray queries take no lock.
/// `rtcNewDevice` needs none of ours: Embree serialises it with a global mutex of its own (`rtcore.cpp`).
pub(super) struct DeviceHandle {
    pub(super) raw: RTCDevice,
    /// Serialises every non-query Embree call on this device (see the type's documentation).
    api: Mutex<()>,
    state: CallbackState<DeviceState>,
}

// SAFETY: the handle has no thread affinity (Embree's per-thread error codes are read on the thread that made the
// call); every call that Embree does not document as thread-safe holds `api` (`DeviceHandle::call`), ray queries
// are documented thread-safe on committed scenes, and the state the callbacks write is behind a `Mutex` and atomics.
unsafe impl Send for DeviceHandle {}
// SAFETY: as for `Send`; no method mutates the handle itself.
unsafe impl Sync for DeviceHandle {}

impl DeviceHandle {
    #[inline]
    fn state(&self) -> &DeviceState {
        self.state.get()
    }

    fn lock(&self) -> MutexGuard<'_, ()> {
        self.api.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Runs `f`, a non-query Embree call on this device or one of its objects, under the device's API lock, and
    /// collects the error it reported there, so that no later call is blamed for it; `what` names the operation
    /// for the message.
    pub(super) fn call<R>(&self, what: &str, f: impl FnOnce() -> R) -> Result<R, EmbreeError> {
        let _api = self.lock();
        let result = f();
        self.check(what)?;
        Ok(result)
    }

    /// [`DeviceHandle::call`] for a release in `Drop`, where an error cannot be returned: it is collected (so no
    /// later call reports it) and, in debug builds, a broken invariant.
    pub(super) fn release(&self, what: &str, f: impl FnOnce()) {
        let result = self.call(what, f);
        debug_assert!(result.is_ok(), "{result:?}");
    }

    /// Collects an error a ray query reported (queries run unlocked and unchecked; this costs one relaxed load when
    /// there is none, inlined into the query: out of line it took 18 instructions a query with the call). Queries
    /// on a committed scene with a checked ray have no documented error, so one is a broken invariant: it panics,
    /// naming Embree's message.
    #[inline]
    pub(super) fn after_query(&self) {
        if self.state().any_pending.load(Ordering::Relaxed) {
            self.report_query_error();
        }
    }

    /// [`DeviceHandle::after_query`]'s error path.
    #[cold]
    #[inline(never)]
    fn report_query_error(&self) {
        if let Err(error) = self.call("ray query", || ()) {
            panic!("{error} (a committed scene rejected a checked ray)");
        }
    }

    /// Collects the error Embree reported on this thread since the last check, if any; `what` names the
    /// operation for the message.
    fn check(&self, what: &str) -> Result<(), EmbreeError> {
        // SAFETY: `raw` is a live device; this reads and clears the calling thread's error code.
        let code = unsafe { rtcGetDeviceError(self.raw) };
        match (self.state().take(), code) {
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

    /// A device property; 0 when Embree rejects the query (its error is collected here).
    fn property(&self, property: RTCDeviceProperty) -> isize {
        self.call("get device property", || {
            // SAFETY: `raw` is a live device and `property` one of the header's property constants.
            unsafe { rtcGetDeviceProperty(self.raw, property) }
        })
        .unwrap_or(0)
    }
}

impl Drop for DeviceHandle {
    fn drop(&mut self) {
        // Every scene and geometry holds an `Arc` to this handle and has released its Embree object already, so
        // no Embree call can still reach the callbacks; unregister them anyway before the state is freed.
        self.release("unregister device callbacks", || {
            // SAFETY: `raw` is live; a null callback unregisters.
            unsafe { rtcSetDeviceErrorFunction(self.raw, None, ptr::null_mut()) };
            // SAFETY: as above.
            unsafe { rtcSetDeviceMemoryMonitorFunction(self.raw, None, ptr::null_mut()) };
        });
        // SAFETY: we own one reference to `raw` and give it up exactly once; with no callback registered, nothing
        // can report into the state any more.
        unsafe { rtcReleaseDevice(self.raw) };
        // SAFETY: both callbacks holding the state's pointer were unregistered above and the device is released;
        // `self.state` is not touched again (`CallbackState` has no `Drop`).
        unsafe { self.state.free() };
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
        let handle = DeviceHandle {
            raw,
            api: Mutex::new(()),
            state: CallbackState::new(DeviceState::default()),
        };
        let user = handle.state.user();
        handle.call(&what, || {
            // SAFETY: `raw` is live and `on_error` has the `RTCErrorFunction` signature; `user` is the state owned
            // by `handle`, which unregisters the callback before freeing it (Drop).
            unsafe { rtcSetDeviceErrorFunction(raw, Some(on_error), user) };
            // SAFETY: as above, for the memory monitor.
            unsafe { rtcSetDeviceMemoryMonitorFunction(raw, Some(on_memory), user) };
        })?;
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

    /// Whether Embree traces packets of `width` rays (4, 8 or 16) with kernels of that width on this CPU; other widths
    /// are still answered, by narrower kernels or one ray at a time.
    pub fn native_packet(&self, width: usize) -> bool {
        let property = match width {
            4 => RTC_DEVICE_PROPERTY_NATIVE_RAY4_SUPPORTED,
            8 => RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED,
            16 => RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED,
            _ => return false,
        };
        self.inner.property(property) != 0
    }

    /// Bytes Embree currently has allocated on this device (BVHs and buffers), from its memory monitor.
    pub fn memory_bytes(&self) -> usize {
        usize::try_from(self.inner.state().bytes.load(Ordering::Relaxed)).unwrap_or(0)
    }

    /// The most bytes Embree has had allocated at once on this device.
    pub fn peak_memory_bytes(&self) -> usize {
        usize::try_from(self.inner.state().peak_bytes.load(Ordering::Relaxed)).unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sys::embree::{BuildQuality, Scene};

    /// A raw user pointer moved to another thread, as Embree hands it to callbacks on its worker threads.
    #[derive(Clone, Copy)]
    struct UserPtr(*mut c_void);
    // SAFETY: the pointee (`DeviceState`) is `Sync`; the tests only pass the pointer to the callbacks.
    unsafe impl Send for UserPtr {}

    impl UserPtr {
        fn get(self) -> *mut c_void {
            self.0
        }
    }

    /// The ownership pattern of [`DeviceHandle`] in pure Rust, so it can run under Miri (`cargo +nightly miri test
    /// --lib callback_state`): the user pointer is handed out, its owner then moves into an `Arc` (which broke the
    /// `&*box` pointer this replaced), the real callbacks write through it from two threads as Embree's would, Rust
    /// reads the state through the owner, and the owner frees it after the "C side" lets go. Miri reports a
    /// use of an invalidated pointer, a leak or a double free as an error.
    #[test]
    fn callback_state_survives_the_move_into_an_arc() {
        struct Owner {
            state: CallbackState<DeviceState>,
        }
        impl Drop for Owner {
            fn drop(&mut self) {
                // SAFETY: the threads holding the user pointer have been joined.
                unsafe { self.state.free() };
            }
        }
        let owner = Owner {
            state: CallbackState::new(DeviceState::default()),
        };
        let user = UserPtr(owner.state.user());
        let shared = Arc::new(owner);
        let threads: Vec<_> = (0..2)
            .map(|i| {
                let shared = Arc::clone(&shared);
                thread::spawn(move || {
                    // SAFETY: `user` is the live state's pointer, as registered with Embree.
                    unsafe { on_memory(user.get(), 100, false) };
                    // SAFETY: as above.
                    unsafe { on_memory(user.get(), -40, true) };
                    let message = CString::new(format!("thread {i}")).unwrap();
                    // SAFETY: as above; `message` is NUL-terminated and outlives the call.
                    unsafe { on_error(user.get(), RTC_ERROR_INVALID_ARGUMENT, message.as_ptr()) };
                    shared.state.get().take()
                })
            })
            .collect();
        let mut messages: Vec<_> = threads
            .into_iter()
            .map(|t| {
                t.join()
                    .unwrap()
                    .expect("each thread collects its own error")
            })
            .map(|e| (e.code, e.message))
            .collect();
        messages.sort_by(|a, b| a.1.cmp(&b.1));
        assert_eq!(
            messages,
            [
                (ErrorCode::InvalidArgument, "thread 0".to_string()),
                (ErrorCode::InvalidArgument, "thread 1".to_string())
            ]
        );
        let state = shared.state.get();
        assert_eq!(state.bytes.load(Ordering::Relaxed), 120);
        assert!((100..=200).contains(&state.peak_bytes.load(Ordering::Relaxed)));
        assert!(
            state.take().is_none(),
            "no error is pending for this thread"
        );
        assert!(!state.any_pending.load(Ordering::Relaxed));
    }

    #[test]
    fn pending_flag_follows_the_errors() {
        let state = DeviceState::default();
        assert!(!state.any_pending.load(Ordering::Relaxed));
        state.record(EmbreeError::invalid_argument("x"));
        assert!(state.any_pending.load(Ordering::Relaxed));
        assert_eq!(state.take().map(|e| e.message), Some("x".to_string()));
        assert!(!state.any_pending.load(Ordering::Relaxed));
    }

    /// An error of an Embree call is collected by that call: an unknown device property (which Embree 3 and 4
    /// reject with `invalid argument`) reads as 0 and is not reported by the next checked call.
    #[test]
    #[cfg_attr(miri, ignore = "calls Embree")]
    fn an_error_is_not_reported_by_the_next_call() {
        let device = Device::new().unwrap();
        let unknown = 0x7fff_0000;
        let raw = device.inner.call("probe", || {
            // SAFETY: `raw` is a live device; Embree rejects the unknown property with an error, nothing else.
            unsafe { rtcGetDeviceProperty(device.inner.raw, unknown) }
        });
        assert!(
            raw.is_err(),
            "embree accepted property {unknown:#x}: {raw:?}"
        );
        assert_eq!(device.inner.property(unknown), 0);
        Scene::new(&device, BuildQuality::Medium)
            .expect("the property's error was collected where it happened");
    }
}
