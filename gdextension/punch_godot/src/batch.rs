//! `PunchInference`: batched inference for every `PunchController` in the game, as an engine singleton that
//! owns the shared state (loaded policies, the controllers punching, the counters).
//!
//! Controllers whose `policy` is the same file share one ONNX session, and once per physics frame (on the
//! scene tree's `physics_frame` signal, before any node's `_physics_process`) all punching controllers are
//! run together: each senses its character, then every shared policy runs once on the observations of all
//! controllers that decide this frame, then each controller acts. Signals are emitted last, with no borrow of
//! this singleton or of the controller held, so handlers may call back freely.

use std::rc::Rc;
use std::time::Instant;

use godot::builtin::{Callable, StringName, Variant};
use godot::classes::{Node, Object};
use godot::global::godot_error;
use godot::obj::{Base, Gd, InstanceId, Singleton};
use godot::prelude::{GodotClass, godot_api};
use punch_core::Policy;
use punch_core::character::DOF_COUNT;
use punch_core::observation::{OBS_DIM, spec_hash};
use punch_core::spec::{POLICY_INPUT, POLICY_OUTPUTS, PolicySpec, ReachVolume};

use crate::punch_controller::PunchController;

/// A controller's request for a decision: the policy to ask and the observation to decide on.
pub type DecisionRequest = (Rc<SharedPolicy>, [f32; OBS_DIM]);

/// One loaded policy file, shared by every controller that plays it.
pub struct SharedPolicy {
    policy: std::cell::RefCell<Policy>,
    /// The timing the policy was trained with (from its metadata).
    pub spec: PolicySpec,
    /// The observation spec hash the policy was trained with.
    pub spec_hash: String,
    /// The target placements it was trained to punch.
    pub reach: ReachVolume,
}

impl SharedPolicy {
    /// Checks that `policy` is a punching policy (its input, outputs and contract).
    pub fn new(policy: Policy) -> Result<Self, String> {
        policy
            .check_interface(POLICY_INPUT, OBS_DIM, &[(POLICY_OUTPUTS[0], DOF_COUNT), (POLICY_OUTPUTS[1], DOF_COUNT)])
            .map_err(|e| format!("incompatible policy: {e}"))?;
        let spec = PolicySpec::from_metadata(|key| policy.metadata(key)).map_err(|e| e.to_string())?;
        let reach = ReachVolume::from_metadata(|key| policy.metadata(key)).map_err(|e| e.to_string())?;
        Ok(Self {
            spec,
            reach,
            spec_hash: policy.metadata(punch_core::spec::keys::SPEC_HASH).unwrap_or_default(),
            policy: std::cell::RefCell::new(policy),
        })
    }

    /// Runs the model on `batch` rows (`PunchPolicy.run`).
    pub fn run(&self, input: &[f32], batch: usize) -> punch_core::error::CoreResult<Vec<punch_core::Tensor>> {
        self.policy.borrow_mut().run(input, batch)
    }

    /// Reads the model (`PunchPolicy`'s metadata and shape queries).
    pub fn read<R>(&self, read: impl FnOnce(&Policy) -> R) -> R {
        read(&self.policy.borrow())
    }

    /// Checks that the policy was trained for this character's observation with `decision_period`.
    pub fn check_spec(&self, decision_period: u32) -> Result<(), String> {
        let expected = spec_hash(decision_period);
        if self.spec_hash != expected || self.spec.decision_period != decision_period {
            return Err(format!(
                "incompatible policy: it was trained for spec {:?}; this character with decision period {decision_period} needs {expected}",
                self.spec_hash
            ));
        }
        Ok(())
    }

    /// Mean actions for `batch` observations (row-major), one inference call.
    pub fn mean_actions(&self, observations: &[f32], batch: usize) -> Result<Vec<f32>, String> {
        let outputs = self.run(observations, batch).map_err(|e| e.to_string())?;
        let mean = outputs.into_iter().next().ok_or("the policy has no output")?;
        if mean.data.iter().any(|v| !v.is_finite()) {
            return Err("the policy returned NaN or infinite actions".into());
        }
        Ok(mean.data)
    }
}

/// Runs every punching `PunchController` once per physics frame, batching their policy calls. An engine
/// singleton the extension registers itself; games need not touch it.
#[derive(GodotClass)]
#[class(init, singleton, base = Object)]
pub struct PunchInference {
    /// The controllers with a punch running (or just started).
    active: Vec<Gd<PunchController>>,
    /// The scene tree whose `physics_frame` signal runs the batch.
    connected_tree: Option<InstanceId>,
    /// Controller work since the last `take_frame_cost_usec`: (microseconds, frames).
    cost: (f64, u64),
    /// Policy calls, the rows they ran, and their time (µs) since the last `take_inference_counts`.
    inference: (u64, u64, f64),
    /// The project-settings error was logged (once per game).
    settings_reported: bool,
    base: Base<Object>,
}

#[godot_api]
impl PunchInference {
    /// Mean time (µs) all controllers together spent per physics frame (sensing, batched inference,
    /// driving) since the last call: for benchmarks.
    #[func]
    pub fn take_frame_cost_usec(&mut self) -> f64 {
        let (usec, frames) = std::mem::take(&mut self.cost);
        if frames == 0 { 0.0 } else { usec / frames as f64 }
    }
}

