//! The model check against real files and the real ONNX Runtime: the shipped policies pass with their
//! measured cost; a file with its graph written twice, or one whose allowed operators would do unbounded
//! work, is refused before ONNX Runtime sees it; a file at the bounds loads and runs.

mod common;

use common::onnx_bytes::*;
use punch_core::contract::spec::OBS_DIM;
use punch_core::inference::runtime;
use punch_core::{CoreError, Policy};
use punch_model_check::{MAX_ROW_ELEMENTS, ModelCost, check_model, measure_model};

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
        Err(CoreError::RefusedModel(reason)) => {
            assert!(reason.to_string().contains(expected), "expected '{expected}': {reason}")
        }
        Err(other) => panic!("refused for another reason: {other}"),
        Ok(_) => panic!("loaded a file that should be refused ({expected})"),
    }
}

#[test]
fn the_shipped_policies_pass_with_their_measured_cost() {
    for style in ["straight", "hook", "swing"] {
        let cost = measure_model(&shipped(style)).expect(style);
        // OBS_DIM (54) -> 128 -> 128 -> 10 (mean) and 10 (sigma): 25 856 multiply-adds, the input, 448 elements
        // written by plain operators (16 units each) and 276 by Tanh and Exp (32 each) per row;
        // the initializers (26 244 elements) are the batch-independent work.
        let obs = OBS_DIM as u64;
        let expected = ModelCost {
            largest_row_elements: 128,
            largest_shared_elements: 128 * 128,
            row_work: obs + obs * 128 + 128 * 128 + 2 * 128 * 10 + 16 * (3 * obs + 276 + 10) + 32 * (266 + 10),
            shared_work: obs * 128 + 128 + 128 * 128 + 128 + 2 * (10 * 128 + 10) + 2 * obs + 4,
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

/// obs [batch, 45] sliced to [batch, 1], grown by Concat to [batch, 256] then to [batch, 256 * `copies`],
/// then a Gemm to mean [batch, 10].
fn concat_growth(copies: usize) -> Vec<u8> {
    let nodes = vec![
        node("Slice", &["obs", "zero", "one", "one"], &["v0"], &[]),
        node("Concat", &vec!["v0"; 256], &["v1"], &[attr_int("axis", 1)]),
        node("Concat", &vec!["v1"; copies], &["v2"], &[attr_int("axis", 1)]),
        node("Gemm", &["v2", "w"], &["mean"], &[]),
    ];
    let inputs = [
        tensor_i64("zero", &[1], &[0]),
        tensor_i64("one", &[1], &[1]),
        tensor_fill("w", &[256 * copies as i64, 10], 0.0),
    ];
    model(&graph(&nodes, &inputs, 45, &["mean"]), 17)
}

#[test]
fn a_value_grown_by_concat_runs_at_the_bound_and_is_refused_beyond_it() {
    init();
    let mut policy = Policy::from_bytes(&concat_growth(256)).expect("at the bound");
    let outputs = policy.run(&[0.5; 2 * 45], 2).expect("runs");
    assert_eq!((outputs[0].batch, outputs[0].width), (2, 10));
    assert_eq!(measure_model(&concat_growth(256)).map(|c| c.largest_row_elements), Ok(MAX_ROW_ELEMENTS));
    refused(&concat_growth(257), "elements per row, more than the 65536");
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
    refused(&model(&graph(&nodes, &seed, 45, &["mean"]), 17), "batch-independent");
}

/// A policy of `layers` (each a Gemm of the given width then `activation`, the last one to 10), on obs
/// [batch, 45].
fn mlp(widths: &[i64], activation: &str) -> Vec<u8> {
    let (mut nodes, mut weights, mut from, mut width) = (Vec::new(), Vec::new(), "obs".to_string(), 45);
    for (i, &next) in widths.iter().chain([10].iter()).enumerate() {
        let (w, h, a) = (format!("w{i}"), format!("h{i}"), format!("a{i}"));
        weights.push(tensor_fill(&w, &[width, next], 0.001));
        nodes.push(node("Gemm", &[&from, &w], &[&h], &[]));
        nodes.push(node(activation, &[&h], &[&a], &[]));
        (from, width) = (a, next);
    }
    nodes.push(node("Identity", &[&from], &["mean"], &[]));
    model(&graph(&nodes, &weights, 45, &["mean"]), 17)
}

/// obs -> Gemm to [batch, `width`], then `op` applied `count` times (Pow with exponent 1.5).
fn chain(op: &str, width: i64, count: usize) -> Vec<u8> {
    let mut nodes = vec![node("Gemm", &["obs", "w"], &["v0"], &[]), node("Abs", &["v0"], &["x0"], &[])];
    for i in 0..count {
        let (from, to) = (format!("x{i}"), format!("x{}", i + 1));
        let inputs: Vec<&str> = if op == "Pow" { vec![&from, "p"] } else { vec![&from] };
        nodes.push(node(op, &inputs, &[&to], &[]));
    }
    nodes.push(node("Slice", &[&format!("x{count}"), "zero", "ten", "one"], &["mean"], &[]));
    let constants = [
        tensor_fill("w", &[45, width], 0.01),
        tensor_f32("p", &[], &[1.5]),
        tensor_i64("zero", &[1], &[0]),
        tensor_i64("ten", &[1], &[10]),
        tensor_i64("one", &[1], &[1]),
    ];
    model(&graph(&nodes, &constants, 45, &["mean"]), 17)
}

/// The decision time of files at the bounds (run with `--ignored --nocapture`; figures for the docs, not a
/// check: tests never check timing).
#[test]
#[ignore]
fn measure_the_worst_files_that_pass() {
    init();
    let files: Vec<(&str, Vec<u8>)> = vec![
        ("shipped straight", shipped("straight")),
        ("MLP 45-1024-1024-864-10 (Gemm, Relu)", mlp(&[1024, 1024, 864], "Relu")),
        ("Pow x 7 on [batch, 1024]", chain("Pow", 1024, 7)),
        ("Softplus x 3 on [batch, 1024]", chain("Softplus", 1024, 3)),
        ("Log x 15 on [batch, 1024]", chain("Log", 1024, 15)),
        ("Tanh x 60 on [batch, 1024]", chain("Tanh", 1024, 60)),
        ("Neg x 110 on [batch, 1024]", chain("Neg", 1024, 110)),
        ("Sqrt x 1990 on [batch, 16]", chain("Sqrt", 16, 1990)),
    ];
    for (name, bytes) in files {
        let cost = match measure_model(&bytes) {
            Ok(cost) => cost,
            Err(error) => {
                println!("{name}: refused: {error}");
                continue;
            }
        };
        let started = std::time::Instant::now();
        let mut policy = Policy::from_bytes(&bytes).expect("loads");
        let load_ms = started.elapsed().as_secs_f64() * 1e3;
        for rows in [1usize, 64] {
            let input = vec![0.3f32; rows * 45];
            policy.run(&input, rows).expect("runs");
            let mut times: Vec<f64> = (0..15)
                .map(|_| {
                    let started = std::time::Instant::now();
                    policy.run(&input, rows).expect("runs");
                    started.elapsed().as_secs_f64() * 1e3
                })
                .collect();
            times.sort_by(f64::total_cmp);
            println!(
                "{name}: row work {} shared {}; load {load_ms:.1} ms; {rows} rows: median {:.3} ms, max {:.3} ms",
                cost.row_work, cost.shared_work, times[7], times[14]
            );
        }
    }
}

/// Nanoseconds per element of each elementwise operator, 64 rows (run with `--ignored --nocapture`; the
/// figures behind `model_check`'s operator weights).
#[test]
#[ignore]
fn measure_the_elementwise_operators() {
    init();
    for op in [
        "Abs",
        "Neg",
        "Relu",
        "Identity",
        "Sqrt",
        "Exp",
        "Log",
        "Tanh",
        "Sigmoid",
        "Elu",
        "Selu",
        "LeakyRelu",
        "Softplus",
        "Softsign",
        "Pow",
    ] {
        // As many nodes as pass the bounds (the Gemm before them is 45 x 1024 multiply-adds a row).
        let count = (1..=200).rev().find(|&n| check_model(&chain(op, 1024, n)).is_ok()).expect("one passes");
        let mut policy = Policy::from_bytes(&chain(op, 1024, count)).expect("loads");
        let input = vec![0.3f32; 64 * 45];
        policy.run(&input, 64).expect("runs");
        let started = std::time::Instant::now();
        for _ in 0..20 {
            policy.run(&input, 64).expect("runs");
        }
        let ns = started.elapsed().as_secs_f64() * 1e9 / (20.0 * 64.0 * 1024.0 * count as f64);
        println!("{op}: {ns:.2} ns per element (with the Gemm before, {count} nodes)");
    }
}
