//! Property tests of the check on real policy files mutated at random (proptest, so a failure shrinks to the
//! smallest mutation and its seed is kept): the addon's shipped policies, the test fixture exported by
//! PyTorch, and a small hand-written graph whose bytes are nearly all structure. Whatever the bytes, the check
//! returns: a cost within the documented bounds, or a `ModelError` that says why, the same for the same
//! bytes, and never a panic.

#[path = "common/onnx_bytes.rs"]
mod onnx_bytes;

use std::path::PathBuf;
use std::sync::OnceLock;

use onnx_bytes::*;
use proptest::prelude::*;
use punch_model_check::{
    MAX_MODEL_BYTES, MAX_ROW_ELEMENTS, MAX_ROW_WORK, MAX_SHARED_ELEMENTS, MAX_SHARED_WORK, ModelError, check_model,
    measure_model,
};

fn project_file(path: &str) -> Vec<u8> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..").join(path);
    std::fs::read(&path).unwrap_or_else(|error| panic!("{}: {error}", path.display()))
}

/// obs [batch, 4] -> Gemm 4x3 -> Tanh -> Clip, as `punch_model_check`'s unit tests write it.
fn small_policy() -> Vec<u8> {
    let nodes = [
        node("Gemm", &["obs", "w", "b"], &["h"], &[attr_int("transB", 1)]),
        node("Tanh", &["h"], &["t"], &[]),
        node("Clip", &["t", "lo", "hi"], &["mean"], &[]),
    ];
    let constants = [
        tensor_fill("w", &[3, 4], 0.5),
        tensor_fill("b", &[3], 0.0),
        tensor_f32("lo", &[], &[-1.0]),
        tensor_f32("hi", &[], &[1.0]),
    ];
    model(&graph(&nodes, &constants, 4, &["mean"]), 17)
}

/// The files mutated: each passes the check as it is.
fn sources() -> &'static [Vec<u8>] {
    static SOURCES: OnceLock<Vec<Vec<u8>>> = OnceLock::new();
    SOURCES.get_or_init(|| {
        let files = vec![
            project_file("addons/punch_controller/policies/straight.onnx"),
            project_file("addons/punch_controller/policies/hook.onnx"),
            project_file("addons/punch_controller/policies/swing.onnx"),
            project_file("tests/fixtures/tiny_actor.onnx"),
            small_policy(),
        ];
        for (i, file) in files.iter().enumerate() {
            assert!(check_model(file).is_ok(), "source {i} passes unmutated");
        }
        files
    })
}

/// One change to a file's bytes; positions are fractions of the file's length, so they fit any file.
#[derive(Debug, Clone)]
enum Mutation {
    /// XOR a byte with a non-zero mask.
    Flip { at: f64, mask: u8 },
    /// Overwrite a byte with a value protobuf gives meaning to (varint continuation, a tag, a length).
    Set { at: f64, value: u8 },
    /// Insert bytes.
    Insert { at: f64, bytes: Vec<u8> },
    /// Remove up to `len` bytes.
    Remove { at: f64, len: usize },
    /// Copy a slice of the file to elsewhere in it (a field written twice, a message nested in itself).
    Duplicate { from: f64, len: usize, to: f64 },
    /// Cut the file short.
    Truncate { at: f64 },
}

fn index(at: f64, len: usize) -> usize {
    ((at * len as f64) as usize).min(len)
}

impl Mutation {
    fn apply(&self, bytes: &mut Vec<u8>) {
        let len = bytes.len();
        match self {
            Mutation::Flip { at, mask } if len > 0 => bytes[index(*at, len - 1)] ^= mask,
            Mutation::Set { at, value } if len > 0 => bytes[index(*at, len - 1)] = *value,
            Mutation::Insert { at, bytes: inserted } => {
                let at = index(*at, len);
                bytes.splice(at..at, inserted.iter().copied());
            }
            Mutation::Remove { at, len: count } => {
                let at = index(*at, len);
                bytes.drain(at..(at + count).min(len));
            }
            Mutation::Duplicate { from, len: count, to } => {
                let from = index(*from, len);
                let slice = bytes[from..(from + count).min(len)].to_vec();
                let to = index(*to, len);
                bytes.splice(to..to, slice);
            }
            Mutation::Truncate { at } => bytes.truncate(index(*at, len)),
            _ => {}
        }
    }
}

/// A position: anywhere, or within the first or last 512 bytes of a file, where the exporters put the graph's
/// nodes, names and opset (the middle of a shipped policy is mostly its weights' raw floats).
fn position() -> impl Strategy<Value = f64> {
    prop_oneof![0.0..1.0f64, 0.0..0.004f64, 0.996..1.0f64]
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let meaningful = prop_oneof![Just(0x80u8), Just(0xff), Just(0x00), Just(0x0a), Just(0x12), Just(0x3a), any::<u8>()];
    prop_oneof![
        (position(), 1..=255u8).prop_map(|(at, mask)| Mutation::Flip { at, mask }),
        (position(), meaningful).prop_map(|(at, value)| Mutation::Set { at, value }),
        (position(), prop::collection::vec(any::<u8>(), 1..12)).prop_map(|(at, bytes)| Mutation::Insert { at, bytes }),
        (position(), 1..64usize).prop_map(|(at, len)| Mutation::Remove { at, len }),
        (position(), 1..256usize, position()).prop_map(|(from, len, to)| Mutation::Duplicate { from, len, to }),
        position().prop_map(|at| Mutation::Truncate { at }),
    ]
}

/// What the check must answer for any bytes.
fn check_any(bytes: &[u8]) -> Result<(), TestCaseError> {
    let result = measure_model(bytes);
    prop_assert_eq!(&result, &measure_model(bytes), "the same bytes, the same answer");
    match result {
        Ok(cost) => {
            prop_assert!(cost.largest_row_elements <= MAX_ROW_ELEMENTS, "{cost:?}");
            prop_assert!(cost.largest_shared_elements <= MAX_SHARED_ELEMENTS, "{cost:?}");
            prop_assert!(cost.row_work <= MAX_ROW_WORK, "{cost:?}");
            prop_assert!(cost.shared_work <= MAX_SHARED_WORK, "{cost:?}");
        }
        Err(error) => {
            prop_assert!(!error.to_string().is_empty(), "{error:?} says why");
            if let ModelError::TooLarge { bytes: size } = error {
                prop_assert!(size > MAX_MODEL_BYTES);
            }
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn mutated_policy_files_pass_within_bounds_or_are_refused_with_a_reason(
        source in 0..5usize,
        mutations in prop::collection::vec(mutation(), 1..6),
    ) {
        let mut bytes = sources()[source].clone();
        for mutation in &mutations {
            mutation.apply(&mut bytes);
        }
        check_any(&bytes)?;
    }

    #[test]
    fn arbitrary_bytes_are_refused_with_a_reason(bytes in prop::collection::vec(any::<u8>(), 0..2048)) {
        check_any(&bytes)?;
    }
}

/// Every prefix of a real exported file gets an answer; every cut before its last fields (the metadata the
/// exporter writes after the graph) is refused, whether it falls inside a varint, a length or a tensor.
#[test]
fn every_prefix_of_a_real_file_is_refused_up_to_its_trailing_fields() {
    let whole = &sources()[3];
    for cut in 0..whole.len() {
        let result = check_model(&whole[..cut]);
        if cut + 64 < whole.len() {
            assert!(
                matches!(result, Err(ModelError::Format(_) | ModelError::Graph(_))),
                "first {cut} bytes: {result:?}"
            );
        }
    }
}
