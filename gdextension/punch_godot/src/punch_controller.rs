//! `PunchController`: plays a trained punching policy on a `PunchCharacter` in a game. The punch itself
//! (decision clock, observation, runtime noise, smoothing, motor law, hits, its end) is `punch_core::punch`;
//! this class moves engine readings in and motor commands and signals out, and `PunchInference` batches the
//! policy calls of every controller.

use std::rc::Rc;

use glam::Vec3;
use godot::builtin::{GString, PackedFloat32Array, PackedStringArray, VarDictionary, Vector2, Vector3};
use godot::classes::{Engine, INode, Node, Node3D, PhysicsShapeQueryParameters3D, ProjectSettings, SphereShape3D};
use godot::global::{godot_error, godot_warn};
use godot::meta::ToGodot;
use godot::obj::{Base, Gd, InstanceId, NewGd, Singleton, WithBaseField, WithUserSignals};
use godot::prelude::{GodotClass, godot_api};
use punch_core::character::{Body, DEFAULT_DECISION_PERIOD};
use punch_core::observation::OBS_DIM;
use punch_core::punch::{Hit, Punch, PunchRecord, PunchSummary, Recovery, RuntimeNoise, Sensed};
use punch_core::sensing::{CharacterGeometry, FEATURE_COUNT, FEATURE_NAMES, FrameReading};
use punch_core::spec::{BagPlacement, PROJECT_SETTINGS, SettingValue, project_setting_problems};

use crate::batch::{DecisionRequest, PunchInference, SharedPolicy};
use crate::convert::vector3;
use crate::engine_io::{add_area_touches, add_bag_contacts, read_forearm_contacts};
use crate::punch_character::PunchCharacter;
use crate::punch_policy::PunchPolicy;
use crate::target::Target;

/// Makes a `PunchCharacter` punch a target with a trained policy (an .onnx file made by `punch train`).
/// Each punch differs when `noise_sigma` > 0: Gaussian noise of that standard deviation is added to the
/// policy's mean action at every decision (or at the first `noise_decisions` only). All controllers that
/// play the same `PunchPolicy` resource share one model and run in one inference call per decision tick.
///
/// A punch asked for away from the guard pose first returns the character to guard (`guard_first`); after
/// it, the character returns to its guard pose under physics (`auto_recover`). Two punches are identical
/// (sigma 0, or the same seed) when they start from the same state of the world: the character at rest in its guard pose (as after `recover()` from rest, or
/// in a scene that has just started) and the target at rest at the same place relative to it.
#[derive(GodotClass)]
#[class(base = Node, init)]
pub struct PunchController {
    /// The policy: an .onnx file from `punch train` (a `PunchPolicy` resource: pick the file, or
    /// `load("res://....onnx")`). The addon ships one per style in `addons/punch_controller/policies/`.
    /// Changing it during a punch ends that punch (`punch_finished` says it was interrupted); the next punch
    /// plays the new policy.
    #[export]
    #[var(set = set_policy)]
    policy: Option<Gd<PunchPolicy>>,
    /// Standard deviation of the noise added to the policy's mean action, in action units (actions lie in
    /// [-1, 1]). Values outside 0..1 are clamped, with a warning. Takes effect at the next decision.
    #[export(range = (0.0, 1.0, 0.01))]
    #[var(set = set_noise_sigma)]
    noise_sigma: f32,
    /// Noise on the first k decisions of a punch only; -1 puts noise on every decision.
    #[export]
    #[init(val = -1)]
    noise_decisions: i32,
    /// Physics frames each decision is held for; must match the policy's.
    #[export]
    #[init(val = DEFAULT_DECISION_PERIOD as i32)]
    decision_period: i32,
    /// The character to drive.
    #[export]
    character: Option<Gd<PunchCharacter>>,
    /// What to punch: any Node3D (a sandbag, a RigidBody3D, CharacterBody3D, StaticBody3D or Area3D, a
    /// marker or bone attachment on another character). The policy aims at its position; its physics object
    /// (the node itself, else a child, else the nearest ancestor that is one) is what the policy feels.
    #[export]
    target: Option<Gd<Node3D>>,
    /// Seed of the noise: the same seed and sigma give the same sequence of punches. A new seed takes
    /// effect at the next punch.
    #[export]
    seed: i64,
    /// The physics layers whose bodies count as hit when a fist touches them (the target always counts).
    /// Only what the character's bodies collide with can be touched (their collision masks: layers 1 to 3 in
    /// the addon's character scene).
    #[export(flags_3d_physics)]
    #[init(val = u32::MAX)]
    hit_layers: u32,
    /// Also count Area3D overlaps of a fist (hurtboxes on `hit_layers`) as hits, with no impulse. An Area3D
    /// target is always checked. Costs a shape query per fist and frame while punching.
    #[export]
    hit_areas: bool,
    /// After a punch, drive the character back to its guard pose under physics (`recovered` says when it
    /// is there). Off: the joints hold where the punch left them.
    #[export]
    #[init(val = true)]
    auto_recover: bool,
    /// A punch asked for while the character is away from its guard pose (the end of an earlier punch,
    /// mid-recovery) first returns it to guard under physics, at most 0.5 s, then plays the policy: punches
    /// land far more often from there (BENCHMARKS.md, "after an earlier punch"). Off: the policy starts from
    /// whatever pose the arms are in. A punch from the guard starts at once either way.
    #[export]
    #[init(val = true)]
    guard_first: bool,
    /// Punch as soon as the scene starts.
    #[export]
    autostart: bool,
    /// Keep each punch's per-frame features, observations and actions for `last_punch_record()`
    /// (for analysis tools such as `punch replay`; leave it off in games).
    #[export]
    record: bool,

