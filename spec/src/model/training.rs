//! The `training:` section: how `cpmx train` trains the policies the spec evaluates — the
//! fidelity to train in, the scenario, the reward as explicit terms, the algorithm and its
//! hyperparameters, the network, iterations and seeds. `cpmx run` ignores it.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::{ObservationSpec, PresetOr};

/// How to train the spec's policies: one policy per seed (`cpmx train`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TrainingSpec {
    /// The fidelity of this spec to train in (a simulated stack, never a lab driver), or a
    /// list of them: one policy per fidelity and seed, trained into `<out>/<fidelity>/<seed>/`
    /// (a single fidelity: `<out>/<seed>/`). Default: `sim`.
    #[serde(default = "default_fidelity")]
    #[schemars(with = "FidelityNames")]
    pub fidelity: TrainingFidelities,
    /// Where the agents train: reference paths, agents, parallel environments, episode
    /// length, start sampling and reset rules. SigmaRL's: `stdlib:sigmarl-intersection`.
    #[schemars(with = "PresetOr<TrainingScenario>")]
    pub scenario: TrainingScenario,
    /// The reward, term by term; a term that is left out contributes nothing.
    /// SigmaRL's: `stdlib:sigmarl-reward`; with the paper's speed and centre-line terms added:
    /// `stdlib:sigmarl-shaped-reward`.
    #[schemars(with = "PresetOr<RewardSpec>")]
    pub reward: RewardSpec,
    /// The learning algorithm and its hyperparameters. SigmaRL's: `stdlib:mappo-sigmarl`.
    #[schemars(with = "PresetOr<AlgorithmSpec>")]
    pub algorithm: AlgorithmSpec,
    /// The actor network (the critic is centralised over all agents' observations, with the
    /// same hidden layers). Default: SigmaRL's, `{hidden: [256, 256, 256], activation: tanh}`.
    #[serde(default)]
    pub network: NetworkSpec,
    /// The observation design the policy is trained with. Default: `stdlib:sigmarl`.
    #[schemars(with = "PresetOr<ObservationSpec>")]
    pub observation: ObservationSpec,
    /// In a `control: trajectory` fidelity, what the planner plans over the control horizon
    /// after the learner's action, its first step: `actor` (default), the current actor's mean
    /// actions on the predicted states, as the lab's planners plan and `cpmx run` evaluates;
    /// `hold`, the learner's action held for all of Hc, so that its exploration moves the
    /// vehicle for the whole horizon. `control: direct` fidelities have no planner: it does
    /// not concern them.
    #[serde(default, skip_serializing_if = "Lookahead::is_actor")]
    pub lookahead: Lookahead,
    /// The actor the training starts from instead of a random one: a safetensors MLP with the
    /// `network`'s layer sizes (layers `actor.N`, e.g. a `cpmx train` seed folder's
    /// `actor.safetensors`), relative to the spec's folder or found on the data path. A warm
    /// start, for a curriculum: an actor trained in sim-mpc continued in the twin. `{seed}` in
    /// the path stands for the seed trained, so that each seed continues its own actor (e.g.
    /// `policies/transfer/sim-mpc/{seed}/actor.safetensors`). The critic and the optimiser
    /// start fresh; the file's content is part of the seed's fingerprint. Default: none
    /// (SigmaRL's random start).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(length(min = 1))]
    pub initial_actor: Option<String>,
    /// Training iterations per seed (SigmaRL: 1000).
    #[schemars(range(min = 1, max = 1000000))]
    pub iterations: u32,
    /// Also keep the actor of every this many iterations, as
    /// `<out>/<seed>/actors/<iteration>.safetensors`, so that the actor can be chosen by how it
    /// drives (policies name one with `mlp: {trained: {seed, iteration}}`) rather than by
    /// SigmaRL's best `episode_reward_mean`, which in a randomised fidelity is partly a draw
    /// among noisy iterations. It does not change what trains (nor the seed's fingerprint).
    /// Default: none (the best and the last actor only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 1, max = 1000000))]
    pub keep_actors_every: Option<u32>,
    /// One policy per seed: the training runs of `cpmx train`, written to
    /// `<out>/<seed>/` (default `<out>`: `out/<name>-train`).
    #[schemars(length(min = 1))]
    pub seeds: Vec<u64>,
}

