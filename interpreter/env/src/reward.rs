//! The reward of one agent at one step, term by term, as SigmaRL's `ScenarioRoadTraffic.reward`
//! computes it for `rew_method = "ttc_sparse"` in training mode (`road_traffic.py:925-1332`),
//! plus the speed and centre-line terms of the paper's reward (`r_speed`, `r_track`), which
//! that method leaves out. Pure functions of the inputs the environment hands in.

use cpmx_world::Point;

use crate::config::{
    CentreLineTerm, NearAgentsTerm, NearBoundaryTerm, ProgressTerm, Ramp, RewardConfig, SpeedTerm,
    SteeringChangeTerm, TimeTerm, TtcTerm, VelocityToPointsTerm,
};

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
    /// Penalty for other agents nearby (centre distances).
    pub near_agents: f64,
    /// Velocity towards the short-term points.
    pub velocity_to_points: f64,
    /// Signed speed ("time") reward.
    pub time: f64,
    /// Steering-change penalty.
    pub steering_change: f64,
    /// The CBF-informed term.
    pub cbf_margins: f64,
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
        self.near_agents += t.near_agents;
        self.velocity_to_points += t.velocity_to_points;
        self.time += t.time;
        self.steering_change += t.steering_change;
        self.cbf_margins += t.cbf_margins;
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
    /// This step's steering command and the agent's previous one (0 before its first step
    /// after a placement), both clamped to the steering limit [rad].
    pub steering_commands_rad: [f64; 2],
    /// The steering limit [rad].
    pub max_steering_rad: f64,
    /// The agent's CBF-informed reward before its weight (in [−1, 0]; 0 without the term).
    pub cbf_margins: f64,
}

/// The linear ramp of SigmaRL's `decreasing_fcn`: 1 at `x0`, 0 at `x1`, `x` clamped to `[x0, x1]`.
pub fn decreasing(x: f64, x0: f64, x1: f64) -> f64 {
    1.0 - (x.clamp(x0, x1) - x0) / (x1 - x0)
}

/// SigmaRL's `exponential_decreasing_fcn`: 1 at `x0`, 0 at `x1`, exponential in between.
pub fn exponentially_decreasing(x: f64, x0: f64, x1: f64) -> f64 {
    let u = (x.clamp(x0, x1) - x0) / (x1 - x0);
    let e_inv = (-1.0f64).exp();
    ((-u).exp() - e_inv) / (1.0 - e_inv)
}

impl Ramp {
    /// The ramp's value at `x`: 1 at and below `x0`, 0 at and beyond `x1`.
    pub fn at(self, x: f64, x0: f64, x1: f64) -> f64 {
        match self {
            Ramp::Linear => decreasing(x, x0, x1),
            Ramp::Exponential => exponentially_decreasing(x, x0, x1),
        }
    }
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
    term.shape.at(distance_m, 0.0, term.within_m) * term.penalty
}

/// The near-agents term: the ramp of every other agent's centre distance, summed.
pub fn near_agents(term: &NearAgentsTerm, agent: usize, positions: &[Point]) -> f64 {
    let p = positions[agent];
    let sum: f64 = positions
        .iter()
        .enumerate()
        .filter(|(j, _)| *j != agent)
        .map(|(_, q)| {
            term.shape
                .at((q[0] - p[0]).hypot(q[1] - p[1]), term.from_m, term.to_m)
        })
        .sum();
    sum * term.penalty
}

/// The mean of `<v, q_k - p_prev>` over the short-term points [m²/s].
fn velocity_towards_points(input: &RewardInput<'_>) -> f64 {
    let v = input.velocities[input.agent];
    let q0 = input.prev_pos;
    let n = input.short_term.len().max(1) as f64;
    input
        .short_term
        .iter()
        .map(|q| v[0] * (q[0] - q0[0]) + v[1] * (q[1] - q0[1]))
        .sum::<f64>()
        / n
}

/// The velocity-to-points term.
pub fn velocity_to_points(term: &VelocityToPointsTerm, input: &RewardInput<'_>) -> f64 {
    let towards = velocity_towards_points(input);
    let factor = if towards > 0.0 {
        1.0
    } else {
        term.against_path_factor
    };
    factor * towards / input.max_speed_mps * term.weight
}

/// The time term.
pub fn time(term: &TimeTerm, input: &RewardInput<'_>) -> f64 {
    let sign = if velocity_towards_points(input) > 0.0 {
        1.0
    } else {
        -1.0
    };
    let v = input.velocities[input.agent];
    sign * v[0].hypot(v[1]) / input.max_speed_mps * term.weight
}

