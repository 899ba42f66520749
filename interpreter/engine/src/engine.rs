//! The one interface every engine implements: given a run, produce its `Recording`.
//! Engines know nothing of each other, of metrics or of files.

use cpmx_policy::{
    AgentPaths, ExternalPolicy, LaneFollow, LaneFollowParams, MlpPolicy, Policy, PolicyError,
    PrioritizedPolicy, ProcessConfig, ProcessPolicy, Ranking, SlotFilling,
};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use cpmx_recording::Recording;
use cpmx_spec::RunPlan;
use cpmx_spec::matrix::stream_key;
use cpmx_spec::model::{Control, DrawnFidelity, Fidelity, SimulatedFidelity};
use rand::SeedableRng;
use rand_chacha::ChaCha20Rng;

use crate::experiment::Experiment;
use crate::policies::{NeighbourActionSource, PreparedPolicy};
use crate::starts::InitialState;

/// Why a run failed.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    #[error("the map has no reference path {0}")]
    UnknownRefPath(usize),
    #[error("the safety filter needs each agent's path to have two boundary points or more")]
    SafetyLanes,
    /// `on_collision: replace-agent` could not prepare the map's paths or place a car.
    #[error("on_collision: replace-agent: {0}")]
    Replacement(String),
    #[error("the policy failed: {0}")]
    Policy(#[from] PolicyError),
    #[error("the spec has no policy `{0}`")]
    UnknownPolicy(String),
    #[error(
        "policy `{0}` is bound from Python (`python: {{}}`) and nothing was bound to it: run the spec \
         with cpmx.run(spec, policies={{\"{0}\": callable}})"
    )]
    Unbound(String),
    #[error(
        "policy `{policy}` names the actor trained with seed {seed}, which was not found: run `cpmx train` first"
    )]
    NotTrained { policy: String, seed: u64 },
    #[error("the spec has no initial configuration `{0}`")]
    UnknownConfiguration(String),
    #[error("fidelity `{0}` cannot run in this build: {1}")]
    Unsupported(String, String),
    #[error(
        "the lab did not answer within {timeout_s} s: is `cpmx lab emulate` or the lab running on domain {domain}?"
    )]
    LabSilent { timeout_s: f64, domain: u32 },
    #[error(
        "the lab's middleware ticks every {period_ms} ms, but `timing.dt` is {dt_ms} ms: the planner \
         must be called every `dt`; set the Lab Control Center's parameter `middleware_period_ms` \
         to {dt_ms} (lab_control_center/parameters.yaml, default 400) and restart the middleware"
    )]
    LabPeriod { period_ms: u64, dt_ms: u64 },
    #[error("the lab ended the run before its first tick: {0}")]
    LabStopped(String),
    /// A fault of the lab ended the run (the vehicles were commanded to stop).
    #[error("{0}; the run was stopped")]
    LabFault(String),
    /// The preflight did not pass within its wait.
    #[error("the preflight did not pass within {waited_s:.0} s (the run did not start): {headline}\n{table}")]
    Preflight {
        headline: String,
        table: String,
        waited_s: f64,
    },
    /// The operator asked to stop (Ctrl-C).
    #[error("interrupted (Ctrl-C); the vehicles were commanded to stop")]
    Interrupted,
    #[error("the lab's middleware: {0}")]
    Lab(#[from] cpmx_lab::LabError),
    /// The run ended early; what was recorded until then is kept as the run's trajectory.
    #[error("{reason} (the {ticks} ticks recorded before are kept)", ticks = recording.times_s.len())]
    Partial {
        reason: Box<RunError>,
        recording: Box<Recording>,
    },
}

