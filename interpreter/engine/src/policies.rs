//! The spec's policies as the interpreter runs them: each network loaded once per experiment
//! (and once per process for the same file), with its observation design, output head and
//! action box; an XP-MARL actor with its ranking. Runs build their [`cpmx_policy::Policy`]
//! from a [`PreparedPolicy`] (see `engine.rs`).

use std::path::Path;
use std::sync::Arc;

use cpmx_policy::{ActionHead, Activation, BoundaryCorners, MlpActor, OutputHead, SigmarlObservation};
use cpmx_spec::model::{
    MlpSpec, NeighbourActions, ObservationSpec, PolicySpec, PriorityKeyword, PrioritySpec,
};

use crate::experiment::PrepareError;
use crate::memo::Memo;

/// A policy as the spec defines it, with its network loaded once.
#[derive(Debug, Clone)]
pub enum PreparedPolicy {
    Mlp {
        actor: Arc<MlpActor>,
        observation: SigmarlObservation,
        output: OutputHead,
        /// The actions' half-ranges (a SigmaRL checkpoint's release's car; else SigmaRL's).
        head: ActionHead,
        sample: bool,
        /// What fills the action slots of an observation that has them (XP-MARL).
        neighbour_actions: Option<NeighbourActionSource>,
    },
    /// A network exported to ONNX, loaded once and shared by the runs.
    Onnx {
        network: Arc<dyn cpmx_policy::Network>,
        observation: SigmarlObservation,
        output: OutputHead,
        sample: bool,
    },
    /// A policy process, started once per run in `dir` (the spec's folder).
    Process {
        spec: cpmx_spec::model::ProcessSpec,
        observation: Option<SigmarlObservation>,
        dir: std::path::PathBuf,
    },
    /// A policy decided in this process by another language (`python: {}`): the decider is
    /// bound with [`Experiment::bind`] before the runs; unbound, its runs fail saying so.
    External {
        observation: Option<SigmarlObservation>,
        decider: Option<Arc<dyn cpmx_policy::Decider>>,
    },
    LaneFollow(cpmx_spec::model::LaneFollowParams),
    /// An `mlp: {trained}` policy whose actor is not there yet: the experiment still prepares
    /// (so runs of the other policies can go ahead), and a run of this one fails saying so.
    NotTrained {
        seed: u64,
    },
}

/// What fills an XP-MARL actor's action slots (see [`cpmx_policy::SlotFilling`]).
#[derive(Debug, Clone)]
pub enum NeighbourActionSource {
    /// Higher-ranked neighbours' actions, ranked by SigmaRL's priority network.
    Learned(Arc<MlpActor>),
    /// Higher-ranked neighbours' actions, ranked at random every step (stream `priority`).
    Random,
    /// No ranking: the slots stay empty.
    Unranked,
    /// Every neighbour's tentative action (opponent modelling).
    Tentative,
}

/// The actors parsed in this process, by activation and file bytes.
static ACTORS: Memo<(Activation, Vec<u8>), MlpActor> = Memo::new();

/// The spec's observation design as the policy crate's.
pub fn observation(o: &ObservationSpec) -> SigmarlObservation {
    SigmarlObservation {
        neighbours: o.observed_agents as usize,
        reference_points: o.ref_points as usize,
        reference_point_stride: o.ref_point_stride as usize,
        position_norm_m: o.position_scale_m,
        speed_norm_mps: o.speed_scale_mps,
        distance_norm_m: o.distance_scale_m,
        observe_center_line_distance: o.center_line_distance,
        observe_boundary_distances: o.boundary_distances,
        observe_steering: o.steering,
        action_slots: !o.neighbour_actions.is_none(),
        observe_vertices: o.neighbour_vertices,
        observe_neighbour_distance: o.neighbour_distance,
        uniform_noise: o.uniform_noise as f32,
        bird_view_scale_m: o.bird_view_scale_m,
        boundary_corners: if o.agent0_boundary_lag {
            BoundaryCorners::LaggedForFirstAgent
        } else {
            BoundaryCorners::Current
        },
        ..SigmarlObservation::default()
    }
}

