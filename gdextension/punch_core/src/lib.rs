//! Godot-free core of the punch controller.
//!
//! Everything here is plain Rust and unit-tested with `cargo test`: the Godot layer (`punch_godot`) only
//! converts engine types and reports errors. Policy inference lives here so that the training server and
//! the in-game controller run the exact same code.

pub mod character;
pub mod controller;
pub mod error;
pub mod noise;
pub mod observation;
pub mod policy;
pub mod protocol;
pub mod runtime;
pub mod sensing;
pub mod session;
pub mod smoothing;

pub use error::CoreError;
pub use policy::{Policy, Tensor};

/// Version of this crate (and of the extension built on it).
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
