//! `cpmx report DIR...`: recomputes every run's metrics from its stored trajectory, merges the
//! folders (e.g. the shards of one sweep) and prints the summary, byte-identical to the summary
//! file of that format that one `cpmx run` of the whole matrix writes. `--metrics` scores the
//! same recordings with other metric definitions, `--group-by` pools them into other rows.

use std::path::{Path, PathBuf};

use cpmx_engine::{Scoring, folder, inputs_hash, store};
use cpmx_recording::Recording;
use cpmx_report::{Format, RunRecord, render, summarize};
use cpmx_spec::model::GroupKey;
use cpmx_spec::{CheckScope, CheckedSpec, DataPath, RunPlan, SpecSource};
use rayon::prelude::*;

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
    /// Score the stored recordings with these metric definitions instead of the folder's:
    /// a preset (`stdlib:at25-paper`) or a YAML file holding a `metrics:` section's value.
    #[arg(long, value_name = "stdlib:NAME|FILE")]
    pub metrics: Option<String>,
    /// Group the summary's rows by these keys instead of the spec's `report.group_by`
    /// (comma-separated: fidelity, policy, initial_configuration), e.g. `--group-by fidelity`
    /// pools a fidelity's policies into one row and their pairs into one comparison.
    #[arg(long, value_name = "KEY,...", value_delimiter = ',', value_parser = parse_group_key)]
    pub group_by: Option<Vec<GroupKey>>,
    /// Compare every other fidelity with this one, or every other policy with this one (paired
    /// over runs that share the rest of their key), instead of the spec's
    /// `report.compare.reference`.
    #[arg(long, value_name = "FIDELITY|POLICY")]
    pub compare: Option<String>,
    #[command(flatten)]
    pub data: DataArgs,
}

fn parse_format(name: &str) -> Result<Format, String> {
    Format::from_name(name).ok_or_else(|| format!("`{name}`: use markdown, csv, json or latex"))
}

fn parse_group_key(name: &str) -> Result<GroupKey, String> {
    [
        GroupKey::Fidelity,
        GroupKey::Policy,
        GroupKey::InitialConfiguration,
    ]
    .into_iter()
    .find(|key| cpmx_report::axis_name(*key) == name)
    .ok_or_else(|| format!("`{name}`: use fidelity, policy or initial_configuration"))
}

/// The options that make the summary differ from the one the folder holds, as its title and
/// `--out`'s diagnostic say them.
fn changes(args: &ReportArgs) -> Vec<String> {
    let mut out = Vec::new();
    if let Some(metrics) = &args.metrics {
        out.push(format!("scored with --metrics {metrics}"));
    }
    if let Some(keys) = &args.group_by {
        let names: Vec<&str> = keys.iter().map(|k| cpmx_report::axis_name(*k)).collect();
        out.push(format!("grouped by {}", names.join(", ")));
    }
    if let Some(reference) = &args.compare {
        out.push(format!("compared with {reference}"));
    }
    out
}

fn fail(message: String) -> Failure {
    eprintln!("error: {message}");
    Failure::InvalidInput
}

/// A folder argument that is not a run folder: a spec file, or a folder without runs.
fn check_is_run_folder(dir: &Path) -> Result<(), Failure> {
    if dir.is_file() {
        eprintln!(
            "error: `{}` is a file; `cpmx report` takes run folders written by `cpmx run`\nhelp: run the spec \
             first (`cpmx run {}`), then report its folder (by default `out/<name>`)",
            dir.display(),
            dir.display()
        );
        return Err(Failure::Usage);
    }
    if !dir.exists() {
        eprintln!(
            "error: `{}` does not exist\nhelp: name a folder written by `cpmx run`",
            dir.display()
        );
        return Err(Failure::Usage);
    }
    if !dir.join("matrix.csv").is_file() {
        eprintln!(
            "error: `{}` is not a run folder (it has no matrix.csv)\nhelp: name a folder written by `cpmx run`",
            dir.display()
        );
        return Err(Failure::Usage);
    }
    Ok(())
}

/// Checks a resolved spec text for scoring: the folder first, then `--data`, `CPMX_DATA`, and
/// last the data path the folder was made with (files are pinned by hash).
fn check_for_scoring(
    name: String,
    text: String,
    dir: &Path,
    data: &DataArgs,
) -> Result<CheckedSpec, Failure> {
    let mut data_path = DataPath::new(dir, &data.data, std::env::var("CPMX_DATA").ok().as_deref());
    data_path.folders.extend(folder::Provenance::read(dir).data_path);
    let source = SpecSource {
        name,
        dir: dir.to_path_buf(),
        text,
    };
    cpmx_spec::check_scoped(
        &source,
        &data_path,
        &cpmx_engine::BuildChecks,
        CheckScope::Measure,
    )
    .map_err(|d| {
        eprint!("{}", cpmx_spec::render(&d, false));
        Failure::InvalidInput
    })
}