    phase: Phase,
    loaded: Option<Loaded>,
    aim: Option<Target>,
    area_query: Option<Gd<PhysicsShapeQueryParameters3D>>,
    events: Vec<Event>,
    last_record: PunchRecord,
    base: Base<Node>,
}

/// What the controller is doing.
#[derive(Default)]
enum Phase {
    #[default]
    Idle,
    Punching(Box<Punch>),
    /// A punch asked for away from the guard pose (`guard_first`): returning to guard before it starts;
    /// the motor commands for the next step.
    Guarding(Box<Punch>, Box<Recovery>, [Vec3; 5]),
    /// Returning to guard; the motor commands for the next step.
    Recovering(Box<Recovery>, [Vec3; 5]),
}

struct Loaded {
    policy: Rc<SharedPolicy>,
    noise: RuntimeNoise,
    /// The seed `noise` was made from.
    seed: i64,
}

enum Event {
    Hit(Hit),
    Finished(PunchSummary, Ending),
    Recovered,
}

/// How a punch ended (`punch_finished`'s `ended`).
enum Ending {
    Completed,
    Interrupted,
    /// The message was logged (an empty one was logged once for many controllers).
    Error(String),
}

#[godot_api]
impl INode for PunchController {
    fn ready(&mut self) {
        if self.autostart {
            self.base_mut().call_deferred("punch", &[]);
        }
    }
}

#[godot_api]
impl PunchController {
    /// Emitted when a punch begins.
    #[signal]
    fn punch_started();

    /// Emitted when a punch starts with the target outside the policy's reach volume (`reach_volume()`):
    /// the punch then goes at `nearest`, the nearest point the policy covers (global coordinates), and may
    /// miss. `offset` is where the target is in the character's frame (+Z ahead, +Y up, +X its left).
    /// Move the character (or the target) so that the target's centre is at `nearest` for a real punch.
    #[signal]
    fn target_out_of_reach(offset: Vector3, nearest: Vector3);

    /// Emitted when a fist strikes something (the target, or a body on `hit_layers`), once per thing and
    /// punch (touching it again in the same punch is no new hit): `impulse` (N s) on it in that first
    /// frame, the fist's peak `speed` so far (m/s), where the fist was (`position`, global), what was hit
    /// (`body`: a CollisionObject3D, or null if it is gone), and `push`, the impulse vector (N s, global
    /// axes) for bodies that physics does not push, such as a CharacterBody3D:
    /// `enemy.velocity += push / enemy_mass_kg` knocks it back.
    #[signal]
    fn hit(impulse: f32, speed: f32, position: Vector3, body: Option<Gd<Node3D>>, push: Vector3);

