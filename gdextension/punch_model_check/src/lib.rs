//! What a policy file may hold before ONNX Runtime sees it (the ONNX verifier `punch_core` runs on every
//! policy file before loading it; no dependency on ONNX Runtime or Godot). A file is data: whatever its bytes, the check
//! refuses it with one clear error, or ONNX Runtime loads it and runs a decision within a bounded time and
//! memory.
//!
//! - The file is read strictly (`proto`, `onnx`): a singular field that occurs twice (protobuf readers merge
//!   the copies, so a checker that reads one copy can be bypassed), an unknown field, or a refused construct
//!   (subgraphs, functions, sparse, external or string data, training info) is an error.
//! - The graph may use only the plain operators the exporter emits (`ALLOWED_OPERATORS`: no control flow
//!   such as Loop, If or Scan, no custom domains), of ONNX opset `MIN_OPSET` to `MAX_OPSET`.
//! - Every value's shape is inferred statically (`shapes`) from the one input [batch, n]; a shape the check
//!   cannot compute is refused. The batch dimension stays a whole dimension of its own (rows never mix), so
//!   a call of B rows does B times a row's work plus the batch-independent work.
//! - Allowed operators alone can still make unbounded work (a Concat of copies grows a 1x1 value to
//!   16384x16384 and a MatMul multiplies it), so the largest value and the total work are bounded:
//!   `MAX_ROW_ELEMENTS` and `MAX_ROW_WORK` per row, `MAX_SHARED_ELEMENTS` and `MAX_SHARED_WORK` for what does
//!   not depend on the batch (initializers, constants, and what ONNX Runtime folds from them at load).
//!
//! The bounds leave a wide margin above the shipped policies (45 -> 128 -> 128 -> 2 x 10: largest value 128
//! elements per row and 16 384 shared; work 40 317 units per row, 52 times under the bound, of which 24 704
//! multiply-adds; 25 074 shared, the initializers). Measured with ONNX Runtime 1.31 on one thread of an AMD
//! EPYC (punch_core's `tests/model_check.rs`, `measure_the_worst_files_that_pass`), the worst files that pass
//! decide one row in at most about 0.1 ms and 64 rows in at most about 6 ms (median; 2.5 ms for a
//! 45-1024-1024-864-10 MLP, 6 ms for Softplus at the bound, the shipped policies 0.05 ms), plus up to 0.5 ms per call for a
//! graph of `MAX_NODES` nodes, whose session takes about 60 ms to create. Memory per row is at most
//! `MAX_ROW_WORK` / 16 elements written (512 KiB of float32), and what does not depend on the batch at most
//! 16 MiB per value. No time limit per call is needed on top: the static bound holds for every file that
//! loads.

mod onnx;
mod proto;
mod shapes;

pub use shapes::ModelCost;

/// Why a policy file is refused; its message says what is refused and why.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ModelError {
    /// The file is larger than `MAX_MODEL_BYTES`.
    #[error("the file has {bytes} bytes, more than the {MAX_MODEL_BYTES} a policy may have")]
    TooLarge {
        /// The file's size.
        bytes: usize,
    },
    /// The bytes are not an ONNX model read strictly (truncated, a field written twice or unknown, a wrong
    /// encoding), or hold a construct a policy may not (subgraphs, functions, sparse, external or string data,
    /// training info, more than `MAX_NODES` nodes).
    #[error("{0}")]
    Format(String),
    /// The model's ONNX opset is outside `MIN_OPSET..=MAX_OPSET`.
    #[error("the model uses ONNX opset {opset}; a policy uses opset {MIN_OPSET} to {MAX_OPSET} (export again)")]
    Opset {
        /// The opset the model imports.
        opset: i64,
    },
    /// The graph uses an operator a policy may not, has a shape the check cannot infer or that mixes rows,
    /// or goes over a bound on its values' size or its work.
    #[error("{0}")]
    Graph(String),
}

