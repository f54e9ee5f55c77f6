//! The policy observation and the versioned spec that both sides of every boundary check: the training
//! server's handshake, the exported ONNX metadata, and `PunchController` when it loads a model.

use crate::contract::character::{DOF_COUNT, DOFS, MAX_JOINT_SPEED_RAD_S, PHYSICS_HZ, POSITION_GAIN_PER_S};
use crate::contract::names::{ends_with, same, starts_with};
use crate::contract::sensing::{FEATURE_COUNT, FEATURE_NAMES};

/// Bumped whenever the observation, action or feature layout or meaning changes. 2: the root's own velocity
/// and turning are features and observed, and every feature is in the frame of the root as it is at that
/// frame (a character carried by its game while it punches), not as it was when the punch started. 3: the
/// character's arm lengths are features and observed (one policy punches with arms sized to any rig).
pub const OBS_SPEC_VERSION: u32 = 3;

/// Whether the policy sees a feature: all of them except the diagnostics and the reward-only quantities
/// (the whole character's contact impulse, the bag's momentum change, fist-bag distances, the joint gap and
/// the guard flags).
const fn observed(name: &str) -> bool {
    !(starts_with(name, "character_impulse")
        || starts_with(name, "bag_momentum_change")
        || ends_with(name, "_bag_distance")
        || same(name, "joint_gap_max_m")
        || same(name, "exploit_flags"))
}

/// Per feature (`FEATURE_NAMES` order), whether the policy sees it.
pub const OBSERVED: [bool; FEATURE_COUNT] = {
    let mut observed_features = [false; FEATURE_COUNT];
    let mut i = 0;
    while i < FEATURE_COUNT {
        observed_features[i] = observed(FEATURE_NAMES[i]);
        i += 1;
    }
    observed_features
};

/// Size of the observation: the observed features (in feature order, all in the character's frame) plus
/// the episode phase. A test checks it against `observed`.
pub const OBS_DIM: usize = 54;

/// Names of the observation entries, in order. "bag" is the target: a sandbag, or any node in a game.
pub fn observation_names() -> Vec<&'static str> {
    FEATURE_NAMES.iter().copied().filter(|name| observed(name)).chain(["episode_phase"]).collect()
}

/// The observation at a decision: the last frame's observed features plus the episode phase
/// (decision index / decisions per episode, 0 at the first decision).
pub fn observation(features: &[f32; FEATURE_COUNT], decision_index: u32, decisions_per_episode: u32) -> [f32; OBS_DIM] {
    let mut out = [0.0; OBS_DIM];
    let observed_values =
        FEATURE_NAMES.iter().zip(features).filter(|(name, _)| observed(name)).map(|(_, value)| *value);
    for (slot, value) in out.iter_mut().zip(observed_values) {
        *slot = value;
    }
    out[OBS_DIM - 1] = decision_index as f32 / decisions_per_episode.max(1) as f32;
    out
}

/// The canonical text of everything a policy depends on: observation, action, features, rates and drive.
/// Its hash names the spec in handshakes and model metadata.
pub fn spec_text(decision_period: u32) -> String {
    let mut text = format!(
        "punch-spec v{OBS_SPEC_VERSION}\nphysics_hz {PHYSICS_HZ}\ndecision_period {decision_period}\n\
         drive velocity-motor gain {POSITION_GAIN_PER_S} max_speed {MAX_JOINT_SPEED_RAD_S}\nobservation {OBS_DIM}:"
    );
    for name in observation_names() {
        text.push(' ');
        text.push_str(name);
    }
    text.push_str(&format!("\naction {DOF_COUNT}:"));
    for dof in &DOFS {
        text.push_str(&format!(" {}[{:.6},{:.6}]@{}", dof.name, dof.lower_rad, dof.upper_rad, dof.max_torque_nm));
    }
    text.push_str(&format!("\nfeatures {FEATURE_COUNT}:"));
    for name in FEATURE_NAMES {
        text.push(' ');
        text.push_str(name);
    }
    text.push('\n');
    text
}

/// 64-bit FNV-1a of `spec_text`, as 16 hex digits.
pub fn spec_hash(decision_period: u32) -> String {
    let hash = spec_text(decision_period)
        .bytes()
        .fold(0xcbf2_9ce4_8422_2325u64, |hash, byte| (hash ^ byte as u64).wrapping_mul(0x0000_0100_0000_01b3));
    format!("{hash:016x}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn observation_size_matches_the_observed_features() {
        assert_eq!(observation_names().len(), OBS_DIM);
        assert_eq!(FEATURE_NAMES.iter().filter(|name| observed(name)).count() + 1, OBS_DIM);
    }

    use crate::contract::sensing::feature_index;

    #[test]
    fn observation_copies_features_and_phase() {
        let features: [f32; FEATURE_COUNT] = std::array::from_fn(|i| i as f32);
        let obs = observation(&features, 3, 10);
        assert_eq!(obs[0], feature_index("fist_r_pos_x").expect("feature") as f32);
        assert_eq!(obs[OBS_DIM - 2], feature_index("body_shoulder_width_m").expect("feature") as f32);
        assert!((obs[OBS_DIM - 1] - 0.3).abs() < 1e-7);
        assert!(obs.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn hash_is_pinned_and_depends_on_the_decision_period() {
        // The shipped policies' `punch_spec_hash` (tests/policy_gate.rs checks their files): a change to the
        // observation changes it, and every policy must then be retrained.
        assert_eq!(spec_hash(5), "b3b18e1568362141");
        assert_ne!(spec_hash(5), spec_hash(4));
        assert_eq!(spec_hash(5).len(), 16);
    }
}
