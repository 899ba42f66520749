//! The reward of one agent at one step, term by term, as SigmaRL's `ScenarioRoadTraffic.reward`
//! computes it for `rew_method = "ttc_sparse"` in training mode (`road_traffic.py:925-1332`),
//! plus the speed and centre-line terms of the paper's reward (`r_speed`, `r_track`), which
//! that method leaves out. Pure functions of the inputs the environment hands in.

use cpmx_world::Point;

use crate::config::{CentreLineTerm, NearBoundaryTerm, ProgressTerm, RewardConfig, SpeedTerm, TtcTerm};

/// The terms of one agent's reward at one step (each already weighted), and their clamped sum.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RewardTerms {
    /// Progress along the short-term reference points.
    pub progress: f64,
    /// Near-boundary penalty.
    pub near_boundary: f64,
    /// Time-to-collision penalty.
    pub near_agents_ttc: f64,
    /// Speed along the path.
    pub speed: f64,
    /// Centre-line distance penalty.
    pub centre_line: f64,
    /// Agent-agent collision penalty.
    pub collide_agents: f64,
    /// Boundary collision penalty.
    pub collide_boundary: f64,
    /// The sum before the clamp.
    pub sum_unclamped: f64,
    /// The reward: the clamped sum.
    pub total: f64,
}

impl std::ops::AddAssign<&RewardTerms> for RewardTerms {
    /// Term by term (for sums over agent-steps; `sum_unclamped` is left as it is).
    fn add_assign(&mut self, t: &RewardTerms) {
        self.progress += t.progress;
        self.near_boundary += t.near_boundary;
        self.near_agents_ttc += t.near_agents_ttc;
        self.speed += t.speed;
        self.centre_line += t.centre_line;
        self.collide_agents += t.collide_agents;
        self.collide_boundary += t.collide_boundary;
        self.total += t.total;
    }
}

/// What one agent's reward depends on.
#[derive(Debug, Clone, Copy)]
pub struct RewardInput<'a> {
    /// Position after the step [m].
    pub pos: Point,
    /// Position at the start of the step (after any reset) [m].
    pub prev_pos: Point,
    /// Short-term reference points computed at the end of the previous step (or the reset).
    pub short_term: &'a [Point],
    /// Unit direction of the centre-line segment nearest to `pos`.
    pub path_direction: [f64; 2],
    /// Distance of `pos` to the centre line [m].
    pub centre_line_distance_m: f64,
    /// Smallest boundary distance (centre minus half width, and corners) [m].
    pub boundary_distance_m: f64,
    /// Index of this agent.
    pub agent: usize,
    /// Positions of all agents after the step [m].
    pub positions: &'a [Point],
    /// Velocities of all agents after the step [m/s].
    pub velocities: &'a [[f64; 2]],
    /// Whether this agent's rectangle crosses another agent's.
    pub collides_with_agents: bool,
    /// Whether this agent's rectangle crosses its shared boundaries.
    pub collides_with_boundary: bool,
    /// Progress normaliser: maximum speed × dt [m].
    pub max_step_m: f64,
    /// Speed normaliser: the maximum speed [m/s].
    pub max_speed_mps: f64,
}

/// The linear ramp of SigmaRL's `decreasing_fcn`: 1 at `x0`, 0 at `x1`, `x` clamped to `[x0, x1]`.
pub fn decreasing(x: f64, x0: f64, x1: f64) -> f64 {
    1.0 - (x.clamp(x0, x1) - x0) / (x1 - x0)
}

/// The progress term.
pub fn progress(term: &ProgressTerm, input: &RewardInput<'_>) -> f64 {
    let (p, q0) = (input.pos, input.prev_pos);
    let moved = [p[0] - q0[0], p[1] - q0[1]];
    let projected: f64 = term
        .point_weights
        .iter()
        .zip(input.short_term)
        .map(|(w, q)| w * (moved[0] * (q[0] - q0[0]) + moved[1] * (q[1] - q0[1])))
        .sum();
    projected / input.max_step_m * term.weight
}

/// The near-boundary term.
pub fn near_boundary(term: &NearBoundaryTerm, distance_m: f64) -> f64 {
    decreasing(distance_m, 0.0, term.within_m) * term.penalty
}

/// The speed term: the agent's velocity along its path, over the maximum speed.
pub fn speed(term: &SpeedTerm, input: &RewardInput<'_>) -> f64 {
    let v = input.velocities[input.agent];
    let d = input.path_direction;
    let along_mps = v[0] * d[0] + v[1] * d[1];
    let factor = if along_mps < 0.0 {
        term.against_path_factor
    } else {
        1.0
    };
    factor * along_mps / input.max_speed_mps * term.weight
}

/// The centre-line term.
pub fn centre_line(term: &CentreLineTerm, distance_m: f64) -> f64 {
    distance_m / term.scale_m * term.penalty
}