/// What fills the control horizon after the learner's action when training through the
/// planner (`training.lookahead`).
impl TrainingSpec {
    /// The iterations whose actors `cpmx train` keeps (`keep_actors_every`).
    pub fn kept_actors(&self) -> KeptActors {
        KeptActors(self.keep_actors_every)
    }

    /// The `initial_actor` file of `seed`: the path with `{seed}` replaced by the seed.
    pub fn initial_actor_of(&self, seed: u64) -> Option<String> {
        self.initial_actor
            .as_ref()
            .map(|file| file.replace("{seed}", &seed.to_string()))
    }
}

/// The iterations whose actors a training keeps besides the best and the last: every Nth
/// (`keep_actors_every: N`), or none. The one rule `cpmx train` writes by and `cpmx validate`
/// checks a policy's `trained: {iteration}` against.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct KeptActors(pub Option<u32>);

impl KeptActors {
    /// Whether the actor of `iteration` is kept.
    pub fn keeps(self, iteration: u64) -> bool {
        self.0
            .is_some_and(|every| iteration.is_multiple_of(u64::from(every)))
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum Lookahead {
    /// The current actor's mean actions on the predicted states (the lab's planner).
    #[default]
    Actor,
    /// The learner's action, held for the whole control horizon.
    Hold,
}

impl Lookahead {
    /// The default, which the resolved spec leaves out (so that it does not change the
    /// fingerprints of actors trained before the key existed).
    pub fn is_actor(&self) -> bool {
        *self == Lookahead::Actor
    }
}

fn default_fidelity() -> TrainingFidelities {
    TrainingFidelities(vec!["sim".to_owned()])
}

/// The fidelities a spec trains in, in the order given (never empty, no name twice: checked).
/// Written as one name or a list.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TrainingFidelities(pub Vec<String>);

impl TrainingFidelities {
    /// The names, in order.
    pub fn names(&self) -> &[String] {
        &self.0
    }

    /// Whether more than one is listed (trainings go to `<out>/<fidelity>/<seed>/`).
    pub fn several(&self) -> bool {
        self.0.len() > 1
    }

    /// The only one, when exactly one is listed.
    pub fn single(&self) -> Option<&str> {
        match self.0.as_slice() {
            [one] => Some(one),
            _ => None,
        }
    }
}

/// One fidelity name, or a list of them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(untagged)]
enum FidelityNames {
    /// One fidelity.
    One(String),
    /// Several, each trained alike.
    Several(#[schemars(length(min = 1))] Vec<String>),
}

impl Serialize for TrainingFidelities {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        match self.single() {
            Some(one) => serializer.serialize_str(one),
            None => self.0.serialize(serializer),
        }
    }
}

impl<'de> Deserialize<'de> for TrainingFidelities {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        Ok(TrainingFidelities(
            match FidelityNames::deserialize(deserializer)? {
                FidelityNames::One(name) => vec![name],
                FidelityNames::Several(names) => names,
            },
        ))
    }
}

/// The training scenario. Exactly one of `path_set`, `ref_paths` and `region` says which
/// reference paths agents are placed on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TrainingScenario {
    /// One of SigmaRL's path sets of the CPM Lab map, numbered as SigmaRL numbers them
    /// (`intersection`: the 24 open paths through the central intersection).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path_set: Option<PathSetName>,
    /// Reference path ids of the spec's map (its own numbering and `map.ref_paths`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ref_paths: Option<Vec<u32>>,
    /// Every reference path of the spec's map that runs through this region.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub region: Option<String>,
    /// Agents per environment (SigmaRL: 4).
    #[schemars(range(min = 1, max = 64))]
    pub agents: u32,
    /// Parallel environments (SigmaRL: 32).
    #[schemars(range(min = 1, max = 65536))]
    pub envs: u32,
    /// SigmaRL's `max_steps`: an environment is done when its step counter reaches
    /// `episode_steps - 1` (so SigmaRL's 128 gives episodes of at most 127 steps), and the
    /// time limit counts as a termination.
    #[schemars(range(min = 2, max = 1000000))]
    pub episode_steps: u32,
    /// How agents are (re)placed.
    pub start: TrainingStart,
    /// What collisions and the entry/exit lines reset.
    pub reset: TrainingReset,
}

