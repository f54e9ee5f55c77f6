//! `PunchController`: plays a trained punching policy on a `PunchCharacter` in a game. Every decision it
//! builds the observation, runs the ONNX policy, adds the designer's noise to the mean action, and hands
//! the action to the same controller code (smoothing, targets, motor law) the training server runs.

use godot::builtin::{GString, VarDictionary, Vector3};
use godot::classes::{CylinderShape3D, FileAccess, INode, Node, Node3D, PhysicsServer3D, RigidBody3D};
use godot::global::godot_error;
use godot::obj::{Base, Gd, Singleton, WithBaseField, WithUserSignals};
use godot::prelude::{GodotClass, godot_api};
use punch_core::Policy;
use punch_core::character::DEFAULT_DECISION_PERIOD;
use punch_core::controller::CharacterController;
use punch_core::noise::GaussianNoise;
use punch_core::observation::{OBS_DIM, observation, spec_hash};
use punch_core::sensing::{BodyState, FEATURE_COUNT, FrameReading, columns, feature_vector};

use crate::convert::{quat, vec3};
use crate::engine_io::add_bag_contacts;
use crate::punch_character::PunchCharacter;
use crate::punch_runtime::ensure_onnx_runtime;

/// Impulse (N s) on the target above which a fist counts as hitting it.
const HIT_IMPULSE_NS: f32 = 0.05;

/// Makes a `PunchCharacter` punch a target with a trained policy (an .onnx file made by `punch train`).
/// Each punch differs when `noise_sigma` > 0: Gaussian noise of that standard deviation is added to the
/// policy's mean action at every decision (or at the first `noise_decisions` only).
#[derive(GodotClass)]
#[class(base = Node, init)]
pub struct PunchController {
    /// The policy: an .onnx file from `punch train`, read through Godot's file system (works in exported games).
    #[export(file = "*.onnx")]
    policy: GString,
    /// Standard deviation of the noise added to the policy's mean action, in action units (actions lie in [-1, 1]).
    #[export(range = (0.0, 1.0, 0.01))]
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

    state: Option<Running>,
    loaded: Option<Loaded>,
    base: Base<Node>,
}

struct Loaded {
    policy: Policy,
    smoothing_window: usize,
    frames: usize,
    noise: GaussianNoise,
}

struct Running {
    controller: CharacterController,
    frame: usize,
    touching: bool,
    peak_speed_mps: f32,
    hits: i64,
    strongest_hit_ns: f32,
}

#[godot_api]
impl INode for PunchController {
    fn ready(&mut self) {
        if self.autostart {
            self.base_mut().call_deferred("punch", &[]);
        }
    }

    fn physics_process(&mut self, _delta: f64) {
        if self.state.is_some() {
            if let Err(error) = self.frame() {
                godot_error!("PunchController: {error}; the controller stops");
                self.state = None;
                self.loaded = None;
            }
        }
    }
}

#[godot_api]
impl PunchController {
    /// Emitted when a punch begins.
    #[signal]
    fn punch_started();

    /// Emitted when a fist starts touching the target: the contact impulse (N s), the fist's speed just
    /// before (m/s), and where the fist was (global position).
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
                self.signals().punch_started().emit();
                true
            }
            Err(error) => {
                godot_error!("PunchController: {error}");
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
    fn is_punching(&self) -> bool {
        self.state.is_some()
    }
}

