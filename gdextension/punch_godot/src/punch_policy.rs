//! `PunchPolicy`: an ONNX policy loaded through Godot's file system and run batched through ONNX Runtime.

use godot::builtin::{GString, PackedByteArray, PackedFloat32Array, PackedStringArray, VarDictionary};
use godot::classes::{FileAccess, IRefCounted, RefCounted};
use godot::global::{Error, godot_error};
use godot::prelude::{Base, GodotClass, godot_api};
use punch_core::Policy;

use crate::punch_runtime::ensure_onnx_runtime;

/// An ONNX policy: one float input of shape [batch, n], float outputs of shape [batch, k]. Loading reads the
/// file through Godot, so `res://` models work inside an exported .pck too. Errors are reported once in
/// Godot's log and leave the policy unloaded; nothing here stops the game.
#[derive(GodotClass)]
#[class(base = RefCounted)]
pub struct PunchPolicy {
    policy: Option<Policy>,
    base: Base<RefCounted>,
}

#[godot_api]
impl IRefCounted for PunchPolicy {
    fn init(base: Base<RefCounted>) -> Self {
        Self { policy: None, base }
    }
}

#[godot_api]
impl PunchPolicy {
    /// Loads the .onnx file at `path` (`res://`, `user://` or absolute). Returns OK, or ERR_FILE_NOT_FOUND,
    /// ERR_CANT_OPEN or ERR_INVALID_DATA with the reason in Godot's log.
    #[func]
    fn load(&mut self, path: GString) -> Error {
        if !FileAccess::file_exists(&path) {
            godot_error!("PunchPolicy: model file not found: {path}");
            self.policy = None;
            return Error::ERR_FILE_NOT_FOUND;
        }
        let bytes = FileAccess::get_file_as_bytes(&path);
        if bytes.is_empty() {
            godot_error!("PunchPolicy: could not read model file {path} (or it is empty)");
            self.policy = None;
            return Error::ERR_CANT_OPEN;
        }
        self.load_from_bytes(bytes)
    }

    /// Loads a policy from the bytes of an .onnx file. Returns OK, ERR_CANT_CREATE when ONNX Runtime could
    /// not be loaded, or ERR_INVALID_DATA when the bytes are not a policy model.
    #[func]
    fn load_from_bytes(&mut self, bytes: PackedByteArray) -> Error {
        self.policy = None;
        if !ensure_onnx_runtime() {
            return Error::ERR_CANT_CREATE;
        }
        match Policy::from_bytes(bytes.as_slice()) {
            Ok(policy) => {
                self.policy = Some(policy);
                Error::OK
            }
            Err(error) => {
                godot_error!("PunchPolicy: {error}");
                Error::ERR_INVALID_DATA
            }
        }
    }

    /// True when a model is loaded and ready to run.
    #[func]
    fn is_loaded(&self) -> bool {
        self.policy.is_some()
    }

    /// Width n of the model's input [batch, n], or 0 when nothing is loaded.
    #[func]
    fn get_input_width(&self) -> i64 {
        self.policy.as_ref().map_or(0, |p| p.input_width() as i64)
    }

    /// Names of the model's outputs in graph order (empty when nothing is loaded).
    #[func]
    fn get_output_names(&self) -> PackedStringArray {
        let names = self.policy.as_ref().map(|p| p.output_names()).unwrap_or_default();
        names.iter().map(|name| GString::from(name.as_str())).collect()
    }

    /// The model's custom metadata entry `key`, or "" when absent or nothing is loaded.
    #[func]
    fn get_metadata(&self, key: GString) -> GString {
        let value = self.policy.as_ref().and_then(|p| p.metadata(&key.to_string()));
        GString::from(value.unwrap_or_default().as_str())
    }

    /// Runs the model on `batch` rows of `input` (row-major [batch, n]) in one ONNX Runtime call. Returns a
    /// Dictionary from output name to a PackedFloat32Array of [batch, k] values, or an empty Dictionary (with
    /// the reason in Godot's log) when nothing is loaded or the input is wrong.
    #[func]
    fn run(&mut self, input: PackedFloat32Array, batch: i64) -> VarDictionary {
        let mut outputs = VarDictionary::new();
        let Some(policy) = self.policy.as_mut() else {
            godot_error!("PunchPolicy: run() called with no model loaded");
            return outputs;
        };
        match policy.run(input.as_slice(), batch.max(0) as usize) {
            Ok(tensors) => {
                for tensor in tensors {
                    outputs.set(tensor.name.as_str(), &PackedFloat32Array::from(tensor.data.as_slice()));
                }
            }
            Err(error) => godot_error!("PunchPolicy: {error}"),
        }
        outputs
    }
}
