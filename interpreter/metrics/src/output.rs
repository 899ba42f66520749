//! The per-run result (it becomes `metrics.json`) and its `per_run.csv` columns.
//!
//! This module owns the serialised shape of a run's metrics and the one float format of
//! the tables; it computes nothing.

use serde::{Deserialize, Serialize};

use crate::config::MetricsConfig;

/// Every metric of one run and the raw counts behind it.
///
/// Rates are NaN (serialised as `null`) when the agents travelled no distance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunMetrics {
    /// Samples used (after resampling and `max_steps`).
    pub num_samples: usize,
    /// Agents in the recording.
    pub num_agents: usize,
    /// CRA-A: `a2a_events` per `cra_a.per_distance_m` of total travelled distance.
    #[serde(with = "nan_as_null")]
    pub cra_a: f64,
    /// CRA-L: `lane_violation_m` per `cra_l.per_distance_m` of total travelled distance
    /// (the script's `LaneViolation_per_unit`).
    #[serde(with = "nan_as_null")]
    pub cra_l: f64,
    /// CD: mean over agents of the mean distance of the centre to its centre line [m].
    #[serde(with = "nan_as_null")]
    pub cd_m: f64,
    /// AS: mean over samples and agents of the speed `|v|` [m/s].
    #[serde(with = "nan_as_null")]
    pub as_mps: f64,
    /// CR-AA: the share of samples in which two agents' outlines cross [%] (NaN unless
    /// `per_sample_collisions`).
    #[serde(with = "nan_as_null", default = "nan")]
    pub cr_aa_pct: f64,
    /// CR-AL: the share of samples in which an agent's outline crosses its road's boundaries
    /// [%] (NaN unless `per_sample_collisions`).
    #[serde(with = "nan_as_null", default = "nan")]
    pub cr_al_pct: f64,
    /// Collision events as counted by `cra_a.count` (per agent: 2 per pair event).
    pub a2a_events: usize,
    /// Total distance travelled by all agents [m].
    pub distance_m: f64,
    /// Distance travelled into violating samples, summed over agents [m].
    pub lane_violation_m: f64,
    /// The parameters these numbers were computed with.
    pub config: MetricsConfig,
    /// Every pair event (i < j), in pair then time order.
    pub pair_events: Vec<PairEvent>,
    /// Per-agent numbers and sample lists.
    pub agents: Vec<AgentMetrics>,
}

/// One agent's share of a run's metrics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AgentMetrics {
    /// Its reference path id.
    pub ref_path: usize,
    /// Distance it travelled [m].
    pub distance_m: f64,
    /// Distance it travelled into violating samples [m].
    pub lane_violation_m: f64,
    /// Mean distance of its centre to its centre line [m] (NaN, `null` in JSON, for an agent
    /// present in no measured sample: one that came and went between two samples of the
    /// metrics' period).
    #[serde(with = "nan_as_null")]
    pub cd_m: f64,
    /// Its mean speed [m/s] (NaN when it is in no measured sample).
    #[serde(with = "nan_as_null")]
    pub as_mps: f64,
    /// Samples at which collision events involving it start (one per pair event).
    pub event_samples: Vec<usize>,
    /// Samples at which it violates its lane.
    pub violation_samples: Vec<usize>,
}

/// A collision event between two agents.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct PairEvent {
    /// The two agents, lower index first.
    pub agents: [usize; 2],
    /// The sample at which the event is stamped (the `enter`-th overlapping one).
    pub sample: usize,
}

fn nan() -> f64 {
    f64::NAN
}

impl RunMetrics {
    /// The columns of the per-sample collision rates, appended to [`RunMetrics::CSV_COLUMNS`]
    /// when the runs measure them.
    pub const PER_SAMPLE_CSV_COLUMNS: [&'static str; 2] = ["cr_aa_pct", "cr_al_pct"];

    /// This run's values for [`RunMetrics::PER_SAMPLE_CSV_COLUMNS`].
    pub fn per_sample_csv_row(&self) -> [String; 2] {
        [format_float(self.cr_aa_pct), format_float(self.cr_al_pct)]
    }

    /// The metric columns of `per_run.csv`, in their fixed order (the report prepends the
    /// run's key columns).
    pub const CSV_COLUMNS: [&'static str; 9] = [
        "cra_a",
        "cra_l",
        "cd_m",
        "as_mps",
        "a2a_events",
        "distance_m",
        "lane_violation_m",
        "num_samples",
        "num_agents",
    ];

    /// This run's values for [`RunMetrics::CSV_COLUMNS`], floats by [`format_float`].
    pub fn csv_row(&self) -> Vec<String> {
        vec![
            format_float(self.cra_a),
            format_float(self.cra_l),
            format_float(self.cd_m),
            format_float(self.as_mps),
            self.a2a_events.to_string(),
            format_float(self.distance_m),
            format_float(self.lane_violation_m),
            self.num_samples.to_string(),
            self.num_agents.to_string(),
        ]
    }
}

/// The one float format of cpmx's tables: 10 significant digits in exponent notation
/// (Rust's `{:.9e}`, e.g. `1.422830314e1`, `-2.5e-3` → `-2.500000000e-3`), which rounds
/// the exact binary value and is the same on every platform. Last-bit differences of libm
/// functions between machines therefore do not change the table. NaN (an undefined rate)
/// is the empty string; infinities are `inf` / `-inf`.
pub fn format_float(value: f64) -> String {
    if value.is_nan() {
        String::new()
    } else if value.is_infinite() {
        if value > 0.0 { "inf".into() } else { "-inf".into() }
    } else {
        format!("{value:.9e}")
    }
}

/// Serialises NaN as `null` and reads `null` back as NaN.
mod nan_as_null {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(value: &f64, serializer: S) -> Result<S::Ok, S::Error> {
        if value.is_nan() {
            serializer.serialize_none()
        } else {
            serializer.serialize_f64(*value)
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(deserializer: D) -> Result<f64, D::Error> {
        Ok(Option::<f64>::deserialize(deserializer)?.unwrap_or(f64::NAN))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn metrics(cra_a: f64) -> RunMetrics {
        RunMetrics {
            num_samples: 3,
            num_agents: 1,
            cra_a,
            cra_l: 94.17839656651672,
            cd_m: 7.285012445142532e-9,
            as_mps: 0.0,
            cr_aa_pct: f64::NAN,
            cr_al_pct: f64::NAN,
            a2a_events: 2,
            distance_m: 14.056489944458008,
            lane_violation_m: 0.0,
            config: MetricsConfig::default(),
            pair_events: vec![PairEvent {
                agents: [0, 1],
                sample: 2,
            }],
            agents: vec![],
        }
    }

    #[test]
    fn nan_rates_round_trip_through_null() {
        let m = metrics(f64::NAN);
        let json = serde_json::to_string(&m).unwrap();
        assert!(json.contains("\"cra_a\":null"), "{json}");
        let back: RunMetrics = serde_json::from_str(&json).unwrap();
        assert!(back.cra_a.is_nan());
        assert_eq!(back.cra_l, m.cra_l);
    }

    #[test]
    fn csv_row_has_the_documented_format() {
        let row = metrics(f64::NAN).csv_row();
        assert_eq!(row.len(), RunMetrics::CSV_COLUMNS.len());
        assert_eq!(
            row,
            [
                "",
                "9.417839657e1",
                "7.285012445e-9",
                "0.000000000e0",
                "2",
                "1.405648994e1",
                "0.000000000e0",
                "3",
                "1"
            ]
        );
        assert_eq!(format_float(-0.0025), "-2.500000000e-3");
    }
}
