//! Policy inference with ONNX Runtime (see `lib.rs`).

pub mod policy;
pub mod runtime;
