//! Static shape inference through the operators a policy may use, with the work each node does.
//!
//! The batch dimension is a symbol (`Dim::Batch`): a value holds it at most once and only as a whole
//! dimension (never merged into another, concatenated, sliced or contracted over), so each row of a call is
//! one character's decision and a call of B rows costs B times a row's work plus the batch-independent work.
//! Every dimension else is a number the check computes; a shape it cannot compute (a Reshape to a shape
//! computed at run time, say) is refused. Short integer tensors (shape arguments) are followed by value,
//! including `Shape` of a value with the batch dimension.

use std::collections::HashMap;

use crate::onnx::{Attribute, FLOAT, Graph, INT32, INT64, InputDim, Node, allowed_type};

#[derive(Clone, Copy, PartialEq, Debug)]
enum Dim {
    N(u64),
    Batch,
}

/// An element of a known integer tensor: a number, or the batch size (from `Shape`).
#[derive(Clone, Copy, PartialEq, Debug)]
enum Int {
    K(i64),
    Batch,
}

#[derive(Clone, Debug)]
struct Value {
    dims: Vec<Dim>,
    ints: Option<Vec<Int>>,
}

/// Most dimensions a value may have.
const MAX_RANK: usize = 8;

/// What a model costs, as the check infers it (elements and multiply-adds; see `model_check`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ModelCost {
    /// Elements of the largest value with the batch dimension, per row.
    pub largest_row_elements: u64,
    /// Elements of the largest value without it (initializers, constants, what is computed from them).
    pub largest_shared_elements: u64,
    /// Work per row: multiply-adds of Gemm and MatMul plus every element written by any node, weighted by
    /// its operator's cost (`weight`).
    pub row_work: u64,
    /// Work done once per call (or once at load, where ONNX Runtime folds constants).
    pub shared_work: u64,
}

/// The limits `infer` holds a model to.
pub(super) struct Bounds {
    pub row_elements: u64,
    pub shared_elements: u64,
    pub row_work: u64,
    pub shared_work: u64,
}

/// Infers every value's shape and the model's cost; refuses what it cannot infer or what exceeds `bounds`.
pub(super) fn infer(graph: &Graph, opset: i64, allowed: &[&str], bounds: &Bounds) -> Result<ModelCost, String> {
    let mut values: HashMap<&str, Value> = HashMap::new();
    let mut cost = ModelCost::default();
    for tensor in &graph.initializers {
        let value = Value {
            dims: tensor.dims.iter().map(|&d| Dim::N(d)).collect(),
            ints: tensor.ints.as_ref().map(|v| v.iter().map(|&k| Int::K(k)).collect()),
        };
        account(&mut cost, &value, 0, 1, bounds).map_err(|e| format!("initializer '{}': {e}", tensor.name))?;
        if values.insert(&tensor.name, value).is_some() {
            return Err(format!("the graph defines '{}' twice", tensor.name));
        }
    }
    let fed: Vec<_> = graph.inputs.iter().filter(|input| !values.contains_key(input.name.as_str())).collect();
    let [input] = fed[..] else {
        return Err(format!("the graph has {} inputs; a policy has one, [batch, n]", fed.len()));
    };
    match (&input.elem_type, input.dims.as_deref()) {
        (Some(FLOAT), Some([first, InputDim::Value(width)])) if *width > 0 => {
            let first = match first {
                InputDim::Open => Dim::Batch,
                InputDim::Value(rows) if *rows > 0 => Dim::N(*rows as u64),
                InputDim::Value(_) => return Err("the input's batch dimension is 0 or negative".into()),
            };
            let value = Value { dims: vec![first, Dim::N(*width as u64)], ints: None };
            account(&mut cost, &value, 0, 1, bounds).map_err(|e| format!("the input: {e}"))?;
            values.insert(&input.name, value);
        }
        _ => return Err(format!("the input '{}' must be float32 of shape [batch, n] with a fixed n", input.name)),
    }
    for (index, node) in graph.nodes.iter().enumerate() {
        let at = |e: String| format!("node {index} ({}): {e}", node.op);
        if !(node.domain.is_empty() || node.domain == "ai.onnx") {
            return Err(format!(
                "the graph uses operator '{}' of domain '{}'; a policy may use only ONNX's own",
                node.op, node.domain
            ));
        }
        if !allowed.contains(&node.op.as_str()) {
            return Err(format!(
                "the graph uses operator '{}', which a policy may not (control flow and other operators whose \
                 work the check cannot bound are refused; allowed: {})",
                node.op,
                allowed.join(", ")
            ));
        }
        let inputs = node
            .inputs
            .iter()
            .map(|name| match name.as_str() {
                "" => Ok(None),
                name => values
                    .get(name)
                    .map(Some)
                    .ok_or_else(|| format!("uses '{name}' before it is defined (nodes must be in order)")),
            })
            .collect::<Result<Vec<_>, _>>()
            .map_err(at)?;
        let (outputs, multiply_adds) = infer_node(node, &inputs, opset).map_err(at)?;
        if outputs.len() != node.outputs.len() {
            return Err(at(format!("names {} outputs; it has {}", node.outputs.len(), outputs.len())));
        }
        for (name, value) in node.outputs.iter().zip(outputs) {
            if name.is_empty() {
                continue;
            }
            account(&mut cost, &value, multiply_adds, weight(&node.op), bounds)
                .map_err(|e| at(format!("'{name}' {e}")))?;
            if values.insert(name, value).is_some() {
                return Err(at(format!("defines '{name}', which the graph already has")));
            }
        }
    }
    if graph.nodes.is_empty() {
        return Err("the graph has no nodes".into());
    }
    for output in &graph.outputs {
        if !values.contains_key(output.as_str()) {
            return Err(format!("the graph's output '{output}' is not computed by the graph"));
        }
    }
    Ok(cost)
}