/// SigmaRL's path sets of the CPM Lab map.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum PathSetName {
    /// The 40 loops (`cpm_entire`, ids 0..39): the numbering the rest of a spec uses.
    Entire,
    /// The 24 open intersection paths (`cpm_mixed` scenario 1, ids 0..23).
    Intersection,
    /// The 4 merge-in paths (ids 0..3).
    MergeIn,
    /// The 4 merge-out paths (ids 0..3).
    MergeOut,
}

/// Start sampling: a uniformly drawn path, a uniformly drawn centre-line point index in
/// `[first_index, floor(n / 2))`, heading along the path, steering 0, a uniform speed;
/// redrawn until the centre is `min_gap_m` from the agents already placed (at a whole reset
/// those before it, at a single-agent reset all others).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TrainingStart {
    /// First admissible centre-line point index (SigmaRL: 3).
    #[schemars(range(min = 0, max = 100000))]
    pub first_index: u32,
    /// Speed range [m/s], `[low, high)`, low < high (SigmaRL: `[0, 1]`, i.e. U[0, 1)).
    pub speed_mps: [f64; 2],
    /// Smallest centre distance to other agents at placement [m] (SigmaRL: 1.5 × the µCar's
    /// diagonal, 0.36696).
    #[schemars(range(min = 0))]
    pub min_gap_m: f64,
}

/// What collisions and the entry/exit lines reset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TrainingReset {
    /// On any agent-agent or agent-boundary collision (SigmaRL: `environment`).
    pub on_collision: ResetScopeName,
    /// When an agent touches its path's entry or exit line (SigmaRL: `agent`, after the
    /// step's reward and observation, which stay the pre-reset ones).
    pub on_entry_or_exit_line: ResetScopeName,
}

/// What an event resets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum ResetScopeName {
    /// The episode of the whole environment ends (done) and every agent is re-placed.
    Environment,
    /// The agent alone is re-placed; the episode goes on.
    Agent,
    /// Nothing.
    None,
}

