//! The policy contract: everything the trainer, a policy file and the game must agree on, defined once.
//!
//! - Sizes and names: the observation (`OBS_DIM`, `observation_names`), the action (`DOF_COUNT`, `DOFS`), the
//!   per-frame features (`FEATURE_NAMES`), and the spec version and hash that name their layout.
//! - Timing: the physics rate (`PHYSICS_HZ`), the decision period, the frames of one punch, and the smoothing
//!   window of the actions (`PolicySpec`).
//! - The default episode conditions (`EpisodeConditions::DEFAULT`: where the target hangs) and the reach
//!   volume a policy covers (`REACH_VOLUME`, `ReachVolume`).
//!
//! The training server's handshake (`handshake_fields`) and its reset replies (`PolicySpec::metadata`) are
//! generated here; the trainer copies the reset's metadata into every policy file it writes, and
//! `PunchController` reads it back with `PolicySpec::from_metadata`, which refuses a policy that lacks a key.

use glam::Vec3;
use serde_json::{Map, Value, json};

use crate::contract::arm_size::ArmScale;
use crate::contract::character::action_from_targets;
use crate::contract::mirror;
use crate::contract::motion::BodyMotion;
use crate::contract::stance::{LEAD_REACH_FORWARD_M, Load, Stance};

pub use crate::contract::character::{DEFAULT_DECISION_PERIOD, DOF_COUNT, DOFS, PHYSICS_HZ};
pub use crate::contract::observation::{OBS_DIM, OBS_SPEC_VERSION, observation_names, spec_hash};
pub use crate::contract::sensing::{FEATURE_COUNT, FEATURE_NAMES};

/// Physics frames of one punch unless a reset says otherwise (the paper's 50: 0.42 s at 120 Hz).
pub const DEFAULT_FRAMES: u32 = 50;
/// A policy's input: the observation, float32 [batch, OBS_DIM].
pub const POLICY_INPUT: &str = "obs";
/// A policy's outputs in order, float32 [batch, DOF_COUNT] each: the mean action, then (optional, unused in a
/// game) the training sigma.
pub const POLICY_OUTPUTS: [&str; 2] = ["mean", "sigma"];
/// Longest episode, frames.
pub const MAX_FRAMES: u32 = 10_000;
/// Largest decision period, frames.
pub const MAX_DECISION_PERIOD: u32 = 60;
/// Largest smoothing window, actions (1 turns smoothing off).
pub const MAX_SMOOTHING_WINDOW: u32 = 50;

/// The conditions of one episode (one punch in training or evaluation): where the target (the bag) hangs, in
/// the character's frame: `distance_m` ahead (+Z), `height_m` of its centre of mass above the ground, `side_m`
/// to the character's left (+X); how fast it moves when the episode starts (`velocity_side_mps` along +X,
/// `velocity_forward_mps` along +Z: a bag still swinging, or, with `glides`, a bag whose rope is carried at
/// that velocity, as a target that walks); how the character's own root moves through the episode (`body`,
/// in training: walking, turning, a lunge); with `rides`, a bag carried along with it; and how the character's
/// arms are sized (`arms`, in training: the range of rigs `PunchCharacter.size_arms` accepts). On the wire it
/// is a reset's `bags` entry and the handshake's `default_bag` (docs/protocol.md; the names there are
/// unchanged).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EpisodeConditions {
    pub distance_m: f32,
    pub height_m: f32,
    pub side_m: f32,
    pub velocity_side_mps: f32,
    pub velocity_forward_mps: f32,
    /// The bag's rope is carried at the bag's velocity (it translates, not swings).
    pub glides: bool,
    /// The bag's rope is carried with the character's root, as if both were moved by one node: the bag stays
    /// where it is relative to the character however the body walks, turns, lunges or bobs.
    pub rides: bool,
    pub body: BodyMotion,
    pub arms: ArmScale,
}

impl EpisodeConditions {
    /// The conditions every policy is trained at unless told otherwise (a bag at rest, the body still, the
    /// addon's arms).
    pub const DEFAULT: Self = Self::at(0.72, 1.35, 0.0);

    /// A bag at rest at a place, the character standing still.
    pub const fn at(distance_m: f32, height_m: f32, side_m: f32) -> Self {
        Self {
            distance_m,
            height_m,
            side_m,
            velocity_side_mps: 0.0,
            velocity_forward_mps: 0.0,
            glides: false,
            rides: false,
            body: BodyMotion { side_mps: 0.0, forward_mps: 0.0, turn_rad_s: 0.0, lunge_m: 0.0, bob_m: 0.0 },
            arms: ArmScale::IDENTITY,
        }
    }

    /// Centre of mass of the bag in the character's frame.
    pub fn position(&self) -> Vec3 {
        Vec3::new(self.side_m, self.height_m, self.distance_m)
    }

    /// Velocity of the bag at the start, in the character's frame.
    pub fn velocity(&self) -> Vec3 {
        Vec3::new(self.velocity_side_mps, 0.0, self.velocity_forward_mps)
    }

