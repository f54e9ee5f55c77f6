//! The ONNX messages a policy may hold (onnx.proto's field numbers), read strictly (`proto`) into the few
//! facts the check needs: the opset, the graph's input, initializers, nodes and outputs.

use crate::proto::{Kind, MANY_I32, MANY_I64, MANY_LEN, MANY_VARINT, Message, ONE_I32, ONE_LEN, ONE_VARINT, Schema};

const MODEL: Schema = Schema {
    name: "ModelProto",
    fields: &[
        (1, "ir_version", ONE_VARINT),
        (2, "producer_name", ONE_LEN),
        (3, "producer_version", ONE_LEN),
        (4, "domain", ONE_LEN),
        (5, "model_version", ONE_VARINT),
        (6, "doc_string", ONE_LEN),
        (7, "graph", ONE_LEN),
        (8, "opset_import", MANY_LEN),
        (14, "metadata_props", MANY_LEN),
        (20, "training_info", Kind::Refused("training information")),
        (25, "functions", Kind::Refused("functions of its own")),
        (26, "configuration", Kind::Refused("device configurations")),
    ],
};
const OPSET: Schema =
    Schema { name: "OperatorSetIdProto", fields: &[(1, "domain", ONE_LEN), (2, "version", ONE_VARINT)] };
const ENTRY: Schema = Schema { name: "StringStringEntryProto", fields: &[(1, "key", ONE_LEN), (2, "value", ONE_LEN)] };
const GRAPH: Schema = Schema {
    name: "GraphProto",
    fields: &[
        (1, "node", MANY_LEN),
        (2, "name", ONE_LEN),
        (5, "initializer", MANY_LEN),
        (10, "doc_string", ONE_LEN),
        (11, "input", MANY_LEN),
        (12, "output", MANY_LEN),
        (13, "value_info", MANY_LEN),
        (14, "quantization_annotation", Kind::Refused("quantization annotations")),
        (15, "sparse_initializer", Kind::Refused("sparse initializers")),
        (16, "metadata_props", MANY_LEN),
    ],
};
const NODE: Schema = Schema {
    name: "NodeProto",
    fields: &[
        (1, "input", MANY_LEN),
        (2, "output", MANY_LEN),
        (3, "name", ONE_LEN),
        (4, "op_type", ONE_LEN),
        (5, "attribute", MANY_LEN),
        (6, "doc_string", ONE_LEN),
        (7, "domain", ONE_LEN),
        (8, "overload", Kind::Refused("function overloads")),
        (9, "metadata_props", MANY_LEN),
        (10, "device_configurations", Kind::Refused("device configurations")),
    ],
};
const ATTRIBUTE: Schema = Schema {
    name: "AttributeProto",
    fields: &[
        (1, "name", ONE_LEN),
        (2, "f", ONE_I32),
        (3, "i", ONE_VARINT),
        (4, "s", ONE_LEN),
        (5, "t", ONE_LEN),
        (6, "g", Kind::Refused("a subgraph")),
        (7, "floats", MANY_I32),
        (8, "ints", MANY_VARINT),
        (9, "strings", MANY_LEN),
        (10, "tensors", Kind::Refused("a list of tensors in an attribute")),
        (11, "graphs", Kind::Refused("subgraphs")),
        (13, "doc_string", ONE_LEN),
        (14, "tp", Kind::Refused("a type attribute")),
        (15, "type_protos", Kind::Refused("type attributes")),
        (20, "type", ONE_VARINT),
        (21, "ref_attr_name", Kind::Refused("a function's attribute reference")),
        (22, "sparse_tensor", Kind::Refused("a sparse tensor")),
        (23, "sparse_tensors", Kind::Refused("sparse tensors")),
    ],
};
const TENSOR: Schema = Schema {
    name: "TensorProto",
    fields: &[
        (1, "dims", MANY_VARINT),
        (2, "data_type", ONE_VARINT),
        (3, "segment", Kind::Refused("a tensor segment")),
        (4, "float_data", MANY_I32),
        (5, "int32_data", MANY_VARINT),
        (6, "string_data", Kind::Refused("string data")),
        (7, "int64_data", MANY_VARINT),
        (8, "name", ONE_LEN),
        (9, "raw_data", ONE_LEN),
        (10, "double_data", MANY_I64),
        (11, "uint64_data", Kind::Refused("uint64 data")),
        (12, "doc_string", ONE_LEN),
        (13, "external_data", Kind::Refused("external data (tensors stored in other files)")),
        (14, "data_location", ONE_VARINT),
        (16, "metadata_props", MANY_LEN),
    ],
};
const VALUE_INFO: Schema = Schema {
    name: "ValueInfoProto",
    fields: &[(1, "name", ONE_LEN), (2, "type", ONE_LEN), (3, "doc_string", ONE_LEN), (4, "metadata_props", MANY_LEN)],
};
const TYPE: Schema = Schema {
    name: "TypeProto",
    fields: &[
        (1, "tensor_type", ONE_LEN),
        (4, "sequence_type", Kind::Refused("a sequence type")),
        (5, "map_type", Kind::Refused("a map type")),
        (6, "denotation", ONE_LEN),
        (8, "sparse_tensor_type", Kind::Refused("a sparse tensor type")),
        (9, "optional_type", Kind::Refused("an optional type")),
    ],
};
const TENSOR_TYPE: Schema =
    Schema { name: "TypeProto.Tensor", fields: &[(1, "elem_type", ONE_VARINT), (2, "shape", ONE_LEN)] };
