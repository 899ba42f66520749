//! What a training environment is made of: the scenario (agents, environments, episode
//! length, start sampling, reset rules) and the reward as explicit terms. The defaults are
//! SigmaRL's intersection training setup (`main_training.py` with `config.json`,
//! `rew_method = "ttc_sparse"`, non-testing mode).

use crate::stack_world::StackPlant;
use cpmx_policy::SigmarlObservation;
use cpmx_vehicle::VehicleParams;

/// Everything a [`crate::VecEnv`] needs besides the reference paths and the seed.
#[derive(Debug, Clone, PartialEq)]
pub struct EnvConfig {
    /// Agents, environments, episodes, starts, resets.
    pub scenario: ScenarioConfig,
    /// The reward terms.
    pub reward: RewardConfig,
    /// The observation design (SigmaRL's 32 values by default).
    pub observation: SigmarlObservation,
    /// Vehicle geometry and limits (the µCar).
    pub vehicle: VehicleParams,
    /// Policy (and simulation) step [s].
    pub dt_s: f64,
    /// How the agents' actions move them.
    pub plant: Plant,
    /// The fidelity's `communication` and `perception` layers: what each agent knows of the
    /// others (none: every other's state exactly, as SigmaRL).
    pub neighbours: crate::neighbours::NeighbourLayers,
    /// The fidelity's `safety:` filter: the agents' actions go through it before they move
    /// the cars (or, with vehicle stacks, into the planner's rollout). The learner learns on
    /// its own sampled actions: the filter is part of the environment.
    pub safety: Option<cpmx_safety::CbfParameters>,
}

/// How the agents' actions move them.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum Plant {
    /// SigmaRL's simulation (`control: direct`): the action applied to the float32 kinematic
    /// bicycle for one step.
    #[default]
    Direct,
    /// The lab's control architecture (`control: trajectory`): planner, MPC follower and the
    /// fidelity's dynamics, sensing and actuation (see `stack_world.rs`).
    Stack(Box<StackPlant>),
}

impl Default for EnvConfig {
    fn default() -> Self {
        EnvConfig {
            scenario: ScenarioConfig::default(),
            reward: RewardConfig::default(),
            observation: SigmarlObservation::default(),
            vehicle: VehicleParams::MU_CAR,
            dt_s: 0.1,
            plant: Plant::Direct,
            neighbours: crate::neighbours::NeighbourLayers::default(),
            safety: None,
        }
    }
}

/// The scenario: how many agents in how many environments, how episodes start and end.
#[derive(Debug, Clone, PartialEq)]
pub struct ScenarioConfig {
    /// Agents per environment (SigmaRL: 4).
    pub agents: usize,
    /// Parallel environments (SigmaRL: 32).
    pub envs: usize,
    /// SigmaRL's `max_steps` (128). An environment is done when its step counter, incremented
    /// at every step, equals `episode_steps - 1`, so an episode lasts at most 127 steps.
    pub episode_steps: u32,
    /// Start sampling.
    pub start: StartRule,
    /// Reset rules.
    pub reset: ResetRule,
}

impl Default for ScenarioConfig {
    fn default() -> Self {
        ScenarioConfig {
            agents: 4,
            envs: 32,
            episode_steps: 128,
            start: StartRule::default(),
            reset: ResetRule::default(),
        }
    }
}

/// How an agent is (re)placed: a uniformly drawn path, a uniformly drawn centre-line point
/// index in `[first_index, floor(n / 2))`, heading along the segment starting there, steering
/// zero, a uniform speed; redrawn (path and point) until its centre is at least `min_gap_m`
/// from the agents already placed.
#[derive(Debug, Clone, PartialEq)]
pub struct StartRule {
    /// First admissible centre-line point index (SigmaRL: 3).
    pub first_index: usize,
    /// Speed range [m/s], drawn uniformly in `[low, high)` (SigmaRL: `[0, 1)`).
    pub speed_mps: (f64, f64),
    /// Smallest centre distance to the other agents [m] (SigmaRL: 1.5 × the µCar's diagonal,
    /// 0.36696).
    pub min_gap_m: f64,
    /// Draws per placement before giving up with an error (SigmaRL loops forever).
    pub max_attempts: u32,
}

