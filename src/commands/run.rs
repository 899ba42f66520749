//! `cpmx run SPEC`: executes the matrix (or a shard of it) into a run folder and prints the
//! summary table.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

use cpmx_engine::{RunOutcome, Shard};
use cpmx_report::{Format, render};
use cpmx_session::{RunError, RunRequest};
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
    /// Also record how long each run's layers took (`safety.solve_s`: the safety filter's
    /// time over the run; `safety.largest_solve_us`: its longest step per agent). Wall-clock
    /// figures differ between machines and runs; without this flag a run folder's numbers are
    /// the same everywhere.
    #[arg(long)]
    pub timing: bool,
    #[command(flatten)]
    pub data: DataArgs,
}

pub(crate) fn parse_shard(text: &str) -> Result<Shard, String> {
    let (k, n) = text.split_once('/').ok_or("expected K/N, e.g. 1/4")?;
    let index: usize = k.trim().parse().map_err(|_| format!("`{k}` is not a number"))?;
    let count: usize = n.trim().parse().map_err(|_| format!("`{n}` is not a number"))?;
    if count == 0 || index == 0 || index > count {
        return Err(format!("K must be between 1 and N, got {index}/{count}"));
    }
    Ok(Shard { index, count })
}

pub fn run(args: &RunArgs) -> Result<(), Failure> {
    let only = cpmx_session::parse_only(&args.only).map_err(|e| session_failure(&e))?;
    let checked = load_checked(&args.spec, &args.data)?;
    // The progress bar, once there is one: the operator's messages (a lab run's preflight
    // table) and the runs' notes go above it on a terminal, else to stderr.
    let bar: Arc<OnceLock<ProgressBar>> = Arc::new(OnceLock::new());
    let operator = {
        let bar = bar.clone();
        cpmx_engine::Operator::new(move |message| say(bar.get(), message))
    };
    let request = RunRequest {
        spec_path: args.spec.clone(),
        out: args.out.clone(),
        only,
        jobs: args.jobs,
        shard: args.shard,
        resume: args.resume,
        force: args.force,
        data: args.data.data.clone(),
        stop: Some(crate::interrupt::flag()),
        operator: Some(operator),
        made_by: crate::made_by(),
        timing: args.timing,
    };

    // Policies bound from Python run only from Python.
    let plans = cpmx_session::selected_plans(&checked, &request).map_err(|e| session_failure(&e))?;
    refuse_python_policies(args, &checked, &plans)?;
    let in_shard = |shard: &Shard| (0..plans.len()).any(|i| shard.contains(i));
    if let Some(shard) = args.shard.filter(|shard| !in_shard(shard)) {
        // More shards than runs (an array job of more tasks than the matrix has runs): say so,
        // instead of a folder with an empty table.
        eprintln!(
            "shard {}/{} holds none of the matrix's {} runs: nothing to run here (the matrix has fewer \
             runs than the array has tasks; `cpmx plan` lists them)",
            shard.index,
            shard.count,
            checked.plan().len()
        );
        return Ok(());
    }

    let on_total = |total: usize| {
        let _ = bar.set(progress_bar(total as u64));
    };
    let on_done = |plan: &cpmx_spec::RunPlan, outcome: &RunOutcome| {
        let Some(bar) = bar.get() else {
            return;
        };
        match outcome {
            // Without a terminal the failures are listed at the end.
            RunOutcome::Failed(reason) if !bar.is_hidden() => {
                bar.println(format!("failed: {}: {reason}", plan.key));
            }
            RunOutcome::Finished(stored) => {
                for note in &stored.notes {
                    say(Some(bar), &format!("note: {}: {note}", plan.key));
                }
            }
            RunOutcome::Failed(_) | RunOutcome::Resumed(_) | RunOutcome::NotRun => {}
        }
        bar.inc(1);
    };
    let result = cpmx_session::run_matrix(&checked, &request, &mut |_| Ok(()), &on_total, &on_done);
    if let Some(bar) = bar.get() {
        bar.finish_and_clear();
    }
    let done = result.map_err(|e| session_failure(&e))?;
    for note in &done.notes {
        eprintln!("note: {note}");
    }
    print!("{}", render(&done.summary, Format::Markdown));
    if !done.stale.is_empty() {
        eprintln!(
            "note: {} runs in the folder were made from an earlier spec and are left out of the summary \
             (e.g. {}); run them again with `--resume`",
            done.stale.len(),
            done.stale[0]
        );
    }
    if let Some((key, reason)) = done.unreadable.first() {
        eprintln!(
            "warning: {} runs' files cannot be read and are left out of the summary (e.g. {key}: {reason}); \
             run them again with `--resume`",
            done.unreadable.len()
        );
    }
    if done.summarised > 0 && done.summarised < done.matrix_runs {
        eprintln!(
            "note: the summary covers {} of the spec's {} runs; the others are not in the folder yet",
            done.summarised, done.matrix_runs
        );
    }
    let failed = done.count(|o| matches!(o, RunOutcome::Failed(_)));
    let resumed = done.count(|o| matches!(o, RunOutcome::Resumed(_)));
    let not_run = done.count(|o| matches!(o, RunOutcome::NotRun));
    eprintln!(
        "{} runs in {}: {} run, {resumed} resumed, {failed} failed{}",
        done.outcomes.len(),
        done.out.display(),
        done.outcomes.len() - failed - resumed - not_run,
        if not_run > 0 {
            format!(", {not_run} not started")
        } else {
            String::new()
        }
    );
    if crate::interrupt::requested() {
        eprintln!(
            "interrupted: every finished run is kept in {} and its summaries cover them ({} of the \
             spec's {}); {not_run} runs were not started.\nresume with: {}",
            done.out.display(),
            done.summarised,
            done.matrix_runs,
            resume_command(
                &ResumeArgs {
                    subcommand: "run",
                    spec: &args.spec,
                    only: &args.only,
                    jobs: args.jobs,
                    shard: args.shard,
                    data: &args.data.data,
                },
                &done.out
            )
        );
        return Err(Failure::Interrupted);
    }
    if failed == 0 {
        return Ok(());
    }
    for (plan, outcome) in &done.outcomes {
        if let RunOutcome::Failed(reason) = outcome {
            eprintln!("  failed: {}: {reason}", plan.key);
        }
    }
    Err(Failure::RunsFailed)
}

