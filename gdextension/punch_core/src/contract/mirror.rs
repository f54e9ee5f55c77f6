//! The mirror of the character's world across its sagittal plane (the plane through the root that holds its up
//! (+Y) and forward (+Z) axes): the left-right reflection x -> -x of the character's frame (`character.rs`, +X
//! is its left). The body is left-right symmetric, so a punch mirrored is a punch of the other hand: a policy
//! trained for one hand plays the other when what it observes and what it does are mirrored (observation in,
//! action out), and the world it then plays in is the mirror of the one it was trained in.
//!
//! Each vector the contract names (features, observation, action or joint targets) mirrors entry by entry:
//! entry `i` of the mirrored vector is `sign[i] * value[partner[i]]` (`Mirror`). The partners and signs are
//! resolved at compile time, by name, from two tables, `DOF_RULES` and `FEATURE_RULES`: a feature or DOF
//! added without a rule stops the build, naming it. What each kind of quantity does:
//!
//! - a polar vector (a position, a velocity, an impulse): x changes sign, y and z keep theirs (`Kind::Polar`);
//! - an axial vector (an angular velocity, a rotation vector, a joint's angles and speeds about its X, Y and Z
//!   axes): x keeps its sign, y and z change theirs (`Kind::Axial`). So the waist's and the shoulders'
//!   flexion (about X) and the elbows keep their sign; the waist's and shoulders' rotation (about Y) and the
//!   shoulders' abduction (about Z) change it, which is why the left shoulder's limits are the negated
//!   right ones for rotation and abduction;
//! - a scalar keeps its sign (a distance, a length, a flag, the episode phase) unless it is a lateral
//!   coordinate or a turn (`Kind::Negated`);
//! - every right entry swaps with its left partner.
//!
//! The arm-length features (`body_*`) describe one arm (the right's, `CharacterGeometry::arm_lengths`): a
//! character's arms are sized alike (`ArmScale` sizes both), so they keep their value.

use glam::{Quat, Vec3};
use serde_json::{Value, json};

use crate::contract::character::{DOF_COUNT, DOFS};
use crate::contract::names::{index_of_joined, is_joined};
use crate::contract::observation::{OBS_DIM, OBSERVED};
use crate::contract::sensing::{FEATURE_COUNT, FEATURE_NAMES};

/// What mirroring does to a quantity, besides moving it to its partner's place.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A scalar that keeps its sign.
    Same,
    /// A scalar that changes sign: a lateral coordinate, or a turn about the up or the forward axis.
    Negated,
    /// The `_x`, `_y`, `_z` entries of a polar vector (position, velocity, impulse): x changes sign.
    Polar,
    /// The `_x`, `_y`, `_z` entries of an axial vector (angular velocity, rotation vector): y and z change sign.
    Axial,
    /// One entry `<name>_<dof>` for every DOF (joint angles, joint speeds): each follows its DOF's rule.
    PerDof,
}

/// The rule of one quantity (or of a right-left pair): `name`'s value goes to `partner`'s place and back,
/// with the sign its `kind` gives. A quantity on the midline is its own partner.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rule {
    pub name: &'static str,
    pub partner: &'static str,
    pub kind: Kind,
}

const fn pair(name: &'static str, partner: &'static str, kind: Kind) -> Rule {
    Rule { name, partner, kind }
}

const fn own(name: &'static str, kind: Kind) -> Rule {
    Rule { name, partner: name, kind }
}

/// How the DOFs (the action, the joint targets, and through `Kind::PerDof` the joint angles and speeds)
/// mirror: a DOF is one component of its joint's rotation vector (an axial vector), so a rotation about X
/// keeps its sign and one about Y or Z changes it (a test checks this against each DOF's axis), and the right
/// joints swap with the left.
pub const DOF_RULES: [Rule; 6] = [
    own("waist_flexion", Kind::Same),
    own("waist_rotation", Kind::Negated),
    pair("shoulder_r_flexion", "shoulder_l_flexion", Kind::Same),
    pair("shoulder_r_rotation", "shoulder_l_rotation", Kind::Negated),
    pair("shoulder_r_abduction", "shoulder_l_abduction", Kind::Negated),
    pair("elbow_r_extension", "elbow_l_extension", Kind::Same),
];

