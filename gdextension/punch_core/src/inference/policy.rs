//! A policy is an ONNX model with one float input of shape [batch, obs_dim] and float outputs of shape
//! [batch, k]. Inference for many characters is one call with a larger batch.

use ort::session::{Session, builder::GraphOptimizationLevel};
use ort::value::{TensorRef, ValueType};

use crate::error::{CoreError, CoreResult};
use crate::inference::runtime;
use punch_model_check::check_model;

/// One named output of a policy run, row-major `[batch, width]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Tensor {
    pub name: String,
    pub batch: usize,
    pub width: usize,
    pub data: Vec<f32>,
}

/// A loaded policy model.
pub struct Policy {
    session: Session,
    input_name: String,
    input_width: usize,
    output_names: Vec<String>,
    /// Each output's fixed width k of [batch, k] (None when the model leaves it open).
    output_widths: Vec<Option<usize>>,
}

impl Policy {
    /// Builds a policy from the bytes of an .onnx file (bytes, not a path, so models inside a Godot .pck
    /// work too). Fails if the runtime is not initialised, the bytes are not ONNX, or the model does not have
    /// one float input of shape [batch, n] with a fixed n. The graph is checked first
    /// (`punch_model_check::check_model`): a file with control flow or other operators a policy may not use is
    /// refused before ONNX Runtime sees it.
    pub fn from_bytes(model_bytes: &[u8]) -> CoreResult<Self> {
        let environment = runtime::environment()?;
        if model_bytes.is_empty() {
            return Err(CoreError::InvalidModel("the file is empty".into()));
        }
        check_model(model_bytes)?;
        let invalid = |e: ort::Error| CoreError::InvalidModel(e.to_string());
        let session = Session::builder(environment)
            .map_err(invalid)?
            .with_optimization_level(GraphOptimizationLevel::Level3)
            .map_err(|e| invalid(e.into()))?
            // Godot's worker pool already uses every core; one ORT thread avoids oversubscription.
            .with_intra_threads(1)
            .map_err(|e| invalid(e.into()))?
            .with_inter_threads(1)
            .map_err(|e| invalid(e.into()))?
            .with_intra_op_spinning(false)
            .map_err(|e| invalid(e.into()))?
            .commit_from_memory(model_bytes)
            .map_err(invalid)?;

        let [input] = session.inputs() else {
            return Err(CoreError::NotAPolicy(format!("expected 1 input, found {}", session.inputs().len())));
        };
        let input_width = float_width(input.dtype()).ok_or_else(|| {
            CoreError::NotAPolicy(format!(
                "input '{}' must be float32 of shape [batch, n], found {}",
                input.name(),
                input.dtype()
            ))
        })?;
        let input_name = input.name().to_string();
        let output_names = session.outputs().iter().map(|o| o.name().to_string()).collect();
        let output_widths = session.outputs().iter().map(|o| float_width(o.dtype())).collect();
        Ok(Self { session, input_name, input_width, output_names, output_widths })
    }

    /// Width n of the input `[batch, n]`.
    pub fn input_width(&self) -> usize {
        self.input_width
    }

    /// Name of the model's input.
    pub fn input_name(&self) -> &str {
        &self.input_name
    }

    /// Names of the model's outputs, in graph order.
    pub fn output_names(&self) -> &[String] {
        &self.output_names
    }

    /// Checks the model's interface: its input is `input` of [batch, `input_width`] and its outputs are, in
    /// order, a leading part (at least the first) of `outputs`, each float32 [batch, width].
    pub fn check_interface(&self, input: &str, input_width: usize, outputs: &[(&str, usize)]) -> CoreResult<()> {
        let describe = |names: &[&str]| names.join(", ");
        let wanted: Vec<&str> = outputs.iter().map(|(name, _)| *name).collect();
        if self.input_name != input || self.input_width != input_width {
            return Err(CoreError::NotAPolicy(format!(
                "its input is '{}' [batch, {}]; a policy's is '{input}' [batch, {input_width}]",
                self.input_name, self.input_width
            )));
        }
        let found: Vec<&str> = self.output_names.iter().map(String::as_str).collect();
        if found.is_empty() || found.len() > outputs.len() || found[..] != wanted[..found.len()] {
            return Err(CoreError::NotAPolicy(format!(
                "its outputs are [{}]; a policy's are [{}] in that order (the first alone will do)",
                describe(&found),
                describe(&wanted)
            )));
        }
        for ((name, width), found) in outputs.iter().zip(&self.output_widths) {
            if *found != Some(*width) {
                return Err(CoreError::NotAPolicy(format!("output '{name}' must be float32 [batch, {width}]")));
            }
        }
        Ok(())
    }

    /// A custom metadata entry of the model (written by the exporter), if present.
    pub fn metadata(&self, key: &str) -> Option<String> {
        self.session.metadata().ok().and_then(|m| m.custom(key))
    }

    /// Runs the policy on `batch` rows of `input` (row-major `[batch, input_width]`). Non-finite inputs are
    /// refused: they would only come back as NaN actions.
    pub fn run(&mut self, input: &[f32], batch: usize) -> CoreResult<Vec<Tensor>> {
        if batch == 0 {
            return Err(CoreError::BadInput("batch must be at least 1".into()));
        }
        if input.len() != batch * self.input_width {
            return Err(CoreError::BadInput(format!(
                "expected {batch} x {} = {} values, got {}",
                self.input_width,
                batch * self.input_width,
                input.len()
            )));
        }
        if let Some(index) = input.iter().position(|v| !v.is_finite()) {
            return Err(CoreError::BadInput(format!("value {index} is not finite ({})", input[index])));
        }
        let failed = |e: ort::Error| CoreError::Inference(e.to_string());
        let tensor = TensorRef::from_array_view(([batch, self.input_width], input)).map_err(failed)?;
        let outputs = self.session.run(ort::inputs![self.input_name.as_str() => tensor]).map_err(failed)?;
        let mut result = Vec::with_capacity(self.output_names.len());
        for name in &self.output_names {
            let (shape, data) = outputs[name.as_str()].try_extract_tensor::<f32>().map_err(failed)?;
            let width = data.len() / batch;
            if shape.first().copied() != Some(batch as i64) || width * batch != data.len() {
                return Err(CoreError::Inference(format!(
                    "output '{name}' has shape {shape:?}, expected [{batch}, k]"
                )));
            }
            result.push(Tensor { name: name.clone(), batch, width, data: data.to_vec() });
        }
        Ok(result)
    }
}

/// The fixed width n of a float32 tensor of shape [batch, n], if the type is one.
fn float_width(value_type: &ValueType) -> Option<usize> {
    match value_type {
        ValueType::Tensor { ty: ort::value::TensorElementType::Float32, shape, .. }
            if shape.len() == 2 && shape[1] > 0 =>
        {
            Some(shape[1] as usize)
        }
        _ => None,
    }
}
