//! SigmaRL's actor network loaded from safetensors: a tanh MLP (`y = x W^T + b`, float32)
//! evaluated for all agents at once with preallocated buffers.
//!
//! This module owns loading, shape checks and the batched forward pass to the raw outputs;
//! turning raw outputs into actions is `action`'s job.

use std::path::{Path, PathBuf};

use safetensors::{Dtype, SafeTensors};

use crate::kernel::{COLS, Dense, ROWS, pad};

/// The layer sizes and tensor names of an MLP actor.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MlpLayout {
    /// Observation size.
    pub input_size: usize,
    /// Widths of the tanh hidden layers.
    pub hidden_sizes: Vec<usize>,
    /// Raw output size (SigmaRL: 2 locations + 2 pre-scales).
    pub output_size: usize,
    /// Tensor name prefix: layer `i` is `{prefix}.{i}.weight` `[out, in]` and `{prefix}.{i}.bias`.
    pub prefix: String,
}

impl MlpLayout {
    /// SigmaRL's actor: 32 -> 256 -> 256 -> 256 -> 4 with tanh, tensors `actor.{0..3}.*`.
    pub fn sigmarl() -> Self {
        MlpLayout {
            input_size: 32,
            hidden_sizes: vec![256, 256, 256],
            output_size: 4,
            prefix: "actor".to_owned(),
        }
    }
}

/// Errors of loading or running an actor.
#[derive(Debug, thiserror::Error)]
pub enum ActorError {
    /// The weights file cannot be read.
    #[error("cannot read weights {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file is not a valid safetensors file.
    #[error("not a safetensors file: {0}")]
    Format(String),
    /// A tensor the layout needs is absent.
    #[error("tensor `{name}` is missing (expected shape {expected:?})")]
    MissingTensor { name: String, expected: Vec<usize> },
    /// A tensor has the wrong shape.
    #[error("tensor `{name}` has shape {found:?}, expected {expected:?}")]
    Shape {
        name: String,
        expected: Vec<usize>,
        found: Vec<usize>,
    },
    /// A tensor is not float32.
    #[error("tensor `{name}` has dtype {found}, expected F32")]
    Dtype { name: String, found: String },
    /// A batch buffer does not fit the network.
    #[error("{what} holds {found} values, expected {expected}")]
    Buffer {
        what: &'static str,
        found: usize,
        expected: usize,
    },
}

/// A loaded MLP actor. Weights are stored transposed and padded once at load.
#[derive(Debug, Clone, PartialEq)]
pub struct MlpActor {
    layers: Vec<Dense>,
    input_size: usize,
    output_size: usize,
}

/// Preallocated buffers for forward passes over up to `capacity` agents.
#[derive(Debug, Clone, PartialEq)]
pub struct ActorWorkspace {
    capacity: usize,
    ping: Vec<f32>,
    pong: Vec<f32>,
}

impl ActorWorkspace {
    /// Largest batch these buffers serve.
    pub fn capacity(&self) -> usize {
        self.capacity
    }
}

impl MlpActor {
    /// Load an actor with `layout` from a safetensors file.
    pub fn load(path: &Path, layout: &MlpLayout) -> Result<Self, ActorError> {
        let bytes = std::fs::read(path).map_err(|source| ActorError::Io {
            path: path.to_owned(),
            source,
        })?;
        Self::from_bytes(&bytes, layout)
    }