    /// These conditions mirrored across the character's sagittal plane (`mirror::CONDITION_RULES`): the bag's
    /// lateral place and velocity, the body's sideways walk and its turning change sign.
    pub fn mirrored(&self) -> Self {
        let body = BodyMotion { side_mps: -self.body.side_mps, turn_rad_s: -self.body.turn_rad_s, ..self.body };
        Self { side_m: -self.side_m, velocity_side_mps: -self.velocity_side_mps, body, ..*self }
    }

    /// As the protocol writes it (docs/protocol.md, `reset`).
    pub fn to_json(&self) -> Value {
        let mut value = json!({"distance_m": self.distance_m, "height_m": self.height_m, "side_m": self.side_m,
               "velocity_side_mps": self.velocity_side_mps, "velocity_forward_mps": self.velocity_forward_mps,
               "bag_glides": self.glides, "bag_rides": self.rides});
        if let Some(object) = value.as_object_mut() {
            object.extend(self.body.to_json_fields().map(|(name, v)| (name.to_string(), v)));
            object.extend(self.arms.to_json_fields().map(|(name, v)| (name.to_string(), v)));
        }
        value
    }
}

impl Default for EpisodeConditions {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// The target placements a policy covers, in the character's frame (`EpisodeConditions`'s conventions): a box of
/// target centres, the target's largest speed when a punch starts, and whether a punch may start from any
/// pose (the end of an earlier punch, mid-recovery) or only from the settled guard.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReachVolume {
    pub distance_m: [f32; 2],
    pub height_m: [f32; 2],
    pub side_m: [f32; 2],
    pub max_target_speed_mps: f32,
    pub any_start_pose: bool,
}

/// The volume `punch train` covers by default: the target's centre 0.60 to 0.85 m in front of the root,
/// 1.15 to 1.55 m high, 0.25 m to either side, moving at up to 1 m/s, from any pose.
pub const REACH_VOLUME: ReachVolume = ReachVolume {
    distance_m: [0.60, 0.85],
    height_m: [1.15, 1.55],
    side_m: [-0.25, 0.25],
    max_target_speed_mps: 1.0,
    any_start_pose: true,
};

/// The farthest a hand's moves reach with the simulated body's own arms (m): the spec volume's far end, moved
/// `LEAD_REACH_FORWARD_M` forward for the lead hand's moves from the stance's guard (`ReachVolume::within_arm`).
pub fn hand_far_m(lead_from_stance: bool) -> f32 {
    REACH_VOLUME.distance_m[1] + if lead_from_stance { LEAD_REACH_FORWARD_M } else { 0.0 }
}

/// How far outside its policy's reach volume a target may be and still be punched (m): a hanging bag sways
/// by millimetres, and a game places things to a centimetre.
pub const REACH_TOLERANCE_M: f32 = 0.03;

/// How far outside its policy's reach volume a target may be and still be aimed at itself (m); beyond, a punch aims
/// at the point this far out nearest to it (`ReachVolume::aim_point`). Policies trained over a volume reach past
/// it: the shipped ones hit standing targets up to 0.3 m beside it, and a hanging bag carried by a character
/// turning at 90 degrees/s, which swings up to 0.3 m out of it, 64 of 64 times aimed at itself (the swing; 54 of
/// 64 aimed at the volume's nearest point). A target further out is no real punch's: the policy was never shown
/// one, and the game is told (`target_out_of_reach`).
pub const AIM_BEYOND_REACH_M: f32 = 0.3;

impl ReachVolume {
    /// The reach of a policy trained at one spot (the quickstart): that spot, at rest, from the guard.
    pub fn spot(placement: EpisodeConditions) -> Self {
        let EpisodeConditions { distance_m, height_m, side_m, .. } = placement;
        Self {
            distance_m: [distance_m; 2],
            height_m: [height_m; 2],
            side_m: [side_m; 2],
            max_target_speed_mps: 0.0,
            any_start_pose: false,
        }
    }

    fn ranges(&self) -> [[f32; 2]; 3] {
        [self.side_m, self.height_m, self.distance_m]
    }

    /// The point of the box nearest to `position` (x side, y height, z distance, as `EpisodeConditions::position`).
    pub fn nearest(&self, position: Vec3) -> Vec3 {
        let [x, y, z] = self.ranges();
        Vec3::new(position.x.clamp(x[0], x[1]), position.y.clamp(y[0], y[1]), position.z.clamp(z[0], z[1]))
    }

    /// Where a punch at a target centred at `position` (the character's frame) aims: at the target itself while
    /// it lies within `AIM_BEYOND_REACH_M` of a volume's box, else at the point that far out nearest to it. A
    /// spot's policy (`spot`) knows one placement only: it aims at the spot.
    pub fn aim_point(&self, position: Vec3) -> Vec3 {
        let margin_m = if self.ranges().iter().all(|[low, high]| low == high) { 0.0 } else { AIM_BEYOND_REACH_M };
        let [x, y, z] = self.ranges();
        let clamp = |v: f32, [low, high]: [f32; 2]| v.clamp(low - margin_m, high + margin_m);
        Vec3::new(clamp(position.x, x), clamp(position.y, y), clamp(position.z, z))
    }

