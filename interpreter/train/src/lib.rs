//! `cpmx train`: a spec's `training:` section made into environments (`cpmx-env`) and a
//! learner (`cpmx-learn`), and one folder per seed with its checkpoints and learning curve.
//!
//! This crate owns the join and the files: [`TrainingSetup`] reads the section (scenario,
//! reward, algorithm, network, fidelity) and the map; [`TrainingEnv`] hands the environments
//! to the learner; [`SeedRun`] trains one seed into `<out>/<seed>/`, checkpointing every
//! iteration so that a killed run resumes to the same weights; [`trained_actors`] tells whether
//! the actors a spec's policies name were trained by its section as it stands; [`collapse`]
//! notices a training whose collisions climb back to their untrained level. Rewards, resets and PPO live in
//! the crates below; the command line (progress bar, `--jobs`, `--only`) lives in `cpmx`.
//!
//! ```text
//! let setup = TrainingSetup::prepare(&checked, "sim")?;         // one of its fidelities
//! for &seed in &setup.seeds {
//!     let (mut run, _start) = SeedRun::open(&setup, out, seed, resume, "cpmx 0.1.0")?;
//!     while run.done() < run.planned() {
//!         let record = run.iterate()?;             // a row of learning_curve.csv, files written
//!     }
//!     run.finish()?;
//! }
//! ```

pub mod collapse;
pub mod curve;
mod environment;
mod provenance;
mod seed_run;
mod setup;

pub use environment::{TrainingEnv, reward_term_names};
pub use provenance::{Provenance, trained_actors};
pub use seed_run::{RunError, RunInfo, SeedRun, Start, write_overview};
pub use setup::{SetupError, TrainingSetup};