impl PunchController {
    fn load(&mut self) -> Result<(), String> {
        if self.loaded.is_some() {
            return Ok(());
        }
        if !ensure_onnx_runtime() {
            return Err("ONNX Runtime could not be loaded (see the error above)".into());
        }
        if !FileAccess::file_exists(&self.policy) {
            return Err(format!("policy file not found: '{}'", self.policy));
        }
        let bytes = FileAccess::get_file_as_bytes(&self.policy);
        let policy = Policy::from_bytes(bytes.as_slice()).map_err(|e| format!("policy '{}': {e}", self.policy))?;
        let expected = spec_hash(self.decision_period.max(1) as u32);
        let found = policy.metadata("punch_spec_hash").unwrap_or_default();
        if found != expected {
            return Err(format!(
                "policy '{}' was trained for spec {found:?}, this character and decision period need {expected}",
                self.policy
            ));
        }
        if policy.input_width() != OBS_DIM {
            return Err(format!(
                "policy '{}' takes {} inputs, the observation has {OBS_DIM}",
                self.policy,
                policy.input_width()
            ));
        }
        let number = |key: &str, default: usize| policy.metadata(key).and_then(|v| v.parse().ok()).unwrap_or(default);
        let smoothing_window = number("punch_smoothing_window", 1);
        let frames = number("punch_frames", 50);
        self.loaded = Some(Loaded { policy, smoothing_window, frames, noise: GaussianNoise::new(self.seed as u64) });
        Ok(())
    }

    fn start(&mut self) -> Result<(), String> {
        self.load()?;
        let character = self.character.clone().ok_or("no character set")?;
        let target = self.target.clone().ok_or("no target set")?;
        if !target.is_instance_valid() {
            return Err("the target was freed".into());
        }
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
        let window = self.loaded.as_ref().map_or(1, |l| l.smoothing_window);
        self.state = Some(Running {
            controller: CharacterController::new(geometry, window),
            frame: 0,
            touching: false,
            peak_speed_mps: 0.0,
            hits: 0,
            strongest_hit_ns: 0.0,
        });
        Ok(())
    }

    /// One physics frame of a punch: sense the frame just simulated, decide when a decision is due, drive.
    fn frame(&mut self) -> Result<(), String> {
        let character = self.character.clone().filter(|c| c.is_instance_valid()).ok_or("the character was freed")?;
        let target = self.target.clone().filter(|t| t.is_instance_valid()).ok_or("the target was freed")?;
        let reading = read(&character, &target)?;
        let period = self.decision_period.max(1) as usize;
        let (sigma, noisy_decisions) = (self.noise_sigma.clamp(0.0, 1.0), self.noise_decisions);
        let (Some(state), Some(loaded)) = (self.state.as_mut(), self.loaded.as_mut()) else { return Ok(()) };
        let features = state.controller.features(&reading);
        let hit = track_hits(state, &features, &reading);
        let total_frames = loaded.frames;
        if state.frame >= total_frames {
            let metrics = finish_metrics(state);
            self.state = None;
            self.signals().punch_finished().emit(&metrics);
            return Ok(());
        }
        if state.frame % period == 0 {
            let decision = state.frame / period;
            let obs = observation(&features, decision as u32, (total_frames / period) as u32);
            let outputs = loaded.policy.run(&obs, 1).map_err(|e| e.to_string())?;
            let mean = outputs.first().ok_or("the policy has no output")?;
            if mean.data.iter().any(|v| !v.is_finite()) {
                return Err("the policy returned NaN".into());
            }
            let noisy = noisy_decisions < 0 || (decision as i32) < noisy_decisions;
            let action: Vec<f32> =
                mean.data.iter().map(|m| if noisy { m + sigma * loaded.noise.sample() } else { *m }).collect();
            state.controller.set_action(&action).map_err(|e| e.to_string())?;
        }
        let commands = state.controller.motor_commands(&reading);
        state.frame += 1;
        if let Some(rig) = character.bind().rig() {
            rig.drive(&commands);
        }
        if let Some((impulse, speed, position)) = hit {
            self.signals().hit().emit(impulse, speed, position);
        }
        Ok(())
    }
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
fn track_hits(
    state: &mut Running,
    features: &[f32; FEATURE_COUNT],
    reading: &FrameReading,
) -> Option<(f32, f32, Vector3)> {
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
    let forearm =
        &reading.bodies[[punch_core::character::Body::ForearmR, punch_core::character::Body::ForearmL][side].index()];
    let position = forearm.position;
    Some((impulses[side], previous_peak.max(speeds[side]), Vector3::new(position.x, position.y, position.z)))
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