impl PunchInference {
    /// Puts a controller on the list run every physics frame (it leaves by itself when its punch ends).
    pub fn enlist(controller: Gd<PunchController>) {
        let mut hub = Self::singleton();
        hub.bind_mut().connect_tick(&controller.clone().upcast::<Node>());
        let mut hub = hub.bind_mut();
        // Comparing handles needs live objects: drop freed controllers first.
        hub.active.retain(|c| c.is_instance_valid());
        if !hub.active.contains(&controller) {
            hub.active.push(controller);
        }
    }

    /// Checks the game's physics settings against the policies' (`PunchController.project_settings_problems`).
    /// The error, which says what to set, is logged once per game; later calls return an empty error.
    pub fn check_project_settings() -> Result<(), String> {
        let problems = PunchController::project_settings_problems();
        if problems.is_empty() {
            return Ok(());
        }
        let mut hub = Self::singleton();
        if std::mem::replace(&mut hub.bind_mut().settings_reported, true) {
            return Err(String::new());
        }
        let lines: Vec<String> = problems.as_slice().iter().map(|line| format!("  - {line}")).collect();
        Err(format!(
            "this project's physics settings are not the ones the policies were trained with, so punches \
             would miss; no punch plays until they are set (the editor plugin offers to set them; see the \
             README, 'Project settings'):\n{}",
            lines.join("\n")
        ))
    }

    /// Policy calls, rows and inference time (µs) since the last call.
    pub fn take_inference_counts() -> (u64, u64, f64) {
        std::mem::take(&mut Self::singleton().bind_mut().inference)
    }

    fn connect_tick(&mut self, node: &Gd<Node>) {
        if !node.is_inside_tree() {
            return;
        }
        let mut tree = node.get_tree();
        if self.connected_tree == Some(tree.instance_id()) {
            return;
        }
        let tick = Callable::from_fn("punch_controller_tick", |_| {
            Self::tick();
            Variant::nil()
        });
        tree.connect(&StringName::from("physics_frame"), &tick);
        self.connected_tree = Some(tree.instance_id());
    }

    fn tick() {
        let started = Instant::now();
        let mut hub = Self::singleton();
        let mut controllers = std::mem::take(&mut hub.bind_mut().active);
        controllers.retain(|c| c.is_instance_valid());
        if controllers.is_empty() {
            // Idle characters are on no list: this check is all a frame costs them (counted for benchmarks).
            hub.bind_mut().count_frame(started);
            return;
        }
        let running: Vec<bool> = controllers.iter().map(|c| c.can_process()).collect();

        // Sense: who decides this frame, with which policy and observation.
        let mut requests: Vec<(usize, Rc<SharedPolicy>, [f32; OBS_DIM])> = Vec::new();
        for (index, controller) in controllers.iter_mut().enumerate() {
            if running[index]
                && let Some((policy, observation)) = controller.bind_mut().sense()
            {
                requests.push((index, policy, observation));
            }
        }

        // Decide: one call per shared policy.
        let mut means: Vec<Option<Result<Vec<f32>, String>>> = (0..controllers.len()).map(|_| None).collect();
        while let Some((_, policy, _)) = requests.first() {
            let policy = policy.clone();
            let (group, rest): (Vec<_>, Vec<_>) = requests.into_iter().partition(|(_, p, _)| Rc::ptr_eq(p, &policy));
            requests = rest;
            let observations: Vec<f32> = group.iter().flat_map(|(_, _, obs)| *obs).collect();
            let inference_started = Instant::now();
            let result = policy.mean_actions(&observations, group.len());
            {
                let mut hub = hub.bind_mut();
                let (calls, rows, usec) = hub.inference;
                hub.inference =
                    (calls + 1, rows + group.len() as u64, usec + inference_started.elapsed().as_secs_f64() * 1e6);
            }
            if let Err(error) = &result {
                // Once for the policy, not once per controller that asked it; each of their punches ends.
                godot_error!("PunchController: inference failed for {} controllers: {error}", group.len());
            }
            let width = result.as_ref().map_or(0, |m| m.len() / group.len());
            for (row, (index, _, _)) in group.iter().enumerate() {
                means[*index] = Some(match &result {
                    Ok(mean) => Ok(mean[row * width..(row + 1) * width].to_vec()),
                    Err(error) => Err(error.clone()),
                });
            }
        }

        // Act, then emit each controller's signals with no borrow held.
        for (index, controller) in controllers.iter_mut().enumerate() {
            if running[index] {
                controller.bind_mut().act(means[index].take());
                PunchController::emit_events(controller);
            }
        }

        controllers.retain(|c| c.is_instance_valid() && c.bind().is_active());
        let mut hub = hub.bind_mut();
        // Controllers that started a punch during this tick (from a signal handler) joined `active` meanwhile.
        for controller in std::mem::take(&mut hub.active).into_iter().filter(|c| c.is_instance_valid()) {
            if !controllers.contains(&controller) {
                controllers.push(controller);
            }
        }
        hub.active = controllers;
        hub.count_frame(started);
    }

    fn count_frame(&mut self, started: Instant) {
        let (usec, frames) = self.cost;
        self.cost = (usec + started.elapsed().as_secs_f64() * 1e6, frames + 1);
    }
}
