//! `onnx: {file}` policies: the graph loaded once per experiment and checked against the
//! observation and the output head (with the `onnx` feature; without it every ONNX policy is
//! refused with a message saying how to build one that runs them).

use std::path::Path;
use std::sync::Arc;

use cpmx_policy::{MlpActor, Network, OutputHead};
use cpmx_spec::model::OnnxSpec;

/// Why an ONNX policy cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum OnnxLoadError {
    /// This build has no ONNX runtime.
    #[error("this build of cpmx runs no ONNX graphs (built without the `onnx` feature)")]
    NotBuilt,
    /// The graph's input does not take the observation.
    #[error("{0}")]
    InputSize(String),
    /// The graph's output is not what the output head reads.
    #[error("{0}")]
    OutputSize(String),
    /// Any other reason: unreadable, not ONNX, several inputs, wrong types or layouts.
    #[error("{0}")]
    Other(String),
}

/// The output head an ONNX spec declares, as the policy crate's.
pub fn head(onnx: &OnnxSpec) -> OutputHead {
    crate::policies::output_head(onnx.output)
}

/// A loaded ONNX graph: a plain MLP, run on cpmx's kernels like `mlp:` weights, or any other
/// graph, run by the ONNX runtime.
#[derive(Debug)]
// Without the `onnx` feature nothing loads a graph; the policy preparation still matches on it.
#[cfg_attr(not(feature = "onnx"), allow(dead_code))]
pub enum LoadedOnnx {
    Mlp(MlpActor),
    Graph(Arc<dyn Network>),
}

/// Loads the graph at `path` and checks it fits `observation` values in and the head out.
#[cfg(feature = "onnx")]
pub fn load(onnx: &OnnxSpec, observation: usize, path: &Path) -> Result<LoadedOnnx, OnnxLoadError> {
    use cpmx_onnx::{OnnxActor, OnnxError};
    let classify = |e: OnnxError| match e {
        OnnxError::InputSize { .. } => OnnxLoadError::InputSize(e.to_string()),
        OnnxError::OutputSize { .. } => OnnxLoadError::OutputSize(e.to_string()),
        e => OnnxLoadError::Other(e.to_string()),
    };
    let actor =
        OnnxActor::load(path, onnx.input_name.as_deref(), onnx.output_name.as_deref()).map_err(classify)?;
    actor.check_fits(observation, head(onnx)).map_err(classify)?;
    Ok(match actor.as_mlp() {
        Some(mlp) => LoadedOnnx::Mlp(mlp.clone()),
        None => LoadedOnnx::Graph(Arc::new(actor)),
    })
}

/// Without the `onnx` feature no graph loads.
#[cfg(not(feature = "onnx"))]
pub fn load(_onnx: &OnnxSpec, _observation: usize, _path: &Path) -> Result<LoadedOnnx, OnnxLoadError> {
    Err(OnnxLoadError::NotBuilt)
}
