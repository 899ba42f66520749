//! Policies: an MLP actor (any layer sizes) or a network exported to ONNX, with its
//! observation design, a policy process in any language, or a built-in baseline.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::PresetOr;

/// One policy of the matrix. Exactly one of `mlp`, `onnx`, `process`, `python` and `builtin`
/// is given.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PolicySpec {
    /// Name of the policy in run keys and tables. Lower-case letters, digits and `-`.
    #[schemars(regex(pattern = r"^[a-z0-9][a-z0-9-]*$"))]
    pub name: String,
    /// A trained actor network (an MLP of any layer sizes stored as safetensors).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mlp: Option<MlpSpec>,
    /// A trained actor network exported to ONNX from any framework, run by cpmx's ONNX
    /// runtime (tract).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub onnx: Option<OnnxSpec>,
    /// A policy process in any language, speaking cpmx's JSON-lines protocol over
    /// stdin/stdout (see docs/policy-process.md); started once per run.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub process: Option<ProcessSpec>,
    /// A policy bound from Python when the spec runs: `cpmx.run(spec, policies={"NAME":
    /// callable})` calls the callable once per step with the agents' observations `[agents,
    /// size]` (of `observation:`, default `stdlib:sigmarl`) and states `[agents, 5]` (x, y,
    /// yaw, speed, steering) and takes actions `[agents, 2]` (speed m/s, steering rad). The
    /// command line cannot run it: `cpmx run` says how to bind it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub python: Option<PythonPolicySpec>,
    /// The observation design the network was trained with (default for `mlp` and `onnx`:
    /// `stdlib:sigmarl`, for `mlp: {trained}` the `training:` section's); for a `process`, the
    /// observation sent with every step (none when omitted).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(with = "Option<PresetOr<ObservationSpec>>")]
    pub observation: Option<ObservationSpec>,
    /// How the network's output distribution becomes an action. Default: `mean`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub action: Option<ActionMode>,
    /// A rule-based policy shipped with cpmx.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub builtin: Option<BuiltinPolicy>,
    /// Parameters of the `lane-follow` baseline.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lane_follow: Option<LaneFollowParams>,
    /// The order in which the agents act within a step, for an actor that observes the actions
    /// of higher-ranked agents (XP-MARL: a SigmaRL checkpoint trained with
    /// `is_using_prioritized_marl`): SigmaRL's learned priority policy, a random order, or none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub priority: Option<PrioritySpec>,
}

/// How the agents of an XP-MARL actor are ranked each step. Agents act in rank order; each
/// observes the actions of its observed neighbours that have already acted this step (zeros for
/// the others), through the communication layer when the fidelity has one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(untagged)]
pub enum PrioritySpec {
    /// `random` or `none`.
    Keyword(PriorityKeyword),
    /// SigmaRL's priority policy.
    Sigmarl(SigmarlPriority),
}

/// Rankings without a network.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum PriorityKeyword {
    /// A fresh uniform permutation every step, from the run's `priority` stream (XP-MARL's
    /// random-priority baseline).
    Random,
    /// No ranking: every agent acts at once with the action slots empty (what SigmaRL 1.2.0's
    /// evaluation did to its random-priority model, whose priority module it never built).
    None,
}

/// SigmaRL's learned priority policy (`*_priority_policy.pth`, saved beside the actor): its
/// score ranks the agents, the highest first.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SigmarlPriority {
    /// A `*_priority_policy.pth` file, or the folder of the training run (relative to the
    /// spec's folder or found on the data path), from which `pick` takes it.
    #[schemars(length(min = 1))]
    pub sigmarl: String,
    /// `best` (`reward<r>_priority_policy.pth`) or `final` (`final_priority_policy.pth`).
    /// Default: the actor's `pick` (SigmaRL saves the two together).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pick: Option<CheckpointPick>,
    /// SHA-256 of the file's bytes (64 hex digits): only a file with this content is taken.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(regex(pattern = r"^[0-9a-f]{64}$"))]
    pub sha256: Option<String>,
}

