//! What a step hands to the learner: next observations, rewards, done flags, running returns,
//! and the per-step logging figures (mean of each reward term, collision and reset counts).

use crate::reward::RewardTerms;

/// The outcome of one step of every environment.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StepResult {
    /// Observations for the next action, `[E][N][obs_dim]` flattened: for a done environment
    /// its reset observation; otherwise the observation of the new states (for an agent that
    /// was re-placed alone, the stale pre-reset one, as in SigmaRL).
    pub observations: Vec<f32>,
    /// Reward of every agent, `[E][N]` flattened.
    pub rewards: Vec<f32>,
    /// Whether each environment ended its episode at this step (and has been reset), `[E]`.
    pub done: Vec<bool>,
    /// Equal to `done` (SigmaRL, through torchrl, treats the time limit as a termination).
    pub terminated: Vec<bool>,
    /// Whether each environment's episode ended at this step by the time limit alone
    /// (`episode_steps`) rather than by a collision or line rule, `[E]`: what Gymnasium calls a
    /// truncation.
    pub truncated: Vec<bool>,
    /// The observations of the states each done environment ended in, before its reset,
    /// `[E][N][obs_dim]` flattened (other environments' rows are zero); filled only when
    /// [`crate::VecEnv::set_keep_final_observations`] asked for them, else empty.
    pub final_observations: Vec<f32>,
    /// Every agent's return since its environment's last whole reset, this step included
    /// (torchrl's `RewardSum`), `[E][N]`; at a done step, the episode's return.
    pub episode_reward: Vec<f32>,
    /// Every term and flag of every agent at this step, `[E][N]`.
    pub agents: Vec<AgentStepInfo>,
    /// Mean of each reward term over the `E * N` agent-steps.
    pub reward_terms: RewardTermMeans,
    /// Agent-steps in collision.
    pub collisions: CollisionCounts,
    /// Resets done at this step.
    pub resets: ResetCounts,
    /// Per randomised fidelity parameter (`VecEnv::randomised_parameters`), the sum of the
    /// values drawn for the episodes that began at this step.
    pub drawn_parameter_sums: Vec<f64>,
    /// Episodes whose fidelity was drawn at this step.
    pub draws: u64,
    /// Agent-steps whose action the fidelity's safety filter changed this step (0 without
    /// one; with vehicle stacks, every rolled-out step of the planner counts).
    pub filtered: u64,
    /// Agent-steps where the filter had no answer and the clamped action went through.
    pub filter_fallbacks: u64,
    /// 50 Hz periods of this step in which the vehicles' followers stopped them once
    /// commanded (0 without vehicle stacks).
    pub follower_stopped: u64,
}

/// One agent at one step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AgentStepInfo {
    /// The reward's terms.
    pub terms: RewardTerms,
    /// Its rectangle crosses another agent's.
    pub collides_with_agents: bool,
    /// Its rectangle crosses its shared road boundaries.
    pub collides_with_boundary: bool,
    /// Its rectangle crosses its path's entry or exit line.
    pub touches_entry_or_exit: bool,
    /// It was re-placed alone after this step.
    pub reset: bool,
    /// The 50 Hz periods of this step in which the lab's follower on its vehicle stopped it
    /// once commanded (a refused trajectory, a command too old, positioning lost); 0 without
    /// a vehicle stack.
    pub follower_stopped_periods: u32,
}

/// Means of the reward terms over the agent-steps of a step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RewardTermMeans {
    pub progress: f64,
    pub near_boundary: f64,
    pub near_agents_ttc: f64,
    pub collide_agents: f64,
    pub collide_boundary: f64,
    pub speed: f64,
    pub centre_line: f64,
    pub near_agents: f64,
    pub velocity_to_points: f64,
    pub time: f64,
    pub steering_change: f64,
    pub cbf_margins: f64,
    /// Mean of the (clamped) reward.
    pub total: f64,
}