/// Largest policy file accepted, bytes (the shipped policies are about 120 kB).
pub const MAX_MODEL_BYTES: usize = 16 * 1024 * 1024;
/// Most graph nodes accepted (the shipped policies have 12).
pub const MAX_NODES: usize = 2000;
/// Oldest ONNX opset accepted (13 moved Squeeze's, Unsqueeze's and Split's arguments to inputs).
pub const MIN_OPSET: i64 = 13;
/// Newest ONNX opset accepted: the check knows its operators' semantics up to this one.
pub const MAX_OPSET: i64 = 24;
/// Most elements of one value with the batch dimension, per row (shipped policies: 128).
pub const MAX_ROW_ELEMENTS: u64 = 1 << 16;
/// Most work per row, in units of one multiply-add: the multiply-adds of Gemm and MatMul plus every element
/// any node writes, weighted by its operator's cost (`shapes::weight`: 16 to 512). Shipped policies: 40 317.
/// A file at this bound decides a row in about 0.1 ms (see the module docs).
pub const MAX_ROW_WORK: u64 = 1 << 21;
/// Most elements of one batch-independent value (16 MiB of float32; shipped policies: 16 384).
pub const MAX_SHARED_ELEMENTS: u64 = 1 << 22;
/// Most batch-independent work, same units (done once per call, or once at load where ONNX Runtime folds
/// constants: a 4096 x 4096 constant squared took 4.1 s to fold; this bound refuses it). Shipped policies:
/// 25 074, their initializers.
pub const MAX_SHARED_WORK: u64 = 1 << 24;

/// Operators a policy graph may use: what the exporter emits for a feed-forward actor, and the plain
/// tensor operators an equivalent export could use instead.
pub const ALLOWED_OPERATORS: &[&str] = &[
    "Abs",
    "Add",
    "Cast",
    "Clip",
    "Concat",
    "Constant",
    "Div",
    "Elu",
    "Exp",
    "Flatten",
    "Gather",
    "Gemm",
    "Identity",
    "LeakyRelu",
    "Log",
    "MatMul",
    "Max",
    "Min",
    "Mul",
    "Neg",
    "Pow",
    "Relu",
    "Reshape",
    "Selu",
    "Shape",
    "Sigmoid",
    "Slice",
    "Softplus",
    "Softsign",
    "Split",
    "Sqrt",
    "Squeeze",
    "Sub",
    "Tanh",
    "Transpose",
    "Unsqueeze",
];

/// Checks a policy file's bytes; the error says what is refused and why.
pub fn check_model(bytes: &[u8]) -> Result<(), ModelError> {
    measure_model(bytes).map(|_| ())
}

/// Checks a policy file's bytes (`check_model`) and returns what it costs.
pub fn measure_model(bytes: &[u8]) -> Result<ModelCost, ModelError> {
    if bytes.len() > MAX_MODEL_BYTES {
        return Err(ModelError::TooLarge { bytes: bytes.len() });
    }
    let model = onnx::read_model(bytes, MAX_NODES).map_err(ModelError::Format)?;
    if !(MIN_OPSET..=MAX_OPSET).contains(&model.opset) {
        return Err(ModelError::Opset { opset: model.opset });
    }
    let bounds = shapes::Bounds {
        row_elements: MAX_ROW_ELEMENTS,
        shared_elements: MAX_SHARED_ELEMENTS,
        row_work: MAX_ROW_WORK,
        shared_work: MAX_SHARED_WORK,
    };
    shapes::infer(&model.graph, model.opset, ALLOWED_OPERATORS, &bounds).map_err(ModelError::Graph)
}

/// The tests' ONNX writer, shared with the integration tests.
#[cfg(test)]
#[path = "../tests/common/onnx_bytes.rs"]
mod onnx_bytes;

#[cfg(test)]
mod tests {
    use super::*;

    use super::onnx_bytes::*;

    /// obs [batch, 4] -> Gemm 4x3 -> Tanh -> Clip: a policy's shape.
    fn policy_graph() -> Vec<u8> {
        graph(
            &[
                node("Gemm", &["obs", "w", "b"], &["h"], &[attr_int("transB", 1)]),
                node("Tanh", &["h"], &["t"], &[]),
                node("Clip", &["t", "lo", "hi"], &["mean"], &[]),
            ],
            &[
                tensor_fill("w", &[3, 4], 0.5),
                tensor_fill("b", &[3], 0.0),
                tensor_f32("lo", &[], &[-1.0]),
                tensor_f32("hi", &[], &[1.0]),
            ],
            4,
            &["mean"],
        )
    }

    /// A graph whose `mean` comes from a Loop of 2^40 iterations.
    fn loop_graph() -> Vec<u8> {
        let body = graph(&[node("Identity", &["obs"], &["mean"], &[])], &[], 4, &["mean"]);
        let subgraph = [text(1, "body"), field(6, &body), int(20, 5)].concat();
        graph(
            &[node("Loop", &["trips", "", "obs"], &["mean"], &[subgraph])],
            &[tensor_i64("trips", &[], &[1 << 40])],
            4,
            &["mean"],
        )
    }

