//! Intel Open Image Denoise 2.x, loaded at run time (`dlopen`) the first time a frame is denoised.
//!
//! **Why loaded, not linked.** Debian 12 has no OIDN package; `scripts/oidn.sh` lays out the CPU library from PyPI's
//! `pyoidn` wheel. Linking it (as the `oidn` crate does, through `OIDN_DIR` at build time) would make every build and
//! every start of cuticle need it; loaded on demand, cuticle without it works as before and `--denoise` alone fails,
//! saying where it looked. The C API used is eleven functions of `OpenImageDenoise/oidn.h` (2.x), declared here by
//! hand; this module checks every size before it reaches C, so [`denoise`] is safe.
//!
//! **Where the library is looked for**, in order: `$CUTICLE_OIDN` (a directory with `lib/`, or the library file),
//! `$XDG_DATA_HOME/cuticle/oidn/lib` (default `~/.local/share/cuticle/oidn/lib`, where `scripts/setup-debian.sh`
//! puts it), then the loader's own search (`libOpenImageDenoise.so.2` on `LD_LIBRARY_PATH` or the system's).

use std::ffi::{c_char, c_int, c_void, CStr};
use std::path::PathBuf;
use std::sync::OnceLock;

/// `OIDN_DEVICE_TYPE_CPU`.
const DEVICE_TYPE_CPU: c_int = 1;
/// `OIDN_FORMAT_FLOAT3`.
const FORMAT_FLOAT3: c_int = 3;
/// `OIDN_ERROR_NONE`.
const ERROR_NONE: c_int = 0;

/// An opaque OIDN handle (`OIDNDevice`, `OIDNFilter`).
type Handle = *mut c_void;

/// The entry points used, as `oidn.h` declares them.
struct Api {
    new_device: unsafe extern "C" fn(kind: c_int) -> Handle,
    set_device_int: unsafe extern "C" fn(device: Handle, name: *const c_char, value: c_int),
    commit_device: unsafe extern "C" fn(device: Handle),
    release_device: unsafe extern "C" fn(device: Handle),
    device_error: unsafe extern "C" fn(device: Handle, message: *mut *const c_char) -> c_int,
    new_filter: unsafe extern "C" fn(device: Handle, kind: *const c_char) -> Handle,
    #[allow(clippy::type_complexity)]
    set_shared_image: unsafe extern "C" fn(
        filter: Handle,
        name: *const c_char,
        data: *mut c_void,
        format: c_int,
        width: usize,
        height: usize,
        byte_offset: usize,
        pixel_stride: usize,
        row_stride: usize,
    ),
    set_filter_bool: unsafe extern "C" fn(filter: Handle, name: *const c_char, value: bool),
    commit_filter: unsafe extern "C" fn(filter: Handle),
    execute_filter: unsafe extern "C" fn(filter: Handle),
    release_filter: unsafe extern "C" fn(filter: Handle),
    // Kept loaded for the life of the process: the function pointers above point into it.
    _library: libloading::Library,
}

/// Why the denoiser cannot run, or what it reported.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct OidnError(pub String);

