//! The metric parameters: a plain mirror of the spec's `metrics:` section, plus the two
//! options SigmaRL's evaluation script has (`max_steps`, `rotate180`).
//!
//! This module owns the types, their defaults (the paper's) and their validation. It does
//! not read a spec: the engine translates the spec's types into these.

use cpmx_world::Point;
use serde::{Deserialize, Serialize};

use crate::MetricsError;

/// All parameters of the per-run metrics.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MetricsConfig {
    /// Recordings are resampled to this period before any metric [s]; hysteresis counts
    /// samples of this period.
    pub sample_period_s: f64,
    /// Agent-agent collision rate.
    pub cra_a: CraAConfig,
    /// Lane-violation rate.
    pub cra_l: CraLConfig,
    /// Keep only the first `max_steps` samples (after resampling), as the script's `max_steps`.
    pub max_steps: Option<usize>,
    /// Map positions, yaws and lanes by a half turn about this centre before any metric, as
    /// the script's `rotate180` (for lab data recorded in a rotated frame).
    pub rotate180: Option<Rotate180>,
    /// Leave out each agent's samples after it reached the end of an open reference path
    /// (its centre within [`END_REACHED_M`] of the last centre-line point, along the path)
    /// from CD, AS, CRA-L and the distance travelled (the spec's
    /// `timing.stop_at_path_end: end-agent`), so that agents that finish early and wait are
    /// not slower for it, and from CRA-A: a pair's collision counts while both agents are
    /// measured (an agent that left the measurement is, in SigmaRL's evaluations, re-placed
    /// elsewhere, not parked where others pile up on it).
    #[serde(default)]
    pub end_at_path_end: bool,
    /// Also measure SigmaRL's per-sample collision rates (its ITSC 2024 evaluation): the share
    /// of samples [%] in which two agents' outlines cross (CR-AA) and in which an agent's
    /// outline crosses its road's boundaries (CR-AL), with SigmaRL's `interX` tests.
    #[serde(default)]
    pub per_sample_collisions: bool,
}

/// How close to the end of an open reference path (along it) an agent has reached it [m]:
/// a little more than `lane-follow` leaves when it stops there (0.15 m).
pub const END_REACHED_M: f64 = 0.2;

/// The half-turn of the script's `rotate180`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Rotate180 {
    /// Centre of the rotation [m]: the centre of the bounding box of all lanelet boundaries
    /// of the map (SigmaRL's `map_center_from_lanelets`).
    pub centre_m: Point,
}

/// Parameters of CRA-A (agent-agent collisions per distance).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CraAConfig {
    /// Consecutive-sample hysteresis of a collision event.
    pub hysteresis: Hysteresis,
    /// Which signed distance between two footprints decides "overlapping".
    pub geometry: CollisionGeometry,
    /// How a pair event is counted.
    pub count: EventCount,
    /// Events are reported per this travelled distance [m] (of all agents together).
    pub per_distance_m: f64,
}

/// Enter/exit hysteresis, in samples of `sample_period_s`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Hysteresis {
    /// An event is stamped at the `enter`-th consecutive overlapping sample (script: `n1 = 3`).
    pub enter: usize,
    /// A collision ends after `exit` consecutive overlap-free samples (script: `n2 = 5`).
    pub exit: usize,
}

/// The signed distance between two footprints (negative = overlapping).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CollisionGeometry {
    /// The spec's `mtv`: the true signed distance. Overlapping rectangles get minus their
    /// minimum-translation-vector length (parry's penetration depth), touching ones 0,
    /// disjoint ones their Euclidean distance. This is what the paper describes.
    Mtv,
    /// SigmaRL's corner-projection rule (`get_distances_between_agents(..., "mtv")`) with
    /// its quirks: an overlap without a corner strictly inside the other rectangle (a
    /// "plus"-shaped crossing) keeps a positive distance. This is what the script computes.
    SigmarlMtv,
}

/// How a collision between two agents is counted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum EventCount {
    /// Each pair event counts once for each of the two agents (2 per collision), as the
    /// script's `raw_a2a_event_count`.
    PerAgent,
    /// Each pair event counts once.
    PerPair,
}

