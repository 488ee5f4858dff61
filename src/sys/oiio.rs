//! Safe wrappers over the OpenImageIO shim (`ffi/oiio_shim.{h,cpp}`).
//!
//! The shim is a small `extern "C"` API that `build.rs` compiles into a shared library linked against OpenImageIO;
//! the function types below mirror `ffi/oiio_shim.h` by hand.
//!
//! **Loaded on first use, not at start-up.** Debian's OpenImageIO pulls in 260 shared libraries (codecs, OpenCV,
//! FFmpeg, ...) whose relocation cost every process 0.4–0.55 s of wall time before `main` (measured: an empty C
//! program linked against Embree starts in 0.01 s, against Embree and OpenImageIO in 0.54–0.57 s). The cuticle binary
//! therefore does not link OpenImageIO: the shim's bytes are embedded in it and loaded with `dlopen` ([`ffi::api`])
//! the first time an image is read or written, and `render` starts that load on a background thread ([`preload`]) so
//! that it overlaps the hair loading, the BVH build and the render instead of preceding them, and waits for it before
//! the process exits ([`finish_preload`]). This module checks every length and string before it reaches C++, so the
//! functions it exposes are safe. Errors come back as [`OiioError`] holding OpenImageIO's own message;
//! [`crate::image`] adds the file name.

use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::path::Path;
use std::ptr::NonNull;

/// Raw declarations mirroring `ffi/oiio_shim.h`.
mod ffi {
    use std::ffi::{c_char, c_int, c_uint, c_void};
    use std::sync::OnceLock;

    /// `CUTICLE_OIIO_FLOAT`.
    pub const FLOAT: c_int = 0;
    /// `CUTICLE_OIIO_HALF`.
    pub const HALF: c_int = 1;
    /// `CUTICLE_OIIO_UINT8`.
    pub const UINT8: c_int = 2;
    /// `CUTICLE_OIIO_UNASSOCIATED_ALPHA`.
    pub const UNASSOCIATED_ALPHA: c_uint = 1;

    /// `CuticleOiioInput`: opaque, only ever behind a pointer (the marker makes it neither `Send`,
    /// `Sync` nor `Unpin`, as the Rustonomicon advises for foreign opaque types).
    #[repr(C)]
    pub struct CuticleOiioInput {
        _private: [u8; 0],
        _marker: std::marker::PhantomData<(*mut u8, std::marker::PhantomPinned)>,
    }

    /// The shim's entry points, as `ffi/oiio_shim.h` declares them.
    pub struct Api {
        pub version: unsafe extern "C" fn() -> c_int,
        #[allow(clippy::type_complexity)]
        pub write_window: unsafe extern "C" fn(
            path: *const c_char,
            width: c_int,
            height: c_int,
            nchannels: c_int,
            channel_names: *const *const c_char,
            pixels: *const c_void,
            pixel_format: c_int,
            file_format: c_int,
            flags: c_uint,
            window: *const super::Window,
            nattrs: c_int,
            attr_names: *const *const c_char,
            attr_values: *const *const c_char,
            err: *mut c_char,
            err_cap: usize,
        ) -> c_int,
        pub input_window:
            unsafe extern "C" fn(input: *const CuticleOiioInput, window: *mut super::Window),
        pub input_attribute: unsafe extern "C" fn(
            input: *const CuticleOiioInput,
            name: *const c_char,
            out: *mut c_char,
            out_cap: usize,
        ) -> c_int,
        pub open: unsafe extern "C" fn(
            path: *const c_char,
            err: *mut c_char,
            err_cap: usize,
        ) -> *mut CuticleOiioInput,
        pub input_size: unsafe extern "C" fn(
            input: *const CuticleOiioInput,
            width: *mut c_int,
            height: *mut c_int,
            nchannels: *mut c_int,
        ),
        pub input_channel_name:
            unsafe extern "C" fn(input: *const CuticleOiioInput, channel: c_int) -> *const c_char,
        pub read_float: unsafe extern "C" fn(
            input: *mut CuticleOiioInput,
            out: *mut f32,
            out_len: usize,
            err: *mut c_char,
            err_cap: usize,
        ) -> c_int,
        pub close: unsafe extern "C" fn(input: *mut CuticleOiioInput),
        /// Keeps the shim (and OpenImageIO) mapped for as long as the pointers above are used: forever.
        _library: libloading::Library,
    }

