//! Loading ONNX Runtime from bad places fails with a clear error, never a panic. A separate test binary:
//! the runtime is process-wide, and these must run before anything loads it.

mod common;

use std::path::Path;

use punch_core::inference::runtime;
use punch_core::{CoreError, Policy};

#[test]
fn bad_runtime_locations_give_clear_errors() {
    let scratch = std::env::temp_dir().join(format!("punch_core_runtime_errors_{}", std::process::id()));
    std::fs::create_dir_all(&scratch).expect("scratch dir");

    // Nothing loaded yet: using a policy says so.
    assert!(matches!(Policy::from_bytes(b"x"), Err(CoreError::RuntimeNotInitialised)));

    // A folder without the library.
    assert!(matches!(runtime::init_from_dir(&scratch), Err(CoreError::RuntimeLibraryMissing { .. })));
    // A missing folder.
    assert!(matches!(
        runtime::init_from_dir(Path::new("/nonexistent/punch")),
        Err(CoreError::RuntimeLibraryMissing { .. })
    ));
    // A file with the right name that is not a shared library.
    let fake_name =
        if cfg!(windows) { runtime::LIBRARY_PREFIX.to_string() } else { format!("{}.1.99.0", runtime::LIBRARY_PREFIX) };
    std::fs::write(scratch.join(&fake_name), b"not a library").expect("write fake");
    let error = runtime::init_from_dir(&scratch).expect_err("a text file is not ONNX Runtime");
    assert!(matches!(error, CoreError::RuntimeLoad { .. }), "{error}");
    assert!(error.to_string().contains(&fake_name), "{error}");
    // A real shared library that is not ONNX Runtime.
    let error = runtime::init(&other_system_library()).expect_err("a system library is not ONNX Runtime");
    assert!(error.to_string().contains("OrtGetApiBase"), "{error}");
    assert!(runtime::version().is_none());

    // The real one still loads afterwards.
    runtime::init_from_dir(&common::onnxruntime_dir()).expect("real runtime loads");
    assert!(runtime::version().is_some());
    std::fs::remove_dir_all(&scratch).ok();
}

/// A shared library every machine of the platform has.
fn other_system_library() -> std::path::PathBuf {
    match std::env::var_os("SystemRoot") {
        Some(windows) if cfg!(windows) => Path::new(&windows).join("System32").join("kernel32.dll"),
        _ => Path::new("/lib/x86_64-linux-gnu/libm.so.6").to_path_buf(),
    }
}

#[cfg(not(windows))] // Windows ships the one unversioned onnxruntime.dll
#[test]
fn find_library_prefers_the_highest_version() {
    let scratch = std::env::temp_dir().join(format!("punch_core_find_{}", std::process::id()));
    std::fs::create_dir_all(&scratch).expect("scratch dir");
    for name in ["libonnxruntime.so.1.9.0", "libonnxruntime.so.1.31.1", "libonnxruntime.so.1.4.2", "libother.so"] {
        std::fs::write(scratch.join(name), b"").expect("write");
    }
    let found = runtime::find_library_in(&scratch).expect("found");
    assert_eq!(found.file_name().and_then(|n| n.to_str()), Some("libonnxruntime.so.1.31.1"));
    std::fs::remove_dir_all(&scratch).ok();
}
