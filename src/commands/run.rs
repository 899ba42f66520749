//! `cpmx run SPEC`: executes the matrix (or a shard of it) into a run folder and prints the
//! summary table.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};

use cpmx_engine::{Experiment, RunOptions, RunOutcome, Shard, execute, folder};
use cpmx_report::{Format, render};
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
    /// Run only some runs, e.g. `fidelity=sim,twin` (also `policy=`, `initial_configuration=`;
    /// repeat for several axes). The folder's summaries still cover every finished run in it.
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
    /// Run into a folder made from a different spec: this spec becomes the folder's spec, and
    /// runs whose inputs it changed are left out of the summaries until they are run again.
    #[arg(long)]
    pub force: bool,
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

/// A run's value of an `--only` axis.
fn axis_value<'a>(plan: &'a cpmx_spec::RunPlan, axis: &str) -> &'a str {
    match axis {
        "fidelity" => &plan.fidelity,
        "policy" => &plan.policy,
        _ => &plan.initial_configuration,
    }
}

/// `--only AXIS=a,b` filters.
fn keep(plan: &cpmx_spec::RunPlan, only: &[(String, Vec<String>)]) -> bool {
    only.iter()
        .all(|(axis, names)| names.iter().any(|n| n == axis_value(plan, axis)))
}

/// Every name of `--only` must be one the matrix has: a typo would silently select nothing.
fn check_only_names(only: &[(String, Vec<String>)], plans: &[cpmx_spec::RunPlan]) -> Result<(), Failure> {
    for (axis, names) in only {
        let mut valid: Vec<&str> = Vec::new();
        for plan in plans {
            let value = axis_value(plan, axis);
            if !valid.contains(&value) {
                valid.push(value);
            }
        }
        for name in names {
            if !valid.contains(&name.as_str()) {
                let suggestion = cpmx_spec::schema::did_you_mean(
                    name,
                    &valid.iter().map(|v| v.to_string()).collect::<Vec<_>>(),
                )
                .map(|best| format!("did you mean `{best}`? "))
                .unwrap_or_default();
                eprintln!(
                    "error: `--only {axis}={}`: the spec has no {} `{name}`\nhelp: {suggestion}the spec's {axis}s: {}",
                    names.join(","),
                    axis.replace('_', " "),
                    valid.join(", ")
                );
                return Err(Failure::Usage);
            }
        }
    }
    Ok(())
}

/// Refuses to run into a folder made from another spec (its runs would be summarised with
/// this spec's) unless `--force`.
fn check_folder_spec(out: &Path, checked: &cpmx_spec::CheckedSpec, force: bool) -> Result<(), Failure> {
    let existing = match folder::read_resolved_spec(out) {
        Ok(text) => text,
        Err(_) if !out.join("spec.resolved.yaml").exists() => return Ok(()),
        Err(e) if force => {
            eprintln!("note: {e}; --force replaces it");
            return Ok(());
        }
        Err(e) => {
            eprintln!(
                "error: {e}\nhelp: choose another `--out`, or `--force` to make this spec the folder's spec"
            );
            return Err(Failure::Usage);
        }
    };
    let differing = folder::differing_sections(&existing, checked);
    if differing.is_empty() || force {
        if !differing.is_empty() {
            eprintln!(
                "note: `{}` was made from a different spec ({}); --force makes this spec its spec",
                out.display(),
                differing.join(", ")
            );
        }
        return Ok(());
    }
    eprintln!(
        "error: `{}` holds runs of a different spec (it differs in: {})\nhelp: choose another `--out`, or \
         `--force` to make this spec the folder's spec (runs it changes are left out of the summaries until \
         they are run again; nothing is deleted)",
        out.display(),
        differing.join(", ")
    );
    Err(Failure::Usage)
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
    if all_plans.is_empty() {
        eprintln!(
            "error: `{}` has no runs: it only trains (no policies and initial configurations)\nhelp: \
             `cpmx train` trains it; add `agents`, `policies`, `initial_configurations`, `repetitions`, `seed` \
             and `fidelities` to benchmark what it trains",
            args.spec.display()
        );
        return Err(Failure::InvalidInput);
    }
    check_only_names(&only, &all_plans)?;
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
    check_folder_spec(&out, &checked, args.force)?;
    let provenance = folder::Provenance {
        spec: std::fs::canonicalize(&args.spec).unwrap_or_else(|_| args.spec.clone()),
        data_path: data_path(&args.spec, &args.data),
    };
    folder::write_header(&out, &checked, &all_plans, &provenance).map_err(|e| io_failure(&out, e))?;

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

    // Summarise every finished run the folder holds for this spec (other shards and earlier
    // `--only` selections included), so the folder's summary is what `cpmx report` gives.
    let held = folder::read_records(&out, &all_plans, &context);
    let summary = folder::write_summaries(&out, &experiment.scoring(), &held.records)
        .map_err(|e| io_failure(&out, e))?;
    print!("{}", render(&summary, Format::Markdown));
    if !held.stale.is_empty() {
        eprintln!(
            "note: {} runs in the folder were made from an earlier spec and are left out of the summary \
             (e.g. {}); run them again with `--resume`",
            held.stale.len(),
            held.stale[0]
        );
    }
    if !held.missing.is_empty() && held.missing.len() < all_plans.len() {
        eprintln!(
            "note: the summary covers {} of the spec's {} runs; the others are not in the folder yet",
            held.records.len(),
            all_plans.len()
        );
    }
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

/// The data path of a spec as absolute folders, for `provenance.json`.
fn data_path(spec: &Path, data: &DataArgs) -> Vec<PathBuf> {
    let spec_dir = spec
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let cpmx_data = std::env::var("CPMX_DATA").ok();
    cpmx_spec::DataPath::new(spec_dir, &data.data, cpmx_data.as_deref())
        .folders
        .into_iter()
        .map(|f| std::fs::canonicalize(&f).unwrap_or(f))
        .collect()
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