const SHAPE: Schema = Schema { name: "TensorShapeProto", fields: &[(1, "dim", MANY_LEN)] };
const DIMENSION: Schema = Schema {
    name: "TensorShapeProto.Dimension",
    fields: &[(1, "dim_value", ONE_VARINT), (2, "dim_param", ONE_LEN), (3, "denotation", ONE_LEN)],
};

/// ONNX element types a policy's tensors may have, with their sizes in bytes.
pub(super) const FLOAT: i64 = 1;
pub(super) const INT32: i64 = 6;
pub(super) const INT64: i64 = 7;
const ELEMENT_TYPES: &[(i64, usize)] = &[(FLOAT, 4), (INT32, 4), (INT64, 8), (9, 1), (10, 2), (11, 8)];

/// Whether `data_type` is one a policy's tensors may have (float, double, float16, int32, int64, bool).
pub(super) fn allowed_type(data_type: i64) -> bool {
    ELEMENT_TYPES.iter().any(|(t, _)| *t == data_type)
}

/// Known integer contents are kept for tensors up to this many elements (shape arguments are short).
const MAX_KNOWN_INTS: u64 = 4096;

/// A constant tensor: an initializer or a Constant's value.
pub(super) struct Tensor {
    pub name: String,
    pub dims: Vec<u64>,
    /// Its values when it is a short integer tensor (shape arguments).
    pub ints: Option<Vec<i64>>,
}

/// An attribute's value.
pub(super) enum Attribute {
    Float,
    Int(i64),
    Text,
    Tensor(Tensor),
    Floats(usize),
    Ints(Vec<i64>),
    Texts,
}

pub(super) struct Node {
    pub op: String,
    pub domain: String,
    pub inputs: Vec<String>,
    pub outputs: Vec<String>,
    pub attributes: Vec<(String, Attribute)>,
}

/// A declared graph input: its name, element type and dimensions (None: no shape declared).
pub(super) struct Input {
    pub name: String,
    pub elem_type: Option<i64>,
    pub dims: Option<Vec<InputDim>>,
}

pub(super) enum InputDim {
    Value(i64),
    /// A named (symbolic) or unnamed dimension.
    Open,
}

pub(super) struct Graph {
    pub nodes: Vec<Node>,
    pub initializers: Vec<Tensor>,
    pub inputs: Vec<Input>,
    pub outputs: Vec<String>,
}

pub(super) struct Model {
    /// The version of ONNX's own operator set ("" / "ai.onnx").
    pub opset: i64,
    pub graph: Graph,
}

