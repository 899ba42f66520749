//! The trainer end to end on a toy task: agents on a line must drive to the origin. It
//! learns within a few iterations, gives the same bits with 1 and 2 threads, and a resumed
//! run ends with the same checkpoint as an uninterrupted one.

use cpmx_learn::{Environment, Hyperparameters, StepResult, Trainer};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha20Rng;

/// `envs` environments of 2 agents at positions in [-1, 1] m; action 0 is the speed (m/s,
/// 0.1 s steps), action 1 is ignored. Reward: 10 x the distance to the origin gained this
/// step. Episodes last 16 steps; observations are both agents' positions, own first.
struct Line {
    envs: usize,
    x: Vec<f32>,
    steps: Vec<u32>,
    rng: ChaCha20Rng,
}

const AGENTS: usize = 2;
const EPISODE: u32 = 16;

impl Line {
    fn new(envs: usize) -> Self {
        Line {
            envs,
            x: vec![0.0; envs * AGENTS],
            steps: vec![0; envs],
            rng: ChaCha20Rng::seed_from_u64(99),
        }
    }

    fn observations(&self) -> Vec<f32> {
        let mut obs = Vec::new();
        for e in 0..self.envs {
            for n in 0..AGENTS {
                obs.extend([self.x[e * AGENTS + n], self.x[e * AGENTS + 1 - n]]);
            }
        }
        obs
    }

    fn reset(&mut self, e: usize) {
        for n in 0..AGENTS {
            self.x[e * AGENTS + n] = self.rng.random_range(-1.0..1.0);
        }
        self.steps[e] = 0;
    }
}

impl Environment for Line {
    fn num_envs(&self) -> usize {
        self.envs
    }
    fn num_agents(&self) -> usize {
        AGENTS
    }
    fn obs_dim(&self) -> usize {
        2
    }
    fn reward_terms(&self) -> Vec<String> {
        vec!["progress".into()]
    }
    fn reset_all(&mut self) -> Vec<f32> {
        for e in 0..self.envs {
            self.reset(e);
        }
        self.observations()
    }
    fn step(&mut self, actions: &[f32]) -> Result<StepResult, String> {
        let mut result = StepResult::default();
        let mut progress = 0.0f64;
        for e in 0..self.envs {
            for n in 0..AGENTS {
                let i = e * AGENTS + n;
                let before = self.x[i].abs();
                self.x[i] += 0.1 * actions[2 * i];
                let r = 10.0 * (before - self.x[i].abs());
                result.rewards.push(r);
                progress += f64::from(r);
            }
            self.steps[e] += 1;
            let done = self.steps[e] >= EPISODE;
            if done {
                self.reset(e);
                result.env_resets += 1;
            }
            result.done.push(done);
        }
        result.reward_term_means = vec![progress / (self.envs * AGENTS) as f64];
        result.observations = self.observations();
        Ok(result)
    }
    fn save_state(&self) -> Vec<u8> {
        let mut bytes: Vec<u8> = self.x.iter().flat_map(|v| v.to_le_bytes()).collect();
        bytes.extend(self.steps.iter().flat_map(|v| v.to_le_bytes()));
        bytes.extend(self.rng.get_word_pos().to_le_bytes());
        bytes
    }
    fn load_state(&mut self, state: &[u8]) -> Result<(), String> {
        let n = self.envs * AGENTS;
        if state.len() != 4 * n + 4 * self.envs + 16 {
            return Err(format!("{} bytes of state", state.len()));
        }
        let word = |i: usize| [state[4 * i], state[4 * i + 1], state[4 * i + 2], state[4 * i + 3]];
        self.x = (0..n).map(|i| f32::from_le_bytes(word(i))).collect();
        self.steps = (0..self.envs).map(|e| u32::from_le_bytes(word(n + e))).collect();
        let pos = u128::from_le_bytes(state[state.len() - 16..].try_into().unwrap());
        self.rng.set_word_pos(pos);
        Ok(())
    }
}

fn hyperparameters() -> Hyperparameters {
    Hyperparameters {
        frames_per_batch: 8 * 32,
        num_epochs: 4,
        minibatch_size: 64,
        lr: 3e-3,
        lr_min: 3e-4,
        actor_hidden: vec![32, 32],
        critic_hidden: vec![32, 32],
        ..Hyperparameters::sigmarl(20)
    }
}