/// Parameters of CRA-L (lane violation per distance).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CraLConfig {
    /// Fraction of the vehicle width by which the footprint may leave its own lane before a
    /// sample counts as a violation. 0 is exactly the script; the paper uses 0.10.
    ///
    /// Applied geometrically by shrinking the footprint by `s = slack · width` on every side
    /// (length and width each reduced by `2 s`, same centre and yaw) before the script's two
    /// tests. A sideways excursion is thus tolerated up to exactly `s`; at the corners the
    /// rule is the erosion of the footprint, i.e. a corner may stick out up to `s` along each
    /// of the car's axes. Must lie in [0, 0.5).
    pub slack: f64,
    /// Violation length is reported per this travelled distance [m].
    pub per_distance_m: f64,
    /// Which boundaries a footprint must stay within: its own lane's (the paper) or the
    /// road's, the reference path's shared boundaries (where a safety filter keeps the car).
    #[serde(default, skip_serializing_if = "LaneBoundaries::is_own_lane")]
    pub boundaries: LaneBoundaries,
}

impl LaneBoundaries {
    /// Whether these are the own lane's (the default, left out of `metrics.json`).
    pub fn is_own_lane(&self) -> bool {
        *self == LaneBoundaries::OwnLane
    }
}

/// The boundaries CRA-L measures against.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LaneBoundaries {
    /// The reference path's own lane (the paper's CRA-L).
    #[default]
    OwnLane,
    /// The road: the reference path's shared boundaries, which neighbouring lanes of the same
    /// direction share (SigmaRL's lanelet collisions, and its safety filter's constraints).
    Road,
}

impl Default for MetricsConfig {
    /// The paper's metric set as the spec writes it (`geometry: mtv`, `slack: 0.10`).
    fn default() -> Self {
        Self {
            sample_period_s: 0.1,
            cra_a: CraAConfig {
                hysteresis: Hysteresis { enter: 3, exit: 5 },
                geometry: CollisionGeometry::Mtv,
                count: EventCount::PerAgent,
                per_distance_m: 100.0,
            },
            cra_l: CraLConfig {
                slack: 0.10,
                per_distance_m: 100.0,
                boundaries: LaneBoundaries::OwnLane,
            },
            max_steps: None,
            rotate180: None,
            end_at_path_end: false,
            per_sample_collisions: false,
        }
    }
}

impl MetricsConfig {
    /// Exactly what SigmaRL's `evaluate_single_run` computes (n1 = 3, n2 = 5, its corner
    /// rule, per-agent counting, no slack), per `per_unit_m`.
    pub fn sigmarl_script(per_unit_m: f64) -> Self {
        Self {
            sample_period_s: 0.1,
            cra_a: CraAConfig {
                hysteresis: Hysteresis { enter: 3, exit: 5 },
                geometry: CollisionGeometry::SigmarlMtv,
                count: EventCount::PerAgent,
                per_distance_m: per_unit_m,
            },
            cra_l: CraLConfig {
                slack: 0.0,
                per_distance_m: per_unit_m,
                boundaries: LaneBoundaries::OwnLane,
            },
            max_steps: None,
            rotate180: None,
            end_at_path_end: false,
            per_sample_collisions: false,
        }
    }

    /// Checks every parameter; the first problem is returned.
    pub fn validate(&self) -> Result<(), MetricsError> {
        let invalid = |what: &'static str, value: f64| MetricsError::InvalidParameter { what, value };
        if !(self.sample_period_s.is_finite() && self.sample_period_s > 0.0) {
            return Err(invalid("sample_period_s", self.sample_period_s));
        }
        if self.cra_a.hysteresis.enter == 0 {
            return Err(invalid("cra_a.hysteresis.enter", 0.0));
        }
        if self.cra_a.hysteresis.exit == 0 {
            return Err(invalid("cra_a.hysteresis.exit", 0.0));
        }
        for (what, value) in [
            ("cra_a.per_distance_m", self.cra_a.per_distance_m),
            ("cra_l.per_distance_m", self.cra_l.per_distance_m),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(invalid(what, value));
            }
        }
        // A slack of half the width or more would shrink the footprint to nothing.
        if !(self.cra_l.slack.is_finite() && (0.0..0.5).contains(&self.cra_l.slack)) {
            return Err(invalid("cra_l.slack", self.cra_l.slack));
        }
        if let Some(r) = self.rotate180
            && !(r.centre_m[0].is_finite() && r.centre_m[1].is_finite())
        {
            return Err(invalid("rotate180.centre_m", r.centre_m[0]));
        }
        Ok(())
    }
}
