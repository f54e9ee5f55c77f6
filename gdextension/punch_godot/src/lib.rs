//! The punch controller's Godot classes. This crate only registers classes and converts engine types;
//! the logic is in `punch_core`.

mod batch;
mod convert;
mod engine_io;
mod punch_character;
mod punch_controller;
mod punch_policy;
mod punch_runtime;
mod punch_training_server;
mod target;
mod training_world;

use godot::prelude::{ExtensionLibrary, gdextension};

struct PunchControllerExtension;

#[gdextension]
unsafe impl ExtensionLibrary for PunchControllerExtension {}
