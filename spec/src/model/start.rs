//! Initial configurations: explicit starts, sampled starts, or measured starts of recorded runs.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

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
}

/// Starts given agent by agent.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ExplicitConfiguration {
    /// Name in run keys and tables. Lower-case letters, digits and `-`.
    #[schemars(regex(pattern = r"^[a-z0-9][a-z0-9-]*$"))]
    pub name: String,
    /// One entry per agent; as many as `agents`.
    #[schemars(length(min = 1))]
    pub agents: Vec<AgentStart>,
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