#[test]
fn the_toy_task_is_learned_in_a_few_iterations() {
    let mut trainer = Trainer::new(Line::new(8), hyperparameters(), 1).unwrap();
    let rewards: Vec<f64> = (0..12)
        .map(|_| trainer.iterate().unwrap().episode_reward_mean)
        .collect();
    eprintln!("episode_reward_mean per iteration: {rewards:?}");
    let first = (rewards[0] + rewards[1]) / 2.0;
    let last = (rewards[10] + rewards[11]) / 2.0;
    // Driving straight to the origin earns about 5 per agent; a random policy about 0.
    assert!(last > first + 1.5 && last > 2.0, "{first} -> {last}");
    // The best actor loads as an inference actor with the same layout.
    let actor = cpmx_policy::MlpActor::from_bytes_inferred(&trainer.best_actor_file(), "actor").unwrap();
    assert_eq!((actor.input_size(), actor.output_size()), (2, 4));
}

fn run(threads: usize, iterations: usize) -> Vec<u8> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let mut trainer = Trainer::new(Line::new(8), hyperparameters(), 5).unwrap();
        for _ in 0..iterations {
            trainer.iterate().unwrap();
        }
        trainer.checkpoint()
    })
}

/// A checkpoint's content independent of the header's key order: metadata and every
/// tensor's bytes, by name.
type Content = (Vec<(String, String)>, Vec<(String, Vec<u8>)>);

fn content(bytes: &[u8]) -> Content {
    let (_, header) = safetensors::SafeTensors::read_metadata(bytes).unwrap();
    let mut meta: Vec<(String, String)> = header.metadata().clone().unwrap().into_iter().collect();
    meta.sort();
    let tensors = safetensors::SafeTensors::deserialize(bytes).unwrap();
    let mut data: Vec<(String, Vec<u8>)> = tensors
        .iter()
        .map(|(n, v)| (n.to_owned(), v.data().to_vec()))
        .collect();
    data.sort();
    (meta, data)
}

/// Names of the tensors or metadata that differ (not their bytes: they are long).
fn differences(a: &[u8], b: &[u8]) -> Vec<String> {
    let (ca, cb) = (content(a), content(b));
    let mut out: Vec<String> =
        ca.0.iter()
            .zip(&cb.0)
            .filter(|(x, y)| x != y)
            .map(|(x, y)| format!("{x:?} vs {y:?}"))
            .collect();
    out.extend(
        ca.1.iter()
            .zip(&cb.1)
            .filter(|(x, y)| x != y)
            .map(|(x, _)| x.0.clone()),
    );
    if ca.1.len() != cb.1.len() {
        out.push("tensor count".into());
    }
    out
}

#[test]
fn one_and_two_threads_give_the_same_bits() {
    let diff = differences(&run(1, 2), &run(2, 2));
    assert!(diff.is_empty(), "{diff:?}");
}

#[test]
fn a_resumed_run_ends_where_an_uninterrupted_one_does() {
    let straight = run(1, 4);
    let half = run(1, 2);
    let mut resumed = Trainer::resume(Line::new(8), hyperparameters(), &half).unwrap();
    assert_eq!(resumed.iteration(), 2);
    resumed.iterate().unwrap();
    resumed.iterate().unwrap();
    let diff = differences(&resumed.checkpoint(), &straight);
    assert!(diff.is_empty(), "{diff:?}");

    // Bad checkpoints are errors, not panics.
    let truncated = &half[..half.len() / 2];
    assert!(Trainer::resume(Line::new(8), hyperparameters(), truncated).is_err());
    let other = Hyperparameters {
        lr: 1e-3,
        ..hyperparameters()
    };
    let err = Trainer::resume(Line::new(8), other, &half).err().unwrap();
    assert!(err.to_string().contains("different hyperparameters"), "{err}");
}

#[test]
fn bad_hyperparameters_are_rejected() {
    let bad = Hyperparameters {
        lr: -1e-4,
        ..hyperparameters()
    };
    let err = Trainer::new(Line::new(8), bad, 1).err().unwrap();
    assert_eq!(
        err.to_string(),
        "invalid training hyperparameters: lr must be positive, got -0.0001"
    );
    let bad = Hyperparameters {
        minibatch_size: 60,
        ..hyperparameters()
    };
    assert!(Trainer::new(Line::new(8), bad, 1).is_err());
}

