//! The process-wide ONNX Runtime: found beside the extension, loaded once by absolute path.
//!
//! ort allows one environment per process, so it lives in a `OnceLock` here and every policy shares it.

use std::ffi::CStr;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use crate::error::{CoreError, CoreResult};

/// File name of the ONNX Runtime library shipped next to the extension: on Linux the wheel's versioned
/// `libonnxruntime.so.X.Y.Z` (this prefix), on Windows `onnxruntime.dll` (this exact name).
#[cfg(not(windows))]
pub const LIBRARY_PREFIX: &str = "libonnxruntime.so";
#[cfg(windows)]
pub const LIBRARY_PREFIX: &str = "onnxruntime.dll";

struct Runtime {
    environment: ort::environment::Environment,
    library_path: PathBuf,
    version: String,
}

static RUNTIME: OnceLock<Runtime> = OnceLock::new();

/// Finds the ONNX Runtime library in `dir` (`LIBRARY_PREFIX`). When several versions are present the highest
/// version wins (compared numerically: 1.31 > 1.9), so a stale copy never shadows the one the build just
/// installed.
pub fn find_library_in(dir: &Path) -> CoreResult<PathBuf> {
    let missing = || CoreError::RuntimeLibraryMissing { dir: dir.to_path_buf(), name: LIBRARY_PREFIX };
    let entries = std::fs::read_dir(dir).map_err(|_| missing())?;
    let mut candidates: Vec<PathBuf> = entries
        .filter_map(|entry| entry.ok().map(|e| e.path()))
        .filter(|path| path.file_name().and_then(|name| name.to_str()).is_some_and(is_runtime_library))
        .collect();
    candidates.sort_by_key(|path| version_key(path));
    candidates.pop().ok_or_else(missing)
}

fn is_runtime_library(name: &str) -> bool {
    if cfg!(windows) { name.eq_ignore_ascii_case(LIBRARY_PREFIX) } else { name.starts_with(LIBRARY_PREFIX) }
}

/// The numeric parts after `.so` in a library name: `libonnxruntime.so.1.31.1` -> [1, 31, 1].
fn version_key(path: &Path) -> Vec<u64> {
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default();
    name.trim_start_matches(LIBRARY_PREFIX).split('.').filter_map(|part| part.parse().ok()).collect()
}

/// Loads ONNX Runtime from `library_path` (made absolute first: ort resolves relative paths against the
/// executable, which is Godot, not the project). A second call is a no-op that returns the first result.
pub fn init(library_path: &Path) -> CoreResult<()> {
    if RUNTIME.get().is_some() {
        return Ok(());
    }
    let library_path = std::path::absolute(library_path)
        .map_err(|e| CoreError::RuntimeLoad { path: library_path.to_path_buf(), reason: e.to_string() })?;
    let load_error = |reason: String| CoreError::RuntimeLoad { path: library_path.clone(), reason };
    if !library_path.is_file() {
        return Err(load_error("no such file".into()));
    }
    let version = read_version(&library_path).map_err(load_error)?;
    let environment = ort::init_from(&library_path)
        .map_err(|e| load_error(e.to_string()))?
        .with_name("punch_controller")
        .build()
        .map_err(|e| load_error(e.to_string()))?;
    // A racing thread may have won; its runtime is equivalent, so losing the race is fine.
    let _ = RUNTIME.set(Runtime { environment, library_path, version });
    Ok(())
}

/// Loads ONNX Runtime from the library `find_library_in` finds in `dir`.
pub fn init_from_dir(dir: &Path) -> CoreResult<()> {
    if RUNTIME.get().is_some() {
        return Ok(());
    }
    init(&find_library_in(dir)?)
}

