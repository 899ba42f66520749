//! SigmaRL's MAPPO (`sigmarl/mappo_cavs.py` with torchrl's collector, `GAE` and
//! `ClipPPOLoss`), written out as one loop. One call of [`Trainer::iterate`] is one iteration:
//!
//! 1. **Collect** `frames_per_batch` env-steps: `T = frames_per_batch / E` steps of every
//!    environment, continuing the episodes of the previous iteration (environments are never
//!    reset at iteration boundaries; done environments reset themselves inside `step`). Every
//!    agent samples `a = high * clamp(tanh(loc + scale * eps))` from the shared actor with
//!    `eps ~ N(0, 1)` drawn as float32 from the `train/actions` stream (env, agent, speed then
//!    steering), and its log-probability is stored as torch scores a stored action.
//! 2. **GAE** once with the critic before the epochs (`gamma`, `lmbda`, `terminated == done`;
//!    the last step of each slice bootstraps from the value of the next observation).
//! 3. **Update**: `num_epochs` times, a permutation of the `E x T` env-steps (Fisher-Yates
//!    from the `train/minibatches` stream) split into minibatches of `minibatch_size`
//!    env-steps; per minibatch the actor runs on its `minibatch_size x N` agent rows, the
//!    centralised critic on the `minibatch_size` concatenated observations; loss = clipped
//!    objective + smooth-L1 value loss + entropy term (one reparameterised sample per entry,
//!    noise from the `train/entropy` stream); the joint actor+critic gradient is clipped to
//!    `max_grad_norm` and one Adam step is taken at the iteration's learning rate.
//! 4. **Log**: `episode_reward_mean` is the mean of the agents' running episode returns over
//!    the (env, step, agent) entries whose env was done at that step, rounded to 2 decimals;
//!    if it is strictly greater than the best so far (initially -1000), the actor and critic
//!    become the best ones.
//!
//! Numbers do not depend on rayon's thread count: the collection runs in a fixed order and the
//! matrix products split rows between threads without changing any sum (see `cpmx_kernels::gemm`).

use std::time::Instant;

use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha20Rng;
use rand_distr::{Distribution, StandardNormal};

pub use crate::hyperparameters::{Hyperparameters, TrainError};

use crate::env::Environment;
use crate::mlp::{Mlp, Tape};
use crate::optim::{AdamState, clip_grad_norm, learning_rate};
use crate::ppo::{LossConfig, LossInput, Losses, gae, ppo_loss};
use crate::tanh_normal;

/// What one iteration did (one row of `learning_curve.csv`).
#[derive(Debug, Clone, PartialEq)]
pub struct IterationRecord {
    /// 1-based iteration.
    pub iteration: u64,
    /// Env-steps collected so far.
    pub samples: u64,
    /// SigmaRL's `episode_reward_mean` (NaN when no episode ended in this batch).
    pub episode_reward_mean: f64,
    /// Episodes that ended in this batch (environments done).
    pub episodes: u64,
    /// Mean of each reward term over the batch's agent-steps.
    pub reward_term_means: Vec<f64>,
    /// Agent-steps in collision.
    pub collisions: u64,
    /// Whole-environment resets.
    pub env_resets: u64,
    /// Single-agent resets.
    pub agent_resets: u64,
    /// Episodes whose randomised parameters were drawn in this batch.
    pub draws: u64,
    /// Per randomised parameter, the mean of the values drawn in this batch (NaN without draws).
    pub drawn_parameter_means: Vec<f64>,
    /// Mean over the minibatch steps of the clipped objective.
    pub policy_loss: f64,
    /// ... of the value loss.
    pub value_loss: f64,
    /// ... of the entropy loss.
    pub entropy_loss: f64,
    /// ... of the joint gradient norm before clipping.
    pub grad_norm: f64,
    /// ... of the clip fraction.
    pub clip_fraction: f64,
    /// The iteration's learning rate.
    pub lr: f64,
    /// Whether this iteration's actor became the best one.
    pub best: bool,
    /// Seconds collecting.
    pub collect_seconds: f64,
    /// Seconds updating (GAE and the epochs).
    pub update_seconds: f64,
    /// The mean pre-tanh scale of the sampled actions over the batch, `[speed, steering]`:
    /// the policy's noise, which grows when a training collapses (the one-sample entropy
    /// estimate cannot show it).
    pub action_scale_means: [f64; 2],
    /// What the environment's safety filter did in the batch, when it has one.
    pub filter: Option<FilterCounts>,
    /// The 50 Hz periods of the batch in which the vehicles' followers stopped them once
    /// commanded, when the vehicles run the lab's follower.
    pub follower_stopped: Option<u64>,
}