#[test]
fn a_training_started_from_a_trained_actor_starts_where_it_left_off() {
    // Ten iterations learn the toy task; a new training started from that actor (another seed,
    // so another random actor it replaces) earns from its first iteration what the first
    // earned at its end, while a random start earns what the first did at its start.
    let mut first = Trainer::new(Line::new(8), hyperparameters(), 1).unwrap();
    let rewards: Vec<f64> = (0..10)
        .map(|_| first.iterate().unwrap().episode_reward_mean)
        .collect();
    let trained = first.actor().clone();
    let mut warm = Trainer::new(Line::new(8), hyperparameters(), 2).unwrap();
    warm.start_from(trained.clone()).unwrap();
    assert_eq!(warm.actor(), &trained);
    let warm_first = warm.iterate().unwrap().episode_reward_mean;
    let cold_first = Trainer::new(Line::new(8), hyperparameters(), 2)
        .unwrap()
        .iterate()
        .unwrap()
        .episode_reward_mean;
    assert!(
        warm_first > cold_first + 1.0 && warm_first > rewards[0] + 1.0,
        "warm {warm_first}, cold {cold_first}, the first training {rewards:?}"
    );
    // Only before the first iteration, and only an actor of the same layout.
    let error = warm.start_from(trained).unwrap_err().to_string();
    assert!(error.contains("only before its first iteration"), "{error}");
    let mut other = Trainer::new(Line::new(8), hyperparameters(), 3).unwrap();
    let wrong = Trainer::new(
        Line::new(8),
        Hyperparameters {
            actor_hidden: vec![16],
            ..hyperparameters()
        },
        3,
    )
    .unwrap()
    .actor()
    .clone();
    let error = other.start_from(wrong).unwrap_err().to_string();
    assert!(
        error.contains("has layers [2, 16, 4], the network trained here [2, 32, 32, 4]"),
        "{error}"
    );
}

#[test]
fn a_critic_warm_up_trains_the_critic_while_the_actor_only_collects() {
    let warmup = Hyperparameters {
        critic_warmup_iterations: 2,
        ..hyperparameters()
    };
    let mut trainer = Trainer::new(Line::new(8), warmup.clone(), 1).unwrap();
    let (actor, critic) = (trainer.actor().clone(), trainer.critic().clone());
    for _ in 0..2 {
        trainer.iterate().unwrap();
    }
    assert_eq!(trainer.actor(), &actor, "the actor moved during the warm-up");
    assert_ne!(
        trainer.critic(),
        &critic,
        "the critic did not learn during the warm-up"
    );
    trainer.iterate().unwrap();
    assert_ne!(
        trainer.actor(),
        &actor,
        "the actor does not learn after the warm-up"
    );
    // A warm-up as long as the training leaves the actor nothing: refused.
    let whole = Hyperparameters {
        critic_warmup_iterations: 20,
        ..hyperparameters()
    };
    let error = Trainer::new(Line::new(8), whole, 1).err().unwrap().to_string();
    assert!(
        error.contains("critic_warmup_iterations 20 leaves none of the 20 iterations"),
        "{error}"
    );
}

#[test]
fn a_bounded_noise_scale_never_exceeds_its_bound() {
    // A fresh actor's scale is about 1 (raw output 0); bounded at 0.3, every sample's noise is
    // at most 0.3, so the iteration's mean scale is too, while the unbounded one is not.
    let bounded = Hyperparameters {
        max_scale: 0.3,
        ..hyperparameters()
    };
    let mut trainer = Trainer::new(Line::new(8), bounded, 1).unwrap();
    for _ in 0..3 {
        let record = trainer.iterate().unwrap();
        assert!(
            record.action_scale_means.iter().all(|&s| s <= 0.3 + 1e-7),
            "{:?}",
            record.action_scale_means
        );
    }
    let mut free = Trainer::new(Line::new(8), hyperparameters(), 1).unwrap();
    let record = free.iterate().unwrap();
    assert!(
        record.action_scale_means.iter().any(|&s| s > 0.5),
        "{:?}",
        record.action_scale_means
    );
}
