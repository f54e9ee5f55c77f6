//! The gate a model passes before a game character plays it, and the batched decisions of every character
//! that plays one.
//!
//! A `PunchingPolicy` is a loaded model checked once as a punching policy: its input and outputs, its policy
//! contract (timing, reach volume, observation spec hash). Every controller that plays the same policy file
//! shares one, so a game's characters run in one inference call per policy and frame (`decide_batched`), and
//! an action that is not a number never reaches a joint motor.

use std::cell::RefCell;
use std::rc::Rc;

use crate::contract::character::DOF_COUNT;
use crate::contract::observation::{OBS_DIM, OBS_SPEC_VERSION, spec_hash};
use crate::contract::spec::{
    NoiseScale, POLICY_INPUT, POLICY_OUTPUTS, PolicySpec, ReachVolume, keys, noise_scale_from_metadata,
    start_load_from_metadata,
};
use crate::contract::stance::Load;
use crate::error::{CoreError, CoreResult};
use crate::inference::policy::{Policy, Tensor};

/// A model checked as a punching policy, shared by every controller that plays it.
pub struct PunchingPolicy {
    /// ONNX Runtime's session needs `&mut` to run; controllers share the policy, and the game runs on one
    /// thread.
    policy: RefCell<Policy>,
    /// The timing the policy was trained with (from its metadata).
    pub spec: PolicySpec,
    /// The observation spec hash the policy was trained with (`observation::spec_hash`).
    pub spec_hash: String,
    /// The target placements it was trained to punch.
    pub reach: ReachVolume,
    /// How the runtime noise is spread over its degrees of freedom (`punch_noise_scale`; uniform without).
    pub noise_scale: NoiseScale,
    /// The load it punches from (`punch_start_load`): the controller draws the arm there before the policy starts;
    /// None: from the guard.
    pub start_load: Option<Load>,
}

impl PunchingPolicy {
    /// Checks that `policy` is a punching policy: its input is the observation, its outputs the mean action
    /// (and sigma), and its metadata holds the policy contract and the reach volume.
    pub fn new(policy: Policy) -> CoreResult<Self> {
        let incompatible = |reason: String| CoreError::IncompatiblePolicy(reason);
        // A policy of an earlier spec is named as such first (its input size would say less about the fix).
        if let Some(version) = policy.metadata(keys::SPEC_VERSION)
            && version != OBS_SPEC_VERSION.to_string()
        {
            return Err(incompatible(format!(
                "it was trained for policy spec version {version}; this extension reads version \
                 {OBS_SPEC_VERSION} (version 2 added the character's own motion to the observation, for punching \
                 on the move; version 3 the arms' lengths, for characters of any size): retrain it with this \
                 version's `punch train` (the addon's own policies are)"
            )));
        }
        policy
            .check_interface(POLICY_INPUT, OBS_DIM, &[(POLICY_OUTPUTS[0], DOF_COUNT), (POLICY_OUTPUTS[1], DOF_COUNT)])
            .map_err(|e| incompatible(e.to_string()))?;
        let spec = PolicySpec::from_metadata(|key| policy.metadata(key)).map_err(|e| incompatible(e.to_string()))?;
        let reach = ReachVolume::from_metadata(|key| policy.metadata(key)).map_err(|e| incompatible(e.to_string()))?;
        let noise_scale =
            noise_scale_from_metadata(|key| policy.metadata(key)).map_err(|e| incompatible(e.to_string()))?;
        let start_load =
            start_load_from_metadata(|key| policy.metadata(key)).map_err(|e| incompatible(e.to_string()))?;
        Ok(Self {
            spec,
            reach,
            noise_scale,
            start_load,
            spec_hash: policy.metadata(keys::SPEC_HASH).unwrap_or_default(),
            policy: RefCell::new(policy),
        })
    }

    /// Runs the model on `batch` rows of `input` (any use of the model, not only punching).
    pub fn run(&self, input: &[f32], batch: usize) -> CoreResult<Vec<Tensor>> {
        self.policy.borrow_mut().run(input, batch)
    }

    /// Reads the model (its metadata and shapes).
    pub fn read<R>(&self, read: impl FnOnce(&Policy) -> R) -> R {
        read(&self.policy.borrow())
    }

    /// Checks that the policy was trained for this character's observation with `decision_period`.
    pub fn check_spec(&self, decision_period: u32) -> CoreResult<()> {
        let expected = spec_hash(decision_period);
        if self.spec_hash != expected || self.spec.decision_period != decision_period {
            return Err(CoreError::IncompatiblePolicy(format!(
                "it was trained for spec {:?}; this character with decision period {decision_period} needs {expected}",
                self.spec_hash
            )));
        }
        Ok(())
    }

    /// Mean actions for `batch` observations (row-major [batch, OBS_DIM]) in one inference call; actions
    /// that are not finite numbers are an error.
    pub fn mean_actions(&self, observations: &[f32], batch: usize) -> CoreResult<Vec<f32>> {
        let outputs = self.run(observations, batch)?;
        let mean = outputs.into_iter().next().ok_or_else(|| CoreError::Inference("the policy has no output".into()))?;
        if mean.data.len() != batch * DOF_COUNT {
            return Err(CoreError::Inference(format!(
                "the policy returned {} values for {batch} actions",
                mean.data.len()
            )));
        }
        if mean.data.iter().any(|v| !v.is_finite()) {
            return Err(CoreError::Inference("the policy returned NaN or infinite actions".into()));
        }
        Ok(mean.data)
    }
}

/// A character's request for a decision: the policy to ask and the observation to decide on.
pub type DecisionRequest = (Rc<PunchingPolicy>, [f32; OBS_DIM]);

/// One policy call of a batch: how many rows it ran and how long it took.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PolicyCall {
    pub rows: usize,
    pub usec: f64,
}

/// The decisions of a batch: per request, its mean action or the error of its policy's call (one error
/// shared by every request of that call, so the caller can report it once); and the calls made.
pub struct BatchedDecisions {
    pub means: Vec<Result<Vec<f32>, Rc<CoreError>>>,
    pub calls: Vec<PolicyCall>,
}

/// Decides every request with one inference call per distinct policy (requests of the same `Rc` share a
/// call), in the order the policies first appear. The means come back in the requests' order.
pub fn decide_batched(requests: &[DecisionRequest]) -> BatchedDecisions {
    let mut means: Vec<Option<Result<Vec<f32>, Rc<CoreError>>>> = (0..requests.len()).map(|_| None).collect();
    let mut calls = Vec::new();
    for (first, (policy, _)) in requests.iter().enumerate() {
        if means[first].is_some() {
            continue;
        }
        let group: Vec<usize> =
            (first..requests.len()).filter(|&index| Rc::ptr_eq(&requests[index].0, policy)).collect();
        let observations: Vec<f32> = group.iter().flat_map(|&index| requests[index].1).collect();
        let started = std::time::Instant::now();
        let result = policy.mean_actions(&observations, group.len()).map_err(Rc::new);
        calls.push(PolicyCall { rows: group.len(), usec: started.elapsed().as_secs_f64() * 1e6 });
        for (row, &index) in group.iter().enumerate() {
            means[index] = Some(match &result {
                Ok(mean) => Ok(mean[row * DOF_COUNT..(row + 1) * DOF_COUNT].to_vec()),
                Err(error) => Err(error.clone()),
            });
        }
    }
    BatchedDecisions { means: means.into_iter().flatten().collect(), calls }
}
