//! Graphs that are plain MLPs run on cpmx's MLP kernels, so that an actor exported to ONNX
//! gives bit for bit the actions of the same weights read from safetensors (`mlp: {weights}`):
//! tract sums its products in another order, and a rollout amplifies the last-bit
//! differences into a different table.
//!
//! A plain MLP is a chain from the input to the output through linear layers — `Gemm`
//! (`transA` 0, `alpha` and `beta` 1), or `MatMul` by a constant optionally followed by `Add`
//! of a constant — with the same activation (`Tanh`, `Relu`, `Elu` with `alpha` 1) after every
//! layer but the last. Constants may be initializers, `Constant` nodes, or a `Transpose` or
//! `Identity` of those (as PyTorch's exporters write them); `Identity` on the chain is skipped.
//! Anything else (another operator, a branch off the chain, a layer that does not take the
//! previous one's width) leaves the graph to tract.

use std::collections::HashMap;

use cpmx_policy::{Activation, MlpActor};
use prost::Message;
use tract_onnx::pb::{AttributeProto, GraphProto, NodeProto, TensorProto, tensor_proto::DataType};

/// A float32 constant: dims and row-major values.
#[derive(Debug, Clone)]
struct Constant {
    dims: Vec<usize>,
    values: Vec<f32>,
}

/// One linear layer as torch stores it: `weight` is `[outputs][inputs]` row-major.
struct Linear {
    weight: Vec<f32>,
    bias: Vec<f32>,
    inputs: usize,
    outputs: usize,
}

/// The MLP the graph in `bytes` is, reading `input` and writing `output`, if it is one.
pub fn as_mlp(bytes: &[u8], input: &str, output: &str) -> Option<MlpActor> {
    let model = tract_onnx::pb::ModelProto::decode(bytes).ok()?;
    let graph = model.graph?;
    let constants = constants(&graph)?;
    let chain: Vec<&NodeProto> = graph
        .node
        .iter()
        .filter(|n| !n.output.iter().all(|o| constants.contains_key(o.as_str())))
        .collect();

    let mut x = input.to_owned();
    let mut layers: Vec<Linear> = Vec::new();
    let mut activations: Vec<Activation> = Vec::new();
    while x != output {
        let node = only_consumer(&chain, &x)?;
        if node.output.len() != 1 {
            return None;
        }
        match node.op_type.as_str() {
            "Identity" => {}
            "Gemm" => {
                let int = |name: &str, default: i64| attribute(node, name).map_or(default, |a| a.i);
                let float = |name: &str| attribute(node, name).map_or(1.0, |a| a.f);
                if node.input.first() != Some(&x)
                    || int("transA", 0) != 0
                    || float("alpha") != 1.0
                    || float("beta") != 1.0
                {
                    return None;
                }
                let b = constants.get(node.input.get(1)?.as_str())?;
                let [rows, cols] = b.dims[..] else { return None };
                let (outputs, inputs, weight) = if int("transB", 0) == 1 {
                    (rows, cols, b.values.clone())
                } else {
                    (cols, rows, transpose(&b.values, rows, cols))
                };
                let bias = match node.input.get(2).filter(|name| !name.is_empty()) {
                    Some(name) => bias(constants.get(name.as_str())?, outputs)?,
                    None => vec![0.0; outputs],
                };
                layers.push(Linear {
                    weight,
                    bias,
                    inputs,
                    outputs,
                });
            }
            "MatMul" => {
                if node.input.first() != Some(&x) {
                    return None;
                }
                let w = constants.get(node.input.get(1)?.as_str())?;
                let [inputs, outputs] = w.dims[..] else {
                    return None;
                };
                let product = &node.output[0];
                // A bias `Add` right after, with the constant on either side.
                let add = only_consumer(&chain, product).filter(|n| n.op_type == "Add");
                let bias_name = add.and_then(|add| match &add.input[..] {
                    [p, b] | [b, p] if p == product && constants.contains_key(b.as_str()) => Some(b),
                    _ => None,
                });
                let (bias, out) = match (add, bias_name) {
                    (Some(add), Some(name)) => {
                        (bias(constants.get(name.as_str())?, outputs)?, add.output.first()?)
                    }
                    _ => (vec![0.0; outputs], product),
                };
                layers.push(Linear {
                    weight: transpose(&w.values, inputs, outputs),
                    bias,
                    inputs,
                    outputs,
                });
                x.clone_from(out);
                continue;
            }
            "Tanh" | "Relu" | "Elu" if activations.len() + 1 == layers.len() => {
                if node.op_type == "Elu" && attribute(node, "alpha").is_some_and(|a| a.f != 1.0) {
                    return None;
                }
                activations.push(match node.op_type.as_str() {
                    "Tanh" => Activation::Tanh,
                    "Relu" => Activation::Relu,
                    _ => Activation::Elu,
                });
            }
            _ => return None,
        }
        x.clone_from(&node.output[0]);
    }
    let one_activation = activations.windows(2).all(|w| w[0] == w[1]);
    let chained = layers.windows(2).all(|w| w[0].outputs == w[1].inputs);
    if layers.is_empty() || activations.len() + 1 != layers.len() || !one_activation || !chained {
        return None;
    }
    let mut sizes = vec![layers[0].inputs];
    sizes.extend(layers.iter().map(|l| l.outputs));
    let tensors: Vec<(&[f32], &[f32])> = layers
        .iter()
        .map(|l| (l.weight.as_slice(), l.bias.as_slice()))
        .collect();
    let activation = activations.first().copied().unwrap_or(Activation::Tanh);
    MlpActor::from_layers(&sizes, &tensors, activation).ok()
}

