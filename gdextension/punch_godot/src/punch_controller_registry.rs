//! `PunchControllerRegistry`: the state every `PunchController` of a game shares, as an engine singleton:
//! which controllers are active, which controller drives each character, and the counters benchmarks read
//! (through `PunchProbe`, in debug builds). The frame pass that runs the active controllers, batching their
//! policy calls, is `PunchController`'s own (`punch_controller.rs`); this class knows controllers only by
//! their instance ids.

use godot::builtin::{Callable, StringName, Variant};
use godot::classes::{Object, SceneTree};
use godot::obj::{Base, Gd, InstanceId, Singleton};
use godot::prelude::{GodotClass, godot_api};
use punch_core::game::policy_gate::PolicyCall;

use crate::punch_spec::PunchSpec;

/// The registry of a game's `PunchController`s: which are active, which one drives each character, and what
/// their frames cost. An engine singleton the extension registers itself; games need not touch it (tests and
/// benchmarks read its counters through `PunchProbe`).
#[derive(GodotClass)]
#[class(init, singleton, base = Object)]
pub struct PunchControllerRegistry {
    /// The controllers with a punch or a recovery running (or just started).
    active: Vec<InstanceId>,
    /// Which controller drives each character now: (character, controller).
    drivers: Vec<(InstanceId, InstanceId)>,
    /// The controllers in a scene tree, busy or not: whose character a hit may strike.
    in_tree: Vec<InstanceId>,
    /// What reacts when a character is struck (`PunchController`'s, given as controllers enter a tree, so that
    /// `PunchCharacter` need not know the controller): the character, the controller whose fist struck it (None:
    /// the game's `take_hit`) and the impulse (N s).
    hit_reaction: Option<fn(InstanceId, Option<InstanceId>, f32)>,
    /// The scene tree whose `physics_frame` signal runs the frame pass.
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
impl PunchControllerRegistry {}

impl PunchControllerRegistry {
    /// The active controllers, in the order they became active.
    pub fn active() -> Vec<InstanceId> {
        Self::singleton().bind().active.clone()
    }

    /// The active controllers at the start of a frame pass (begun at `started`), or None when there are none:
    /// the frame is then counted, and this one lookup is all that idle characters cost a frame.
    pub fn begin_frame(started: std::time::Instant) -> Option<Vec<InstanceId>> {
        let mut hub = Self::singleton();
        let mut hub = hub.bind_mut();
        if hub.active.is_empty() {
            hub.count(started, &[]);
            return None;
        }
        Some(hub.active.clone())
    }

    /// Puts a controller on the list run every physics frame of `tree`, whose `physics_frame` signal then
    /// runs `frame_pass` (connected once per tree).
    pub fn enlist(controller: InstanceId, mut tree: Gd<SceneTree>, frame_pass: fn()) {
        let mut hub = Self::singleton();
        let mut hub = hub.bind_mut();
        if !hub.active.contains(&controller) {
            hub.active.push(controller);
        }
        if hub.connected_tree != Some(tree.instance_id()) {
            let tick = Callable::from_fn("punch_controller_frame", move |_| {
                frame_pass();
                Variant::nil()
            });
            tree.connect(&StringName::from("physics_frame"), &tick);
            hub.connected_tree = Some(tree.instance_id());
        }
    }

    /// A controller entered (`inside` true) or left a scene tree; `reaction` is what reacts to hits.
    pub fn set_in_tree(controller: InstanceId, inside: bool, reaction: fn(InstanceId, Option<InstanceId>, f32)) {
        let mut hub = Self::singleton();
        let mut hub = hub.bind_mut();
        hub.in_tree.retain(|id| *id != controller);
        if inside {
            hub.in_tree.push(controller);
        }
        hub.hit_reaction = Some(reaction);
    }

