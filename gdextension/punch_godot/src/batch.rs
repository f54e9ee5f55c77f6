//! Batched inference for every `PunchController` in the game. Controllers whose `policy` is the same file
//! share one ONNX session, and once per physics frame (on the scene tree's `physics_frame` signal, before
//! any node's `_physics_process`) all punching controllers are run together: each senses its character,
//! then every shared policy runs once on the observations of all controllers that decide this frame, then
//! each controller acts. Signals are emitted last, outside any borrow, so handlers may call back freely.

use std::cell::{Cell, RefCell};
use std::collections::HashMap;
use std::rc::Rc;
use std::time::Instant;

use godot::builtin::{Callable, GString, StringName, Variant};
use godot::classes::{FileAccess, Node};
use godot::obj::{Gd, InstanceId};
use punch_core::Policy;
use punch_core::observation::{OBS_DIM, spec_hash};

use crate::punch_controller::PunchController;
use crate::punch_runtime::ensure_onnx_runtime;

/// One loaded policy file, shared by every controller that plays it.
pub struct SharedPolicy {
    policy: RefCell<Policy>,
    /// Actions are smoothed over this many decisions, as in training.
    pub smoothing_window: usize,
    /// Physics frames of one punch, as in training.
    pub frames: usize,
    /// The observation spec hash the policy was trained with.
    pub spec_hash: String,
}

thread_local! {
    /// Loaded policies by path, with the file's modification time: a changed file is loaded again.
    static POLICIES: RefCell<HashMap<String, (u64, Rc<SharedPolicy>)>> = RefCell::new(HashMap::new());
    static ACTIVE: RefCell<Vec<Gd<PunchController>>> = const { RefCell::new(Vec::new()) };
    static CONNECTED_TREE: Cell<Option<InstanceId>> = const { Cell::new(None) };
    /// Controller work since the last `take_frame_cost`: (microseconds, frames).
    static COST: Cell<(f64, u64)> = const { Cell::new((0.0, 0)) };
    /// Policy calls, the rows they ran, and their time (µs) since the last `take_inference_counts`.
    static INFERENCE: Cell<(u64, u64, f64)> = const { Cell::new((0, 0, 0.0)) };
}

impl SharedPolicy {
    /// The policy at `path` (read through Godot's file system, so it works inside a .pck), loaded once per
    /// version of the file and shared by every controller that plays it.
    pub fn get(path: &GString) -> Result<Rc<Self>, String> {
        if path.is_empty() {
            return Err("no policy file set".into());
        }
        if !FileAccess::file_exists(path) {
            return Err(format!("policy file not found: '{path}'"));
        }
        let key = path.to_string();
        let modified = FileAccess::get_modified_time(path);
        if let Some(shared) =
            POLICIES.with(|p| p.borrow().get(&key).filter(|(m, _)| *m == modified).map(|(_, s)| s.clone()))
        {
            return Ok(shared);
        }
        let shared = Rc::new(Self::load(path)?);
        POLICIES.with(|p| p.borrow_mut().insert(key, (modified, shared.clone())));
        Ok(shared)
    }

    fn load(path: &GString) -> Result<Self, String> {
        if !ensure_onnx_runtime() {
            return Err("ONNX Runtime could not be loaded (see the error above)".into());
        }
        let bytes = FileAccess::get_file_as_bytes(path);
        let policy = Policy::from_bytes(bytes.as_slice()).map_err(|e| format!("policy '{path}': {e}"))?;
        if policy.input_width() != OBS_DIM {
            return Err(format!(
                "incompatible policy '{path}': it takes {} inputs, the observation has {OBS_DIM}",
                policy.input_width()
            ));
        }
        let number = |key: &str, default: usize| policy.metadata(key).and_then(|v| v.parse().ok()).unwrap_or(default);
        Ok(Self {
            smoothing_window: number("punch_smoothing_window", 1),
            frames: number("punch_frames", 50),
            spec_hash: policy.metadata("punch_spec_hash").unwrap_or_default(),
            policy: RefCell::new(policy),
        })
    }

    /// Checks that the policy was trained for this character's observation with `decision_period`.
    pub fn check_spec(&self, decision_period: u32) -> Result<(), String> {
        let expected = spec_hash(decision_period);
        if self.spec_hash != expected {
            return Err(format!(
                "incompatible policy: it was trained for spec {:?}; this character with decision period {decision_period} needs {expected}",
                self.spec_hash
            ));
        }
        Ok(())
    }

    /// Mean actions for `batch` observations (row-major), one inference call.
    pub fn mean_actions(&self, observations: &[f32], batch: usize) -> Result<Vec<f32>, String> {
        let outputs = self.policy.borrow_mut().run(observations, batch).map_err(|e| e.to_string())?;
        let mean = outputs.into_iter().next().ok_or("the policy has no output")?;
        Ok(mean.data)
    }
}

/// Puts a controller on the list run every physics frame (it leaves by itself when its punch ends).
pub fn enlist(controller: Gd<PunchController>) {
    connect_tick(&controller.clone().upcast::<Node>());
    ACTIVE.with(|active| {
        let mut active = active.borrow_mut();
        // Comparing handles needs live objects: drop freed controllers first.
        active.retain(|c| c.is_instance_valid());
        if !active.contains(&controller) {
            active.push(controller);
        }
    });
}

/// Mean controller work per physics frame (µs, all controllers together) since the last call.
pub fn take_frame_cost_usec() -> f64 {
    let (usec, frames) = COST.replace((0.0, 0));
    if frames == 0 { 0.0 } else { usec / frames as f64 }
}

/// Policy calls, rows and inference time (µs) since the last call.
pub fn take_inference_counts() -> (u64, u64, f64) {
    INFERENCE.replace((0, 0, 0.0))
}

fn connect_tick(node: &Gd<Node>) {
    if !node.is_inside_tree() {
        return;
    }
    let mut tree = node.get_tree();
    if CONNECTED_TREE.get() == Some(tree.instance_id()) {
        return;
    }
    let tick = Callable::from_fn("punch_controller_tick", |_| {
        tick();
        Variant::nil()
    });
    tree.connect(&StringName::from("physics_frame"), &tick);
    CONNECTED_TREE.set(Some(tree.instance_id()));
}

fn tick() {
    let started = Instant::now();
    let mut controllers: Vec<Gd<PunchController>> = ACTIVE.with(|a| a.take());
    controllers.retain(|c| c.is_instance_valid());
    if controllers.is_empty() {
        return;
    }
    let running: Vec<bool> = controllers.iter().map(|c| c.can_process()).collect();

    // Sense: who decides this frame, with which policy and observation.
    let mut requests: Vec<(usize, Rc<SharedPolicy>, [f32; OBS_DIM])> = Vec::new();
    for (index, controller) in controllers.iter_mut().enumerate() {
        if running[index] {
            if let Some((policy, observation)) = controller.bind_mut().sense() {
                requests.push((index, policy, observation));
            }
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
        let (calls, rows, usec) = INFERENCE.get();
        INFERENCE.set((calls + 1, rows + group.len() as u64, usec + inference_started.elapsed().as_secs_f64() * 1e6));
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

    controllers.retain(|c| c.is_instance_valid() && c.bind().is_punching());
    ACTIVE.with(|active| {
        let added = active.take();
        for controller in added.into_iter().filter(|c| c.is_instance_valid()) {
            if !controllers.contains(&controller) {
                controllers.push(controller);
            }
        }
        *active.borrow_mut() = controllers;
    });
    let (usec, frames) = COST.get();
    COST.set((usec + started.elapsed().as_secs_f64() * 1e6, frames + 1));
}