    /// Emitted when a punch is over, however it ended, with `frames`, `peak_fist_speed_mps`, `hits`,
    /// `strongest_hit_ns` (the largest fist impulse of one frame), `ended` ("completed"; "interrupted":
    /// cancelled, restarted, or its policy changed before its last frame; "error": it stopped on an error,
    /// given in `error` and logged), and `interrupted` (true unless completed). Every `punch_started` is
    /// followed by one `punch_finished`, so code waiting for it never waits forever.
    #[signal]
    fn punch_finished(metrics: VarDictionary);

    /// Emitted when the character is back in its guard pose after `recover()` (or a punch with
    /// `auto_recover`), or when the recovery's time is up.
    #[signal]
    fn recovered();

    /// Starts a punch (a punch already running ends first, interrupted): at once from the guard pose, else
    /// after a return to guard (`guard_first`) or from the current pose.
    /// Returns false (with the reason in the log) when the policy, the character or the target is missing or
    /// unusable, or the project's physics settings are not the policy's. A target outside the policy's
    /// reach gets a punch at the nearest point it covers, and `target_out_of_reach`.
    #[func]
    fn punch(&mut self) -> bool {
        self.interrupt();
        match self.start() {
            Ok(out_of_reach) => {
                PunchInference::enlist(self.to_gd());
                self.signals().punch_started().emit();
                if let Some((offset, nearest)) = out_of_reach {
                    self.signals().target_out_of_reach().emit(vector3(offset), vector3(nearest));
                }
                true
            }
            Err(error) => {
                if !error.is_empty() {
                    godot_error!("PunchController '{}': {error}", self.base().get_name());
                }
                false
            }
        }
    }

    /// The target placements the policy was trained to punch, in the character's frame: `distance_m`,
    /// `height_m` and `side_m` ranges of the target's centre (Vector2(low, high); +Z ahead, +Y up, +X the
    /// character's left), `max_target_speed_mps` and `any_start_pose` (false: only from the settled guard).
    /// Targets up to 3 cm outside still count. Empty when the policy cannot be loaded.
    #[func]
    fn reach_volume(&self) -> VarDictionary {
        let mut result = VarDictionary::new();
        let reach = match self.shared_policy() {
            Ok(policy) => policy.reach,
            Err(error) => {
                if !error.is_empty() {
                    godot_error!("PunchController '{}': {error}", self.base().get_name());
                }
                return result;
            }
        };
        for (key, [low, high]) in
            [("distance_m", reach.distance_m), ("height_m", reach.height_m), ("side_m", reach.side_m)]
        {
            result.set(key, Vector2::new(low, high));
        }
        result.set("max_target_speed_mps", reach.max_target_speed_mps);
        result.set("any_start_pose", reach.any_start_pose);
        result
    }

    /// Ends the current punch (`punch_finished` reports it interrupted) or recovery; the joints then hold
    /// the pose they are in.
    #[func]
    fn cancel(&mut self) {
        self.interrupt();
        if matches!(std::mem::take(&mut self.phase), Phase::Recovering(..)) {
            self.hold();
        }
    }

    /// Drives the character back to its guard pose under physics (ending a punch that is running);
    /// `recovered` is emitted when it is there.
    #[func]
    fn recover(&mut self) {
        self.interrupt();
        match self.start_recovery() {
            Ok(()) => PunchInference::enlist(self.to_gd()),
            Err(error) => godot_error!("PunchController '{}': {error}", self.base().get_name()),
        }
    }

    /// True while a punch is running (including its return to guard first, `guard_first`).
    #[func]
    pub fn is_punching(&self) -> bool {
        matches!(self.phase, Phase::Punching(_) | Phase::Guarding(..))
    }

    /// True while the character returns to its guard pose.
    #[func]
    fn is_recovering(&self) -> bool {
        matches!(self.phase, Phase::Recovering(..))
    }

