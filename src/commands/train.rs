//! `cpmx train SPEC`: one policy per seed of the spec's `training:` section, into
//! `<out>/<seed>/` (see `cpmx-train`), with a progress bar on a terminal and a summary table.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

use cpmx_train::{RunError, SeedRun, Start, TrainingSetup, write_overview};
use indicatif::{ProgressBar, ProgressStyle};

use super::{Failure, load_checked_for};
use crate::DataArgs;

/// Options of `cpmx train`.
#[derive(Debug, clap::Args)]
pub struct TrainArgs {
    /// The spec file (its `training:` section).
    pub spec: PathBuf,
    /// The training folder. Default: `out/<name>-train`.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Train only some seeds, e.g. `seed=1,3`.
    #[arg(long, value_name = "seed=SEEDS")]
    pub only: Option<String>,
    /// Worker threads (default: all cores). The weights do not depend on it.
    #[arg(long)]
    pub jobs: Option<usize>,
    /// Continue each seed from its last finished iteration (to the same weights as an
    /// uninterrupted run); seeds without a checkpoint start.
    #[arg(long)]
    pub resume: bool,
    #[command(flatten)]
    pub data: DataArgs,
}

/// The build that trains: version and commit.
fn made_by() -> String {
    match option_env!("CPMX_COMMIT") {
        Some(commit) if !commit.is_empty() => {
            format!("cpmx {} (commit {commit})", env!("CARGO_PKG_VERSION"))
        }
        _ => format!("cpmx {}", env!("CARGO_PKG_VERSION")),
    }
}

/// The seeds `--only seed=...` keeps, checked against the spec's.
fn selected_seeds(only: Option<&str>, seeds: &[u64]) -> Result<Vec<u64>, Failure> {
    let Some(only) = only else {
        return Ok(seeds.to_vec());
    };
    let listed: Vec<String> = seeds.iter().map(u64::to_string).collect();
    let Some(("seed", values)) = only.split_once('=') else {
        eprintln!("error: `--only {only}`: expected seed=..., e.g. `--only seed=1,3`");
        return Err(Failure::Usage);
    };
    let mut chosen = Vec::new();
    for value in values.split(',') {
        match value.trim().parse::<u64>() {
            Ok(seed) if seeds.contains(&seed) => {
                if !chosen.contains(&seed) {
                    chosen.push(seed);
                }
            }
            _ => {
                eprintln!(
                    "error: `--only seed={values}`: the spec trains no seed `{value}`\nhelp: the spec's seeds: {}",
                    listed.join(", ")
                );
                return Err(Failure::Usage);
            }
        }
    }
    Ok(chosen)
}