/// Folder of the binary this code is linked into: the extension's shared library in Godot, the test program in
/// tests (found with `dladdr` on one of its functions).
#[cfg(unix)]
pub fn own_binary_dir() -> Option<PathBuf> {
    use std::ffi::CStr;

    // SAFETY: Dl_info is plain data; dladdr fills it for an address inside a loaded object.
    let mut info: libc::Dl_info = unsafe { std::mem::zeroed() };
    let address = own_binary_dir as *const libc::c_void;
    // SAFETY: `address` is a function of this library; `info` is a valid out-pointer.
    if unsafe { libc::dladdr(address, &mut info) } == 0 || info.dli_fname.is_null() {
        return None;
    }
    // SAFETY: dli_fname is a NUL-terminated path owned by the dynamic loader.
    let path = unsafe { CStr::from_ptr(info.dli_fname) }.to_str().ok()?;
    Path::new(path).canonicalize().ok()?.parent().map(Path::to_path_buf)
}

/// Folder of the binary this code is linked into: the extension's DLL in Godot, the test program in tests (the
/// module that holds one of its functions).
#[cfg(windows)]
pub fn own_binary_dir() -> Option<PathBuf> {
    use std::ffi::c_void;
    use std::os::windows::ffi::OsStringExt;

    const FROM_ADDRESS: u32 = 0x4; // GET_MODULE_HANDLE_EX_FLAG_FROM_ADDRESS
    const UNCHANGED_REFCOUNT: u32 = 0x2; // GET_MODULE_HANDLE_EX_FLAG_UNCHANGED_REFCOUNT
    #[link(name = "kernel32")]
    unsafe extern "system" {
        fn GetModuleHandleExW(flags: u32, address: *const c_void, module: *mut *mut c_void) -> i32;
        fn GetModuleFileNameW(module: *mut c_void, file_name: *mut u16, size: u32) -> u32;
    }
    let mut module = std::ptr::null_mut();
    let address = own_binary_dir as *const c_void;
    // SAFETY: `address` is a function of this DLL; `module` is a valid out-pointer; no reference is taken.
    if unsafe { GetModuleHandleExW(FROM_ADDRESS | UNCHANGED_REFCOUNT, address, &mut module) } == 0 {
        return None;
    }
    let mut buffer = vec![0u16; 32_768]; // the longest path Windows allows
    // SAFETY: `buffer` holds `buffer.len()` u16s; the call writes at most that many.
    let length = unsafe { GetModuleFileNameW(module, buffer.as_mut_ptr(), buffer.len() as u32) } as usize;
    if length == 0 || length >= buffer.len() {
        return None;
    }
    let path = PathBuf::from(std::ffi::OsString::from_wide(&buffer[..length]));
    path.parent().map(Path::to_path_buf)
}

/// The loaded ONNX Runtime's version string (e.g. "1.31.1"), if it is loaded.
pub fn version() -> Option<&'static str> {
    RUNTIME.get().map(|r| r.version.as_str())
}

/// Absolute path of the loaded library, if it is loaded.
pub fn library_path() -> Option<&'static Path> {
    RUNTIME.get().map(|r| r.library_path.as_path())
}

pub(crate) fn environment() -> CoreResult<&'static ort::environment::Environment> {
    RUNTIME.get().map(|r| &r.environment).ok_or(CoreError::RuntimeNotInitialised)
}

/// Asks the library itself for its version (`OrtGetApiBase()->GetVersionString()`), so the figure we report
/// is the one actually running, not the one in a file name.
fn read_version(library_path: &Path) -> Result<String, String> {
    // SAFETY: loading ONNX Runtime runs no initialisers with preconditions; ort loads the same file next.
    let library = unsafe { libloading::Library::new(library_path) }.map_err(|e| e.to_string())?;
    // SAFETY: OrtGetApiBase has this signature in every ONNX Runtime release.
    let get_api_base =
        unsafe { library.get::<unsafe extern "C" fn() -> *const ort::sys::OrtApiBase>(b"OrtGetApiBase") }
            .map_err(|_| "the library does not export OrtGetApiBase (not ONNX Runtime?)".to_string())?;
    // SAFETY: the API base is a static table inside the library, valid while the library is loaded.
    let version = unsafe {
        let base = get_api_base();
        if base.is_null() {
            return Err("OrtGetApiBase returned null".into());
        }
        CStr::from_ptr(((*base).GetVersionString)()).to_string_lossy().into_owned()
    };
    Ok(version)
}