    /// The last finished punch, when `record` is on: `features` (frames x feature count, the names are
    /// the training server's), `observations` (decisions x 45), `mean_actions` and `actions` (decisions x 10,
    /// before and after noise), `frames` and `decisions`.
    #[func]
    fn last_punch_record(&self) -> VarDictionary {
        let record = &self.last_record;
        let mut result = VarDictionary::new();
        result.set("features", &PackedFloat32Array::from(record.features.as_slice()));
        result.set("observations", &PackedFloat32Array::from(record.observations.as_slice()));
        result.set("mean_actions", &PackedFloat32Array::from(record.mean_actions.as_slice()));
        result.set("actions", &PackedFloat32Array::from(record.actions.as_slice()));
        result.set("frames", (record.features.len() / FEATURE_COUNT) as i64);
        result.set("decisions", (record.observations.len() / OBS_DIM) as i64);
        result
    }

    /// Mean time (µs) all controllers together spent per physics frame (sensing, batched inference,
    /// driving) since the last call: for benchmarks.
    #[func]
    fn take_frame_cost_usec() -> f64 {
        PunchInference::singleton().bind_mut().take_frame_cost_usec()
    }

    /// How batched the inference was since the last call, over all controllers: `calls` to ONNX Runtime,
    /// the `rows` (controller decisions) they ran, and the time they took, `usec` (for benchmarks).
    #[func]
    fn take_inference_counts() -> VarDictionary {
        let (calls, rows, usec) = PunchInference::take_inference_counts();
        let mut counts = VarDictionary::new();
        counts.set("calls", calls as i64);
        counts.set("rows", rows as i64);
        counts.set("usec", usec);
        counts
    }

    /// Names of the per-frame features in `last_punch_record()`, in column order.
    #[func]
    fn feature_names() -> PackedStringArray {
        FEATURE_NAMES.iter().map(|name| GString::from(*name)).collect()
    }

    /// Where the training puts the target's centre relative to the character's root, in the character's
    /// frame (+Z ahead, +Y up, +X the character's left): place a target here for the trained punch.
    #[func]
    fn default_target_offset() -> Vector3 {
        let position = BagPlacement::DEFAULT.position();
        Vector3::new(position.x, position.y, position.z)
    }

    /// The project settings policies are trained with (setting path to value): a game needs the same.
    #[func]
    fn required_project_settings() -> VarDictionary {
        let mut settings = VarDictionary::new();
        for setting in PROJECT_SETTINGS {
            let value = match setting.value {
                SettingValue::Int(v) => v.to_variant(),
                SettingValue::Float(v) => v.to_variant(),
                SettingValue::Text(v) => v.to_variant(),
            };
            settings.set(setting.path, &value);
        }
        settings
    }

    /// The running game's settings that differ from `required_project_settings()`, one line each saying
    /// what to set (empty when all is well). The physics rate is the engine's current one.
    #[func]
    pub fn project_settings_problems() -> PackedStringArray {
        project_setting_problems(|path| {
            if path == PROJECT_SETTINGS[0].path {
                return (Some(Engine::singleton().get_physics_ticks_per_second() as f64), None);
            }
            let value = ProjectSettings::singleton().get_setting(path);
            let number = value.try_to::<f64>().ok().or_else(|| value.try_to::<i64>().ok().map(|v| v as f64));
            (number, value.try_to::<GString>().ok().map(|s| s.to_string()))
        })
        .iter()
        .map(GString::from)
        .collect()
    }

    /// Sets the policy; the next punch plays it (a punch running now ends, interrupted).
    #[func]
    fn set_policy(&mut self, policy: Option<Gd<PunchPolicy>>) {
        let changed = policy != self.policy;
        self.policy = policy;
        self.loaded = None;
        if changed {
            // After the change: a `punch_finished` handler that punches again gets the new policy.
            self.interrupt();
        }
    }