    /// The shim library, built by `build.rs` and embedded in the binary.
    static SHIM: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/libcuticle_oiio.so"));

    static API: OnceLock<Result<Api, String>> = OnceLock::new();

    /// The shim's entry points, loading the shim (and with it OpenImageIO) on the first call; a call made while
    /// another thread loads it waits for that load.
    pub fn api() -> Result<&'static Api, super::OiioError> {
        API.get_or_init(load)
            .as_ref()
            .map_err(|e| super::OiioError::new(format!("cannot load OpenImageIO: {e}")))
    }

    /// Writes the embedded shim into an anonymous in-memory file (`memfd_create`) and `dlopen`s it by its
    /// `/proc/self/fd` path: nothing is written to disk, and a `noexec` /tmp does not matter. Where that fails
    /// (no memfd, no /proc), the shim goes to a temporary file in the temporary directory, deleted once loaded.
    fn load() -> Result<Api, String> {
        let library = match load_from_memfd() {
            Ok(library) => library,
            Err(memfd) => load_from_temp_file()
                .map_err(|file| format!("from memory ({memfd}), from a temporary file ({file})"))?,
        };
        symbols(library)
    }

    pub(super) fn load_from_memfd() -> Result<libloading::Library, String> {
        use std::io::Write;
        use std::os::fd::AsRawFd;
        let fd = rustix::fs::memfd_create("cuticle-oiio-shim", rustix::fs::MemfdFlags::CLOEXEC)
            .map_err(|e| format!("memfd_create: {e}"))?;
        let mut file = std::fs::File::from(fd);
        file.write_all(SHIM).map_err(|e| e.to_string())?;
        open(std::path::Path::new(&format!(
            "/proc/self/fd/{}",
            file.as_raw_fd()
        )))
        // `file` closes here: the loader keeps its own mapping.
    }

    pub(super) fn load_from_temp_file() -> Result<libloading::Library, String> {
        use std::io::Write;
        let mut file = tempfile::Builder::new()
            .prefix("cuticle-oiio-shim-")
            .suffix(".so")
            .tempfile()
            .map_err(|e| e.to_string())?;
        file.write_all(SHIM).map_err(|e| e.to_string())?;
        file.flush().map_err(|e| e.to_string())?;
        open(file.path())
        // The file is deleted here; the loader keeps its mapping.
    }

    fn open(path: &std::path::Path) -> Result<libloading::Library, String> {
        // SAFETY: the library is cuticle's own shim, built with this binary; loading it runs only the static
        // initialisers of OpenImageIO and its dependencies, which have no preconditions on the loading program.
        unsafe { libloading::Library::new(path) }.map_err(|e| e.to_string())
    }

    /// The shim's entry points in `library`.
    pub(super) fn symbols(library: libloading::Library) -> Result<Api, String> {
        use super::super::symbol as get;
        // SAFETY: each symbol is one of the shim's `extern "C"` functions, and the field it fills has exactly
        // the parameter and return types `ffi/oiio_shim.h` declares for it (mirrored by hand, as before); the
        // pointers stay valid because `_library` is kept with them and never unloaded.
        unsafe {
            Ok(Api {
                version: get(&library, b"cuticle_oiio_version\0")?,
                write_window: get(&library, b"cuticle_oiio_write_window\0")?,
                input_window: get(&library, b"cuticle_oiio_input_window\0")?,
                input_attribute: get(&library, b"cuticle_oiio_input_attribute\0")?,
                open: get(&library, b"cuticle_oiio_open\0")?,
                input_size: get(&library, b"cuticle_oiio_input_size\0")?,
                input_channel_name: get(&library, b"cuticle_oiio_input_channel_name\0")?,
                read_float: get(&library, b"cuticle_oiio_read_float\0")?,
                close: get(&library, b"cuticle_oiio_close\0")?,
                _library: library,
            })
        }
    }
}

