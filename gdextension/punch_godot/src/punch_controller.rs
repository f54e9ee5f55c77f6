//! `PunchController`: plays a trained punching policy on a `PunchCharacter` in a game. Every decision it
//! builds the observation, runs the ONNX policy, adds the designer's noise to the mean action, and hands
//! the action to the same controller code (smoothing, targets, motor law) the training server runs.

use std::rc::Rc;

use godot::builtin::{GString, PackedFloat32Array, PackedStringArray, VarDictionary, Vector3};
use godot::classes::{CylinderShape3D, INode, Node, Node3D, PhysicsServer3D, RigidBody3D};
use godot::global::{godot_error, godot_warn};
use godot::obj::{Base, Gd, Singleton, WithBaseField, WithUserSignals};
use godot::prelude::{GodotClass, godot_api};
use punch_core::character::{Body, DEFAULT_DECISION_PERIOD};
use punch_core::controller::CharacterController;
use punch_core::noise::GaussianNoise;
use punch_core::observation::{OBS_DIM, observation};
use punch_core::sensing::{BodyState, FEATURE_COUNT, FEATURE_NAMES, FrameReading, columns, feature_vector};

use crate::batch::{self, SharedPolicy};
use crate::convert::{quat, vec3};
use crate::engine_io::add_bag_contacts;
use crate::punch_character::PunchCharacter;

/// Impulse (N s) on the target above which a fist counts as hitting it.
const HIT_IMPULSE_NS: f32 = 0.05;

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

    state: Option<Running>,
    loaded: Option<Loaded>,
    events: Vec<Event>,
    last_record: Record,
    base: Base<Node>,
}

struct Loaded {
    policy: Rc<SharedPolicy>,
    noise: GaussianNoise,
}

struct Running {
    controller: CharacterController,
    fist_offsets: [glam::Vec3; 2],
    frame: usize,
    /// Frames of this punch (from the policy).
    frames: usize,
    /// The current frame's reading, kept from sensing to acting.
    reading: FrameReading,
    touching: bool,
    peak_speed_mps: f32,
    hits: i64,
    strongest_hit_ns: f32,
    record: Option<Record>,
}

/// What a punch did, frame by frame (see `record`).
#[derive(Default)]
struct Record {
    features: Vec<f32>,
    observations: Vec<f32>,
    mean_actions: Vec<f32>,
    actions: Vec<f32>,
}