/// Elements of `dims` other than the batch dimension, and how many batch dimensions it has.
fn split(dims: &[Dim]) -> (u64, usize) {
    dims.iter().fold((1u64, 0), |(product, batches), dim| match dim {
        Dim::N(n) => (product.saturating_mul(*n), batches),
        Dim::Batch => (product, batches + 1),
    })
}

/// Work units per element an operator writes, one unit being a multiply-add of Gemm or MatMul. Measured
/// with ONNX Runtime 1.31 on one thread of an AMD EPYC (`tests/model_check.rs`,
/// `measure_the_elementwise_operators`): a multiply-add takes about 0.05 ns, an element of a plain operator
/// up to 0.45 ns, of Sqrt, Exp, Sigmoid, Softsign or Tanh up to 1.6, of Log, Elu or Selu up to 5.4, of Pow
/// 7.5 and of Softplus 25. Each weight is at least that time over 0.05 ns.
pub(super) fn weight(op: &str) -> u64 {
    match op {
        "Tanh" | "Sigmoid" | "Softsign" | "Sqrt" | "Exp" => 32,
        "Log" | "Elu" | "Selu" => 128,
        "Pow" => 256,
        "Softplus" => 512,
        _ => 16,
    }
}

/// Adds a node's output `value` (`weight` units per element, plus `multiply_adds`) to `cost` and checks
/// the bounds.
fn account(
    cost: &mut ModelCost,
    value: &Value,
    multiply_adds: u64,
    weight: u64,
    bounds: &Bounds,
) -> Result<(), String> {
    if value.dims.len() > MAX_RANK {
        return Err(format!("has {} dimensions, more than {MAX_RANK}", value.dims.len()));
    }
    let (elements, batches) = split(&value.dims);
    let work = elements.saturating_mul(weight).saturating_add(multiply_adds);
    match batches {
        0 => {
            cost.largest_shared_elements = cost.largest_shared_elements.max(elements);
            cost.shared_work = cost.shared_work.saturating_add(work);
            if elements > bounds.shared_elements {
                return Err(format!(
                    "has {elements} elements, more than the {} a batch-independent value may have",
                    bounds.shared_elements
                ));
            }
            if cost.shared_work > bounds.shared_work {
                return Err(format!(
                    "brings the batch-independent work to {}, more than the {} a policy may do",
                    cost.shared_work, bounds.shared_work
                ));
            }
        }
        1 => {
            cost.largest_row_elements = cost.largest_row_elements.max(elements);
            cost.row_work = cost.row_work.saturating_add(work);
            if elements > bounds.row_elements {
                return Err(format!(
                    "has {elements} elements per row, more than the {} a policy's value may have",
                    bounds.row_elements
                ));
            }
            if cost.row_work > bounds.row_work {
                return Err(format!(
                    "brings the work per row (multiply-adds and weighted elements written) to {}, more than the {} a \
                     policy may do",
                    cost.row_work, bounds.row_work
                ));
            }
        }
        _ => return Err(mixes_rows()),
    }
    Ok(())
}