pub fn run(args: &TrainArgs) -> Result<(), Failure> {
    // Training needs the map and the training section, not the weights of evaluated policies;
    // the actors it is about to train are naturally not there yet, and what the run matrix's
    // repetitions will be is not its concern.
    let checked = load_checked_for(
        &args.spec,
        &args.data,
        cpmx_spec::CheckScope::Measure,
        &[
            "cpmx::check::not-trained",
            "cpmx::check::deterministic-repetitions",
        ],
    )?;
    let setup = TrainingSetup::prepare(&checked).map_err(|e| {
        eprintln!("error: {e}");
        Failure::InvalidInput
    })?;
    let seeds = selected_seeds(args.only.as_deref(), &setup.seeds)?;
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| Path::new("out").join(format!("{}-train", setup.spec_name)));
    let jobs = args
        .jobs
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    if jobs == 0 {
        eprintln!("error: `--jobs 0`: at least one worker thread is needed");
        return Err(Failure::Usage);
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs)
        .build()
        .map_err(|e| {
            eprintln!("error: cannot start {jobs} worker threads: {e}");
            Failure::InvalidInput
        })?;

    // Open every seed's folder before training any, so that a refusal (a run that exists
    // without --resume, changed inputs, a damaged checkpoint) stops before work is done.
    let mut runs = Vec::new();
    for &seed in &seeds {
        match SeedRun::open(&setup, &out, seed, args.resume, &made_by()) {
            Ok(run) => runs.push(run),
            Err(e) => return Err(report_open_error(&e)),
        }
    }
    if let Ok(text) = std::fs::read(&args.spec) {
        let _ = cpmx_engine::store::write_atomic(&out.join("spec.yaml"), &text);
    }

    let mut summary = Vec::new();
    for (mut run, start) in runs {
        let seed_started = Instant::now();
        let first = run.done();
        match start {
            Start::Fresh => eprintln!(
                "seed {}: training {} iterations into {}",
                run_seed(&run),
                run.planned(),
                run.dir().display()
            ),
            Start::Resumed { done } if done >= run.planned() => {
                eprintln!("seed {}: already trained ({done} iterations)", run_seed(&run))
            }
            Start::Resumed { done } => eprintln!(
                "seed {}: resuming after iteration {done} of {}",
                run_seed(&run),
                run.planned()
            ),
        }
        let bar = progress_bar(run.planned(), first);
        let mut last_rewards: Vec<f64> = Vec::new();
        while run.done() < run.planned() {
            let record = pool.install(|| run.iterate()).map_err(|e| {
                bar.abandon();
                eprintln!("error: seed {}: {e}", run_seed(&run));
                Failure::InvalidInput
            })?;
            if record.episode_reward_mean.is_finite() {
                last_rewards.push(record.episode_reward_mean);
            }
            let message = format!(
                "seed {}  reward {}  best {:.2}",
                run_seed(&run),
                show(record.episode_reward_mean),
                run.best_reward()
            );
            if bar.is_hidden() {
                if record.iteration.is_multiple_of(10) || record.iteration == run.planned() {
                    eprintln!(
                        "  iteration {}/{}: {message}  ({:.2} s)",
                        record.iteration,
                        run.planned(),
                        record.collect_seconds + record.update_seconds
                    );
                }
            } else {
                bar.set_message(message);
                bar.set_position(record.iteration);
            }
        }
        bar.finish_and_clear();
        run.finish().map_err(|e| report_io(&e))?;
        let trained = run.done() - first;
        let seconds = seed_started.elapsed().as_secs_f64();
        summary.push((
            run_seed(&run),
            run.done(),
            run.best_reward(),
            last_rewards,
            (trained > 0).then(|| seconds / trained as f64),
            run.dir().to_owned(),
        ));
    }
    write_overview(&out, &setup.spec_name, &setup.seeds).map_err(|e| report_io(&e))?;

    println!("| seed | iterations | best episode_reward_mean | mean of the last 10 | s/iteration | actor |");
    println!("|---:|---:|---:|---:|---:|---|");
    for (seed, done, best, rewards, per_iteration, dir) in summary {
        let tail = &rewards[rewards.len().saturating_sub(10)..];
        let tail_mean = (!tail.is_empty()).then(|| tail.iter().sum::<f64>() / tail.len() as f64);
        println!(
            "| {seed} | {done} | {} | {} | {} | {} |",
            show(best),
            tail_mean.map_or("–".into(), |m| format!("{m:.3}")),
            per_iteration.map_or("–".into(), |s| format!("{s:.2}")),
            dir.join("actor.safetensors").display()
        );
    }
    Ok(())
}

fn run_seed(run: &SeedRun) -> String {
    run.dir()
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
}

fn show(v: f64) -> String {
    if v.is_finite() && v > -1000.0 {
        format!("{v:.2}")
    } else {
        "–".into()
    }
}

fn report_open_error(e: &RunError) -> Failure {
    match e {
        RunError::Exists { .. } => {
            eprintln!(
                "error: {e}\nhelp: `--resume` continues it (to the same weights as an uninterrupted run); \
                 `--out DIR` trains into another folder"
            );
            Failure::Usage
        }
        RunError::Changed { .. } | RunError::Unknown { .. } => {
            eprintln!(
                "error: {e}\nhelp: train the changed spec into another folder with `--out DIR`; nothing was changed here"
            );
            Failure::Usage
        }
        _ => {
            eprintln!("error: {e}\nhelp: the folder was left as it was");
            Failure::InvalidInput
        }
    }
}

fn report_io(e: &RunError) -> Failure {
    eprintln!("error: {e}");
    Failure::InvalidInput
}

fn progress_bar(planned: u64, done: u64) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(planned);
    bar.set_position(done);
    bar.reset_eta();
    if let Ok(style) = ProgressStyle::with_template("{bar:30} {pos}/{len} it  {msg}  {elapsed} (eta {eta})") {
        bar.set_style(style);
    }
    bar
}
