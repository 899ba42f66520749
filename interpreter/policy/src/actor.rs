//! MLP actor networks loaded from safetensors (`y = x W^T + b`, float32, an activation after
//! every layer but the last) evaluated for all agents at once with preallocated buffers:
//! SigmaRL's exact 32 -> 256 -> 256 -> 256 -> 4 tanh layout ([`MlpLayout`]), or any MLP whose
//! layer sizes are read from the file ([`MlpActor::from_bytes_any`]).
//!
//! This module owns loading, shape checks and the batched forward pass to the raw outputs;
//! turning raw outputs into actions is `action`'s job. The layers run on `cpmx-kernels`'
//! dense layer (`dense_layer_packed`: the weights packed once at load), whose products are the
//! trainer's (`dense_layer`) to the bit: an actor cpmx trained gives here the bits it gave while
//! training.

use std::path::{Path, PathBuf};

use safetensors::SafeTensors;

use crate::layers::{Layer, Tensors, mlp_layers};
use crate::torch::NamedTensor;

pub use cpmx_kernels::Activation;
use cpmx_kernels::{Mat, PackedB, dense_layer_packed};

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
    /// The activation after every hidden layer.
    pub activation: Activation,
}

impl MlpLayout {
    /// The layout stored in a safetensors file under `prefix`: layers `{prefix}.0`,
    /// `{prefix}.1`, ... as long as both tensors exist, sizes from the weight shapes (each
    /// layer's input must be the previous layer's output; tanh after every layer but the last).
    pub fn from_safetensors(bytes: &[u8], prefix: &str) -> Result<Self, ActorError> {
        let tensors = SafeTensors::deserialize(bytes).map_err(|e| ActorError::Format(e.to_string()))?;
        let mut sizes: Vec<usize> = Vec::new();
        for i in 0.. {
            let name = format!("{prefix}.{i}.weight");
            let Ok(view) = tensors.tensor(&name) else { break };
            let shape = view.shape();
            let expected_in = sizes.last().copied();
            match (shape, expected_in) {
                ([outputs, inputs], Some(expected)) if *inputs == expected => sizes.push(*outputs),
                ([outputs, inputs], None) => sizes.extend([*inputs, *outputs]),
                (found, _) => {
                    return Err(ActorError::Shape {
                        name,
                        expected: vec![0, expected_in.unwrap_or(0)],
                        found: found.to_vec(),
                    });
                }
            }
        }
        if sizes.len() < 2 {
            return Err(ActorError::MissingTensor {
                name: format!("{prefix}.0.weight"),
                expected: vec![],
            });
        }
        Ok(MlpLayout {
            input_size: sizes[0],
            hidden_sizes: sizes[1..sizes.len() - 1].to_vec(),
            output_size: sizes[sizes.len() - 1],
            prefix: prefix.to_owned(),
            activation: Activation::Tanh,
        })
    }

    /// All layer widths, input first.
    pub fn sizes(&self) -> Vec<usize> {
        let mut sizes = vec![self.input_size];
        sizes.extend(&self.hidden_sizes);
        sizes.push(self.output_size);
        sizes
    }

