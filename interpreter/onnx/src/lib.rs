//! Actor networks exported to ONNX (`onnx: {file: ...}`), run by tract, a pure Rust ONNX
//! runtime: loaded once per experiment, their input and output checked against the
//! observation and the output head, then run once per policy step for all agents at once
//! ([`OnnxActor`], a [`cpmx_policy::Network`]). A graph that is a plain MLP is also read as
//! one ([`OnnxActor::as_mlp`], `lower`), so that the engine runs it on cpmx's MLP kernels, bit
//! for bit as the same weights from safetensors. [`export`] writes an MLP's safetensors as an
//! ONNX graph (Gemm or MatMul + Add, and the activation), for other runtimes and the tests.
//!
//! This crate owns reading, checking and running ONNX graphs. It knows nothing of specs,
//! observations or actions beyond their sizes.

pub mod export;
mod lower;
mod shape;

use std::path::{Path, PathBuf};

use tract_onnx::prelude::*;

pub use cpmx_policy::{Activation, OutputHead};
pub use export::{LinearStyle, mlp_to_onnx};
pub use shape::{Batch, Dim, TensorShape};

/// Why an ONNX file cannot be used as an actor.
#[derive(Debug, thiserror::Error)]
pub enum OnnxError {
    #[error("cannot read {}: {source}", path.display())]
    Read { path: PathBuf, source: std::io::Error },
    /// Not an ONNX model tract can load (protobuf, operators, types).
    #[error("not an ONNX model cpmx can run: {0}")]
    Format(String),
    /// The graph has no input, or several and none was named.
    #[error("the graph takes {} inputs ({}); cpmx feeds one, the observation", names.len(), names.join(", "))]
    Inputs { names: Vec<String> },
    /// The named input does not exist.
    #[error("the graph has no input `{name}`; its inputs: {}", available.join(", "))]
    NoInput { name: String, available: Vec<String> },
    /// The graph has several outputs and none was named, or none at all.
    #[error("the graph has {} outputs ({}); name the one with the actions with `output_name`", names.len(), names.join(", "))]
    Outputs { names: Vec<String> },
    /// The named output does not exist.
    #[error("the graph has no output `{name}`; its outputs: {}", available.join(", "))]
    NoOutput { name: String, available: Vec<String> },
    /// The input or output is not float32.
    #[error("{what} `{name}` holds {found}, cpmx exchanges float32")]
    Dtype {
        what: &'static str,
        name: String,
        found: String,
    },
    /// The input or output is not `[batch, size]` or `[size]` with a usable batch.
    #[error("{what} `{name}` has shape {shape}; {why}")]
    Layout {
        what: &'static str,
        name: String,
        shape: TensorShape,
        why: String,
    },
    /// The input does not take the observation.
    #[error("input `{name}` has shape {shape}, the observation has {observation} values")]
    InputSize {
        name: String,
        shape: TensorShape,
        observation: usize,
    },
    /// The output does not give what the head reads.
    #[error(
        "output `{name}` has shape {shape}, {width} values per agent; the output head `{head}` reads {expected} ({what})"
    )]
    OutputSize {
        name: String,
        shape: TensorShape,
        width: usize,
        expected: usize,
        head: &'static str,
        what: &'static str,
    },
}

/// An ONNX actor ready to run: one float32 input `[batch, inputs]` (or `[inputs]`), one
/// float32 output `[batch, outputs]` (or `[outputs]`).
#[derive(Debug, Clone)]
pub struct OnnxActor {
    plan: Arc<TypedRunnableModel>,
    input_name: String,
    input_shape: TensorShape,
    output_name: String,
    output_shape: TensorShape,
    input_size: usize,
    output_size: usize,
    batch: Batch,
    /// The graph as an MLP for cpmx's kernels, when it is one.
    mlp: Option<cpmx_policy::MlpActor>,
}

impl OnnxActor {
    /// Loads an ONNX file; `input_name` / `output_name` choose among several (default: the
    /// only one).
    pub fn load(path: &Path, input_name: Option<&str>, output_name: Option<&str>) -> Result<Self, OnnxError> {
        let bytes = std::fs::read(path).map_err(|source| OnnxError::Read {
            path: path.to_owned(),
            source,
        })?;
        Self::from_bytes(&bytes, input_name, output_name)
    }

