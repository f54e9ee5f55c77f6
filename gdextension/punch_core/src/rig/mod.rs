//! Rig retargeting: a user's skeleton posed from the simulated body (see `lib.rs`).

pub mod bone_map;
pub mod fist;
pub mod skeleton_pose;
pub mod transform;
