//! Which tensors of a weight file are an MLP's layers, whatever the file's format: layers
//! `PREFIX.N.weight` `[outputs, inputs]` with `PREFIX.N.bias` in ascending `N` under the one
//! prefix that holds layers (`actor` when several do), each layer taking the previous one's
//! outputs. safetensors files and PyTorch state dicts (SigmaRL's checkpoints,
//! `module.0.module.0.params.{0,2,4,6}`) are read through this one rule.

use safetensors::{Dtype, SafeTensors};

use crate::actor::ActorError;
use crate::torch::NamedTensor;

/// Tensors by name, of any file format.
pub(crate) trait Tensors {
    /// Every tensor's name, sorted.
    fn names(&self) -> Vec<String>;
    /// A tensor's shape.
    fn shape(&self, name: &str) -> Option<Vec<usize>>;
    /// A float32 tensor of the `expected` shape, row-major.
    fn f32(&self, name: &str, expected: &[usize]) -> Result<Vec<f32>, ActorError>;
}

/// One layer: `weight` is `[outputs][inputs]` row-major (torch's `Linear`).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Layer {
    pub name: String,
    pub inputs: usize,
    pub outputs: usize,
    pub weight: Vec<f32>,
    pub bias: Vec<f32>,
}

/// The MLP layers among `tensors`, in order.
pub(crate) fn mlp_layers(tensors: &(impl Tensors + ?Sized)) -> Result<Vec<Layer>, ActorError> {
    let names = tensors.names();
    let mut by_prefix: std::collections::BTreeMap<String, Vec<u64>> = Default::default();
    for name in &names {
        let Some(stem) = name.strip_suffix(".weight") else {
            continue;
        };
        let Some((prefix, index)) = stem.rsplit_once('.') else {
            continue;
        };
        if let Ok(n) = index.parse::<u64>() {
            by_prefix.entry(prefix.to_owned()).or_default().push(n);
        }
    }
    let prefix = match by_prefix.len() {
        0 => return Err(ActorError::NoLayers { found: names }),
        1 => by_prefix.keys().next().cloned().unwrap_or_default(),
        _ if by_prefix.contains_key("actor") => "actor".to_owned(),
        _ => {
            return Err(ActorError::AmbiguousPrefix {
                prefixes: by_prefix.into_keys().collect(),
            });
        }
    };
    let mut indices = by_prefix.remove(&prefix).unwrap_or_default();
    indices.sort_unstable();
    let mut layers: Vec<Layer> = Vec::with_capacity(indices.len());
    for n in indices {
        let name = format!("{prefix}.{n}.weight");
        let shape = tensors.shape(&name).unwrap_or_default();
        let [outputs, inputs] = shape[..] else {
            return Err(ActorError::Rank { name, found: shape });
        };
        if let Some(previous) = layers.last()
            && previous.outputs != inputs
        {
            return Err(ActorError::Chain {
                name,
                expected: vec![outputs, previous.outputs],
                found: shape,
                previous: previous.name.clone(),
            });
        }
        let weight = tensors.f32(&name, &[outputs, inputs])?;
        let bias = tensors.f32(&format!("{prefix}.{n}.bias"), &[outputs])?;
        layers.push(Layer {
            name,
            inputs,
            outputs,
            weight,
            bias,
        });
    }
    Ok(layers)
}

impl Tensors for SafeTensors<'_> {
    fn names(&self) -> Vec<String> {
        let mut names: Vec<String> = SafeTensors::names(self).into_iter().map(str::to_owned).collect();
        names.sort();
        names
    }

    fn shape(&self, name: &str) -> Option<Vec<usize>> {
        self.tensor(name).ok().map(|v| v.shape().to_vec())
    }

    fn f32(&self, name: &str, expected: &[usize]) -> Result<Vec<f32>, ActorError> {
        let view = self.tensor(name).map_err(|_| ActorError::MissingTensor {
            name: name.to_owned(),
            expected: expected.to_vec(),
        })?;
        if view.dtype() != Dtype::F32 {
            return Err(ActorError::Dtype {
                name: name.to_owned(),
                found: view.dtype().to_string(),
            });
        }
        if view.shape() != expected {
            return Err(ActorError::Shape {
                name: name.to_owned(),
                expected: expected.to_vec(),
                found: view.shape().to_vec(),
            });
        }
        Ok(view
            .data()
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect())
    }
}

impl Tensors for [NamedTensor] {
    fn names(&self) -> Vec<String> {
        let mut names: Vec<String> = self.iter().map(|t| t.name.clone()).collect();
        names.sort();
        names
    }

    fn shape(&self, name: &str) -> Option<Vec<usize>> {
        self.iter().find(|t| t.name == name).map(|t| t.shape.clone())
    }

    fn f32(&self, name: &str, expected: &[usize]) -> Result<Vec<f32>, ActorError> {
        let tensor = self
            .iter()
            .find(|t| t.name == name)
            .ok_or_else(|| ActorError::MissingTensor {
                name: name.to_owned(),
                expected: expected.to_vec(),
            })?;
        if tensor.shape != expected {
            return Err(ActorError::Shape {
                name: name.to_owned(),
                expected: expected.to_vec(),
                found: tensor.shape.clone(),
            });
        }
        Ok(tensor.values.clone())
    }
}