    fn refused(bytes: &[u8], expected: &str) {
        let error = check_model(bytes).expect_err(expected).to_string();
        assert!(error.contains(expected), "expected '{expected}' in: {error}");
    }

    #[test]
    fn a_plain_policy_passes_and_its_work_is_counted() {
        let cost = measure_model(&model(&policy_graph(), 17)).expect("passes");
        // Per row: the input 4, Gemm 3x4 multiply-adds + 3 written, Tanh 3 (32 units each), Clip 3 (16 each).
        assert_eq!((cost.largest_row_elements, cost.row_work), (4, 4 + 12 + 3 * 16 + 3 * 32 + 3 * 16));
        // Batch-independent: the initializers, written once.
        assert_eq!((cost.largest_shared_elements, cost.shared_work), (12, 12 + 3 + 1 + 1));
    }

    #[test]
    fn control_flow_custom_domains_and_functions_are_refused() {
        refused(&model(&loop_graph(), 17), "operator 'Loop': the model holds a subgraph");
        let scan = graph(&[node("Scan", &["obs"], &["mean"], &[])], &[], 4, &["mean"]);
        refused(&model(&scan, 17), "'Scan'");
        let custom =
            [policy_graph(), field(1, &[text(1, "obs"), text(2, "x"), text(4, "Tanh"), text(7, "com.evil")].concat())]
                .concat();
        refused(&model(&custom, 17), "domain 'com.evil'");
        refused(&[model(&policy_graph(), 17), field(25, b"")].concat(), "functions");
    }

    #[test]
    fn a_field_written_twice_is_refused_whichever_copy_comes_first() {
        let (good, evil) = (field(7, &policy_graph()), field(7, &loop_graph()));
        let opset = field(8, &[text(1, ""), int(2, 17)].concat());
        for graphs in [[&evil, &good], [&good, &evil], [&good, &good]] {
            refused(
                &[opset.clone(), graphs[0].clone(), graphs[1].clone()].concat(),
                "ModelProto.graph field more than once",
            );
        }
        // Inside a node, a tensor and an opset import too.
        let doubled_op = graph(
            &[field(1, &[text(1, "obs"), text(2, "mean"), text(4, "Tanh"), text(4, "Loop")].concat())],
            &[],
            4,
            &["mean"],
        );
        refused(&model(&doubled_op, 17), "NodeProto.op_type field more than once");
        let doubled_type = [tensor_fill("w", &[3, 4], 0.5), int(2, 7)].concat();
        let graph_with =
            |w: &[u8]| graph(&[node("MatMul", &["obs", "w"], &["mean"], &[])], &[w.to_vec()], 4, &["mean"]);
        refused(&model(&graph_with(&doubled_type), 17), "TensorProto.data_type field more than once");
        refused(
            &[field(8, &[text(1, ""), int(2, 17), int(2, 1)].concat()), field(7, &policy_graph())].concat(),
            "version field more than once",
        );
    }

    #[test]
    fn unknown_fields_wrong_encodings_and_external_data_are_refused() {
        refused(&[model(&policy_graph(), 17), int(99, 1)].concat(), "field 99");
        refused(&[model(&policy_graph(), 17), int(7, 1)].concat(), "wrong encoding");
        let external = [tensor_fill("w", &[3, 4], 0.5), int(14, 1)].concat();
        let graph_with = graph(&[node("MatMul", &["obs", "w"], &["mean"], &[])], &[external], 4, &["mean"]);
        refused(&model(&graph_with, 17), "outside the file");
        let short = [int(1, 3), int(1, 4), int(2, 1), text(8, "w"), field(9, &[0; 8])].concat();
        let graph_with = graph(&[node("MatMul", &["obs", "w"], &["mean"], &[])], &[short], 4, &["mean"]);
        refused(&model(&graph_with, 17), "8 bytes for 12 elements");
        refused(&model(&policy_graph(), 11), "opset 11");
    }

    /// obs [batch, 4] sliced to [batch, 1], grown by Concat to [batch, 256] then [batch, 256 * `copies`].
    fn concat_growth(copies: usize) -> Vec<u8> {
        let nodes = [
            node("Slice", &["obs", "zero", "one", "one"], &["v0"], &[]),
            node("Concat", &vec!["v0"; 256], &["v1"], &[attr_int("axis", 1)]),
            node("Concat", &vec!["v1"; copies], &["mean"], &[attr_int("axis", 1)]),
        ];
        let ints = [tensor_i64("zero", &[1], &[0]), tensor_i64("one", &[1], &[1])];
        model(&graph(&nodes, &ints, 4, &["mean"]), 17)
    }