/// What a safety filter in the environment did over a batch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FilterCounts {
    /// Agent-steps whose action it changed.
    pub changed: u64,
    /// Agent-steps it had no answer for (the clamped action went through).
    pub fallbacks: u64,
}

/// One iteration's collected batch, env-major.
#[derive(Debug, Clone, Default)]
struct Batch {
    /// `[E][T + 1][N * D]` (the extra step holds the bootstrap observation).
    obs: Vec<f32>,
    /// `[E][T][N][2]`.
    action: Vec<f32>,
    /// `[E][T][N]`.
    log_prob: Vec<f32>,
    reward: Vec<f32>,
    advantage: Vec<f32>,
    target: Vec<f32>,
    /// `[E][T]`.
    done: Vec<bool>,
    /// `[E][T + 1]` critic values.
    value: Vec<f32>,
}

/// The named random streams of a training run.
pub(crate) const STREAMS: [&str; 4] = [
    "train/init",
    "train/actions",
    "train/minibatches",
    "train/entropy",
];

/// The 32-byte key of a named stream of `seed` (the project's rule, `cpmx-spec`'s
/// `stream_key`: SHA-256 of `"cpmx/stream/v1\0"`, the seed little-endian, `0`, the name).
pub fn stream_key(seed: u64, stream: &str) -> [u8; 32] {
    use sha2::{Digest, Sha256};
    let mut hasher = Sha256::new();
    hasher.update(b"cpmx/stream/v1\0");
    hasher.update(seed.to_le_bytes());
    hasher.update([0u8]);
    hasher.update(stream.as_bytes());
    hasher.finalize().into()
}

/// A MAPPO training run over an environment.
pub struct Trainer<E: Environment> {
    pub(crate) env: E,
    pub(crate) hp: Hyperparameters,
    pub(crate) seed: u64,
    pub(crate) actor: Mlp,
    pub(crate) critic: Mlp,
    pub(crate) adam_actor: AdamState,
    pub(crate) adam_critic: AdamState,
    pub(crate) adam_steps: u64,
    /// Completed iterations.
    pub(crate) iteration: u64,
    pub(crate) rng_actions: ChaCha20Rng,
    pub(crate) rng_minibatches: ChaCha20Rng,
    pub(crate) rng_entropy: ChaCha20Rng,
    /// The observations to act on next, `[E][N][D]`.
    pub(crate) observations: Vec<f32>,
    /// Running episode return per agent, `[E][N]`.
    pub(crate) episode_return: Vec<f32>,
    pub(crate) best_reward: f64,
    pub(crate) best_actor: Mlp,
    pub(crate) best_critic: Mlp,
    batch: Batch,
    work: Workspace,
}

/// Buffers of the update, reused across minibatches.
#[derive(Debug, Clone, Default)]
struct Workspace {
    actor_tape: Tape,
    critic_tape: Tape,
    x: Vec<f32>,
    action: Vec<f32>,
    log_prob: Vec<f32>,
    advantage: Vec<f32>,
    target: Vec<f32>,
    eps: Vec<f32>,
    d_raw: Vec<f32>,
    d_value: Vec<f32>,
    actor_grad: Vec<f32>,
    critic_grad: Vec<f32>,
}

/// Everything of a trainer but its buffers (what a checkpoint restores).
pub(crate) struct Parts<E> {
    pub env: E,
    pub hp: Hyperparameters,
    pub seed: u64,
    pub actor: Mlp,
    pub critic: Mlp,
    pub adam_actor: AdamState,
    pub adam_critic: AdamState,
    pub adam_steps: u64,
    pub iteration: u64,
    pub rng_actions: ChaCha20Rng,
    pub rng_minibatches: ChaCha20Rng,
    pub rng_entropy: ChaCha20Rng,
    pub observations: Vec<f32>,
    pub episode_return: Vec<f32>,
    pub best_reward: f64,
    pub best_actor: Mlp,
    pub best_critic: Mlp,
}

