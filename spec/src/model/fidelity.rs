//! Fidelity levels: stacks of simulation layers (control, dynamics, sensing, actuation), or the
//! physical lab reached through its middleware.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::PresetOr;
use super::faults::LabFaults;
use super::parameter::Parameter;

/// One fidelity level.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(untagged)]
// A spec holds a handful of fidelities; boxing the simulated stack would only obscure the
// patterns that match on its layers.
#[allow(clippy::large_enum_variant)]
pub enum Fidelity {
    /// A simulated stack of layers.
    Simulated(SimulatedFidelity),
    /// The physical CPM Lab (or `cpmx lab emulate`).
    Lab(LabFidelity),
}

/// A simulated fidelity: control × dynamics × sensing × actuation. Any numeric parameter of
/// its layers may be a distribution, drawn per run (`cpmx run`) and per episode (`cpmx train`).
// As written in a spec `P` is `Parameter`; an engine runs a `DrawnFidelity` (`P = f64`), made by
// `SimulatedFidelity::draw`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, bound(deserialize = "P: Deserialize<'de>"))]
#[schemars(rename = "SimulatedFidelity")]
pub struct SimulatedFidelity<P = Parameter> {
    /// How the policy's action reaches the vehicle.
    pub control: Control,
    /// The vehicle model.
    pub dynamics: DynamicsLayer<P>,
    /// How the agents' states are measured. Default: `ideal`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sensing: Option<SensingLayer<P>>,
    /// How commands reach the actuators. Default: `ideal`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub actuation: Option<ActuationLayer<P>>,
    /// The vehicles' MPC trajectory follower (`control: trajectory`). Default: the lab's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub follower: Option<FollowerSpec>,
    /// How each agent learns the others' states by messages (V2V): without it every agent
    /// knows every other's state exactly. Ideal values (`communication: {}`) give the same
    /// runs as leaving it out.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub communication: Option<CommunicationLayer<P>>,
    /// What each agent's own sensors detect of the others (onboard perception instead of
    /// global state). Ideal values (`perception: {}`) give the same runs as leaving it out.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub perception: Option<PerceptionLayer<P>>,
    /// A safety filter between the policy's action and the vehicle (`stdlib:sigmarl-cbf`,
    /// `control: direct`): each agent's action is filtered against its lane's boundaries
    /// before it moves the car; the run folder's notes count what the filter did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(with = "Option<PresetOr<super::SafetyLayer>>")]
    pub safety: Option<super::SafetyLayer>,
}

/// The communication layer: each agent broadcasts its state at policy steps (first at the
/// run's start, then whenever `1 / rate_hz` has passed); a message reaches each other agent
/// `latency_ms` later unless it is lost or the receiver is out of range when it is sent. An
/// agent observes the others as their last messages say (not extrapolated); one never heard,
/// or unheard for longer than `max_age_ms`, is absent from its observation as SigmaRL's
/// observation treats agents that are not there. In a planner's lookahead a neighbour heard
/// this very step is predicted as without the layer; one known from an older message stays as
/// it was heard.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, bound(deserialize = "P: Deserialize<'de>"))]
#[schemars(rename = "CommunicationLayer")]
pub struct CommunicationLayer<P = Parameter> {
    /// Delay from sending to receiving [ms]. Default: 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(extend("minimum" = 0, "maximum" = 60000))]
    pub latency_ms: Option<P>,
    /// Messages per second from each agent. Default: one every policy step.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(extend("exclusiveMinimum" = 0, "maximum" = 1000))]
    pub rate_hz: Option<P>,
    /// Probability that a message does not reach a receiver (independently per receiver).
    /// Default: 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(extend("minimum" = 0, "maximum" = 1))]
    pub drop_probability: Option<P>,
    /// Farthest receiver, centre to centre [m]. Default: unlimited.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub range_m: Option<P>,
    /// Age of the last message after which its sender counts as unheard [ms]. Default: never.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(extend("minimum" = 0))]
    pub max_age_ms: Option<P>,
}

