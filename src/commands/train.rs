//! `cpmx train SPEC`: one policy per seed (and per fidelity) of the spec's `training:`
//! section, into `<out>/<seed>/` (`<out>/<fidelity>/<seed>/` when it trains in several
//! fidelities; see `cpmx-train`), with a progress bar on a terminal and a summary table.

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
    /// Train only some seeds or fidelities, e.g. `seed=1,3` or `fidelity=sim-mpc`
    /// (repeatable: `--only fidelity=twin --only seed=2`).
    #[arg(long, value_name = "AXIS=NAMES")]
    pub only: Vec<String>,
    /// Worker threads (default: all cores). The weights do not depend on it.
    #[arg(long)]
    pub jobs: Option<usize>,
    /// Continue each seed from its last finished iteration (to the same weights as an
    /// uninterrupted run); seeds without a checkpoint start.
    #[arg(long)]
    pub resume: bool,
    /// Train the K-th of N deterministic slices of the training runs (`cpmx plan` lists
    /// them), e.g. `--shard 2/4`; shards into one `--out` folder give the folder one
    /// unsharded training gives.
    #[arg(long, value_name = "K/N", value_parser = super::run::parse_shard)]
    pub shard: Option<cpmx_engine::Shard>,
    #[command(flatten)]
    pub data: DataArgs,
}

