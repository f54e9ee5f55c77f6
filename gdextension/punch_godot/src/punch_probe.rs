//! `PunchProbe`: what tests, benchmarks and analysis tools read from the game's classes, kept off those
//! classes' own API. Built only with the `probe` feature (a default feature: the debug library the editor,
//! the trainer's Godot runs and the tests load; exported games' release library is built without it).

use godot::builtin::{PackedStringArray, VarDictionary};
use godot::obj::Gd;
use godot::prelude::{GodotClass, godot_api};

use crate::punch_controller::PunchController;
use crate::punch_controller_registry::PunchControllerRegistry;
use crate::punch_skeleton_modifier::PunchSkeletonModifier;

/// Debug builds only: counters and records for tests, benchmarks and analysis tools (`punch replay`, the
/// evaluator), as static functions, so that the game classes carry none of them. Exported games (the release
/// library) do not have this class.
#[derive(GodotClass)]
#[class(no_init, base = Object)]
pub struct PunchProbe {}

#[godot_api]
impl PunchProbe {
    /// Mean time (µs) all controllers together spent per physics frame (sensing, batched inference, driving)
    /// since the last call.
    #[func]
    fn take_frame_cost_usec() -> f64 {
        PunchControllerRegistry::take_frame_cost_usec()
    }

    /// How batched the inference was since the last call, over all controllers: `calls` to ONNX Runtime,
    /// the `rows` (controller decisions) they ran, and the time they took, `usec`.
    #[func]
    fn take_inference_counts() -> VarDictionary {
        let (calls, rows, usec) = PunchControllerRegistry::take_inference_counts();
        let mut counts = VarDictionary::new();
        counts.set("calls", calls as i64);
        counts.set("rows", rows as i64);
        counts.set("usec", usec);
        counts
    }

    /// How many controllers the frame pass runs now (punching, recovering, or with a last command to give).
    #[func]
    fn active_controller_count() -> i64 {
        PunchControllerRegistry::active_count() as i64
    }

    /// Mean time (µs) all `PunchSkeletonModifier`s spent per character-frame writing poses since the last call
    /// (`usec_per_frame`), and how many character-frames that was (`frames`).
    #[func]
    fn take_skeleton_cost_usec() -> VarDictionary {
        PunchSkeletonModifier::take_cost_usec()
    }

    /// The bones `modifier` writes each frame, in order (empty before it first poses its skeleton).
    #[func]
    fn written_bones(modifier: Gd<PunchSkeletonModifier>) -> PackedStringArray {
        modifier.bind().written_bones()
    }

    /// Keeps each of `controller`'s punches' per-frame features, observations and actions from its next punch
    /// on (`last_punch_record`), or stops keeping them (off by default: games need not pay for it).
    #[func]
    fn set_recording(mut controller: Gd<PunchController>, record: bool) {
        controller.bind_mut().set_record(record);
    }

    /// `controller`'s last finished punch, when recording (`set_recording`): `features` (frames x feature
    /// count, the names are `PunchSpec.feature_names()`), `observations` (decisions x the observation size),
    /// `mean_actions` and `actions` (decisions x 10, before and after noise), `frames` and `decisions`.
    #[func]
    fn last_punch_record(controller: Gd<PunchController>) -> VarDictionary {
        controller.bind().last_punch_record()
    }
}
