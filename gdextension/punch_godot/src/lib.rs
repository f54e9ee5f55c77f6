//! The punch controller's Godot classes. This crate only registers classes and converts engine types;
//! the logic is in `punch_core`.

mod punch_policy;
mod punch_runtime;

use godot::prelude::{ExtensionLibrary, gdextension};

struct PunchControllerExtension;

#[gdextension]
unsafe impl ExtensionLibrary for PunchControllerExtension {}
