//! Graphs that are plain MLPs run on cpmx's MLP kernels: a chain from the input through
//! linear layers (`Gemm`, or `MatMul` by a constant and `Add` of a constant) with the same
//! activation (`Tanh`, `Relu`, `Elu` with alpha 1) after every layer but the last, ending in
//! the output. Such a graph gives bit for bit the actions of the same weights as safetensors
//! (`mlp: {weights}`); any other graph runs on tract.

use std::collections::HashMap;

use cpmx_policy::{Activation, MlpActor};
use prost::Message;
use tract_onnx::pb::{ModelProto, NodeProto, TensorProto, tensor_proto::DataType};

/// The MLP the graph in `bytes` is, reading `input` and writing `output`, if it is one.
pub fn as_mlp(bytes: &[u8], input: &str, output: &str) -> Option<MlpActor> {
    let model = ModelProto::decode(bytes).ok()?;
    let graph = model.graph?;
    let constants: HashMap<&str, &TensorProto> =
        graph.initializer.iter().map(|t| (t.name.as_str(), t)).collect();
    let mut x = input.to_owned();
    // (weight [outputs, inputs], bias, inputs, outputs) per layer, and the activations.
    let mut layers: Vec<(Vec<f32>, Vec<f32>, usize, usize)> = Vec::new();
    let mut activations: Vec<Activation> = Vec::new();
    let mut nodes = graph.node.iter().peekable();
    while let Some(node) = nodes.next() {
        if node.input.first() != Some(&x) || node.output.len() != 1 {
            return None;
        }
        match node.op_type.as_str() {
            "Gemm" => {
                let ints = |name: &str, default: i64| attribute(node, name).map_or(default, |a| a.i);
                let floats = |name: &str| attribute(node, name).map_or(1.0, |a| a.f);
                if ints("transA", 0) != 0 || floats("alpha") != 1.0 || floats("beta") != 1.0 {
                    return None;
                }
                let (dims, w) = constant(&constants, node.input.get(1)?)?;
                let [a, b] = dims[..] else { return None };
                let (outputs, inputs, weight) = if ints("transB", 0) == 1 {
                    (a, b, w)
                } else {
                    (b, a, transpose(&w, a, b))
                };
                let bias = match node.input.get(2) {
                    Some(name) => bias(&constants, name, outputs)?,
                    None => vec![0.0; outputs],
                };
                layers.push((weight, bias, inputs, outputs));
            }
            "MatMul" => {
                let (dims, w) = constant(&constants, node.input.get(1)?)?;
                let [inputs, outputs] = dims[..] else { return None };
                let add = nodes.next()?;
                let product = &node.output[0];
                let other = match &add.input[..] {
                    [p, b] if p == product => b,
                    [b, p] if p == product => b,
                    _ => return None,
                };
                if add.op_type != "Add" || add.output.len() != 1 {
                    return None;
                }
                layers.push((
                    transpose(&w, inputs, outputs),
                    bias(&constants, other, outputs)?,
                    inputs,
                    outputs,
                ));
                x.clone_from(&add.output[0]);
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
    let same = activations.windows(2).all(|w| w[0] == w[1]);
    if x != output || layers.is_empty() || activations.len() + 1 != layers.len() || !same {
        return None;
    }
    let chained = layers.windows(2).all(|w| w[0].3 == w[1].2);
    if !chained {
        return None;
    }
    let activation = activations.first().copied().unwrap_or(Activation::Tanh);
    MlpActor::from_bytes_any(&safetensors(&layers), activation).ok()
}

fn attribute<'a>(node: &'a NodeProto, name: &str) -> Option<&'a tract_onnx::pb::AttributeProto> {
    node.attribute.iter().find(|a| a.name == name)
}

/// A float32 constant's dims and values (raw little-endian data or `float_data`).
fn constant(constants: &HashMap<&str, &TensorProto>, name: &str) -> Option<(Vec<usize>, Vec<f32>)> {
    let t = constants.get(name)?;
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
    (values.len() == dims.iter().product::<usize>()).then_some((dims, values))
}

/// A bias of `outputs` values (`[outputs]` or `[1, outputs]`).
fn bias(constants: &HashMap<&str, &TensorProto>, name: &str, outputs: usize) -> Option<Vec<f32>> {
    let (dims, values) = constant(constants, name)?;
    matches!(dims[..], [n] | [1, n] if n == outputs).then_some(values)
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

/// The layers as a safetensors file in `mlp: {weights}`'s layout (`actor.N.weight`, `.bias`).
fn safetensors(layers: &[(Vec<f32>, Vec<f32>, usize, usize)]) -> Vec<u8> {
    let mut header = Vec::new();
    let mut data: Vec<u8> = Vec::new();
    for (l, (w, b, inputs, outputs)) in layers.iter().enumerate() {
        for (kind, values, shape) in [
            ("weight", w, format!("[{outputs},{inputs}]")),
            ("bias", b, format!("[{outputs}]")),
        ] {
            let start = data.len();
            data.extend(values.iter().flat_map(|v| v.to_le_bytes()));
            header.push(format!(
                "\"actor.{l}.{kind}\":{{\"dtype\":\"F32\",\"shape\":{shape},\"data_offsets\":[{start},{}]}}",
                data.len()
            ));
        }
    }
    let header = format!("{{{}}}", header.join(","));
    let mut bytes = (header.len() as u64).to_le_bytes().to_vec();
    bytes.extend(header.as_bytes());
    bytes.extend(data);
    bytes
}