/// A multi-layer perceptron actor, its layer sizes read from the file: a safetensors file
/// (`weights`), the actor this spec's `training:` section trains (`trained`), or a SigmaRL
/// checkpoint as SigmaRL writes it (`sigmarl`). Exactly one of the three is given.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MlpSpec {
    /// The safetensors file: layers `PREFIX.N.weight` `[outputs, inputs]` and `PREFIX.N.bias`
    /// in ascending `N` (SigmaRL: `actor.{0..3}`), relative to the spec's folder or found on
    /// the data path.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(length(min = 1))]
    pub weights: Option<String>,
    /// The actor trained by this spec's `training:` section for one of its seeds. It is the
    /// file `<dir>/<seed>/actor.safetensors` (`actor.last.safetensors` with `which: last`,
    /// `actors/<iteration>.safetensors` with `iteration`), where `<dir>` is `cpmx train`'s
    /// output folder, by default `out/<name>-train`; the file is looked up like any relative
    /// file (the spec's folder, then the data path) and then in the current directory, where
    /// `cpmx train` writes by default.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trained: Option<TrainedActor>,
    /// A SigmaRL checkpoint as SigmaRL writes it: a `*_policy.pth` file (PyTorch's
    /// `torch.save` of the actor's state dict), or a folder of one training run, from which
    /// `pick` takes the actor. Relative to the spec's folder or found on the data path (e.g.
    /// `paper-at25/seed1` in SigmaRL's reference data). The observation the actor was trained
    /// with comes from the checkpoint's `*_data.json` (its `parameters`); the policy gives no
    /// `observation:` of its own. Read in Rust: no Python at run time.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(length(min = 1))]
    pub sigmarl: Option<String>,
    /// Which actor of a SigmaRL checkpoint folder (`sigmarl: DIR`): `best` (the default:
    /// `reward<r>_policy.pth`, the actor SigmaRL saved at its best mean episode reward, the
    /// highest `r` if there are several) or `final` (`final_policy.pth`, after the last
    /// iteration). Not for a `.pth` file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pick: Option<CheckpointPick>,
    /// The SigmaRL release whose conventions the checkpoint follows (`sigmarl:` only):
    /// `1.5.0` (the default: the paper's actors and later releases), `1.4.0` (its ITSC 2025
    /// checkpoint) or `1.2.0` (its ITSC 2024 and ICRA 2025 checkpoints). A 1.4.0 actor's
    /// steering spans its car's ±45° (later releases' ±31°), and its observation has no
    /// one-step lag of agent 0's boundary distances; its simulation integrates over the step:
    /// pair it with `dynamics: kinematic-rk4`. A 1.2.0 actor's steering spans ±35°, its head
    /// is torchrl 0.2.1's, and its simulation is VMAS's: pair it with `dynamics: kinematic-vmas`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tag: Option<SigmarlTag>,
    /// SHA-256 of the weight file's bytes (64 hex digits). When given, only a file with this
    /// content is taken: the data path is searched for one. `cpmx run` records it in the run
    /// folder's `spec.resolved.yaml`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(regex(pattern = r"^[0-9a-f]{64}$"))]
    pub sha256: Option<String>,
    /// The activation after every hidden layer. Default: `tanh` (SigmaRL).
    #[serde(default)]
    pub activation: MlpActivation,
    /// How the last layer's outputs become an action. Default: `sigmarl-tanh-normal`.
    #[serde(default)]
    pub output: OutputHead,
}

/// A network stored as ONNX: one input fed the observation (`[batch, size]` with a symbolic
/// or unit batch, or `[size]`) and one output read as the raw outputs (`[batch, 4]` for
/// SigmaRL's head, `[batch, 2]` for the deterministic ones), float32.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct OnnxSpec {
    /// The ONNX file (e.g. `torch.onnx.export(actor, ...)`), relative to the spec's folder or
    /// found on the data path.
    #[schemars(length(min = 1))]
    pub file: String,
    /// SHA-256 of the file's bytes (64 hex digits). When given, only a file with this content
    /// is taken: the data path is searched for one. `cpmx run` records it in the run folder's
    /// `spec.resolved.yaml`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(regex(pattern = r"^[0-9a-f]{64}$"))]
    pub sha256: Option<String>,
    /// The graph input that takes the observation. Default: the graph's only input.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(length(min = 1))]
    pub input_name: Option<String>,
    /// The graph output read as the network's raw outputs. Default: the graph's only output.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(length(min = 1))]
    pub output_name: Option<String>,
    /// How the raw outputs become an action. Default: `sigmarl-tanh-normal` (an exported
    /// SigmaRL actor whose graph ends in the 4 raw outputs).
    #[serde(default)]
    pub output: OutputHead,
}