/// The reward: the sum of the terms given, then the clamp.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RewardSpec {
    /// Progress towards the short-term reference points:
    /// `weight × Σ_k w_k ⟨p − p_prev, q_k − p_prev⟩ / (max speed × dt)`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub progress: Option<ProgressSpec>,
    /// `penalty × ramp(d)`, `d` the smallest distance of the centre (minus half the width)
    /// and the 4 corners to the shared road boundaries; the ramp falls from 1 at 0 to 0 at
    /// `within_m`, linearly (SigmaRL today) or exponentially (SigmaRL when the paper's
    /// policies were trained).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub near_boundary: Option<NearBoundarySpec>,
    /// `penalty × Σ_j ramp(c_ij)` over the other agents, `c_ij` the distance of the centres;
    /// the ramp falls from 1 at `from_m` to 0 at `to_m` (SigmaRL when the paper's policies were
    /// trained: exponentially from (L + W) / 2 to L + W).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub near_agents: Option<NearAgentsSpec>,
    /// `penalty × mean_j (1 − clamp(TTC_ij, 0, horizon_s) / horizon_s)` over the other agents
    /// within `within_m` (SigmaRL's, which is practically always 0: see `safe_distance_m`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub near_agents_ttc: Option<TtcSpec>,
    /// `weight × v_along / max speed`, times `against_path_factor` when moving against the
    /// path: the paper's `r_speed` (SigmaRL's `ttc_sparse` reward has none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed: Option<SpeedSpec>,
    /// `penalty × d / scale_m`, `d` the centre's distance to the centre line: the paper's
    /// `r_track` (SigmaRL's `ttc_sparse` reward has none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub centre_line: Option<CentreLineSpec>,
    /// `weight × f × mean_k ⟨v, q_k − p_prev⟩ / max speed`, the velocity after the step against
    /// the (unnormalised) vectors from the previous position to the short-term reference
    /// points of `progress`, `f = against_path_factor` when that mean is negative: SigmaRL's
    /// "high velocity" reward when the paper's policies were trained.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity_to_points: Option<VelocityToPointsSpec>,
    /// `± weight × |v| / max speed`, positive when the velocity points towards the short-term
    /// reference points (the mean of `velocity_to_points` is positive), negative otherwise:
    /// SigmaRL's "time" reward when the paper's policies were trained.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time: Option<TimeSpec>,
    /// `penalty × max(|δ_t − δ_(t−1)| − threshold_rad, 0) / (2 δ_max − 2 threshold_rad)`, the
    /// change of the steering command from the agent's previous step (0 before its first step
    /// after a placement): SigmaRL's steering-change penalty when the paper's policies were
    /// trained.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub steering_change: Option<SteeringChangeSpec>,
    /// SigmaRL's CBF-informed reward (ITSC 2026, tag 1.6.0): the safety filter's rows (each
    /// circle against the lane's left and right boundaries, and against every other
    /// agent's circles) evaluated under the joint sampled action, without solving or
    /// filtering; `weight × mean(clamp(g_left / threshold, −1, 0), clamp(g_right / …),
    /// clamp(min(g_agents, 0) / …))`, each `g` the worst row of its kind.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cbf_margins: Option<CbfMarginsSpec>,
    /// Added when the agent's rectangle crosses another agent's (SigmaRL adds its -1 twice: -2).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub collide_agents: Option<f64>,
    /// Added when the agent's rectangle crosses its road's boundaries (SigmaRL: -2).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub collide_boundary: Option<f64>,
    /// The sum is clamped to `[low, high]` (SigmaRL: `[-1, 1]`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub clamp: Option<[f64; 2]>,
}

/// The progress term.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ProgressSpec {
    /// Weight (SigmaRL's `reward_progress`: 0.1).
    pub weight: f64,
    /// Number of short-term reference points (SigmaRL: 3).
    #[schemars(range(min = 1, max = 32))]
    pub points: u32,
    /// Index spacing of the points on the centre line (SigmaRL: 2). Default: 2.
    #[serde(default = "default_spacing")]
    #[schemars(range(min = 1, max = 32))]
    pub spacing: u32,
    /// Weights of the points; one per point. Default: SigmaRL's `linspace(1, 0.2, points)`
    /// normalised to sum 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub point_weights: Option<Vec<f64>>,
}

fn default_spacing() -> u32 {
    2
}

/// The speed reward.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SpeedSpec {
    /// Weight at the maximum speed along the path.
    pub weight: f64,
    /// Multiplies the term when the velocity points against the path (SigmaRL: 2). Default 1.
    #[serde(default = "default_against_path_factor")]
    #[schemars(range(min = 0))]
    pub against_path_factor: f64,
}

fn default_against_path_factor() -> f64 {
    1.0
}

/// The centre-line penalty.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CentreLineSpec {
    /// Penalty at a distance of `scale_m` (SigmaRL: -0.02).
    pub penalty: f64,
    /// Distance normaliser [m] (SigmaRL: (lane width - vehicle width) / 2 = 0.0215 on the CPM map).
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub scale_m: f64,
}

/// The near-boundary penalty.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct NearBoundarySpec {
    /// Penalty at distance 0 (SigmaRL: -0.2).
    pub penalty: f64,
    /// Distance where the penalty reaches 0 [m] (SigmaRL: 0.02).
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub within_m: f64,
    /// How the penalty falls with the distance. Default: `linear` (SigmaRL today).
    #[serde(default, skip_serializing_if = "RampShape::is_linear")]
    pub shape: RampShape,
}

/// How a proximity penalty falls from its full value to 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum RampShape {
    /// `1 − x`, `x` the clamped distance scaled to [0, 1] (SigmaRL's `decreasing_fcn`).
    #[default]
    Linear,
    /// `(e^(−x) − e^(−1)) / (1 − e^(−1))` (SigmaRL's `exponential_decreasing_fcn`).
    Exponential,
}

