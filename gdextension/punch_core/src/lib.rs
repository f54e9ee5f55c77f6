//! Godot-free core of the punch controller: everything the training server and the in-game controller
//! share, so that training and game cannot drift. One folder per subsystem; `punch_godot` only moves engine
//! data in and out of them and reports errors.
//!
//! Dependencies point one way: `contract` depends on nothing else here; `rig`, `game` and `training` build on
//! it, and none of them on another; `game` plays policies through `inference`, which has every file checked
//! by the `punch_model_check` crate before ONNX Runtime sees it.
//!
//! Everything here is plain Rust and unit-tested with `cargo test` (with a fake world standing in for the
//! engine).

/// The policy contract and what training and the game both run, defined once: sizes, names, rates and the
/// spec hash (`spec`), the character's bodies and joints (`character`), what it senses each frame
/// (`sensing`), the policy's observation (`observation`), Eq. 1 smoothing (`smoothing`), the motor law
/// (`controller`), the arms' sizes (`arm_size`), how training moves a character's root (`motion`), the mirror
/// that turns a policy of one hand into one of the other (`mirror`, its tables resolved by name: `names`), and the
/// stances' guards (`stance`).
pub mod contract;
/// One punch in a game, free of Godot: the punch itself (decision clock, runtime noise, hits, its end:
/// `punch`, `noise`), a controller's phases and events (`lifecycle`), the six moves and which hand throws each
/// (`moves`), and the gate a policy passes before a character plays it, with the batched decisions of every
/// character (`policy_gate`).
pub mod game;
/// Policy inference with ONNX Runtime: the process-wide runtime (`runtime`) and a policy file checked by
/// `punch_model_check` and loaded as a session (`policy`).
pub mod inference;
/// Rig retargeting: finding a user's skeleton's bones (`bone_map`), posing it from the simulated upper body
/// and blending with its animation (`skeleton_pose`), closing its hands into fists (`fist`), and reading the
/// transforms a game gives without trusting them (`transform`: scale 0, mirrored, NaN).
pub mod rig;
/// The training server, free of Godot: its episodes over N slots (`session`), the trainer's wire format
/// (`protocol`), who may use a server (`access`), its sockets (`connections`, Linux) and its log budget
/// (`log_budget`).
pub mod training;

pub mod error;
#[cfg(test)]
mod fake_world;

pub use error::CoreError;
pub use inference::policy::{Policy, Tensor};

/// Version of this crate (and of the extension built on it).
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
