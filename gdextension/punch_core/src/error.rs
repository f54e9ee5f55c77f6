//! One error type for the core; the Godot layer turns it into `godot_error!` messages.

use std::path::PathBuf;

/// Everything that can go wrong in the core, with enough context to act on.
#[derive(Debug, thiserror::Error)]
pub enum CoreError {
    /// No ONNX Runtime library (`runtime::LIBRARY_PREFIX`) was found where it was looked for.
    #[error("ONNX Runtime library not found in {dir} (expected a file named {name}*)")]
    RuntimeLibraryMissing { dir: PathBuf, name: &'static str },

    /// The ONNX Runtime library exists but could not be loaded or initialised.
    #[error("could not load ONNX Runtime from {path}: {reason}")]
    RuntimeLoad { path: PathBuf, reason: String },

    /// The runtime was used before `runtime::init` succeeded.
    #[error("ONNX Runtime is not initialised")]
    RuntimeNotInitialised,

    /// The bytes are not a model ONNX Runtime accepts.
    #[error("invalid ONNX model: {0}")]
    InvalidModel(String),

    /// The file holds what a policy file may not (`punch_model_check`), so ONNX Runtime never sees it.
    #[error("invalid ONNX model: {0}")]
    RefusedModel(#[from] punch_model_check::ModelError),

    /// The model loads but does not have the shape of a policy (one float input of shape [batch, n]).
    #[error("model is not a policy: {0}")]
    NotAPolicy(String),

    /// The input given to `Policy::run` does not match the model.
    #[error("bad policy input: {0}")]
    BadInput(String),

    /// The model is a policy but not one a punching character can play (its interface or policy contract).
    #[error("incompatible policy: {0}")]
    IncompatiblePolicy(String),

    /// ONNX Runtime failed while running the model.
    #[error("inference failed: {0}")]
    Inference(String),
}

pub type CoreResult<T> = Result<T, CoreError>;