/// The background load [`preload`] started, if any, for [`finish_preload`].
static PRELOADING: std::sync::Mutex<Option<std::thread::JoinHandle<()>>> =
    std::sync::Mutex::new(None);

/// Starts loading OpenImageIO on a background thread, for a command that will read or write an image after other
/// work: the load then overlaps that work. Errors surface at the first image call. The process must call
/// [`finish_preload`] before it exits.
pub fn preload() {
    let handle = std::thread::spawn(|| {
        let _ = ffi::api();
    });
    if let Ok(mut slot) = PRELOADING.lock() {
        *slot = Some(handle);
    }
}

/// Waits for a load [`preload`] started. A process must not exit while another thread is inside `dlopen`: exit
/// runs the static destructors of the libraries loaded so far while the loader runs the initialisers of the next,
/// and the process can die of a signal instead of exiting with its code (a `render` refused for its memory
/// estimate, exit status 2, can end by a signal).
pub fn finish_preload() {
    let handle = PRELOADING.lock().ok().and_then(|mut slot| slot.take());
    if let Some(handle) = handle {
        let _ = handle.join();
    }
}

/// Bytes reserved for an error message from the shim (longer ones are truncated).
const ERROR_CAPACITY: usize = 1024;

/// An error reported by OpenImageIO or found before calling it.
#[derive(Debug, thiserror::Error)]
#[error("{message}")]
pub struct OiioError {
    /// What went wrong, in OpenImageIO's words where it reported the error.
    pub message: String,
}

impl OiioError {
    fn new(message: impl Into<String>) -> Self {
        OiioError {
            message: message.into(),
        }
    }

    /// The message the shim wrote into `buffer`.
    fn from_buffer(buffer: &[u8; ERROR_CAPACITY]) -> Self {
        let message = CStr::from_bytes_until_nul(buffer)
            .map(|s| s.to_string_lossy().trim_end().to_owned())
            .unwrap_or_default();
        if message.is_empty() {
            Self::new("openimageio failed without a message")
        } else {
            Self::new(message)
        }
    }
}

/// The pixel format a file stores.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileFormat {
    /// 32-bit float: exact for everything the renderer produces.
    Float,
    /// 16-bit half float.
    Half,
    /// 8-bit unsigned, 0..=255 meaning 0..=1 (display-referred, already encoded by the caller).
    Uint8,
}

impl FileFormat {
    fn raw(self) -> c_int {
        match self {
            FileFormat::Float => ffi::FLOAT,
            FileFormat::Half => ffi::HALF,
            FileFormat::Uint8 => ffi::UINT8,
        }
    }
}

/// Interleaved pixels in memory, in one of the formats the shim accepts.
#[derive(Clone, Copy, Debug)]
pub enum Pixels<'a> {
    /// 32-bit floats.
    F32(&'a [f32]),
    /// 8-bit values, 255 meaning 1.
    U8(&'a [u8]),
}

impl Pixels<'_> {
    fn len(&self) -> usize {
        match self {
            Pixels::F32(p) => p.len(),
            Pixels::U8(p) => p.len(),
        }
    }

    fn raw(&self) -> (*const c_void, c_int) {
        match self {
            Pixels::F32(p) => (p.as_ptr().cast(), ffi::FLOAT),
            Pixels::U8(p) => (p.as_ptr().cast(), ffi::UINT8),
        }
    }
}

/// How [`write_image`] stores the pixels.
#[derive(Clone, Copy, Debug)]
pub struct WriteOptions {
    /// The pixel format in the file; OpenImageIO converts from the memory format.
    pub format: FileFormat,
    /// The colour channels are not premultiplied by alpha, so OpenImageIO must not divide them by
    /// alpha when writing a format with unassociated alpha (PNG).
    pub unassociated_alpha: bool,
}

