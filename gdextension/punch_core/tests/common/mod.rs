//! Shared test helpers: the project's fixtures and the ONNX Runtime library the build installed.

/// The ONNX writer `punch_model_check`'s tests use.
#[path = "../../../punch_model_check/tests/common/onnx_bytes.rs"]
pub mod onnx_bytes;

use std::path::PathBuf;

pub fn project_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Folder with libonnxruntime.so*: $PUNCH_ONNXRUNTIME_DIR, else the addon's bin/ (filled by scons).
pub fn onnxruntime_dir() -> PathBuf {
    std::env::var_os("PUNCH_ONNXRUNTIME_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| project_root().join("addons/punch_controller/bin"))
}

#[allow(dead_code)] // not every test binary reads fixtures
pub fn fixture(name: &str) -> PathBuf {
    project_root().join("tests/fixtures").join(name)
}
