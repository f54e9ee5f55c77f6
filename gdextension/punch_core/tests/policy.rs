//! Policy inference through ONNX Runtime on the shared fixture (tests/fixtures/tiny_actor.onnx), whose
//! expected outputs were computed by onnxruntime in Python.

mod common;

use punch_core::inference::runtime;
use punch_core::{CoreError, Policy};
use serde_json::Value;

fn init_runtime() {
    let dir = common::onnxruntime_dir();
    if let Err(error) = runtime::init_from_dir(&dir) {
        panic!("{error}: run ./dev setup (or scons) first, or set PUNCH_ONNXRUNTIME_DIR");
    }
}

fn fixture_policy() -> (Policy, Value) {
    init_runtime();
    let bytes = std::fs::read(common::fixture("tiny_actor.onnx")).expect("fixture model is readable");
    let expected: Value = serde_json::from_str(
        &std::fs::read_to_string(common::fixture("tiny_actor_expected.json")).expect("fixture json is readable"),
    )
    .expect("fixture json parses");
    (Policy::from_bytes(&bytes).expect("fixture model loads"), expected)
}

fn floats(value: &Value) -> Vec<f32> {
    value.as_array().expect("array").iter().map(|v| v.as_f64().expect("number") as f32).collect()
}

#[test]
fn runtime_reports_the_loaded_version() {
    init_runtime();
    let version = runtime::version().expect("loaded");
    assert!(version.starts_with("1."), "unexpected ONNX Runtime version {version}");
    assert!(runtime::library_path().expect("loaded").is_absolute());
}

#[test]
fn fixture_outputs_match_python_onnxruntime() {
    let (mut policy, expected) = fixture_policy();
    let batch = expected["batch"].as_u64().expect("batch") as usize;
    assert_eq!(policy.input_width(), expected["input_width"].as_u64().expect("width") as usize);
    assert_eq!(policy.input_name(), "obs");
    assert_eq!(policy.output_names(), ["mean", "sigma"]);

    let outputs = policy.run(&floats(&expected["input"]), batch).expect("run succeeds");
    for tensor in outputs {
        let want = floats(&expected["outputs"][&tensor.name]);
        assert_eq!(tensor.batch, batch);
        assert_eq!(tensor.data.len(), want.len(), "output {}", tensor.name);
        let worst = tensor.data.iter().zip(&want).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
        assert!(worst <= 1e-5, "output {} differs from Python by {worst}", tensor.name);
    }
}

#[test]
fn batched_rows_equal_single_rows() {
    let (mut policy, expected) = fixture_policy();
    let input = floats(&expected["input"]);
    let width = policy.input_width();
    let batched = policy.run(&input, 3).expect("batched run");
    for row in 0..3 {
        let single = policy.run(&input[row * width..(row + 1) * width], 1).expect("single run");
        for (b, s) in batched.iter().zip(&single) {
            assert_eq!(&b.data[row * b.width..(row + 1) * b.width], s.data.as_slice());
        }
    }
}

#[test]
fn metadata_is_readable() {
    let (policy, expected) = fixture_policy();
    assert_eq!(policy.metadata("purpose").as_deref(), expected["metadata"]["purpose"].as_str());
    assert_eq!(policy.metadata("no such key"), None);
}

#[test]
fn wrong_input_size_is_refused() {
    let (mut policy, _) = fixture_policy();
    let width = policy.input_width();
    assert!(matches!(policy.run(&vec![0.0; width + 1], 1), Err(CoreError::BadInput(_))));
    assert!(matches!(policy.run(&[], 0), Err(CoreError::BadInput(_))));
}

#[test]
fn non_finite_input_is_refused() {
    let (mut policy, _) = fixture_policy();
    let mut input = vec![0.0; policy.input_width()];
    input[2] = f32::NAN;
    assert!(matches!(policy.run(&input, 1), Err(CoreError::BadInput(_))));
    input[2] = f32::INFINITY;
    assert!(matches!(policy.run(&input, 1), Err(CoreError::BadInput(_))));
}

#[test]
fn garbage_bytes_are_an_invalid_model() {
    init_runtime();
    assert!(matches!(Policy::from_bytes(b""), Err(CoreError::InvalidModel(_))));
    assert!(matches!(Policy::from_bytes(b"this is not an onnx file"), Err(CoreError::RefusedModel(_))));
    let bytes = std::fs::read(common::fixture("tiny_actor.onnx")).expect("fixture");
    assert!(matches!(Policy::from_bytes(&bytes[..bytes.len() / 2]), Err(CoreError::RefusedModel(_))));
}