/// The single node that reads `value` among the non-constant nodes; `None` when none or
/// several do (a branch off the chain).
fn only_consumer<'a>(nodes: &[&'a NodeProto], value: &str) -> Option<&'a NodeProto> {
    let mut readers = nodes.iter().filter(|n| n.input.iter().any(|i| i == value));
    let node = readers.next()?;
    readers.next().is_none().then_some(*node)
}

fn attribute<'a>(node: &'a NodeProto, name: &str) -> Option<&'a AttributeProto> {
    node.attribute.iter().find(|a| a.name == name)
}

/// Every float32 constant of the graph by name: initializers, `Constant` nodes, and
/// `Identity` or 2-D `Transpose` of constants, in graph order. `None` when a constant is
/// malformed (the graph is left to tract, which reports it).
fn constants(graph: &GraphProto) -> Option<HashMap<&str, Constant>> {
    let mut constants: HashMap<&str, Constant> = HashMap::new();
    for t in &graph.initializer {
        if let Some(c) = tensor(t) {
            constants.insert(t.name.as_str(), c);
        }
    }
    for node in &graph.node {
        let [out] = &node.output[..] else { continue };
        let input = node.input.first().and_then(|i| constants.get(i.as_str()));
        let value = match (node.op_type.as_str(), input) {
            ("Constant", _) => attribute(node, "value")
                .and_then(|a| a.t.as_ref())
                .and_then(tensor),
            ("Identity", Some(c)) => Some(c.clone()),
            ("Transpose", Some(c)) => {
                let [rows, cols] = c.dims[..] else { continue };
                let perm = attribute(node, "perm").map_or(vec![1, 0], |a| a.ints.clone());
                (perm == [1, 0]).then(|| Constant {
                    dims: vec![cols, rows],
                    values: transpose(&c.values, rows, cols),
                })
            }
            _ => None,
        };
        if let Some(c) = value {
            constants.insert(out.as_str(), c);
        }
    }
    Some(constants)
}

/// A float32 tensor stored in the file (raw little-endian data or `float_data`).
fn tensor(t: &TensorProto) -> Option<Constant> {
    if t.data_type != DataType::Float as i32 || t.data_location.is_some_and(|l| l != 0) {
        return None;
    }
    let dims: Vec<usize> = t
        .dims
        .iter()
        .map(|&d| usize::try_from(d).ok())
        .collect::<Option<_>>()?;
    let values: Vec<f32> = if t.raw_data.is_empty() {
        t.float_data.clone()
    } else {
        t.raw_data
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()
    };
    (values.len() == dims.iter().product::<usize>()).then_some(Constant { dims, values })
}

/// A bias of `outputs` values (`[outputs]` or `[1, outputs]`).
fn bias(c: &Constant, outputs: usize) -> Option<Vec<f32>> {
    matches!(c.dims[..], [n] | [1, n] if n == outputs).then(|| c.values.clone())
}

/// `[rows, cols]` to `[cols, rows]`.
fn transpose(w: &[f32], rows: usize, cols: usize) -> Vec<f32> {
    let mut t = vec![0.0; w.len()];
    for r in 0..rows {
        for c in 0..cols {
            t[c * rows + r] = w[r * cols + c];
        }
    }
    t
}