/// The steering-change term.
pub fn steering_change(term: &SteeringChangeTerm, input: &RewardInput<'_>) -> f64 {
    let [now, before] = input.steering_commands_rad;
    let excess = ((now - before).abs() - term.threshold_rad).max(0.0);
    excess / (2.0 * input.max_steering_rad - 2.0 * term.threshold_rad) * term.penalty
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
        near_agents: config
            .near_agents
            .as_ref()
            .map_or(0.0, |a| near_agents(a, input.agent, input.positions)),
        velocity_to_points: config
            .velocity_to_points
            .as_ref()
            .map_or(0.0, |v| velocity_to_points(v, input)),
        time: config.time.as_ref().map_or(0.0, |t| time(t, input)),
        steering_change: config
            .steering_change
            .as_ref()
            .map_or(0.0, |c| steering_change(c, input)),
        cbf_margins: config
            .cbf_margins
            .as_ref()
            .map_or(0.0, |c| c.weight * input.cbf_margins),
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
        + t.centre_line
        + t.near_agents
        + t.velocity_to_points
        + t.time
        + t.steering_change
        + t.cbf_margins;
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

    /// An agent at the origin that moved 0.05 m along x, with short-term points ahead on the
    /// x axis, and a second agent `other_at_m` away along y.
    fn input<'a>(
        positions: &'a [Point],
        velocities: &'a [[f64; 2]],
        short_term: &'a [Point],
        steering_commands_rad: [f64; 2],
    ) -> RewardInput<'a> {
        RewardInput {
            pos: positions[0],
            prev_pos: [positions[0][0] - 0.05, positions[0][1]],
            short_term,
            path_direction: [1.0, 0.0],
            centre_line_distance_m: 0.0,
            boundary_distance_m: 1.0,
            agent: 0,
            positions,
            velocities,
            collides_with_agents: false,
            collides_with_boundary: false,
            max_step_m: 0.1,
            max_speed_mps: 1.0,
            steering_commands_rad,
            max_steering_rad: 0.5,
            cbf_margins: 0.0,
        }
    }

    #[test]
    fn the_exponential_ramp_is_sigmarls() {
        let e = (-1.0f64).exp();
        assert_eq!(exponentially_decreasing(-0.1, 0.0, 0.02), 1.0);
        assert_eq!(exponentially_decreasing(0.5, 0.0, 0.02), 0.0);
        let mid = exponentially_decreasing(0.01, 0.0, 0.02);
        assert!((mid - ((-0.5f64).exp() - e) / (1.0 - e)).abs() < 1e-15, "{mid}");
        // Steeper near the boundary than the linear ramp, so above it in between.
        assert!(mid < 0.5 && Ramp::Exponential.at(0.002, 0.0, 0.02) > 0.0);
        let term = NearBoundaryTerm {
            penalty: -0.2,
            within_m: 0.02,
            shape: Ramp::Exponential,
        };
        assert!((near_boundary(&term, 0.01) - (-0.2 * mid)).abs() < 1e-15);
    }

    #[test]
    fn near_agents_sums_every_other_agent() {
        let term = NearAgentsTerm {
            penalty: -0.2,
            from_m: 0.1,
            to_m: 0.3,
            shape: Ramp::Linear,
        };
        // One agent at 0.05 m (full penalty), one at 0.2 m (half), one beyond.
        let positions = [[0.0, 0.0], [0.05, 0.0], [0.0, 0.2], [1.0, 1.0]];
        assert!((near_agents(&term, 0, &positions) - (-0.2 * 1.5)).abs() < 1e-12);
        // Alone, nothing.
        assert_eq!(near_agents(&term, 0, &positions[..1]), 0.0);
    }

    #[test]
    fn velocity_and_time_terms_follow_the_direction_to_the_points() {
        let positions = [[0.0, 0.0]];
        // Points 0.1, 0.2 and 0.3 m ahead of the previous position (-0.05, 0).
        let points = [[0.05, 0.0], [0.15, 0.0], [0.25, 0.0]];
        let forward = [[0.8, 0.0]];
        let i = input(&positions, &forward, &points, [0.0, 0.0]);
        let v_term = VelocityToPointsTerm {
            weight: 0.05,
            against_path_factor: 2.0,
        };
        // mean <v, q - p_prev> = 0.8 x mean(0.1, 0.2, 0.3) = 0.16 m²/s.
        assert!((velocity_to_points(&v_term, &i) - 0.05 * 0.16).abs() < 1e-12);
        assert!((time(&TimeTerm { weight: 0.05 }, &i) - 0.05 * 0.8).abs() < 1e-12);
        let backward = [[-0.8, 0.0]];
        let i = input(&positions, &backward, &points, [0.0, 0.0]);
        assert!((velocity_to_points(&v_term, &i) - 2.0 * 0.05 * -0.16).abs() < 1e-12);
        assert!((time(&TimeTerm { weight: 0.05 }, &i) + 0.05 * 0.8).abs() < 1e-12);
    }

    #[test]
    fn steering_changes_within_the_threshold_are_free() {
        let positions = [[0.0, 0.0]];
        let velocities = [[0.5, 0.0]];
        let points = [[0.05, 0.0]];
        let term = SteeringChangeTerm {
            penalty: -0.02,
            threshold_rad: 0.1,
        };
        let at = |now: f64, before: f64| {
            steering_change(&term, &input(&positions, &velocities, &points, [now, before]))
        };
        assert_eq!(at(0.3, 0.25), 0.0);
        assert_eq!(at(-0.1, 0.0), 0.0);
        // From one limit to the other: (1.0 - 0.1) / (1.0 - 0.2) x the penalty, as SigmaRL's
        // denominator subtracts the threshold twice.
        assert!((at(0.5, -0.5) - (-0.02 * 0.9 / 0.8)).abs() < 1e-15);
        assert!((at(0.0, 0.3) - (-0.02 * 0.2 / 0.8)).abs() < 1e-15);
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