    /// Sets `noise_sigma`, clamped to 0..1 with a warning.
    #[func]
    fn set_noise_sigma(&mut self, sigma: f32) {
        let clamped = if sigma.is_finite() { sigma.clamp(0.0, 1.0) } else { 0.0 };
        if clamped != sigma {
            godot_warn!(
                "PunchController '{}': noise_sigma {sigma} is outside 0..1; using {clamped}",
                self.base().get_name()
            );
        }
        self.noise_sigma = clamped;
    }
}

impl PunchController {
    /// Starts a punch; `Some((offset, nearest))` when the target is out of reach (`target_out_of_reach`).
    fn start(&mut self) -> Result<Option<(Vec3, Vec3)>, String> {
        PunchInference::check_project_settings()?;
        if self.loaded.as_ref().is_some_and(|loaded| loaded.seed != self.seed) {
            // A new seed starts a new sequence of punches.
            self.loaded = None;
        }
        if self.loaded.is_none() {
            let policy = self.shared_policy()?;
            let noise = RuntimeNoise::new(self.seed as u64, self.noise_sigma, self.noise_decisions);
            self.loaded = Some(Loaded { policy, noise, seed: self.seed });
        }
        let loaded = self.loaded.as_ref().ok_or("no policy")?;
        loaded.policy.check_spec(self.decision_period.max(1) as u32)?;
        let mut target = Target::resolve(live(&self.target).ok_or("no target set (or it was freed)")?);
        let mut geometry = self.geometry()?;
        let offset = geometry.root_rotation.inverse() * (target.state().position - geometry.root_position);
        let reach = loaded.policy.reach;
        let out_of_reach = (!reach.contains(offset)).then(|| {
            // The policy sees the target at the nearest point it covers, and punches there.
            let nearest = geometry.root_position + geometry.root_rotation * reach.nearest(offset);
            target.aim_at(nearest);
            (offset, nearest)
        });
        target.describe(&mut geometry);
        self.aim = Some(target);
        let punch = Box::new(Punch::new(geometry, loaded.policy.spec, self.record));
        self.phase = if self.guard_first {
            // Decided at the next frame's reading: a character already in guard punches in that same frame.
            Phase::Guarding(punch, Box::new(Recovery::new(geometry)), [Vec3::ZERO; 5])
        } else {
            Phase::Punching(punch)
        };
        Ok(out_of_reach)
    }

    /// The policy resource as a checked punching policy (an empty error: refused and reported before).
    fn shared_policy(&self) -> Result<Rc<SharedPolicy>, String> {
        let mut policy = self.policy.clone().ok_or("no policy set")?;
        policy.bind_mut().punching()
    }

    /// The character's rest geometry where it stands now.
    fn geometry(&self) -> Result<CharacterGeometry, String> {
        let character = live(&self.character).ok_or("no character set (or it was freed)")?;
        let root = character.get_global_transform();
        let geometry = character.bind().rig().map(|rig| rig.geometry_at(root));
        geometry.ok_or_else(|| "the character is not ready (is it in the scene tree?)".into())
    }

    fn start_recovery(&mut self) -> Result<(), String> {
        let recovery = Recovery::new(self.geometry()?);
        self.phase = Phase::Recovering(Box::new(recovery), [Vec3::ZERO; 5]);
        Ok(())
    }

    /// Ends a running punch early: `punch_finished` (interrupted) is emitted now.
    fn interrupt(&mut self) {
        if !self.is_punching() {
            return;
        }
        let (Phase::Punching(punch) | Phase::Guarding(punch, ..)) = std::mem::take(&mut self.phase) else { return };
        let (summary, record) = punch.interrupt();
        self.last_record = record.unwrap_or_default();
        self.hold();
        self.signals().punch_finished().emit(&finish_metrics(&summary, &Ending::Interrupted));
    }

    /// Stops the joint motors: the character holds its pose.
    fn hold(&self) {
        if let Some(character) = live(&self.character)
            && let Some(rig) = character.bind().rig()
        {
            rig.drive(&[Vec3::ZERO; 5]);
        }
    }

    /// Ends the punch on an error, logging it.
    fn stop_with_error(&mut self, error: &str) {
        godot_error!("PunchController '{}': {error}; the punch stops", self.base().get_name());
        self.stop_quietly(error);
    }

