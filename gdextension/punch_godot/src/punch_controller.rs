//! `PunchController`: plays a trained punching policy on a `PunchCharacter` in a game. The punch itself
//! (decision clock, observation, runtime noise, smoothing, motor law, hits, its end) is `punch_core::punch`;
//! this class moves engine readings in and motor commands and signals out, and `PunchInference` batches the
//! policy calls of every controller.

use std::rc::Rc;

use godot::builtin::{GString, PackedFloat32Array, PackedStringArray, VarDictionary, Vector3};
use godot::classes::{CylinderShape3D, INode, Node, Node3D, PhysicsServer3D, RigidBody3D};
use godot::global::{godot_error, godot_warn};
use godot::obj::{Base, Gd, Singleton, WithBaseField, WithUserSignals};
use godot::prelude::{GodotClass, godot_api};
use punch_core::character::DEFAULT_DECISION_PERIOD;
use punch_core::observation::OBS_DIM;
use punch_core::punch::{Hit, Punch, PunchRecord, PunchSummary, RuntimeNoise, Sensed};
use punch_core::sensing::{BodyState, FEATURE_COUNT, FEATURE_NAMES, FrameReading};
use punch_core::spec::BagPlacement;

use crate::batch::{DecisionRequest, PunchInference, SharedPolicy};
use crate::convert::{quat, vec3};
use crate::engine_io::add_bag_contacts;
use crate::punch_character::PunchCharacter;

/// Makes a `PunchCharacter` punch a target with a trained policy (an .onnx file made by `punch train`).
/// Each punch differs when `noise_sigma` > 0: Gaussian noise of that standard deviation is added to the
/// policy's mean action at every decision (or at the first `noise_decisions` only). All controllers that
/// play the same policy file share one model and run in one inference call per decision tick.
#[derive(GodotClass)]
#[class(base = Node, init)]
pub struct PunchController {
    /// The policy: an .onnx file from `punch train`, read through Godot's file system (works in exported games).
    #[export(file = "*.onnx")]
    #[var(set = set_policy)]
    policy: GString,
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
    /// What to punch: any Node3D. A RigidBody3D target (such as the sandbag's `Bag`) also reports hits.
    #[export]
    target: Option<Gd<Node3D>>,
    /// Seed of the noise: the same seed and sigma give the same sequence of punches.
    #[export]
    seed: i64,
    /// Punch as soon as the scene starts.
    #[export]
    autostart: bool,
    /// Keep each punch's per-frame features, observations and actions for `last_punch_record()`
    /// (for analysis tools such as `punch replay`; leave it off in games).
    #[export]
    record: bool,

    state: Option<Punch>,
    loaded: Option<Loaded>,
    events: Vec<Event>,
    last_record: PunchRecord,
    base: Base<Node>,
}

struct Loaded {
    policy: Rc<SharedPolicy>,
    noise: RuntimeNoise,
}

enum Event {
    Hit(Hit),
    Finished(PunchSummary),
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

    /// Emitted when a fist starts touching the target: the contact impulse (N s), the fist's peak speed
    /// so far (m/s), and where the fist was (global position).
    #[signal]
    fn hit(impulse: f32, speed: f32, position: Vector3);

    /// Emitted when a punch is over, with `frames`, `peak_fist_speed_mps`, `hits` and `strongest_hit_ns`.
    #[signal]
    fn punch_finished(metrics: VarDictionary);

    /// Starts a punch from the character's current pose. Returns false (with the reason in the log) when the
    /// policy, the character or the target is missing or unusable.
    #[func]
    fn punch(&mut self) -> bool {
        match self.start() {
            Ok(()) => {
                PunchInference::enlist(self.to_gd());
                self.signals().punch_started().emit();
                true
            }
            Err(error) => {
                godot_error!("PunchController '{}': {error}", self.base().get_name());
                self.loaded = None;
                false
            }
        }
    }

    /// Stops the current punch, if any.
    #[func]
    fn reset(&mut self) {
        self.state = None;
    }

