//! The metrics of the benchmark and how results are reported.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// The paper's four metrics with their parameters explicit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MetricsSpec {
    /// Recordings are resampled to this period [s] before any metric; hysteresis counts
    /// samples of this period.
    #[schemars(extend("exclusiveMinimum" = 0, "maximum" = 10))]
    pub sample_period_s: f64,
    /// Collision rate agent-agent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cra_a: Option<CraASpec>,
    /// Collision rate agent-lane (lane violations).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cra_l: Option<CraLSpec>,
    /// Centre-line deviation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cd: Option<CdSpec>,
    /// Average speed.
    #[serde(default, skip_serializing_if = "Option::is_none", rename = "as")]
    pub average_speed: Option<AsSpec>,
    /// SigmaRL's per-sample collision rates of its ITSC 2024 evaluation, beside the four: CR-AA,
    /// the share of samples [%] in which two cars' outlines cross, and CR-AL, the share in
    /// which a car's outline crosses its road's boundaries (SigmaRL's `interX` tests, on the
    /// metrics' footprint). `{}`: no parameters.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub per_sample_collisions: Option<PerSampleCollisionsSpec>,
    /// The vehicle whose footprint (length and width) the metrics score: collisions between
    /// agents, lane violations. Default: the spec's `vehicle`. A run can observe and drive as
    /// its actor was trained (`vehicle: stdlib:sigmarl-2025`) and be scored with the µCar of the
    /// paper's Table 1 (`footprint: stdlib:mu-car`); the report's header names both.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(with = "Option<super::PresetOr<super::VehicleSpec>>")]
    pub footprint: Option<super::VehicleSpec>,
}

/// `per_sample_collisions: {}`: SigmaRL's per-sample collision rates (no parameters).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PerSampleCollisionsSpec {}

/// CRA-A: agent-agent collision events per distance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CraASpec {
    /// Consecutive samples needed to enter and to leave a collision.
    pub hysteresis: Hysteresis,
    /// How the signed distance between footprints is computed.
    pub geometry: CollisionGeometry,
    /// Whether an event counts once per agent involved or once per pair.
    pub count: CollisionCount,
    /// Events are normalised per this travelled distance [m] (the paper: 100).
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub per_distance_m: f64,
}

/// Hysteresis of the collision detector, in samples.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Hysteresis {
    /// Consecutive overlapping samples that start an event (the script: 3).
    #[schemars(range(min = 1, max = 1000))]
    pub enter: u32,
    /// Consecutive free samples that end it (the script: 5).
    #[schemars(range(min = 1, max = 1000))]
    pub exit: u32,
}

/// Signed distance between two footprints.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum CollisionGeometry {
    /// The minimum translation vector: negative penetration depth on any overlap.
    Mtv,
    /// The paper's evaluation script: negative only when a corner lies inside the other box.
    SigmarlMtv,
}

/// How collision events are counted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum CollisionCount {
    /// Each event counts for every agent involved (the paper's script).
    PerAgent,
    /// Each event counts once.
    PerPair,
}

/// CRA-L: distance driven outside the own lane, per distance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CraLSpec {
    /// Tolerance as a fraction of the vehicle width before a footprint counts as outside
    /// (the paper: 0.10; the script: 0). In [0, 1).
    #[schemars(range(min = 0.0), extend("exclusiveMaximum" = 1))]
    pub slack: f64,
    /// Normalised per this travelled distance [m] (the paper: 100).
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub per_distance_m: f64,
    /// The boundaries a footprint must stay within: `own-lane` (default, the paper) or `road`
    /// (the reference path's shared boundaries: SigmaRL's lanelet collisions, and what its
    /// safety filter keeps the car within).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub boundaries: Option<CraLBoundaries>,
}

/// The boundaries CRA-L measures against.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum CraLBoundaries {
    /// The reference path's own lane.
    OwnLane,
    /// The road: the reference path's shared boundaries.
    Road,
}

/// CD: mean distance of the vehicle centre to its reference centre line. No parameters.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CdSpec {}

/// AS: mean speed. No parameters.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct AsSpec {}

/// How per-run metrics are grouped, summarised and compared.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ReportSpec {
    /// Rows of the summary table: one per value of these axes. Default: one row per fidelity
    /// and policy. Leaving `policy` out pools the policies into one row (as the paper pools its
    /// three training seeds); the summary then names the policies each row pools.
    #[serde(default = "default_group_by")]
    #[schemars(length(min = 1))]
    pub group_by: Vec<GroupKey>,
    /// Statistics in the summary.
    #[serde(default = "default_statistics")]
    pub statistics: Vec<Statistic>,
    /// Bootstrap confidence intervals.
    #[serde(default)]
    pub bootstrap: Bootstrap,
    /// Paired comparison of every fidelity with a reference fidelity.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub compare: Option<Compare>,
}

impl Default for ReportSpec {
    fn default() -> Self {
        Self {
            group_by: default_group_by(),
            statistics: default_statistics(),
            bootstrap: Bootstrap::default(),
            compare: None,
        }
    }
}

fn default_group_by() -> Vec<GroupKey> {
    vec![GroupKey::Fidelity, GroupKey::Policy]
}

fn default_statistics() -> Vec<Statistic> {
    vec![Statistic::Mean, Statistic::Std, Statistic::Iqm, Statistic::Ci95]
}

/// A matrix axis to group by.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum GroupKey {
    /// The fidelity level.
    Fidelity,
    /// The policy.
    Policy,
    /// The initial configuration.
    InitialConfiguration,
}

/// A summary statistic.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Statistic {
    /// Arithmetic mean.
    Mean,
    /// Sample standard deviation (n − 1).
    Std,
    /// Interquartile mean: drop floor(n/4) at each end.
    Iqm,
    /// The median (the mean of the middle two for an even count).
    Median,
    /// The mean without the largest and the smallest value, as SigmaRL's evaluation drops its
    /// best and its worst environment (undefined for fewer than three runs).
    TrimmedMean,
    /// Normal 95 % confidence interval of the mean.
    Ci95,
    /// Stratified bootstrap 95 % confidence interval of the mean and the IQM.
    Bootstrap,
}

/// Bootstrap settings.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Bootstrap {
    /// Number of resamples.
    #[schemars(range(min = 100, max = 1000000))]
    pub resamples: u32,
    /// Seed of the bootstrap stream.
    pub seed: u64,
}

impl Default for Bootstrap {
    fn default() -> Self {
        Self {
            resamples: 10_000,
            seed: 7,
        }
    }
}

/// Paired comparison between fidelities.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Compare {
    /// The fidelity every other fidelity is compared with, or the policy every other policy is
    /// compared with (over runs of the same fidelity, initial configuration and repetition;
    /// per fidelity when `group_by` holds `fidelity`). A fidelity swept on its own
    /// layers has no runs under its bare name: name one of its points (`sim@latency_ms=0`),
    /// whom every other point and fidelity is then compared with, or sweep the others alike
    /// (each point is then compared with the reference at the same point).
    pub reference: String,
    /// The test. Only `paired` exists: differences over run keys.
    pub test: PairedTest,
}

/// Comparison designs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum PairedTest {
    /// Paired differences over runs that differ only in fidelity.
    Paired,
}