    /// The volume mirrored across the character's sagittal plane: the side range negated (the reach of a policy
    /// played mirrored, by the other hand).
    pub fn mirrored(&self) -> Self {
        Self { side_m: [-self.side_m[1], -self.side_m[0]], ..*self }
    }

    /// Whether a target centre lies in the box, give or take `REACH_TOLERANCE_M`.
    pub fn contains(&self, position: Vec3) -> bool {
        position.is_finite() && self.nearest(position).distance(position) <= REACH_TOLERANCE_M
    }

    /// The volume of a character whose arm (shoulder to fist centre) is `shortfall_m` shorter than the simulated
    /// body's: no target farther than `hand_far_m` (the farthest its hand's moves reach with the body's own arms)
    /// less the shortfall, the near end no farther than the far one. A straight's reach shrinks with the arm; a
    /// bent-arm move nearer than its hand's range keeps what the shorter arm still reaches. Longer arms keep the
    /// volume: the policy was never shown farther targets. Why: with short arms the jab missed almost only the
    /// targets beyond the arm (experiments/notebook.md, "Where the jab misses").
    pub fn within_arm(&self, hand_far_m: f32, shortfall_m: f32) -> Self {
        if shortfall_m.is_nan() || shortfall_m <= 0.0 {
            return *self;
        }
        let far = self.distance_m[1].min(hand_far_m - shortfall_m);
        Self { distance_m: [self.distance_m[0].min(far), far], ..*self }
    }

    /// As the handshake and a policy's metadata write it.
    pub fn to_json(&self) -> Value {
        json!({"distance_m": self.distance_m, "height_m": self.height_m, "side_m": self.side_m,
               "max_target_speed_mps": self.max_target_speed_mps, "any_start_pose": self.any_start_pose})
    }

    /// Reads a volume back; every field must be there, ranges ordered, speeds not negative.
    pub fn from_json(value: &Value) -> Result<Self, String> {
        let range = |key: &str| -> Result<[f32; 2], String> {
            let pair = value.get(key).and_then(Value::as_array).filter(|p| p.len() == 2);
            let numbers: Option<Vec<f32>> =
                pair.map(|p| p.iter().filter_map(Value::as_f64).filter(|v| v.is_finite()).map(|v| v as f32).collect());
            match numbers.as_deref() {
                Some(&[low, high]) if low <= high => Ok([low, high]),
                _ => Err(format!("'{key}' must be [low, high] with low <= high")),
            }
        };
        let speed = value
            .get("max_target_speed_mps")
            .and_then(Value::as_f64)
            .filter(|v| v.is_finite() && *v >= 0.0)
            .ok_or("'max_target_speed_mps' must be a number >= 0")?;
        let any_start_pose =
            value.get("any_start_pose").and_then(Value::as_bool).ok_or("'any_start_pose' must be true or false")?;
        Ok(Self {
            distance_m: range("distance_m")?,
            height_m: range("height_m")?,
            side_m: range("side_m")?,
            max_target_speed_mps: speed as f32,
            any_start_pose,
        })
    }

    /// The reach written in a policy file's metadata (`keys::REACH_VOLUME`); required, as the rest of the
    /// contract is.
    pub fn from_metadata(lookup: impl Fn(&str) -> Option<String>) -> Result<Self, SpecError> {
        let key = keys::REACH_VOLUME;
        let text = lookup(key).ok_or(SpecError::MissingKey { key })?;
        let bad = |reason: String| SpecError::BadValue { key, value: text.clone(), reason };
        let value: Value = serde_json::from_str(&text).map_err(|e| bad(format!("not JSON: {e}")))?;
        Self::from_json(&value).map_err(bad)
    }
}

/// A value of a Godot project setting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SettingValue {
    Int(i64),
    Float(f64),
    Text(&'static str),
}

impl SettingValue {
    /// Whether a game's value (as Godot gives it: a number or a string) is this one.
    pub fn matches(&self, number: Option<f64>, text: Option<&str>) -> bool {
        match (self, number, text) {
            (Self::Int(want), Some(have), _) => have == *want as f64,
            // Godot stores floats as f32 in places: 0.4 reads back as 0.4000000059604645.
            (Self::Float(want), Some(have), _) => (have - want).abs() < 1e-6,
            (Self::Text(want), _, Some(have)) => have == *want,
            _ => false,
        }
    }
}

impl std::fmt::Display for SettingValue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Int(value) => write!(f, "{value}"),
            Self::Float(value) => write!(f, "{value}"),
            Self::Text(value) => write!(f, "\"{value}\""),
        }
    }
}

/// A project setting the physics of a punch depends on: where to find it in the editor, its path and the
/// value the training project uses (godot_project/project.godot).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProjectSetting {
    pub path: &'static str,
    /// As the editor's Project Settings dialog shows it.
    pub label: &'static str,
    pub value: SettingValue,
}