    /// SigmaRL's actor: 32 -> 256 -> 256 -> 256 -> 4 with tanh, tensors `actor.{0..3}.*`.
    pub fn sigmarl() -> Self {
        MlpLayout {
            input_size: 32,
            hidden_sizes: vec![256, 256, 256],
            output_size: 4,
            prefix: "actor".to_owned(),
            activation: Activation::Tanh,
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
    /// A weight tensor is not a matrix.
    #[error("tensor `{name}` has shape {found:?}, expected a matrix [outputs, inputs]")]
    Rank { name: String, found: Vec<usize> },
    /// A layer's inputs are not the previous layer's outputs.
    #[error(
        "tensor `{name}` has shape {found:?}, expected {expected:?}: its inputs must equal the {} outputs of `{previous}`",
        expected[1]
    )]
    Chain {
        name: String,
        expected: Vec<usize>,
        found: Vec<usize>,
        previous: String,
    },
    /// The file holds no MLP layers (`PREFIX.N.weight` with `PREFIX.N.bias`).
    #[error(
        "no MLP layers found: expected tensors `PREFIX.0.weight`, `PREFIX.0.bias`, `PREFIX.1.weight`, ...; the file has {found:?}"
    )]
    NoLayers { found: Vec<String> },
    /// Several tensor prefixes hold layers and none is `actor`.
    #[error("tensors of several networks ({prefixes:?}) and none is called `actor`")]
    AmbiguousPrefix { prefixes: Vec<String> },
    /// The first layer does not take the observation's values.
    #[error(
        "tensor `{name}` has shape {found:?}, expected [{}, {observation}]: the first layer takes the observation's {observation} values",
        found[0]
    )]
    InputSize {
        name: String,
        found: Vec<usize>,
        observation: usize,
    },
    /// The last layer does not give the outputs the output head reads.
    #[error(
        "tensor `{name}` has shape {found:?}, expected [{expected}, {}]: the output head `{head}` reads {expected} outputs ({what})",
        found[1]
    )]
    OutputSize {
        name: String,
        found: Vec<usize>,
        expected: usize,
        head: &'static str,
        what: &'static str,
    },
    /// A tensor is not float32.
    #[error("tensor `{name}` has dtype {found}, expected F32")]
    Dtype { name: String, found: String },
    /// A PyTorch checkpoint that does not read.
    #[error(transparent)]
    Checkpoint(#[from] crate::torch::TorchError),
    /// A batch buffer does not fit the network.
    #[error("{what} holds {found} values, expected {expected}")]
    Buffer {
        what: &'static str,
        found: usize,
        expected: usize,
    },
}

/// One layer, its weight transposed (W^T, `inputs x outputs`) and packed once into the panels
/// the product reads (`PackedB`): a decision reads every weight once, in the order it uses them.
#[derive(Debug, Clone, PartialEq)]
struct Dense {
    outputs: usize,
    weight_t: PackedB,
    bias: Vec<f32>,
    activation: Activation,
}

impl Dense {
    /// A layer from torch's `weight` (`[outputs][inputs]`, row-major) and `bias`.
    fn new(weight: &[f32], bias: &[f32], inputs: usize, outputs: usize, activation: Activation) -> Self {
        let mut weight_t = vec![0.0; inputs * outputs];
        for (j, row) in weight.chunks_exact(inputs).take(outputs).enumerate() {
            for (k, &w) in row.iter().enumerate() {
                weight_t[k * outputs + j] = w;
            }
        }
        Dense {
            outputs,
            weight_t: PackedB::new(Mat::rows(&weight_t, outputs), inputs, outputs),
            bias: bias[..outputs].to_vec(),
            activation,
        }
    }

    /// `y = activation(x W^T + b)` for `rows` rows.
    fn apply(&self, x: &[f32], rows: usize, y: &mut [f32]) {
        dense_layer_packed(x, rows, &self.weight_t, &self.bias, self.activation, y);
    }
}

/// A loaded MLP actor. Weights are transposed once at load and shared by its clones (a
/// planner forks the policy every tick: a copy of SigmaRL's 140,000 weights each time cost
/// more than the forward passes).
#[derive(Debug, Clone, PartialEq)]
pub struct MlpActor {
    layers: std::sync::Arc<[Dense]>,
    /// The weight tensor of each layer and its shape `[outputs, inputs]`.
    weights: std::sync::Arc<[(String, [usize; 2])]>,
    input_size: usize,
    output_size: usize,
    /// Widest hidden layer.
    width: usize,
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