impl Default for StartRule {
    fn default() -> Self {
        StartRule {
            first_index: 3,
            speed_mps: (0.0, 1.0),
            min_gap_m: 1.5 * 0.22f64.hypot(0.107),
            max_attempts: 10_000,
        }
    }
}

/// What an event resets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ResetScope {
    /// The whole environment ends its episode (done) and all agents are re-placed.
    Environment,
    /// Only the agents concerned are re-placed; the episode goes on (not done).
    Agent,
    /// Nothing happens.
    None,
}

/// What ends an episode or re-places an agent.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ResetRule {
    /// On any agent-agent or agent-boundary collision (SigmaRL: the environment).
    pub on_collision: ResetScope,
    /// When an agent's rectangle touches its path's entry or exit line (SigmaRL: that agent,
    /// after the step's reward and observation, which stay the pre-reset ones).
    pub on_entry_or_exit_line: ResetScope,
}

impl Default for ResetRule {
    fn default() -> Self {
        ResetRule {
            on_collision: ResetScope::Environment,
            on_entry_or_exit_line: ResetScope::Agent,
        }
    }
}

/// The reward: a sum of explicit terms, then a clamp. A term that is `None` (or a penalty of
/// 0) contributes nothing.
#[derive(Debug, Clone, PartialEq)]
pub struct RewardConfig {
    /// Progress along the short-term reference points.
    pub progress: Option<ProgressTerm>,
    /// Penalty for being near the shared road boundaries.
    pub near_boundary: Option<NearBoundaryTerm>,
    /// Time-to-collision penalty for nearby agents.
    pub near_agents_ttc: Option<TtcTerm>,
    /// Reward for speed along the path (none in SigmaRL's `ttc_sparse` reward).
    pub speed: Option<SpeedTerm>,
    /// Penalty for the distance to the centre line (none in SigmaRL's `ttc_sparse` reward).
    pub centre_line: Option<CentreLineTerm>,
    /// Penalty for other agents' centres nearby (SigmaRL's before the TTC term).
    pub near_agents: Option<NearAgentsTerm>,
    /// Reward for the velocity towards the short-term points (SigmaRL's "high velocity").
    pub velocity_to_points: Option<VelocityToPointsTerm>,
    /// Signed speed reward (SigmaRL's "time" reward).
    pub time: Option<TimeTerm>,
    /// Penalty for changing the steering command quickly.
    pub steering_change: Option<SteeringChangeTerm>,
    /// SigmaRL's CBF-informed reward: the filter's rows under the joint sampled action.
    pub cbf_margins: Option<CbfMarginsTerm>,
    /// Added when the agent's rectangle crosses another agent's (SigmaRL adds its -1 twice: -2).
    pub collide_agents: f64,
    /// Added when the agent's rectangle crosses its shared road boundary (SigmaRL: -2).
    pub collide_boundary: f64,
    /// The sum is clamped to `[low, high]` (SigmaRL: `[-1, 1]`).
    pub clamp: Option<(f64, f64)>,
}

impl Default for RewardConfig {
    fn default() -> Self {
        RewardConfig {
            progress: Some(ProgressTerm::default()),
            near_boundary: Some(NearBoundaryTerm::default()),
            near_agents_ttc: Some(TtcTerm::default()),
            speed: None,
            centre_line: None,
            near_agents: None,
            velocity_to_points: None,
            time: None,
            steering_change: None,
            cbf_margins: None,
            collide_agents: -2.0,
            collide_boundary: -2.0,
            clamp: Some((-1.0, 1.0)),
        }
    }
}

/// `weight * sum_k w_k <p - p_prev, q_k - p_prev> / (max_speed * dt)`, with `q_k` the
/// short-term reference points computed at the end of the previous step (or at the reset):
/// centre-line points `c + 1 + k * spacing` after the closest point `c`, past the end of an
/// open path continued along its last segment.
#[derive(Debug, Clone, PartialEq)]
pub struct ProgressTerm {
    /// Weight (SigmaRL's `reward_progress`: 0.1).
    pub weight: f64,
    /// Weights of the points, in order (SigmaRL: `linspace(1, 0.2, 3) / sum`).
    pub point_weights: Vec<f64>,
    /// Index spacing of the points on the centre line (SigmaRL: 2).
    pub spacing: usize,
}