    /// Ends the punch on an error already logged (once for all the controllers a shared policy failed).
    fn stop_quietly(&mut self, error: &str) {
        if let Phase::Punching(punch) | Phase::Guarding(punch, ..) = std::mem::take(&mut self.phase) {
            // Whoever waits for the end of the punch hears of it.
            self.events.push(Event::Finished(punch.interrupt().0, Ending::Error(error.to_string())));
        }
        self.hold();
        self.loaded = None;
    }

    /// True while the controller drives its character (punching or recovering).
    pub(crate) fn is_active(&self) -> bool {
        !matches!(self.phase, Phase::Idle)
    }

    /// First half of a frame: reads the frame just simulated and, when a decision is due, returns the
    /// observation to decide on (with the policy to ask). Ends the punch after its last frame.
    pub(crate) fn sense(&mut self) -> Option<DecisionRequest> {
        match self.try_sense() {
            Ok(request) => request,
            Err(error) => {
                self.stop_with_error(&error);
                None
            }
        }
    }

    fn try_sense(&mut self) -> Result<Option<DecisionRequest>, String> {
        let character = live(&self.character).ok_or("the character was freed")?;
        let character = character.bind();
        let rig = character.rig().ok_or("the character is not ready")?;
        let mut reading = FrameReading { bodies: rig.read_bodies(), ..FrameReading::default() };
        if let Phase::Recovering(recovery, commands) = &mut self.phase {
            match recovery.step(&reading) {
                Some(next) => *commands = next,
                None => {
                    self.phase = Phase::Idle;
                    rig.drive(&[Vec3::ZERO; 5]);
                    self.events.push(Event::Recovered);
                }
            }
            return Ok(None);
        }
        if let Phase::Guarding(_, recovery, commands) = &mut self.phase {
            if let Some(next) = recovery.step(&reading) {
                *commands = next;
                return Ok(None);
            }
            // In guard: the punch starts with this frame.
            if let Phase::Guarding(punch, ..) = std::mem::take(&mut self.phase) {
                self.phase = Phase::Punching(punch);
            }
        }
        let Phase::Punching(punch) = &mut self.phase else { return Ok(None) };
        let aim = self.aim.as_ref().filter(|aim| aim.is_valid()).ok_or("the target was freed")?;
        reading.bag = aim.state();
        let mut touches = Vec::new();
        if let Some(state) = aim.reported_contacts() {
            add_bag_contacts(state, &rig.body_rids, &mut reading);
        }
        let (target_rid, reports) = (aim.body_rid(), aim.reported_contacts().is_some());
        read_forearm_contacts(&rig.forearm_states, target_rid, reports, self.hit_layers, &mut reading, &mut touches);
        if self.hit_areas || aim.area().is_some() {
            let mask = self.hit_layers | aim.area().map_or(0, |area| area.get_collision_layer());
            let [right, left] = punch.fists(&reading);
            let fists = [(Body::ForearmR.index(), right.0), (Body::ForearmL.index(), left.0)];
            let query = self.area_query.get_or_insert_with(|| fist_query(rig.geometry.fist_radius_m));
            if let Some(mut space) = character.base().get_world_3d().and_then(|w| w.get_direct_space_state()) {
                add_area_touches(&mut space, query, fists, mask, &mut touches);
            }
        }
        let (hits, sensed) = punch.sense(reading, &touches);
        self.events.extend(hits.into_iter().map(Event::Hit));
        match sensed {
            Sensed::Hold => Ok(None),
            Sensed::Decide(observation) => {
                let policy = self.loaded.as_ref().ok_or("no policy")?.policy.clone();
                Ok(Some((policy, *observation)))
            }
            Sensed::Finished(summary, record) => {
                self.events.push(Event::Finished(summary, Ending::Completed));
                self.last_record = record.unwrap_or_default();
                self.phase = Phase::Idle;
                if self.auto_recover {
                    let geometry = rig.geometry_at(character.base().get_global_transform());
                    let mut recovery = Recovery::new(geometry);
                    if let Some(commands) = recovery.step(&reading) {
                        self.phase = Phase::Recovering(Box::new(recovery), commands);
                    }
                }
                Ok(None)
            }
        }
    }