/// A spec's `python: {}` policies cannot run from the command line: a located error for each
/// one the selected runs use, saying how to bind it.
fn refuse_python_policies(
    args: &RunArgs,
    checked: &cpmx_spec::CheckedSpec,
    plans: &[cpmx_spec::RunPlan],
) -> Result<(), Failure> {
    let python: Vec<_> = checked
        .spec
        .policies
        .iter()
        .enumerate()
        .filter(|(_, p)| p.python.is_some() && plans.iter().any(|r| r.policy == p.name))
        .map(|(i, p)| {
            checked.diagnostic(
                cpmx_spec::Problem::error(
                    "cpmx::policy::python",
                    format!(
                        "policy `{}` is bound from Python: the command line cannot run it",
                        p.name
                    ),
                    checked.key_span(&format!("/policies/{i}/python")),
                    "a Python callable",
                )
                .with_help(format!(
                    "run the spec from Python (`pip install ./python`): cpmx.run(\"{}\", policies={{\"{}\": \
                     callable}}); or leave the policy out here with `--only policy=...`",
                    args.spec.display(),
                    p.name
                )),
            )
        })
        .collect();
    if python.is_empty() {
        return Ok(());
    }
    eprint!("{}", cpmx_spec::render(&python, std::io::stderr().is_terminal()));
    Err(Failure::InvalidInput)
}

/// Prints a session error and gives its exit code.
pub(crate) fn session_failure(e: &RunError) -> Failure {
    match e.help() {
        Some(help) => eprintln!("error: {e}\nhelp: {help}"),
        None => eprintln!("error: {e}"),
    }
    match e {
        RunError::Usage { .. } => Failure::Usage,
        RunError::Invalid { .. } | RunError::Io { .. } => Failure::InvalidInput,
    }
}

/// The arguments a resumed `cpmx run` or `cpmx train` repeats.
pub(crate) struct ResumeArgs<'a> {
    pub subcommand: &'a str,
    pub spec: &'a Path,
    pub only: &'a [String],
    pub jobs: Option<usize>,
    pub shard: Option<Shard>,
    pub data: &'a [PathBuf],
}

/// The command that continues an interrupted one: the same arguments with `--out` and
/// `--resume`.
pub(crate) fn resume_command(args: &ResumeArgs<'_>, out: &Path) -> String {
    let mut words = vec![
        "cpmx".to_owned(),
        args.subcommand.to_owned(),
        shell_word(&args.spec.display().to_string()),
        "--out".to_owned(),
        shell_word(&out.display().to_string()),
    ];
    for only in args.only {
        words.extend(["--only".to_owned(), shell_word(only)]);
    }
    if let Some(jobs) = args.jobs {
        words.extend(["--jobs".to_owned(), jobs.to_string()]);
    }
    if let Some(shard) = args.shard {
        words.extend(["--shard".to_owned(), format!("{}/{}", shard.index, shard.count)]);
    }
    for dir in args.data {
        words.extend(["--data".to_owned(), shell_word(&dir.display().to_string())]);
    }
    words.push("--resume".to_owned());
    words.join(" ")
}

/// `word` as a POSIX shell reads it back: unquoted when it is plain, else in single quotes.
pub(crate) fn shell_word(word: &str) -> String {
    let plain = !word.is_empty()
        && word
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_./=,:@%+".contains(c));
    if plain {
        word.to_owned()
    } else {
        format!("'{}'", word.replace('\'', "'\\''"))
    }
}

/// A message above the progress bar on a terminal, else on stderr.
fn say(bar: Option<&ProgressBar>, message: &str) {
    match bar {
        Some(bar) if !bar.is_hidden() => bar.println(message),
        _ => eprintln!("{message}"),
    }
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
