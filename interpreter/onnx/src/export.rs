//! Writes an MLP stored as safetensors (layers `PREFIX.N.weight` `[outputs, inputs]` and
//! `PREFIX.N.bias`, as `mlp: {weights}` reads them) as an ONNX model: input `observation`
//! `[batch, inputs]`, output `raw` `[batch, outputs]`, one linear layer per `N` (`Gemm` with
//! `transB = 1`, or `MatMul` by the transposed weight and `Add`, as torch.onnx exports
//! `nn.Linear`) and the activation after every layer but the last. Opset 13, IR version 7:
//! the file loads in onnxruntime and every other ONNX runtime, not only in cpmx.

use prost::Message;
use safetensors::{Dtype, SafeTensors};
use tract_onnx::pb::tensor_proto::DataType;
use tract_onnx::pb::tensor_shape_proto::{Dimension, dimension};
use tract_onnx::pb::{
    AttributeProto, GraphProto, ModelProto, NodeProto, OperatorSetIdProto, TensorProto, TensorShapeProto,
    TypeProto, ValueInfoProto, attribute_proto::AttributeType, type_proto,
};

use cpmx_policy::Activation;

/// How a linear layer is written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinearStyle {
    /// One `Gemm` node (`x W^T + b`, `transB = 1`).
    Gemm,
    /// `MatMul` by the transposed weight, then `Add` of the bias.
    MatMulAdd,
}

/// Why an MLP could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    #[error("not a safetensors file: {0}")]
    Format(String),
    #[error("no tensor named `PREFIX.0.weight`")]
    NoLayers,
    #[error("tensor `{name}`: {why}")]
    Tensor { name: String, why: String },
}

/// The ONNX model (protobuf bytes) of the MLP in the safetensors `weights`.
pub fn mlp_to_onnx(
    weights: &[u8],
    activation: Activation,
    style: LinearStyle,
) -> Result<Vec<u8>, ExportError> {
    let tensors = SafeTensors::deserialize(weights).map_err(|e| ExportError::Format(e.to_string()))?;
    let prefix = tensors
        .names()
        .into_iter()
        .filter_map(|n| n.strip_suffix(".0.weight"))
        .min()
        .ok_or(ExportError::NoLayers)?
        .to_owned();

    let mut layers = Vec::new();
    for i in 0.. {
        let name = format!("{prefix}.{i}.weight");
        if tensors.tensor(&name).is_err() {
            break;
        }
        let (w_shape, w) = read_f32(&tensors, &name)?;
        let bias = format!("{prefix}.{i}.bias");
        let (b_shape, b) = read_f32(&tensors, &bias)?;
        let [outputs, inputs] = w_shape[..] else {
            return Err(ExportError::Tensor {
                name,
                why: format!("shape {w_shape:?} is not [outputs, inputs]"),
            });
        };
        if b_shape != [outputs] {
            return Err(ExportError::Tensor {
                name: bias,
                why: format!("shape {b_shape:?}, expected [{outputs}]"),
            });
        }
        layers.push((name, bias, inputs, outputs, w, b));
    }

    let mut nodes = Vec::new();
    let mut initializer = Vec::new();
    let mut x = "observation".to_owned();
    let last = layers.len() - 1;
    for (l, (w_name, b_name, inputs, outputs, w, b)) in layers.iter().enumerate() {
        let linear_out = if l == last {
            "raw".to_owned()
        } else {
            format!("linear{l}")
        };
        match style {
            LinearStyle::Gemm => {
                initializer.push(tensor(w_name, &[*outputs, *inputs], w));
                nodes.push(node(
                    &format!("gemm{l}"),
                    "Gemm",
                    &[&x, w_name, b_name],
                    &linear_out,
                    vec![AttributeProto {
                        name: "transB".into(),
                        r#type: AttributeType::Int as i32,
                        i: 1,
                        ..AttributeProto::default()
                    }],
                ));
            }
            LinearStyle::MatMulAdd => {
                let mut transposed = vec![0.0; w.len()];
                for o in 0..*outputs {
                    for i in 0..*inputs {
                        transposed[i * outputs + o] = w[o * inputs + i];
                    }
                }
                let wt = format!("{w_name}.transposed");
                initializer.push(tensor(&wt, &[*inputs, *outputs], &transposed));
                let product = format!("matmul{l}_out");
                nodes.push(node(
                    &format!("matmul{l}"),
                    "MatMul",
                    &[&x, &wt],
                    &product,
                    vec![],
                ));
                nodes.push(node(
                    &format!("add{l}"),
                    "Add",
                    &[&product, b_name],
                    &linear_out,
                    vec![],
                ));
            }
        }
        initializer.push(tensor(b_name, &[*outputs], b));
        x = linear_out;
        let op = match activation {
            Activation::Tanh => Some("Tanh"),
            Activation::Relu => Some("Relu"),
            Activation::Elu => Some("Elu"),
            Activation::Identity => None,
        };
        if let Some(op) = op.filter(|_| l != last) {
            let out = format!("hidden{l}");
            nodes.push(node(&format!("act{l}"), op, &[&x], &out, vec![]));
            x = out;
        }
    }

    let model = ModelProto {
        ir_version: 7,
        opset_import: vec![OperatorSetIdProto {
            domain: String::new(),
            version: 13,
        }],
        producer_name: "cpmx".into(),
        producer_version: env!("CARGO_PKG_VERSION").into(),
        graph: Some(GraphProto {
            name: "actor".into(),
            node: nodes,
            initializer,
            input: vec![value_info("observation", layers[0].2)],
            output: vec![value_info("raw", layers[last].3)],
            ..GraphProto::default()
        }),
        ..ModelProto::default()
    };
    Ok(model.encode_to_vec())
}