impl ProgressTerm {
    /// SigmaRL's weights for `points` points: `linspace(1, 0.2, points)` normalised to sum 1.
    pub fn sigmarl_weights(points: usize) -> Vec<f64> {
        let raw: Vec<f64> = match points {
            0 => vec![],
            1 => vec![1.0],
            _ => (0..points)
                .map(|k| 1.0 - 0.8 * k as f64 / (points - 1) as f64)
                .collect(),
        };
        let sum: f64 = raw.iter().sum();
        raw.iter().map(|w| w / sum).collect()
    }
}

impl Default for ProgressTerm {
    fn default() -> Self {
        ProgressTerm {
            weight: 0.1,
            point_weights: Self::sigmarl_weights(3),
            spacing: 2,
        }
    }
}

/// `penalty * ramp(d; 0, within_m)` with `d` the smallest of the distances of the centre
/// (minus half the width) and of the 4 corners to the left and right shared boundaries.
/// Agent 0's corners are those of the start of the step when the observation design lags them
/// (SigmaRL's order of updates).
#[derive(Debug, Clone, PartialEq)]
pub struct NearBoundaryTerm {
    /// Penalty at distance 0 (SigmaRL: -0.2).
    pub penalty: f64,
    /// Distance where the penalty reaches 0 [m] (SigmaRL: 0.02).
    pub within_m: f64,
    /// The ramp (SigmaRL: linear; exponential when the paper's policies were trained).
    pub shape: Ramp,
}

impl Default for NearBoundaryTerm {
    fn default() -> Self {
        NearBoundaryTerm {
            penalty: -0.2,
            within_m: 0.02,
            shape: Ramp::Linear,
        }
    }
}

/// How a proximity penalty falls from 1 at `x0` to 0 at `x1`; `x` is clamped to `[x0, x1]`
/// and scaled to `u = (x - x0) / (x1 - x0)` in [0, 1].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Ramp {
    /// `1 - u` (SigmaRL's `decreasing_fcn`).
    #[default]
    Linear,
    /// `(e^-u - e^-1) / (1 - e^-1)` (SigmaRL's `exponential_decreasing_fcn`).
    Exponential,
}

/// `penalty * sum_{j != i} ramp(|p_j - p_i|; from_m, to_m)`: every other agent whose centre is
/// nearer than `to_m` adds up to `penalty` (SigmaRL's near-agents penalty before the TTC term,
/// with centre-to-centre distances).
#[derive(Debug, Clone, PartialEq)]
pub struct NearAgentsTerm {
    /// Penalty per agent at `from_m` or nearer.
    pub penalty: f64,
    /// Where the full penalty starts [m].
    pub from_m: f64,
    /// Where the penalty reaches 0 [m].
    pub to_m: f64,
    /// The ramp.
    pub shape: Ramp,
}

/// `weight * f * mean_k <v, q_k - p_prev> / max_speed` with the progress term's short-term
/// points `q_k` and previous position `p_prev` (unnormalised vectors, so the value also scales
/// with the points' distance), `f = against_path_factor` when the mean is negative: SigmaRL's
/// "high velocity" reward of `rew_method = "default"`.
#[derive(Debug, Clone, PartialEq)]
pub struct VelocityToPointsTerm {
    /// Weight.
    pub weight: f64,
    /// Multiplies the term when it is negative (SigmaRL: 2).
    pub against_path_factor: f64,
}

/// `weight * s * |v| / max_speed`, `s = 1` when `mean_k <v, q_k - p_prev> > 0` (moving towards
/// the short-term points), else `-1`: SigmaRL's "time" reward of `rew_method = "default"`.
#[derive(Debug, Clone, PartialEq)]
pub struct TimeTerm {
    /// Weight.
    pub weight: f64,
}

