//! What the learner needs from a training environment: vectorised multi-agent stepping with
//! whole-env resets done inside `step`, and an opaque state for checkpoints.

/// The outcome of one step of all environments.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StepResult {
    /// The observations to act on next, `[E][N][obs_dim]`: for an environment that is done
    /// this step, those after its reset. (With `terminated == done` the value of a terminal
    /// observation is never bootstrapped, so the pre-reset observation is not needed.)
    pub observations: Vec<f32>,
    /// Rewards `[E][N]`.
    pub rewards: Vec<f32>,
    /// Whether each environment's episode ended with this step (it has been reset).
    pub done: Vec<bool>,
    /// Per reward term (in [`Environment::reward_terms`] order), the mean over the `E x N`
    /// agent-steps of this step.
    pub reward_term_means: Vec<f64>,
    /// Agent-steps in collision this step.
    pub collisions: u64,
    /// Whole-environment resets this step.
    pub env_resets: u64,
    /// Single-agent resets this step (agents re-spawned without ending the episode).
    pub agent_resets: u64,
    /// Per randomised parameter ([`Environment::randomised_parameters`]), the sum of the values
    /// drawn for the episodes that began this step.
    pub drawn_parameter_sums: Vec<f64>,
    /// Episodes whose parameters were drawn this step.
    pub draws: u64,
    /// Agent-steps whose action the environment's safety filter changed this step.
    pub filtered: u64,
    /// Agent-steps the filter had no answer for.
    pub filter_fallbacks: u64,
    /// 50 Hz periods in which the vehicles' followers stopped them once commanded (a refused
    /// trajectory, a command too old, positioning lost) this step.
    pub follower_stopped: u64,
}

/// A batch of `E` environments with `N` agents each that share one policy.
pub trait Environment {
    /// `E`.
    fn num_envs(&self) -> usize;
    /// `N`.
    fn num_agents(&self) -> usize;
    /// Observation size per agent.
    fn obs_dim(&self) -> usize;
    /// Names of the reward terms reported in [`StepResult::reward_term_means`].
    fn reward_terms(&self) -> Vec<String>;
    /// Reset every environment; the observations `[E][N][obs_dim]`.
    fn reset_all(&mut self) -> Vec<f32>;
    /// Apply `actions` (`[E][N][2]`: speed m/s, steering rad) to every environment; an error
    /// message if the environments cannot go on.
    fn step(&mut self, actions: &[f32]) -> Result<StepResult, String>;
    /// The learner's current actor, handed over before every collection (an environment
    /// whose plant plans ahead with the policy uses it; by default nothing does).
    fn set_actor(&mut self, actor: &crate::Mlp) -> Result<(), String> {
        let _ = actor;
        Ok(())
    }
    /// Whether a safety filter changes the actions before they move the vehicles (the
    /// learner learns on its own sampled actions; the filter's counts go into the records).
    fn filters(&self) -> bool {
        false
    }
    /// Whether the vehicles run the lab's follower (a `control: trajectory` fidelity), whose
    /// stops go into the records.
    fn follows(&self) -> bool {
        false
    }
    /// Names of the parameters drawn per episode (none by default).
    fn randomised_parameters(&self) -> Vec<String> {
        Vec::new()
    }
    /// Everything needed to continue exactly (states, counters, random stream positions).
    fn save_state(&self) -> Vec<u8>;
    /// Restore a [`Environment::save_state`]; an error message if the bytes do not fit.
    fn load_state(&mut self, state: &[u8]) -> Result<(), String>;
}
