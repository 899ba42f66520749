//! `cpmx export ACTOR --format onnx`: a trained actor (a `cpmx train` seed folder, or any MLP
//! stored as safetensors) as an ONNX model that any ONNX runtime loads, so that cpmx's policies
//! run elsewhere. The model maps observations `[batch, inputs]` to the network's raw outputs
//! `[batch, outputs]` (for SigmaRL's head: two locations and two pre-scales of the TanhNormal;
//! the mean action is `high * tanh(loc)`). The written file is read back with tract and
//! compared with the safetensors actor before the command reports success.

use std::path::{Path, PathBuf};

use cpmx_onnx::{Activation, LinearStyle, OnnxActor, mlp_to_onnx};
use cpmx_policy::MlpActor;

use super::Failure;

/// The formats `cpmx export` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ExportFormat {
    /// ONNX (opset 13), as torch.onnx exports an MLP.
    Onnx,
}

/// The hidden layers' activation of the actor to export.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ExportActivation {
    Tanh,
    Relu,
    Elu,
}

/// Options of `cpmx export`.
#[derive(Debug, clap::Args)]
pub struct ExportArgs {
    /// A `cpmx train` seed folder (its `actor.safetensors`) or a safetensors MLP file.
    pub actor: PathBuf,
    /// The format to write.
    #[arg(long, value_enum)]
    pub format: ExportFormat,
    /// The file to write. Default: beside the actor, `actor.onnx` (or the file's name with
    /// `.onnx`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// The activation after every hidden layer (what the network was trained with; `cpmx
    /// train` trains tanh networks).
    #[arg(long, value_enum, default_value_t = ExportActivation::Tanh)]
    pub activation: ExportActivation,
}

/// Observations the written model is checked on.
const CHECKED_OBSERVATIONS: usize = 256;

pub fn run(args: &ExportArgs) -> Result<(), Failure> {
    let weights = if args.actor.is_dir() {
        args.actor.join("actor.safetensors")
    } else {
        args.actor.clone()
    };
    let bytes = std::fs::read(&weights).map_err(|e| {
        eprintln!("error: cannot read the actor `{}`: {e}", weights.display());
        if args.actor.is_dir() {
            eprintln!("help: a `cpmx train` seed folder holds `actor.safetensors`; name it or the file");
        }
        Failure::InvalidInput
    })?;
    let activation = match args.activation {
        ExportActivation::Tanh => Activation::Tanh,
        ExportActivation::Relu => Activation::Relu,
        ExportActivation::Elu => Activation::Elu,
    };
    let model = mlp_to_onnx(&bytes, activation, LinearStyle::Gemm).map_err(|e| {
        eprintln!("error: `{}`: {e}", weights.display());
        Failure::InvalidInput
    })?;
    let out = args.out.clone().unwrap_or_else(|| default_out(&weights));

    // Check the model against the actor before writing it.
    let actor = MlpActor::load_any(&weights, activation).map_err(|e| {
        eprintln!("error: `{}`: {e}", weights.display());
        Failure::InvalidInput
    })?;
    let written = OnnxActor::from_bytes(&model, None, None).map_err(|e| {
        eprintln!("error: the written model does not load back: {e}; please report this");
        Failure::InvalidInput
    })?;
    let largest = largest_difference(&actor, &written).map_err(|e| {
        eprintln!("error: the written model does not run: {e}; please report this");
        Failure::InvalidInput
    })?;
    if let Err(e) = cpmx_engine::store::write_atomic(&out, &model) {
        eprintln!("error: cannot write `{}`: {e}", out.display());
        return Err(Failure::InvalidInput);
    }
    println!(
        "wrote {}: input `observation` [batch, {}], output `raw` [batch, {}]; on {CHECKED_OBSERVATIONS} \
         observations it gives the actor's outputs within {largest:.1e}",
        out.display(),
        actor.input_size(),
        actor.output_size()
    );
    Ok(())
}

/// Beside the actor: `DIR/actor.onnx` for `DIR/actor.safetensors`, else `NAME.onnx`.
fn default_out(weights: &Path) -> PathBuf {
    weights.with_extension("onnx")
}

/// The largest difference between the actor's raw outputs and the model's on observations
/// spread over [-2, 2] (a fixed sequence: the check is the same on every machine).
fn largest_difference(actor: &MlpActor, model: &OnnxActor) -> Result<f32, String> {
    use cpmx_policy::Network;
    let (inputs, outputs) = (actor.input_size(), actor.output_size());
    let n = CHECKED_OBSERVATIONS;
    let observations: Vec<f32> = (0..n * inputs)
        .map(|k| ((k as f64 * 0.618_033_988_749_895).fract() * 4.0 - 2.0) as f32)
        .collect();
    let mut expected = vec![0.0; n * outputs];
    let mut ws = actor.workspace(n);
    actor
        .forward(&observations, &mut ws, &mut expected)
        .map_err(|e| e.to_string())?;
    let mut got = vec![0.0; n * outputs];
    model.forward(&observations, &mut got)?;
    Ok(expected
        .iter()
        .zip(&got)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f32::max))
}