/// How the per-frame features (`FEATURE_NAMES`) mirror. Everything is in the root's frame, so the mirror
/// plane is x = 0 there.
pub const FEATURE_RULES: [Rule; 18] = [
    pair("fist_r_pos", "fist_l_pos", Kind::Polar),
    pair("fist_r_vel", "fist_l_vel", Kind::Polar),
    pair("fist_r_impulse", "fist_l_impulse", Kind::Polar),
    own("character_impulse", Kind::Polar),
    own("bag_pos", Kind::Polar),
    own("bag_vel", Kind::Polar),
    own("bag_momentum_change", Kind::Polar),
    pair("fist_r_bag_distance", "fist_l_bag_distance", Kind::Same),
    own("angle", Kind::PerDof),
    own("speed", Kind::PerDof),
    own("root_vel", Kind::Polar),
    own("root_spin", Kind::Axial),
    own("body_upper_arm_m", Kind::Same),
    own("body_forearm_m", Kind::Same),
    own("body_shoulder_width_m", Kind::Same),
    own("joint_gap_max_m", Kind::Same),
    own("exploit_flags", Kind::Same),
    // The observation's own entry after the observed features.
    own("episode_phase", Kind::Same),
];

/// How an episode's conditions (`EpisodeConditions`, as the protocol writes them: a reset's `bags` entry)
/// mirror: the bag's lateral place and velocity, the body's sideways walk and its turning change sign; the
/// rest keeps its value (both arms are sized alike).
pub const CONDITION_RULES: [Rule; 15] = [
    own("distance_m", Kind::Same),
    own("height_m", Kind::Same),
    own("side_m", Kind::Negated),
    own("velocity_side_mps", Kind::Negated),
    own("velocity_forward_mps", Kind::Same),
    own("bag_glides", Kind::Same),
    own("bag_rides", Kind::Same),
    own("body_side_mps", Kind::Negated),
    own("body_forward_mps", Kind::Same),
    own("body_turn_rad_s", Kind::Negated),
    own("body_lunge_m", Kind::Same),
    own("body_bob_m", Kind::Same),
    own("arms_upper_arm_scale", Kind::Same),
    own("arms_forearm_scale", Kind::Same),
    own("arms_shoulder_shift_m", Kind::Same),
];

/// A mirror of vectors of `N` entries: entry `i` of the mirror is `sign[i] * value[partner[i]]`. It is its
/// own inverse (`partner[partner[i]] == i`, partners share a sign), and exact in floating point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mirror<const N: usize> {
    pub partner: [usize; N],
    pub sign: [f32; N],
}

impl<const N: usize> Mirror<N> {
    pub fn apply(&self, values: &[f32; N]) -> [f32; N] {
        std::array::from_fn(|i| self.sign[i] * values[self.partner[i]])
    }

    /// As the handshake writes it: `{"partner": [...], "sign": [...]}`.
    pub fn to_json(&self) -> Value {
        json!({"partner": self.partner.to_vec(), "sign": self.sign.to_vec()})
    }
}