/// The physics settings policies are trained with: a game plays them as trained only with the same.
pub const PROJECT_SETTINGS: [ProjectSetting; 4] = [
    ProjectSetting {
        path: "physics/common/physics_ticks_per_second",
        label: "Physics > Common > Physics Ticks per Second",
        value: SettingValue::Int(PHYSICS_HZ as i64),
    },
    ProjectSetting {
        path: "physics/3d/physics_engine",
        label: "Physics > 3D > Physics Engine",
        value: SettingValue::Text("Jolt Physics"),
    },
    ProjectSetting {
        path: "physics/jolt_physics_3d/simulation/position_steps",
        label: "Physics > Jolt Physics 3D > Simulation > Position Steps",
        value: SettingValue::Int(8),
    },
    ProjectSetting {
        path: "physics/jolt_physics_3d/simulation/baumgarte_stabilization_factor",
        label: "Physics > Jolt Physics 3D > Simulation > Baumgarte Stabilization Factor",
        value: SettingValue::Float(0.4),
    },
];

/// The settings of `PROJECT_SETTINGS` a game has wrong (`lookup` gives a setting's value by path, as a
/// number or a string), each as a line that says what to set.
pub fn project_setting_problems(lookup: impl Fn(&str) -> (Option<f64>, Option<String>)) -> Vec<String> {
    PROJECT_SETTINGS
        .iter()
        .filter_map(|setting| {
            let (number, text) = lookup(setting.path);
            (!setting.value.matches(number, text.as_deref())).then(|| {
                let have = text.map(|t| format!("{t:?}")).or(number.map(|n| n.to_string()));
                format!(
                    "{} ({}) is {}; set it to {}",
                    setting.label,
                    setting.path,
                    have.unwrap_or_else(|| "unset".into()),
                    setting.value
                )
            })
        })
        .collect()
}

/// Names of the policy-file metadata entries of the contract (ONNX custom metadata).
pub mod keys {
    pub const SPEC_VERSION: &str = "punch_spec_version";
    pub const SPEC_HASH: &str = "punch_spec_hash";
    pub const PHYSICS_HZ: &str = "punch_physics_hz";
    pub const DECISION_PERIOD: &str = "punch_decision_period";
    pub const FRAMES: &str = "punch_frames";
    pub const SMOOTHING_WINDOW: &str = "punch_smoothing_window";
    pub const OBSERVATION_SIZE: &str = "punch_observation_size";
    pub const ACTION_SIZE: &str = "punch_action_size";
    pub const ACTION_SPEC: &str = "punch_action_spec";
    /// The target placements the policy covers (`ReachVolume::to_json`), written by the trainer.
    pub const REACH_VOLUME: &str = "punch_reach_volume";
    /// Optional: how the designer's runtime noise is spread over the degrees of freedom (`NoiseScale`).
    pub const NOISE_SCALE: &str = "punch_noise_scale";
    /// Optional: the load the policy punches from (`stance::Load`'s name; `punch train --load`), absent for a
    /// policy trained from the guard itself.
    pub const START_LOAD: &str = "punch_start_load";
}

/// Per degree of freedom (action order), the share of the designer's runtime noise sigma it gets: 0 to 1.
/// A policy trained with a motion style keeps its guard arm and the waist's flexion nearly still under
/// noise (the style explored them that narrowly), so a designer's sigma varies the punch, not the guard.
pub type NoiseScale = [f32; DOF_COUNT];

/// Every degree of freedom gets the whole sigma: a policy without `punch_noise_scale`.
pub const UNIFORM_NOISE: NoiseScale = [1.0; DOF_COUNT];

/// The policy's noise scale (`keys::NOISE_SCALE`): a JSON array of `DOF_COUNT` numbers from 0 to 1, or
/// `UNIFORM_NOISE` when the key is absent. Anything else is an error naming the key.
pub fn noise_scale_from_metadata(lookup: impl Fn(&str) -> Option<String>) -> Result<NoiseScale, SpecError> {
    let key = keys::NOISE_SCALE;
    let Some(text) = lookup(key) else { return Ok(UNIFORM_NOISE) };
    let bad = |reason: String| SpecError::BadValue { key, value: text.chars().take(200).collect(), reason };
    let value: Value = serde_json::from_str(&text).map_err(|e| bad(format!("not JSON: {e}")))?;
    let numbers: Option<Vec<f32>> = value.as_array().filter(|items| items.len() == DOF_COUNT).and_then(|items| {
        items.iter().map(|v| v.as_f64().filter(|x| (0.0..=1.0).contains(x)).map(|x| x as f32)).collect()
    });
    let numbers = numbers.ok_or_else(|| bad(format!("must be a list of {DOF_COUNT} numbers from 0 to 1")))?;
    let mut scale = UNIFORM_NOISE;
    scale.copy_from_slice(&numbers);
    Ok(scale)
}

/// The load the policy punches from (`keys::START_LOAD`): None when the key is absent (from the guard); a name that
/// is no load is an error naming the key and the loads there are.
pub fn start_load_from_metadata(lookup: impl Fn(&str) -> Option<String>) -> Result<Option<Load>, SpecError> {
    let key = keys::START_LOAD;
    let Some(text) = lookup(key) else { return Ok(None) };
    let names: Vec<&str> = Load::ALL.iter().map(|(name, _)| *name).collect();
    Load::from_name(&text).map(Some).ok_or_else(|| SpecError::BadValue {
        key,
        value: text.chars().take(200).collect(),
        reason: format!("it is none of the loads {names:?}"),
    })
}

