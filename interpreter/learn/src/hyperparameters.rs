//! The learner's hyperparameters (SigmaRL's names and values) with their checks, and the
//! learner's errors.

use crate::optim::AdamConfig;

/// The hyperparameters, named as in SigmaRL's `config.json` / `Parameters`.
#[derive(Debug, Clone, PartialEq)]
pub struct Hyperparameters {
    /// Iterations of the whole run (the learning-rate schedule's horizon).
    pub n_iters: u64,
    /// Env-steps collected per iteration (all environments together).
    pub frames_per_batch: usize,
    /// Passes over each batch.
    pub num_epochs: usize,
    /// Env-steps per minibatch.
    pub minibatch_size: usize,
    /// Initial learning rate.
    pub lr: f64,
    /// The learning rate the schedule decays towards.
    pub lr_min: f64,
    /// Joint gradient-norm bound.
    pub max_grad_norm: f64,
    /// PPO clip ε.
    pub clip_epsilon: f64,
    /// Discount γ.
    pub gamma: f64,
    /// GAE λ.
    pub lmbda: f64,
    /// Entropy bonus weight.
    pub entropy_eps: f64,
    /// Value loss weight.
    pub critic_coef: f64,
    /// Adam's β1, β2, ε.
    pub adam: AdamConfig,
    /// Hidden widths of the actor (tanh).
    pub actor_hidden: Vec<usize>,
    /// Hidden widths of the centralised critic (tanh).
    pub critic_hidden: Vec<usize>,
    /// Action half-ranges `[speed m/s, steering rad]`.
    pub action_high: [f32; 2],
    /// The first iterations that update the critic only: the actor collects but does not
    /// learn, so that a fresh critic beside a warm-started actor has learnt its values before
    /// its advantages move it (0: SigmaRL, both from the first iteration).
    pub critic_warmup_iterations: u64,
    /// The largest scale of the actor's action noise (before tanh; `f32::INFINITY`: none, as
    /// SigmaRL). A bound keeps a state's noise from growing without limit where the policy
    /// gradient widens it (docs/transfer.md).
    pub max_scale: f32,
}

impl Hyperparameters {
    /// SigmaRL's values (`training_setup.md` sections 1, 5, 6) for `n_iters` iterations.
    pub fn sigmarl(n_iters: u64) -> Self {
        Hyperparameters {
            n_iters,
            frames_per_batch: 4096,
            num_epochs: 30,
            minibatch_size: 512,
            lr: 1e-4,
            lr_min: 1e-5,
            max_grad_norm: 1.0,
            clip_epsilon: 0.2,
            gamma: 0.99,
            lmbda: 0.9,
            entropy_eps: 5e-4,
            critic_coef: 1.0,
            adam: AdamConfig::default(),
            actor_hidden: vec![256, 256, 256],
            critic_hidden: vec![256, 256, 256],
            action_high: [1.0, 0.541_052_04],
            critic_warmup_iterations: 0,
            max_scale: f32::INFINITY,
        }
    }

    /// What a checkpoint records to refuse resuming with other values: the `Debug` form, less
    /// the fields added since checkpoints were first written when they hold the value that
    /// means "as before" (an unbounded `max_scale`), so that older checkpoints still resume.
    pub fn fingerprint(&self) -> String {
        let text = format!("{self:?}");
        if self.max_scale == f32::INFINITY {
            text.replace(", max_scale: inf", "")
        } else {
            text
        }
    }

    /// Check the values against each other and the environment's sizes.
    pub fn check(&self, envs: usize, agents: usize, obs_dim: usize) -> Result<(), TrainError> {
        let bad = |what: String| Err(TrainError::Hyperparameters(what));
        if envs == 0 || agents == 0 || obs_dim == 0 {
            return bad(format!(
                "the environment has {envs} envs, {agents} agents, {obs_dim} observations"
            ));
        }
        if self.frames_per_batch == 0 || !self.frames_per_batch.is_multiple_of(envs) {
            return bad(format!(
                "frames_per_batch {} is not a positive multiple of the {envs} environments",
                self.frames_per_batch
            ));
        }
        if self.minibatch_size == 0 || !self.frames_per_batch.is_multiple_of(self.minibatch_size) {
            return bad(format!(
                "minibatch_size {} does not divide frames_per_batch {}",
                self.minibatch_size, self.frames_per_batch
            ));
        }
        let positive = [
            ("lr", self.lr),
            ("max_grad_norm", self.max_grad_norm),
            ("clip_epsilon", self.clip_epsilon),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                return bad(format!("{name} must be positive, got {v}"));
            }
        }
        let unit = [("gamma", self.gamma), ("lmbda", self.lmbda)];
        for (name, v) in unit {
            if !(0.0..=1.0).contains(&v) {
                return bad(format!("{name} must lie in [0, 1], got {v}"));
            }
        }
        if !(self.lr_min >= 0.0 && self.lr_min <= self.lr) || self.clip_epsilon >= 1.0 || self.n_iters == 0 {
            return bad("need 0 <= lr_min <= lr, clip_epsilon < 1 and n_iters > 0".into());
        }
        if self.critic_warmup_iterations >= self.n_iters {
            return bad(format!(
                "critic_warmup_iterations {} leaves none of the {} iterations to the actor",
                self.critic_warmup_iterations, self.n_iters
            ));
        }
        if self.actor_hidden.contains(&0) || self.critic_hidden.contains(&0) {
            return bad("hidden layers need at least one unit".into());
        }
        Ok(())
    }
}

/// Errors of the learner.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// Hyperparameters that cannot work.
    #[error("invalid training hyperparameters: {0}")]
    Hyperparameters(String),
    /// A checkpoint that cannot be resumed.
    #[error("cannot resume from the checkpoint: {0}")]
    Checkpoint(String),
    /// The environment's answer does not fit its sizes, or its state does not load.
    #[error("environment: {0}")]
    Environment(String),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fingerprint_names_a_bounded_scale_and_reads_unbounded_as_before() {
        let unbounded = Hyperparameters::sigmarl(10);
        let fingerprint = unbounded.fingerprint();
        assert!(!fingerprint.contains("max_scale"), "{fingerprint}");
        assert!(
            fingerprint.ends_with("critic_warmup_iterations: 0 }"),
            "{fingerprint}"
        );
        let bounded = Hyperparameters {
            max_scale: 1.0,
            ..unbounded.clone()
        };
        assert!(bounded.fingerprint().contains("max_scale: 1.0"));
        assert_ne!(bounded.fingerprint(), fingerprint);
    }
}