    /// Whether these buffers serve `actor`'s passes over `agents` agents.
    pub fn serves(&self, actor: &MlpActor, agents: usize) -> bool {
        let size = self.capacity * actor.width;
        agents <= self.capacity && self.ping.len() == size && self.pong.len() == size
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
            let weight = tensors.f32(&format!("{}.{i}.weight", layout.prefix), &[outputs, inputs])?;
            let bias = tensors.f32(&format!("{}.{i}.bias", layout.prefix), &[outputs])?;
            let activation = if i + 1 < n_layers {
                layout.activation
            } else {
                Activation::Identity
            };
            layers.push(Dense::new(&weight, &bias, inputs, outputs, activation));
        }
        let weights = sizes
            .windows(2)
            .enumerate()
            .map(|(i, pair)| (format!("{}.{i}.weight", layout.prefix), [pair[1], pair[0]]))
            .collect();
        Ok(Self::assemble(layers, weights))
    }

    /// Load an MLP of any layer sizes from a safetensors file: layers `PREFIX.N.weight`
    /// `[outputs, inputs]` and `PREFIX.N.bias` `[outputs]` in ascending `N` (gaps allowed, as
    /// torch's `nn.Sequential` numbers linear layers between activations), with `PREFIX` the
    /// only prefix that has such tensors (or `actor` among several). Each layer's inputs must
    /// equal the previous layer's outputs; `activation` follows every layer but the last.
    pub fn load_any(path: &Path, activation: Activation) -> Result<Self, ActorError> {
        let bytes = std::fs::read(path).map_err(|source| ActorError::Io {
            path: path.to_owned(),
            source,
        })?;
        Self::from_bytes_any(&bytes, activation)
    }

    /// [`MlpActor::load_any`] from the bytes of a safetensors file.
    pub fn from_bytes_any(bytes: &[u8], activation: Activation) -> Result<Self, ActorError> {
        let tensors = SafeTensors::deserialize(bytes).map_err(|e| ActorError::Format(e.to_string()))?;
        Ok(Self::from_layers_found(&mlp_layers(&tensors)?, activation))
    }

    /// The actor of a PyTorch state dict (a SigmaRL checkpoint's tensors, read by
    /// [`crate::torch::read_state_dict`]), by the same rule as [`MlpActor::from_bytes_any`].
    pub fn from_state_dict(tensors: &[NamedTensor], activation: Activation) -> Result<Self, ActorError> {
        Ok(Self::from_layers_found(&mlp_layers(tensors)?, activation))
    }

    /// The actor of a SigmaRL checkpoint (`*_policy.pth`, as `torch.save` writes it).
    pub fn load_checkpoint(path: &Path, activation: Activation) -> Result<Self, ActorError> {
        let tensors = crate::torch::read_state_dict(path)?;
        Self::from_state_dict(&tensors, activation)
    }

    fn from_layers_found(found: &[Layer], activation: Activation) -> Self {
        let layers = found
            .iter()
            .enumerate()
            .map(|(i, l)| {
                let act = if i + 1 < found.len() {
                    activation
                } else {
                    Activation::Identity
                };
                Dense::new(&l.weight, &l.bias, l.inputs, l.outputs, act)
            })
            .collect();
        let weights = found
            .iter()
            .map(|l| (l.name.clone(), [l.outputs, l.inputs]))
            .collect();
        Self::assemble(layers, weights)
    }

    /// Load an actor whose layout is read from the file itself (see
    /// [`MlpLayout::from_safetensors`]).
    pub fn load_inferred(path: &Path, prefix: &str) -> Result<Self, ActorError> {
        let bytes = std::fs::read(path).map_err(|source| ActorError::Io {
            path: path.to_owned(),
            source,
        })?;
        Self::from_bytes_inferred(&bytes, prefix)
    }

    /// [`MlpActor::load_inferred`] from the bytes of a safetensors file.
    pub fn from_bytes_inferred(bytes: &[u8], prefix: &str) -> Result<Self, ActorError> {
        let layout = MlpLayout::from_safetensors(bytes, prefix)?;
        Self::from_bytes(bytes, &layout)
    }

    /// An actor from in-memory tensors: `sizes` are the layer widths (input first) and
    /// `layers[i]` is torch's `(weight [out][in] row-major, bias [out])` of layer `i`, named
    /// `actor.{i}.*` as a trainer writes them; `activation` follows every layer but the last.
    /// (A trainer hands its current weights over this way, and so does an ONNX graph that is a
    /// plain MLP.)
    pub fn from_layers(
        sizes: &[usize],
        layers: &[(&[f32], &[f32])],
        activation: Activation,
    ) -> Result<Self, ActorError> {
        if sizes.len() < 2 || layers.len() != sizes.len() - 1 {
            return Err(ActorError::Buffer {
                what: "layer list",
                found: layers.len(),
                expected: sizes.len().saturating_sub(1),
            });
        }
        let n_layers = layers.len();
        let mut dense = Vec::with_capacity(n_layers);
        let mut weights = Vec::with_capacity(n_layers);
        for (i, (pair, (weight, bias))) in sizes.windows(2).zip(layers).enumerate() {
            let (inputs, outputs) = (pair[0], pair[1]);
            if weight.len() != inputs * outputs || bias.len() != outputs {
                return Err(ActorError::Buffer {
                    what: "layer tensors",
                    found: weight.len() + bias.len(),
                    expected: inputs * outputs + outputs,
                });
            }
            let act = if i + 1 < n_layers {
                activation
            } else {
                Activation::Identity
            };
            dense.push(Dense::new(weight, bias, inputs, outputs, act));
            weights.push((format!("actor.{i}.weight"), [outputs, inputs]));
        }
        Ok(Self::assemble(dense, weights))
    }

    fn assemble(layers: Vec<Dense>, weights: Vec<(String, [usize; 2])>) -> Self {
        let input_size = weights.first().map_or(0, |(_, s)| s[1]);
        let output_size = weights.last().map_or(0, |(_, s)| s[0]);
        let hidden = layers.len().saturating_sub(1);
        let width = layers[..hidden].iter().map(|l| l.outputs).max().unwrap_or(0);
        MlpActor {
            layers: layers.into(),
            weights: weights.into(),
            input_size,
            output_size,
            width,
        }
    }

    /// Checks that the first layer takes `observation` values (when the policy has an
    /// observation) and the last gives what `head` reads, naming the tensor and shapes.
    pub fn check_fits(&self, observation: Option<usize>, head: crate::OutputHead) -> Result<(), ActorError> {
        if let (Some(observation), Some((name, [o, i]))) = (observation, self.weights.first())
            && *i != observation
        {
            return Err(ActorError::InputSize {
                name: name.clone(),
                found: vec![*o, *i],
                observation,
            });
        }
        if let Some((name, [o, i])) = self.weights.last()
            && *o != head.raw_size()
        {
            return Err(ActorError::OutputSize {
                name: name.clone(),
                found: vec![*o, *i],
                expected: head.raw_size(),
                head: head.name(),
                what: head.describe(),
            });
        }
        Ok(())
    }

    /// The weight tensor of each layer with its shape `[outputs, inputs]`, first layer first.
    pub fn weight_tensors(&self) -> &[(String, [usize; 2])] {
        &self.weights
    }

    /// Observation size the network expects (compare with the observation design's size).
    pub fn input_size(&self) -> usize {
        self.input_size
    }

    /// Raw output size.
    pub fn output_size(&self) -> usize {
        self.output_size
    }

    /// Whether `other` runs the same weights (the same loaded actor, shared by clones).
    pub fn same_weights(&self, other: &MlpActor) -> bool {
        std::sync::Arc::ptr_eq(&self.layers, &other.layers)
    }

    /// Buffers for forward passes over up to `agents` agents.
    pub fn workspace(&self, agents: usize) -> ActorWorkspace {
        ActorWorkspace {
            capacity: agents,
            ping: vec![0.0; agents * self.width],
            pong: vec![0.0; agents * self.width],
        }
    }

    /// Raw outputs for a batch: `observations` holds `agents * input_size()` values
    /// (agent-major), `raw` receives `agents * output_size()` values. Allocation-free after
    /// the first call on a thread.
    ///
    /// All agents run through each layer at once (each weight is loaded once per batch); an
    /// agent's outputs do not depend on the batch.
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
            (
                "workspace buffer",
                ws.ping.len().min(ws.pong.len()),
                ws.capacity * self.width,
            ),
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
        if self.input_size == 0 || self.output_size == 0 {
            raw.fill(0.0);
            return Ok(());
        }

        // The input feeds the first layer, the last writes `raw`; hidden layers alternate
        // between the two buffers.
        let (ping, pong) = (&mut ws.ping, &mut ws.pong);
        let last = self.layers.len() - 1;
        let mut width = self.input_size;
        for (l, layer) in self.layers.iter().enumerate() {
            let (src, dst): (&[f32], &mut [f32]) = match (l, l % 2) {
                (0, _) if l == last => (observations, &mut *raw),
                (0, _) => (observations, &mut ping[..agents * layer.outputs]),
                (_, 1) if l == last => (&ping[..agents * width], &mut *raw),
                (_, 0) if l == last => (&pong[..agents * width], &mut *raw),
                (_, 1) => (&ping[..agents * width], &mut pong[..agents * layer.outputs]),
                _ => (&pong[..agents * width], &mut ping[..agents * layer.outputs]),
            };
            layer.apply(src, agents, dst);
            width = layer.outputs;
        }
        Ok(())
    }
}