/// Reads a model's bytes strictly.
pub(super) fn read_model(bytes: &[u8], max_nodes: usize) -> Result<Model, String> {
    let model = Message::parse(bytes, &MODEL)?;
    let mut opset = None;
    for entry in model.all_bytes(8) {
        let entry = Message::parse(entry, &OPSET)?;
        let domain = entry.text(1)?;
        if domain.is_empty() || domain == "ai.onnx" {
            if opset.is_some() {
                return Err("the model imports ONNX's operator set twice".into());
            }
            opset = Some(entry.int(2).unwrap_or(0));
        }
    }
    let mut keys = Vec::new();
    for entry in model.all_bytes(14) {
        let key = Message::parse(entry, &ENTRY)?.text(1)?;
        if keys.contains(&key) {
            return Err(format!("the model's metadata has the key '{key}' twice (readers differ on which counts)"));
        }
        keys.push(key);
    }
    let graph = model.bytes(7).ok_or("the file holds no ONNX graph")?;
    Ok(Model { opset: opset.ok_or("the model imports no ONNX operator set")?, graph: read_graph(graph, max_nodes)? })
}

fn read_graph(bytes: &[u8], max_nodes: usize) -> Result<Graph, String> {
    let graph = Message::parse(bytes, &GRAPH)?;
    let node_bytes = graph.all_bytes(1);
    if node_bytes.len() > max_nodes {
        return Err(format!("the graph has more than {max_nodes} nodes"));
    }
    let nodes = node_bytes.into_iter().map(read_node).collect::<Result<Vec<_>, _>>()?;
    let initializers = graph.all_bytes(5).into_iter().map(read_tensor).collect::<Result<Vec<_>, _>>()?;
    let inputs = graph.all_bytes(11).into_iter().map(read_input).collect::<Result<Vec<_>, _>>()?;
    let outputs = graph
        .all_bytes(12)
        .into_iter()
        .map(|bytes| read_input(bytes).map(|output| output.name))
        .collect::<Result<Vec<_>, _>>()?;
    for info in graph.all_bytes(13) {
        read_input(info)?; // hints only, but read as strictly as the rest
    }
    for entry in graph.all_bytes(16) {
        Message::parse(entry, &ENTRY)?;
    }
    Ok(Graph { nodes, initializers, inputs, outputs })
}

fn read_node(bytes: &[u8]) -> Result<Node, String> {
    let node = Message::parse(bytes, &NODE)?;
    let op = node.text(4)?;
    let mut attributes: Vec<(String, Attribute)> = Vec::new();
    for attribute in node.all_bytes(5) {
        // Named with the operator: "operator 'Loop': the model holds a subgraph".
        let (name, value) = read_attribute(attribute).map_err(|e| format!("operator '{op}': {e}"))?;
        if attributes.iter().any(|(n, _)| *n == name) {
            return Err(format!("a node has the attribute '{name}' twice"));
        }
        attributes.push((name, value));
    }
    for entry in node.all_bytes(9) {
        Message::parse(entry, &ENTRY)?;
    }
    Ok(Node { op, domain: node.text(7)?, inputs: node.all_text(1)?, outputs: node.all_text(2)?, attributes })
}

fn read_attribute(bytes: &[u8]) -> Result<(String, Attribute), String> {
    let attribute = Message::parse(bytes, &ATTRIBUTE)?;
    let name = attribute.text(1)?;
    // The type says which value counts; a value field of another type is refused, not ignored.
    let (value, field) = match attribute.int(20) {
        Some(1) => (Attribute::Float, 2),
        Some(2) => (Attribute::Int(attribute.int(3).unwrap_or(0)), 3),
        Some(3) => (Attribute::Text, 4),
        Some(4) => (Attribute::Tensor(read_tensor(attribute.bytes(5).ok_or("a tensor attribute has no tensor")?)?), 5),
        Some(6) => (Attribute::Floats(attribute.all_floats(7)?.len()), 7),
        Some(7) => (Attribute::Ints(attribute.all_ints(8)?), 8),
        Some(8) => (Attribute::Texts, 9),
        other => {
            return Err(format!(
                "attribute '{name}' has type {other:?}; a policy's attributes are numbers, texts or tensors"
            ));
        }
    };
    if let Some(extra) = [2, 3, 4, 5, 7, 8, 9].into_iter().find(|&n| n != field && attribute.has(n)) {
        return Err(format!("attribute '{name}' holds a value (field {extra}) of another type than it declares"));
    }
    Ok((name, value))
}