/// The library file names tried, in order (see the module docs).
fn candidates() -> Vec<PathBuf> {
    let name = "libOpenImageDenoise.so.2";
    let mut out = Vec::new();
    if let Some(dir) = std::env::var_os("CUTICLE_OIDN").map(PathBuf::from) {
        if dir.is_file() {
            out.push(dir);
        } else {
            out.push(dir.join("lib").join(name));
            out.push(dir.join(name));
        }
    }
    let data = std::env::var_os("XDG_DATA_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".local/share")));
    if let Some(data) = data {
        out.push(data.join("cuticle/oidn/lib").join(name));
    }
    out.push(PathBuf::from(name));
    out
}

fn load() -> Result<Api, String> {
    let mut tried = Vec::new();
    for path in candidates() {
        // A bare name goes to the loader's search; a path must exist to be worth a try.
        if path.components().count() > 1 && !path.exists() {
            tried.push(format!("{} (missing)", path.display()));
            continue;
        }
        // SAFETY: loading OpenImageDenoise runs only its static initialisers and those of its oneTBB, which have
        // no preconditions on the loading program.
        match unsafe { libloading::Library::new(&path) } {
            Ok(library) => return symbols(library),
            Err(e) => tried.push(format!("{} ({e})", path.display())),
        }
    }
    Err(format!(
        "Open Image Denoise is not installed: tried {}; `sh scripts/oidn.sh ~/.local/share/cuticle/oidn` installs it \
         (scripts/setup-debian.sh does), or set CUTICLE_OIDN to its directory",
        tried.join(", ")
    ))
}

fn symbols(library: libloading::Library) -> Result<Api, String> {
    /// # Safety
    /// As [`super::symbol`]'s.
    unsafe fn get<T: Copy>(library: &libloading::Library, name: &[u8]) -> Result<T, String> {
        // SAFETY: passed on to the caller.
        unsafe { super::symbol(library, name) }
            .map_err(|e| format!("Open Image Denoise lacks a 2.x function: {e}"))
    }
    // SAFETY: each field has exactly the parameter and return types `oidn.h` (2.x) declares for its symbol; the
    // pointers stay valid because `_library` is kept with them and never unloaded.
    unsafe {
        Ok(Api {
            new_device: get(&library, b"oidnNewDevice\0")?,
            set_device_int: get(&library, b"oidnSetDeviceInt\0")?,
            commit_device: get(&library, b"oidnCommitDevice\0")?,
            release_device: get(&library, b"oidnReleaseDevice\0")?,
            device_error: get(&library, b"oidnGetDeviceError\0")?,
            new_filter: get(&library, b"oidnNewFilter\0")?,
            set_shared_image: get(&library, b"oidnSetSharedFilterImage\0")?,
            set_filter_bool: get(&library, b"oidnSetFilterBool\0")?,
            commit_filter: get(&library, b"oidnCommitFilter\0")?,
            execute_filter: get(&library, b"oidnExecuteFilter\0")?,
            release_filter: get(&library, b"oidnReleaseFilter\0")?,
            _library: library,
        })
    }
}

fn api() -> Result<&'static Api, OidnError> {
    static API: OnceLock<Result<Api, String>> = OnceLock::new();
    API.get_or_init(load)
        .as_ref()
        .map_err(|e| OidnError(e.clone()))
}

/// Whether the library can be loaded (it is, on success).
pub fn available() -> Result<(), OidnError> {
    api().map(drop)
}

/// The images one [`denoise`] call reads: `width` × `height` RGB triples each, row by row.
pub struct Guides<'a> {
    /// The noisy colour (linear, high dynamic range).
    pub color: &'a [f32],
    /// The albedo guide, in [0, 1], or `None`.
    pub albedo: Option<&'a [f32]>,
    /// The normal guide, in [−1, 1], or `None` (OIDN reads it only with an albedo).
    pub normal: Option<&'a [f32]>,
    /// `color` is high dynamic range (radiance; a guide being prefiltered is not).
    pub hdr: bool,
    /// The guides are free of noise (prefiltered), so the filter may follow them exactly.
    pub clean_aux: bool,
}