enum Event {
    Hit { impulse_ns: f32, speed_mps: f32, position: Vector3 },
    Finished(VarDictionary),
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
                batch::enlist(self.to_gd());
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
        batch::take_frame_cost_usec()
    }

    /// How batched the inference was since the last call, over all controllers: `calls` to ONNX Runtime,
    /// the `rows` (controller decisions) they ran, and the time they took, `usec` (for benchmarks).
    #[func]
    fn take_inference_counts() -> VarDictionary {
        let (calls, rows, usec) = batch::take_inference_counts();
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

    #[func]
    fn set_policy(&mut self, policy: GString) {
        self.policy = policy;
        self.loaded = None;
    }

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
            let policy = SharedPolicy::get(&self.policy)?;
            self.loaded = Some(Loaded { policy, noise: GaussianNoise::new(self.seed as u64) });
        }
        let loaded = self.loaded.as_ref().ok_or("no policy")?;
        loaded.policy.check_spec(self.decision_period.max(1) as u32)?;
        let character = live(&self.character).ok_or("no character set (or it was freed)")?;
        let target = live(&self.target).ok_or("no target set (or it was freed)")?;
        let mut geometry = character.bind().rig().map(|rig| rig.geometry).ok_or("the character is not ready")?;
        if let Ok(body) = target.clone().try_cast::<RigidBody3D>() {
            geometry.bag_mass_kg = body.get_mass();
            if let Some((radius, height)) = cylinder_of(&body) {
                geometry.bag_radius_m = radius;
                geometry.bag_height_m = height;
            }
        }
        let root = character.get_global_transform();
        geometry.root_rotation = quat(root.basis.get_quaternion());
        geometry.root_position = vec3(root.origin);
        self.state = Some(Running {
            controller: CharacterController::new(geometry, loaded.policy.smoothing_window),
            fist_offsets: geometry.fist_offsets,
            frame: 0,
            frames: loaded.policy.frames,
            reading: FrameReading::default(),
            touching: false,
            peak_speed_mps: 0.0,
            hits: 0,
            strongest_hit_ns: 0.0,
            record: self.record.then(Record::default),
        });
        Ok(())
    }

    fn stop_with_error(&mut self, error: &str) {
        godot_error!("PunchController '{}': {error}; the punch stops", self.base().get_name());
        self.state = None;
        self.loaded = None;
    }

    /// First half of a frame: reads the frame just simulated and, when a decision is due, returns the
    /// observation to decide on (with the policy to ask). Ends the punch after its last frame.
    pub(crate) fn sense(&mut self) -> Option<(Rc<SharedPolicy>, [f32; OBS_DIM])> {
        match self.try_sense() {
            Ok(request) => request,
            Err(error) => {
                self.stop_with_error(&error);
                None
            }
        }
    }

    fn try_sense(&mut self) -> Result<Option<(Rc<SharedPolicy>, [f32; OBS_DIM])>, String> {
        let character = live(&self.character).ok_or("the character was freed")?;
        let target = live(&self.target).ok_or("the target was freed")?;
        let reading = read(&character, &target)?;
        let period = self.decision_period.max(1) as usize;
        let (Some(state), Some(loaded)) = (self.state.as_mut(), self.loaded.as_ref()) else { return Ok(None) };
        let features = state.controller.features(&reading);
        if let Some(hit) = track_hits(state, &features, &reading) {
            self.events.push(hit);
        }
        if let Some(record) = state.record.as_mut().filter(|_| state.frame > 0) {
            record.features.extend_from_slice(&features);
        }
        state.reading = reading;
        if state.frame >= state.frames {
            let mut finished = self.state.take().expect("checked above");
            self.events.push(Event::Finished(finish_metrics(&finished)));
            self.last_record = finished.record.take().unwrap_or_default();
            return Ok(None);
        }
        if state.frame % period != 0 {
            return Ok(None);
        }
        let decision = (state.frame / period) as u32;
        let observation = observation(&features, decision, (state.frames / period) as u32);
        if let Some(record) = state.record.as_mut() {
            record.observations.extend_from_slice(&observation);
        }
        Ok(Some((loaded.policy.clone(), observation)))
    }

    /// Second half of a frame: takes the decision's mean action (when one was due), adds the noise, and
    /// drives the joints.
    pub(crate) fn act(&mut self, mean: Option<Result<Vec<f32>, String>>) {
        if let Err(error) = self.try_act(mean) {
            self.stop_with_error(&error);
        }
    }

    fn try_act(&mut self, mean: Option<Result<Vec<f32>, String>>) -> Result<(), String> {
        let (sigma, noisy_decisions, period) = (self.noise_sigma, self.noise_decisions, self.decision_period.max(1));
        if self.state.is_none() {
            return Ok(());
        }
        let character = live(&self.character).ok_or("the character was freed")?;
        let (Some(state), Some(loaded)) = (self.state.as_mut(), self.loaded.as_mut()) else { return Ok(()) };
        if let Some(mean) = mean {
            let mean = mean?;
            if mean.iter().any(|v| !v.is_finite()) {
                return Err("the policy returned NaN or infinite actions".into());
            }
            let decision = state.frame as i32 / period;
            let noisy = noisy_decisions < 0 || decision < noisy_decisions;
            let action: Vec<f32> = mean
                .iter()
                .map(|m| if noisy && sigma > 0.0 { m + sigma * loaded.noise.sample() } else { *m })
                .collect();
            state.controller.set_action(&action).map_err(|e| e.to_string())?;
            if let Some(record) = state.record.as_mut() {
                record.mean_actions.extend_from_slice(&mean);
                record.actions.extend_from_slice(&action);
            }
        }
        let commands = state.controller.motor_commands(&state.reading);
        state.frame += 1;
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
                Event::Hit { impulse_ns, speed_mps, position } => {
                    controller.signals().hit().emit(impulse_ns, speed_mps, position)
                }
                Event::Finished(metrics) => controller.signals().punch_finished().emit(&metrics),
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

/// Updates the punch's statistics; returns a hit when a fist starts touching the target this frame.
fn track_hits(state: &mut Running, features: &[f32; FEATURE_COUNT], reading: &FrameReading) -> Option<Event> {
    let length = |column: usize| feature_vector(features, column).length();
    let speeds = [length(columns::FIST_R_VEL), length(columns::FIST_L_VEL)];
    let impulses = [length(columns::FIST_R_IMPULSE), length(columns::FIST_L_IMPULSE)];
    let previous_peak = state.peak_speed_mps;
    state.peak_speed_mps = state.peak_speed_mps.max(speeds[0]).max(speeds[1]);
    let side = if impulses[0] >= impulses[1] { 0 } else { 1 };
    let touching = impulses[side] > HIT_IMPULSE_NS;
    let started = touching && !state.touching;
    state.touching = touching;
    if !started {
        return None;
    }
    state.hits += 1;
    state.strongest_hit_ns = state.strongest_hit_ns.max(impulses[side]);
    let forearm = &reading.bodies[[Body::ForearmR, Body::ForearmL][side].index()];
    let fist = forearm.position + forearm.rotation * state.fist_offsets[side];
    Some(Event::Hit {
        impulse_ns: impulses[side],
        speed_mps: previous_peak.max(speeds[side]),
        position: Vector3::new(fist.x, fist.y, fist.z),
    })
}

fn finish_metrics(state: &Running) -> VarDictionary {
    let mut metrics = VarDictionary::new();
    metrics.set("frames", state.frame as i64);
    metrics.set("peak_fist_speed_mps", state.peak_speed_mps);
    metrics.set("hits", state.hits);
    metrics.set("strongest_hit_ns", state.strongest_hit_ns);
    metrics
}

fn cylinder_of(body: &Gd<RigidBody3D>) -> Option<(f32, f32)> {
    let owner = *body.get_shape_owners().as_slice().first()? as u32;
    let cylinder = body.shape_owner_get_shape(owner, 0)?.try_cast::<CylinderShape3D>().ok()?;
    Some((cylinder.get_radius(), cylinder.get_height()))
}