impl<E: Environment> Trainer<E> {
    pub(crate) fn from_parts(p: Parts<E>) -> Self {
        Trainer {
            env: p.env,
            hp: p.hp,
            seed: p.seed,
            actor: p.actor,
            critic: p.critic,
            adam_actor: p.adam_actor,
            adam_critic: p.adam_critic,
            adam_steps: p.adam_steps,
            iteration: p.iteration,
            rng_actions: p.rng_actions,
            rng_minibatches: p.rng_minibatches,
            rng_entropy: p.rng_entropy,
            observations: p.observations,
            episode_return: p.episode_return,
            best_reward: p.best_reward,
            best_actor: p.best_actor,
            best_critic: p.best_critic,
            batch: Batch::default(),
            work: Workspace::default(),
        }
    }

    /// A fresh run: networks initialised as PyTorch does from the `train/init` stream of
    /// `seed`, every environment reset.
    pub fn new(mut env: E, hp: Hyperparameters, seed: u64) -> Result<Self, TrainError> {
        let (envs, agents, obs_dim) = (env.num_envs(), env.num_agents(), env.obs_dim());
        hp.check(envs, agents, obs_dim)?;
        let mut init = ChaCha20Rng::from_seed(stream_key(seed, STREAMS[0]));
        let actor = Mlp::init(&layer_sizes(obs_dim, &hp.actor_hidden, 4), &mut init);
        let critic = Mlp::init(&layer_sizes(agents * obs_dim, &hp.critic_hidden, 1), &mut init);
        let observations = env.reset_all();
        check_len("reset observations", observations.len(), envs * agents * obs_dim)?;
        Ok(Trainer {
            adam_actor: AdamState::new(actor.params.len()),
            adam_critic: AdamState::new(critic.params.len()),
            best_actor: actor.clone(),
            best_critic: critic.clone(),
            actor,
            critic,
            adam_steps: 0,
            iteration: 0,
            rng_actions: ChaCha20Rng::from_seed(stream_key(seed, STREAMS[1])),
            rng_minibatches: ChaCha20Rng::from_seed(stream_key(seed, STREAMS[2])),
            rng_entropy: ChaCha20Rng::from_seed(stream_key(seed, STREAMS[3])),
            observations,
            episode_return: vec![0.0; envs * agents],
            best_reward: -1000.0,
            env,
            hp,
            seed,
            batch: Batch::default(),
            work: Workspace::default(),
        })
    }

    /// Completed iterations.
    pub fn iteration(&self) -> u64 {
        self.iteration
    }

    /// The current actor.
    /// Starts from `actor` instead of the random actor [`Trainer::new`] drew: a warm start,
    /// e.g. a curriculum that continues in one fidelity an actor trained in another. Its layer
    /// sizes must be this trainer's actor's; the critic and the optimiser start fresh, as in a
    /// new training. Only before the first iteration.
    pub fn start_from(&mut self, actor: Mlp) -> Result<(), TrainError> {
        if self.iteration > 0 {
            return Err(TrainError::Hyperparameters(
                "a training starts from another actor only before its first iteration".to_owned(),
            ));
        }
        if actor.sizes() != self.actor.sizes() {
            return Err(TrainError::Hyperparameters(format!(
                "the actor to start from has layers {:?}, the network trained here {:?}",
                actor.sizes(),
                self.actor.sizes()
            )));
        }
        self.best_actor = actor.clone();
        self.actor = actor;
        Ok(())
    }

    pub fn actor(&self) -> &Mlp {
        &self.actor
    }

    /// The current critic.
    pub fn critic(&self) -> &Mlp {
        &self.critic
    }

    /// The best actor so far (SigmaRL's rule) and its `episode_reward_mean`.
    pub fn best(&self) -> (&Mlp, &Mlp, f64) {
        (&self.best_actor, &self.best_critic, self.best_reward)
    }

    /// The environment.
    pub fn env(&self) -> &E {
        &self.env
    }

    /// The hyperparameters.
    pub fn hyperparameters(&self) -> &Hyperparameters {
        &self.hp
    }