/// What one run needs: the experiment, the run's plan and its initial states.
#[derive(Debug, Clone, Copy)]
pub struct RunInputs<'a> {
    pub experiment: &'a Experiment,
    pub plan: &'a RunPlan,
    pub starts: &'a [InitialState],
    /// The run's simulated fidelity with its randomised parameters drawn for this run
    /// (`None` for the lab, and where an engine reads nothing from its layers).
    pub fidelity: Option<&'a DrawnFidelity>,
    /// Set when the operator asks to stop (Ctrl-C): the lab driver stops the vehicles and
    /// ends its run as interrupted, keeping what it recorded.
    pub stop: Option<&'a AtomicBool>,
    /// Where the lab driver tells the operator what it waits for (the preflight's table).
    pub operator: Option<&'a Operator>,
    /// Whether to record how long the layers took (`cpmx run --timing`).
    pub timing: bool,
}

/// Where a lab run tells the operator what it waits for, while it waits (the library prints
/// nothing; the command line shows it).
#[derive(Clone)]
pub struct Operator(Arc<dyn Fn(&str) + Send + Sync>);

impl Operator {
    /// An operator shown messages by `show`.
    pub fn new(show: impl Fn(&str) + Send + Sync + 'static) -> Self {
        Self(Arc::new(show))
    }

    /// Shows `message`.
    pub fn say(&self, message: &str) {
        (self.0)(message);
    }
}

impl std::fmt::Debug for Operator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Operator")
    }
}

