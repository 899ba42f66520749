//! The `safety:` layer of a simulated fidelity: a filter between the policy's action and the
//! vehicle that changes the action as little as it can to keep the vehicle safe. Only
//! SigmaRL's CBF-QP exists (`stdlib:sigmarl-cbf`); `cpmx-safety` computes it.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// A safety filter (`stdlib:sigmarl-cbf`: SigmaRL's, ITSC 2025).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SafetyLayer {
    /// SigmaRL's control-barrier-function QP: the vehicle as circles along its axis, kept from
    /// its lane's two boundaries by truncated-Taylor CBFs on SigmaRL's pseudo-distance; the
    /// QP changes the nominal acceleration and steering rate (the action over one `dt`) as
    /// little as its weights allow; where it has no solution the action goes through.
    pub cbf: CbfFilter,
}

/// The CBF filter's parameters (SigmaRL's defaults in `stdlib:sigmarl-cbf`, tag 1.4.0).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CbfFilter {
    /// Circles that approximate the vehicle, evenly along its length (SigmaRL: 3).
    #[schemars(range(min = 1, max = 20))]
    pub circles: u32,
    /// The distance each circle's centre keeps from a boundary [m] (SigmaRL: 0.05, fixed, not
    /// the radius that covers the vehicle).
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub circle_radius_m: f64,
    /// The finite-difference step of the distance's gradient and Hessian [m] (SigmaRL: 0.02).
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub difference_step_m: f64,
    /// The class-K gain λ of the condition `λ·h + ḣ·dt + ½·ḧ·dt² ≥ 0` (SigmaRL: 0.1).
    #[schemars(range(min = 0))]
    pub gain: f64,
    /// Weights of the squared changes of acceleration and steering rate.
    pub weights: CbfWeights,
    /// The acceleration the QP may choose, either sign [m/s²] (SigmaRL: 40).
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub acceleration_limit_mps2: f64,
    /// The steering rate the QP may choose, either sign [rad/s] (SigmaRL: 40).
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub steering_rate_limit_radps: f64,
    /// The speed commands' range [m/s], `[lowest, highest]` (SigmaRL: `[-0.5, 1.0]`).
    pub speed_range_mps: [f64; 2],
    /// The steering commands' bound [°] (SigmaRL: 45).
    #[schemars(range(min = 0, max = 90))]
    pub max_steering_deg: f64,
    /// Rows that keep the vehicles apart (SigmaRL's later centralised QP; its 1.4.0 filter
    /// keeps one vehicle in its lane). Absent: each vehicle is filtered alone.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub agents: Option<CbfAgents>,
    /// Where the QP has no solution, its rows are relaxed by slacks whose squares cost this
    /// weight each (SigmaRL's later QP: 1e9), so the filter still does the least harm it can.
    /// Absent: the clamped nominal action goes through (SigmaRL 1.4.0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub slack_weight: Option<f64>,
}

/// The rows between vehicles: each vehicle as `circles` circles that cover the footprint
/// collisions are scored with (`metrics.footprint`, else the vehicle); for two vehicles in
/// range, every pair of their circles keeps twice the radius apart (or, with `predictor`, one
/// row keeps the footprints' predicted margin); the answer is one QP's over all the vehicles
/// (vehicles whose lone answers break no such row keep them).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CbfAgents {
    /// Two vehicles whose centres are closer than this are kept apart [m].
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub range_m: f64,
    /// SigmaRL's MTV-based margin (ECC 2025) instead of the circles: the network that predicts
    /// the minimum translation vector between two footprints from their relative pose
    /// (`sm_predictor.pth` as SigmaRL saves it, relative to the spec's folder or found on the
    /// data path, e.g. `sigmarl-published/checkpoints/ecc25/sm_predictor.pth`); one row per
    /// pair keeps the predicted margin less the network's error bound positive. Positions are
    /// scaled by the footprint's length, as SigmaRL scales them by its car's (the network
    /// learned SigmaRL's 0.16 m × 0.08 m car).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(length(min = 1))]
    pub predictor: Option<String>,
}

/// The CBF-QP's weights (SigmaRL: 30 and 1).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CbfWeights {
    /// On the squared change of acceleration.
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub acceleration: f64,
    /// On the squared change of steering rate.
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub steering_rate: f64,
}
