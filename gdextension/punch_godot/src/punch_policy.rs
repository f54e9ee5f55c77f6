//! `PunchPolicy`: a policy file as a Godot resource. The addon's `punch_policy_loader.gd` loads `.onnx` files
//! as this class, so the editor lists them as `PunchPolicy`, `PunchController.policy` takes one, and an export
//! packs them like any other resource a scene uses, with no export filter. (The loader is GDScript because the
//! editor asks loaders about files from its scanning thread, and this extension's code runs on the main
//! thread only.)

use std::rc::Rc;

use godot::builtin::{GString, PackedByteArray, PackedFloat32Array, PackedStringArray, VarDictionary};
use godot::classes::{FileAccess, IResource, Resource};
use godot::global::{Error, godot_error};
use godot::obj::WithBaseField;
use godot::prelude::{Base, GodotClass, godot_api};
use punch_core::Policy;
use punch_core::game::policy_gate::PunchingPolicy;

use crate::punch_runtime::ensure_onnx_runtime;

/// A trained policy: an .onnx file from `punch train`, loaded with `load("res://....onnx")` or picked in the
/// inspector (the addon's loader reads .onnx files as this resource). The model runs through ONNX Runtime; its
/// file is read through Godot's file system, so it works inside an exported .pck. A file that is not a
/// model is refused at load with the reason in Godot's log; one that is a model but not a punching policy
/// (wrong input or outputs, no policy contract) is refused, once, by the first `PunchController` that plays
/// it. Also usable on its own to run any model with one float input [batch, n] (`run`).
#[derive(GodotClass)]
#[class(base = Resource, tool)]
pub struct PunchPolicy {
    model: Model,
    base: Base<Resource>,
}

/// What a `PunchPolicy` holds.
enum Model {
    Empty,
    /// A model, not yet checked as a punching policy.
    Loaded(Policy),
    /// A punching policy, shared by every controller that plays this resource (one inference call per tick).
    Punching(Rc<PunchingPolicy>),
    /// Not a punching policy; the reason was logged by the first controller that tried it.
    Refused,
}

#[godot_api]
impl IResource for PunchPolicy {
    fn init(base: Base<Resource>) -> Self {
        Self { model: Model::Empty, base }
    }
}

#[godot_api]
impl PunchPolicy {
    /// Loads the .onnx file at `path` (`res://`, `user://` or absolute). Returns OK, or ERR_FILE_NOT_FOUND,
    /// ERR_CANT_OPEN or ERR_INVALID_DATA with the reason in Godot's log. (`load(path)` in GDScript does this
    /// for you and caches the resource.)
    #[func]
    fn load(&mut self, path: GString) -> Error {
        if !FileAccess::file_exists(&path) {
            godot_error!("PunchPolicy: model file not found: {path}");
            self.model = Model::Empty;
            return Error::ERR_FILE_NOT_FOUND;
        }
        let bytes = FileAccess::get_file_as_bytes(&path);
        if bytes.is_empty() {
            godot_error!("PunchPolicy: could not read model file {path} (or it is empty)");
            self.model = Model::Empty;
            return Error::ERR_CANT_OPEN;
        }
        self.load_model(&bytes, &format!("PunchPolicy '{path}'"))
    }

    /// Loads a policy from the bytes of an .onnx file. Returns OK, ERR_CANT_CREATE when ONNX Runtime could
    /// not be loaded, or ERR_INVALID_DATA when the bytes are not a policy model.
    #[func]
    fn load_from_bytes(&mut self, bytes: PackedByteArray) -> Error {
        self.load_model(&bytes, "PunchPolicy")
    }

    /// True when a model is loaded and ready to run.
    #[func]
    fn is_loaded(&self) -> bool {
        self.read(|_| ()).is_some()
    }

    /// Width n of the model's input [batch, n], or 0 when nothing is loaded.
    #[func]
    fn get_input_width(&self) -> i64 {
        self.read(|p| p.input_width() as i64).unwrap_or(0)
    }

    /// Names of the model's outputs in graph order (empty when nothing is loaded).
    #[func]
    fn get_output_names(&self) -> PackedStringArray {
        let names = self.read(|p| p.output_names().iter().map(|name| GString::from(name.as_str())).collect());
        names.unwrap_or_default()
    }

    /// The model's custom metadata entry `key`, or "" when absent or nothing is loaded.
    #[func]
    fn get_metadata(&self, key: GString) -> GString {
        let value = self.read(|p| p.metadata(&key.to_string())).flatten();
        GString::from(value.unwrap_or_default().as_str())
    }

    /// Runs the model on `batch` rows of `input` (row-major [batch, n]) in one ONNX Runtime call. Returns a
    /// Dictionary from output name to a PackedFloat32Array of [batch, k] values, or an empty Dictionary (with
    /// the reason in Godot's log) when nothing is loaded or the input is wrong.
    #[func]
    fn run(&mut self, input: PackedFloat32Array, batch: i64) -> VarDictionary {
        let mut outputs = VarDictionary::new();
        let result = match &mut self.model {
            Model::Loaded(policy) => policy.run(input.as_slice(), batch.max(0) as usize),
            Model::Punching(shared) => shared.run(input.as_slice(), batch.max(0) as usize),
            Model::Empty => {
                godot_error!("PunchPolicy: run() called with no model loaded");
                return outputs;
            }
            Model::Refused => {
                godot_error!("PunchPolicy: run() called on a model refused as a punching policy");
                return outputs;
            }
        };
        match result {
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

impl PunchPolicy {
    /// The model as a punching policy, checked once (its interface and contract) and then shared. The error
    /// is empty when it was refused before (it was reported then): one message per policy, not per
    /// controller.
    pub fn punching(&mut self) -> Result<Rc<PunchingPolicy>, String> {
        let name = self.base().get_path();
        match std::mem::replace(&mut self.model, Model::Refused) {
            Model::Loaded(policy) => {
                let shared = PunchingPolicy::new(policy).map(Rc::new).map_err(|e| format!("policy '{name}': {e}"))?;
                self.model = Model::Punching(shared.clone());
                Ok(shared)
            }
            Model::Punching(shared) => {
                self.model = Model::Punching(shared.clone());
                Ok(shared)
            }
            Model::Refused => Err(String::new()),
            Model::Empty => {
                self.model = Model::Empty;
                Err(format!("the policy resource '{name}' holds no model (it did not load)"))
            }
        }
    }

    /// Loads a model from `bytes`; errors are logged after `origin` (what was loaded).
    fn load_model(&mut self, bytes: &PackedByteArray, origin: &str) -> Error {
        self.model = Model::Empty;
        if !ensure_onnx_runtime() {
            return Error::ERR_CANT_CREATE;
        }
        match Policy::from_bytes(bytes.as_slice()) {
            Ok(policy) => {
                self.model = Model::Loaded(policy);
                Error::OK
            }
            Err(error) => {
                godot_error!("{origin}: {error}");
                Error::ERR_INVALID_DATA
            }
        }
    }

    fn read<R>(&self, read: impl FnOnce(&Policy) -> R) -> Option<R> {
        match &self.model {
            Model::Loaded(policy) => Some(read(policy)),
            Model::Punching(shared) => Some(shared.read(read)),
            Model::Empty | Model::Refused => None,
        }
    }
}