    /// Load an actor with `layout` from the bytes of a safetensors file.
    pub fn from_bytes(bytes: &[u8], layout: &MlpLayout) -> Result<Self, ActorError> {
        let tensors = SafeTensors::deserialize(bytes).map_err(|e| ActorError::Format(e.to_string()))?;
        let mut sizes = vec![layout.input_size];
        sizes.extend(&layout.hidden_sizes);
        sizes.push(layout.output_size);
        let n_layers = sizes.len() - 1;

        let mut layers = Vec::with_capacity(n_layers);
        for (i, pair) in sizes.windows(2).enumerate() {
            let (inputs, outputs) = (pair[0], pair[1]);
            let weight = read_f32(
                &tensors,
                &format!("{}.{i}.weight", layout.prefix),
                &[outputs, inputs],
            )?;
            let bias = read_f32(&tensors, &format!("{}.{i}.bias", layout.prefix), &[outputs])?;

            // Transpose to [in][out] and pad the outputs to the register tile.
            let out_padded = pad(outputs, COLS);
            let mut wt = vec![0.0f32; inputs * out_padded];
            for j in 0..outputs {
                for k in 0..inputs {
                    wt[k * out_padded + j] = weight[j * inputs + k];
                }
            }
            let mut padded_bias = bias;
            padded_bias.resize(out_padded, 0.0);
            layers.push(Dense {
                inputs,
                outputs,
                out_padded,
                wt,
                bias: padded_bias,
                tanh: i + 1 < n_layers,
            });
        }
        Ok(MlpActor {
            layers,
            input_size: layout.input_size,
            output_size: layout.output_size,
        })
    }

    /// Observation size the network expects (compare with the observation design's size).
    pub fn input_size(&self) -> usize {
        self.input_size
    }

    /// Raw output size.
    pub fn output_size(&self) -> usize {
        self.output_size
    }

    /// Buffers for forward passes over up to `agents` agents.
    pub fn workspace(&self, agents: usize) -> ActorWorkspace {
        let rows = pad(agents.max(1), ROWS);
        let width = self
            .layers
            .iter()
            .map(|l| l.out_padded)
            .chain([self.input_size])
            .max()
            .unwrap_or(0);
        ActorWorkspace {
            capacity: agents,
            ping: vec![0.0; rows * width],
            pong: vec![0.0; rows * width],
        }
    }

    /// Raw outputs for a batch: `observations` holds `agents * input_size()` values
    /// (agent-major), `raw` receives `agents * output_size()` values. Allocation-free.
    pub fn forward(
        &self,
        observations: &[f32],
        ws: &mut ActorWorkspace,
        raw: &mut [f32],
    ) -> Result<(), ActorError> {
        // Check the buffers.
        let agents = raw.len() / self.output_size.max(1);
        let checks = [
            ("raw output buffer", raw.len(), agents * self.output_size),
            ("observation buffer", observations.len(), agents * self.input_size),
            ("workspace capacity (agents)", agents.min(ws.capacity), agents),
        ];
        for (what, found, expected) in checks {
            if found != expected {
                return Err(ActorError::Buffer {
                    what,
                    found,
                    expected,
                });
            }
        }
        let rows = pad(agents.max(1), ROWS);

        // Copy the observations into the padded input rows.
        let input = &mut ws.ping[..rows * self.input_size];
        input[..observations.len()].copy_from_slice(observations);
        input[observations.len()..].fill(0.0);

        // Run the layers, alternating between the two buffers.
        let (mut src, mut dst) = (&mut ws.ping, &mut ws.pong);
        let mut stride = self.input_size;
        for layer in &self.layers {
            layer.apply(
                &src[..rows * stride],
                stride,
                rows,
                &mut dst[..rows * layer.out_padded],
            );
            stride = layer.out_padded;
            std::mem::swap(&mut src, &mut dst);
        }

        // Unpad the outputs.
        for (a, out) in raw.chunks_exact_mut(self.output_size).enumerate() {
            out.copy_from_slice(&src[a * stride..a * stride + self.output_size]);
        }
        Ok(())
    }
}

/// A float32 tensor with the expected shape, as a flat vector.
fn read_f32(tensors: &SafeTensors<'_>, name: &str, expected: &[usize]) -> Result<Vec<f32>, ActorError> {
    let view = tensors.tensor(name).map_err(|_| ActorError::MissingTensor {
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
