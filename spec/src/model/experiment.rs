//! The top level of a spec: identity, map, vehicle, timing, the matrix axes and the planner.

use indexmap::IndexMap;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::{Fidelity, InitialConfiguration, MetricsSpec, PolicySpec, PresetOr, ReportSpec, TrainingSpec};

/// A cpmx experiment: a paired matrix of fidelities × policies × initial configurations ×
/// repetitions, and how to measure every run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(title = "cpmx experiment")]
#[schemars(extend(
    "if" = {"anyOf": [
        {"not": {"required": ["training"]}},
        {"required": ["agents"]},
        {"required": ["policies"]},
        {"required": ["initial_configurations"]},
        {"required": ["repetitions"]},
        {"required": ["seed"]}
    ]},
    "then" = {"required": ["agents", "policies", "initial_configurations", "repetitions", "seed", "fidelities"]}
))]
pub struct Spec {
    /// Language version. Only `1` exists.
    pub cpmx: u32,
    /// Name of the experiment; names the output folder. Lower-case letters, digits and `-`.
    #[schemars(regex(pattern = r"^[a-z0-9][a-z0-9-]*$"), length(max = 64))]
    pub name: String,
    /// Free text describing the experiment.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// The road network: a map file (CommonRoad XML or lanelet2 OSM) or a built-in map
    /// (`stdlib:intersection`).
    pub map: MapSpec,
    /// Vehicle geometry and limits. Default: `stdlib:mu-car`, the CPM Lab µCar.
    #[schemars(with = "PresetOr<VehicleSpec>")]
    pub vehicle: VehicleSpec,
    /// Policy step and evaluation horizon.
    pub timing: Timing,
    /// Number of agents (vehicles) in every run; required, with the other axes of the run
    /// matrix (`cpmx validate` says which are missing). A spec that only trains (`training:`) may
    /// leave out the run matrix (`agents`, `policies`, `initial_configurations`,
    /// `repetitions`, `seed`; `fidelities` then only names fidelities to train in, by default
    /// SigmaRL's `sim`, and `timing` defaults to SigmaRL's `dt: 0.1`); `cpmx run` then has
    /// nothing to run.
    #[serde(default)]
    #[schemars(range(min = 1, max = 64))]
    pub agents: u32,
    /// The policies to compare: one axis of the run matrix. Required unless the spec only
    /// trains (see `agents`).
    #[serde(default)]
    #[schemars(length(min = 1))]
    pub policies: Vec<PolicySpec>,
    /// Initial configurations, shared by every fidelity (paired design): one axis of the matrix.
    /// Required unless the spec only trains (see `agents`).
    #[serde(default)]
    #[schemars(length(min = 1))]
    pub initial_configurations: Vec<InitialConfiguration>,
    /// Repetitions of every (fidelity, policy, initial configuration): one axis of the matrix.
    /// Required unless the spec only trains (see `agents`).
    #[serde(default = "one_repetition")]
    #[schemars(range(min = 1, max = 10000))]
    pub repetitions: u32,
    /// Root seed: every random stream of every run derives from it. Required unless the spec
    /// only trains (see `agents`).
    #[serde(default)]
    pub seed: u64,
    /// Fidelity levels by name, each a stack of layers: one axis of the matrix. Required
    /// unless the spec only trains (see `agents`).
    #[serde(default)]
    #[schemars(length(min = 1))]
    pub fidelities: IndexMap<String, Fidelity>,
    /// How a policy becomes a reference trajectory; needed by fidelities with
    /// `control: trajectory` and by lab fidelities.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub planner: Option<Planner>,
    /// What happens when two agents collide. Default: `continue`.
    #[serde(default)]
    pub on_collision: OnCollision,
    /// The metrics and their parameters. Default: `stdlib:at25`, the paper's four metrics.
    #[schemars(with = "PresetOr<MetricsSpec>")]
    pub metrics: MetricsSpec,
    /// How results are grouped, summarised and compared.
    #[serde(default)]
    pub report: ReportSpec,
    /// How `cpmx train` trains the policies this spec evaluates (one policy per seed);
    /// `cpmx run` ignores it. A policy names what was trained with `mlp: {trained: {seed: N}}`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub training: Option<TrainingSpec>,
}

fn one_repetition() -> u32 {
    1
}

