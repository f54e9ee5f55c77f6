//! The policy contract and what training and the game both run (see `lib.rs`).

pub mod arm_size;
pub mod character;
pub mod controller;
pub mod head_size;
pub mod mirror;
pub mod motion;
pub mod names;
pub mod observation;
pub mod sensing;
pub mod smoothing;
pub mod spec;
pub mod stance;