/// The entries a policy file must have to be played; a missing one is an error, never a default.
pub const REQUIRED_METADATA: [&str; 5] =
    [keys::SPEC_HASH, keys::PHYSICS_HZ, keys::DECISION_PERIOD, keys::FRAMES, keys::SMOOTHING_WINDOW];

/// What re-exporting a policy takes (named in every error about a policy's metadata).
pub const REEXPORT_HINT: &str =
    "export it again with `punch train` or `punch pretrain`, which write the whole contract";

/// Why a policy's metadata is not a contract this build can play.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SpecError {
    #[error("the policy has no '{key}' metadata; {REEXPORT_HINT}")]
    MissingKey { key: &'static str },
    #[error("the policy's '{key}' metadata is {value:?}: {reason}; {REEXPORT_HINT}")]
    BadValue { key: &'static str, value: String, reason: String },
}

/// A value of `PolicySpec::new` out of range: which field (its metadata key) and why.
#[derive(Debug, Clone, PartialEq)]
pub struct InvalidSpec {
    pub key: &'static str,
    pub reason: String,
}

impl std::fmt::Display for InvalidSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.reason)
    }
}

impl From<InvalidSpec> for String {
    fn from(invalid: InvalidSpec) -> Self {
        invalid.reason
    }
}

/// The timing a policy was trained with: a game plays it with the same.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PolicySpec {
    /// Physics frames each decision is held for.
    pub decision_period: u32,
    /// Physics frames of one punch (a multiple of the decision period).
    pub frames: u32,
    /// Actions are smoothed over this many decisions (the paper's Eq. 1; 1: off).
    pub smoothing_window: u32,
}

impl PolicySpec {
    /// A checked spec: every value in range and `frames` a multiple of `decision_period`.
    pub fn new(decision_period: u32, frames: u32, smoothing_window: u32) -> Result<Self, InvalidSpec> {
        let invalid = |key, reason| Err(InvalidSpec { key, reason });
        if !(1..=MAX_DECISION_PERIOD).contains(&decision_period) {
            return invalid(
                keys::DECISION_PERIOD,
                format!("the decision period must be 1..={MAX_DECISION_PERIOD} frames, not {decision_period}"),
            );
        }
        if !(1..=MAX_FRAMES).contains(&frames) || !frames.is_multiple_of(decision_period) {
            return invalid(
                keys::FRAMES,
                format!(
                    "'frames' ({frames}) must be in 1..={MAX_FRAMES} and a multiple of the decision period ({decision_period})"
                ),
            );
        }
        if !(1..=MAX_SMOOTHING_WINDOW).contains(&smoothing_window) {
            return invalid(
                keys::SMOOTHING_WINDOW,
                format!("'smoothing_window' must be an integer in 1..={MAX_SMOOTHING_WINDOW}, not {smoothing_window}"),
            );
        }
        Ok(Self { decision_period, frames, smoothing_window })
    }

    /// Decisions in one punch.
    pub fn decisions(&self) -> u32 {
        self.frames / self.decision_period
    }

    /// The observation-spec hash for this decision period.
    pub fn spec_hash(&self) -> String {
        spec_hash(self.decision_period)
    }

    /// The contract as policy-file metadata: what the training server announces with every reset and the
    /// trainer writes into the policies it exports.
    pub fn metadata(&self) -> Vec<(&'static str, String)> {
        vec![
            (keys::SPEC_VERSION, OBS_SPEC_VERSION.to_string()),
            (keys::SPEC_HASH, self.spec_hash()),
            (keys::PHYSICS_HZ, PHYSICS_HZ.to_string()),
            (keys::DECISION_PERIOD, self.decision_period.to_string()),
            (keys::FRAMES, self.frames.to_string()),
            (keys::SMOOTHING_WINDOW, self.smoothing_window.to_string()),
            (keys::OBSERVATION_SIZE, OBS_DIM.to_string()),
            (keys::ACTION_SIZE, DOF_COUNT.to_string()),
            (
                keys::ACTION_SPEC,
                format!(
                    "{DOF_COUNT} raw actions in [-1, 1]; see docs/env.md (mean clipped to [-1, 1], smoothed by the controller)"
                ),
            ),
        ]
    }

    /// `metadata` as a JSON object (for the protocol).
    pub fn metadata_json(&self) -> Value {
        Value::Object(self.metadata().into_iter().map(|(key, value)| (key.to_string(), Value::String(value))).collect())
    }