/// The spec's activation and output head as the policy crate's.
pub fn network_options(mlp: &cpmx_spec::model::MlpSpec) -> (Activation, OutputHead) {
    use cpmx_spec::model::MlpActivation;
    let activation = match mlp.activation {
        MlpActivation::Tanh => Activation::Tanh,
        MlpActivation::Relu => Activation::Relu,
        MlpActivation::Elu => Activation::Elu,
    };
    (activation, output_head(mlp.output))
}

/// The spec's output head as the policy crate's.
pub(crate) fn output_head(head: cpmx_spec::model::OutputHead) -> OutputHead {
    use cpmx_spec::model::OutputHead as Head;
    match head {
        Head::SigmarlTanhNormal => OutputHead::SigmarlTanhNormal,
        Head::DeterministicTanh => OutputHead::DeterministicTanh,
        Head::DeterministicClip => OutputHead::DeterministicClip,
    }
}

/// Loads a policy's network (once per experiment): layer sizes from the file, checked against
/// the observation and the output head.
pub fn load_network(
    mlp: &cpmx_spec::model::MlpSpec,
    observation: &SigmarlObservation,
    weights: &Path,
) -> Result<(MlpActor, OutputHead), cpmx_policy::ActorError> {
    let (activation, output) = network_options(mlp);
    let bytes = std::fs::read(weights).map_err(|source| cpmx_policy::ActorError::Io {
        path: weights.to_owned(),
        source,
    })?;
    // A SigmaRL checkpoint is torch.save's zip archive: read it as such (the spec names it
    // with `sigmarl:`; a `weights:` file that is one is read the same way).
    let checkpoint = mlp.sigmarl.is_some() || bytes.starts_with(b"PK\x03\x04");
    let actor = ACTORS.get_or_parse((activation, bytes), |(activation, bytes)| {
        if checkpoint {
            MlpActor::load_checkpoint(weights, *activation)
        } else {
            MlpActor::from_bytes_any(bytes, *activation)
        }
    })?;
    actor.check_fits(Some(observation.size()), output)?;
    Ok((actor, output))
}

/// Loads a policy's networks (once per experiment): the actor from `weights`, and an XP-MARL
/// actor's priority network from `priority_weights`.
pub fn prepare_policy(
    policy: &PolicySpec,
    weights: Option<&Path>,
    priority_weights: Option<&Path>,
) -> Result<PreparedPolicy, PrepareError> {
    if policy.python.is_some() {
        return Ok(PreparedPolicy::External {
            observation: policy.observation.as_ref().map(observation),
            decider: None,
        });
    }
    if let Some(process) = &policy.process {
        return Ok(PreparedPolicy::Process {
            spec: process.clone(),
            observation: policy.observation.as_ref().map(observation),
            dir: std::path::PathBuf::from("."),
        });
    }
    let sample = policy.action == Some(cpmx_spec::model::ActionMode::Sample);
    if let Some(onnx) = &policy.onnx {
        let observation = observation(policy.observation.as_ref().expect("defaulted to stdlib:sigmarl"));
        let path = weights.unwrap_or(Path::new(&onnx.file));
        let loaded =
            crate::onnx::load(onnx, observation.size(), path).map_err(|source| PrepareError::Onnx {
                policy: policy.name.clone(),
                source,
            })?;
        let output = crate::onnx::head(onnx);
        // A plain MLP runs as `mlp:` weights do: same kernels, same bits.
        return Ok(match loaded {
            crate::onnx::LoadedOnnx::Mlp(actor) => PreparedPolicy::Mlp {
                actor: Arc::new(actor),
                observation,
                output,
                head: ActionHead::default(),
                sample,
                neighbour_actions: None,
            },
            crate::onnx::LoadedOnnx::Graph(network) => PreparedPolicy::Onnx {
                network,
                observation,
                output,
                sample,
            },
        });
    }
    match (&policy.mlp, weights) {
        (Some(mlp), found) => {
            let observation = observation(policy.observation.as_ref().expect("defaulted to stdlib:sigmarl"));
            let path = match (found, &mlp.weights, &mlp.trained) {
                (Some(path), _, _) => path,
                (None, Some(weights), _) => Path::new(weights),
                (None, None, None) if mlp.sigmarl.is_some() => {
                    return Err(PrepareError::Checkpoint {
                        policy: policy.name.clone(),
                    });
                }
                (None, None, trained) => {
                    return Err(PrepareError::NotTrained {
                        policy: policy.name.clone(),
                        seed: trained.as_ref().map_or(0, |t| t.seed),
                    });
                }
            };
            let (actor, output) =
                load_network(mlp, &observation, path).map_err(|source| PrepareError::Actor {
                    policy: policy.name.clone(),
                    source,
                })?;
            let neighbour_actions = neighbour_action_source(policy, &observation, priority_weights)?;
            Ok(PreparedPolicy::Mlp {
                actor: Arc::new(actor),
                observation,
                output,
                // A SigmaRL checkpoint's release decides its box; everything else has SigmaRL's.
                head: action_head(mlp),
                sample,
                neighbour_actions,
            })
        }
        (None, _) => Ok(PreparedPolicy::LaneFollow(
            policy.lane_follow.clone().unwrap_or_default(),
        )),
    }
}

