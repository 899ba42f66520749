//! One seed's training run and its folder `<out>/<seed>/`:
//!
//! | file | what |
//! |---|---|
//! | `actor.safetensors` | the best actor by SigmaRL's rule (an `mlp: {weights}` file) |
//! | `actor.last.safetensors` | the actor of the last finished iteration |
//! | `actors/<iteration>.safetensors` | the actor of every `keep_actors_every`th iteration |
//! | `critic.safetensors` | the critic of the last finished iteration |
//! | `checkpoint.safetensors` | networks, Adam's moments, environments, random streams |
//! | `learning_curve.csv`, `learning_curve.svg` | a row per iteration (see `curve`) and its chart |
//! | `run.json` | seed, fingerprint of the inputs, iterations done and planned, commit |
//!
//! Invariants: every file is replaced atomically (written beside, then renamed), and the
//! checkpoint is written last in an iteration, so a kill at any moment leaves a folder that
//! `--resume` continues to exactly the weights of an uninterrupted run (rows of the curve
//! after the checkpoint's iteration are dropped and computed again). A folder is never
//! continued with inputs whose fingerprint differs from the one it was started with.

use std::fs;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use cpmx_learn::{Environment as _, IterationRecord, TrainError, Trainer};
use cpmx_spec::model::KeptActors;

use crate::collapse::{self, Collapse};
use crate::curve;
use crate::environment::{TrainingEnv, reward_term_names};
use crate::setup::TrainingSetup;

/// Errors of a seed's run; none of them removes or damages a file of the folder.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The folder already holds a run of this seed and `--resume` was not given.
    #[error(
        "`{}` already holds seed {seed}'s training ({done} of {planned} iterations)",
        dir.display()
    )]
    Exists {
        dir: PathBuf,
        seed: u64,
        done: u64,
        planned: u64,
    },
    /// The folder's run was started with other inputs.
    #[error(
        "`{}` was trained from a different training section, vehicle, timing or map (fingerprint {found}, \
         this spec's {expected})",
        dir.display()
    )]
    Changed {
        dir: PathBuf,
        found: String,
        expected: String,
    },
    /// A checkpoint without the `run.json` that says what it was trained from.
    #[error("`{}` holds a checkpoint without its run.json: what it was trained from is unknown", dir.display())]
    Unknown { dir: PathBuf },
    /// The checkpoint cannot be continued.
    #[error("`{}`: {source}", path.display())]
    Checkpoint { path: PathBuf, source: TrainError },
    /// The learner failed.
    #[error(transparent)]
    Train(#[from] TrainError),
    /// The environment could not be built.
    #[error("the training scenario: {0}")]
    Environment(#[from] cpmx_env::ConfigError),
    /// A file could not be read or written.
    #[error("`{}`: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },
    /// Another process is training the seed in this folder (it holds the folder's lock).
    #[error(
        "`{}` is being trained by another `cpmx train` (it holds `{LOCK_FILE}` there): two writers would mix their iterations",
        dir.display()
    )]
    Busy { dir: PathBuf },
}

/// The file whose lock a seed's run holds while it writes the folder (an advisory lock, released
/// when the process ends, however it ends).
const LOCK_FILE: &str = ".lock";

/// Takes the lock of seed folder `dir` (creating the folder), or says who holds it.
fn lock_folder(dir: &Path) -> Result<fs::File, RunError> {
    let io = |source| RunError::Io {
        path: dir.to_path_buf(),
        source,
    };
    fs::create_dir_all(dir).map_err(io)?;
    let file = fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(dir.join(LOCK_FILE))
        .map_err(io)?;
    match file.try_lock() {
        Ok(()) => Ok(file),
        Err(fs::TryLockError::WouldBlock) => Err(RunError::Busy {
            dir: dir.to_path_buf(),
        }),
        Err(fs::TryLockError::Error(source)) => Err(io(source)),
    }
}

/// Where a run stands when its folder is opened.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Start {
    /// No checkpoint: training starts at iteration 1.
    Fresh,
    /// Continued after this many finished iterations.
    Resumed { done: u64 },
}

/// What `run.json` records.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RunInfo {
    /// The spec's name.
    pub spec: String,
    /// The training seed.
    pub seed: u64,
    /// SHA-256 of the inputs that shape the weights ([`TrainingSetup::fingerprint`]).
    pub fingerprint: String,
    /// Iterations finished (those of the checkpoint).
    pub iterations_done: u64,
    /// Iterations the spec plans.
    pub iterations_planned: u64,
    /// SigmaRL's best `episode_reward_mean` so far, and the iteration it was reached at.
    pub best_episode_reward_mean: Option<f64>,
    pub best_iteration: Option<u64>,
    /// The version of cpmx that made the folder and, when known, the git commit it was built
    /// from; a resumed run lists every build that contributed iterations.
    pub made_by: Vec<String>,
}