/// The OpenImageIO version linked, as `major * 10000 + minor * 100 + patch` (20407 for 2.4.7).
pub fn version() -> Result<u32, OiioError> {
    let api = ffi::api()?;
    // SAFETY: the function takes no arguments and returns a compile-time constant.
    let v = unsafe { (api.version)() };
    Ok(u32::try_from(v).unwrap_or(0))
}

fn path_cstring(path: &Path) -> Result<CString, OiioError> {
    #[cfg(unix)]
    let bytes = {
        use std::os::unix::ffi::OsStrExt;
        path.as_os_str().as_bytes().to_vec()
    };
    #[cfg(not(unix))]
    let bytes = path
        .to_str()
        .ok_or_else(|| OiioError::new("path is not valid UTF-8"))?
        .as_bytes()
        .to_vec();
    CString::new(bytes).map_err(|_| OiioError::new("path contains a NUL byte"))
}

fn to_c_int(value: usize, what: &str) -> Result<c_int, OiioError> {
    c_int::try_from(value).map_err(|_| OiioError::new(format!("{what} {value} is too large")))
}

/// Writes `width` × `height` pixels of `channels.len()` interleaved channels to `path`, in the file
/// format its extension names (OpenImageIO's choice), overwriting any existing file in place
/// ([`crate::image::write`] adds the atomic temporary-file-and-rename step).
///
/// A channel named `A` becomes the alpha channel, one named `Z` the depth channel.
pub fn write_image<S: AsRef<str>>(
    path: &Path,
    width: usize,
    height: usize,
    channels: &[S],
    pixels: Pixels<'_>,
    options: WriteOptions,
) -> Result<(), OiioError> {
    write_image_window(path, width, height, channels, pixels, options, None, &[])
}

/// Where an image's pixels sit in a larger frame (`CuticleOiioWindow` of `ffi/oiio_shim.h`; EXR's data window
/// inside its display window): pixel (0, 0) of the data is pixel (`x`, `y`) of a `full_width` × `full_height`
/// frame.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    /// Column of the data's first pixel in the full frame.
    pub x: c_int,
    /// Row of the data's first pixel in the full frame.
    pub y: c_int,
    /// Width of the full frame.
    pub full_width: c_int,
    /// Height of the full frame.
    pub full_height: c_int,
}

/// Longest string attribute [`OpenImage::attributes`] returns, bytes.
const ATTRIBUTE_CAPACITY: usize = 4096;

