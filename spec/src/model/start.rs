//! Initial configurations: explicit starts, sampled starts, measured starts of recorded runs, or
//! measured start poses listed per run in a CSV file (the lab's, as the paper published them).

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::MapSpec;

/// One initial configuration entry. An entry of `sample` or `from_runs` expands into several
/// named configurations.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(untagged)]
pub enum InitialConfiguration {
    /// Starts given agent by agent.
    Explicit(ExplicitConfiguration),
    /// Starts sampled on the map, named `sample1`, `sample2`, …
    Sampled(SampledStarts),
    /// Measured initial poses of recorded runs.
    FromRuns(FromRuns),
    /// Measured start poses per run from a CSV file.
    FromPoses(FromPoses),
}

impl InitialConfiguration {
    /// The entry's own map, when it names one (else the runs drive on the spec's `map`).
    pub fn own_map(&self) -> Option<&MapSpec> {
        match self {
            InitialConfiguration::Explicit(e) => e.map.as_ref(),
            InitialConfiguration::Sampled(s) => s.map.as_ref(),
            InitialConfiguration::FromRuns(_) | InitialConfiguration::FromPoses(_) => None,
        }
    }

    /// How many agents the entry's configurations place, given the spec's `agents`.
    pub fn agents(&self, spec_agents: u32) -> usize {
        match self {
            InitialConfiguration::Explicit(e) => e.agents.len(),
            InitialConfiguration::Sampled(s) => s.sample.agents.unwrap_or(spec_agents) as usize,
            InitialConfiguration::FromRuns(_) | InitialConfiguration::FromPoses(_) => spec_agents as usize,
        }
    }
}

/// The default of `off_road_tolerance_m`: how far a start's footprint may reach beyond the
/// road and still be run (with a warning).
pub const DEFAULT_OFF_ROAD_TOLERANCE_M: f64 = 0.02;

fn default_off_road_tolerance_m() -> f64 {
    DEFAULT_OFF_ROAD_TOLERANCE_M
}

fn is_default_off_road_tolerance(value: &f64) -> bool {
    *value == DEFAULT_OFF_ROAD_TOLERANCE_M
}

/// Starts given agent by agent.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ExplicitConfiguration {
    /// Name in run keys and tables. Lower-case letters, digits and `-`.
    #[schemars(regex(pattern = r"^[a-z0-9][a-z0-9-]*$"))]
    pub name: String,
    /// The map this configuration's runs drive on, in any form of the spec's `map` (e.g.
    /// `{sigmarl: roundabout_1}`), when it is not the spec's `map`: one experiment evaluates
    /// on several maps (training stays on the spec's `map`). Its `ref_path` numbers are this
    /// map's. A lab fidelity drives on the spec's `map` only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub map: Option<MapSpec>,
    /// One entry per agent; as many as `agents`, unless the configuration has its own `map`
    /// (then as many as it places).
    #[schemars(length(min = 1))]
    pub agents: Vec<AgentStart>,
    /// How far [m] a start's footprint may reach beyond its path's road and still be run,
    /// with a warning that gives the distance; farther is an error. Default: 0.02 (measured
    /// poses of the lab's indoor positioning lie up to about a centimetre beside the truth).
    #[serde(
        default = "default_off_road_tolerance_m",
        skip_serializing_if = "is_default_off_road_tolerance"
    )]
    #[schemars(range(min = 0.0, max = 1.0))]
    pub off_road_tolerance_m: f64,
}

/// Where one agent starts. Either `arc_length` on its reference path, or a `pose`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct AgentStart {
    /// The reference path the agent follows (the map's numbering: SigmaRL's 0-based index
    /// for the CPM Lab map).
    pub ref_path: u64,
    /// Distance along the path's centre line [m]; the agent heads along the path.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.0))]
    pub arc_length: Option<f64>,
    /// Initial speed [m/s]. Default: 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = -5.0, max = 5.0))]
    pub speed: Option<f64>,
    /// An explicit pose instead of `arc_length`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose: Option<Pose>,
}

/// A pose in the map frame. Give `yaw_deg` or `yaw`, not both.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Pose {
    /// x [m].
    pub x: f64,
    /// y [m].
    pub y: f64,
    /// Heading [deg].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub yaw_deg: Option<f64>,
    /// Heading [rad].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub yaw: Option<f64>,
}

impl Pose {
    /// The heading in radians, whichever way it was given (0 when neither).
    pub fn yaw_rad(&self) -> f64 {
        self.yaw.or(self.yaw_deg.map(f64::to_radians)).unwrap_or(0.0)
    }
}

/// `sample: {...}`: random starts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SampledStarts {
    /// The configurations' name: `NAME` for `count: 1`, `NAME1`, `NAME2`, … for more. Default:
    /// `sample1`, `sample2`, … numbered across the unnamed `sample` entries.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(regex(pattern = r"^[a-z0-9][a-z0-9-]*$"))]
    pub name: Option<String>,
    /// The map the draws are made on and the runs drive on, when it is not the spec's `map`
    /// (any form of `map`, e.g. `{sigmarl: roundabout_1}`). A lab fidelity drives on the
    /// spec's `map` only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub map: Option<MapSpec>,
    /// How to sample.
    pub sample: SampleSpec,
}

