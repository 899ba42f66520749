//! Running a spec's matrix (or the part `--only` and `--shard` select) into a run folder:
//! refusing names the matrix lacks and folders of another spec, preparing the experiment,
//! executing, and summarising every finished run the folder holds for the spec, so that the
//! folder's summary is what `cpmx report` gives.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use cpmx_engine::{Experiment, Operator, RunOptions, RunOutcome, Shard, execute, folder};
use cpmx_report::Summary;
use cpmx_spec::{CheckedSpec, RunPlan};

/// `--only AXIS=a,b`: the runs whose value of `axis` is one of `names`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Only {
    /// `fidelity`, `policy` or `initial_configuration`.
    pub axis: String,
    pub names: Vec<String>,
}

/// The axes `--only` selects on.
pub const ONLY_AXES: [&str; 3] = ["fidelity", "policy", "initial_configuration"];

/// Reads `--only` arguments (`AXIS=a,b`).
pub fn parse_only(only: &[String]) -> Result<Vec<Only>, RunError> {
    only.iter()
        .map(|o| match o.split_once('=') {
            Some((axis, names)) if ONLY_AXES.contains(&axis) => Ok(Only {
                axis: axis.to_owned(),
                names: names.split(',').map(str::to_owned).collect(),
            }),
            _ => Err(RunError::Usage {
                message: format!(
                    "`--only {o}`: expected fidelity=..., policy=... or initial_configuration=..."
                ),
                help: None,
            }),
        })
        .collect()
}

/// The plural of an `--only` axis, for messages.
fn plural(axis: &str) -> String {
    match axis {
        "policy" => "policies".to_owned(),
        "fidelity" => "fidelities".to_owned(),
        other => format!("{}s", other.replace('_', " ")),
    }
}

/// Whether `name` of `--only` selects the run whose axis value is `value`: the name itself, or,
/// for a fidelity, every point of a swept fidelity by its name (`twin` selects `twin@delay_ms=80`).
fn selects(axis: &str, name: &str, value: &str) -> bool {
    name == value || (axis == "fidelity" && value.split_once('@').is_some_and(|(base, _)| base == name))
}

/// What to run and where.
#[derive(Debug, Clone, Default)]
pub struct RunRequest {
    /// The spec file (recorded in the folder's `provenance.json`).
    pub spec_path: PathBuf,
    /// The run folder; default `out/<name>`.
    pub out: Option<PathBuf>,
    pub only: Vec<Only>,
    /// Worker threads; default all cores.
    pub jobs: Option<usize>,
    pub shard: Option<Shard>,
    /// Skip runs stored with unchanged inputs.
    pub resume: bool,
    /// Make this spec the folder's spec even if another made it.
    pub force: bool,
    /// The data path's folders given with the request (before `CPMX_DATA`).
    pub data: Vec<PathBuf>,
    /// Set to start no further run (Ctrl-C); runs under way finish and are kept (a lab run
    /// stops its vehicles and ends as interrupted).
    pub stop: Option<Arc<AtomicBool>>,
    /// Where lab runs tell the operator what they wait for (the preflight's table).
    pub operator: Option<Operator>,
    /// The build that runs (`cpmx 0.1.0 (commit 09b1a77)`), recorded in `provenance.json`.
    pub made_by: String,
    /// Also record how long the layers took (wall clock: not the same on another machine).
    pub timing: bool,
}

/// Why a matrix could not be run; nothing was run (runs that fail are outcomes, not this).
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The request does not fit the spec (exit 2 on the command line).
    #[error("{message}")]
    Usage { message: String, help: Option<String> },
    /// The spec's inputs cannot be used (exit 1).
    #[error("{message}")]
    Invalid { message: String, help: Option<String> },
    /// The run folder cannot be written.
    #[error("cannot write the run folder `{path}`: {source}")]
    Io { path: PathBuf, source: std::io::Error },
}

impl RunError {
    /// The help line, when there is one.
    pub fn help(&self) -> Option<&str> {
        match self {
            RunError::Usage { help, .. } | RunError::Invalid { help, .. } => help.as_deref(),
            RunError::Io { .. } => None,
        }
    }
}

/// What a run of the matrix did.
#[derive(Debug)]
pub struct MatrixRun {
    /// The run folder.
    pub out: PathBuf,
    /// Runs of the whole matrix.
    pub matrix_runs: usize,
    /// The selected runs, in matrix order, with what became of each.
    pub outcomes: Vec<(RunPlan, RunOutcome)>,
    /// The summary of every finished run the folder holds for this spec.
    pub summary: Summary,
    /// Finished runs the summary covers.
    pub summarised: usize,
    /// Keys of runs in the folder made from an earlier spec (left out of the summary).
    pub stale: Vec<String>,
    /// Runs whose files cannot be read, with the reason: left out of the summary.
    pub unreadable: Vec<(String, String)>,
    /// Notes for the user (e.g. that `--force` replaced the folder's spec).
    pub notes: Vec<String>,
}

