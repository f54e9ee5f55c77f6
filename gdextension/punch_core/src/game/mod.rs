//! One punch in a game, free of Godot (see `lib.rs`).

pub mod lifecycle;
pub mod moves;
pub mod noise;
pub mod policy_gate;
pub mod punch;