    /// True while a punch is running.
    #[func]
    pub fn is_punching(&self) -> bool {
        self.state.is_some()
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

    /// Sets the policy file; the next punch loads it.
    #[func]
    fn set_policy(&mut self, policy: GString) {
        self.policy = policy;
        self.loaded = None;
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
    fn start(&mut self) -> Result<(), String> {
        if self.loaded.is_none() {
            let policy = PunchInference::policy(&self.policy)?;
            let noise = RuntimeNoise::new(self.seed as u64, self.noise_sigma, self.noise_decisions);
            self.loaded = Some(Loaded { policy, noise });
        }
        let loaded = self.loaded.as_ref().ok_or("no policy")?;
        loaded.policy.check_spec(self.decision_period.max(1) as u32)?;
        let character = live(&self.character).ok_or("no character set (or it was freed)")?;
        let target = live(&self.target).ok_or("no target set (or it was freed)")?;
        let root = character.get_global_transform();
        let mut geometry =
            character.bind().rig().map(|rig| rig.geometry_at(root)).ok_or("the character is not ready")?;
        if let Ok(body) = target.clone().try_cast::<RigidBody3D>() {
            geometry.bag_mass_kg = body.get_mass();
            if let Some((radius, height)) = cylinder_of(&body) {
                geometry.bag_radius_m = radius;
                geometry.bag_height_m = height;
            }
        }
        self.state = Some(Punch::new(geometry, loaded.policy.spec, self.record));
        Ok(())
    }

    fn stop_with_error(&mut self, error: &str) {
        godot_error!("PunchController '{}': {error}; the punch stops", self.base().get_name());
        self.state = None;
        self.loaded = None;
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
        let target = live(&self.target).ok_or("the target was freed")?;
        let reading = read(&character, &target)?;
        let (Some(punch), Some(loaded)) = (self.state.as_mut(), self.loaded.as_ref()) else { return Ok(None) };
        let (hit, sensed) = punch.sense(reading);
        self.events.extend(hit.map(Event::Hit));
        match sensed {
            Sensed::Hold => Ok(None),
            Sensed::Decide(observation) => Ok(Some((loaded.policy.clone(), *observation))),
            Sensed::Finished(summary, record) => {
                self.state = None;
                self.events.push(Event::Finished(summary));
                self.last_record = record.unwrap_or_default();
                Ok(None)
            }
        }
    }

    /// Second half of a frame: takes the decision's mean action (when one was due), adds the noise, and
    /// drives the joints.
    pub(crate) fn act(&mut self, mean: Option<Result<Vec<f32>, String>>) {
        if let Err(error) = self.try_act(mean) {
            self.stop_with_error(&error);
        }
    }

    fn try_act(&mut self, mean: Option<Result<Vec<f32>, String>>) -> Result<(), String> {
        if self.state.is_none() {
            return Ok(());
        }
        let character = live(&self.character).ok_or("the character was freed")?;
        let (Some(punch), Some(loaded)) = (self.state.as_mut(), self.loaded.as_mut()) else { return Ok(()) };
        // The inspector may change these at any time: they apply from the next decision.
        loaded.noise.sigma = self.noise_sigma;
        loaded.noise.noisy_decisions = self.noise_decisions;
        let mean = mean.transpose()?;
        let commands = punch.act(mean.as_deref(), &mut loaded.noise).map_err(|e| e.to_string())?;
        if let Some(rig) = character.bind().rig() {
            rig.drive(&commands);
        }
        Ok(())
    }

    /// Emits the signals a frame produced (called with no borrow of the controller held).
    pub(crate) fn emit_events(controller: &mut Gd<Self>) {
        let events = std::mem::take(&mut controller.bind_mut().events);
        for event in events {
            match event {
                Event::Hit(hit) => controller.signals().hit().emit(
                    hit.impulse_ns,
                    hit.speed_mps,
                    Vector3::new(hit.position.x, hit.position.y, hit.position.z),
                ),
                Event::Finished(summary) => controller.signals().punch_finished().emit(&finish_metrics(&summary)),
            }
        }
    }
}

/// The node if it is set and not freed (cloning a freed node's handle would panic).
fn live<T: GodotClass>(node: &Option<Gd<T>>) -> Option<Gd<T>> {
    node.as_ref().filter(|n| n.is_instance_valid()).cloned()
}

/// Reads the character and the target into the core's frame reading.
fn read(character: &Gd<PunchCharacter>, target: &Gd<Node3D>) -> Result<FrameReading, String> {
    let character = character.bind();
    let rig = character.rig().ok_or("the character is not ready")?;
    let mut reading = FrameReading { bodies: rig.read_bodies(), ..FrameReading::default() };
    let transform = target.get_global_transform();
    reading.bag = BodyState {
        position: vec3(transform.origin),
        rotation: quat(transform.basis.get_quaternion()),
        ..BodyState::default()
    };
    if let Ok(body) = target.clone().try_cast::<RigidBody3D>() {
        reading.bag.linear_velocity = vec3(body.get_linear_velocity());
        reading.bag.angular_velocity = vec3(body.get_angular_velocity());
        if let Some(state) = PhysicsServer3D::singleton().body_get_direct_state(body.get_rid()) {
            add_bag_contacts(&state, &rig.body_rids, &mut reading);
        }
    }
    Ok(reading)
}

fn finish_metrics(summary: &PunchSummary) -> VarDictionary {
    let mut metrics = VarDictionary::new();
    metrics.set("frames", summary.frames as i64);
    metrics.set("peak_fist_speed_mps", summary.peak_fist_speed_mps);
    metrics.set("hits", summary.hits);
    metrics.set("strongest_hit_ns", summary.strongest_hit_ns);
    metrics
}

fn cylinder_of(body: &Gd<RigidBody3D>) -> Option<(f32, f32)> {
    let owner = *body.get_shape_owners().as_slice().first()? as u32;
    let cylinder = body.shape_owner_get_shape(owner, 0)?.try_cast::<CylinderShape3D>().ok()?;
    Some((cylinder.get_radius(), cylinder.get_height()))
}