    /// Run one iteration (collect, GAE, update, log).
    pub fn iterate(&mut self) -> Result<IterationRecord, TrainError> {
        let k = self.iteration + 1;
        let lr = learning_rate(k, self.hp.n_iters, self.hp.lr, self.hp.lr_min);
        let start = Instant::now();
        let mut record = self.collect()?;
        let collected = Instant::now();
        self.compute_gae();
        let sums = self.update(lr, k > self.hp.critic_warmup_iterations);
        record.iteration = k;
        record.samples = k * self.hp.frames_per_batch as u64;
        record.lr = lr;
        let steps = (self.hp.num_epochs * self.hp.frames_per_batch / self.hp.minibatch_size).max(1) as f64;
        record.policy_loss = sums.0.objective / steps;
        record.value_loss = sums.0.critic / steps;
        record.entropy_loss = sums.0.entropy_loss / steps;
        record.clip_fraction = sums.0.clip_fraction / steps;
        record.grad_norm = sums.1 / steps;
        if record.episode_reward_mean > self.best_reward {
            self.best_reward = record.episode_reward_mean;
            self.best_actor = self.actor.clone();
            self.best_critic = self.critic.clone();
            record.best = true;
        }
        record.collect_seconds = (collected - start).as_secs_f64();
        record.update_seconds = collected.elapsed().as_secs_f64();
        self.iteration = k;
        Ok(record)
    }

    /// Step 1: collect one batch with sampled actions.
    fn collect(&mut self) -> Result<IterationRecord, TrainError> {
        let (envs, agents, d) = (self.env.num_envs(), self.env.num_agents(), self.env.obs_dim());
        let steps = self.hp.frames_per_batch / envs;
        let (nd, high) = (agents * d, self.hp.action_high);
        let b = &mut self.batch;
        b.obs.resize(envs * (steps + 1) * nd, 0.0);
        b.action.resize(envs * steps * agents * 2, 0.0);
        b.log_prob.resize(envs * steps * agents, 0.0);
        b.reward.resize(envs * steps * agents, 0.0);
        b.done.resize(envs * steps, false);
        let mut record = IterationRecord {
            iteration: 0,
            samples: 0,
            episode_reward_mean: f64::NAN,
            episodes: 0,
            reward_term_means: vec![0.0; self.env.reward_terms().len()],
            collisions: 0,
            env_resets: 0,
            agent_resets: 0,
            draws: 0,
            drawn_parameter_means: vec![0.0; self.env.randomised_parameters().len()],
            filter: self.env.filters().then(FilterCounts::default),
            follower_stopped: self.env.follows().then_some(0),
            policy_loss: 0.0,
            value_loss: 0.0,
            entropy_loss: 0.0,
            grad_norm: 0.0,
            clip_fraction: 0.0,
            lr: 0.0,
            best: false,
            collect_seconds: 0.0,
            update_seconds: 0.0,
            action_scale_means: [0.0; 2],
        };
        self.env.set_actor(&self.actor).map_err(TrainError::Environment)?;
        let (mut ended_sum, mut ended_count) = (0.0f64, 0u64);
        let mut actions = vec![0.0f32; envs * agents * 2];
        let mut log_probs = vec![0.0f32; envs * agents];
        let tape = &mut self.work.actor_tape;
        for t in 0..steps {
            for e in 0..envs {
                let at = (e * (steps + 1) + t) * nd;
                b.obs[at..at + nd].copy_from_slice(&self.observations[e * nd..(e + 1) * nd]);
            }
            self.actor.forward(&self.observations, envs * agents, tape);
            for (i, raw) in tape.output().chunks_exact(4).enumerate() {
                let p = tanh_normal::params(raw, self.hp.max_scale);
                for (sum, scale) in record.action_scale_means.iter_mut().zip(p.scale) {
                    *sum += f64::from(scale);
                }
                let eps: [f32; 2] = [
                    StandardNormal.sample(&mut self.rng_actions),
                    StandardNormal.sample(&mut self.rng_actions),
                ];
                let a = tanh_normal::sample(&p, eps, high);
                actions[2 * i..2 * i + 2].copy_from_slice(&a);
                log_probs[i] = tanh_normal::log_prob(&p, a, high).log_prob as f32;
            }
            let result = self.env.step(&actions).map_err(TrainError::Environment)?;
            check_len("step observations", result.observations.len(), envs * nd)?;
            check_len("step rewards", result.rewards.len(), envs * agents)?;
            check_len("step done flags", result.done.len(), envs)?;
            check_len(
                "reward terms",
                result.reward_term_means.len(),
                record.reward_term_means.len(),
            )?;
            for e in 0..envs {
                let et = e * steps + t;
                for n in 0..agents {
                    let (i, j) = (e * agents + n, et * agents + n);
                    b.action[2 * j..2 * j + 2].copy_from_slice(&actions[2 * i..2 * i + 2]);
                    b.log_prob[j] = log_probs[i];
                    b.reward[j] = result.rewards[i];
                    self.episode_return[i] += result.rewards[i];
                    if result.done[e] {
                        ended_sum += f64::from(self.episode_return[i]);
                        ended_count += 1;
                        self.episode_return[i] = 0.0;
                    }
                }
                b.done[et] = result.done[e];
                record.episodes += u64::from(result.done[e]);
            }
            for (sum, v) in record.reward_term_means.iter_mut().zip(&result.reward_term_means) {
                *sum += v / steps as f64;
            }
            record.collisions += result.collisions;
            if let Some(f) = &mut record.filter {
                f.changed += result.filtered;
                f.fallbacks += result.filter_fallbacks;
            }
            if let Some(stopped) = &mut record.follower_stopped {
                *stopped += result.follower_stopped;
            }
            record.env_resets += result.env_resets;
            record.agent_resets += result.agent_resets;
            if result.draws > 0 {
                check_len(
                    "drawn parameters",
                    result.drawn_parameter_sums.len(),
                    record.drawn_parameter_means.len(),
                )?;
                for (sum, v) in record
                    .drawn_parameter_means
                    .iter_mut()
                    .zip(&result.drawn_parameter_sums)
                {
                    *sum += v;
                }
                record.draws += result.draws;
            }
            self.observations = result.observations;
        }
        for e in 0..envs {
            let at = (e * (steps + 1) + steps) * nd;
            b.obs[at..at + nd].copy_from_slice(&self.observations[e * nd..(e + 1) * nd]);
        }
        if ended_count > 0 {
            record.episode_reward_mean = round2(ended_sum / ended_count as f64);
        }
        for mean in &mut record.drawn_parameter_means {
            *mean /= record.draws as f64;
        }
        for mean in &mut record.action_scale_means {
            *mean /= (steps * envs * agents) as f64;
        }
        Ok(record)
    }

