//! `cpmx run SPEC`: executes the matrix (or a shard of it) into a run folder and prints the
//! summary table.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use cpmx_engine::{Experiment, RunOptions, RunOutcome, Shard, execute, folder};
use cpmx_report::{Format, RunRecord, render};
use indicatif::{ProgressBar, ProgressStyle};

use super::{Failure, load_checked};
use crate::DataArgs;

/// Options of `cpmx run`.
#[derive(Debug, clap::Args)]
pub struct RunArgs {
    /// The spec file.
    pub spec: PathBuf,
    /// The run folder. Default: `out/<name>`.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Run only some runs, e.g. `fidelity=sim,twin` (also `policy=`, `initial_configuration=`).
    #[arg(long, value_name = "AXIS=NAMES")]
    pub only: Vec<String>,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long)]
    pub jobs: Option<usize>,
    /// Run the K-th of N deterministic slices of the matrix, e.g. `--shard 2/4`.
    #[arg(long, value_name = "K/N", value_parser = parse_shard)]
    pub shard: Option<Shard>,
    /// Skip runs already stored in the folder with unchanged inputs.
    #[arg(long)]
    pub resume: bool,
    #[command(flatten)]
    pub data: DataArgs,
}

fn parse_shard(text: &str) -> Result<Shard, String> {
    let (k, n) = text.split_once('/').ok_or("expected K/N, e.g. 1/4")?;
    let index: usize = k.trim().parse().map_err(|_| format!("`{k}` is not a number"))?;
    let count: usize = n.trim().parse().map_err(|_| format!("`{n}` is not a number"))?;
    if count == 0 || index == 0 || index > count {
        return Err(format!("K must be between 1 and N, got {index}/{count}"));
    }
    Ok(Shard { index, count })
}

/// `--only AXIS=a,b` filters.
fn keep(plan: &cpmx_spec::RunPlan, only: &[(String, Vec<String>)]) -> bool {
    only.iter().all(|(axis, names)| {
        let value = match axis.as_str() {
            "fidelity" => &plan.fidelity,
            "policy" => &plan.policy,
            _ => &plan.initial_configuration,
        };
        names.iter().any(|n| n == value)
    })
}

fn parse_only(only: &[String]) -> Result<Vec<(String, Vec<String>)>, Failure> {
    only.iter()
        .map(|o| match o.split_once('=') {
            Some((axis, names)) if ["fidelity", "policy", "initial_configuration"].contains(&axis) => {
                Ok((axis.to_owned(), names.split(',').map(str::to_owned).collect()))
            }
            _ => {
                eprintln!(
                    "error: `--only {o}`: expected fidelity=..., policy=... or initial_configuration=..."
                );
                Err(Failure::Usage)
            }
        })
        .collect()
}

pub fn run(args: &RunArgs) -> Result<(), Failure> {
    let only = parse_only(&args.only)?;
    let checked = load_checked(&args.spec, &args.data)?;
    let all_plans = checked.plan();
    let plans: Vec<_> = all_plans.iter().filter(|p| keep(p, &only)).cloned().collect();

    // Refuse fidelities this build cannot run before doing anything.
    for (name, fidelity) in &checked.spec.fidelities {
        if plans.iter().any(|p| &p.fidelity == name)
            && let Err(e) = cpmx_engine::engine_for(name, fidelity)
        {
            eprintln!("error: {e}\nhelp: leave it out with `--only fidelity=...`");
            return Err(Failure::InvalidInput);
        }
    }

    // Prepare the experiment and the folder.
    let experiment = Experiment::prepare(&checked).map_err(|e| {
        eprintln!("error: {e}");
        Failure::InvalidInput
    })?;
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| Path::new("out").join(&checked.spec.name));
    folder::write_header(&out, &checked, &all_plans).map_err(|e| io_failure(&out, e))?;

    // Run.
    let shard = args.shard.unwrap_or(Shard::WHOLE);
    let jobs = args
        .jobs
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let total = plans
        .iter()
        .enumerate()
        .filter(|(i, _)| shard.contains(*i))
        .count();
    let bar = progress_bar(total as u64);
    let on_done = |plan: &cpmx_spec::RunPlan, outcome: &RunOutcome| {
        match outcome {
            RunOutcome::Failed(reason) => bar.println(format!("failed: {}: {reason}", plan.key)),
            RunOutcome::Finished(stored) => {
                for note in &stored.notes {
                    bar.println(format!("note: {}: {note}", plan.key));
                }
            }
            RunOutcome::Resumed(_) => {}
        }
        bar.inc(1);
    };
    let options = RunOptions {
        jobs,
        shard,
        resume: args.resume,
    };
    let context = folder::context_hash(&checked);
    let outcomes = execute(&experiment, &plans, &out, &options, &context, &on_done).map_err(|e| {
        eprintln!("error: cannot start {jobs} worker threads: {e}");
        Failure::InvalidInput
    })?;
    bar.finish_and_clear();

    // Summarise everything the folder holds for this matrix (other shards included).
    let (records, _missing) = folder::read_records(&out, &all_plans);
    let records: Vec<RunRecord> = records.into_iter().filter(|r| keep(&r.plan, &only)).collect();
    let summary = folder::write_summaries(&out, &experiment, &records).map_err(|e| io_failure(&out, e))?;
    print!("{}", render(&summary, Format::Markdown));
    let failed: Vec<_> = outcomes
        .iter()
        .filter(|(_, o)| matches!(o, RunOutcome::Failed(_)))
        .collect();
    let resumed = outcomes
        .iter()
        .filter(|(_, o)| matches!(o, RunOutcome::Resumed(_)))
        .count();
    eprintln!(
        "{} runs in {}: {} run, {resumed} resumed, {} failed",
        outcomes.len(),
        out.display(),
        outcomes.len() - failed.len() - resumed,
        failed.len()
    );
    if failed.is_empty() {
        Ok(())
    } else {
        for (plan, outcome) in failed {
            if let RunOutcome::Failed(reason) = outcome {
                eprintln!("  failed: {}: {reason}", plan.key);
            }
        }
        Err(Failure::RunsFailed)
    }
}

fn io_failure(out: &Path, e: std::io::Error) -> Failure {
    eprintln!("error: cannot write the run folder `{}`: {e}", out.display());
    Failure::InvalidInput
}

fn progress_bar(total: u64) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(total);
    if let Ok(style) = ProgressStyle::with_template("{bar:40} {pos}/{len} runs  {elapsed} (eta {eta})") {
        bar.set_style(style);
    }
    bar
}