/// Every folder after the first holds runs of the first one's spec (its context hash: the
/// resolved spec but its report section and description), as the shards of one sweep do. The
/// summary follows the first folder's run matrix: another spec's runs would be left out
/// without a word.
fn check_same_spec(
    dirs: &[PathBuf],
    first_name: &str,
    context: &str,
    data: &DataArgs,
) -> Result<(), Failure> {
    let first = &dirs[0];
    for dir in &dirs[1..] {
        let path = dir.join("spec.resolved.yaml");
        let text = folder::read_resolved_spec(dir).map_err(fail)?;
        let checked = check_for_scoring(path.display().to_string(), text, dir, data)?;
        if folder::ResolvedSpec::of(&checked).context_hash() != context {
            let (what, help) = if checked.spec.name == first_name {
                (
                    format!(
                        "`{}` and `{}` hold runs of two versions of spec `{first_name}`",
                        first.display(),
                        dir.display()
                    ),
                    "run the older shard again with the current spec (`cpmx run SPEC --out DIR --shard K/N \
                     --resume --force`), or report each folder on its own"
                        .to_owned(),
                )
            } else {
                (
                    format!(
                        "`{}` holds runs of another spec than `{}` (`{}`)",
                        dir.display(),
                        first.display(),
                        checked.spec.name
                    ),
                    format!("report each folder on its own (`cpmx report {}`)", dir.display()),
                )
            };
            eprintln!(
                "error: {what}: `cpmx report` merges the folders of one spec, e.g. its shards\nhelp: {help}"
            );
            return Err(Failure::Usage);
        }
    }
    Ok(())
}

/// `--metrics` or `--group-by` write into a folder that is not one of those reported: other
/// summaries in a run folder would contradict its own `metrics.json` files and spec, and the
/// next `cpmx report` of it would give the old ones again.
fn check_out_is_not_reported(out: Option<&Path>, dirs: &[PathBuf], changes: &str) -> Result<(), Failure> {
    let Some(out) = out else {
        return Ok(());
    };
    let Ok(out_canonical) = out.canonicalize() else {
        return Ok(()); // not there yet: a new folder
    };
    if let Some(dir) = dirs
        .iter()
        .find(|d| d.canonicalize().is_ok_and(|d| d == out_canonical))
    {
        eprintln!(
            "error: `--out {}` is a folder being reported: its summaries, {changes}, would contradict its runs' \
             metrics.json and its spec\nhelp: write these summaries into another folder, e.g. `--out {}-rescored`",
            out.display(),
            dir.display()
        );
        return Err(Failure::Usage);
    }
    Ok(())
}

/// The folder's resolved spec with its `metrics` section replaced by `metrics` (a preset name
/// or a YAML file), as the text of a spec.
fn with_metrics(resolved: &serde_json::Value, metrics: &str) -> Result<String, Failure> {
    let value = if metrics.starts_with(cpmx_spec::STDLIB_PREFIX) {
        serde_json::Value::from(metrics)
    } else {
        let text =
            std::fs::read_to_string(metrics).map_err(|e| fail(format!("--metrics `{metrics}`: {e}")))?;
        serde_saphyr::from_str::<serde_json::Value>(&text)
            .map_err(|e| fail(format!("--metrics `{metrics}`: not YAML: {e}")))?
    };
    let mut spec = resolved.clone();
    if let Some(root) = spec.as_object_mut() {
        root.insert("metrics".into(), value);
    }
    // JSON is YAML: the spec checker reads it as it reads any spec.
    serde_json::to_string_pretty(&spec).map_err(|e| fail(e.to_string()))
}