/// The perception layer: each agent detects the others whose centre is within `range_m` and
/// within `field_of_view_deg` about its heading, each with `detection_probability` per step,
/// and sees their position and heading with Gaussian noise (speed and steering as they are).
/// A detected agent is observed as seen; one not detected is heard through `communication`
/// when the fidelity has it, else absent from the observation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, bound(deserialize = "P: Deserialize<'de>"))]
#[schemars(rename = "PerceptionLayer")]
pub struct PerceptionLayer<P = Parameter> {
    /// Farthest detection, centre to centre [m]. Default: unlimited.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub range_m: Option<P>,
    /// Field of view, centred on the heading [°]. Default: all around (360).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(extend("exclusiveMinimum" = 0, "maximum" = 360))]
    pub field_of_view_deg: Option<P>,
    /// Standard deviation of the position noise, per axis [m]. Default: 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(extend("minimum" = 0))]
    pub noise_position_m: Option<P>,
    /// Standard deviation of the heading noise [rad]. Default: 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(extend("minimum" = 0))]
    pub noise_yaw_rad: Option<P>,
    /// Probability of detecting an agent in range and view at a step. Default: 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(extend("minimum" = 0, "maximum" = 1))]
    pub detection_probability: Option<P>,
}

/// The vehicle-side MPC trajectory follower.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FollowerSpec {
    /// How the MPC finds its inputs. Default: `gradient`.
    #[serde(default)]
    pub solver: FollowerSolver,
}

/// The MPC's optimiser.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum FollowerSolver {
    /// The lab's: 20 warm-started gradient steps with momentum on the nonlinear model.
    #[default]
    Gradient,
    /// The exact optimum of the linearised problem (an interior-point QP, clarabel).
    Qp,
}

/// How the policy's action reaches the vehicle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum Control {
    /// The action is applied to the kinematic bicycle every `dt` with exact states (SigmaRL's
    /// simulation). Grey-box dynamics, a sensing or actuation model and a `follower` need
    /// `trajectory`.
    Direct,
    /// The policy plans a timed trajectory over Hc/Hp that a vehicle-side MPC follows (the lab).
    Trajectory,
}

/// The vehicle model layer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(untagged)]
#[schemars(rename = "DynamicsLayer")]
pub enum DynamicsLayer<P = Parameter> {
    /// `kinematic` (or `kinematic-rk4`, `kinematic-vmas`): the kinematic bicycle as SigmaRL
    /// integrates it.
    Kinematic(KinematicKeyword),
    /// The identified grey-box µCar model (`stdlib:mu-car-greybox`).
    GreyBox(#[schemars(with = "PresetOr<GreyBoxModel>")] GreyBoxModel<P>),
}

/// The keywords of the kinematic bicycle: how a step is integrated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum KinematicKeyword {
    /// The kinematic bicycle, one explicit Euler step per `dt` (SigmaRL 1.5.0 on, and the
    /// paper's actors).
    Kinematic,
    /// The same bicycle and inputs, the motion integrated over the step (classical
    /// Runge–Kutta, 5 substeps), as SigmaRL 1.4.0's dopri5 integrates it (its ITSC 2025
    /// checkpoints). `control: direct` only, not in training.
    KinematicRk4,
    /// SigmaRL 1.2.0's car in VMAS (its ITSC 2024 and ICRA 2025 checkpoints): the commanded
    /// speed and steering taken at once (no acceleration or steering-rate limit), one
    /// Runge–Kutta step of the bicycle over `dt`, then VMAS's force round trip with its drag
    /// of 0.25, so the car moves `Δ/dt − 0.25·v` (about 0.8 × the commanded speed when
    /// steady) and its yaw rate likewise. `control: direct` only, not in training.
    KinematicVmas,
}