fn read_f32(tensors: &SafeTensors<'_>, name: &str) -> Result<(Vec<usize>, Vec<f32>), ExportError> {
    let view = tensors.tensor(name).map_err(|_| ExportError::Tensor {
        name: name.to_owned(),
        why: "missing".into(),
    })?;
    if view.dtype() != Dtype::F32 {
        return Err(ExportError::Tensor {
            name: name.to_owned(),
            why: format!("dtype {:?}, expected F32", view.dtype()),
        });
    }
    let values = view
        .data()
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    Ok((view.shape().to_vec(), values))
}

fn tensor(name: &str, dims: &[usize], values: &[f32]) -> TensorProto {
    TensorProto {
        name: name.into(),
        dims: dims.iter().map(|&d| d as i64).collect(),
        data_type: DataType::Float as i32,
        raw_data: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
        ..TensorProto::default()
    }
}

fn node(name: &str, op: &str, inputs: &[&str], output: &str, attribute: Vec<AttributeProto>) -> NodeProto {
    NodeProto {
        name: name.into(),
        op_type: op.into(),
        input: inputs.iter().map(|s| (*s).to_owned()).collect(),
        output: vec![output.into()],
        attribute,
        ..NodeProto::default()
    }
}

/// A float32 `[batch, size]` value with a symbolic batch.
fn value_info(name: &str, size: usize) -> ValueInfoProto {
    let dim = |value| Dimension {
        value: Some(value),
        ..Dimension::default()
    };
    ValueInfoProto {
        name: name.into(),
        r#type: Some(TypeProto {
            value: Some(type_proto::Value::TensorType(type_proto::Tensor {
                elem_type: DataType::Float as i32,
                shape: Some(TensorShapeProto {
                    dim: vec![
                        dim(dimension::Value::DimParam("batch".into())),
                        dim(dimension::Value::DimValue(size as i64)),
                    ],
                }),
            })),
            ..TypeProto::default()
        }),
        ..ValueInfoProto::default()
    }
}