/// A seed's training run bound to its folder.
pub struct SeedRun {
    trainer: Trainer<TrainingEnv>,
    dir: PathBuf,
    info: RunInfo,
    /// Rows of the curve so far (header first), kept to rewrite the SVG.
    curve_text: String,
    /// The collapse rule fed every row of the curve ([`crate::collapse`]).
    collapse_watch: collapse::Watch,
    /// The iterations whose actors are kept in `actors/` (`keep_actors_every`).
    kept_actors: KeptActors,
    /// The folder's lock, held for as long as the run is open.
    _lock: fs::File,
}

impl SeedRun {
    /// Opens (`resume`) or starts seed `seed`'s run in `<out>/<seed>/`. `made_by` names the
    /// build (version and commit).
    pub fn open(
        setup: &TrainingSetup,
        out: &Path,
        seed: u64,
        resume: bool,
        made_by: &str,
    ) -> Result<(SeedRun, Start), RunError> {
        let dir = out.join(seed.to_string());
        let checkpoint_path = dir.join("checkpoint.safetensors");
        let planned = setup.hyperparameters.n_iters;
        let env = TrainingEnv::new(setup.env.clone(), &setup.paths, seed)?;
        let header = curve::header(
            &reward_term_names(&setup.env.reward),
            &setup.randomised_parameters(),
            setup.env.safety.is_some(),
            env.follows(),
        );
        // Before the folder is read: what it holds is then this process's alone.
        let lock = lock_folder(&dir)?;
        let previous: Option<RunInfo> = fs::read(dir.join("run.json"))
            .ok()
            .and_then(|bytes| serde_json::from_slice(&bytes).ok());
        if checkpoint_path.is_file() {
            let done = previous.as_ref().map_or(0, |i| i.iterations_done);
            if !resume {
                return Err(RunError::Exists {
                    dir,
                    seed,
                    done,
                    planned,
                });
            }
            let Some(mut info) = previous else {
                return Err(RunError::Unknown { dir });
            };
            let expected = setup.fingerprint(seed).unwrap_or_default();
            if info.fingerprint != expected {
                return Err(RunError::Changed {
                    dir,
                    found: info.fingerprint.clone(),
                    expected: expected.to_owned(),
                });
            }
            let bytes = read(&checkpoint_path)?;
            let trainer = Trainer::resume(env, setup.hyperparameters.clone(), &bytes).map_err(|source| {
                RunError::Checkpoint {
                    path: checkpoint_path.clone(),
                    source,
                }
            })?;
            let done = trainer.iteration();
            let old_curve = fs::read_to_string(dir.join("learning_curve.csv")).unwrap_or_default();
            let mut curve_text = curve::rows_through(&old_curve, done, header).join("\n");
            curve_text.push('\n');
            info.iterations_done = done;
            info.iterations_planned = planned;
            // The checkpoint may be one iteration ahead of run.json: its best comes from the curve.
            if let Some((iteration, reward)) = curve::last_best(&curve_text) {
                info.best_iteration = Some(iteration);
                info.best_episode_reward_mean = Some(reward);
            }
            if info.made_by.last().map(String::as_str) != Some(made_by) {
                info.made_by.push(made_by.to_owned());
            }
            let mut collapse_watch = collapse::Watch::default();
            for (iteration, collisions) in curve::column_points(&curve_text, "collisions") {
                collapse_watch.push(iteration, collisions);
            }
            let run = SeedRun {
                trainer,
                dir,
                info,
                curve_text,
                collapse_watch,
                kept_actors: setup.kept_actors,
                _lock: lock,
            };
            write_atomic(&run.dir.join("learning_curve.csv"), run.curve_text.as_bytes())?;
            return Ok((run, Start::Resumed { done }));
        }
        let mut trainer = Trainer::new(env, setup.hyperparameters.clone(), seed)?;
        if let Some(actor) = setup.initial_actors.get(&seed) {
            trainer.start_from(actor.clone())?;
        }
        let mut info = new_info(setup, seed);
        info.made_by.push(made_by.to_owned());
        let run = SeedRun {
            trainer,
            dir,
            info,
            curve_text: format!("{header}\n"),
            collapse_watch: collapse::Watch::default(),
            kept_actors: setup.kept_actors,
            _lock: lock,
        };
        // run.json first: a checkpoint is never without it.
        run.write_info()?;
        write_atomic(&run.dir.join("learning_curve.csv"), run.curve_text.as_bytes())?;
        write_atomic(&run.dir.join("actor.safetensors"), &run.trainer.best_actor_file())?;
        Ok((run, Start::Fresh))
    }

    /// Iterations finished.
    pub fn done(&self) -> u64 {
        self.trainer.iteration()
    }

    /// Iterations planned.
    pub fn planned(&self) -> u64 {
        self.info.iterations_planned
    }

    /// The run's folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// SigmaRL's best `episode_reward_mean` so far (-1000 before any episode ended).
    pub fn best_reward(&self) -> f64 {
        self.trainer.best().2
    }

