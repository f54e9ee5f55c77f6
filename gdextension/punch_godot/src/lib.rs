//! The punch controller's Godot classes. This crate only registers classes and converts engine types;
//! the logic is in `punch_core`.

mod arm_sizing;
mod convert;
mod engine_io;
mod head_sizing;
mod punch_character;
mod punch_controller;
mod punch_controller_registry;
mod punch_moveset;
mod punch_policy;
// Tests' and benchmarks' hooks, off the game classes: debug builds only.
#[cfg(feature = "probe")]
mod punch_probe;
mod punch_runtime;
mod punch_skeleton_modifier;
mod punch_spec;
mod skin;
// Training runs on Linux (the trainer starts headless Linux Godot); the game classes build everywhere.
#[cfg(unix)]
mod punch_training_server;
mod target;
#[cfg(unix)]
mod training_world;

use godot::prelude::{ExtensionLibrary, gdextension};

struct PunchControllerExtension;

#[gdextension]
unsafe impl ExtensionLibrary for PunchControllerExtension {}