impl RampShape {
    /// Whether this is the default, `linear`.
    pub fn is_linear(&self) -> bool {
        *self == RampShape::Linear
    }
}

/// The penalty for other agents' centres nearby.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct NearAgentsSpec {
    /// Penalty per other agent at a centre distance of `from_m` or less (SigmaRL then: -0.2).
    pub penalty: f64,
    /// Centre distance at and below which the full penalty applies [m] (SigmaRL then:
    /// (L + W) / 2).
    #[schemars(range(min = 0))]
    pub from_m: f64,
    /// Centre distance at and beyond which nothing applies [m], above `from_m` (SigmaRL then:
    /// L + W).
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub to_m: f64,
    /// How the penalty falls between the two. Default: `linear`.
    #[serde(default, skip_serializing_if = "RampShape::is_linear")]
    pub shape: RampShape,
}

/// The velocity towards the short-term reference points.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct VelocityToPointsSpec {
    /// Weight (SigmaRL then: 0.05).
    pub weight: f64,
    /// Multiplies the term when it is negative (SigmaRL then: 2). Default 1.
    #[serde(default = "default_against_path_factor")]
    #[schemars(range(min = 0))]
    pub against_path_factor: f64,
}

/// The time reward.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TimeSpec {
    /// Weight at the maximum speed (SigmaRL then: 0.05).
    pub weight: f64,
}

/// The steering-change penalty.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SteeringChangeSpec {
    /// Penalty per unit of the normalised excess change (SigmaRL then: -0.02).
    pub penalty: f64,
    /// Changes up to this much are free [rad] (SigmaRL then: 10° = 0.17453); below the
    /// vehicle's steering limit.
    #[schemars(range(min = 0))]
    pub threshold_rad: f64,
}

/// The CBF-informed reward term: SigmaRL 1.6.0's constraint values under the joint action.
/// The rows are the filter's truncated-Taylor rows `λh + ḣΔt + ½ḧΔt²` on circles that cover
/// the training vehicle (the lane rows keep each circle's covering radius from the boundary;
/// the pair rows keep two circles a diameter apart); each sampled command becomes the
/// acceleration and steering rate that reach it over one `dt` (speed clamped to [−0.5, max
/// speed], steering to the vehicle's limit, the rates to ±5 m/s² and ±π/2 rad/s, SigmaRL's).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CbfMarginsSpec {
    /// The mean of the three clamped terms is multiplied by this (SigmaRL: 1).
    #[serde(default = "default_one")]
    pub weight: f64,
    /// A row's value is divided by this before it is clamped to [−1, 0]: a margin this short
    /// costs the whole term (SigmaRL's `h_nom`, the paper's CBF constraint threshold: 0.1).
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub threshold: f64,
    /// The class-K gain λ (SigmaRL: 0.5).
    #[serde(default = "default_cbf_margin_gain")]
    #[schemars(range(min = 0))]
    pub gain: f64,
    /// The Taylor horizon Δt in steps of `dt` (SigmaRL: 2).
    #[serde(default = "default_cbf_margin_horizon")]
    #[schemars(range(min = 1, max = 100))]
    pub horizon_steps: u32,
    /// Circles along the vehicle (SigmaRL: 3).
    #[serde(default = "default_cbf_margin_circles")]
    #[schemars(range(min = 1, max = 20))]
    pub circles: u32,
}

fn default_one() -> f64 {
    1.0
}

fn default_cbf_margin_gain() -> f64 {
    0.5
}

fn default_cbf_margin_horizon() -> u32 {
    2
}

fn default_cbf_margin_circles() -> u32 {
    3
}