    /// The iteration whose actor is the best so far (none before any episode ended).
    pub fn best_iteration(&self) -> Option<u64> {
        self.info.best_iteration
    }

    /// The first collapse of the learning curve so far ([`crate::collapse`]).
    pub fn collapse(&self) -> Option<Collapse> {
        self.collapse_watch.collapse()
    }

    /// One iteration, then its files: the curve's row, the actors and critic, the
    /// checkpoint, `run.json` (and the chart every 10 iterations and at the end).
    pub fn iterate(&mut self) -> Result<IterationRecord, RunError> {
        let record = self.trainer.iterate()?;
        let row = curve::row(&record);
        self.curve_text.push_str(&row);
        self.curve_text.push('\n');
        self.collapse_watch
            .push(record.iteration as f64, record.collisions as f64);
        append_line(&self.dir.join("learning_curve.csv"), &row)?;
        let actor = self.trainer.actor_file();
        write_atomic(&self.dir.join("actor.last.safetensors"), &actor)?;
        if self.kept_actors.keeps(record.iteration) {
            let kept = self.dir.join("actors");
            fs::create_dir_all(&kept).map_err(|source| RunError::Io {
                path: kept.clone(),
                source,
            })?;
            write_atomic(&kept.join(format!("{}.safetensors", record.iteration)), &actor)?;
        }
        write_atomic(&self.dir.join("critic.safetensors"), &self.trainer.critic_file())?;
        if record.best {
            write_atomic(
                &self.dir.join("actor.safetensors"),
                &self.trainer.best_actor_file(),
            )?;
            self.info.best_episode_reward_mean = Some(record.episode_reward_mean);
            self.info.best_iteration = Some(record.iteration);
        }
        write_atomic(
            &self.dir.join("checkpoint.safetensors"),
            &self.trainer.checkpoint(),
        )?;
        self.info.iterations_done = record.iteration;
        self.write_info()?;
        if record.iteration.is_multiple_of(10) || record.iteration == self.planned() {
            self.write_chart()?;
        }
        Ok(record)
    }

    /// Writes the chart and `run.json` (also when the run stops before its plan).
    pub fn finish(&self) -> Result<(), RunError> {
        self.write_chart()?;
        self.write_info()
    }

    fn write_info(&self) -> Result<(), RunError> {
        let mut text = serde_json::to_string_pretty(&self.info).expect("plain data");
        text.push('\n');
        write_atomic(&self.dir.join("run.json"), text.as_bytes())
    }

    fn write_chart(&self) -> Result<(), RunError> {
        let series = [curve::Series {
            name: format!("seed {}", self.info.seed),
            points: curve::reward_points(&self.curve_text),
        }];
        let title = format!("{}: seed {}", self.info.spec, self.info.seed);
        write_atomic(
            &self.dir.join("learning_curve.svg"),
            curve::svg(&title, &series).as_bytes(),
        )
    }
}

fn new_info(setup: &TrainingSetup, seed: u64) -> RunInfo {
    RunInfo {
        spec: setup.spec_name.clone(),
        seed,
        fingerprint: setup.fingerprint(seed).unwrap_or_default().to_owned(),
        iterations_done: 0,
        iterations_planned: setup.hyperparameters.n_iters,
        best_episode_reward_mean: None,
        best_iteration: None,
        made_by: Vec::new(),
    }
}

/// The learning curves of every seed folder under `out` as one chart (`learning_curves.svg`).
pub fn write_overview(out: &Path, spec_name: &str, seeds: &[u64]) -> Result<(), RunError> {
    let series: Vec<curve::Series> = seeds
        .iter()
        .filter_map(|seed| {
            let text = fs::read_to_string(out.join(seed.to_string()).join("learning_curve.csv")).ok()?;
            Some(curve::Series {
                name: format!("seed {seed}"),
                points: curve::reward_points(&text),
            })
        })
        .collect();
    write_atomic(
        &out.join("learning_curves.svg"),
        curve::svg(&format!("{spec_name}: episode_reward_mean"), &series).as_bytes(),
    )
}

fn read(path: &Path) -> Result<Vec<u8>, RunError> {
    fs::read(path).map_err(|source| RunError::Io {
        path: path.to_owned(),
        source,
    })
}

/// Replaces `path` with `bytes` atomically (`cpmx-engine`'s store: a temporary file, then a
/// rename).
fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), RunError> {
    cpmx_engine::store::write_atomic(path, bytes).map_err(|source| RunError::Io {
        path: path.to_owned(),
        source,
    })
}

fn append_line(path: &Path, line: &str) -> Result<(), RunError> {
    let io = |source| RunError::Io {
        path: path.to_owned(),
        source,
    };
    let mut file = fs::OpenOptions::new().append(true).open(path).map_err(io)?;
    writeln!(file, "{line}").map_err(io)
}