    /// Reads the contract back from a policy file's metadata (`lookup` gives an entry by key). Every key of
    /// `REQUIRED_METADATA` must be there with a value this build can play: a missing or bad one is an error
    /// that names the key and how to re-export. The spec hash is only required here; it is compared with
    /// the character's own by the caller.
    pub fn from_metadata(lookup: impl Fn(&str) -> Option<String>) -> Result<Self, SpecError> {
        let get = |key: &'static str| lookup(key).ok_or(SpecError::MissingKey { key });
        let number = |key: &'static str| -> Result<u32, SpecError> {
            let value = get(key)?;
            value.trim().parse::<u32>().map_err(|_| SpecError::BadValue {
                key,
                value: value.clone(),
                reason: "not a whole number".into(),
            })
        };
        get(keys::SPEC_HASH)?;
        let physics_hz = number(keys::PHYSICS_HZ)?;
        if physics_hz != PHYSICS_HZ {
            return Err(SpecError::BadValue {
                key: keys::PHYSICS_HZ,
                value: physics_hz.to_string(),
                reason: format!("this build simulates at {PHYSICS_HZ} Hz"),
            });
        }
        let (decision_period, frames, smoothing_window) =
            (number(keys::DECISION_PERIOD)?, number(keys::FRAMES)?, number(keys::SMOOTHING_WINDOW)?);
        Self::new(decision_period, frames, smoothing_window).map_err(|invalid| SpecError::BadValue {
            key: invalid.key,
            value: lookup(invalid.key).unwrap_or_default(),
            reason: invalid.reason,
        })
    }
}

/// The spec part of the training server's handshake for `decision_period`: versions, hash, rates, sizes,
/// every name, the action bounds, the default bag placement, the reach volume training covers and the mirror's
/// rules (`mirror::rules_json`), the action that holds each stance's guard (`stance_guard_actions`) and each
/// stance's guard with the punching arm loaded (`loaded_guard_actions`, by load, `stance::Load`) and how much
/// further forward a lead hand's targets lie (`stance_lead_forward_m`, `stance::LEAD_REACH_FORWARD_M`).
pub fn handshake_fields(decision_period: u32) -> Map<String, Value> {
    let mut fields = Map::new();
    fields.insert("spec_version".into(), json!(OBS_SPEC_VERSION));
    fields.insert("spec_hash".into(), json!(spec_hash(decision_period)));
    fields.insert("physics_hz".into(), json!(PHYSICS_HZ));
    fields.insert("decision_period".into(), json!(decision_period));
    fields.insert("action_names".into(), json!(DOFS.iter().map(|d| d.name).collect::<Vec<_>>()));
    fields.insert("action_lower_rad".into(), json!(DOFS.iter().map(|d| d.lower_rad).collect::<Vec<_>>()));
    fields.insert("action_upper_rad".into(), json!(DOFS.iter().map(|d| d.upper_rad).collect::<Vec<_>>()));
    fields.insert("observation_names".into(), json!(observation_names()));
    fields.insert("feature_names".into(), json!(FEATURE_NAMES.to_vec()));
    fields.insert("default_bag".into(), EpisodeConditions::DEFAULT.to_json());
    fields.insert("reach_volume".into(), REACH_VOLUME.to_json());
    fields.insert("mirror".into(), mirror::rules_json());
    let guard = |stance: Stance| json!(action_from_targets(&stance.guard_targets()));
    fields.insert(
        "stance_guard_actions".into(),
        json!({"orthodox": guard(Stance::Orthodox), "southpaw": guard(Stance::Southpaw)}),
    );
    // Each stance's guard with the punching (right) arm loaded (`punch train --guard G --load L`).
    let loaded = |stance: Stance| {
        let by_name: Map<String, Value> = Load::ALL
            .iter()
            .map(|(name, load)| (name.to_string(), json!(action_from_targets(&load.loaded(stance.guard_targets())))))
            .collect();
        Value::Object(by_name)
    };
    fields.insert(
        "loaded_guard_actions".into(),
        json!({"orthodox": loaded(Stance::Orthodox), "southpaw": loaded(Stance::Southpaw)}),
    );
    fields.insert("stance_lead_forward_m".into(), json!(LEAD_REACH_FORWARD_M));
    fields
}

#[cfg(test)]
mod tests {
    use std::collections::HashMap;

    use super::*;