/// `penalty * max(|c_t - c_(t-1)| - threshold_rad, 0) / (2 max_steering - 2 threshold_rad)`
/// with `c` the steering commands (clamped to the steering limit) of this step and of the
/// agent's previous one, 0 before its first step after a placement. SigmaRL's
/// `rew_method = "default"` penalty compares the two commands before this one (its buffer is
/// filled after the reward); this term compares the change the action itself makes.
#[derive(Debug, Clone, PartialEq)]
pub struct SteeringChangeTerm {
    /// Penalty per unit of the scaled excess change.
    pub penalty: f64,
    /// Free change [rad].
    pub threshold_rad: f64,
}

/// `weight × mean(clamp(g_left / threshold, −1, 0), clamp(g_right / threshold, −1, 0),
/// clamp(min(g_agents, 0) / threshold, −1, 0))`: the worst values of the CBF filter's rows
/// (each circle against the lane's boundaries, and against every other agent's circles) under
/// the step's joint sampled action, at the states the action is taken in (SigmaRL 1.6.0).
#[derive(Debug, Clone, PartialEq)]
pub struct CbfMarginsTerm {
    /// The weight of the mean.
    pub weight: f64,
    /// A margin this short costs the whole term.
    pub threshold: f64,
    /// The rows and the conversion of commands into inputs.
    pub parameters: cpmx_safety::margins::MarginParameters,
}

/// `penalty * mean_{j != i} (1 - clamp(ttc_ij, 0, horizon_s) / horizon_s)`; `ttc_ij` is the
/// first positive root of `|p + v t| = safe_distance_m` (relative position and velocity),
/// infinite for agents farther than `within_m`. With SigmaRL's `safe_distance_m = 0` the
/// root exists only for a relative velocity pointing exactly at the other centre, so the
/// term is practically always 0.
#[derive(Debug, Clone, PartialEq)]
pub struct TtcTerm {
    /// Penalty at TTC 0 (SigmaRL: -0.2).
    pub penalty: f64,
    /// Centre distance beyond which another agent is ignored [m] (SigmaRL: 0.3).
    pub within_m: f64,
    /// TTC where the penalty reaches 0 [s] (SigmaRL: 3.75).
    pub horizon_s: f64,
    /// Distance whose reaching counts as the collision [m] (SigmaRL: 0).
    pub safe_distance_m: f64,
}

impl Default for TtcTerm {
    fn default() -> Self {
        TtcTerm {
            penalty: -0.2,
            within_m: 0.3,
            horizon_s: 3.75,
            safe_distance_m: 0.0,
        }
    }
}

/// `weight * v_along / max_speed`, times `against_path_factor` when `v_along < 0`: `v_along`
/// is the velocity after the step projected on the direction of the centre-line segment
/// nearest to the agent. The speed reward of the paper's `r_speed` (SigmaRL's "high velocity"
/// and "time" shaping of `rew_method = "default"`, which project on unnormalised vectors to
/// the short-term points instead of a unit direction).
#[derive(Debug, Clone, PartialEq)]
pub struct SpeedTerm {
    /// Weight.
    pub weight: f64,
    /// Multiplies the term when the agent moves against its path (SigmaRL: 2).
    pub against_path_factor: f64,
}

/// `penalty * d / scale_m`, `d` the distance of the agent's centre to its path's centre line
/// (SigmaRL's "deviating from reference path" shaping: penalty -0.02, scale
/// `(lane width - vehicle width) / 2`).
#[derive(Debug, Clone, PartialEq)]
pub struct CentreLineTerm {
    /// Penalty at a distance of `scale_m`.
    pub penalty: f64,
    /// Distance normaliser [m].
    pub scale_m: f64,
}