    #[test]
    fn a_value_grown_by_concat_passes_up_to_the_bound_and_not_beyond() {
        let at_bound = measure_model(&concat_growth(256)).expect("2^16 elements per row pass");
        assert_eq!(at_bound.largest_row_elements, MAX_ROW_ELEMENTS);
        refused(&concat_growth(257), "elements per row, more than the 65536");
    }

    #[test]
    fn unbounded_work_from_allowed_operators_is_refused() {
        // A 1x1 constant grown to 2^11 x 2^11 by Concat (at the bound) and multiplied by itself: 2^33 multiply-adds.
        let mut nodes = Vec::new();
        for i in 0..22 {
            let (from, to) = (format!("c{i}"), format!("c{}", i + 1));
            nodes.push(node("Concat", &[&from, &from], &[&to], &[attr_int("axis", (i % 2) as i64)]));
        }
        nodes.push(node("MatMul", &["c22", "c22"], &["square"], &[]));
        nodes.push(node("Gemm", &["obs", "w"], &["mean"], &[]));
        let seed = [tensor_fill("c0", &[1, 1], 1.0), tensor_fill("w", &[4, 3], 0.5)];
        refused(&model(&graph(&nodes, &seed, 4, &["mean"]), 17), "batch-independent work");
        // Per row: [batch, 256] x [256, 256] sixty times is over the work bound.
        let mut nodes = vec![node("MatMul", &["obs", "wide"], &["h0"], &[])];
        for i in 0..60 {
            nodes.push(node("MatMul", &[&format!("h{i}"), "square"], &[&format!("h{}", i + 1)], &[]));
        }
        nodes.push(node("Identity", &["h60"], &["mean"], &[]));
        let weights = [tensor_fill("wide", &[4, 256], 0.01), tensor_fill("square", &[256, 256], 0.01)];
        refused(&model(&graph(&nodes, &weights, 4, &["mean"]), 17), "work per row");
    }

    #[test]
    fn shapes_the_check_cannot_infer_or_that_mix_rows_are_refused() {
        let runtime_shape = graph(
            &[
                node("Shape", &["obs"], &["s"], &[]),
                node("Mul", &["s", "s"], &["s2"], &[]),
                node("Reshape", &["obs", "s2"], &["mean"], &[]),
            ],
            &[],
            4,
            &["mean"],
        );
        refused(&model(&runtime_shape, 17), "constant the check can read");
        let outer = graph(
            &[
                node("Transpose", &["obs"], &["t"], &[]),
                node("MatMul", &["t", "obs"], &["x"], &[]),
                node("MatMul", &["obs", "t"], &["mean"], &[]),
            ],
            &[],
            4,
            &["mean"],
        );
        refused(&model(&outer, 17), "combine rows");
        // Reshape to [batch, -1] through Shape and Gather passes: the batch size is followed as a symbol.
        let flatten = graph(
            &[
                node("Shape", &["obs"], &["s"], &[]),
                node("Gather", &["s", "zero"], &["rows"], &[]),
                node("Concat", &["rows", "minus_one"], &["target"], &[attr_int("axis", 0)]),
                node("Reshape", &["obs", "target"], &["mean"], &[]),
            ],
            &[tensor_i64("zero", &[1], &[0]), tensor_i64("minus_one", &[1], &[-1])],
            4,
            &["mean"],
        );
        assert_eq!(measure_model(&model(&flatten, 17)).map(|c| c.largest_row_elements), Ok(4));
    }

    #[test]
    fn garbage_truncation_and_size_are_refused_without_panicking() {
        assert!(check_model(b"").is_err());
        assert!(check_model(&[0x3a, 0x7f, 0x01]).is_err(), "a field longer than the file");
        assert!(check_model(&[0xff; 12]).is_err(), "an endless varint");
        assert!(check_model(&vec![0u8; MAX_MODEL_BYTES + 1]).expect_err("size").to_string().contains("more than"));
        let whole = model(&policy_graph(), 17);
        for cut in 0..whole.len() {
            let _ = check_model(&whole[..cut]); // no panic at any length
        }
        assert!(check_model(&whole[..whole.len() - 2]).is_err());
    }
}
