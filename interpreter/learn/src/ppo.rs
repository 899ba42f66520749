//! The pieces of SigmaRL's MAPPO update that are not networks: generalised advantage
//! estimation (torchrl's `GAE`) and the clipped PPO loss (torchrl's `ClipPPOLoss`: objective,
//! smooth-L1 value loss, one-sample entropy estimate) with its gradients with respect to the
//! actor's raw outputs and the critic's values.

use rayon::prelude::*;

use crate::tanh_normal::{self, Params};

/// GAE over one environment's `T` consecutive steps with `N` agents, torchrl's recursion with
/// `terminated == done`:
/// `delta_t = r_t + gamma V(s_{t+1}) (1 - done_t) - V(s_t)`,
/// `A_t = delta_t + gamma lambda (1 - done_t) A_{t+1}`, `target_t = A_t + V(s_t)`.
/// `reward`, `advantage`, `target` are `[T][N]`; `value` holds `T + 1` values per env-step
/// (the critic's single output, shared by the agents; the last one bootstraps the slice).
/// Computed in float64, stored as float32.
pub fn gae(
    gamma: f64,
    lambda: f64,
    reward: &[f32],
    done: &[bool],
    value: &[f32],
    advantage: &mut [f32],
    target: &mut [f32],
) {
    let steps = done.len();
    let agents = reward.len() / steps.max(1);
    assert_eq!(
        value.len(),
        steps + 1,
        "one value per step plus the bootstrap value"
    );
    for n in 0..agents {
        let mut next_advantage = 0.0f64;
        for t in (0..steps).rev() {
            let not_done = if done[t] { 0.0 } else { 1.0 };
            let v = f64::from(value[t]);
            let delta = f64::from(reward[t * agents + n]) + gamma * f64::from(value[t + 1]) * not_done - v;
            next_advantage = delta + gamma * lambda * not_done * next_advantage;
            advantage[t * agents + n] = next_advantage as f32;
            target[t * agents + n] = (next_advantage + v) as f32;
        }
    }
}

/// One env-step of a minibatch: its index, its entries' raw-output gradients and loss terms,
/// and its value gradient.
type EnvStepChunk<'a> = (usize, ((&'a mut [f32], &'a mut [[f64; 4]]), &'a mut f32));

/// The loss coefficients and the action box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LossConfig {
    /// PPO's ε: the log-ratio is clipped to `[ln(1 - ε), ln(1 + ε)]`.
    pub clip_epsilon: f64,
    /// Weight of the entropy bonus (`entropy_eps`).
    pub entropy_coef: f64,
    /// Weight of the value loss (`critic_coef`).
    pub critic_coef: f64,
    /// Action half-ranges.
    pub high: [f32; 2],
    /// The action noise's largest scale (`f32::INFINITY`: unbounded, SigmaRL).
    pub max_scale: f32,
}

/// One minibatch's data, `S` env-steps of `N` agents: every per-entry slice is `[S][N]`
/// (actions and noise `[S][N][2]`).
#[derive(Debug, Clone, Copy)]
pub struct LossInput<'a> {
    /// Stored actions.
    pub action: &'a [f32],
    /// Their log-probabilities under the collecting policy.
    pub log_prob_old: &'a [f32],
    /// Advantages.
    pub advantage: &'a [f32],
    /// Value targets.
    pub value_target: &'a [f32],
    /// Standard normal noise of the entropy sample.
    pub entropy_eps: &'a [f32],
}

/// The loss terms of a minibatch (means over its `S x N` entries).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Losses {
    /// `-mean(min(r A, clip(r) A))`.
    pub objective: f64,
    /// `critic_coef * mean(smooth_l1(target, V))`.
    pub critic: f64,
    /// `-entropy_coef * entropy`.
    pub entropy_loss: f64,
    /// The one-sample entropy estimate `-mean(log p(a~))`.
    pub entropy: f64,
    /// Fraction of entries whose log-ratio was clipped.
    pub clip_fraction: f64,
}

impl Losses {
    /// The sum that is differentiated.
    pub fn total(&self) -> f64 {
        self.objective + self.critic + self.entropy_loss
    }
}