/// A configuration the environment cannot run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConfigError {
    #[error("a training scenario needs at least one agent and one environment")]
    Empty,
    #[error("a training scenario needs at least one reference path")]
    NoPaths,
    #[error("episode_steps must be at least 2 (an episode lasts episode_steps - 1 steps)")]
    EpisodeTooShort,
    #[error("reference path {id} has {points} centre-line points: no start index in [{first}, {end})")]
    NoStartPoint {
        id: usize,
        points: usize,
        first: usize,
        end: usize,
    },
    #[error("reference path {id} is degenerate (fewer than two centre-line or boundary points)")]
    DegeneratePath { id: usize },
    #[error("the speed range [{low}, {high}) is empty")]
    SpeedRange { low: f64, high: f64 },
    #[error("{name} must be positive, found {value}")]
    NotPositive { name: &'static str, value: f64 },
    #[error("the clamp [{low}, {high}] is empty")]
    Clamp { low: f64, high: f64 },
    #[error("the progress term has no point weights")]
    NoProgressPoints,
    #[error("the velocity_to_points and time terms need the progress term's short-term points")]
    NoShortTermPoints,
    #[error("the vehicles cannot run: {0}")]
    Stack(String),
    #[error("observation size {found} does not fit the layout ({expected} values expected)")]
    Observation { found: usize, expected: usize },
    #[error(
        "a reference path's road boundaries have fewer than two points: no lane for the safety filter or the CBF rows"
    )]
    Lanes,
}

impl EnvConfig {
    /// Checks what the environment relies on (paths are checked when they are prepared).
    pub fn check(&self) -> Result<(), ConfigError> {
        let s = &self.scenario;
        if s.agents == 0 || s.envs == 0 {
            return Err(ConfigError::Empty);
        }
        if s.episode_steps < 2 {
            return Err(ConfigError::EpisodeTooShort);
        }
        let (low, high) = s.start.speed_mps;
        if low.partial_cmp(&high) != Some(std::cmp::Ordering::Less) {
            return Err(ConfigError::SpeedRange { low, high });
        }
        positive("dt_s", self.dt_s)?;
        if let Plant::Stack(plant) = &self.plant {
            plant.check(self.dt_s).map_err(ConfigError::Stack)?;
        }
        positive("max_speed_mps", self.vehicle.max_speed_mps)?;
        if let Some(p) = &self.reward.progress
            && p.point_weights.is_empty()
        {
            return Err(ConfigError::NoProgressPoints);
        }
        if let Some(b) = &self.reward.near_boundary {
            positive("near_boundary.within_m", b.within_m)?;
        }
        if let Some(t) = &self.reward.near_agents_ttc {
            positive("near_agents_ttc.horizon_s", t.horizon_s)?;
        }
        if let Some(c) = &self.reward.centre_line {
            positive("centre_line.scale_m", c.scale_m)?;
        }
        if let Some(a) = &self.reward.near_agents {
            positive("near_agents.to_m - near_agents.from_m", a.to_m - a.from_m)?;
        }
        if let Some(c) = &self.reward.steering_change {
            positive(
                "the steering limit - steering_change.threshold_rad",
                self.vehicle.max_steering_rad - c.threshold_rad,
            )?;
        }
        if (self.reward.velocity_to_points.is_some() || self.reward.time.is_some())
            && self.reward.progress.is_none()
        {
            return Err(ConfigError::NoShortTermPoints);
        }
        if let Some((low, high)) = self.reward.clamp
            && !matches!(
                low.partial_cmp(&high),
                Some(std::cmp::Ordering::Less | std::cmp::Ordering::Equal)
            )
        {
            return Err(ConfigError::Clamp { low, high });
        }
        Ok(())
    }
}

fn positive(name: &'static str, value: f64) -> Result<(), ConfigError> {
    if value > 0.0 && value.is_finite() {
        Ok(())
    } else {
        Err(ConfigError::NotPositive { name, value })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sigmarl_progress_weights() {
        let w = ProgressTerm::sigmarl_weights(3);
        assert!((w[0] - 0.555_555_6).abs() < 1e-7);
        assert!((w[1] - 0.333_333_3).abs() < 1e-7);
        assert!((w[2] - 0.111_111_1).abs() < 1e-7);
    }

    #[test]
    fn the_default_is_valid_and_the_min_gap_is_sigmarls() {
        let c = EnvConfig::default();
        assert_eq!(c.check(), Ok(()));
        assert!((c.scenario.start.min_gap_m - 0.36696).abs() < 1e-5);
    }

    #[test]
    fn an_empty_clamp_is_rejected() {
        let mut c = EnvConfig::default();
        c.reward.clamp = Some((1.0, -1.0));
        assert!(matches!(c.check(), Err(ConfigError::Clamp { .. })));
    }
}
