//! Writes ONNX protobuf bytes by hand, so tests can build the files a hostile user would: fields written
//! twice, graphs a real exporter never makes. (Field numbers are onnx.proto's.)
#![allow(dead_code)] // each test binary uses a part

pub fn varint(mut value: u64, out: &mut Vec<u8>) {
    while value >= 0x80 {
        out.push((value as u8) | 0x80);
        value >>= 7;
    }
    out.push(value as u8);
}

/// A length-delimited field.
pub fn field(number: u64, body: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    varint((number << 3) | 2, &mut out);
    varint(body.len() as u64, &mut out);
    out.extend_from_slice(body);
    out
}

/// A varint field (negative values as protobuf writes int64).
pub fn int(number: u64, value: i64) -> Vec<u8> {
    let mut out = Vec::new();
    varint(number << 3, &mut out);
    varint(value as u64, &mut out);
    out
}

pub fn text(number: u64, value: &str) -> Vec<u8> {
    field(number, value.as_bytes())
}

/// TensorProto of int64 values.
pub fn tensor_i64(name: &str, dims: &[i64], values: &[i64]) -> Vec<u8> {
    let raw: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    [dims.iter().flat_map(|&d| int(1, d)).collect(), int(2, 7), text(8, name), field(9, &raw)].concat()
}

/// TensorProto of float32 values (raw data).
pub fn tensor_f32(name: &str, dims: &[i64], values: &[f32]) -> Vec<u8> {
    let raw: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    [dims.iter().flat_map(|&d| int(1, d)).collect(), int(2, 1), text(8, name), field(9, &raw)].concat()
}

/// TensorProto of float32 `value` everywhere.
pub fn tensor_fill(name: &str, dims: &[i64], value: f32) -> Vec<u8> {
    let count = dims.iter().product::<i64>() as usize;
    tensor_f32(name, dims, &vec![value; count])
}

/// AttributeProto of type INT.
pub fn attr_int(name: &str, value: i64) -> Vec<u8> {
    [text(1, name), int(3, value), int(20, 2)].concat()
}

/// AttributeProto of type INTS.
pub fn attr_ints(name: &str, values: &[i64]) -> Vec<u8> {
    [text(1, name), values.iter().flat_map(|&v| int(8, v)).collect(), int(20, 7)].concat()
}

/// AttributeProto of type TENSOR.
pub fn attr_tensor(name: &str, tensor: &[u8]) -> Vec<u8> {
    [text(1, name), field(5, tensor), int(20, 4)].concat()
}

/// NodeProto (field 1 of a graph).
pub fn node(op: &str, inputs: &[&str], outputs: &[&str], attributes: &[Vec<u8>]) -> Vec<u8> {
    let body = [
        inputs.iter().flat_map(|i| text(1, i)).collect::<Vec<u8>>(),
        outputs.iter().flat_map(|o| text(2, o)).collect(),
        text(4, op),
        attributes.iter().flat_map(|a| field(5, a)).collect(),
    ]
    .concat();
    field(1, &body)
}

/// ValueInfoProto of a float32 tensor; a dimension of None is the symbolic "batch".
pub fn float_info(name: &str, dims: &[Option<i64>]) -> Vec<u8> {
    let dims: Vec<u8> =
        dims.iter().flat_map(|d| field(1, &d.map_or_else(|| text(2, "batch"), |v| int(1, v)))).collect();
    let tensor_type = [int(1, 1), field(2, &dims)].concat();
    [text(1, name), field(2, &field(1, &tensor_type))].concat()
}

/// GraphProto body: `nodes` (already fields), initializers, the input obs [batch, `width`], `outputs` (each
/// [batch, ?]).
pub fn graph(nodes: &[Vec<u8>], initializers: &[Vec<u8>], width: i64, outputs: &[&str]) -> Vec<u8> {
    [
        nodes.concat(),
        text(2, "policy"),
        initializers.iter().flat_map(|t| field(5, t)).collect(),
        field(11, &float_info("obs", &[None, Some(width)])),
        outputs.iter().flat_map(|o| field(12, &text(1, o))).collect(),
    ]
    .concat()
}

/// ModelProto with `graph` and ONNX opset `opset`.
pub fn model(graph: &[u8], opset: i64) -> Vec<u8> {
    [int(1, 8), field(8, &[text(1, ""), int(2, opset)].concat()), field(7, graph)].concat()
}