/// The CPM Lab's identified vehicle model (cpm-lab-interface.md §4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "GreyBoxModel")]
pub struct GreyBoxModel<P = Parameter> {
    /// p1..p10 of the lab's `VehicleModel.cxx`.
    pub parameters: [P; 10],
    /// Euler integration step [s] (the lab: 0.02).
    #[schemars(extend("exclusiveMinimum" = 0, "maximum" = 1))]
    pub euler_step_s: P,
    /// Battery voltage [V] (the lab's simulated vehicles: 7.8).
    #[schemars(extend("exclusiveMinimum" = 0, "maximum" = 20))]
    pub battery_voltage_v: P,
}

/// The sensing layer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(untagged)]
#[schemars(rename = "SensingLayer")]
pub enum SensingLayer<P = Parameter> {
    /// `ideal`: exact states, no delay.
    Ideal(IdealKeyword),
    /// An indoor positioning system with latency, noise and drops (`stdlib:cpm-ips`).
    Model(#[schemars(with = "PresetOr<SensingModel>")] SensingModel<P>),
}

/// The keyword `ideal`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum IdealKeyword {
    /// No imperfection.
    Ideal,
}

/// The CPM Lab's indoor positioning system and the on-car fusion (cpm-lab-interface.md §5).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "SensingModel")]
pub struct SensingModel<P = Parameter> {
    /// Frame rate [Hz].
    #[schemars(extend("exclusiveMinimum" = 0, "maximum" = 1000))]
    pub rate_hz: P,
    /// Delay between a frame and its arrival on the car [ms].
    #[schemars(extend("minimum" = 0, "maximum" = 10000))]
    pub latency_ms: P,
    /// Half-width of the uniform position noise [m].
    #[schemars(extend("minimum" = 0))]
    pub noise_position_m: P,
    /// Half-width of the uniform heading noise [rad].
    #[schemars(extend("minimum" = 0))]
    pub noise_yaw_rad: P,
    /// Probability that a frame is dropped.
    #[schemars(extend("minimum" = 0, "maximum" = 1))]
    pub drop_probability: P,
    /// Gain of the on-car blend toward a positioning fix (the lab: 0.3).
    #[schemars(extend("minimum" = 0, "maximum" = 1))]
    pub fusion_gain: P,
}

/// The actuation layer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(untagged)]
#[schemars(rename = "ActuationLayer")]
pub enum ActuationLayer<P = Parameter> {
    /// `ideal`: commands act at once.
    Ideal(IdealKeyword),
    /// Commands act after a delay.
    Model(ActuationModel<P>),
}

/// Actuation imperfections.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(rename = "ActuationModel")]
pub struct ActuationModel<P = Parameter> {
    /// Delay of throttle and steering [ms] (the lab's simulated vehicles: 80).
    #[schemars(extend("minimum" = 0, "maximum" = 10000))]
    pub delay_ms: P,
}

/// The physical lab, reached through its DDS middleware.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct LabFidelity {
    /// The driver. Only `cpm-dds` exists.
    pub driver: LabDriver,
    /// DDS domain on which the lab's middleware talks to planners (the lab: 1, its `--domain_number`;
    /// the vehicles themselves use the lab domain, usually 21).
    #[schemars(range(min = 0, max = 232))]
    pub domain: u32,
    /// The lab's vehicle ids, one per agent in agent order.
    #[schemars(length(min = 1))]
    pub vehicle_ids: Vec<u8>,
    /// Unicast discovery peers (`host` or `host:port`); the lab disables multicast.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub initial_peers: Vec<String>,
    /// Network interface to use (name or address); default: all.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interface: Option<String>,
    /// How long to wait for the lab before giving up [s].
    #[serde(default = "default_lab_timeout_s")]
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub timeout_s: f64,
    /// The checks before every run: every vehicle reports, fresh positioning, battery, and
    /// each vehicle at its planned start. Does not enter the runs' input hash.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preflight: Option<Preflight>,
    /// A vehicle whose positioning fixes are older than this during a run is stopped and the
    /// run fails [s] (the lab's controller stops such a car at 3 s). Default: 1. Does not enter
    /// the runs' input hash.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub ips_age_limit_s: Option<f64>,
    /// Faults `cpmx lab emulate` plays (the driver ignores them; they do not enter the runs'
    /// input hash). The same mapping as `cpmx lab emulate --faults FILE`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub faults: Option<LabFaults>,
    /// A communication layer applied to the states the middleware delivers, so that the real
    /// lab runs communication-limited experiments (see the simulated fidelities' layer).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub communication: Option<CommunicationLayer<Parameter>>,
}