/// The PPO loss of a minibatch and its gradients: `raw` is the actor's output `[S][N][4]`,
/// `value` the critic's `[S]`; `d_raw` and `d_value` receive the loss gradients.
pub fn ppo_loss(
    config: &LossConfig,
    raw: &[f32],
    value: &[f32],
    input: &LossInput<'_>,
    d_raw: &mut [f32],
    d_value: &mut [f32],
) -> Losses {
    let steps = value.len();
    let entries = input.log_prob_old.len();
    let agents = entries / steps.max(1);
    assert_eq!(raw.len(), entries * 4, "actor outputs");
    let inv = 1.0 / entries as f64;
    let (log_low, log_high) = ((1.0 - config.clip_epsilon).ln(), (1.0 + config.clip_epsilon).ln());
    // Entries are independent but for the sums: each env-step's entries (its agents) run as one
    // task, in parallel, and the sums are then taken in entry order, so the result does not
    // depend on the threads.
    let mut terms = vec![[0.0f64; 4]; entries];
    d_value.fill(0.0);
    let entry = |(s, ((d_raw, terms), d_value)): EnvStepChunk<'_>| {
        for (a, (d_raw, term)) in d_raw.chunks_exact_mut(4).zip(terms).enumerate() {
            let i = s * agents + a;
            let p: Params = tanh_normal::params(&raw[i * 4..i * 4 + 4], config.max_scale);
            let action = [input.action[2 * i], input.action[2 * i + 1]];
            let eps = [input.entropy_eps[2 * i], input.entropy_eps[2 * i + 1]];
            let scored = tanh_normal::log_prob(&p, action, config.high);
            let advantage = f64::from(input.advantage[i]);

            // Clipped objective on the log-ratio.
            let log_ratio = scored.log_prob - f64::from(input.log_prob_old[i]);
            let clipped = log_ratio.clamp(log_low, log_high);
            let (gain, clipped_gain) = (log_ratio.exp() * advantage, clipped.exp() * advantage);
            let d_log_prob = if gain <= clipped_gain { -gain * inv } else { 0.0 };

            // Entropy estimate through a reparameterised sample.
            let sampled = tanh_normal::sample_log_prob(&p, eps, config.high);
            let d_sample = config.entropy_coef * inv;

            for ((d, &g_scored), &g_sampled) in d_raw.iter_mut().zip(&scored.grad_raw).zip(&sampled.grad_raw)
            {
                *d = (d_log_prob * g_scored + d_sample * g_sampled) as f32;
            }

            // Smooth-L1 value loss (beta 1) on the shared value.
            let diff = f64::from(value[s]) - f64::from(input.value_target[i]);
            let critic = if diff.abs() < 1.0 {
                0.5 * diff * diff
            } else {
                diff.abs() - 0.5
            };
            *d_value += (config.critic_coef * diff.clamp(-1.0, 1.0) * inv) as f32;
            *term = [
                gain.min(clipped_gain),
                f64::from(u8::from(clipped != log_ratio)),
                sampled.log_prob,
                critic,
            ];
        }
    };
    if crate::mlp::serial() {
        d_raw[..entries * 4]
            .chunks_mut(4 * agents)
            .zip(terms.chunks_mut(agents))
            .zip(d_value.iter_mut())
            .enumerate()
            .for_each(entry);
    } else {
        d_raw[..entries * 4]
            .par_chunks_mut(4 * agents)
            .zip(terms.par_chunks_mut(agents))
            .zip(d_value.par_iter_mut())
            .enumerate()
            .for_each(entry);
    }
    let mut sums = Losses::default();
    for [gain, clip, log_prob, critic] in terms {
        sums.objective -= gain;
        sums.clip_fraction += clip;
        sums.entropy -= log_prob;
        sums.critic += critic;
    }
    let entropy = sums.entropy * inv;
    Losses {
        objective: sums.objective * inv,
        critic: config.critic_coef * sums.critic * inv,
        entropy_loss: -config.entropy_coef * entropy,
        entropy,
        clip_fraction: sums.clip_fraction * inv,
    }
}