/// Parameters of sampled starts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SampleSpec {
    /// Number of configurations to draw.
    #[schemars(range(min = 1, max = 10000))]
    pub count: u32,
    /// Seed of the draw (independent of the spec's `seed`, so that configurations stay fixed
    /// when the run seed changes).
    pub seed: u64,
    /// Smallest centre-to-centre distance between two agents [m].
    #[serde(default = "default_min_gap")]
    #[schemars(range(min = 0.0))]
    pub min_gap: f64,
    /// How many agents a draw places. Default: the spec's `agents`. Another number needs the
    /// entry's own `map` (the spec's `agents` is the count on the spec's map).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 1, max = 64))]
    pub agents: Option<u32>,
    /// `per-configuration` (default): every run of a configuration starts from its one draw.
    /// `per-repetition`: repetition r starts from its own draw, the same for every policy and
    /// fidelity (paired), so that `repetitions` are independent starts of one named
    /// configuration (SigmaRL's evaluation: each of its environments its own random start).
    #[serde(default, skip_serializing_if = "SampleDraw::is_per_configuration")]
    pub draw: SampleDraw,
    /// `on-road` (default): a uniform arc length, a car length clear of the path's ends, the
    /// footprint on the road, at rest. `sigmarl`: as SigmaRL's testing mode places its cars
    /// (the rule of `on_collision: replace-agent`, with this entry's `min_gap`): a centre-line
    /// point drawn uniformly in `[3, n - 3)`, heading along the lane, a speed drawn in
    /// `[0, max speed)`.
    #[serde(default, skip_serializing_if = "SamplePlacement::is_on_road")]
    pub placement: SamplePlacement,
}

/// How a `sample` entry places each car.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum SamplePlacement {
    /// A uniform arc length on a uniform path, on the road, at rest.
    #[default]
    OnRoad,
    /// SigmaRL's testing-mode placement: centre-line point index in `[3, n - 3)`, a uniform
    /// speed.
    Sigmarl,
}

impl SamplePlacement {
    fn is_on_road(&self) -> bool {
        *self == SamplePlacement::OnRoad
    }
}

/// What one draw of a `sample` entry starts: all runs of a configuration, or one repetition.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum SampleDraw {
    /// One draw per configuration, shared by its runs.
    #[default]
    PerConfiguration,
    /// One draw per repetition, shared by the policies and fidelities.
    PerRepetition,
}

impl SampleDraw {
    fn is_per_configuration(&self) -> bool {
        *self == SampleDraw::PerConfiguration
    }
}

fn default_min_gap() -> f64 {
    0.5
}

/// `from_runs: {...}`: measured starts of recorded runs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FromRuns {
    /// Which runs.
    pub from_runs: FromRunsSpec,
}

/// Which recorded runs provide starts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FromRunsSpec {
    /// A run folder written by `cpmx run`, relative to the spec's folder.
    #[schemars(length(min = 1))]
    pub dir: String,
    /// The fidelity of the runs to take (e.g. `lab`).
    pub fidelity: String,
}

/// `from_poses: {...}`: start poses measured per run, from a CSV file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FromPoses {
    /// Which file, and how its rows name runs.
    pub from_poses: FromPosesSpec,
}

/// A CSV file of measured start poses, a row per run: the row's policy label, initial
/// configuration and repetition, then each vehicle's pose and reference path. Its header names
/// the columns: either `policy`, `initial_configuration`, `repetition`, or (as the paper's
/// `poses.csv`) a `file` column whose value ends in `<label>/<configuration>-<repetition>`
/// plus an extension (`results/physical_lab/seed1/init2-3.td`: label `seed1`, configuration
/// `init2`, repetition 3); `v<k>_x`, `v<k>_y` [m] and `v<k>_theta` (or `v<k>_yaw`) [rad] for
/// vehicles `k = 1..agents` in the map's frame; `ref_path_ids`, the vehicles' reference paths
/// separated by `|`. Each configuration the file names becomes an initial configuration of the
/// matrix, and each run of it starts from its own row: the same in every fidelity (paired).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FromPosesSpec {
    /// The CSV file, relative to the spec's folder or found on the data path (e.g.
    /// `paper-at25/poses.csv` of SigmaRL's reference data).
    #[schemars(length(min = 1))]
    pub file: String,
    /// SHA-256 of the file's bytes (64 hex digits). When given, only a file with this content
    /// is taken: the data path is searched for one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(regex(pattern = r"^[0-9a-f]{64}$"))]
    pub sha256: Option<String>,
    /// The label of the file's rows each policy starts from, by policy, e.g. `{paper-seed1:
    /// seed1, cpmx-seed1: seed1}` (several policies may start from one label's rows). Default:
    /// a policy's own name. Every policy of the spec needs rows for every configuration and
    /// repetition; rows of other labels are left out.
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub policies: std::collections::BTreeMap<String, String>,
    /// How far [m] a start's footprint may reach beyond its path's road and still be run,
    /// with a warning that gives the distance; farther is an error. Default: 0.02.
    #[serde(
        default = "default_off_road_tolerance_m",
        skip_serializing_if = "is_default_off_road_tolerance"
    )]
    #[schemars(range(min = 0.0, max = 1.0))]
    pub off_road_tolerance_m: f64,
}