pub fn run(args: &ReportArgs) -> Result<(), Failure> {
    for dir in &args.dirs {
        check_is_run_folder(dir)?;
    }

    // The folder's spec, checked against its hash, and what scores its runs.
    let first = &args.dirs[0];
    let resolved_path = first.join("spec.resolved.yaml");
    let text = folder::read_resolved_spec(first).map_err(fail)?;
    let checked = check_for_scoring(resolved_path.display().to_string(), text, first, &args.data)?;
    let context = folder::ResolvedSpec::of(&checked).context_hash();
    let mut checked = match &args.metrics {
        None => checked,
        Some(metrics) => {
            let text = with_metrics(&checked.resolved, metrics)?;
            let name = format!("{} with --metrics {metrics}", resolved_path.display());
            check_for_scoring(name, text, first, &args.data)?
        }
    };
    check_same_spec(&args.dirs, &checked.spec.name, &context, &args.data)?;
    let changes = changes(args).join(", ");
    if !changes.is_empty() {
        check_out_is_not_reported(args.out.as_deref(), &args.dirs, &changes)?;
        // The summary's title says what differs from the spec's own summary.
        checked.spec.name = format!("{} ({changes})", checked.spec.name);
    }
    if let Some(keys) = &args.group_by {
        checked.spec.report.group_by = keys.clone();
    }
    if let Some(reference) = &args.compare {
        let fidelities = checked.fidelity_points.keys().map(String::as_str);
        let policies = checked.spec.policies.iter().map(|p| p.name.as_str());
        let names: Vec<&str> = fidelities.chain(policies).collect();
        if !names.contains(&reference.as_str()) {
            eprintln!(
                "error: --compare `{reference}` is no fidelity or policy of the folder's runs\nhelp: name one of {}",
                names.join(", ")
            );
            return Err(Failure::Usage);
        }
        checked.spec.report.compare = Some(cpmx_spec::model::Compare {
            reference: reference.clone(),
            test: cpmx_spec::model::PairedTest::Paired,
        });
    }
    let scoring =
        Scoring::prepare(&checked).map_err(|e| fail(format!("{}: {e}", resolved_path.display())))?;
    let plans = folder::read_matrix(first).map_err(fail)?;

    // Every run of the matrix, from whichever folder holds it, measured from its trajectory
    // (in parallel; taken in the matrix's order, the first problem in that order reported).
    let found: Vec<Result<Found, Failure>> = plans
        .par_iter()
        .map(|plan| find_and_measure(plan, &args.dirs, &context, &scoring))
        .collect();
    let mut records = Vec::new();
    let (mut missing, mut stale, mut damaged) = (Vec::new(), Vec::new(), Vec::new());
    for found in found {
        match found? {
            Found::Measured(record) => records.push(*record),
            Found::Missing(key) => missing.push(key),
            Found::Stale(key) => stale.push(key),
            Found::Damaged(why) => damaged.push(why),
        }
    }
    if !missing.is_empty() {
        eprintln!(
            "note: {} of {} runs are not in these folders (e.g. {})",
            missing.len(),
            plans.len(),
            missing[0]
        );
    }
    if !damaged.is_empty() {
        eprintln!(
            "warning: the metrics.json of {} of {} runs cannot be read, and they are left out (e.g. {}); run \
             them again with `cpmx run SPEC --resume`",
            damaged.len(),
            plans.len(),
            damaged[0]
        );
    }
    if !stale.is_empty() {
        eprintln!(
            "note: {} runs were made from an earlier spec and are left out (e.g. {}); run them again with \
             `cpmx run SPEC --resume`",
            stale.len(),
            stale[0]
        );
    }

    if records.is_empty() {
        return Err(fail(format!(
            "nothing to report: no run of `{}` in {} is finished with its current spec",
            scoring.spec.name,
            if args.dirs.len() == 1 {
                "this folder"
            } else {
                "these folders"
            }
        )));
    }
    let summary = summarize(
        &scoring.spec.name,
        &records,
        &scoring.spec.report,
        &cpmx_report::Origins::of_spec(&scoring.spec),
    );
    if let Some(out) = &args.out {
        folder::write_summaries_from(out, &args.dirs, &scoring, &records)
            .map_err(|e| fail(format!("cannot write `{}`: {e}", out.display())))?;
    }
    print!("{}", render(&summary, args.format));
    Ok(())
}

/// What the report found of one run of the matrix.
enum Found {
    /// Finished with the current spec, and measured from its trajectory.
    Measured(Box<RunRecord>),
    /// In none of the folders.
    Missing(String),
    /// Made from an earlier spec.
    Stale(String),
    /// Its `metrics.json` is there but cannot be read (why).
    Damaged(String),
}

/// Finds `plan`'s run in the first of `dirs` that has it finished and measures it.
fn find_and_measure(
    plan: &RunPlan,
    dirs: &[PathBuf],
    context: &str,
    scoring: &Scoring,
) -> Result<Found, Failure> {
    let Some(dir) = dirs.iter().find(|d| store::finished(d, plan)) else {
        // A metrics.json that is there but cannot be read is not a run never made.
        return Ok(
            match dirs.iter().find_map(|d| {
                let run = store::run_dir(d, plan);
                run.join("metrics.json")
                    .is_file()
                    .then(|| store::read_stored(&run).err())?
            }) {
                Some(why) => Found::Damaged(why),
                None => Found::Missing(plan.key.clone()),
            },
        );
    };
    let run = store::run_dir(dir, plan);
    let stored = store::read_stored(&run).map_err(fail)?;
    if stored.inputs_hash != inputs_hash(context, plan) {
        return Ok(Found::Stale(plan.key.clone()));
    }
    let path = run.join("trajectory.csv");
    let bytes = std::fs::read(&path).map_err(|e| fail(format!("{}: {e}", path.display())))?;
    let recording =
        Recording::read_csv(bytes.as_slice()).map_err(|e| fail(format!("{}: {e}", path.display())))?;
    let metrics = scoring
        .measure_in(plan, &recording)
        .map_err(|e| fail(format!("{}: {e}", path.display())))?;
    Ok(Found::Measured(Box::new(RunRecord {
        plan: plan.clone(),
        metrics,
        recording_sha256: folder::sha256_hex(&bytes),
        drawn_parameters: stored.drawn_parameters,
        statistics: stored.statistics,
    })))
}