impl RunInputs<'_> {
    /// The map the run drives on (its configuration's).
    pub fn map(&self) -> &cpmx_world::Map {
        self.experiment.map_of(&self.plan.initial_configuration)
    }

    /// The reference path of every agent, in agent order, prepared for the policies.
    pub fn agent_paths(&self) -> Result<AgentPaths, RunError> {
        let paths = self
            .starts
            .iter()
            .map(|s| {
                self.map()
                    .reference_path(s.ref_path)
                    .ok_or(RunError::UnknownRefPath(s.ref_path))
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(AgentPaths::new(paths))
    }

    /// What the agents know of each other through the fidelity's `communication` and
    /// `perception` layers, drawing from the run's streams of those names.
    pub fn neighbour_knowledge(&self) -> cpmx_sensing::NeighbourKnowledge {
        let fidelity = self.fidelity;
        cpmx_stack::neighbour_knowledge(
            self.starts.len(),
            fidelity.and_then(|f| f.communication.as_ref()),
            fidelity.and_then(|f| f.perception.as_ref()),
            |name| stream_key(self.plan.seed, name),
        )
    }

    /// How the run's policy acts (`action: sample` or the mean) and its `policy` stream.
    fn action_mode(&self, sample: bool) -> (cpmx_policy::ActionMode, ChaCha20Rng) {
        let mode = if sample {
            cpmx_policy::ActionMode::Sample
        } else {
            cpmx_policy::ActionMode::Mean
        };
        (mode, ChaCha20Rng::from_seed(stream_key(self.plan.seed, "policy")))
    }

    /// The run's stream of observation noise (`observation-noise`).
    fn noise_stream(&self) -> ChaCha20Rng {
        ChaCha20Rng::from_seed(stream_key(self.plan.seed, "observation-noise"))
    }

    /// A fresh policy for this run, with its random stream (`policy`) from the run's seed.
    pub fn policy(&self) -> Result<Box<dyn Policy>, RunError> {
        let prepared = self
            .experiment
            .policy(&self.plan.policy)
            .ok_or_else(|| RunError::UnknownPolicy(self.plan.policy.clone()))?;
        Ok(match prepared {
            PreparedPolicy::Mlp {
                actor,
                observation,
                output,
                head,
                sample,
                neighbour_actions,
            } => {
                let (mode, rng) = self.action_mode(*sample);
                let noise = self.noise_stream();
                let actor = actor.as_ref().clone();
                match neighbour_actions {
                    None => Box::new(
                        MlpPolicy::with_output(actor, *observation, *output, mode, rng)?
                            .with_action_head(*head)
                            .with_noise_stream(noise),
                    ),
                    Some(source) => {
                        let filling = match source {
                            NeighbourActionSource::Learned(priority) => {
                                SlotFilling::Propagated(Ranking::Learned(Box::new(priority.as_ref().clone())))
                            }
                            NeighbourActionSource::Random => SlotFilling::Propagated(Ranking::Random(
                                Box::new(ChaCha20Rng::from_seed(stream_key(self.plan.seed, "priority"))),
                            )),
                            NeighbourActionSource::Unranked => SlotFilling::Propagated(Ranking::Unranked),
                            NeighbourActionSource::Tentative => SlotFilling::Tentative,
                        };
                        Box::new(
                            PrioritizedPolicy::new(actor, *observation, filling, *output, mode, rng)?
                                .with_action_head(*head)
                                .with_noise_stream(noise),
                        )
                    }
                }
            }
            PreparedPolicy::Onnx {
                network,
                observation,
                output,
                sample,
            } => {
                let (mode, rng) = self.action_mode(*sample);
                Box::new(
                    MlpPolicy::with_network(network.clone(), *observation, *output, mode, rng)?
                        .with_noise_stream(self.noise_stream()),
                )
            }
            PreparedPolicy::Process {
                spec,
                observation,
                dir,
            } => Box::new(
                ProcessPolicy::start(ProcessConfig {
                    command: spec.command.clone(),
                    dir: dir.clone(),
                    timeout_s: spec.timeout_s,
                    observation: *observation,
                    seed: self.plan.seed,
                    dt_s: self.experiment.spec.timing.dt,
                    name: self.plan.policy.clone(),
                })?
                .with_noise_stream(self.noise_stream()),
            ),
            PreparedPolicy::External { observation, decider } => {
                let decider = decider
                    .clone()
                    .ok_or_else(|| RunError::Unbound(self.plan.policy.clone()))?;
                Box::new(ExternalPolicy::new(decider, *observation).with_noise_stream(self.noise_stream()))
            }
            PreparedPolicy::NotTrained { seed } => {
                return Err(RunError::NotTrained {
                    policy: self.plan.policy.clone(),
                    seed: *seed,
                });
            }
            PreparedPolicy::LaneFollow(p) => Box::new(LaneFollow::new(LaneFollowParams {
                target_speed_mps: p.target_speed,
                time_gap_s: p.time_gap_s,
                look_ahead_m: p.look_ahead_m,
                ..LaneFollowParams::default()
            })),
        })
    }
}

/// An engine: produces a run's recording.
pub trait Engine: Sync {
    fn run(&self, inputs: &RunInputs<'_>) -> Result<Recording, RunError>;

    /// Several runs of one experiment, each result the one [`Engine::run`] gives: one after
    /// the other, unless the engine shares work between runs in lock-step (the twin's MPCs).
    fn run_together(&self, inputs: &[RunInputs<'_>]) -> Vec<Result<Recording, RunError>> {
        inputs.iter().map(|inputs| self.run(inputs)).collect()
    }

    /// Whether [`Engine::run_together`] gains from being handed several runs.
    fn steps_together(&self) -> bool {
        false
    }
}

/// [`Engine::run`] of an engine whose primitive is [`Engine::run_together`]: a group of one.
pub(crate) fn run_alone(engine: &dyn Engine, inputs: &RunInputs<'_>) -> Result<Recording, RunError> {
    let mut results = engine.run_together(std::slice::from_ref(inputs));
    results.pop().expect("one result per run")
}

/// The engine of a fidelity, or why this build has none.
pub fn engine_for(name: &str, fidelity: &Fidelity) -> Result<&'static dyn Engine, RunError> {
    if let Some(reason) = crate::checks::unsupported_reason(fidelity) {
        return Err(RunError::Unsupported(name.to_owned(), reason));
    }
    match fidelity {
        Fidelity::Simulated(SimulatedFidelity {
            control: Control::Direct,
            ..
        }) => Ok(&crate::sim::SimEngine),
        Fidelity::Lab(_) => Ok(&crate::lab::LabEngine),
        Fidelity::Simulated(_) => Ok(&crate::twin::TwinEngine),
    }
}
