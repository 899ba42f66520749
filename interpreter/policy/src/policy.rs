//! The interface the engines call ([`Policy`]) and its learned implementation
//! ([`MlpPolicy`]: SigmaRL observation -> network -> output head), where the network is an
//! [`MlpActor`] on cpmx's kernels or a [`Network`] another runtime evaluates (ONNX).
//!
//! A policy is built once per run and then called once per step with all agents; it owns
//! its buffers, its random stream and SigmaRL's one-step memory of footprint corners.

use std::path::Path;
use std::sync::Arc;

use cpmx_vehicle::Command;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha20Rng;

use crate::action::{ActionHead, ActionMode, ActionOutput, OutputHead};
use crate::actor::{ActorError, ActorWorkspace, MlpActor, MlpLayout};
use crate::memory::ObservationMemory;
use crate::observation::{ObservationError, ObservationInput, SigmarlObservation};

/// Errors of building or calling a policy.
#[derive(Debug, thiserror::Error)]
pub enum PolicyError {
    /// The observation could not be formed.
    #[error(transparent)]
    Observation(#[from] ObservationError),
    /// The network could not be loaded or run.
    #[error(transparent)]
    Actor(#[from] ActorError),
    /// The observation design and the network disagree on the input size.
    #[error("the observation has {observation} values but the network expects {network} inputs")]
    InputSize { observation: usize, network: usize },
    /// The network does not produce the raw outputs its output head reads.
    #[error("the network has {found} outputs, the output head reads {expected} ({what})")]
    OutputSize {
        found: usize,
        expected: usize,
        what: &'static str,
    },
    /// A network of another runtime (ONNX) failed to run.
    #[error("the network failed: {0}")]
    Network(String),
    /// A policy process failed (crashed, hung, or answered out of protocol).
    #[error("the policy process {0}")]
    Process(String),
    /// A policy decided outside cpmx's crates (a Python callable) failed.
    #[error("the bound policy {0}")]
    External(String),
    /// The command buffer does not hold one command per agent.
    #[error("{found} command slots for {agents} agents")]
    CommandCount { found: usize, agents: usize },
}

/// A decision maker for all agents of a run, called once per policy step.
pub trait Policy {
    /// Choose one command per agent (`out[i]` for `input.agents[i]`).
    fn act(&mut self, input: &ObservationInput<'_>, out: &mut [Command]) -> Result<(), PolicyError>;

    /// Forget everything carried between steps (call when the run restarts).
    fn reset(&mut self);

    /// A copy for looking ahead: its calls (e.g. on predicted states) leave this policy's
    /// memory untouched. A sampling policy hands the copy a fresh stream seeded from its own,
    /// so the copy's draws are reproducible and do not repeat this policy's future draws.
    fn fork(&mut self) -> Box<dyn Policy>;

    /// This policy as an [`MlpPolicy`] on cpmx's kernels, whose network pass can serve other
    /// policies of the same actor too ([`crate::act_together`]); `None` for any other policy.
    fn as_mlp(&mut self) -> Option<&mut MlpPolicy> {
        None
    }
}

/// The commands of the actions in `outputs`, agent by agent.
pub(crate) fn write_commands(outputs: &[ActionOutput], out: &mut [Command]) {
    for (command, output) in out.iter_mut().zip(outputs) {
        *command = Command {
            speed_mps: f64::from(output.action[0]),
            steering_rad: f64::from(output.action[1]),
        };
    }
}

/// The sampling stream of a policy's fork: a fresh one seeded from `rng` when the policy
/// samples (the copy's draws neither touch nor repeat the policy's), else `rng` as it is.
pub(crate) fn fork_stream(mode: ActionMode, rng: &mut ChaCha20Rng) -> ChaCha20Rng {
    match mode {
        ActionMode::Sample => ChaCha20Rng::seed_from_u64(rng.next_u64()),
        ActionMode::Mean => rng.clone(),
    }
}

/// Check that the command buffer fits the agents.
pub(crate) fn check_commands(input: &ObservationInput<'_>, out: &[Command]) -> Result<(), PolicyError> {
    if out.len() == input.agents.len() {
        Ok(())
    } else {
        Err(PolicyError::CommandCount {
            found: out.len(),
            agents: input.agents.len(),
        })
    }
}

/// A network evaluated by another runtime (an ONNX graph): raw outputs for a batch of
/// observations. Loaded once per experiment and shared by the runs.
pub trait Network: std::fmt::Debug + Send + Sync {
    /// Values per observation.
    fn input_size(&self) -> usize;
    /// Raw outputs per agent.
    fn output_size(&self) -> usize;
    /// Raw outputs for a batch: `observations` holds `agents * input_size()` values
    /// (agent-major), `raw` receives `agents * output_size()` values.
    fn forward(&self, observations: &[f32], raw: &mut [f32]) -> Result<(), String>;
}

/// The network of an [`MlpPolicy`].
#[derive(Debug, Clone)]
enum Net {
    /// An MLP on cpmx's kernels, with its buffers.
    Mlp {
        actor: MlpActor,
        workspace: ActorWorkspace,
    },
    /// A network of another runtime.
    External(Arc<dyn Network>),
}

impl Net {
    fn input_size(&self) -> usize {
        match self {
            Net::Mlp { actor, .. } => actor.input_size(),
            Net::External(n) => n.input_size(),
        }
    }

    fn output_size(&self) -> usize {
        match self {
            Net::Mlp { actor, .. } => actor.output_size(),
            Net::External(n) => n.output_size(),
        }
    }
}

/// A SigmaRL policy: observation design, network and action head.
#[derive(Debug, Clone)]
pub struct MlpPolicy {
    observation: SigmarlObservation,
    net: Net,
    head: ActionHead,
    output: OutputHead,
    mode: ActionMode,
    rng: ChaCha20Rng,
    /// The observations, with the corners of the states seen at the previous call (none after
    /// a reset).
    memory: ObservationMemory,
    raw: Vec<f32>,
    outputs: Vec<ActionOutput>,
}

impl MlpPolicy {
    /// Combine a loaded actor with an observation design and SigmaRL's output head; fails if
    /// their sizes differ. `rng` is the run's policy-sampling stream (only drawn from in
    /// [`ActionMode::Sample`]).
    pub fn new(
        actor: MlpActor,
        observation: SigmarlObservation,
        mode: ActionMode,
        rng: ChaCha20Rng,
    ) -> Result<Self, PolicyError> {
        Self::with_output(actor, observation, OutputHead::default(), mode, rng)
    }

    /// [`MlpPolicy::new`] with another output head.
    pub fn with_output(
        actor: MlpActor,
        observation: SigmarlObservation,
        output: OutputHead,
        mode: ActionMode,
        rng: ChaCha20Rng,
    ) -> Result<Self, PolicyError> {
        check_input_size(&observation, &actor)?;
        let workspace = actor.workspace(0);
        Self::with_net(Net::Mlp { actor, workspace }, observation, output, mode, rng)
    }

    /// A policy over a network of another runtime (an ONNX graph) with `output`'s head; fails
    /// if the network's input is not the observation's size or its outputs are not what the
    /// head reads.
    pub fn with_network(
        network: Arc<dyn Network>,
        observation: SigmarlObservation,
        output: OutputHead,
        mode: ActionMode,
        rng: ChaCha20Rng,
    ) -> Result<Self, PolicyError> {
        if network.input_size() != observation.size() {
            return Err(PolicyError::InputSize {
                observation: observation.size(),
                network: network.input_size(),
            });
        }
        Self::with_net(Net::External(network), observation, output, mode, rng)
    }

    /// The same policy drawing its observation's noise (if the design adds any) from `rng`.
    pub fn with_noise_stream(mut self, rng: ChaCha20Rng) -> Self {
        self.memory.set_noise_stream(rng);
        self
    }

    /// The same policy with the actions' half-ranges of `head` (a SigmaRL release's car; the
    /// default is SigmaRL's later ±1 m/s, ±31°).
    pub fn with_action_head(mut self, head: ActionHead) -> Self {
        self.head = head;
        self
    }

    fn with_net(
        net: Net,
        observation: SigmarlObservation,
        output: OutputHead,
        mode: ActionMode,
        rng: ChaCha20Rng,
    ) -> Result<Self, PolicyError> {
        if net.output_size() != output.raw_size() {
            return Err(PolicyError::OutputSize {
                found: net.output_size(),
                expected: output.raw_size(),
                what: output.describe(),
            });
        }
        Ok(MlpPolicy {
            observation,
            net,
            head: ActionHead::default(),
            output,
            mode,
            rng,
            memory: ObservationMemory::default(),
            raw: Vec::new(),
            outputs: Vec::new(),
        })
    }

    /// Load SigmaRL actor weights (safetensors, [`MlpLayout::sigmarl`] with the observation's
    /// size as input) and build the policy.
    pub fn from_file(
        weights: &Path,
        observation: SigmarlObservation,
        mode: ActionMode,
        rng: ChaCha20Rng,
    ) -> Result<Self, PolicyError> {
        let layout = MlpLayout {
            input_size: observation.size(),
            ..MlpLayout::sigmarl()
        };
        Self::new(MlpActor::load(weights, &layout)?, observation, mode, rng)
    }

    /// Distribution parameters and actions of the last call, one per agent.
    pub fn outputs(&self) -> &[ActionOutput] {
        &self.outputs
    }

    /// Observations of the last call (`agents * size` values, agent-major).
    pub fn observations(&self) -> &[f32] {
        self.memory.observations()
    }

    /// Size buffers for `agents` (allocates only when the agent count grows).
    fn prepare(&mut self, agents: usize) {
        self.raw.resize(agents * self.net.output_size(), 0.0);
        self.outputs.resize(agents, ActionOutput::default());
        if let Net::Mlp { actor, workspace } = &mut self.net
            && workspace.capacity() < agents
        {
            *workspace = actor.workspace(agents);
        }
    }
}

/// The check `cpmx validate` runs: the observation size must equal the network's input size.
pub fn check_input_size(observation: &SigmarlObservation, actor: &MlpActor) -> Result<(), PolicyError> {
    if observation.size() == actor.input_size() {
        Ok(())
    } else {
        Err(PolicyError::InputSize {
            observation: observation.size(),
            network: actor.input_size(),
        })
    }
}

impl MlpPolicy {
    /// The first half of [`Policy::act`]: checks the command buffer, observes every agent (with
    /// the caller's previous corners if given, else the policy's own memory of the previous
    /// call; remembering this step's corners for the next) and returns the network's input,
    /// one row per agent.
    pub fn observe(&mut self, input: &ObservationInput<'_>, out: &[Command]) -> Result<&[f32], PolicyError> {
        check_commands(input, out)?;
        self.prepare(input.agents.len());
        Ok(self.memory.observe(&self.observation, input)?)
    }

    /// The actor on cpmx's kernels, if the network is one (else another runtime's).
    pub fn actor(&self) -> Option<&MlpActor> {
        match &self.net {
            Net::Mlp { actor, .. } => Some(actor),
            Net::External(_) => None,
        }
    }

    /// The second half of [`Policy::act`]: the output head on the network's raw outputs for
    /// the agents of the last [`MlpPolicy::observe`] (one row each), as commands.
    pub fn act_on_outputs(&mut self, raw: &[f32], out: &mut [Command]) {
        for (raw, output) in raw.chunks_exact(self.output.raw_size()).zip(&mut self.outputs) {
            *output = self.output.map(&self.head, raw, self.mode, &mut self.rng);
        }
        write_commands(&self.outputs, out);
    }
}

impl Policy for MlpPolicy {
    /// Observe, run the network for all agents at once, map to commands.
    fn act(&mut self, input: &ObservationInput<'_>, out: &mut [Command]) -> Result<(), PolicyError> {
        self.observe(input, out)?;
        let observations = self.memory.observations();
        debug_assert_eq!(self.net.input_size(), self.observation.size());
        let mut raw = std::mem::take(&mut self.raw);
        let passed = match &mut self.net {
            Net::Mlp { actor, workspace } => actor
                .forward(observations, workspace, &mut raw)
                .map_err(PolicyError::from),
            Net::External(network) => network
                .forward(observations, &mut raw)
                .map_err(PolicyError::Network),
        };
        if passed.is_ok() {
            self.act_on_outputs(&raw, out);
        }
        self.raw = raw;
        passed
    }

    fn as_mlp(&mut self) -> Option<&mut MlpPolicy> {
        match self.net {
            Net::Mlp { .. } => Some(self),
            Net::External(_) => None,
        }
    }

    fn reset(&mut self) {
        self.memory.forget();
    }

    fn fork(&mut self) -> Box<dyn Policy> {
        let mut copy = self.clone();
        copy.memory = self.memory.remembering();
        copy.rng = fork_stream(self.mode, &mut self.rng);
        Box::new(copy)
    }
}
