//! `cpmx report DIR...`: recomputes every run's metrics from its stored trajectory, merges the
//! folders (e.g. the shards of one sweep) and prints the summary, byte-identical to the summary
//! file of that format that one `cpmx run` of the whole matrix writes.

use std::path::{Path, PathBuf};

use cpmx_engine::{Experiment, folder, measure, store};
use cpmx_recording::Recording;
use cpmx_report::{Format, RunRecord, render, summarize};
use cpmx_spec::{DataPath, SpecSource};

use super::Failure;
use crate::DataArgs;

/// Options of `cpmx report`.
#[derive(Debug, clap::Args)]
pub struct ReportArgs {
    /// Run folders written by `cpmx run` (several merge, e.g. shards of one sweep).
    #[arg(required = true)]
    pub dirs: Vec<PathBuf>,
    /// Output format: markdown, csv, json or latex.
    #[arg(long, default_value = "markdown", value_parser = parse_format)]
    pub format: Format,
    /// Also write the summary files and plots into this folder.
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[command(flatten)]
    pub data: DataArgs,
}

fn parse_format(name: &str) -> Result<Format, String> {
    Format::from_name(name).ok_or_else(|| format!("`{name}`: use markdown, csv, json or latex"))
}

fn fail(message: String) -> Failure {
    eprintln!("error: {message}");
    Failure::InvalidInput
}

/// The experiment a run folder was made from (its `spec.resolved.yaml`).
fn folder_experiment(dir: &Path, data: &DataArgs) -> Result<Experiment, Failure> {
    let path = dir.join("spec.resolved.yaml");
    let source = SpecSource::read(&path).map_err(|e| fail(format!("{}: {e}", path.display())))?;
    let data_path = DataPath::new(dir, &data.data, std::env::var("CPMX_DATA").ok().as_deref());
    let checked = cpmx_spec::check(&source, &data_path, &cpmx_engine::BuildChecks).map_err(|d| {
        eprint!("{}", cpmx_spec::render(&d, false));
        Failure::InvalidInput
    })?;
    Experiment::prepare(&checked).map_err(|e| fail(format!("{}: {e}", path.display())))
}

pub fn run(args: &ReportArgs) -> Result<(), Failure> {
    let experiment = folder_experiment(&args.dirs[0], &args.data)?;
    let plans = folder::read_matrix(&args.dirs[0]).map_err(fail)?;

    // Every run of the matrix, from whichever folder holds it, measured from its trajectory.
    let mut records = Vec::new();
    let mut missing = Vec::new();
    for plan in &plans {
        let Some(dir) = args.dirs.iter().find(|d| store::finished(d, plan)) else {
            missing.push(plan.key.clone());
            continue;
        };
        let path = store::run_dir(dir, plan).join("trajectory.csv");
        let file = std::fs::File::open(&path).map_err(|e| fail(format!("{}: {e}", path.display())))?;
        let recording = Recording::read_csv(file).map_err(|e| fail(format!("{}: {e}", path.display())))?;
        let metrics =
            measure(&experiment, &recording).map_err(|e| fail(format!("{}: {e}", path.display())))?;
        records.push(RunRecord {
            plan: plan.clone(),
            metrics,
        });
    }
    if !missing.is_empty() {
        eprintln!(
            "note: {} of {} runs are not in these folders (e.g. {})",
            missing.len(),
            plans.len(),
            missing[0]
        );
    }

    let summary = summarize(&experiment.spec.name, &records, &experiment.spec.report);
    if let Some(out) = &args.out {
        folder::write_summaries(out, &experiment, &records)
            .map_err(|e| fail(format!("cannot write `{}`: {e}", out.display())))?;
    }
    print!("{}", render(&summary, args.format));
    Ok(())
}