impl MatrixRun {
    /// How many outcomes satisfy `which`.
    pub fn count(&self, which: fn(&RunOutcome) -> bool) -> usize {
        self.outcomes.iter().filter(|(_, o)| which(o)).count()
    }
}

/// The runs `request` selects from the spec's matrix: every name of `--only` must be one
/// the matrix has (a typo would silently select nothing).
pub fn selected_plans(checked: &CheckedSpec, request: &RunRequest) -> Result<Vec<RunPlan>, RunError> {
    let all = checked.plan();
    if all.is_empty() {
        return Err(RunError::Invalid {
            message: format!(
                "`{}` has no runs: it only trains (no policies and initial configurations)",
                request.spec_path.display()
            ),
            help: Some(
                "`cpmx train` trains it; add `agents`, `policies`, `initial_configurations`, \
                 `repetitions`, `seed` and `fidelities` to benchmark what it trains"
                    .into(),
            ),
        });
    }
    for only in &request.only {
        let mut valid: Vec<&str> = Vec::new();
        for plan in &all {
            let value = axis_value(plan, &only.axis);
            if !valid.contains(&value) {
                valid.push(value);
            }
        }
        for name in &only.names {
            if valid.iter().any(|v| selects(&only.axis, name, v)) {
                continue;
            }
            let suggestion = cpmx_spec::schema::did_you_mean(
                name,
                &valid.iter().map(|v| v.to_string()).collect::<Vec<_>>(),
            )
            .map(|best| format!("did you mean `{best}`? "))
            .unwrap_or_default();
            return Err(RunError::Usage {
                message: format!(
                    "`--only {}={}`: the spec has no {} `{name}`",
                    only.axis,
                    only.names.join(","),
                    only.axis.replace('_', " ")
                ),
                help: Some(format!(
                    "{suggestion}the spec's {}: {}",
                    plural(&only.axis),
                    valid.join(", ")
                )),
            });
        }
    }
    Ok(all
        .into_iter()
        .filter(|p| {
            request.only.iter().all(|o| {
                o.names
                    .iter()
                    .any(|n| selects(&o.axis, n, axis_value(p, &o.axis)))
            })
        })
        .collect())
}

/// A run's value of an `--only` axis.
fn axis_value<'a>(plan: &'a RunPlan, axis: &str) -> &'a str {
    match axis {
        "fidelity" => &plan.fidelity,
        "policy" => &plan.policy,
        _ => &plan.initial_configuration,
    }
}

/// Runs what `request` selects of the checked spec into its folder. `bind` may complete the
/// experiment before anything runs (the Python package binds its callables there);
/// `on_total` hears how many runs this call executes, `on_done` each one as it finishes.
pub fn run_matrix(
    checked: &CheckedSpec,
    request: &RunRequest,
    bind: &mut dyn FnMut(&mut Experiment) -> Result<(), String>,
    on_total: &dyn Fn(usize),
    on_done: &(dyn Fn(&RunPlan, &RunOutcome) + Sync),
) -> Result<MatrixRun, RunError> {
    let all_plans = checked.plan();
    let plans = selected_plans(checked, request)?;

    // Refuse fidelities this build cannot run before doing anything.
    for (name, point) in &checked.fidelity_points {
        let fidelity = &point.fidelity;
        if plans.iter().any(|p| &p.fidelity == name)
            && let Err(e) = cpmx_engine::engine_for(name, fidelity)
        {
            return Err(RunError::Invalid {
                message: e.to_string(),
                help: Some("leave it out with `--only fidelity=...`".into()),
            });
        }
    }

    // Prepare the experiment, bind what is bound from outside, and open the folder.
    let mut experiment = Experiment::prepare(checked).map_err(|e| RunError::Invalid {
        message: e.to_string(),
        help: None,
    })?;
    bind(&mut experiment).map_err(|message| RunError::Invalid { message, help: None })?;
    if let Some(unbound) = experiment
        .unbound()
        .into_iter()
        .find(|name| plans.iter().any(|p| p.policy == *name))
    {
        return Err(RunError::Invalid {
            message: format!(
                "policy `{unbound}` is bound from Python (`python: {{}}`) and nothing was bound to it"
            ),
            help: Some(format!(
                "pass it: cpmx.run(spec, policies={{\"{unbound}\": callable}})"
            )),
        });
    }
    if let Some((policy, seed)) = experiment
        .not_trained()
        .into_iter()
        .find(|(name, _)| plans.iter().any(|p| p.policy == *name))
    {
        return Err(RunError::Invalid {
            message: format!(
                "policy `{policy}` names the actor trained with seed {seed}, which was not found"
            ),
            help: Some(format!(
                "run `cpmx train` first, or leave it out with `--only policy=...` (the other policies than `{policy}`)"
            )),
        });
    }
    let out = request
        .out
        .clone()
        .unwrap_or_else(|| Path::new("out").join(&checked.spec.name));
    let mut notes = Vec::new();
    let resolved = folder::ResolvedSpec::of(checked);
    check_folder_spec(&out, &resolved, request.force, &mut notes)?;
    let mut made_by = folder::Provenance::read(&out).made_by;
    if made_by.last() != Some(&request.made_by) {
        made_by.push(request.made_by.clone());
    }
    let provenance = folder::Provenance {
        spec: std::fs::canonicalize(&request.spec_path).unwrap_or_else(|_| request.spec_path.clone()),
        data_path: data_path(&request.spec_path, &request.data),
        made_by,
    };
    let io = |e| RunError::Io {
        path: out.clone(),
        source: e,
    };
    folder::write_header(&out, checked, &resolved, &all_plans, &provenance).map_err(io)?;

    // Run.
    let shard = request.shard.unwrap_or(Shard::WHOLE);
    let jobs = request
        .jobs
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    on_total(
        plans
            .iter()
            .enumerate()
            .filter(|(i, _)| shard.contains(*i))
            .count(),
    );
    let options = RunOptions {
        jobs,
        shard,
        resume: request.resume,
        stop: request.stop.clone(),
        operator: request.operator.clone(),
        timing: request.timing,
    };
    let context = resolved.context_hash();
    let fresh = cpmx_engine::FreshRuns::default();
    let outcomes = execute(&experiment, &plans, &out, &options, &context, &fresh, on_done).map_err(|e| {
        RunError::Invalid {
            message: format!("cannot start {jobs} worker threads: {e}"),
            help: None,
        }
    })?;

    // Summarise every finished run the folder holds for this spec (other shards and earlier
    // `--only` selections included), so the folder's summary is what `cpmx report` gives.
    let held = folder::read_records(&out, &all_plans, &context, &fresh);
    // On the runs' number of threads too (the figures of the runs are drawn in parallel).
    let summary = match rayon::ThreadPoolBuilder::new().num_threads(jobs.max(1)).build() {
        Ok(pool) => {
            pool.install(|| folder::write_summaries(&out, &experiment.scoring(), &held.records, &fresh))
        }
        Err(_) => folder::write_summaries(&out, &experiment.scoring(), &held.records, &fresh),
    }
    .map_err(io)?;
    Ok(MatrixRun {
        out,
        matrix_runs: all_plans.len(),
        outcomes,
        summary,
        summarised: held.records.len(),
        stale: held.stale,
        unreadable: held.unreadable,
        notes,
    })
}

