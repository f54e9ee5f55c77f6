//! `PunchRuntime`: the extension's own facts (versions, where ONNX Runtime was loaded from).

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
        versions.set("onnxruntime", punch_core::inference::runtime::version().unwrap_or(""));
        let library =
            punch_core::inference::runtime::library_path().map(|p| p.display().to_string()).unwrap_or_default();
        versions.set("onnxruntime_library", &GString::from(library.as_str()));
        versions.set("onnxruntime_loaded", loaded);
        versions
    }
}

/// Loads ONNX Runtime from the `libonnxruntime.so*` that sits next to this extension's own library, by
/// absolute path, so that users never set an environment variable. Logs one clear error on failure.
pub fn ensure_onnx_runtime() -> bool {
    if punch_core::inference::runtime::version().is_some() {
        return true;
    }
    let Some(dir) = punch_core::inference::runtime::own_binary_dir() else {
        godot_error!("PunchController: could not determine where the extension library was loaded from");
        return false;
    };
    match punch_core::inference::runtime::init_from_dir(&dir) {
        Ok(()) => true,
        Err(error) => {
            godot_error!("PunchController: {error}. Rebuild the addon (scons) so that bin/ holds ONNX Runtime.");
            false
        }
    }
}