/// Activations of an MLP's hidden layers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum MlpActivation {
    /// tanh (SigmaRL).
    #[default]
    Tanh,
    /// max(x, 0).
    Relu,
    /// x for x > 0, exp(x) - 1 otherwise.
    Elu,
}

/// How a network's raw outputs become the action `[speed m/s, steering rad]` in SigmaRL's
/// action box (speed ±1 m/s, steering ±31°).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum OutputHead {
    /// 4 outputs: 2 locations and 2 pre-scales of a TanhNormal (SigmaRL, torchrl's
    /// `NormalParamExtractor`); `action: mean | sample` applies.
    #[default]
    SigmarlTanhNormal,
    /// 2 outputs squashed by tanh into the box (deterministic actors).
    DeterministicTanh,
    /// 2 outputs taken as speed and steering, clipped to the box.
    DeterministicClip,
}

/// A policy bound from Python (`python: {}`): what it computes is the callable's.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PythonPolicySpec {}

/// A policy process.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ProcessSpec {
    /// Program and arguments, e.g. `[python3, planner.py, --flag]`; run in the spec's folder.
    #[schemars(length(min = 1))]
    pub command: Vec<String>,
    /// Longest wait for one answer [s]; a process that takes longer fails its run.
    #[serde(default = "default_timeout_s")]
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub timeout_s: f64,
}

fn default_timeout_s() -> f64 {
    10.0
}

/// An actor trained by this spec.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TrainedActor {
    /// The training seed (one of `training.seeds`).
    pub seed: u64,
    /// The best actor by SigmaRL's rule (`best`, the default) or the last one (`last`).
    #[serde(default)]
    pub which: TrainedChoice,
    /// Instead, the actor of this iteration, which the training kept
    /// (`training.keep_actors_every`): `<dir>/<seed>/actors/<iteration>.safetensors`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 1))]
    pub iteration: Option<u64>,
    /// `cpmx train`'s output folder, if it was given with `--out`. Default: `out/<name>-train`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(length(min = 1))]
    pub dir: Option<String>,
    /// The fidelity it was trained in: one of `training.fidelity` (needed when that lists
    /// several, whose actors are in `<dir>/<fidelity>/<seed>/`; its only one by default), or,
    /// for an actor in another folder (`dir`), any fidelity of the spec. Reports compare
    /// policies by the fidelity they were trained in (the transfer matrix).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fidelity: Option<String>,
    /// The point of the training section's sweeps it was trained at (`lr=0.001`, as `cpmx
    /// plan` lists the training runs), when the section sweeps a hyperparameter: its actors
    /// are in `<dir>/<point>/...`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(length(min = 1))]
    pub point: Option<String>,
}

/// A SigmaRL release whose conventions a checkpoint follows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
pub enum SigmarlTag {
    /// Tag 1.2.0 (September 2024, the ITSC 2024 and ICRA 2025 papers): actions span ±1 m/s and
    /// ±35°, the location of the TanhNormal shifted into the box and back in float32 as torchrl
    /// 0.2.1 does, no boundary-distance lag. Its simulation is VMAS's: pair it with
    /// `dynamics: kinematic-vmas`.
    #[serde(rename = "1.2.0")]
    V1_2_0,
    /// Tag 1.4.0 (May 2025, the ITSC 2025 paper): actions span ±1 m/s and ±45° (π/4), no
    /// boundary-distance lag in the observation.
    #[serde(rename = "1.4.0")]
    V1_4_0,
    /// Tag 1.5.0 and later (the paper's actors): actions span ±1 m/s and ±31°, agent 0's
    /// boundary distances one step late.
    #[default]
    #[serde(rename = "1.5.0")]
    V1_5_0,
}

impl SigmarlTag {
    /// The half-ranges of the actions, `[speed m/s, steering rad]`: the car of the release.
    pub fn action_high(self) -> [f32; 2] {
        match self {
            SigmarlTag::V1_2_0 => [1.0, 0.610_865_24],
            SigmarlTag::V1_4_0 => [1.0, std::f32::consts::FRAC_PI_4],
            SigmarlTag::V1_5_0 => [1.0, 0.541_052_04],
        }
    }

    /// Whether agent 0's boundary distances are observed one step late.
    pub fn agent0_boundary_lag(self) -> bool {
        self == SigmarlTag::V1_5_0
    }