    /// Second half of a frame: takes the decision's mean action (when one was due), adds the noise, and
    /// drives the joints. A failed decision (`mean` an error, logged by the batch) ends the punch.
    pub(crate) fn act(&mut self, mean: Option<Result<Vec<f32>, String>>) {
        match mean {
            Some(Err(error)) => self.stop_quietly(&error),
            mean => {
                if let Err(error) = self.try_act(mean.and_then(Result::ok)) {
                    self.stop_with_error(&error);
                }
            }
        }
    }

    fn try_act(&mut self, mean: Option<Vec<f32>>) -> Result<(), String> {
        let commands = match &mut self.phase {
            Phase::Idle => return Ok(()),
            Phase::Recovering(_, commands) | Phase::Guarding(_, _, commands) => *commands,
            Phase::Punching(punch) => {
                let loaded = self.loaded.as_mut().ok_or("no policy")?;
                // The inspector may change these at any time: they apply from the next decision.
                loaded.noise.sigma = self.noise_sigma;
                loaded.noise.noisy_decisions = self.noise_decisions;
                punch.act(mean.as_deref(), &mut loaded.noise).map_err(|e| e.to_string())?
            }
        };
        let character = live(&self.character).ok_or("the character was freed")?;
        if let Some(rig) = character.bind().rig() {
            rig.drive(&commands);
        }
        Ok(())
    }

    /// Emits the signals a frame produced (called with no borrow of the controller held), including any
    /// that its handlers cause.
    pub(crate) fn emit_events(controller: &mut Gd<Self>) {
        loop {
            let events = std::mem::take(&mut controller.bind_mut().events);
            if events.is_empty() {
                return;
            }
            for event in events {
                match event {
                    Event::Hit(hit) => {
                        let body = Gd::<Node3D>::try_from_instance_id(InstanceId::from_i64(hit.collider as i64)).ok();
                        let push = Vector3::new(hit.impulse.x, hit.impulse.y, hit.impulse.z);
                        let position = Vector3::new(hit.position.x, hit.position.y, hit.position.z);
                        controller.signals().hit().emit(hit.impulse_ns(), hit.speed_mps, position, body.as_ref(), push);
                    }
                    Event::Finished(summary, ending) => {
                        controller.signals().punch_finished().emit(&finish_metrics(&summary, &ending))
                    }
                    Event::Recovered => controller.signals().recovered().emit(),
                }
            }
        }
    }
}

/// The node if it is set and not freed (cloning a freed node's handle would panic).
fn live<T: GodotClass>(node: &Option<Gd<T>>) -> Option<Gd<T>> {
    node.as_ref().filter(|n| n.is_instance_valid()).cloned()
}

/// A sphere query of the fist's size for overlapping areas.
fn fist_query(radius_m: f32) -> Gd<PhysicsShapeQueryParameters3D> {
    let mut sphere = SphereShape3D::new_gd();
    sphere.set_radius(radius_m);
    let mut query = PhysicsShapeQueryParameters3D::new_gd();
    query.set_shape(&sphere);
    query.set_collide_with_areas(true);
    query.set_collide_with_bodies(false);
    query
}

fn finish_metrics(summary: &PunchSummary, ending: &Ending) -> VarDictionary {
    let mut metrics = VarDictionary::new();
    let (ended, error) = match ending {
        Ending::Completed => ("completed", ""),
        Ending::Interrupted => ("interrupted", ""),
        Ending::Error(error) => ("error", error.as_str()),
    };
    metrics.set("ended", ended);
    if !error.is_empty() {
        metrics.set("error", error);
    }
    metrics.set("frames", summary.frames as i64);
    metrics.set("peak_fist_speed_mps", summary.peak_fist_speed_mps);
    metrics.set("hits", summary.hits);
    metrics.set("strongest_hit_ns", summary.strongest_hit_ns);
    metrics.set("interrupted", summary.interrupted);
    metrics
}