fn mixes_rows() -> String {
    "would combine rows of the batch (a policy decides each row alone, and the check bounds work per row)".into()
}

fn attribute<'a>(node: &'a Node, name: &str) -> Option<&'a Attribute> {
    node.attributes.iter().find(|(n, _)| n == name).map(|(_, a)| a)
}

fn int_attribute(node: &Node, name: &str, default: Option<i64>) -> Result<i64, String> {
    match attribute(node, name) {
        Some(Attribute::Int(value)) => Ok(*value),
        Some(_) => Err(format!("attribute '{name}' must be an integer")),
        None => default.ok_or_else(|| format!("needs the attribute '{name}'")),
    }
}

/// `axis` in [-rank, rank) (or [-rank, rank] when `inclusive`) as an index.
fn normalise(axis: i64, rank: usize, inclusive: bool) -> Result<usize, String> {
    let rank = rank as i64;
    let axis_index = if axis < 0 { axis + rank } else { axis };
    let top = if inclusive { rank } else { rank - 1 };
    if (0..=top).contains(&axis_index) {
        Ok(axis_index as usize)
    } else {
        Err(format!("axis {axis} is out of range for rank {rank}"))
    }
}

/// The numbers of a constant integer input the check can read (shape arguments).
fn constants(value: &Value, what: &str) -> Result<Vec<i64>, String> {
    let ints = value.ints.as_ref().ok_or_else(|| {
        format!("its {what} must be a constant the check can read (a shape computed at run time cannot be bounded)")
    })?;
    ints.iter()
        .map(|i| match i {
            Int::K(k) => Ok(*k),
            Int::Batch => Err(format!("its {what} depends on the batch size")),
        })
        .collect()
}

fn broadcast(a: &[Dim], b: &[Dim]) -> Result<Vec<Dim>, String> {
    let rank = a.len().max(b.len());
    let at = |dims: &[Dim], i: usize| if i < rank - dims.len() { Dim::N(1) } else { dims[i - (rank - dims.len())] };
    (0..rank)
        .map(|i| match (at(a, i), at(b, i)) {
            (x, y) if x == y => Ok(x),
            (Dim::N(1), y) => Ok(y),
            (x, Dim::N(1)) => Ok(x),
            (Dim::Batch, _) | (_, Dim::Batch) => Err(mixes_rows()),
            _ => Err(format!("shapes {a:?} and {b:?} do not broadcast")),
        })
        .collect()
}

/// The product of `dims` as one dimension (Flatten): the batch dimension only alone or with ones.
fn product(dims: &[Dim]) -> Result<Dim, String> {
    match split(dims) {
        (n, 0) => Ok(Dim::N(n)),
        (1, 1) => Ok(Dim::Batch),
        _ => Err("would merge the batch dimension with another (rows of the batch would mix)".into()),
    }
}

/// Elements of `dims` counting the batch dimension as 1 (the work per row).
fn elements(dims: &[Dim]) -> u64 {
    split(dims).0
}

const UNARY: &[&str] = &[
    "Abs",
    "Elu",
    "Exp",
    "LeakyRelu",
    "Log",
    "Neg",
    "Relu",
    "Selu",
    "Sigmoid",
    "Softplus",
    "Softsign",
    "Sqrt",
    "Tanh",
];