/// The time-to-collision penalty.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TtcSpec {
    /// Penalty at TTC 0 (SigmaRL: -0.2).
    pub penalty: f64,
    /// Other agents farther than this centre distance are ignored [m] (SigmaRL: 0.3).
    #[schemars(range(min = 0))]
    pub within_m: f64,
    /// TTC where the penalty reaches 0 [s] (SigmaRL: 3.75).
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub horizon_s: f64,
    /// The TTC is the time until the centres are this close [m]. Default 0 (SigmaRL's
    /// setting, under which a TTC exists only when the relative velocity points exactly at
    /// the other centre).
    #[serde(default)]
    #[schemars(range(min = 0))]
    pub safe_distance_m: f64,
}

/// The learning algorithm. Only `mappo` exists.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct AlgorithmSpec {
    /// Multi-agent PPO with a centralised critic, as SigmaRL trains.
    pub mappo: MappoSpec,
}

/// MAPPO's hyperparameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MappoSpec {
    /// Env-steps collected per iteration (over all environments; SigmaRL: 4096 = 32 × 128);
    /// a multiple of the scenario's `envs`.
    #[schemars(range(min = 1, max = 100000000))]
    pub frames_per_iteration: u32,
    /// Env-steps per minibatch (SigmaRL: 512); at most `frames_per_iteration`.
    #[schemars(range(min = 1, max = 100000000))]
    pub minibatch: u32,
    /// Passes over each iteration's batch (SigmaRL: 30).
    #[schemars(range(min = 1, max = 10000))]
    pub epochs: u32,
    /// Learning rate of the first iterations (SigmaRL: 1e-4), decaying linearly towards
    /// `lr_min` with SigmaRL's one-iteration lag.
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub lr: f64,
    /// Learning rate the schedule decays towards (SigmaRL: 1e-5); at most `lr`.
    #[schemars(range(min = 0))]
    pub lr_min: f64,
    /// PPO's ratio clip ε (SigmaRL: 0.2).
    #[schemars(extend("exclusiveMinimum" = 0, "exclusiveMaximum" = 1))]
    pub clip: f64,
    /// Discount (SigmaRL: 0.99).
    #[schemars(range(min = 0, max = 1))]
    pub gamma: f64,
    /// GAE λ (SigmaRL: 0.9).
    #[schemars(range(min = 0, max = 1))]
    pub lambda: f64,
    /// Entropy coefficient (SigmaRL: 5e-4).
    #[schemars(range(min = 0))]
    pub entropy: f64,
    /// Global L2 norm the joint actor and critic gradient is clipped to (SigmaRL: 1.0).
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub max_grad_norm: f64,
    /// The critic's loss (SigmaRL: `smooth-l1`).
    pub value_loss: ValueLoss,
    /// The first iterations that train the critic only: the actor collects but does not
    /// learn. With `initial_actor`, the fresh critic first learns the warm actor's values, so
    /// that its first advantages are not noise that undoes the warm start. Fewer than
    /// `iterations`. Default: 0 (SigmaRL).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub critic_warmup_iterations: u32,
    /// The largest scale of the actor's action noise, before tanh (the scale is clamped to it,
    /// with no gradient above). Default: none (SigmaRL). Through the twin a warm actor's scale
    /// collapsed to its floor (0.01) in most states and grew past 30 in others without one
    /// (docs/transfer.md).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(extend("exclusiveMinimum" = 0.01))]
    pub max_scale: Option<f64>,
}

fn is_zero(n: &u32) -> bool {
    *n == 0
}

/// The critic's loss.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum ValueLoss {
    /// Huber loss with β = 1 (SigmaRL).
    SmoothL1,
    /// Squared error.
    Mse,
}

/// The actor's hidden layers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct NetworkSpec {
    /// Widths of the hidden layers (SigmaRL: `[256, 256, 256]`).
    #[schemars(length(min = 1, max = 16))]
    pub hidden: Vec<u32>,
    /// Activation after each hidden layer (SigmaRL: `tanh`).
    pub activation: Activation,
}

impl Default for NetworkSpec {
    fn default() -> Self {
        NetworkSpec {
            hidden: vec![256, 256, 256],
            activation: Activation::Tanh,
        }
    }
}

/// Activations.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum Activation {
    /// Hyperbolic tangent (SigmaRL).
    Tanh,
    /// Rectified linear unit.
    Relu,
}