/// Agent-steps in collision at a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CollisionCounts {
    /// Agent-steps whose rectangle crosses another agent's.
    pub with_agents: u64,
    /// Agent-steps whose rectangle crosses the shared road boundaries.
    pub with_boundary: u64,
}

/// Resets at a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ResetCounts {
    /// Whole environments reset (done).
    pub environments: u64,
    /// Agents re-placed alone.
    pub agents: u64,
    /// Placements that found no start `min_gap_m` from the others within `max_attempts`
    /// draws and took the farthest one drawn.
    pub relaxed_starts: u64,
}

/// Sums over agent-steps, accumulated per environment and added in environment order.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct StepTotals {
    pub terms: RewardTerms,
    pub with_agents: u64,
    pub with_boundary: u64,
    pub env_resets: u64,
    pub agent_resets: u64,
    pub starts_relaxed: u64,
    /// Agent-steps whose action the safety filter changed.
    pub filtered: u64,
    /// Agent-steps where the filter had no answer and the clamped action went through.
    pub filter_fallbacks: u64,
    /// 50 Hz periods in which the vehicles' followers stopped them once commanded.
    pub follower_stopped: u64,
}

impl StepTotals {
    pub(crate) fn add_agent(&mut self, info: &AgentStepInfo) {
        self.terms += &info.terms;
        self.with_agents += u64::from(info.collides_with_agents);
        self.with_boundary += u64::from(info.collides_with_boundary);
        self.follower_stopped += u64::from(info.follower_stopped_periods);
    }

    pub(crate) fn add(&mut self, o: &StepTotals) {
        self.terms += &o.terms;
        self.with_agents += o.with_agents;
        self.with_boundary += o.with_boundary;
        self.env_resets += o.env_resets;
        self.agent_resets += o.agent_resets;
        self.starts_relaxed += o.starts_relaxed;
        self.filtered += o.filtered;
        self.filter_fallbacks += o.filter_fallbacks;
        self.follower_stopped += o.follower_stopped;
    }
}

impl StepResult {
    /// Buffers for E environments of N agents.
    pub fn new(envs: usize, agents: usize, obs_dim: usize) -> Self {
        let mut r = StepResult::default();
        r.resize(envs, agents, obs_dim);
        r
    }

    pub(crate) fn resize(&mut self, envs: usize, agents: usize, obs_dim: usize) {
        self.observations.resize(envs * agents * obs_dim, 0.0);
        self.rewards.resize(envs * agents, 0.0);
        self.episode_reward.resize(envs * agents, 0.0);
        self.agents.resize(envs * agents, AgentStepInfo::default());
        self.done.resize(envs, false);
        self.terminated.resize(envs, false);
        self.truncated.resize(envs, false);
    }

    pub(crate) fn set_totals(&mut self, t: StepTotals, agent_steps: usize) {
        let k = agent_steps.max(1) as f64;
        self.reward_terms = RewardTermMeans {
            progress: t.terms.progress / k,
            near_boundary: t.terms.near_boundary / k,
            near_agents_ttc: t.terms.near_agents_ttc / k,
            collide_agents: t.terms.collide_agents / k,
            collide_boundary: t.terms.collide_boundary / k,
            speed: t.terms.speed / k,
            centre_line: t.terms.centre_line / k,
            near_agents: t.terms.near_agents / k,
            velocity_to_points: t.terms.velocity_to_points / k,
            time: t.terms.time / k,
            steering_change: t.terms.steering_change / k,
            cbf_margins: t.terms.cbf_margins / k,
            total: t.terms.total / k,
        };
        self.collisions = CollisionCounts {
            with_agents: t.with_agents,
            with_boundary: t.with_boundary,
        };
        self.resets = ResetCounts {
            environments: t.env_resets,
            agents: t.agent_resets,
            relaxed_starts: t.starts_relaxed,
        };
        self.filtered = t.filtered;
        self.filter_fallbacks = t.filter_fallbacks;
        self.follower_stopped = t.follower_stopped;
    }
}