/// [`write_image`] with the data placed at `window` in a larger frame (`None`: the image is the whole frame) and
/// string `attributes` (name, value) stored as file metadata (EXR header attributes).
#[allow(clippy::too_many_arguments)]
pub fn write_image_window<S: AsRef<str>>(
    path: &Path,
    width: usize,
    height: usize,
    channels: &[S],
    pixels: Pixels<'_>,
    options: WriteOptions,
    window: Option<Window>,
    attributes: &[(String, String)],
) -> Result<(), OiioError> {
    let expected = width
        .checked_mul(height)
        .and_then(|n| n.checked_mul(channels.len()))
        .ok_or_else(|| OiioError::new("image size overflows"))?;
    if expected == 0 {
        return Err(OiioError::new(format!(
            "empty image ({width}x{height}, {} channels)",
            channels.len()
        )));
    }
    if pixels.len() != expected {
        return Err(OiioError::new(format!(
            "pixel buffer holds {} values, {width}x{height}x{} needs {expected}",
            pixels.len(),
            channels.len()
        )));
    }
    let c_string =
        |s: &str| CString::new(s).map_err(|_| OiioError::new(format!("{s:?} contains a NUL byte")));
    let c_path = path_cstring(path)?;
    let names = channels
        .iter()
        .map(|n| c_string(n.as_ref()))
        .collect::<Result<Vec<_>, _>>()?;
    let name_ptrs: Vec<*const c_char> = names.iter().map(|n| n.as_ptr()).collect();
    let keys = attributes
        .iter()
        .map(|(k, _)| c_string(k))
        .collect::<Result<Vec<_>, _>>()?;
    let values = attributes
        .iter()
        .map(|(_, v)| c_string(v))
        .collect::<Result<Vec<_>, _>>()?;
    let key_ptrs: Vec<*const c_char> = keys.iter().map(|k| k.as_ptr()).collect();
    let value_ptrs: Vec<*const c_char> = values.iter().map(|v| v.as_ptr()).collect();
    let (pixel_ptr, pixel_format) = pixels.raw();
    let (c_width, c_height) = (to_c_int(width, "width")?, to_c_int(height, "height")?);
    let c_nchannels = to_c_int(channels.len(), "channel count")?;
    let c_nattrs = to_c_int(attributes.len(), "attribute count")?;
    let flags = if options.unassociated_alpha {
        ffi::UNASSOCIATED_ALPHA
    } else {
        0
    };
    let window_ptr = window
        .as_ref()
        .map_or(std::ptr::null(), |w| w as *const Window);
    let mut err = [0u8; ERROR_CAPACITY];
    // SAFETY: as in `write_image`; in addition `window_ptr` is null or points to a `Window` that outlives the
    // call, and `key_ptrs`/`value_ptrs` hold `attributes.len()` NUL-terminated strings each, alive until after it.
    let status = unsafe {
        (ffi::api()?.write_window)(
            c_path.as_ptr(),
            c_width,
            c_height,
            c_nchannels,
            name_ptrs.as_ptr(),
            pixel_ptr,
            pixel_format,
            options.format.raw(),
            flags,
            window_ptr,
            c_nattrs,
            key_ptrs.as_ptr(),
            value_ptrs.as_ptr(),
            err.as_mut_ptr().cast(),
            err.len(),
        )
    };
    if status == 0 {
        Ok(())
    } else {
        Err(OiioError::from_buffer(&err))
    }
}

/// An image file open for reading: its header read (size and channel names), its pixels not yet decoded, so a
/// caller can look at the header (size, data window, attributes) and then decode the pixels without opening the
/// file a second time.
pub struct OpenImage {
    input: Input,
    /// Width of the data window, in pixels.
    pub width: usize,
    /// Height of the data window, in pixels.
    pub height: usize,
    /// Channel names in the order OpenImageIO reports them.
    pub channels: Vec<String>,
}