    /// [`OnnxActor::load`] from the file's bytes.
    pub fn from_bytes(
        bytes: &[u8],
        input_name: Option<&str>,
        output_name: Option<&str>,
    ) -> Result<Self, OnnxError> {
        let format = |e: TractError| OnnxError::Format(format!("{e:#}"));
        let mut model = tract_onnx::onnx()
            .model_for_read(&mut &bytes[..])
            .map_err(format)?;

        // The input: the only one, and the one named if a name is given.
        let inputs: Vec<String> = model
            .input_outlets()
            .map_err(format)?
            .iter()
            .map(|o| model.node(o.node).name.clone())
            .collect();
        let input = match (&inputs[..], input_name) {
            ([only], None) => only.clone(),
            ([only], Some(name)) if only == name => only.clone(),
            (_, Some(name)) if !inputs.iter().any(|i| i == name) => {
                return Err(OnnxError::NoInput {
                    name: name.to_owned(),
                    available: inputs,
                });
            }
            _ => return Err(OnnxError::Inputs { names: inputs }),
        };

        // The output: the only one, or the one named.
        let outputs: Vec<(OutletId, String)> = model
            .output_outlets()
            .map_err(format)?
            .iter()
            .map(|&o| {
                let label = model.outlet_label(o).map(str::to_owned);
                (o, label.unwrap_or_else(|| model.node(o.node).name.clone()))
            })
            .collect();
        let names = || outputs.iter().map(|(_, n)| n.clone()).collect::<Vec<_>>();
        let (outlet, output) = match (&outputs[..], output_name) {
            ([only], None) => only.clone(),
            (_, Some(name)) => {
                outputs
                    .iter()
                    .find(|(_, n)| n == name)
                    .cloned()
                    .ok_or_else(|| OnnxError::NoOutput {
                        name: name.to_owned(),
                        available: names(),
                    })?
            }
            _ => return Err(OnnxError::Outputs { names: names() }),
        };
        model.select_output_outlets(&[outlet]).map_err(format)?;

        // Types and shapes as declared and inferred.
        let typed = model.into_typed().map_err(format)?;
        let input_fact = typed.input_fact(0).map_err(format)?.clone();
        let output_fact = typed.output_fact(0).map_err(format)?.clone();
        for (what, name, fact) in [("input", &input, &input_fact), ("output", &output, &output_fact)] {
            if fact.datum_type != f32::datum_type() {
                return Err(OnnxError::Dtype {
                    what,
                    name: name.clone(),
                    found: format!("{:?}", fact.datum_type),
                });
            }
        }
        let input_shape = TensorShape::of(&input_fact);
        let output_shape = TensorShape::of(&output_fact);
        let layout =
            |what: &'static str, name: &String, shape: &TensorShape, why: String| OnnxError::Layout {
                what,
                name: name.clone(),
                shape: shape.clone(),
                why,
            };
        let (batch, input_size) = input_shape
            .layout()
            .map_err(|why| layout("input", &input, &input_shape, why))?;
        let (_, output_size) = output_shape
            .layout()
            .map_err(|why| layout("output", &output, &output_shape, why))?;

        let plan = typed
            .into_optimized()
            .and_then(|m| m.into_runnable())
            .map_err(format)?;
        let mlp = lower::as_mlp(bytes, &input, &output)
            .filter(|m| m.input_size() == input_size && m.output_size() == output_size);
        Ok(OnnxActor {
            mlp,
            plan,
            input_name: input,
            input_shape,
            output_name: output,
            output_shape,
            input_size,
            output_size,
            batch,
        })
    }

    /// Checks that the input takes `observation` values and the output gives what `head`
    /// reads, naming both shapes.
    pub fn check_fits(&self, observation: usize, head: cpmx_policy::OutputHead) -> Result<(), OnnxError> {
        if self.input_size != observation {
            return Err(OnnxError::InputSize {
                name: self.input_name.clone(),
                shape: self.input_shape.clone(),
                observation,
            });
        }
        if self.output_size != head.raw_size() {
            return Err(OnnxError::OutputSize {
                name: self.output_name.clone(),
                shape: self.output_shape.clone(),
                width: self.output_size,
                expected: head.raw_size(),
                head: head.name(),
                what: head.describe(),
            });
        }
        Ok(())
    }

    /// The input's name and declared shape.
    pub fn input(&self) -> (&str, &TensorShape) {
        (&self.input_name, &self.input_shape)
    }

    /// The output's name and shape.
    pub fn output(&self) -> (&str, &TensorShape) {
        (&self.output_name, &self.output_shape)
    }

    /// How agents are batched: all at once (symbolic batch) or one at a time.
    pub fn batch(&self) -> Batch {
        self.batch
    }

    /// The graph as an MLP for cpmx's kernels, when it is a plain MLP (see `lower`); the
    /// [`cpmx_policy::Network`] implementation always runs the graph on tract.
    pub fn as_mlp(&self) -> Option<&cpmx_policy::MlpActor> {
        self.mlp.as_ref()
    }

    /// Runs the graph on `rows` observations stacked in `data` into `out`.
    fn run(&self, rows: usize, data: &[f32], out: &mut [f32]) -> TractResult<()> {
        let input = match self.batch {
            Batch::Symbolic | Batch::One => Tensor::from_shape(&[rows, self.input_size], data)?,
            Batch::None => Tensor::from_shape(&[self.input_size], data)?,
        };
        let result = self.plan.run(tvec!(input.into_tvalue()))?;
        let values = result[0].to_plain_array_view::<f32>()?;
        if values.len() != out.len() {
            return Err(TractError::msg(format!(
                "output `{}` gave {} values for {rows} agents, expected {}",
                self.output_name,
                values.len(),
                out.len()
            )));
        }
        for (slot, value) in out.iter_mut().zip(values.iter()) {
            *slot = *value;
        }
        Ok(())
    }
}

impl cpmx_policy::Network for OnnxActor {
    fn input_size(&self) -> usize {
        self.input_size
    }

    fn output_size(&self) -> usize {
        self.output_size
    }

    /// All agents in one run when the batch is symbolic, else one run per agent.
    fn forward(&self, observations: &[f32], raw: &mut [f32]) -> Result<(), String> {
        let agents = raw.len() / self.output_size.max(1);
        if observations.len() != agents * self.input_size || raw.len() != agents * self.output_size {
            return Err(format!(
                "{} observation values and {} output slots do not make whole agents of {} and {}",
                observations.len(),
                raw.len(),
                self.input_size,
                self.output_size
            ));
        }
        let result = match self.batch {
            Batch::Symbolic => self.run(agents, observations, raw),
            Batch::One | Batch::None => observations
                .chunks_exact(self.input_size)
                .zip(raw.chunks_exact_mut(self.output_size))
                .try_for_each(|(o, r)| self.run(1, o, r)),
        };
        result.map_err(|e| format!("{e:#}"))
    }
}
