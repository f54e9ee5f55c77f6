//! The training server, free of Godot (see `lib.rs`).

pub mod access;
// The training server runs on Linux (the trainer starts headless Linux Godot).
#[cfg(unix)]
pub mod connections;
pub mod log_budget;
pub mod protocol;
pub mod session;
