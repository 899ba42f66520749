//! The learner of `cpmx train`: SigmaRL's MAPPO (`training_setup.md` sections 4-8) over any
//! vectorised multi-agent [`Environment`].
//!
//! This crate owns the networks' training (an f32 MLP with forward, backward and per-tensor
//! gradients on `cpmx-kernels`' blocked FMA products and dense layer, `mlp`), the action distribution with its
//! gradients (`tanh_normal`), GAE and the clipped PPO loss (`ppo`), Adam, joint gradient
//! clipping and the learning-rate schedule (`optim`), the trainer loop (`trainer`) and its
//! files (`checkpoint`). It knows nothing of vehicles, maps, rewards or specs: the scenario is
//! an [`Environment`].
//!
//! # How `cpmx train` uses it
//! ```text
//! let hp = Hyperparameters { ..Hyperparameters::sigmarl(n_iters) };   // from the spec
//! let mut trainer = match resume_bytes {
//!     Some(bytes) => Trainer::resume(env, hp, &bytes)?,
//!     None => Trainer::new(env, hp, run_seed)?,
//! };
//! while trainer.iteration() < n_iters {
//!     let record = trainer.iterate()?;            // one row of learning_curve.csv
//!     write(actor_last.safetensors, trainer.actor_file());
//!     if record.best { write(actor.safetensors, trainer.best_actor_file()); }
//!     write(checkpoint.safetensors, trainer.checkpoint());
//! }
//! ```
//! Rayon's current pool (`--jobs`) speeds up the matrix products; numbers do not depend on it.

pub mod checkpoint;
pub mod env;
pub mod hyperparameters;
pub mod mlp;
pub mod optim;
pub mod ppo;
pub mod tanh_normal;
pub mod trainer;

pub use checkpoint::network_file;
pub use env::{Environment, StepResult};
pub use mlp::{Mlp, Tape};
pub use optim::{AdamConfig, AdamState, clip_grad_norm, learning_rate};
pub use ppo::{LossConfig, LossInput, Losses, gae, ppo_loss};
pub use trainer::{FilterCounts, Hyperparameters, IterationRecord, TrainError, Trainer, stream_key};