/// The TTC term, in float32 with SigmaRL's operation order (`_apply_ttc_near_agent_penalty`),
/// since whether its discriminant is positive is decided by rounding.
pub fn near_agents_ttc(term: &TtcTerm, agent: usize, positions: &[Point], velocities: &[[f64; 2]]) -> f64 {
    let n = positions.len();
    let f = |v: f64| v as f32;
    let (pi, vi) = (positions[agent], velocities[agent]);
    let d_safe = f(term.safe_distance_m);
    let (gate, eps) = (f(term.within_m), 1e-6f32);
    let mut risk_sum = 0.0f64;
    for j in 0..n {
        let p = [f(positions[j][0]) - f(pi[0]), f(positions[j][1]) - f(pi[1])];
        let v = [f(velocities[j][0]) - f(vi[0]), f(velocities[j][1]) - f(vi[1])];
        let a = v[0] * v[0] + v[1] * v[1];
        let b = 2.0 * (p[0] * v[0] + p[1] * v[1]);
        let c = (p[0] * p[0] + p[1] * p[1]) - d_safe * d_safe;
        let disc = b * b - 4.0 * a * c;
        let dist = (p[0] * p[0] + p[1] * p[1]).max(0.0).sqrt();
        let valid = a > eps && disc > 0.0 && b < 0.0;
        let candidate = (-b - disc.max(0.0).sqrt()) / (2.0 * a + eps);
        let mut ttc = if valid && candidate > 0.0 {
            candidate
        } else {
            f32::INFINITY
        };
        if dist <= d_safe {
            ttc = 0.0;
        }
        if j == agent || dist > gate {
            ttc = f32::INFINITY;
        }
        let ttc = f64::from(ttc).min(term.horizon_s);
        risk_sum += decreasing(ttc, 0.0, term.horizon_s);
    }
    risk_sum / n.saturating_sub(1).max(1) as f64 * term.penalty
}

/// Every term of one agent's reward.
pub fn reward(config: &RewardConfig, input: &RewardInput<'_>) -> RewardTerms {
    let mut t = RewardTerms {
        progress: config.progress.as_ref().map_or(0.0, |p| progress(p, input)),
        near_boundary: config
            .near_boundary
            .as_ref()
            .map_or(0.0, |b| near_boundary(b, input.boundary_distance_m)),
        near_agents_ttc: config.near_agents_ttc.as_ref().map_or(0.0, |t| {
            near_agents_ttc(t, input.agent, input.positions, input.velocities)
        }),
        speed: config.speed.as_ref().map_or(0.0, |s| speed(s, input)),
        centre_line: config
            .centre_line
            .as_ref()
            .map_or(0.0, |c| centre_line(c, input.centre_line_distance_m)),
        collide_agents: if input.collides_with_agents {
            config.collide_agents
        } else {
            0.0
        },
        collide_boundary: if input.collides_with_boundary {
            config.collide_boundary
        } else {
            0.0
        },
        ..RewardTerms::default()
    };
    t.sum_unclamped = t.progress
        + t.near_agents_ttc
        + t.near_boundary
        + t.collide_agents
        + t.collide_boundary
        + t.speed
        + t.centre_line;
    t.total = match config.clamp {
        Some((low, high)) => t.sum_unclamped.clamp(low, high),
        None => t.sum_unclamped,
    };
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ramp_is_one_at_zero_and_zero_beyond() {
        assert_eq!(decreasing(-1.0, 0.0, 0.02), 1.0);
        assert_eq!(decreasing(0.03, 0.0, 0.02), 0.0);
        assert!((decreasing(0.01, 0.0, 0.02) - 0.5).abs() < 1e-12);
    }

    #[test]
    fn ttc_needs_a_safe_distance_to_ever_be_nonzero() {
        let sigmarl = TtcTerm::default();
        let pos = [[0.0, 0.0], [0.2, 0.0]];
        let head_on = [[1.0, 0.0], [0.0, 0.0]];
        // SigmaRL's safe distance 0: the discriminant is 0 even head-on.
        assert_eq!(near_agents_ttc(&sigmarl, 0, &pos, &head_on), 0.0);
        // With a safe distance of 0.1 m: TTC = (0.2 - 0.1) / 1 s.
        let term = TtcTerm {
            safe_distance_m: 0.1,
            ..sigmarl
        };
        let p = near_agents_ttc(&term, 0, &pos, &head_on);
        assert!((p - (-0.2 * (1.0 - 0.1 / 3.75))).abs() < 1e-6, "{p}");
        // Beyond the 0.3 m gate nothing counts.
        assert_eq!(
            near_agents_ttc(&term, 0, &[[0.0, 0.0], [0.5, 0.0]], &head_on),
            0.0
        );
    }
}