    fn lookup(entries: &[(&'static str, String)]) -> impl Fn(&str) -> Option<String> {
        let map: HashMap<String, String> = entries.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
        move |key| map.get(key).cloned()
    }

    #[test]
    fn a_shorter_arm_reaches_less_far_and_a_longer_one_no_farther() {
        let jab = ReachVolume { distance_m: [0.70, 0.95], ..REACH_VOLUME };
        let short = jab.within_arm(0.95, 0.155);
        assert!((short.distance_m[1] - 0.795).abs() < 1e-6 && short.distance_m[0] == 0.70, "{short:?}");
        assert_eq!(short.height_m, jab.height_m);
        assert_eq!(jab.within_arm(0.95, -0.155), jab, "longer arms keep the volume");
        assert_eq!(jab.within_arm(0.95, f32::NAN), jab);
        // A hook nearer than its hand's range keeps what the shorter arm reaches.
        let hook = ReachVolume { distance_m: [0.60, 0.70], ..REACH_VOLUME };
        assert_eq!(hook.within_arm(0.85, 0.10), hook);
        let shortest = hook.within_arm(0.85, 0.30);
        assert!((shortest.distance_m[0] - 0.55).abs() < 1e-6 && shortest.distance_m[0] == shortest.distance_m[1]);
    }

    #[test]
    fn metadata_round_trips() {
        let spec = PolicySpec::new(5, 50, 3).expect("valid");
        assert_eq!(PolicySpec::from_metadata(lookup(&spec.metadata())), Ok(spec));
        assert_eq!(spec.decisions(), 10);
        assert_eq!(spec.metadata_json()[keys::SMOOTHING_WINDOW], json!("3"));
    }

    #[test]
    fn the_noise_scale_is_uniform_without_its_key_and_refused_when_it_lies() {
        assert_eq!(noise_scale_from_metadata(lookup(&[])), Ok(UNIFORM_NOISE));
        let styled = "[0.1, 1, 1, 1, 1, 1, 0.05, 0.05, 0.05, 0.05]".to_string();
        let scale = noise_scale_from_metadata(lookup(&[(keys::NOISE_SCALE, styled)])).expect("valid");
        assert_eq!((scale[0], scale[1], scale[9]), (0.1, 1.0, 0.05));
        for bad in [
            "[1, 1]",
            "[1,1,1,1,1,1,1,1,1,2]",
            "[1,1,1,1,1,1,1,1,1,-0.1]",
            "[1,1,1,1,1,1,1,1,1,\"a\"]",
            "{\"a\": 1}",
            "nan",
            "[1,1,1,1,1,1,1,1,1,1e999]",
            "",
        ] {
            let error = noise_scale_from_metadata(lookup(&[(keys::NOISE_SCALE, bad.to_string())])).expect_err(bad);
            assert!(error.to_string().contains(keys::NOISE_SCALE), "{error}");
        }
    }

    #[test]
    fn the_start_load_is_none_without_its_key_and_refused_when_it_names_no_load() {
        assert_eq!(start_load_from_metadata(lookup(&[])), Ok(None));
        let hook = start_load_from_metadata(lookup(&[(keys::START_LOAD, "hook".to_string())]));
        assert_eq!(hook, Ok(Some(Load::Hook)));
        for bad in ["", "Hook", "swing", "hook "] {
            let error = start_load_from_metadata(lookup(&[(keys::START_LOAD, bad.to_string())])).expect_err(bad);
            assert!(error.to_string().contains(keys::START_LOAD) && error.to_string().contains("uppercut"), "{error}");
        }
    }

    #[test]
    fn every_required_key_is_required_and_named() {
        let full = PolicySpec::new(5, 100, 3).expect("valid").metadata();
        for key in REQUIRED_METADATA {
            let partial: Vec<_> = full.iter().filter(|(k, _)| *k != key).cloned().collect();
            let error = PolicySpec::from_metadata(lookup(&partial)).expect_err("refused");
            assert_eq!(error, SpecError::MissingKey { key });
            assert!(error.to_string().contains(key) && error.to_string().contains("punch pretrain"), "{error}");
        }
    }

    #[test]
    fn bad_values_are_refused() {
        let spec = PolicySpec::new(5, 50, 1).expect("valid").metadata();
        for (key, value) in [
            (keys::FRAMES, "0"),
            (keys::FRAMES, "7"),
            (keys::FRAMES, "1000000000000"),
            (keys::SMOOTHING_WINDOW, "0"),
            (keys::SMOOTHING_WINDOW, "x"),
            (keys::PHYSICS_HZ, "60"),
            (keys::DECISION_PERIOD, "-5"),
        ] {
            let changed: Vec<_> =
                spec.iter().map(|(k, v)| (*k, if *k == key { value.to_string() } else { v.clone() })).collect();
            let error = PolicySpec::from_metadata(lookup(&changed)).expect_err("refused");
            assert!(error.to_string().contains(&format!("'{key}'")), "{key} = {value}: {error}");
        }
    }

    #[test]
    fn project_settings_are_checked_one_by_one() {
        let training = |path: &str| match path {
            "physics/3d/physics_engine" => (None, Some("Jolt Physics".to_string())),
            "physics/jolt_physics_3d/simulation/baumgarte_stabilization_factor" => (Some(0.4000000059604645), None),
            "physics/jolt_physics_3d/simulation/position_steps" => (Some(8.0), None),
            _ => (Some(120.0), None),
        };
        assert!(project_setting_problems(training).is_empty());
        // A new Godot project: 60 Hz, the default engine, Jolt's default solver.
        let fresh = |path: &str| match path {
            "physics/3d/physics_engine" => (None, Some("DEFAULT".to_string())),
            "physics/jolt_physics_3d/simulation/baumgarte_stabilization_factor" => (Some(0.2), None),
            "physics/jolt_physics_3d/simulation/position_steps" => (Some(2.0), None),
            _ => (Some(60.0), None),
        };
        let problems = project_setting_problems(fresh);
        assert_eq!(problems.len(), 4);
        assert_eq!(
            problems[0],
            "Physics > Common > Physics Ticks per Second (physics/common/physics_ticks_per_second) is 60; set it to 120"
        );
        assert!(problems[1].ends_with("is \"DEFAULT\"; set it to \"Jolt Physics\""), "{}", problems[1]);
    }

    #[test]
    fn the_handshake_announces_the_spec() {
        let fields = handshake_fields(5);
        assert_eq!(fields["spec_hash"], json!(spec_hash(5)));
        assert_eq!(fields["observation_names"].as_array().map(Vec::len), Some(OBS_DIM));
        assert_eq!(fields["action_names"].as_array().map(Vec::len), Some(DOF_COUNT));
        assert_eq!(fields["default_bag"]["distance_m"], json!(0.72f32));
        assert_eq!(ReachVolume::from_json(&fields["reach_volume"]), Ok(REACH_VOLUME));
        assert_eq!(fields["mirror"], mirror::rules_json());
        assert_eq!(fields["stance_lead_forward_m"], json!(LEAD_REACH_FORWARD_M));
    }

    #[test]
    fn mirrored_conditions_follow_the_mirror_rules_field_by_field() {
        let conditions = EpisodeConditions {
            distance_m: 0.7,
            height_m: 1.3,
            side_m: 0.2,
            velocity_side_mps: -0.4,
            velocity_forward_mps: 0.3,
            glides: true,
            rides: false,
            body: BodyMotion { side_mps: 0.5, forward_mps: 1.1, turn_rad_s: -1.2, lunge_m: 0.2, bob_m: 0.03 },
            arms: ArmScale { upper_arm: 1.1, forearm: 0.9, shoulder_shift_m: 0.02 },
        };
        let (plain, mirrored) = (conditions.to_json(), conditions.mirrored().to_json());
        let (plain, mirrored) = (plain.as_object().expect("object"), mirrored.as_object().expect("object"));
        assert_eq!(plain.len(), mirror::CONDITION_RULES.len(), "every field has a mirror rule");
        for (name, value) in plain {
            let expected = mirror::mirror_condition(name, value).unwrap_or_else(|| panic!("{name} has no mirror rule"));
            assert_eq!(mirrored[name], expected, "{name}");
        }
        assert_eq!(conditions.mirrored().mirrored(), conditions);
        assert_eq!(conditions.mirrored().position(), mirror::mirror_point(conditions.position()));
        assert_eq!(REACH_VOLUME.mirrored(), REACH_VOLUME, "the default reach is symmetric");
        let right = ReachVolume { side_m: [-0.3, 0.1], ..REACH_VOLUME };
        assert_eq!(right.mirrored().side_m, [-0.1, 0.3]);
    }

    #[test]
    fn the_reach_volume_contains_its_box_give_or_take_the_tolerance() {
        let centre = EpisodeConditions::at(0.72, 1.35, 0.0).position();
        assert!(REACH_VOLUME.contains(centre));
        assert!(REACH_VOLUME.contains(Vec3::new(0.25 + REACH_TOLERANCE_M * 0.9, 1.55, 0.85)));
        let far = Vec3::new(0.0, 1.35, 1.2);
        assert!(!REACH_VOLUME.contains(far));
        assert_eq!(REACH_VOLUME.nearest(far), Vec3::new(0.0, 1.35, 0.85));
        assert!(!REACH_VOLUME.contains(Vec3::NAN));
        let spot = ReachVolume::spot(EpisodeConditions::DEFAULT);
        assert!(spot.contains(centre + Vec3::new(0.02, 0.0, 0.0)));
        assert!(!spot.contains(centre + Vec3::new(0.0, 0.05, 0.0)));
    }

    #[test]
    fn a_target_a_little_out_of_reach_is_aimed_at_itself_and_one_far_out_at_the_margin() {
        let beside = Vec3::new(0.25 + 0.2, 1.35, 0.7);
        assert!(!REACH_VOLUME.contains(beside));
        assert_eq!(REACH_VOLUME.aim_point(beside), beside);
        let far = Vec3::new(0.0, 1.35, 2.0);
        assert_eq!(REACH_VOLUME.aim_point(far), Vec3::new(0.0, 1.35, 0.85 + AIM_BEYOND_REACH_M));
        let spot = ReachVolume::spot(EpisodeConditions::DEFAULT);
        assert_eq!(spot.aim_point(beside), spot.nearest(beside));
    }

    #[test]
    fn a_policy_must_state_its_reach() {
        let written = REACH_VOLUME.to_json().to_string();
        assert_eq!(ReachVolume::from_metadata(|_| Some(written.clone())), Ok(REACH_VOLUME));
        let missing = ReachVolume::from_metadata(|_| None).expect_err("required");
        assert_eq!(missing, SpecError::MissingKey { key: keys::REACH_VOLUME });
        for bad in [
            "{}",
            "[1]",
            r#"{"distance_m": [0.9, 0.6], "height_m": [1, 2], "side_m": [0, 0],
                    "max_target_speed_mps": 0, "any_start_pose": false}"#,
        ] {
            let error = ReachVolume::from_metadata(|_| Some(bad.to_string())).expect_err(bad);
            assert!(error.to_string().contains(keys::REACH_VOLUME), "{error}");
        }
    }
}