/// The road network of an experiment.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(untagged)]
pub enum MapSpec {
    /// A built-in map written by cpmx, e.g. `stdlib:intersection`.
    Builtin(#[schemars(regex(pattern = r"^stdlib:[a-z0-9][a-z0-9-]*$"))] String),
    /// A map file.
    File(MapFile),
    /// One of SigmaRL's scenarios, e.g. `{sigmarl: intersection_2}`.
    Sigmarl(SigmarlMap),
}

/// Where SigmaRL's scenario table is looked for on the data path when the spec names none
/// (`sigmarl-published/maps/scenarios.json` of the reference data).
pub const SIGMARL_SCENARIO_TABLE: &str = "sigmarl-published/maps/scenarios.json";

/// One of SigmaRL's scenarios (its JOSM centre-line map, scale, lane width and reference paths),
/// read as SigmaRL reads it; `ref_path` numbers are the scenario's (positions in its table).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SigmarlMap {
    /// The scenario's name in SigmaRL's table, e.g. `intersection_2`, `roundabout_1`,
    /// `interchange_3`, `on_ramp_1` (`cpmx validate` lists them when the name is unknown).
    #[schemars(length(min = 1))]
    pub sigmarl: String,
    /// Lane width [m]: the boundaries lie half of it either side of each centre line. Default:
    /// the table's (what SigmaRL's parser uses when given none; its environment of later
    /// versions passes its own `lane_width` parameter instead).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub lane_width_m: Option<f64>,
    /// SigmaRL's scenario table (`scenarios.json`: its `constants.SCENARIOS`), relative to the
    /// spec's folder or found on the data path; the map files lie beside it. Default:
    /// `sigmarl-published/maps/scenarios.json`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(length(min = 1))]
    pub table: Option<String>,
    /// SHA-256 of the scenario table's bytes (64 hex digits): only a table with this content is
    /// taken. `cpmx run` records it in the run folder's `spec.resolved.yaml`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(regex(pattern = r"^[0-9a-f]{64}$"))]
    pub sha256: Option<String>,
}

impl SigmarlMap {
    /// The scenario table's path as the spec gives it (or the default).
    pub fn table_file(&self) -> &str {
        self.table.as_deref().unwrap_or(SIGMARL_SCENARIO_TABLE)
    }
}

/// A map read from a file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MapFile {
    /// Path of the map file, relative to the spec's folder or found on the data path
    /// (`--data DIR`, `CPMX_DATA`).
    #[schemars(length(min = 1))]
    pub file: String,
    /// SHA-256 of the file's bytes (64 hex digits). When given, only a file with this content
    /// is taken: the data path is searched for one. `cpmx run` records it in the run
    /// folder's `spec.resolved.yaml`, so that a folder finds its map wherever it moves.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(regex(pattern = r"^[0-9a-f]{64}$"))]
    pub sha256: Option<String>,
    /// File format; detected from the content when omitted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub format: Option<MapFormat>,
    /// Restrict the map to a named part that the map defines (e.g. `intersection`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub region: Option<String>,
    /// Reference paths defined by the spec, in addition to the map's own numbering.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub ref_paths: Vec<RefPathDefinition>,
    /// The SigmaRL release whose reference paths the map's paths follow (CommonRoad maps):
    /// `1.5.0` (the default) blends the road boundaries where the lanes beside a path change,
    /// `1.2.0` (its ITSC 2024 and ICRA 2025 checkpoints' paths) joins them as they are. The
    /// boundaries observed and scored follow it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tag: Option<super::SigmarlTag>,
}

/// Map file formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum MapFormat {
    /// CommonRoad XML (the CPM Lab map).
    Commonroad,
    /// lanelet2 OSM XML (as made with JOSM).
    Lanelet2,
}

/// A reference path defined by a list of consecutive lanelets.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RefPathDefinition {
    /// The id agents use to name this path (64-bit); replaces a map path of the same id.
    pub id: u64,
    /// Lanelet ids in driving order, as the map file writes them (64-bit, negative ones too;
    /// the reverse of a two-way lanelet2 lanelet N is -N-1); each must be a successor of
    /// the one before. `cpmx validate` on a spec with only `cpmx`, `name` and `map` lists them.
    #[schemars(length(min = 1))]
    pub lanelets: Vec<i64>,
}