/// Why a table does not give every name a rule.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RuleError {
    /// No rule names this entry.
    NoRule(&'static str),
    /// Two rules name this entry.
    TwoRules(&'static str),
    /// This entry's rule names a partner that is not there.
    NoPartner(&'static str),
}

impl RuleError {
    pub const fn name(&self) -> &'static str {
        match self {
            Self::NoRule(name) | Self::TwoRules(name) | Self::NoPartner(name) => name,
        }
    }
}

const AXES: [&str; 3] = ["x", "y", "z"];

/// The partner's name parts and the sign, when `rule` names `name` (from either end of the pair).
const fn rule_for(name: &str, rule: &Rule, dof_rules: &[Rule]) -> Option<([&'static str; 3], f32)> {
    let ends = [(rule.name, rule.partner), (rule.partner, rule.name)];
    let mut end = 0;
    while end < 2 {
        let (this, other) = ends[end];
        match rule.kind {
            Kind::Same | Kind::Negated => {
                if is_joined(name, &[this]) {
                    let sign = if matches!(rule.kind, Kind::Same) { 1.0 } else { -1.0 };
                    return Some(([other, "", ""], sign));
                }
            }
            Kind::Polar | Kind::Axial => {
                let mut axis = 0;
                while axis < 3 {
                    if is_joined(name, &[this, "_", AXES[axis]]) {
                        let flips = if matches!(rule.kind, Kind::Polar) { axis == 0 } else { axis != 0 };
                        return Some(([other, "_", AXES[axis]], if flips { -1.0 } else { 1.0 }));
                    }
                    axis += 1;
                }
            }
            Kind::PerDof => {
                let mut i = 0;
                while i < dof_rules.len() {
                    let dof = &dof_rules[i];
                    let mut dof_end = 0;
                    while dof_end < 2 {
                        let (dof_this, dof_other) =
                            if dof_end == 0 { (dof.name, dof.partner) } else { (dof.partner, dof.name) };
                        if is_joined(name, &[this, "_", dof_this]) {
                            let sign = if matches!(dof.kind, Kind::Same) { 1.0 } else { -1.0 };
                            // A DOF rule names `this_<dof>`; its partner is `other_<dof partner>` (one name
                            // part for the prefix and the underscore, one for the DOF).
                            return Some(([other, "_", dof_other], sign));
                        }
                        dof_end += 1;
                    }
                    i += 1;
                }
            }
        }
        end += 1;
    }
    None
}

/// The mirror of a list of names under `rules` (with `dof_rules` for `Kind::PerDof` rules): every name must be
/// named by exactly one rule, and its partner must be in the list.
pub const fn resolve<const N: usize>(
    names: &[&'static str; N],
    rules: &[Rule],
    dof_rules: &[Rule],
) -> Result<Mirror<N>, RuleError> {
    let mut mirror = Mirror { partner: [0; N], sign: [1.0; N] };
    let mut i = 0;
    while i < N {
        let mut found: Option<([&'static str; 3], f32)> = None;
        let mut r = 0;
        while r < rules.len() {
            if let Some(rule) = rule_for(names[i], &rules[r], dof_rules) {
                if found.is_some() {
                    return Err(RuleError::TwoRules(names[i]));
                }
                found = Some(rule);
            }
            r += 1;
        }
        let Some((partner, sign)) = found else { return Err(RuleError::NoRule(names[i])) };
        let Some(index) = index_of_joined(names, &partner) else { return Err(RuleError::NoPartner(names[i])) };
        mirror.partner[i] = index;
        mirror.sign[i] = sign;
        i += 1;
    }
    Ok(mirror)
}

const fn resolved<const N: usize>(result: Result<Mirror<N>, RuleError>) -> Mirror<N> {
    match result {
        Ok(mirror) => mirror,
        Err(RuleError::NoRule(name)) => panic!("{}", name),
        Err(RuleError::TwoRules(name)) => panic!("{}", name),
        Err(RuleError::NoPartner(name)) => panic!("{}", name),
    }
}

/// The DOFs' names in action order.
pub const DOF_NAMES: [&str; DOF_COUNT] = {
    let mut names = [""; DOF_COUNT];
    let mut i = 0;
    while i < DOF_COUNT {
        names[i] = DOFS[i].name;
        i += 1;
    }
    names
};

/// The mirror of an action, of joint targets, of any per-DOF vector in action order.
pub const DOF_MIRROR: Mirror<DOF_COUNT> = resolved(resolve(&DOF_NAMES, &DOF_RULES, &[]));

/// The mirror of a frame's features.
pub const FEATURE_MIRROR: Mirror<FEATURE_COUNT> = resolved(resolve(&FEATURE_NAMES, &FEATURE_RULES, &DOF_RULES));

/// The mirror of an observation: the observed features' (the partner of an observed feature must be observed),
/// and the episode phase unchanged.
pub const OBSERVATION_MIRROR: Mirror<OBS_DIM> = {
    let mut slot_of = [usize::MAX; FEATURE_COUNT];
    let mut slots = 0;
    let mut f = 0;
    while f < FEATURE_COUNT {
        if OBSERVED[f] {
            slot_of[f] = slots;
            slots += 1;
        }
        f += 1;
    }
    assert!(slots == OBS_DIM - 1, "the observation is the observed features and the phase");
    let mut mirror = Mirror { partner: [OBS_DIM - 1; OBS_DIM], sign: [1.0; OBS_DIM] };
    let mut f = 0;
    while f < FEATURE_COUNT {
        if OBSERVED[f] {
            let partner = FEATURE_MIRROR.partner[f];
            if !OBSERVED[partner] {
                panic!("{}", FEATURE_NAMES[f]);
            }
            mirror.partner[slot_of[f]] = slot_of[partner];
            mirror.sign[slot_of[f]] = FEATURE_MIRROR.sign[f];
        }
        f += 1;
    }
    mirror
};

/// The mirror of the conditions' fields, in `CONDITION_RULES` order (as `EpisodeConditions::to_json` names them).
pub const CONDITION_NAMES: [&str; CONDITION_RULES.len()] = {
    let mut names = [""; CONDITION_RULES.len()];
    let mut i = 0;
    while i < names.len() {
        names[i] = CONDITION_RULES[i].name;
        i += 1;
    }
    names
};

const CONDITION_MIRROR: Mirror<{ CONDITION_RULES.len() }> = resolved(resolve(&CONDITION_NAMES, &CONDITION_RULES, &[]));

/// The mirrored action (raw, in [-1, 1]): its joint targets are the mirrored targets (`mirror_targets`), since
/// every left limit is the right one with the sign its rule gives.
pub fn mirror_action(action: &[f32; DOF_COUNT]) -> [f32; DOF_COUNT] {
    DOF_MIRROR.apply(action)
}

/// The mirrored joint targets (or angles, or speeds), rad, in action order.
pub fn mirror_targets(targets: &[f32; DOF_COUNT]) -> [f32; DOF_COUNT] {
    DOF_MIRROR.apply(targets)
}

pub fn mirror_features(features: &[f32; FEATURE_COUNT]) -> [f32; FEATURE_COUNT] {
    FEATURE_MIRROR.apply(features)
}

pub fn mirror_observation(observation: &[f32; OBS_DIM]) -> [f32; OBS_DIM] {
    OBSERVATION_MIRROR.apply(observation)
}

/// A point or a polar vector in the character's frame, mirrored: x changes sign.
pub fn mirror_point(point: Vec3) -> Vec3 {
    Vec3::new(-point.x, point.y, point.z)
}

/// An axial vector (an angular velocity, a rotation vector) in the character's frame, mirrored: y and z
/// change sign.
pub fn mirror_axial(vector: Vec3) -> Vec3 {
    Vec3::new(vector.x, -vector.y, -vector.z)
}

/// A rotation in the character's frame, mirrored (M R M with M the reflection): its axis is axial.
pub fn mirror_rotation(rotation: Quat) -> Quat {
    Quat::from_xyzw(rotation.x, -rotation.y, -rotation.z, rotation.w)
}

/// A value of `CONDITION_RULES`'s field `name` mirrored (None for a name that is not a field): numbers change
/// sign where the rule says, the rest is unchanged.
pub fn mirror_condition(name: &str, value: &Value) -> Option<Value> {
    let index = CONDITION_NAMES.iter().position(|n| *n == name)?;
    Some(match value.as_f64() {
        Some(number) if CONDITION_MIRROR.sign[index] < 0.0 => json!(-number),
        _ => value.clone(),
    })
}

/// The whole mirror as the training server's handshake announces it (`mirror`, docs/protocol.md): per
/// feature, observation entry and action entry its partner's index and sign, and per condition field its sign.
pub fn rules_json() -> Value {
    let conditions: serde_json::Map<String, Value> =
        CONDITION_NAMES.iter().zip(CONDITION_MIRROR.sign).map(|(name, sign)| (name.to_string(), json!(sign))).collect();
    json!({
        "features": FEATURE_MIRROR.to_json(),
        "observation": OBSERVATION_MIRROR.to_json(),
        "action": DOF_MIRROR.to_json(),
        "conditions": conditions,
    })
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;
    use crate::contract::character::{Axis, BODY_COUNT, Body, joint_target, targets_from_action};
    use crate::contract::controller::CharacterController;
    use crate::contract::observation::{observation, observation_names};
    use crate::contract::sensing::{BagContact, BodyState, CharacterGeometry, FrameReading};

    fn involution<const N: usize>(mirror: &Mirror<N>, names: &[&str]) {
        for i in 0..N {
            let p = mirror.partner[i];
            assert_eq!(mirror.partner[p], i, "{} -> {} -> {}", names[i], names[p], names[mirror.partner[p]]);
            assert_eq!(mirror.sign[p], mirror.sign[i], "{} and {} differ in sign", names[i], names[p]);
            assert!(mirror.sign[i] == 1.0 || mirror.sign[i] == -1.0);
        }
    }

    #[test]
    fn every_mirror_is_its_own_inverse() {
        involution(&DOF_MIRROR, &DOF_NAMES);
        involution(&FEATURE_MIRROR, &FEATURE_NAMES);
        involution(&OBSERVATION_MIRROR, &observation_names());
        involution(&CONDITION_MIRROR, &CONDITION_NAMES);
    }

    #[test]
    fn a_name_without_a_rule_or_with_two_is_refused_by_name() {
        // The build resolves the real tables (a feature or DOF added without a rule stops it, naming it); the
        // same resolution on a list with a new name:
        let mut names = [""; FEATURE_COUNT + 1];
        names[..FEATURE_COUNT].copy_from_slice(&FEATURE_NAMES);
        names[FEATURE_COUNT] = "fist_r_spin_x";
        assert_eq!(resolve(&names, &FEATURE_RULES, &DOF_RULES), Err(RuleError::NoRule("fist_r_spin_x")));
        let mut dof_names = [""; DOF_COUNT + 1];
        dof_names[..DOF_COUNT].copy_from_slice(&DOF_NAMES);
        dof_names[DOF_COUNT] = "wrist_r_flexion";
        assert_eq!(resolve(&dof_names, &DOF_RULES, &[]), Err(RuleError::NoRule("wrist_r_flexion")));
        // A DOF added with a rule but no angle feature, or a right entry without its left partner:
        let mut more_rules = [own("x", Kind::Same); DOF_RULES.len() + 1];
        more_rules[..DOF_RULES.len()].copy_from_slice(&DOF_RULES);
        more_rules[DOF_RULES.len()] = pair("wrist_r_flexion", "wrist_l_flexion", Kind::Same);
        assert_eq!(resolve(&dof_names, &more_rules, &[]), Err(RuleError::NoPartner("wrist_r_flexion")));
        let twice = [own("bag_pos", Kind::Polar), own("bag_pos", Kind::Axial)];
        assert_eq!(resolve(&["bag_pos_x"], &twice, &[]), Err(RuleError::TwoRules("bag_pos_x")));
        assert_eq!(RuleError::NoPartner("a").name(), "a");
    }

    #[test]
    fn the_features_right_and_left_partners_are_consistent() {
        for (i, name) in FEATURE_NAMES.iter().enumerate() {
            let partner = FEATURE_NAMES[FEATURE_MIRROR.partner[i]];
            let swapped: String = if name.contains("_r_") {
                name.replace("_r_", "_l_")
            } else if name.contains("_l_") {
                name.replace("_l_", "_r_")
            } else {
                name.to_string()
            };
            assert_eq!(partner, swapped, "{name}");
            // Lateral components of polar vectors flip; so do the axial vectors' y and z, and the joint
            // rotations about Y and Z (checked against the DOFs below).
            let polar = ["pos", "vel", "impulse", "momentum_change"].iter().any(|q| name.contains(q));
            if polar && !name.starts_with("speed") {
                assert_eq!(FEATURE_MIRROR.sign[i] < 0.0, name.ends_with("_x"), "{name}");
            }
        }
        let spin = |axis: &str| {
            FEATURE_MIRROR.sign[crate::contract::sensing::feature_index(&format!("root_spin_{axis}")).expect("feature")]
        };
        assert_eq!((spin("x"), spin("y"), spin("z")), (1.0, -1.0, -1.0));
    }

    #[test]
    fn a_dofs_sign_is_its_axis_sign_for_an_axial_vector_and_its_partner_is_the_other_sides_joint() {
        for (i, dof) in DOFS.iter().enumerate() {
            let partner = &DOFS[DOF_MIRROR.partner[i]];
            assert_eq!(DOF_MIRROR.sign[i] < 0.0, dof.axis != Axis::X, "{}", dof.name);
            assert_eq!(partner.axis, dof.axis, "{}", dof.name);
            assert_eq!(partner.max_torque_nm, dof.max_torque_nm, "{}", dof.name);
            for prefix in ["angle_", "speed_"] {
                let feature =
                    crate::contract::sensing::feature_index(&format!("{prefix}{}", dof.name)).expect("feature");
                assert_eq!(FEATURE_NAMES[FEATURE_MIRROR.partner[feature]], format!("{prefix}{}", partner.name));
                assert_eq!(FEATURE_MIRROR.sign[feature], DOF_MIRROR.sign[i]);
            }
        }
    }

    #[test]
    fn limits_map_onto_limits() {
        for (i, dof) in DOFS.iter().enumerate() {
            let partner = &DOFS[DOF_MIRROR.partner[i]];
            let (lower, upper) = if DOF_MIRROR.sign[i] < 0.0 {
                (-dof.upper_rad, -dof.lower_rad)
            } else {
                (dof.lower_rad, dof.upper_rad)
            };
            // Exact: the left limits are written as the negated right ones.
            assert_eq!((partner.lower_rad, partner.upper_rad), (lower, upper), "{} -> {}", dof.name, partner.name);
        }
        let upper = targets_from_action(&[1.0; DOF_COUNT]).expect("valid");
        let lower = targets_from_action(&[-1.0; DOF_COUNT]).expect("valid");
        let mirrored_upper = mirror_targets(&upper);
        for i in 0..DOF_COUNT {
            assert!(mirrored_upper[i] == upper[i] || mirrored_upper[i] == lower[i], "{}", DOF_NAMES[i]);
        }
    }

    #[test]
    fn the_observation_mirror_is_the_observed_features_mirror_with_the_phase_unchanged() {
        let features: [f32; FEATURE_COUNT] =
            std::array::from_fn(|i| (i as f32 + 1.0) * if i % 3 == 0 { -1.0 } else { 1.0 });
        let direct = mirror_observation(&observation(&features, 4, 10));
        let through_features = observation(&mirror_features(&features), 4, 10);
        assert_eq!(direct, through_features);
        assert_eq!(direct[OBS_DIM - 1], 0.4);
    }

    #[test]
    fn the_handshake_carries_every_table() {
        let rules = rules_json();
        assert_eq!(rules["features"]["partner"].as_array().map(Vec::len), Some(FEATURE_COUNT));
        assert_eq!(rules["observation"]["sign"].as_array().map(Vec::len), Some(OBS_DIM));
        assert_eq!(rules["action"]["partner"][2], json!(6));
        assert_eq!(rules["conditions"]["side_m"], json!(-1.0));
        assert_eq!(rules["conditions"]["height_m"], json!(1.0));
    }

    #[test]
    fn rotations_mirror_as_reflections() {
        let m = glam::Mat3::from_diagonal(Vec3::new(-1.0, 1.0, 1.0));
        let rotation = Quat::from_euler(glam::EulerRot::YXZ, 0.4, -0.9, 1.3);
        let reflected = m * glam::Mat3::from_quat(rotation) * m;
        let mirrored = glam::Mat3::from_quat(mirror_rotation(rotation));
        assert!((reflected - mirrored).abs().to_cols_array().iter().all(|d| *d < 1e-6));
        let vector = Vec3::new(0.3, -1.2, 0.8);
        assert!(
            (crate::contract::character::rotation_vector(mirror_rotation(Quat::from_scaled_axis(vector)))
                - mirror_axial(vector))
            .length()
                < 1e-6
        );
    }

    /// Body and joint partners: `Body::ALL` and `JOINTS` orders.
    const BODY_PARTNER: [usize; BODY_COUNT] = [0, 1, 4, 5, 2, 3, 6];
    const JOINT_PARTNER: [usize; 5] = [0, 3, 4, 1, 2];

    /// A character as symmetric as the addon's scene (rest rotations about X, right parts at -x, left at +x),
    /// with fists and anchors off their segments' axes so that a wrong sign shows.
    fn symmetric_geometry() -> CharacterGeometry {
        let arm = Quat::from_rotation_x(0.61);
        let forearm = Quat::from_rotation_x(2.7);
        let fist = Vec3::new(-0.01, -0.155, 0.005);
        let (shoulder, upper_arm_top) = (Vec3::new(-0.18, 0.09, 0.01), Vec3::new(-0.004, 0.14, 0.0));
        let (elbow_in_arm, elbow_in_forearm) = (Vec3::new(0.003, -0.14, 0.0), Vec3::new(0.0, 0.1, -0.002));
        CharacterGeometry {
            rest_rotations: [Quat::IDENTITY, Quat::IDENTITY, arm, forearm, arm, forearm, Quat::IDENTITY],
            fist_offsets: [fist, mirror_point(fist)],
            fist_radius_m: 0.045,
            joint_anchors: [
                (Vec3::new(0.0, 0.076, 0.0), Vec3::new(0.0, -0.27, 0.01)),
                (shoulder, upper_arm_top),
                (elbow_in_arm, elbow_in_forearm),
                (mirror_point(shoulder), mirror_point(upper_arm_top)),
                (mirror_point(elbow_in_arm), mirror_point(elbow_in_forearm)),
            ],
            bag_radius_m: 0.175,
            bag_height_m: 1.0,
            bag_mass_kg: 35.0,
            root_rotation: Quat::IDENTITY,
            root_position: Vec3::ZERO,
            pelvis_rest_position: Vec3::new(0.0, 0.98, 0.0),
        }
    }

    fn mirror_body(body: &BodyState) -> BodyState {
        BodyState {
            position: mirror_point(body.position),
            rotation: mirror_rotation(body.rotation),
            linear_velocity: mirror_point(body.linear_velocity),
            angular_velocity: mirror_axial(body.angular_velocity),
        }
    }

    /// The world of a reading reflected across the character's sagittal plane (its root is at the origin).
    fn mirror_reading(reading: &FrameReading) -> FrameReading {
        let mut mirrored = *reading;
        for (b, body) in mirrored.bodies.iter_mut().enumerate() {
            *body = mirror_body(&reading.bodies[BODY_PARTNER[b]]);
        }
        mirrored.bag = mirror_body(&reading.bag);
        for contact in &mut mirrored.contacts {
            *contact = BagContact {
                body: BODY_PARTNER[contact.body],
                point: mirror_point(contact.point),
                impulse: mirror_point(contact.impulse),
            };
        }
        mirrored
    }

    /// A pose with every joint bent and every body moving, a bag swinging, and contacts from both fists and
    /// the torso; `k` varies it.
    fn busy_reading(geometry: &CharacterGeometry, k: f32) -> FrameReading {
        let wave = |i: usize, a: f32| (1.7 * i as f32 + a * k + 0.3).sin();
        let mut reading = FrameReading::default();
        for (i, body) in reading.bodies.iter_mut().enumerate() {
            let turn =
                Quat::from_euler(glam::EulerRot::YXZ, 0.5 * wave(i, 1.0), 0.4 * wave(i, 2.0), 0.3 * wave(i, 3.0));
            *body = BodyState {
                position: Vec3::new(0.2 * wave(i, 4.0), 1.0 + 0.3 * wave(i, 5.0), 0.2 * wave(i, 6.0)),
                rotation: (turn * geometry.rest_rotations[i]).normalize(),
                linear_velocity: Vec3::new(wave(i, 7.0), 2.0 * wave(i, 8.0), 3.0 * wave(i, 9.0)),
                angular_velocity: Vec3::new(4.0 * wave(i, 10.0), 3.0 * wave(i, 11.0), 2.0 * wave(i, 12.0)),
            };
        }
        reading.bodies[Body::Pelvis.index()].rotation = Quat::from_rotation_y(0.2 * k);
        reading.bag = BodyState {
            position: Vec3::new(0.15, 1.35, 0.7 + 0.01 * k),
            rotation: Quat::from_rotation_z(0.1 * k),
            linear_velocity: Vec3::new(0.4, -0.1, 0.8 * k),
            angular_velocity: Vec3::new(0.2, 0.5, -0.3),
        };
        let controller = CharacterController::new(*geometry, 1);
        let [(fist_r, _), (fist_l, _)] = controller.fists(&reading);
        reading.contacts[0] = BagContact {
            body: Body::ForearmR.index(),
            point: fist_r + 0.02 * Vec3::Z,
            impulse: Vec3::new(0.3, 0.1, 2.0),
        };
        reading.contacts[1] =
            BagContact { body: Body::ForearmL.index(), point: fist_l, impulse: Vec3::new(-0.5, 0.2, k) };
        reading.contacts[2] =
            BagContact { body: Body::Torso.index(), point: Vec3::ONE, impulse: Vec3::new(0.1, 0.0, 0.4) };
        reading.contact_count = 3;
        reading
    }

    #[test]
    fn a_mirrored_world_senses_the_mirrored_features_and_drives_the_mirrored_joints() {
        // The controllers of a character and of its mirror image, fed the mirrored actions and readings, frame
        // after frame: the mirror image senses the mirrored features and commands the mirrored motors.
        let geometry = symmetric_geometry();
        let (mut plain, mut mirrored) = (CharacterController::new(geometry, 3), CharacterController::new(geometry, 3));
        for frame in 0..4 {
            let action: [f32; DOF_COUNT] = std::array::from_fn(|i| (0.9 * i as f32 + frame as f32).sin());
            let executed = plain.set_action(&action).expect("valid");
            let executed_mirrored = mirrored.set_action(&mirror_action(&action)).expect("valid");
            assert_eq!(executed_mirrored, mirror_action(&executed), "smoothing commutes with the mirror");
            let reading = busy_reading(&geometry, frame as f32);
            let features = plain.features(&reading);
            let sensed = mirrored.features(&mirror_reading(&reading));
            let expected = mirror_features(&features);
            for (i, name) in FEATURE_NAMES.iter().enumerate() {
                assert!(
                    (sensed[i] - expected[i]).abs() < 1e-4,
                    "{name}: {} mirrored, {} sensed",
                    expected[i],
                    sensed[i]
                );
            }
            assert!(features[crate::contract::sensing::columns::FIST_R_IMPULSE + 2] != 0.0, "the right fist hit");
            let commands = plain.motor_commands(&reading);
            let commands_mirrored = mirrored.motor_commands(&mirror_reading(&reading));
            for joint in 0..5 {
                let expected = mirror_axial(commands[JOINT_PARTNER[joint]]);
                assert!(
                    (commands_mirrored[joint] - expected).length() < 1e-4,
                    "joint {joint}: {expected} {}",
                    commands_mirrored[joint]
                );
            }
        }
    }

    #[test]
    fn the_mirrored_targets_are_the_mirrored_joint_rotations() {
        let targets = targets_from_action(&[0.3, -0.6, 0.4, -0.1, 0.9, 0.6, -0.5, 0.7, 0.3, -0.4]).expect("valid");
        let mirrored = mirror_targets(&targets);
        for (joint, partner) in JOINT_PARTNER.into_iter().enumerate() {
            let expected = mirror_rotation(joint_target(partner, &targets));
            assert!(joint_target(joint, &mirrored).angle_between(expected) < 1e-6, "joint {joint}");
        }
    }

    proptest! {
        #[test]
        fn mirroring_twice_is_the_identity(
            features in prop::array::uniform32(-10.0f32..10.0),
            more in prop::array::uniform32(-10.0f32..10.0),
            action in prop::array::uniform10(-1.5f32..1.5),
        ) {
            let mut all = [0.0f32; FEATURE_COUNT];
            all[..32].copy_from_slice(&features);
            all[32..].copy_from_slice(&more[..FEATURE_COUNT - 32]);
            prop_assert_eq!(mirror_features(&mirror_features(&all)), all);
            let obs = observation(&all, 3, 10);
            prop_assert_eq!(mirror_observation(&mirror_observation(&obs)), obs);
            prop_assert_eq!(mirror_action(&mirror_action(&action)), action);
        }

        #[test]
        fn a_mirrored_action_gives_exactly_the_mirrored_targets(action in prop::array::uniform10(-1.5f32..1.5)) {
            let targets = targets_from_action(&action).expect("valid");
            let mirrored = targets_from_action(&mirror_action(&action)).expect("valid");
            prop_assert_eq!(mirrored, mirror_targets(&targets));
        }
    }
}