    /// Whether the TanhNormal's location passes through torchrl 0.2.1's shift into the box and
    /// back (`loc + high - high` in float32, which moves its last bits).
    pub fn shifts_location(self) -> bool {
        self == SigmarlTag::V1_2_0
    }
}

/// Which actor of a SigmaRL checkpoint folder.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum CheckpointPick {
    /// `reward<r>_policy.pth`: the actor at the best mean episode reward (SigmaRL's rule).
    #[default]
    Best,
    /// `final_policy.pth`: the actor after the last iteration.
    Final,
}

impl CheckpointPick {
    /// As the spec writes it.
    pub fn label(self) -> &'static str {
        match self {
            CheckpointPick::Best => "best",
            CheckpointPick::Final => "final",
        }
    }
}

/// Which of a training run's actors.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum TrainedChoice {
    /// The actor with the best `episode_reward_mean` (SigmaRL's rule): `actor.safetensors`.
    #[default]
    Best,
    /// The actor of the last iteration: `actor.last.safetensors`.
    Last,
}

impl TrainedActor {
    /// The actor's file relative to the training folder `dir` (or the default
    /// `out/<spec_name>-train`): `<dir>/<seed>/actor.safetensors` (`actor.last.safetensors`
    /// for `which: last`, `actors/<iteration>.safetensors` for `iteration`), or
    /// `<dir>/<fidelity>/<seed>/...` for an actor of a spec that trains in several fidelities
    /// (`training`: the spec's section, if it has one).
    pub fn relative_file(&self, spec_name: &str, training: Option<&crate::model::TrainingSpec>) -> String {
        let file = match (self.iteration, self.which) {
            (Some(iteration), _) => format!("actors/{iteration}.safetensors"),
            (None, TrainedChoice::Best) => "actor.safetensors".to_owned(),
            (None, TrainedChoice::Last) => "actor.last.safetensors".to_owned(),
        };
        let mut dir = self.dir.as_deref().map_or_else(
            || format!("out/{spec_name}-train"),
            |d| d.trim_end_matches('/').to_owned(),
        );
        if let Some(point) = &self.point {
            dir = format!("{dir}/{point}");
        }
        match &self.fidelity {
            Some(fidelity)
                if training
                    .is_some_and(|t| t.fidelity.several() && t.fidelity.names().contains(fidelity)) =>
            {
                format!("{dir}/{fidelity}/{}/{file}", self.seed)
            }
            _ => format!("{dir}/{}/{file}", self.seed),
        }
    }

    /// The fidelity it was trained in: `fidelity`, else the spec's only training fidelity.
    pub fn trained_in<'a>(&'a self, training: Option<&'a crate::model::TrainingSpec>) -> Option<&'a str> {
        self.fidelity
            .as_deref()
            .or_else(|| training.and_then(|t| t.fidelity.single()))
    }
}

/// Deterministic or stochastic actions.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum ActionMode {
    /// The mean of the TanhNormal, as SigmaRL evaluates (deterministic).
    #[default]
    Mean,
    /// A sample of the TanhNormal, drawn from the run's `policy` stream.
    Sample,
}

/// Built-in baseline policies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum BuiltinPolicy {
    /// Follows its reference path at a target speed, keeps a time gap to the agent ahead and
    /// yields inside the intersection.
    LaneFollow,
}

/// Parameters of the `lane-follow` baseline.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct LaneFollowParams {
    /// Target speed [m/s].
    #[serde(default = "default_target_speed")]
    #[schemars(range(min = 0.0, max = 5.0))]
    pub target_speed: f64,
    /// Time gap kept to the agent ahead [s].
    #[serde(default = "default_time_gap")]
    #[schemars(range(min = 0.0, max = 10.0))]
    pub time_gap_s: f64,
    /// Pure-pursuit look-ahead distance [m].
    #[serde(default = "default_look_ahead")]
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub look_ahead_m: f64,
}

fn default_target_speed() -> f64 {
    0.5
}
fn default_time_gap() -> f64 {
    1.0
}
fn default_look_ahead() -> f64 {
    0.25
}

impl Default for LaneFollowParams {
    fn default() -> Self {
        Self {
            target_speed: default_target_speed(),
            time_gap_s: default_time_gap(),
            look_ahead_m: default_look_ahead(),
        }
    }
}

