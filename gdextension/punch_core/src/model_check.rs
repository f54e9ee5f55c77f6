//! What a policy file may hold before ONNX Runtime sees it: a file is data, so its graph may use only the
//! plain operators the exporter emits (no control flow such as Loop, If or Scan, no custom domains, no
//! model-local functions), within size limits. Every allowed operator does work bounded by the sizes of its
//! tensors, so with the file size bounded an inference call's time is bounded too.
//!
//! The ONNX protobuf is read directly (only the few fields needed): ModelProto.graph (7) and .functions
//! (25); GraphProto.node (1); NodeProto.op_type (4) and .domain (7).

/// Largest policy file accepted, bytes (the shipped policies are about 120 kB).
pub const MAX_MODEL_BYTES: usize = 16 * 1024 * 1024;
/// Most graph nodes accepted (the shipped policies have about 20).
pub const MAX_NODES: usize = 2000;

/// Operators a policy graph may use: what the exporter emits for a feed-forward actor, and the plain
/// tensor operators an equivalent export could use instead.
pub const ALLOWED_OPERATORS: &[&str] = &[
    "Abs",
    "Add",
    "Cast",
    "Clip",
    "Concat",
    "Constant",
    "Div",
    "Elu",
    "Exp",
    "Flatten",
    "Gather",
    "Gemm",
    "HardTanh",
    "Identity",
    "LeakyRelu",
    "Log",
    "MatMul",
    "Max",
    "Min",
    "Mul",
    "Neg",
    "Pow",
    "Relu",
    "Reshape",
    "Selu",
    "Shape",
    "Sigmoid",
    "Slice",
    "Softplus",
    "Softsign",
    "Split",
    "Sqrt",
    "Squeeze",
    "Sub",
    "Tanh",
    "Transpose",
    "Unsqueeze",
];

/// Checks a policy file's bytes; the error says what is refused and why.
pub fn check_model(bytes: &[u8]) -> Result<(), String> {
    if bytes.len() > MAX_MODEL_BYTES {
        return Err(format!("the file has {} bytes, more than the {MAX_MODEL_BYTES} a policy may have", bytes.len()));
    }
    let mut graph = None;
    for field in Fields::new(bytes) {
        match field? {
            (7, Value::Bytes(body)) => graph = Some(body),
            (25, _) => return Err("the model defines functions of its own; a policy may not".into()),
            _ => {}
        }
    }
    let graph = graph.ok_or("the file holds no ONNX graph")?;
    let mut nodes = 0;
    for field in Fields::new(graph) {
        let (1, Value::Bytes(node)) = field? else { continue };
        nodes += 1;
        if nodes > MAX_NODES {
            return Err(format!("the graph has more than {MAX_NODES} nodes"));
        }
        let (mut operator, mut domain) = (String::new(), String::new());
        for field in Fields::new(node) {
            match field? {
                (4, Value::Bytes(text)) => operator = String::from_utf8_lossy(text).into_owned(),
                (7, Value::Bytes(text)) => domain = String::from_utf8_lossy(text).into_owned(),
                _ => {}
            }
        }
        if !(domain.is_empty() || domain == "ai.onnx") {
            return Err(format!(
                "the graph uses operator '{operator}' of domain '{domain}'; a policy may use only ONNX's own"
            ));
        }
        if !ALLOWED_OPERATORS.contains(&operator.as_str()) {
            return Err(format!(
                "the graph uses operator '{operator}', which a policy may not (control flow and other operators \
                 whose work is not bounded by the file are refused; allowed: {})",
                ALLOWED_OPERATORS.join(", ")
            ));
        }
    }
    if nodes == 0 {
        return Err("the graph has no nodes".into());
    }
    Ok(())
}

/// A protobuf field's value (fixed-width values are skipped; a policy check needs none of them).
enum Value<'a> {
    Number,
    Bytes(&'a [u8]),
}

/// The fields of one protobuf message, in order.
struct Fields<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Fields<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, at: 0 }
    }

    fn varint(&mut self) -> Result<u64, String> {
        let mut value = 0u64;
        for shift in (0..64).step_by(7) {
            let byte = *self.bytes.get(self.at).ok_or("the file is not a valid ONNX model (truncated)")?;
            self.at += 1;
            value |= u64::from(byte & 0x7f) << shift;
            if byte & 0x80 == 0 {
                return Ok(value);
            }
        }
        Err("the file is not a valid ONNX model (bad varint)".into())
    }

    fn skip(&mut self, count: u64) -> Result<&'a [u8], String> {
        let end = usize::try_from(count)
            .ok()
            .and_then(|n| self.at.checked_add(n))
            .filter(|&end| end <= self.bytes.len())
            .ok_or("the file is not a valid ONNX model (a field runs past its end)")?;
        let slice = &self.bytes[self.at..end];
        self.at = end;
        Ok(slice)
    }
}

impl<'a> Iterator for Fields<'a> {
    type Item = Result<(u64, Value<'a>), String>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.at >= self.bytes.len() {
            return None;
        }
        let field = (|| {
            let key = self.varint()?;
            let value = match key & 7 {
                0 => self.varint().map(|_| Value::Number)?,
                1 => self.skip(8).map(|_| Value::Number)?,
                2 => {
                    let length = self.varint()?;
                    Value::Bytes(self.skip(length)?)
                }
                5 => self.skip(4).map(|_| Value::Number)?,
                other => return Err(format!("the file is not a valid ONNX model (wire type {other})")),
            };
            Ok((key >> 3, value))
        })();
        if field.is_err() {
            self.at = self.bytes.len(); // one error, then the end
        }
        Some(field)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn varint(mut value: u64, out: &mut Vec<u8>) {
        while value >= 0x80 {
            out.push((value as u8) | 0x80);
            value >>= 7;
        }
        out.push(value as u8);
    }

    fn field(number: u64, body: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        varint((number << 3) | 2, &mut out);
        varint(body.len() as u64, &mut out);
        out.extend_from_slice(body);
        out
    }

    fn model(operators: &[(&str, &str)]) -> Vec<u8> {
        let graph: Vec<u8> = operators
            .iter()
            .flat_map(|(op, domain)| field(1, &[field(4, op.as_bytes()), field(7, domain.as_bytes())].concat()))
            .collect();
        field(7, &graph)
    }

    #[test]
    fn the_exporters_operators_pass() {
        assert_eq!(check_model(&model(&[("Gemm", ""), ("Tanh", ""), ("Clip", "ai.onnx")])), Ok(()));
    }

    #[test]
    fn control_flow_custom_domains_and_functions_are_refused() {
        for (op, domain, expected) in
            [("Loop", "", "'Loop'"), ("If", "", "'If'"), ("Scan", "", "'Scan'"), ("Tanh", "com.evil", "domain")]
        {
            let error = check_model(&model(&[("Gemm", ""), (op, domain)])).expect_err(op);
            assert!(error.contains(expected), "{error}");
        }
        let with_function = [model(&[("Gemm", "")]), field(25, b"")].concat();
        assert!(check_model(&with_function).expect_err("functions").contains("functions"));
    }

    #[test]
    fn garbage_truncation_and_size_are_refused_without_panicking() {
        assert!(check_model(b"").is_err());
        assert!(check_model(&[0x3a, 0x7f, 0x01]).is_err(), "a field longer than the file");
        assert!(check_model(&[0xff; 12]).is_err(), "an endless varint");
        assert!(check_model(&vec![0u8; MAX_MODEL_BYTES + 1]).expect_err("size").contains("more than"));
        let truncated = model(&[("Gemm", "")]);
        assert!(check_model(&truncated[..truncated.len() - 2]).is_err());
    }
}