/// Opens `path` (first subimage; any format OpenImageIO reads) and reads its size and channel names.
pub fn open_image(path: &Path) -> Result<OpenImage, OiioError> {
    let c_path = path_cstring(path)?;
    let mut err = [0u8; ERROR_CAPACITY];
    let api = ffi::api()?;
    // SAFETY: `c_path` is NUL-terminated and outlives the call; `err` is writable for its length.
    let raw = unsafe { (api.open)(c_path.as_ptr(), err.as_mut_ptr().cast(), err.len()) };
    let input = Input {
        raw: NonNull::new(raw).ok_or_else(|| OiioError::from_buffer(&err))?,
        api,
    };
    let (mut width, mut height, mut nchannels): (c_int, c_int, c_int) = (0, 0, 0);
    // SAFETY: `input` is an open handle and the three out-pointers are valid, distinct locals.
    unsafe { (api.input_size)(input.raw.as_ptr(), &mut width, &mut height, &mut nchannels) };
    let (Ok(width), Ok(height), Ok(nchannels)) = (
        usize::try_from(width),
        usize::try_from(height),
        usize::try_from(nchannels),
    ) else {
        return Err(OiioError::new("image reports a negative size"));
    };
    let channels = (0..nchannels)
        .map(|c| {
            let c = to_c_int(c, "channel index")?;
            // SAFETY: `input` is open; the shim bounds-checks `c` (null when out of range).
            let name = unsafe { (api.input_channel_name)(input.raw.as_ptr(), c) };
            if name.is_null() {
                return Err(OiioError::new(format!("channel {c} has no name")));
            }
            // SAFETY: a non-null name is NUL-terminated and lives until `input` is closed (after
            // this copy).
            let name = unsafe { CStr::from_ptr(name) };
            Ok(name.to_string_lossy().into_owned())
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(OpenImage {
        input,
        width,
        height,
        channels,
    })
}

impl OpenImage {
    /// Where the data window sits in the full frame.
    pub fn window(&self) -> Window {
        let mut window = Window {
            x: 0,
            y: 0,
            full_width: 0,
            full_height: 0,
        };
        // SAFETY: `input` is an open handle and `window` a valid local the shim fills.
        unsafe { (self.input.api.input_window)(self.input.raw.as_ptr(), &mut window) };
        window
    }

    /// The value of each string attribute named in `names`, `None` when the file has none of that name.
    pub fn attributes(&self, names: &[&str]) -> Result<Vec<Option<String>>, OiioError> {
        let mut attributes = Vec::with_capacity(names.len());
        for name in names {
            let c_name = CString::new(*name).map_err(|_| {
                OiioError::new(format!("attribute name {name:?} contains a NUL byte"))
            })?;
            let mut buffer = vec![0u8; ATTRIBUTE_CAPACITY];
            // SAFETY: `input` is open, `c_name` is NUL-terminated, `buffer` is writable for its length; all
            // outlive the call.
            let n = unsafe {
                (self.input.api.input_attribute)(
                    self.input.raw.as_ptr(),
                    c_name.as_ptr(),
                    buffer.as_mut_ptr().cast(),
                    buffer.len(),
                )
            };
            attributes.push(match n {
                -1 => None,
                n if n < 0 => {
                    return Err(OiioError::new(format!(
                        "attribute {name:?} is longer than {ATTRIBUTE_CAPACITY} bytes"
                    )))
                }
                n => {
                    buffer.truncate(n as usize);
                    Some(String::from_utf8_lossy(&buffer).into_owned())
                }
            });
        }
        Ok(attributes)
    }

    /// Decodes the pixels, converted to `f32`, and closes the file. 8-bit files come back as stored, divided by
    /// 255 (no sRGB decoding); colour is premultiplied by alpha (OpenImageIO multiplies it in for formats that
    /// store straight alpha, such as PNG).
    pub fn read(self) -> Result<DecodedImage, OiioError> {
        let len = self
            .width
            .checked_mul(self.height)
            .and_then(|n| n.checked_mul(self.channels.len()))
            .ok_or_else(|| OiioError::new("image size overflows"))?;
        let mut data = vec![0.0f32; len];
        let mut err = [0u8; ERROR_CAPACITY];
        // SAFETY: `input` is open; `data` is writable for exactly `len` floats, the size the shim
        // checks against width·height·nchannels; `err` is writable for its length.
        let status = unsafe {
            (self.input.api.read_float)(
                self.input.raw.as_ptr(),
                data.as_mut_ptr(),
                data.len(),
                err.as_mut_ptr().cast(),
                err.len(),
            )
        };
        if status != 0 {
            return Err(OiioError::from_buffer(&err));
        }
        Ok(DecodedImage {
            width: self.width,
            height: self.height,
            channels: self.channels,
            data,
        })
    }
}

/// An image read by [`read_image`]: interleaved `f32` pixels, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct DecodedImage {
    /// Width of the data window, in pixels.
    pub width: usize,
    /// Height of the data window, in pixels.
    pub height: usize,
    /// Channel names in the order OpenImageIO reports them.
    pub channels: Vec<String>,
    /// `width * height * channels.len()` values.
    pub data: Vec<f32>,
}

/// An open `CuticleOiioInput`, closed on drop, with the loaded shim that opened it.
struct Input {
    raw: NonNull<ffi::CuticleOiioInput>,
    api: &'static ffi::Api,
}

impl Drop for Input {
    fn drop(&mut self) {
        // SAFETY: the handle came from `cuticle_oiio_open` and `Input` owns it: it is closed once.
        unsafe { (self.api.close)(self.raw.as_ptr()) }
    }
}

/// Reads the first subimage of `path` (any format OpenImageIO reads: EXR including DWAA/DWAB,
/// Radiance HDR, PNG, TIFF, ...), converted to `f32` ([`OpenImage::read`]).
pub fn read_image(path: &Path) -> Result<DecodedImage, OiioError> {
    open_image(path)?.read()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn links_openimageio_2_4_or_later() {
        let version = version().expect("the embedded shim loads");
        assert!(version >= 20400, "linked OpenImageIO version {version}");
    }

    #[test]
    fn the_shim_loads_from_memory_and_from_a_temporary_file() {
        for (how, library) in [
            ("memfd", ffi::load_from_memfd()),
            ("temporary file", ffi::load_from_temp_file()),
        ] {
            let api = ffi::symbols(library.unwrap_or_else(|e| panic!("{how}: {e}")))
                .unwrap_or_else(|e| panic!("{how}: {e}"));
            // SAFETY: takes no arguments, returns a constant.
            let v = unsafe { (api.version)() };
            assert!(v >= 20400, "{how}: OpenImageIO version {v}");
        }
    }

    #[test]
    fn rejects_a_buffer_of_the_wrong_size() {
        let err = write_image(
            Path::new("unused.exr"),
            2,
            2,
            &["R"],
            Pixels::F32(&[0.0; 3]),
            WriteOptions {
                format: FileFormat::Float,
                unassociated_alpha: false,
            },
        )
        .unwrap_err();
        assert!(err.message.contains("holds 3 values"), "{err}");
    }

    #[test]
    fn window_layout_matches_the_c_struct() {
        assert_eq!(
            std::mem::size_of::<Window>(),
            4 * std::mem::size_of::<c_int>()
        );
        assert_eq!(
            std::mem::align_of::<Window>(),
            std::mem::align_of::<c_int>()
        );
        assert_eq!(std::mem::offset_of!(Window, full_height), 12);
    }

    #[test]
    fn a_window_and_attributes_are_read_back() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("tile.exr");
        let window = Window {
            x: 3,
            y: 2,
            full_width: 10,
            full_height: 8,
        };
        let attributes = [("cuticle:scene".to_owned(), "abc".to_owned())];
        write_image_window(
            &path,
            2,
            1,
            &["R"],
            Pixels::F32(&[1.0, 2.0]),
            WriteOptions {
                format: FileFormat::Float,
                unassociated_alpha: false,
            },
            Some(window),
            &attributes,
        )
        .unwrap();
        let file = open_image(&path).unwrap();
        assert_eq!((file.width, file.height), (2, 1));
        assert_eq!(file.window(), window);
        assert_eq!(
            file.attributes(&["cuticle:scene", "cuticle:missing"])
                .unwrap(),
            [Some("abc".to_owned()), None]
        );
        assert_eq!(file.read().unwrap().data, [1.0, 2.0]);
    }

    #[test]
    fn a_window_outside_the_frame_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let window = Window {
            x: 9,
            y: 0,
            full_width: 10,
            full_height: 8,
        };
        let err = write_image_window(
            &dir.path().join("tile.exr"),
            2,
            1,
            &["R"],
            Pixels::F32(&[1.0, 2.0]),
            WriteOptions {
                format: FileFormat::Float,
                unassociated_alpha: false,
            },
            Some(window),
            &[],
        )
        .unwrap_err();
        assert!(err.message.contains("outside"), "{err}");
    }

    #[test]
    fn reports_a_missing_file() {
        let err = read_image(Path::new("/nonexistent/cuticle/missing.exr")).unwrap_err();
        assert!(!err.message.is_empty());
    }
}