fn default_lab_timeout_s() -> f64 {
    30.0
}

impl LabFidelity {
    /// The preflight's parameters (the defaults when the spec gives none).
    pub fn preflight(&self) -> Preflight {
        self.preflight.clone().unwrap_or_default()
    }

    /// The positioning age that stops a run [s].
    pub fn ips_age_limit_s(&self) -> f64 {
        self.ips_age_limit_s.unwrap_or(DEFAULT_IPS_AGE_LIMIT_S)
    }
}

/// The default of `ips_age_limit_s` [s].
pub const DEFAULT_IPS_AGE_LIMIT_S: f64 = 1.0;

/// The checks before a lab run, on the state lists the lab sends before the first planned tick.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Preflight {
    /// How far a vehicle may stand from its planned start [m]. Default: 0.02.
    #[serde(default = "default_position_tolerance_m")]
    #[schemars(range(min = 0.0))]
    pub position_tolerance_m: f64,
    /// How far its heading may differ from the start's [deg]. Default: 5.
    #[serde(default = "default_heading_tolerance_deg")]
    #[schemars(range(min = 0.0, max = 180.0))]
    pub heading_tolerance_deg: f64,
    /// The oldest positioning fix a vehicle may report (`IPS_update_age_nanoseconds`) [ms].
    /// Default: 500.
    #[serde(default = "default_max_ips_age_ms")]
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub max_ips_age_ms: f64,
    /// The lowest battery voltage a vehicle may report [V]. Default: 7.0 (3.5 V a cell of the
    /// µCar's two-cell battery).
    #[serde(default = "default_min_battery_v")]
    #[schemars(range(min = 0.0, max = 20.0))]
    pub min_battery_v: f64,
    /// What a misplaced vehicle does: `wait` for the operator to place it (the run starts once
    /// every check passes, or fails after `wait_s`), or `record`: start anyway and record where
    /// the vehicles stood, so that `from_runs` starts the simulated fidelities there.
    /// Default: `wait`.
    #[serde(default)]
    pub misplaced: Misplaced,
    /// How long to wait for the operator before the run fails [s]. Default: 120.
    #[serde(default = "default_preflight_wait_s")]
    #[schemars(range(min = 0.0))]
    pub wait_s: f64,
}

impl Default for Preflight {
    fn default() -> Self {
        Self {
            position_tolerance_m: default_position_tolerance_m(),
            heading_tolerance_deg: default_heading_tolerance_deg(),
            max_ips_age_ms: default_max_ips_age_ms(),
            min_battery_v: default_min_battery_v(),
            misplaced: Misplaced::default(),
            wait_s: default_preflight_wait_s(),
        }
    }
}

fn default_position_tolerance_m() -> f64 {
    0.02
}
fn default_heading_tolerance_deg() -> f64 {
    5.0
}
fn default_max_ips_age_ms() -> f64 {
    500.0
}
fn default_min_battery_v() -> f64 {
    7.0
}
fn default_preflight_wait_s() -> f64 {
    120.0
}

/// What the preflight does with a vehicle off its planned start.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum Misplaced {
    /// Wait for the operator to place it; the run does not start until it stands there.
    #[default]
    Wait,
    /// Start anyway and record the actual starts (the run's first sample and a note).
    Record,
}

/// Lab drivers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum LabDriver {
    /// The CPM Lab's DDS topics and message types.
    CpmDds,
}