/// A node's output values and its multiply-adds.
fn infer_node(node: &Node, inputs: &[Option<&Value>], opset: i64) -> Result<(Vec<Value>, u64), String> {
    let arity = |low: usize, high: usize| {
        if (low..=high).contains(&inputs.len()) {
            Ok(())
        } else {
            Err(format!("has {} inputs; it takes {low} to {high}", inputs.len()))
        }
    };
    let input = |i: usize| inputs.get(i).copied().flatten().ok_or_else(|| format!("needs input {i}"));
    let optional = |i: usize| inputs.get(i).copied().flatten();
    let shaped = |dims: Vec<Dim>| Ok((vec![Value { dims, ints: None }], 0));
    let op = node.op.as_str();
    match op {
        _ if UNARY.contains(&op) => {
            arity(1, 1)?;
            shaped(input(0)?.dims.clone())
        }
        "Identity" => {
            arity(1, 1)?;
            Ok((vec![input(0)?.clone()], 0))
        }
        "Cast" => {
            arity(1, 1)?;
            let to = int_attribute(node, "to", None)?;
            if !allowed_type(to) {
                return Err(format!("casts to element type {to}, which a policy may not use"));
            }
            let value = input(0)?;
            let ints = if to == INT64 || to == INT32 { value.ints.clone() } else { None };
            Ok((vec![Value { dims: value.dims.clone(), ints }], 0))
        }
        "Clip" => {
            arity(1, 3)?;
            for bound in [optional(1), optional(2)].into_iter().flatten() {
                if bound.dims.iter().any(|d| *d != Dim::N(1)) {
                    return Err("its min and max must be single values".into());
                }
            }
            shaped(input(0)?.dims.clone())
        }
        "Add" | "Sub" | "Mul" | "Div" | "Pow" => {
            arity(2, 2)?;
            shaped(broadcast(&input(0)?.dims, &input(1)?.dims)?)
        }
        "Max" | "Min" => {
            arity(1, usize::MAX)?;
            let mut dims = input(0)?.dims.clone();
            for i in 1..inputs.len() {
                dims = broadcast(&dims, &input(i)?.dims)?;
            }
            // Each input is read once per output element: count them (a Max of many copies is work).
            let reads = elements(&dims).saturating_mul(inputs.len() as u64 - 1).saturating_mul(weight("Max"));
            Ok((vec![Value { dims, ints: None }], reads))
        }
        "Gemm" => {
            arity(2, 3)?;
            let (a, b) = (&input(0)?.dims, &input(1)?.dims);
            let (&[a0, a1], &[b0, b1]) = (&a[..], &b[..]) else {
                return Err("its A and B must be matrices".into());
            };
            let trans = |name| int_attribute(node, name, Some(0)).map(|t| t != 0);
            let (m, k) = if trans("transA")? { (a1, a0) } else { (a0, a1) };
            let (k2, n) = if trans("transB")? { (b1, b0) } else { (b0, b1) };
            contracted(k, k2)?;
            let out = vec![m, n];
            if let Some(c) = optional(2)
                && broadcast(&c.dims, &out)? != out
            {
                return Err("its C does not broadcast to the output".into());
            }
            let multiply_adds = elements(&out).saturating_mul(elements(&[k]));
            Ok((vec![Value { dims: out, ints: None }], multiply_adds))
        }
        "MatMul" => {
            arity(2, 2)?;
            let (mut a, mut b) = (input(0)?.dims.clone(), input(1)?.dims.clone());
            if a.is_empty() || b.is_empty() {
                return Err("multiplies a scalar".into());
            }
            let (a_vector, b_vector) = (a.len() == 1, b.len() == 1);
            if a_vector {
                a.insert(0, Dim::N(1));
            }
            if b_vector {
                b.push(Dim::N(1));
            }
            let k = a[a.len() - 1];
            contracted(k, b[b.len() - 2])?;
            let mut out = broadcast(&a[..a.len() - 2], &b[..b.len() - 2])?;
            let lead = out.len();
            out.extend([a[a.len() - 2], b[b.len() - 1]]);
            if b_vector {
                out.pop();
            }
            if a_vector {
                out.remove(lead);
            }
            let multiply_adds = elements(&out).saturating_mul(elements(&[k]));
            Ok((vec![Value { dims: out, ints: None }], multiply_adds))
        }
        "Concat" => {
            arity(1, usize::MAX)?;
            let values = (0..inputs.len()).map(input).collect::<Result<Vec<_>, _>>()?;
            let rank = values[0].dims.len();
            let axis = normalise(int_attribute(node, "axis", None)?, rank, false)?;
            let mut total = 0u64;
            for value in &values {
                if value.dims.len() != rank {
                    return Err("concatenates values of different ranks".into());
                }
                for (d, (x, y)) in value.dims.iter().zip(&values[0].dims).enumerate() {
                    if d != axis && x != y {
                        return Err(format!("concatenates shapes {:?} and {:?}", values[0].dims, value.dims));
                    }
                }
                match value.dims[axis] {
                    Dim::N(n) => total = total.saturating_add(n),
                    Dim::Batch if values.len() == 1 => {}
                    Dim::Batch => return Err("concatenates along the batch dimension".into()),
                }
            }
            let mut dims = values[0].dims.clone();
            if values.len() > 1 {
                dims[axis] = Dim::N(total);
            }
            let ints = if rank == 1 {
                values.iter().map(|v| v.ints.clone()).collect::<Option<Vec<_>>>().map(|v| v.concat())
            } else {
                None
            };
            Ok((vec![Value { dims, ints }], 0))
        }
        "Constant" => {
            arity(0, 0)?;
            let [(name, value)] = &node.attributes[..] else {
                return Err("must have exactly one attribute, its value".into());
            };
            let value = match (name.as_str(), value) {
                ("value", Attribute::Tensor(tensor)) => Value {
                    dims: tensor.dims.iter().map(|&d| Dim::N(d)).collect(),
                    ints: tensor.ints.as_ref().map(|v| v.iter().map(|&k| Int::K(k)).collect()),
                },
                ("value_float", Attribute::Float) => Value { dims: vec![], ints: None },
                ("value_floats", Attribute::Floats(count)) => Value { dims: vec![Dim::N(*count as u64)], ints: None },
                ("value_int", Attribute::Int(k)) => Value { dims: vec![], ints: Some(vec![Int::K(*k)]) },
                ("value_ints", Attribute::Ints(v)) => {
                    Value { dims: vec![Dim::N(v.len() as u64)], ints: Some(v.iter().map(|&k| Int::K(k)).collect()) }
                }
                _ => return Err(format!("its value '{name}' is not a numeric tensor")),
            };
            Ok((vec![value], 0))
        }
        "Flatten" => {
            arity(1, 1)?;
            let value = input(0)?;
            let axis = normalise(int_attribute(node, "axis", Some(1))?, value.dims.len(), true)?;
            let dims = vec![product(&value.dims[..axis])?, product(&value.dims[axis..])?];
            Ok((vec![Value { dims, ints: value.ints.clone() }], 0))
        }
        "Gather" => {
            arity(2, 2)?;
            let (data, indices) = (input(0)?, input(1)?);
            let axis = normalise(int_attribute(node, "axis", Some(0))?, data.dims.len(), false)?;
            let Dim::N(length) = data.dims[axis] else { return Err("gathers along the batch dimension".into()) };
            let mut dims = data.dims[..axis].to_vec();
            dims.extend(&indices.dims);
            dims.extend(&data.dims[axis + 1..]);
            let mut ints = None;
            if let (Some(known), Some(picks), 1) = (&data.ints, &indices.ints, data.dims.len()) {
                let picked = picks.iter().map(|pick| match pick {
                    Int::K(k) => {
                        let index = if *k < 0 { k + length as i64 } else { *k };
                        known
                            .get(usize::try_from(index).map_err(|_| "an index out of range".to_string())?)
                            .copied()
                            .ok_or_else(|| "an index out of range".to_string())
                    }
                    Int::Batch => Err("an index that is the batch size".to_string()),
                });
                ints = Some(picked.collect::<Result<Vec<_>, _>>()?);
            }
            Ok((vec![Value { dims, ints }], 0))
        }
        "Reshape" => {
            arity(2, 2)?;
            let (data, shape) = (input(0)?, input(1)?);
            let targets = shape.ints.as_ref().ok_or(
                "its shape must be a constant the check can read (a shape computed at run time cannot be bounded)",
            )?;
            let allow_zero = int_attribute(node, "allowzero", Some(0))? != 0;
            let mut dims = Vec::with_capacity(targets.len());
            let mut inferred = None;
            for (i, target) in targets.iter().enumerate() {
                dims.push(match target {
                    Int::Batch => Dim::Batch,
                    Int::K(-1) if inferred.is_none() => {
                        inferred = Some(i);
                        Dim::N(1)
                    }
                    Int::K(0) if !allow_zero => {
                        *data.dims.get(i).ok_or("copies a dimension the input does not have")?
                    }
                    Int::K(k) if *k >= 0 => Dim::N(*k as u64),
                    Int::K(k) => return Err(format!("has the target dimension {k}")),
                });
            }
            let ((have, have_batches), (want, want_batches)) = (split(&data.dims), split(&dims));
            match inferred {
                None if (have, have_batches) == (want, want_batches) => {}
                Some(i) if have_batches == want_batches && want > 0 && have % want == 0 => {
                    dims[i] = Dim::N(have / want)
                }
                Some(i) if have_batches == want_batches + 1 && have == want => dims[i] = Dim::Batch,
                _ => return Err(format!("cannot reshape {:?} to {targets:?} for every batch size", data.dims)),
            }
            Ok((vec![Value { dims, ints: data.ints.clone() }], 0))
        }
        "Shape" => {
            arity(1, 1)?;
            let dims = &input(0)?.dims;
            let rank = dims.len() as i64;
            let clamp = |v: i64| (if v < 0 { v + rank } else { v }).clamp(0, rank) as usize;
            let start = clamp(int_attribute(node, "start", Some(0))?);
            let end = clamp(int_attribute(node, "end", Some(rank))?).max(start);
            let ints = dims[start..end]
                .iter()
                .map(|d| match d {
                    Dim::N(n) => Int::K(*n as i64),
                    Dim::Batch => Int::Batch,
                })
                .collect::<Vec<_>>();
            Ok((vec![Value { dims: vec![Dim::N(ints.len() as u64)], ints: Some(ints) }], 0))
        }
        "Slice" => {
            arity(3, 5)?;
            let data = input(0)?;
            let rank = data.dims.len();
            let starts = constants(input(1)?, "starts")?;
            let ends = input(2)?.ints.clone().ok_or("its ends must be a constant the check can read")?;
            let axes = match optional(3) {
                Some(axes) => constants(axes, "axes")?,
                None => (0..starts.len() as i64).collect(),
            };
            let steps = match optional(4) {
                Some(steps) => constants(steps, "steps")?,
                None => vec![1; starts.len()],
            };
            if [ends.len(), axes.len(), steps.len()].iter().any(|&n| n != starts.len()) {
                return Err("its starts, ends, axes and steps differ in length".into());
            }
            let mut dims = data.dims.clone();
            let mut ints = data.ints.clone();
            let mut done = Vec::new();
            for (((&start, &end), &axis), &step) in starts.iter().zip(&ends).zip(&axes).zip(&steps) {
                let axis = normalise(axis, rank, false)?;
                if done.contains(&axis) || step == 0 {
                    return Err("repeats an axis or has a step of 0".into());
                }
                done.push(axis);
                match (dims[axis], end) {
                    (Dim::Batch, Int::Batch) if start == 0 && step == 1 => {}
                    (Dim::Batch, Int::K(end)) if start == 0 && step == 1 && end >= i64::from(i32::MAX) => {}
                    (Dim::Batch, _) => return Err("slices the batch dimension".into()),
                    (Dim::N(_), Int::Batch) => return Err("its ends depend on the batch size".into()),
                    (Dim::N(length), Int::K(end)) => {
                        let (first, step, count) = slice_range(length, start, end, step);
                        dims[axis] = Dim::N(count);
                        if rank == 1 {
                            ints = ints
                                .map(|known| (0..count as i128).map(|i| known[(first + i * step) as usize]).collect());
                        }
                    }
                }
            }
            Ok((vec![Value { dims, ints }], 0))
        }
        "Split" => {
            arity(1, 2)?;
            let data = input(0)?;
            let axis = normalise(int_attribute(node, "axis", Some(0))?, data.dims.len(), false)?;
            let Dim::N(length) = data.dims[axis] else { return Err("splits the batch dimension".into()) };
            let count = node.outputs.len() as u64;
            let sizes: Vec<u64> = match optional(1) {
                Some(split) => {
                    let sizes = constants(split, "split")?;
                    if sizes.len() as u64 != count || sizes.iter().any(|&s| s < 0) {
                        return Err("its split does not match its outputs".into());
                    }
                    sizes.into_iter().map(|s| s as u64).collect()
                }
                None if count == 0 => return Err("has no outputs".into()),
                None if opset >= 18 && attribute(node, "num_outputs").is_some() => {
                    if int_attribute(node, "num_outputs", None)? as u64 != count {
                        return Err("its num_outputs does not match its outputs".into());
                    }
                    let chunk = length.div_ceil(count);
                    let last = length.checked_sub(chunk * (count - 1)).ok_or("cannot split into so many parts")?;
                    (0..count).map(|i| if i + 1 == count { last } else { chunk }).collect()
                }
                None if length % count == 0 => vec![length / count; count as usize],
                None => return Err(format!("cannot split {length} into {count} equal parts")),
            };
            if sizes.iter().fold(0u64, |sum, &s| sum.saturating_add(s)) != length {
                return Err(format!("its parts do not add up to {length}"));
            }
            let mut start = 0usize;
            let outputs = sizes
                .iter()
                .map(|&size| {
                    let mut dims = data.dims.clone();
                    dims[axis] = Dim::N(size);
                    let ints = data
                        .ints
                        .as_ref()
                        .filter(|_| dims.len() == 1)
                        .map(|known| known[start..start + size as usize].to_vec());
                    start += size as usize;
                    Value { dims, ints }
                })
                .collect();
            Ok((outputs, 0))
        }
        "Squeeze" => {
            arity(1, 2)?;
            let data = input(0)?;
            let dims = match optional(1) {
                None if data.dims.contains(&Dim::Batch) => {
                    return Err("squeezes without axes, which depends on the batch size".into());
                }
                None => data.dims.iter().copied().filter(|d| *d != Dim::N(1)).collect(),
                Some(axes) => {
                    let axes = constants(axes, "axes")?
                        .into_iter()
                        .map(|a| normalise(a, data.dims.len(), false))
                        .collect::<Result<Vec<_>, _>>()?;
                    if axes.iter().any(|&a| data.dims[a] != Dim::N(1)) {
                        return Err("squeezes a dimension that is not 1".into());
                    }
                    (0..data.dims.len()).filter(|d| !axes.contains(d)).map(|d| data.dims[d]).collect()
                }
            };
            Ok((vec![Value { dims, ints: data.ints.clone() }], 0))
        }
        "Unsqueeze" => {
            arity(2, 2)?;
            let data = input(0)?;
            let axes = constants(input(1)?, "axes")?;
            let rank = data.dims.len() + axes.len();
            if rank > MAX_RANK {
                return Err(format!("would have more than {MAX_RANK} dimensions"));
            }
            let mut axes = axes.into_iter().map(|a| normalise(a, rank, false)).collect::<Result<Vec<_>, _>>()?;
            axes.sort_unstable();
            if axes.windows(2).any(|w| w[0] == w[1]) {
                return Err("repeats an axis".into());
            }
            let mut rest = data.dims.iter();
            let dims = (0..rank)
                .map(|d| if axes.contains(&d) { Dim::N(1) } else { *rest.next().expect("rank adds up") })
                .collect();
            Ok((vec![Value { dims, ints: data.ints.clone() }], 0))
        }
        "Transpose" => {
            arity(1, 1)?;
            let data = input(0)?;
            let rank = data.dims.len();
            let perm: Vec<i64> = match attribute(node, "perm") {
                Some(Attribute::Ints(perm)) => perm.clone(),
                Some(_) => return Err("its perm must be integers".into()),
                None => (0..rank as i64).rev().collect(),
            };
            let mut sorted = perm.clone();
            sorted.sort_unstable();
            if sorted != (0..rank as i64).collect::<Vec<_>>() {
                return Err(format!("its perm {perm:?} is no permutation of {rank} axes"));
            }
            let dims = perm.iter().map(|&p| data.dims[p as usize]).collect();
            Ok((vec![Value { dims, ints: data.ints.clone().filter(|_| rank <= 1) }], 0))
        }
        other => Err(format!("the check has no shape rule for '{other}'")),
    }
}

/// A contracted dimension (Gemm's and MatMul's K): equal on both sides and not the batch.
fn contracted(k: Dim, k2: Dim) -> Result<(), String> {
    match (k, k2) {
        (Dim::Batch, _) | (_, Dim::Batch) => Err(mixes_rows()),
        (a, b) if a != b => Err(format!("multiplies over {a:?} and {b:?}, which differ")),
        _ => Ok(()),
    }
}

/// The range ONNX's Slice picks from a dimension of `length`: first index, step, count.
fn slice_range(length: u64, start: i64, end: i64, step: i64) -> (i128, i128, u64) {
    let length = length as i128;
    let (mut start, mut end, step) = (i128::from(start), i128::from(end), i128::from(step));
    if start < 0 {
        start += length;
    }
    if end < 0 {
        end += length;
    }
    let (first, span) = if step > 0 {
        let first = start.clamp(0, length);
        (first, end.clamp(0, length) - first)
    } else {
        let first = start.clamp(0, length - 1);
        (first, first - end.clamp(-1, length - 1))
    };
    let count = if span <= 0 { 0 } else { (span + step.abs() - 1) / step.abs() };
    (first, step, count as u64)
}
