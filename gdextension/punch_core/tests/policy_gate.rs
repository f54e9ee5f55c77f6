//! The policy gate on real files: the shipped policies pass it and decide batched exactly as one by one; a
//! model that is no punching policy, or one trained for another observation, is refused with the reason.

mod common;

use std::rc::Rc;

use punch_core::contract::character::DOF_COUNT;
use punch_core::contract::observation::{OBS_DIM, spec_hash};
use punch_core::contract::spec::{REACH_VOLUME, keys};
use punch_core::game::policy_gate::{PunchingPolicy, decide_batched};
use punch_core::inference::runtime;
use punch_core::{CoreError, Policy};

/// The observation spec hash of every policy the addon ships (their `punch_spec_hash`), pinned: a change to
/// the observation (features, order, decision period) changes it, and the shipped policies must be retrained.
const SHIPPED_SPEC_HASH: &str = "b3b18e1568362141";

fn load(path: std::path::PathBuf) -> Policy {
    if let Err(error) = runtime::init_from_dir(&common::onnxruntime_dir()) {
        panic!("{error}: run ./dev setup (or scons) first, or set PUNCH_ONNXRUNTIME_DIR");
    }
    Policy::from_bytes(&std::fs::read(&path).expect("readable")).expect("a model")
}

fn shipped(style: &str) -> PunchingPolicy {
    let path = common::project_root().join(format!("addons/punch_controller/policies/{style}.onnx"));
    PunchingPolicy::new(load(path)).expect("a shipped policy passes the gate")
}

fn observations(rows: usize) -> Vec<f32> {
    (0..rows * OBS_DIM).map(|i| ((i * 37 % 101) as f32 / 50.0 - 1.0) * 0.5).collect()
}

#[test]
fn the_shipped_policies_pass_with_their_contract_and_the_pinned_spec_hash() {
    assert_eq!(spec_hash(5), SHIPPED_SPEC_HASH, "the observation spec changed: retrain the shipped policies");
    for style in ["straight", "hook", "swing"] {
        let policy = shipped(style);
        assert_eq!(policy.spec_hash, SHIPPED_SPEC_HASH, "{style}");
        assert_eq!(policy.read(|p| p.metadata(keys::SPEC_HASH)).as_deref(), Some(SHIPPED_SPEC_HASH));
        assert_eq!((policy.spec.decision_period, policy.reach), (5, REACH_VOLUME), "{style}");
        policy.check_spec(5).expect("this character's spec");
        let error = policy.check_spec(4).expect_err("another decision period");
        assert!(matches!(error, CoreError::IncompatiblePolicy(_)) && error.to_string().contains(&spec_hash(4)));
    }
}

#[test]
fn a_model_that_is_no_punching_policy_is_refused_with_the_reason() {
    let tiny = load(common::fixture("tiny_actor.onnx"));
    let error = PunchingPolicy::new(tiny).err().expect("refused");
    assert!(matches!(error, CoreError::IncompatiblePolicy(_)), "{error}");
    assert!(error.to_string().contains(&format!("[batch, {OBS_DIM}]")), "says what a policy's input is: {error}");
}

#[test]
fn batched_decisions_equal_one_by_one_with_one_call_per_policy() {
    let (straight, hook) = (Rc::new(shipped("straight")), Rc::new(shipped("hook")));
    let rows = observations(5);
    let row = |i: usize| -> [f32; OBS_DIM] { rows[i * OBS_DIM..(i + 1) * OBS_DIM].try_into().expect("a row") };
    let requests = vec![
        (straight.clone(), row(0)),
        (hook.clone(), row(1)),
        (straight.clone(), row(2)),
        (straight.clone(), row(3)),
        (hook.clone(), row(4)),
    ];
    let batch = decide_batched(&requests);
    assert_eq!(batch.calls.iter().map(|c| c.rows).collect::<Vec<_>>(), [3, 2], "one call per policy");
    for (index, (policy, observation)) in requests.iter().enumerate() {
        let alone = policy.mean_actions(observation, 1).expect("decides");
        let batched = batch.means[index].as_ref().expect("decided");
        assert_eq!(batched.len(), DOF_COUNT);
        for (a, b) in batched.iter().zip(&alone) {
            assert!((a - b).abs() < 1e-5, "row {index}: batched {a} alone {b}");
        }
    }
}

#[test]
fn a_failed_call_fails_only_the_requests_of_its_policy() {
    let (straight, hook) = (Rc::new(shipped("straight")), Rc::new(shipped("hook")));
    let mut broken = [0.1; OBS_DIM];
    broken[3] = f32::NAN;
    let requests = vec![(straight.clone(), [0.1; OBS_DIM]), (hook.clone(), broken), (hook, [0.1; OBS_DIM])];
    let batch = decide_batched(&requests);
    assert!(batch.means[0].is_ok(), "another policy's call is unaffected");
    let (first, second) = (batch.means[1].as_ref().expect_err("fails"), batch.means[2].as_ref().expect_err("fails"));
    assert!(Rc::ptr_eq(first, second), "one error for the call, reported once");
}
