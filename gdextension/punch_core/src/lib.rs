//! Godot-free core of the punch controller: everything the training server and the in-game controller
//! share, so that training and game cannot drift.
//!
//! - `spec`: the policy contract (sizes, names, rates, timing, default target), defined once.
//! - `character`, `sensing`, `observation`, `smoothing`, `controller`: the character's control spec, what
//!   it senses each frame, the policy's observation, Eq. 1 smoothing, and the motor law.
//! - `punch`: one punch in a game (decision clock, runtime noise, hits, its end); `session`: the training
//!   server's episodes over N slots; `protocol`: the trainer's wire format; `access`: who may use a server.
//! - `motion`: how training moves a character's root while it punches (walking, turning, a lunge, the bob).
//! - `bone_map`: finds the punching body's bones (hips, spine to chest, neck, head, shoulders, arms, hands) in a
//!   user's skeleton from its bone names and hierarchy (Godot humanoid, Mixamo, Unreal, CMU, MakeHuman, Blender).
//! - `fist`: closes the rig's hands into fists (the finger bones below each hand bend toward the palm, about
//!   axes read from the rest).
//! - `policy`, `model_check`, `runtime`, `noise`: ONNX Runtime inference (of files checked to be plain
//!   feed-forward graphs) and seeded Gaussian noise.
//!
//! Everything here is plain Rust and unit-tested with `cargo test` (with a fake world standing in for the
//! engine); the Godot layer (`punch_godot`) only moves engine data in and out and reports errors.

pub mod access;
pub mod arm_size;
pub mod bone_map;
pub mod character;
// The training server runs on Linux (the trainer starts headless Linux Godot).
#[cfg(unix)]
pub mod connections;
pub mod controller;
pub mod error;
#[cfg(test)]
mod fake_world;
pub mod fist;
pub mod lifecycle;
pub mod log_budget;
pub mod model_check;
pub mod motion;
pub mod noise;
pub mod observation;
pub mod policy;
pub mod policy_gate;
pub mod protocol;
pub mod punch;
pub mod runtime;
pub mod sensing;
pub mod session;
pub mod skeleton_pose;
pub mod smoothing;
pub mod spec;

pub use error::CoreError;
pub use policy::{Policy, Tensor};

/// Version of this crate (and of the extension built on it).
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