/// Vehicle geometry and limits (the µCar: 0.22 m × 0.107 m, wheelbase 0.15 m).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct VehicleSpec {
    /// Body length [m].
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub length: f64,
    /// Body width [m].
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub width: f64,
    /// Distance between the axles [m].
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub wheelbase: f64,
    /// Distance from the centre of gravity to the rear axle [m]; at most the wheelbase.
    #[schemars(range(min = 0))]
    pub rear_axle: f64,
    /// Steering limit [deg], symmetric.
    #[schemars(extend("exclusiveMinimum" = 0, "exclusiveMaximum" = 90))]
    pub max_steering_deg: f64,
    /// Steering-rate limit [deg/s], symmetric.
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub max_steering_rate_deg_s: f64,
    /// Acceleration range [m/s²]: `[min, max]`, min < 0 < max.
    pub accel: [f64; 2],
    /// Speed command limit [m/s], symmetric.
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub max_speed: f64,
}

/// Policy step and evaluation horizon.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Timing {
    /// Policy step [s] (SigmaRL: 0.1).
    #[schemars(extend("exclusiveMinimum" = 0, "maximum" = 10))]
    pub dt: f64,
    /// Number of policy steps per run (the paper: 180, i.e. 18 s).
    #[schemars(range(min = 1, max = 1000000))]
    pub steps: u32,
    /// How the metrics treat an agent that reaches the end of an open reference path (the
    /// simulation drives it on as its policy decides: a policy that stops there waits, one
    /// that does not drives past the end). `stop` (default): the metrics measure it to the
    /// run's end, the time it waits too (AS drops).
    /// `end-agent`: its samples after it reached the end (its centre within 0.2 m of the last
    /// centre-line point) are left out of CD, AS, CRA-L and the distance, so that speeds of
    /// policies that finish early stay comparable, and out of CRA-A: a collision counts while
    /// both agents are measured (the car has left the measurement; in the simulation it
    /// still drives on, where others may hit it uncounted).
    #[serde(default, skip_serializing_if = "StopAtPathEnd::is_default")]
    pub stop_at_path_end: StopAtPathEnd,
}

/// The rule of `timing.stop_at_path_end`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum StopAtPathEnd {
    /// The agent is measured to the run's end; time it waits at the end counts.
    #[default]
    Stop,
    /// The agent's run ends there: later samples are not measured.
    EndAgent,
}

impl StopAtPathEnd {
    fn is_default(&self) -> bool {
        *self == StopAtPathEnd::Stop
    }
}

/// How a policy becomes a timed reference trajectory (`control: trajectory`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Planner {
    /// Hc: policy steps rolled out on predicted states.
    #[schemars(range(min = 1, max = 1000))]
    pub control_horizon: u32,
    /// Hp: length of the trajectory in policy steps; Hc ≤ Hp.
    #[schemars(range(min = 1, max = 1000))]
    pub prediction_horizon: u32,
    /// What the trajectory does between Hc and Hp.
    #[serde(default)]
    pub after_control_horizon: AfterControlHorizon,
}

/// The rule between Hc and Hp.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct AfterControlHorizon {
    /// Speed after Hc.
    #[serde(default)]
    pub speed: SpeedAfterHc,
    /// Steering after Hc.
    #[serde(default)]
    pub steering: SteeringAfterHc,
}

/// Speed after the control horizon.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum SpeedAfterHc {
    /// Keep the speed reached at Hc (the paper).
    #[default]
    Hold,
}

/// Steering after the control horizon.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum SteeringAfterHc {
    /// Bring the steering linearly to zero by Hp (the paper).
    #[default]
    LinearToZero,
    /// Keep the steering reached at Hc.
    Hold,
}

/// What happens when two agents collide.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum OnCollision {
    /// Keep driving through the overlap (SigmaRL's evaluation rollouts).
    #[default]
    Continue,
    /// Put the colliding agents back to their initial state.
    ResetAgent,
    /// Stop the run at the first collision.
    EndRun,
    /// SigmaRL's testing mode (its evaluation scripts): a car whose outline crosses another
    /// car's, its road's boundaries or its path's entry or exit line leaves, and a new agent
    /// is placed instead, on a reference path of the map drawn uniformly, at a centre-line
    /// point drawn uniformly in `[3, n - 3)`, at least 1.2 of the car's diagonal from every
    /// other car, heading along the lane, at a speed drawn in `[0, max speed)`. The metrics
    /// measure each agent over the samples it is present in. Simulated `control: direct`
    /// fidelities only.
    ReplaceAgent,
}