/// Reads a constant tensor and checks that its data matches its shape and type.
pub(super) fn read_tensor(bytes: &[u8]) -> Result<Tensor, String> {
    let tensor = Message::parse(bytes, &TENSOR)?;
    let name = tensor.text(8)?;
    let data_type = tensor.int(2).unwrap_or(0);
    let &(_, size) = ELEMENT_TYPES
        .iter()
        .find(|(t, _)| *t == data_type)
        .ok_or_else(|| format!("tensor '{name}' has element type {data_type}, which a policy may not use"))?;
    if tensor.int(14).unwrap_or(0) != 0 {
        return Err(format!("tensor '{name}' is stored outside the file; a policy's data must be inside it"));
    }
    let mut dims = Vec::new();
    let mut elements: u64 = 1;
    for dim in tensor.all_ints(1)? {
        let dim = u64::try_from(dim).map_err(|_| format!("tensor '{name}' has a negative dimension"))?;
        elements = elements.saturating_mul(dim);
        dims.push(dim);
    }
    let typed = match data_type {
        FLOAT => tensor.count_fixed(4, 4)?,
        INT64 => tensor.all_ints(7)?.len(),
        11 => tensor.count_fixed(10, 8)?,
        _ => tensor.all_ints(5)?.len(), // int32, bool, float16
    };
    let typed_fields = [4, 5, 7, 10].into_iter().filter(|&n| tensor.has(n)).count();
    let stored = match (tensor.bytes(9), typed_fields) {
        (Some(raw), 0) => {
            if raw.len() as u64 != elements.saturating_mul(size as u64) {
                return Err(format!("tensor '{name}' holds {} bytes for {elements} elements", raw.len()));
            }
            elements
        }
        (None, 0 | 1) => typed as u64,
        _ => return Err(format!("tensor '{name}' stores its data in more than one field")),
    };
    if stored != elements {
        return Err(format!("tensor '{name}' holds {stored} values for {elements} elements"));
    }
    let ints = if (data_type == INT64 || data_type == INT32) && elements <= MAX_KNOWN_INTS {
        Some(match tensor.bytes(9) {
            Some(raw) if data_type == INT64 => {
                raw.chunks_exact(8).map(|b| i64::from_le_bytes(b.try_into().expect("8 bytes"))).collect()
            }
            Some(raw) => raw.chunks_exact(4).map(|b| i64::from(i32::from_le_bytes(b.try_into().expect("4")))).collect(),
            None if data_type == INT64 => tensor.all_ints(7)?,
            None => tensor.all_ints(5)?.into_iter().map(|v| i64::from(v as i32)).collect(),
        })
    } else {
        None
    };
    Ok(Tensor { name, dims, ints })
}

fn read_input(bytes: &[u8]) -> Result<Input, String> {
    let info = Message::parse(bytes, &VALUE_INFO)?;
    for entry in info.all_bytes(4) {
        Message::parse(entry, &ENTRY)?;
    }
    let name = info.text(1)?;
    let Some(type_bytes) = info.bytes(2) else { return Ok(Input { name, elem_type: None, dims: None }) };
    let Some(tensor_type) = Message::parse(type_bytes, &TYPE)?.bytes(1) else {
        return Ok(Input { name, elem_type: None, dims: None });
    };
    let tensor_type = Message::parse(tensor_type, &TENSOR_TYPE)?;
    let dims = match tensor_type.bytes(2) {
        None => None,
        Some(shape) => Some(
            Message::parse(shape, &SHAPE)?
                .all_bytes(1)
                .into_iter()
                .map(|dim| {
                    let dim = Message::parse(dim, &DIMENSION)?;
                    match (dim.int(1), dim.has(2)) {
                        (Some(_), true) => Err(format!("input '{name}' has a dimension both fixed and named")),
                        (Some(value), false) => Ok(InputDim::Value(value)),
                        (None, _) => Ok(InputDim::Open),
                    }
                })
                .collect::<Result<Vec<_>, String>>()?,
        ),
    };
    Ok(Input { name, elem_type: tensor_type.int(1), dims })
}