    /// Step 2: values of every collected observation, then GAE per environment.
    fn compute_gae(&mut self) {
        let (envs, agents) = (self.env.num_envs(), self.env.num_agents());
        let steps = self.hp.frames_per_batch / envs;
        let b = &mut self.batch;
        let tape = &mut self.work.critic_tape;
        self.critic.forward(&b.obs, envs * (steps + 1), tape);
        b.value.clear();
        b.value.extend_from_slice(tape.output());
        b.advantage.resize(b.reward.len(), 0.0);
        b.target.resize(b.reward.len(), 0.0);
        let per_env = steps * agents;
        for e in 0..envs {
            let r = e * per_env..(e + 1) * per_env;
            gae(
                self.hp.gamma,
                self.hp.lmbda,
                &b.reward[r.clone()],
                &b.done[e * steps..(e + 1) * steps],
                &b.value[e * (steps + 1)..(e + 1) * (steps + 1)],
                &mut b.advantage[r.clone()],
                &mut b.target[r],
            );
        }
    }

    /// Step 3: the epochs of minibatch steps; returns the summed losses and gradient norms.
    /// Without `actor_learns` (the critic's warm-up) only the critic's gradient is clipped
    /// and stepped.
    fn update(&mut self, lr: f64, actor_learns: bool) -> (Losses, f64) {
        let (envs, agents, d) = (self.env.num_envs(), self.env.num_agents(), self.env.obs_dim());
        let steps = self.hp.frames_per_batch / envs;
        let (nd, mb) = (agents * d, self.hp.minibatch_size);
        let config = LossConfig {
            clip_epsilon: self.hp.clip_epsilon,
            entropy_coef: self.hp.entropy_eps,
            critic_coef: self.hp.critic_coef,
            high: self.hp.action_high,
            max_scale: self.hp.max_scale,
        };
        let mut sums = (Losses::default(), 0.0);
        let steps_per_iteration = (self.hp.num_epochs * (envs * steps / mb)) as u64;
        let warmup_steps = self.hp.critic_warmup_iterations * steps_per_iteration;
        let mut order: Vec<usize> = (0..envs * steps).collect();
        let w = &mut self.work;
        w.actor_grad.resize(self.actor.params.len(), 0.0);
        w.critic_grad.resize(self.critic.params.len(), 0.0);
        for _ in 0..self.hp.num_epochs {
            order.shuffle(&mut self.rng_minibatches);
            for chunk in order.chunks_exact(mb) {
                // Gather the minibatch (sample = env-step e * T + t).
                w.x.clear();
                w.action.clear();
                w.log_prob.clear();
                w.advantage.clear();
                w.target.clear();
                for &s in chunk {
                    let (e, t) = (s / steps, s % steps);
                    let o = (e * (steps + 1) + t) * nd;
                    w.x.extend_from_slice(&self.batch.obs[o..o + nd]);
                    let r = s * agents..(s + 1) * agents;
                    w.action
                        .extend_from_slice(&self.batch.action[2 * r.start..2 * r.end]);
                    w.log_prob.extend_from_slice(&self.batch.log_prob[r.clone()]);
                    w.advantage.extend_from_slice(&self.batch.advantage[r.clone()]);
                    w.target.extend_from_slice(&self.batch.target[r]);
                }
                w.eps.clear();
                for _ in 0..2 * mb * agents {
                    w.eps.push(StandardNormal.sample(&mut self.rng_entropy));
                }
                // Forward both networks (the critic reads the same rows as concatenations).
                // The two networks are independent until the loss: rayon overlaps them (each
                // computes exactly as alone).
                let (actor, critic) = (&self.actor, &self.critic);
                let (x, actor_tape, critic_tape) = (&w.x, &mut w.actor_tape, &mut w.critic_tape);
                rayon::join(
                    || actor.forward(x, mb * agents, actor_tape),
                    || critic.forward(x, mb, critic_tape),
                );
                w.d_raw.resize(mb * agents * 4, 0.0);
                w.d_value.resize(mb, 0.0);
                let input = LossInput {
                    action: &w.action,
                    log_prob_old: &w.log_prob,
                    advantage: &w.advantage,
                    value_target: &w.target,
                    entropy_eps: &w.eps,
                };
                let losses = ppo_loss(
                    &config,
                    w.actor_tape.output(),
                    w.critic_tape.output(),
                    &input,
                    &mut w.d_raw,
                    &mut w.d_value,
                );
                // Backward, joint clipping, one Adam step over both networks.
                let (actor_tape, critic_tape) = (&mut w.actor_tape, &mut w.critic_tape);
                let (actor_grad, critic_grad) = (&mut w.actor_grad, &mut w.critic_grad);
                let (d_raw, d_value) = (&w.d_raw, &w.d_value);
                rayon::join(
                    || actor.backward(actor_tape, d_raw, actor_grad),
                    || critic.backward(critic_tape, d_value, critic_grad),
                );
                let norm = if actor_learns {
                    clip_grad_norm(
                        &mut [&mut w.actor_grad, &mut w.critic_grad],
                        self.hp.max_grad_norm,
                    )
                } else {
                    clip_grad_norm(&mut [&mut w.critic_grad], self.hp.max_grad_norm)
                };
                self.adam_steps += 1;
                let step = self.adam_steps;
                if actor_learns {
                    // The actor's Adam counts its own steps from its first (bias correction).
                    let actor_step = step - warmup_steps;
                    self.adam_actor.step(
                        &self.hp.adam,
                        actor_step,
                        lr,
                        &mut self.actor.params,
                        &w.actor_grad,
                    );
                }
                self.adam_critic
                    .step(&self.hp.adam, step, lr, &mut self.critic.params, &w.critic_grad);
                sums.0.objective += losses.objective;
                sums.0.critic += losses.critic;
                sums.0.entropy_loss += losses.entropy_loss;
                sums.0.entropy += losses.entropy;
                sums.0.clip_fraction += losses.clip_fraction;
                sums.1 += norm;
            }
        }
        sums
    }
}

/// Layer widths `inputs, hidden..., outputs`.
pub(crate) fn layer_sizes(inputs: usize, hidden: &[usize], outputs: usize) -> Vec<usize> {
    let mut s = vec![inputs];
    s.extend(hidden);
    s.push(outputs);
    s
}

fn check_len(what: &str, found: usize, expected: usize) -> Result<(), TrainError> {
    if found == expected {
        Ok(())
    } else {
        Err(TrainError::Environment(format!(
            "{what}: {found} values, expected {expected}"
        )))
    }
}

/// Python's `round(x, 2)` (correctly rounded decimal).
fn round2(x: f64) -> f64 {
    format!("{x:.2}").parse().unwrap_or(x)
}