/// Denoises `guides.color` with OIDN's `RT` filter (HDR, the guides as given, `cleanAux` off: the guides carry the
/// frame's own noise) on a CPU device of `threads` threads; returns the denoised RGB in the same layout. The
/// thread count is fixed by the caller so that the result does not follow the machine.
pub fn denoise(
    guides: &Guides<'_>,
    width: usize,
    height: usize,
    threads: usize,
) -> Result<Vec<f32>, OidnError> {
    let len = width
        .checked_mul(height)
        .and_then(|n| n.checked_mul(3))
        .ok_or_else(|| OidnError(format!("a {width} x {height} image is too large")))?;
    if width == 0 || height == 0 {
        return Err(OidnError("an empty image".to_owned()));
    }
    for (name, image) in [
        ("color", Some(guides.color)),
        ("albedo", guides.albedo),
        ("normal", guides.normal),
    ] {
        if let Some(image) = image {
            if image.len() != len {
                return Err(OidnError(format!(
                    "the {name} image has {} values for {width} x {height} RGB pixels",
                    image.len()
                )));
            }
        }
    }
    let threads = c_int::try_from(threads.max(1)).unwrap_or(c_int::MAX);
    let api = api()?;
    // Inputs are shared read-only: OIDN reads them and writes only "output". It takes `void*` for every image,
    // so the inputs are copied into buffers it may be handed mutably.
    let mut inputs: Vec<(&CStr, Vec<f32>)> = vec![(c"color", guides.color.to_vec())];
    if let Some(albedo) = guides.albedo {
        inputs.push((c"albedo", albedo.to_vec()));
        if let Some(normal) = guides.normal {
            inputs.push((c"normal", normal.to_vec()));
        }
    }
    let mut output = vec![0.0f32; len];
    // SAFETY: every pointer passed is either a handle OIDN returned (checked non-null) or a buffer of exactly
    // width × height × 3 f32 (checked above) that lives until the filter is released at the end of this block;
    // strides of 0 tell OIDN the images are packed. Names are NUL-terminated literals.
    unsafe {
        let device = (api.new_device)(DEVICE_TYPE_CPU);
        if device.is_null() {
            return Err(OidnError(
                "Open Image Denoise could not create a CPU device".to_owned(),
            ));
        }
        let error = |device: Handle| {
            let mut message: *const c_char = std::ptr::null();
            let code = (api.device_error)(device, &mut message);
            (code != ERROR_NONE).then(|| {
                let text = if message.is_null() {
                    String::new()
                } else {
                    CStr::from_ptr(message).to_string_lossy().into_owned()
                };
                OidnError(format!("Open Image Denoise: {text} (error {code})"))
            })
        };
        (api.set_device_int)(device, c"numThreads".as_ptr(), threads);
        (api.commit_device)(device);
        let result = (|| {
            if let Some(e) = error(device) {
                return Err(e);
            }
            let filter = (api.new_filter)(device, c"RT".as_ptr());
            if filter.is_null() {
                return Err(error(device).unwrap_or_else(|| OidnError("no RT filter".to_owned())));
            }
            for (name, image) in inputs.iter_mut() {
                (api.set_shared_image)(
                    filter,
                    name.as_ptr(),
                    image.as_mut_ptr().cast(),
                    FORMAT_FLOAT3,
                    width,
                    height,
                    0,
                    0,
                    0,
                );
            }
            (api.set_shared_image)(
                filter,
                c"output".as_ptr(),
                output.as_mut_ptr().cast(),
                FORMAT_FLOAT3,
                width,
                height,
                0,
                0,
                0,
            );
            (api.set_filter_bool)(filter, c"hdr".as_ptr(), guides.hdr);
            (api.set_filter_bool)(filter, c"cleanAux".as_ptr(), guides.clean_aux);
            (api.commit_filter)(filter);
            (api.execute_filter)(filter);
            let failed = error(device);
            (api.release_filter)(filter);
            failed.map_or(Ok(()), Err)
        })();
        (api.release_device)(device);
        result?;
    }
    Ok(output)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Sizes are checked before anything reaches C.
    #[test]
    fn wrong_sizes_are_refused_before_the_library_is_called() {
        let color = vec![0.5f32; 12];
        let g = Guides {
            color: &color,
            albedo: Some(&color[..9]),
            normal: None,
            hdr: true,
            clean_aux: false,
        };
        let e = denoise(&g, 2, 2, 1).unwrap_err();
        assert!(e.0.contains("albedo image has 9 values"), "{e}");
        let g = Guides {
            color: &color,
            albedo: None,
            normal: None,
            hdr: true,
            clean_aux: false,
        };
        assert!(denoise(&g, 0, 4, 1).is_err());
        assert!(denoise(&g, usize::MAX, 2, 1).is_err());
    }
}