/// The action box (and torchrl 0.2.1's location shift) of a SigmaRL checkpoint's release;
/// SigmaRL's later box for every other actor.
fn action_head(mlp: &MlpSpec) -> ActionHead {
    mlp.tag.map_or_else(ActionHead::default, |tag| ActionHead {
        high: tag.action_high(),
        shift_location: tag.shifts_location(),
    })
}

/// What fills the action slots of an actor whose observation has them: its `priority:` (the
/// priority network loaded from `priority_weights`), or tentative actions.
fn neighbour_action_source(
    policy: &PolicySpec,
    observation: &SigmarlObservation,
    priority_weights: Option<&Path>,
) -> Result<Option<NeighbourActionSource>, PrepareError> {
    let actions = policy
        .observation
        .as_ref()
        .map_or(NeighbourActions::None, |o| o.neighbour_actions);
    let source = match (actions, &policy.priority) {
        (NeighbourActions::None, _) => return Ok(None),
        (NeighbourActions::Tentative, _) => NeighbourActionSource::Tentative,
        (NeighbourActions::Propagated, Some(PrioritySpec::Keyword(PriorityKeyword::Random))) => {
            NeighbourActionSource::Random
        }
        (NeighbourActions::Propagated, Some(PrioritySpec::Keyword(PriorityKeyword::None))) => {
            NeighbourActionSource::Unranked
        }
        (NeighbourActions::Propagated, Some(PrioritySpec::Sigmarl(_)) | None) => {
            let path = priority_weights.ok_or_else(|| PrepareError::Checkpoint {
                policy: policy.name.clone(),
            })?;
            let bytes = std::fs::read(path).map_err(|source| PrepareError::Actor {
                policy: policy.name.clone(),
                source: cpmx_policy::ActorError::Io {
                    path: path.to_owned(),
                    source,
                },
            })?;
            let network = ACTORS
                .get_or_parse((Activation::Tanh, bytes), |_| {
                    MlpActor::load_checkpoint(path, Activation::Tanh)
                })
                .map_err(|source| PrepareError::Actor {
                    policy: policy.name.clone(),
                    source,
                })?;
            let base = observation.size() - observation.action_slot_count();
            if network.input_size() != base || network.output_size() != 2 {
                return Err(PrepareError::Priority {
                    policy: policy.name.clone(),
                    reason: format!(
                        "its priority network maps {} inputs to {} outputs, where the observation without the \
                         action slots has {base} values and a priority score takes 2",
                        network.input_size(),
                        network.output_size()
                    ),
                });
            }
            NeighbourActionSource::Learned(Arc::new(network))
        }
    };
    Ok(Some(source))
}