    /// `character` was struck `impulse_ns` hard by `from`'s fist (None: by the game): its controller reacts.
    pub fn react_to_hit(character: InstanceId, from: Option<InstanceId>, impulse_ns: f32) {
        // Copied out first: the reaction enlists its controller, which borrows the registry again.
        let reaction = Self::singleton().bind().hit_reaction;
        if let Some(reaction) = reaction {
            reaction(character, from, impulse_ns);
        }
    }

    /// The controllers in a scene tree now.
    pub fn in_tree() -> Vec<InstanceId> {
        Self::singleton().bind().in_tree.clone()
    }

    /// Keeps the active controllers for which `keep` is true (the frame pass drops those that are done).
    pub fn retain_active(mut keep: impl FnMut(InstanceId) -> bool) {
        let active = Self::active();
        let kept: Vec<InstanceId> = active.iter().copied().filter(|id| keep(*id)).collect();
        let mut hub = Self::singleton();
        let mut hub = hub.bind_mut();
        // Controllers enlisted while `keep` ran (a signal handler started a punch) stay too.
        let joined: Vec<InstanceId> = hub.active.iter().copied().filter(|id| !active.contains(id)).collect();
        hub.active = kept.into_iter().chain(joined).collect();
        let active = hub.active.clone();
        hub.drivers.retain(|(_, controller)| active.contains(controller));
    }

    /// The active controller that drives `character` now, if one does.
    pub fn driver_of(character: InstanceId) -> Option<InstanceId> {
        let hub = Self::singleton();
        let hub = hub.bind();
        hub.drivers.iter().find(|(driven, _)| *driven == character).map(|(_, controller)| *controller)
    }

    /// Records that `controller` drives `character` from now on; returns the controller that drove it until
    /// now, if another one did.
    pub fn take_over(character: InstanceId, controller: InstanceId) -> Option<InstanceId> {
        let mut hub = Self::singleton();
        let mut hub = hub.bind_mut();
        let previous = match hub.drivers.iter_mut().find(|(driven, _)| *driven == character) {
            Some(entry) => Some(std::mem::replace(&mut entry.1, controller)),
            None => {
                hub.drivers.push((character, controller));
                None
            }
        };
        previous.filter(|previous| *previous != controller)
    }

    /// Checks the game's physics settings against the policies' (`PunchSpec.project_settings_problems`).
    /// The error, which says what to set, is logged once per game; later calls return an empty error.
    pub fn check_project_settings() -> Result<(), String> {
        let problems = PunchSpec::project_settings_problems();
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

    /// How many controllers the frame pass runs now (punching, recovering, or with a last command to give).
    #[cfg(feature = "probe")]
    pub fn active_count() -> usize {
        Self::singleton().bind().active.len()
    }

    /// Mean time (µs) all controllers together spent per physics frame (sensing, batched inference, driving)
    /// since the last call.
    #[cfg(feature = "probe")]
    pub fn take_frame_cost_usec() -> f64 {
        let (usec, frames) = std::mem::take(&mut Self::singleton().bind_mut().cost);
        if frames == 0 { 0.0 } else { usec / frames as f64 }
    }

    /// The policy calls, the rows they ran and their time (µs) since the last call.
    #[cfg(feature = "probe")]
    pub fn take_inference_counts() -> (u64, u64, f64) {
        std::mem::take(&mut Self::singleton().bind_mut().inference)
    }

    /// Counts one frame of controller work that began at `started`, and its policy calls.
    pub fn count_frame(started: std::time::Instant, calls: &[PolicyCall]) {
        Self::singleton().bind_mut().count(started, calls);
    }

    fn count(&mut self, started: std::time::Instant, calls: &[PolicyCall]) {
        let (usec, frames) = self.cost;
        self.cost = (usec + started.elapsed().as_secs_f64() * 1e6, frames + 1);
        for call in calls {
            let (count, rows, usec) = self.inference;
            self.inference = (count + 1, rows + call.rows as u64, usec + call.usec);
        }
    }
}