/// Refuses to run into a folder made from another spec (its runs would be summarised with
/// this spec's) unless `force`.
fn check_folder_spec(
    out: &Path,
    resolved: &folder::ResolvedSpec,
    force: bool,
    notes: &mut Vec<String>,
) -> Result<(), RunError> {
    let existing = match folder::read_resolved_spec(out) {
        Ok(text) => text,
        Err(_) if !out.join("spec.resolved.yaml").exists() => return Ok(()),
        Err(e) if force => {
            notes.push(format!("{e}; --force replaces it"));
            return Ok(());
        }
        Err(e) => {
            return Err(RunError::Usage {
                message: e.to_string(),
                help: Some("choose another `--out`, or `--force` to make this spec the folder's spec".into()),
            });
        }
    };
    let differing = resolved.differing_sections(&existing);
    if differing.is_empty() {
        return Ok(());
    }
    if force {
        notes.push(format!(
            "`{}` was made from a different spec ({}); --force makes this spec its spec",
            out.display(),
            differing.join(", ")
        ));
        return Ok(());
    }
    Err(RunError::Usage {
        message: format!(
            "`{}` holds runs of a different spec (it differs in: {})",
            out.display(),
            differing.join(", ")
        ),
        help: Some(
            "choose another `--out`, or `--force` to make this spec the folder's spec (runs it \
             changes are left out of the summaries until they are run again; nothing is deleted)"
                .into(),
        ),
    })
}

/// The data path of a spec as absolute folders, for `provenance.json`.
fn data_path(spec: &Path, data: &[PathBuf]) -> Vec<PathBuf> {
    let spec_dir = spec
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let cpmx_data = std::env::var("CPMX_DATA").ok();
    cpmx_spec::DataPath::new(spec_dir, data, cpmx_data.as_deref())
        .folders
        .into_iter()
        .map(|f| std::fs::canonicalize(&f).unwrap_or(f))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_swept_fidelity_selects_its_points() {
        let only = parse_only(&["fidelity=twin@latency_ms=0+drop_probability=0.1,sim".to_owned()]).unwrap();
        assert_eq!(only[0].names, ["twin@latency_ms=0+drop_probability=0.1", "sim"]);
        assert!(selects("fidelity", "twin", "twin@delay_ms=80"));
        assert!(selects("fidelity", "twin@delay_ms=80", "twin@delay_ms=80"));
        assert!(!selects("fidelity", "twin", "twin-v2v@delay_ms=80"));
        assert!(!selects("policy", "twin", "twin@delay_ms=80"));
        assert_eq!(plural("fidelity"), "fidelities");
        assert_eq!(plural("initial_configuration"), "initial configurations");
    }
}
