//! The policy observation and the versioned spec that both sides of every boundary check: the training
//! server's handshake, the exported ONNX metadata, and `PunchController` when it loads a model.

use crate::character::{DOFS, DOF_COUNT, MAX_JOINT_SPEED_RAD_S, PHYSICS_HZ, POSITION_GAIN_PER_S};
use crate::sensing::{FEATURE_COUNT, FEATURE_NAMES, feature_index};

/// Bumped whenever the observation, action or feature layout or meaning changes.
pub const OBS_SPEC_VERSION: u32 = 1;

/// Features copied into the observation, in order (all in the character's frame).
const OBSERVED_FEATURES: [&str; 44] = [
    "fist_r_pos_x", "fist_r_pos_y", "fist_r_pos_z", "fist_r_vel_x", "fist_r_vel_y", "fist_r_vel_z",
    "fist_l_pos_x", "fist_l_pos_y", "fist_l_pos_z", "fist_l_vel_x", "fist_l_vel_y", "fist_l_vel_z",
    "fist_r_impulse_x", "fist_r_impulse_y", "fist_r_impulse_z",
    "fist_l_impulse_x", "fist_l_impulse_y", "fist_l_impulse_z",
    "bag_pos_x", "bag_pos_y", "bag_pos_z", "bag_vel_x", "bag_vel_y", "bag_vel_z",
    "angle_waist_flexion", "angle_waist_rotation",
    "angle_shoulder_r_flexion", "angle_shoulder_r_rotation", "angle_shoulder_r_abduction", "angle_elbow_r_extension",
    "angle_shoulder_l_flexion", "angle_shoulder_l_rotation", "angle_shoulder_l_abduction", "angle_elbow_l_extension",
    "speed_waist_flexion", "speed_waist_rotation",
    "speed_shoulder_r_flexion", "speed_shoulder_r_rotation", "speed_shoulder_r_abduction", "speed_elbow_r_extension",
    "speed_shoulder_l_flexion", "speed_shoulder_l_rotation", "speed_shoulder_l_abduction", "speed_elbow_l_extension",
];

/// Size of the observation: the observed features plus the episode phase.
pub const OBS_DIM: usize = OBSERVED_FEATURES.len() + 1;

/// Names of the observation entries, in order. "bag" is the target: a sandbag, or any node in a game.
pub fn observation_names() -> Vec<&'static str> {
    OBSERVED_FEATURES.iter().copied().chain(["episode_phase"]).collect()
}

/// The observation at a decision: the last frame's features plus the episode phase
/// (decision index / decisions per episode, 0 at the first decision).
pub fn observation(features: &[f32; FEATURE_COUNT], decision_index: u32, decisions_per_episode: u32) -> [f32; OBS_DIM] {
    let mut out = [0.0; OBS_DIM];
    for (slot, name) in out.iter_mut().zip(OBSERVED_FEATURES) {
        // The names are checked against FEATURE_NAMES by a test.
        *slot = feature_index(name).map_or(f32::NAN, |i| features[i]);
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
    fn every_observed_feature_exists() {
        for name in OBSERVED_FEATURES {
            assert!(feature_index(name).is_some(), "{name} is not a feature");
        }
    }

    #[test]
    fn observation_copies_features_and_phase() {
        let features: [f32; FEATURE_COUNT] = std::array::from_fn(|i| i as f32);
        let obs = observation(&features, 3, 10);
        assert_eq!(obs[0], feature_index("fist_r_pos_x").expect("feature") as f32);
        assert_eq!(obs[OBS_DIM - 2], feature_index("speed_elbow_l_extension").expect("feature") as f32);
        assert!((obs[OBS_DIM - 1] - 0.3).abs() < 1e-7);
        assert!(obs.iter().all(|v| v.is_finite()));
    }

    #[test]
    fn hash_is_stable_and_depends_on_the_decision_period() {
        assert_eq!(spec_hash(5), spec_hash(5));
        assert_ne!(spec_hash(5), spec_hash(4));
        assert_eq!(spec_hash(5).len(), 16);
    }
}