/// What `--only` keeps of an axis (`seed` or `fidelity`): every value listed for it, checked
/// against the spec's (all of them when the axis is not named).
fn selected<T: Clone + PartialEq + std::fmt::Display>(
    only: &[String],
    axis: &str,
    values: &[T],
    parse: impl Fn(&str) -> Option<T>,
) -> Result<Vec<T>, Failure> {
    let listed: Vec<String> = values.iter().map(T::to_string).collect();
    let mut chosen = Vec::new();
    let mut named = false;
    for filter in only {
        let Some((name, list)) = filter.split_once('=') else {
            eprintln!(
                "error: `--only {filter}`: expected AXIS=NAMES, e.g. `--only seed=1,3` or `--only fidelity=sim`"
            );
            return Err(Failure::Usage);
        };
        if !["seed", "fidelity"].contains(&name) {
            eprintln!("error: `--only {filter}`: `cpmx train` selects by `seed` or `fidelity`");
            return Err(Failure::Usage);
        }
        if name != axis {
            continue;
        }
        named = true;
        for value in list.split(',') {
            match parse(value.trim()) {
                Some(v) if values.contains(&v) => {
                    if !chosen.contains(&v) {
                        chosen.push(v);
                    }
                }
                _ => {
                    eprintln!(
                        "error: `--only {axis}={list}`: the spec trains no {axis} `{value}`\nhelp: the spec's {}: {}",
                        if axis == "seed" { "seeds" } else { "fidelities" },
                        listed.join(", ")
                    );
                    return Err(Failure::Usage);
                }
            }
        }
    }
    Ok(if named { chosen } else { values.to_vec() })
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
    let setup_error = |e: cpmx_train::SetupError| {
        eprintln!("error: {e}");
        Failure::InvalidInput
    };
    let all_fidelities = TrainingSetup::fidelities(&checked).map_err(setup_error)?;
    let several = all_fidelities.len() > 1;
    let fidelities = selected(&args.only, "fidelity", &all_fidelities, |v| Some(v.to_owned()))?;
    // One setup per point of the section's sweeps (one point without them) and fidelity.
    let points: Vec<String> = checked.training_points.iter().map(|p| p.name.clone()).collect();
    let mut setups = Vec::new();
    for point in &points {
        for fidelity in &fidelities {
            setups.push((
                point.clone(),
                fidelity.clone(),
                TrainingSetup::prepare_at(&checked, fidelity, point).map_err(setup_error)?,
            ));
        }
    }
    let Some((_, _, first_setup)) = setups.first() else {
        return Ok(());
    };
    let seeds = selected(&args.only, "seed", &first_setup.seeds, |v| v.parse().ok())?;
    let spec_name = first_setup.spec_name.clone();
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| Path::new("out").join(format!("{spec_name}-train")));
    // A folder per point of the sweeps, then per fidelity when the spec trains in several.
    let folder = |point: &str, fidelity: &str| {
        let at = if point.is_empty() {
            out.clone()
        } else {
            out.join(point)
        };
        if several { at.join(fidelity) } else { at }
    };
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

    // Open every seed's folder before training any (of this shard: the training runs in
    // `cpmx plan`'s order, every N-th from the K-th), so that a refusal (a run that exists
    // without --resume, changed inputs, a damaged checkpoint) stops before work is done.
    let shard = args.shard.unwrap_or(cpmx_engine::Shard::WHOLE);
    let mut runs = Vec::new();
    let mut index = 0;
    for (point, fidelity, setup) in &setups {
        for &seed in &seeds {
            let mine = shard.contains(index);
            index += 1;
            if !mine {
                continue;
            }
            match SeedRun::open(
                setup,
                &folder(point, fidelity),
                seed,
                args.resume,
                &crate::made_by(),
            ) {
                Ok((run, start)) => runs.push((point.clone(), fidelity.clone(), run, start)),
                Err(e) => return Err(report_open_error(&e)),
            }
        }
    }
    if runs.is_empty() {
        // More shards than training runs (an array job of more tasks than seeds): say so,
        // instead of an empty table.
        eprintln!(
            "shard {}/{} holds none of the {index} training runs: nothing to train here (the spec \
             has fewer training runs than the array has tasks; `cpmx plan` lists them)",
            shard.index, shard.count
        );
        return Ok(());
    }
    if let Ok(text) = std::fs::read(&args.spec) {
        let _ = cpmx_engine::store::write_atomic(&out.join("spec.yaml"), &text);
    }

    let mut summary = Vec::new();
    crate::interrupt::flag();
    for (point, fidelity, mut run, start) in runs {
        let seed_started = Instant::now();
        let first = run.done();
        let mut label = if several {
            format!("{fidelity} seed {}", run_seed(&run))
        } else {
            format!("seed {}", run_seed(&run))
        };
        if !point.is_empty() {
            label = format!("{point} {label}");
        }
        match start {
            Start::Fresh => eprintln!(
                "{label}: training {} iterations into {}",
                run.planned(),
                run.dir().display()
            ),
            Start::Resumed { done } if done >= run.planned() => {
                eprintln!("{label}: already trained ({done} iterations)")
            }
            Start::Resumed { done } => {
                eprintln!("{label}: resuming after iteration {done} of {}", run.planned())
            }
        }
        let bar = progress_bar(run.planned(), first);
        let mut last_rewards: Vec<f64> = Vec::new();
        // Said once, as soon as it shows (a resumed run's curve counts from its first row).
        let mut collapse_said = false;
        while run.done() < run.planned() {
            let record = pool.install(|| run.iterate()).map_err(|e| {
                bar.abandon();
                eprintln!("error: {label}: {e}");
                Failure::InvalidInput
            })?;
            if record.episode_reward_mean.is_finite() {
                last_rewards.push(record.episode_reward_mean);
            }
            if crate::interrupt::requested() {
                bar.abandon();
                eprintln!(
                    "interrupted: {label} stopped after iteration {} of {}; its folder {} keeps \
                     every finished iteration (checkpoint, learning curve, the best actor so far).\n\
                     resume with: {}",
                    record.iteration,
                    run.planned(),
                    run.dir().display(),
                    super::run::resume_command(
                        &super::run::ResumeArgs {
                            subcommand: "train",
                            spec: &args.spec,
                            only: &args.only,
                            jobs: args.jobs,
                            shard: args.shard,
                            data: &args.data.data,
                        },
                        &out
                    )
                );
                return Err(Failure::Interrupted);
            }
            if !collapse_said && let Some(seen) = run.collapse() {
                collapse_said = true;
                bar.suspend(|| eprintln!("{}", collapse_warning(&label, &seen, &run)));
            }
            let message = format!(
                "{label}  reward {}  best {:.2}",
                show(record.episode_reward_mean),
                run.best_reward()
            );
            if bar.is_hidden() {
                // No terminal (a Slurm log, a pipe): a line per iteration once an iteration takes
                // a second or more, else every tenth, so that no stretch is silent for long.
                let iteration_s = record.collect_seconds + record.update_seconds;
                if iteration_s >= 1.0
                    || record.iteration.is_multiple_of(10)
                    || record.iteration == run.planned()
                {
                    eprintln!(
                        "  iteration {}/{}: {message}  ({:.2} s)",
                        record.iteration,
                        run.planned(),
                        iteration_s
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
        summary.push(SeedSummary {
            warning: run.collapse().map(|seen| collapse_warning(&label, &seen, &run)),
            label,
            done: run.done(),
            best: run.best_reward(),
            last_rewards,
            seconds_per_iteration: (trained > 0).then(|| seconds / trained as f64),
            dir: run.dir().to_owned(),
        });
    }
    for (point, fidelity, setup) in &setups {
        write_overview(&folder(point, fidelity), &spec_name, &setup.seeds).map_err(|e| report_io(&e))?;
    }

    println!("| run | iterations | best episode_reward_mean | mean of the last 10 | s/iteration | actor |");
    println!("|---:|---:|---:|---:|---:|---|");
    for seed in &summary {
        let tail = &seed.last_rewards[seed.last_rewards.len().saturating_sub(10)..];
        let tail_mean = (!tail.is_empty()).then(|| tail.iter().sum::<f64>() / tail.len() as f64);
        println!(
            "| {} | {} | {} | {} | {} | {} |",
            seed.label,
            seed.done,
            show(seed.best),
            tail_mean.map_or("–".into(), |m| format!("{m:.3}")),
            seed.seconds_per_iteration
                .map_or("–".into(), |s| format!("{s:.2}")),
            seed.dir.join("actor.safetensors").display()
        );
    }
    // Again after the table: a warning said mid-training scrolls away in a long log.
    for warning in summary.iter().filter_map(|seed| seed.warning.as_ref()) {
        eprintln!("{warning}");
    }
    Ok(())
}

/// A seed's line of the summary table, and its warning.
struct SeedSummary {
    label: String,
    done: u64,
    best: f64,
    /// `episode_reward_mean` of the iterations trained by this command.
    last_rewards: Vec<f64>,
    seconds_per_iteration: Option<f64>,
    dir: PathBuf,
    warning: Option<String>,
}

/// What `cpmx train` says about a collapsed training: the evidence, what it means for the
/// actor kept, and where to look.
fn collapse_warning(label: &str, seen: &cpmx_train::collapse::Collapse, run: &SeedRun) -> String {
    let best = run
        .best_iteration()
        .map_or_else(String::new, |k| format!(" (the best so far: iteration {k})"));
    format!(
        "warning: {label}: {seen}: the training has collapsed. SigmaRL's best-actor rule reads \
         `episode_reward_mean` alone, which can stay level while episodes shorten, so the actor \
         it keeps{best} may come from the collapse.\n\
         help: the `collisions` column of {} shows it; docs/training.md, \"A training that collapses\"",
        run.dir().join("learning_curve.csv").display()
    )
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
        RunError::Busy { .. } => {
            eprintln!(
                "error: {e}\nhelp: let it finish, or stop it (Ctrl-C finishes the iteration under way) and continue with `--resume`; nothing was changed here"
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
