//! `PunchRuntime`: the extension's own facts (versions, where ONNX Runtime was loaded from).

use std::path::{Path, PathBuf};

use godot::builtin::{GString, VarDictionary};
use godot::global::godot_error;
use godot::prelude::{GodotClass, godot_api};

/// Version information about the punch controller extension and the ONNX Runtime it runs policies with.
#[derive(GodotClass)]
#[class(init, base = Object)]
pub struct PunchRuntime {}

#[godot_api]
impl PunchRuntime {
    /// Returns a Dictionary with `extension` (this extension's version), `godot_api` (the Godot API level it
    /// was built for), `onnxruntime` (the loaded ONNX Runtime's version, or "" if it failed to load) and
    /// `onnxruntime_library` (its absolute path). Loads ONNX Runtime if it is not loaded yet.
    #[func]
    fn versions() -> VarDictionary {
        let mut versions = VarDictionary::new();
        versions.set("extension", punch_core::VERSION);
        versions.set("godot_api", "4.6");
        let loaded = ensure_onnx_runtime();
        versions.set("onnxruntime", punch_core::runtime::version().unwrap_or(""));
        let library = punch_core::runtime::library_path().map(|p| p.display().to_string()).unwrap_or_default();
        versions.set("onnxruntime_library", &GString::from(library.as_str()));
        versions.set("onnxruntime_loaded", loaded);
        versions
    }
}

/// Loads ONNX Runtime from the `libonnxruntime.so*` that sits next to this extension's own library, by
/// absolute path, so that users never set an environment variable. Logs one clear error on failure.
pub fn ensure_onnx_runtime() -> bool {
    if punch_core::runtime::version().is_some() {
        return true;
    }
    let Some(dir) = own_library_dir() else {
        godot_error!("PunchController: could not determine where the extension library was loaded from");
        return false;
    };
    match punch_core::runtime::init_from_dir(&dir) {
        Ok(()) => true,
        Err(error) => {
            godot_error!("PunchController: {error}. Rebuild the addon (scons) so that bin/ holds ONNX Runtime.");
            false
        }
    }
}

/// Folder of the shared library this code is running from (found with `dladdr` on one of its functions).
#[cfg(unix)]
fn own_library_dir() -> Option<PathBuf> {
    use std::ffi::CStr;

    // SAFETY: Dl_info is plain data; dladdr fills it for an address inside a loaded object.
    let mut info: libc::Dl_info = unsafe { std::mem::zeroed() };
    let address = own_library_dir as *const libc::c_void;
    // SAFETY: `address` is a function of this library; `info` is a valid out-pointer.
    if unsafe { libc::dladdr(address, &mut info) } == 0 || info.dli_fname.is_null() {
        return None;
    }
    // SAFETY: dli_fname is a NUL-terminated path owned by the dynamic loader.
    let path = unsafe { CStr::from_ptr(info.dli_fname) }.to_str().ok()?;
    Path::new(path).canonicalize().ok()?.parent().map(Path::to_path_buf)
}

/// Folder of the DLL this code is running from (the module that holds one of its functions).
#[cfg(windows)]
fn own_library_dir() -> Option<PathBuf> {
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
    let address = own_library_dir as *const c_void;
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
