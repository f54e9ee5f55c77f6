//! The model check against real files and the real ONNX Runtime: the shipped policies pass with their
//! measured cost; a file with its graph written twice, or one whose allowed operators would do unbounded
//! work, is refused before ONNX Runtime sees it; a file at the bounds loads and runs.

mod common;

use common::onnx_bytes::*;
use punch_core::model_check::{MAX_ROW_ELEMENTS, ModelCost, check_model, measure_model};
use punch_core::{CoreError, Policy, runtime};

fn init() {
    if let Err(error) = runtime::init_from_dir(&common::onnxruntime_dir()) {
        panic!("{error}: run ./dev setup (or scons) first, or set PUNCH_ONNXRUNTIME_DIR");
    }
}

fn shipped(style: &str) -> Vec<u8> {
    std::fs::read(common::project_root().join(format!("addons/punch_controller/policies/{style}.onnx")))
        .expect("readable")
}

/// A graph whose outputs `mean` and `sigma` come from a Loop of 2^40 iterations (the bypass).
fn loop_graph() -> Vec<u8> {
    let body = graph(&[node("Identity", &["obs"], &["mean"], &[])], &[], 45, &["mean"]);
    let subgraph = [text(1, "body"), field(6, &body), int(20, 5)].concat();
    graph(
        &[node("Loop", &["trips", "", "obs"], &["mean"], &[subgraph]), node("Identity", &["mean"], &["sigma"], &[])],
        &[tensor_i64("trips", &[], &[1 << 40])],
        45,
        &["mean", "sigma"],
    )
}

fn refused(bytes: &[u8], expected: &str) {
    init();
    match Policy::from_bytes(bytes) {
        Err(CoreError::InvalidModel(reason)) => assert!(reason.contains(expected), "expected '{expected}': {reason}"),
        Err(other) => panic!("refused for another reason: {other}"),
        Ok(_) => panic!("loaded a file that should be refused ({expected})"),
    }
}

#[test]
fn the_shipped_policies_pass_with_their_measured_cost() {
    for style in ["straight", "hook", "swing"] {
        let cost = measure_model(&shipped(style)).expect(style);
        // 45 -> 128 -> 128 -> 10 (mean) and 10 (sigma): 24 704 multiply-adds and 742 elements written per row;
        // the initializers (25 074 elements) are the batch-independent work.
        let expected = ModelCost {
            largest_row_elements: 128,
            largest_shared_elements: 128 * 128,
            row_work: 45 + 3 * 45 + 45 * 128 + 128 * 128 + 2 * 128 * 10 + 4 * 128 + 5 * 10,
            shared_work: 45 * 128 + 128 + 128 * 128 + 128 + 2 * (10 * 128 + 10) + 2 * 45 + 4,
        };
        assert_eq!(cost, expected, "{style}");
    }
    check_model(&std::fs::read(common::fixture("tiny_actor.onnx")).expect("fixture")).expect("tiny_actor passes");
}

#[test]
fn a_graph_written_twice_is_refused_whichever_copy_comes_first() {
    let policy = shipped("straight");
    let evil = field(7, &loop_graph());
    // Protobuf merges the copies wherever they are; the file's own graph field is near its end.
    refused(&[evil.clone(), policy.clone()].concat(), "ModelProto.graph field more than once");
    refused(&[policy.clone(), evil].concat(), "ModelProto.graph field more than once");
    refused(&[policy.clone(), field(7, &[])].concat(), "ModelProto.graph field more than once");
}

/// obs [batch, 45] sliced to [batch, 1], doubled `doublings` times by Concat, then a Gemm to mean [batch, 10].
fn concat_growth(doublings: usize) -> Vec<u8> {
    let mut nodes = vec![node("Slice", &["obs", "zero", "one", "one"], &["v0"], &[])];
    for i in 0..doublings {
        let (from, to) = (format!("v{i}"), format!("v{}", i + 1));
        nodes.push(node("Concat", &[&from, &from], &[&to], &[attr_int("axis", 1)]));
    }
    nodes.push(node("Gemm", &[&format!("v{doublings}"), "w"], &["mean"], &[]));
    let inputs =
        [tensor_i64("zero", &[1], &[0]), tensor_i64("one", &[1], &[1]), tensor_fill("w", &[1 << doublings, 10], 0.0)];
    model(&graph(&nodes, &inputs, 45, &["mean"]), 17)
}

#[test]
fn a_value_grown_by_concat_runs_at_the_bound_and_is_refused_beyond_it() {
    init();
    let mut policy = Policy::from_bytes(&concat_growth(16)).expect("at the bound");
    let outputs = policy.run(&[0.5; 2 * 45], 2).expect("runs");
    assert_eq!((outputs[0].batch, outputs[0].width), (2, 10));
    assert_eq!(measure_model(&concat_growth(16)).map(|c| c.largest_row_elements), Ok(MAX_ROW_ELEMENTS));
    refused(&concat_growth(17), "elements per row, more than the 65536");
}

#[test]
fn a_constant_grown_by_concat_and_multiplied_is_refused_before_it_is_folded() {
    // 1x1 grown to 4096x4096 (the size whose folding took 4.1 s at load) and squared by MatMul.
    let mut nodes = Vec::new();
    for i in 0..24 {
        let (from, to) = (format!("c{i}"), format!("c{}", i + 1));
        nodes.push(node("Concat", &[&from, &from], &[&to], &[attr_int("axis", (i % 2) as i64)]));
    }
    nodes.push(node("MatMul", &["c24", "c24"], &["square"], &[]));
    nodes.push(node("Gemm", &["obs", "w"], &["mean"], &[]));
    let seed = [tensor_fill("c0", &[1, 1], 1.0), tensor_fill("w", &[45, 10], 0.5)];
    refused(&model(&graph(&nodes, &seed, 45, &["mean"]), 17), "more than the 4194304 a batch-independent value");
}