/// SigmaRL's observation design (ego view, partial observation), with its parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ObservationSpec {
    /// The design. Only `sigmarl` exists.
    pub design: ObservationDesign,
    /// Number of nearest other agents observed.
    #[schemars(range(min = 0, max = 16))]
    pub observed_agents: u32,
    /// Number of short-term reference points.
    #[schemars(range(min = 1, max = 32))]
    pub ref_points: u32,
    /// Index stride between short-term reference points on the centre line.
    #[schemars(range(min = 1, max = 32))]
    pub ref_point_stride: u32,
    /// Position normaliser [m] (SigmaRL: 10 × vehicle length).
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub position_scale_m: f64,
    /// Speed normaliser [m/s] (SigmaRL: maximum speed).
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub speed_scale_mps: f64,
    /// Distance normaliser for centre line, boundaries and other agents [m]
    /// (SigmaRL: 3 × lane width).
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub distance_scale_m: f64,
    /// Observe the distances to the road's boundaries.
    pub boundary_distances: bool,
    /// Observe the distance to the own centre line.
    pub center_line_distance: bool,
    /// SigmaRL's quirk: agent 0's corner-based boundary distances use the previous step's
    /// corners. `true` reproduces SigmaRL's code; `false` uses the current corners.
    pub agent0_boundary_lag: bool,
    /// Observe the steering angles, over 2π (SigmaRL's `is_obs_steering`): the own after the
    /// own speed, each observed agent's after its velocity (1 + `observed_agents` values).
    /// A steering rate limit makes the steering a state the policy cannot see otherwise.
    /// Default: `false` (SigmaRL's published policies).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub steering: bool,
    /// The actions of the observed agents, appended after everything else as `[speed,
    /// steering]` per observed agent, in m/s and rad (SigmaRL 1.2.0's XP-MARL actors):
    /// `propagated` (the action an agent already chose this step, by `priority:` order, else
    /// zeros) or `tentative` (what the same actor chooses for it with the slots empty: SigmaRL's
    /// "perfect opponent modelling"). Default: `none`. Read from a checkpoint's `*_data.json`.
    #[serde(default, skip_serializing_if = "NeighbourActions::is_none")]
    pub neighbour_actions: NeighbourActions,
    /// Observe each observed agent's corners (`true`, the default: SigmaRL's vertices) or,
    /// with `false`, its position in the ego frame, heading relative to the own over 2π and
    /// length and width over the position normaliser (SigmaRL's `is_observe_vertices: false`).
    #[serde(default = "yes", skip_serializing_if = "is_yes")]
    pub neighbour_vertices: bool,
    /// Observe each observed agent's centre distance (default `true`; SigmaRL's
    /// `is_observe_distance_to_agents`).
    #[serde(default = "yes", skip_serializing_if = "is_yes")]
    pub neighbour_distance: bool,
    /// Noise added to every normalised value, uniform on [0, this) and drawn anew each step
    /// from the run's `observation-noise` stream (SigmaRL 1.2.0's `is_add_noise`: 0.2 × the
    /// vehicle's width). Default: 0, none. Policies with a network only.
    #[serde(default, skip_serializing_if = "is_zero")]
    #[schemars(range(min = 0.0, max = 1.0))]
    pub uniform_noise: f64,
    /// Observe in the map frame instead of the ego frame (SigmaRL's bird's-eye view,
    /// `is_ego_view: false`): the own position, heading over 2π and velocity, then reference
    /// points, the others' corners and velocities in map coordinates, positions over these
    /// `[x, y]` normalisers [m] (SigmaRL: its world's 4.5 × 4.0). Default: the ego frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bird_view_scale_m: Option<[f64; 2]>,
}

fn yes() -> bool {
    true
}

fn is_yes(value: &bool) -> bool {
    *value
}

fn is_zero(value: &f64) -> bool {
    *value == 0.0
}

/// Which actions of the observed agents an observation carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum NeighbourActions {
    /// None (SigmaRL's observation).
    #[default]
    None,
    /// Those of higher-ranked agents that acted earlier in the step (XP-MARL).
    Propagated,
    /// Each one's first-pass action (opponent modelling).
    Tentative,
}

impl NeighbourActions {
    /// Whether the observation carries no actions.
    pub fn is_none(&self) -> bool {
        *self == NeighbourActions::None
    }
}

/// Observation designs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum ObservationDesign {
    /// SigmaRL's observation.
    Sigmarl,
}
