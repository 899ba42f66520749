//! `cpmx export ACTOR --format onnx|safetensors`: an actor (a `cpmx train` seed folder, any MLP
//! stored as safetensors, or a SigmaRL checkpoint: a `*_policy.pth` or a folder of one training
//! run) as an ONNX model that any ONNX runtime loads, so that cpmx's policies run elsewhere, or
//! a SigmaRL checkpoint as the safetensors file docs/policies.md's conversion writes (the same
//! bytes). The ONNX model maps observations `[batch, inputs]` to the network's raw outputs
//! `[batch, outputs]` (for SigmaRL's head: two locations and two pre-scales of the TanhNormal;
//! the mean action is `high * tanh(loc)`). The written file is read back with tract and
//! compared with the actor before the command reports success.

use std::path::{Path, PathBuf};

use cpmx_onnx::{Activation, LinearStyle, OnnxActor, mlp_to_onnx};
use cpmx_policy::MlpActor;
use cpmx_spec::model::CheckpointPick;

use super::Failure;

/// The formats `cpmx export` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ExportFormat {
    /// ONNX (opset 13), as torch.onnx exports an MLP.
    Onnx,
    /// safetensors, layers `actor.{i}.weight|bias` (a SigmaRL checkpoint as docs/policies.md
    /// converts it).
    Safetensors,
}

/// Which actor of a SigmaRL checkpoint folder.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ExportPick {
    /// `reward<r>_policy.pth`, the best reward's.
    Best,
    /// `final_policy.pth`.
    Final,
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
    /// A `cpmx train` seed folder (its `actor.safetensors`), a safetensors MLP file, or a SigmaRL
    /// checkpoint (`*_policy.pth`, or a folder of one training run).
    pub actor: PathBuf,
    /// The format to write.
    #[arg(long, value_enum)]
    pub format: ExportFormat,
    /// The file to write. Default: beside the actor, `actor.onnx` (or the file's name with
    /// `.onnx` or `.safetensors`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Which actor of a SigmaRL checkpoint folder (default: the best reward's).
    #[arg(long, value_enum)]
    pub pick: Option<ExportPick>,
    /// The activation after every hidden layer (what the network was trained with; `cpmx
    /// train` trains tanh networks).
    #[arg(long, value_enum, default_value_t = ExportActivation::Tanh)]
    pub activation: ExportActivation,
}

/// Observations the written model is checked on.
const CHECKED_OBSERVATIONS: usize = 256;

pub fn run(args: &ExportArgs) -> Result<(), Failure> {
    let (weights, bytes, checkpoint) = actor_bytes(args)?;
    if args.format == ExportFormat::Safetensors {
        if !checkpoint {
            eprintln!("error: `{}` is a safetensors actor already", weights.display());
            eprintln!("help: `--format safetensors` converts a SigmaRL checkpoint (`*_policy.pth`)");
            return Err(Failure::InvalidInput);
        }
        let out = args
            .out
            .clone()
            .unwrap_or_else(|| weights.with_extension("safetensors"));
        if let Err(e) = cpmx_engine::store::write_atomic(&out, &bytes) {
            eprintln!("error: cannot write `{}`: {e}", out.display());
            return Err(Failure::InvalidInput);
        }
        let actor = MlpActor::from_bytes_any(&bytes, cpmx_policy::Activation::Tanh).map_err(|e| {
            eprintln!("error: the written actor does not read back: {e}; please report this");
            Failure::InvalidInput
        })?;
        let sizes: Vec<String> = actor
            .weight_tensors()
            .iter()
            .map(|(_, [o, _])| o.to_string())
            .collect();
        println!(
            "wrote {}: {} -> {} (`actor.{{i}}.weight|bias`, float32), the tensors of {}",
            out.display(),
            actor.input_size(),
            sizes.join(" -> "),
            weights.display()
        );
        return Ok(());
    }
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
    let actor = MlpActor::from_bytes_any(&bytes, activation).map_err(|e| {
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

/// The actor's file, its safetensors bytes (a SigmaRL checkpoint converted as docs/policies.md
/// does), and whether it was a checkpoint.
fn actor_bytes(args: &ExportArgs) -> Result<(PathBuf, Vec<u8>, bool), Failure> {
    let seed_folder = args.actor.is_dir() && args.actor.join("actor.safetensors").is_file();
    let is_checkpoint = |path: &Path| {
        path.extension().is_some_and(|e| e == "pth" || e == "pt")
            || std::fs::read(path).is_ok_and(|b| b.starts_with(b"PK\x03\x04"))
    };
    if seed_folder || (!args.actor.is_dir() && !is_checkpoint(&args.actor)) {
        let weights = if seed_folder {
            args.actor.join("actor.safetensors")
        } else {
            args.actor.clone()
        };
        let bytes = std::fs::read(&weights).map_err(|e| {
            eprintln!("error: cannot read the actor `{}`: {e}", weights.display());
            Failure::InvalidInput
        })?;
        return Ok((weights, bytes, false));
    }
    let pick = args.pick.map(|p| match p {
        ExportPick::Best => CheckpointPick::Best,
        ExportPick::Final => CheckpointPick::Final,
    });
    let files = cpmx_spec::sigmarl::locate(&args.actor, pick).map_err(|reason| {
        eprintln!("error: {reason}");
        if args.actor.is_dir() {
            eprintln!(
                "help: name a `cpmx train` seed folder (with `actor.safetensors`), a SigmaRL checkpoint folder \
                 (with `reward<r>_policy.pth` or `final_policy.pth`) or a file"
            );
        }
        Failure::InvalidInput
    })?;
    let converted = cpmx_policy::torch::read_state_dict(&files.policy)
        .map_err(cpmx_policy::ActorError::from)
        .and_then(|tensors| cpmx_policy::torch::to_safetensors(&tensors));
    let bytes = converted.map_err(|e| {
        eprintln!("error: {e}");
        Failure::InvalidInput
    })?;
    Ok((files.policy, bytes, true))
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
