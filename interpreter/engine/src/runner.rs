//! Executing a run matrix: the runs of a shard in parallel (rayon, `--jobs` threads), each
//! engine run followed by its metrics and stored at once, finished runs skipped on `--resume`.
//! Results come back in matrix order whatever the thread count, so tables are identical.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::SendError;
use std::sync::{Arc, Mutex};

use cpmx_metrics::{PathGeometry, RunMetrics, evaluate};
use cpmx_recording::Recording;
use cpmx_spec::RunPlan;
use cpmx_spec::model::{DrawnFidelity, Fidelity};
use rayon::prelude::*;
use sha2::{Digest, Sha256};

use crate::engine::{Operator, RunError, RunInputs, engine_for};
use crate::experiment::Experiment;
use crate::fresh::FreshRuns;
use crate::groups::lockstep_groups;
use crate::pipeline::pipelined;
use crate::store::{
    EARLIER_RECORDING, Failure, StoredRun, finished_run, run_dir, store_failure, store_run, write_atomic,
};

/// A slice of the matrix: runs whose index `i` (0-based, matrix order) has `i % count == index - 1`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// 1-based.
    pub index: usize,
    pub count: usize,
}

impl Shard {
    pub const WHOLE: Shard = Shard { index: 1, count: 1 };

    pub fn contains(&self, run_index: usize) -> bool {
        run_index % self.count == self.index - 1
    }
}

/// How to execute.
#[derive(Debug, Clone)]
pub struct RunOptions {
    pub jobs: usize,
    pub shard: Shard,
    pub resume: bool,
    /// Set (by a Ctrl-C handler) to start no further run: the runs under way finish and are
    /// stored, the others come back [`RunOutcome::NotRun`]. A lab run under way stops its
    /// vehicles and ends as interrupted, keeping what it recorded.
    pub stop: Option<Arc<AtomicBool>>,
    /// Where lab runs tell the operator what they wait for (the preflight's table).
    pub operator: Option<Operator>,
    /// Also record how long the layers took (the safety filter's solve time): wall-clock
    /// figures, which differ between machines and runs, so off by default.
    pub timing: bool,
}

/// What became of one run.
#[derive(Debug)]
pub enum RunOutcome {
    Finished(Box<StoredRun>),
    /// Skipped by `--resume`: stored earlier with the same inputs.
    Resumed(Box<StoredRun>),
    Failed(String),
    /// Not started: execution was stopped (`RunOptions::stop`) before its turn.
    NotRun,
}

/// Runs `plans` (already filtered by `--only`) and stores each into `out`; `on_done` is called
/// as runs finish (for a progress bar).
///
/// A finished run is stored by writer threads beside the `jobs` threads that compute (see
/// [`pipelined`]): its files are formatted, written and `fsync`ed while the next run
/// computes. A run counts as done (`on_done`, its outcome) when its `metrics.json` is in
/// place; the writers have stored every finished run when this returns, Ctrl-C included (the
/// runs under way finish and are stored). What they stored goes into `fresh` too, for the
/// folder's summaries.
pub fn execute(
    experiment: &Experiment,
    plans: &[RunPlan],
    out: &Path,
    options: &RunOptions,
    context_hash: &str,
    fresh: &FreshRuns,
    on_done: &(dyn Fn(&RunPlan, &RunOutcome) + Sync),
) -> Result<Vec<(RunPlan, RunOutcome)>, rayon::ThreadPoolBuildError> {
    let selected: Vec<&RunPlan> = plans
        .iter()
        .enumerate()
        .filter(|(i, _)| options.shard.contains(*i))
        .map(|(_, p)| p)
        .collect();
    let jobs = options.jobs.max(1);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(jobs).build()?;
    // Fidelities whose lab did not answer: their later runs fail at once instead of waiting
    // for the same timeout again.
    let silent: Mutex<BTreeSet<String>> = Mutex::new(BTreeSet::new());
    let store = |run: ToStore<'_>| {
        let outcome = match store_run(out, run.plan, &run.recording, &run.stored) {
            Ok(trajectory_sha256) => {
                fresh.insert(&run.plan.key, trajectory_sha256, *run.recording);
                RunOutcome::Finished(run.stored)
            }
            Err(e) => RunOutcome::Failed(format!("cannot store the run: {e}")),
        };
        on_done(run.plan, &outcome);
        (run.index, outcome)
    };
    let groups = lockstep_groups(experiment, &selected, jobs);
    let (computed, stored): (Vec<Vec<Settled>>, _) = pipelined(jobs + 1, store, |to_writer| {
        pool.install(|| {
            groups
                .par_iter()
                .map(|group| {
                    let runs: Vec<(usize, &RunPlan)> = group.iter().map(|&i| (i, selected[i])).collect();
                    execute_group(experiment, &runs, out, options, context_hash, &silent)
                        .into_iter()
                        .map(|(index, plan, computed)| {
                            let outcome = match computed {
                                Computed::Outcome(outcome) => outcome,
                                Computed::Finished { recording, stored } => {
                                    let run = ToStore {
                                        index,
                                        plan,
                                        recording,
                                        stored,
                                    };
                                    // Sending fails only when the writers are gone (one panicked).
                                    match to_writer.send(run) {
                                        Ok(()) => return (index, None),
                                        Err(SendError(run)) => return (index, Some(store(run).1)),
                                    }
                                }
                            };
                            on_done(plan, &outcome);
                            (index, Some(outcome))
                        })
                        .collect()
                })
                .collect()
        })
    });
    let mut outcomes: Vec<Option<RunOutcome>> = (0..selected.len()).map(|_| None).collect();
    for (index, outcome) in computed.into_iter().flatten() {
        outcomes[index] = outcome;
    }
    for (index, outcome) in stored {
        outcomes[index] = Some(outcome);
    }
    Ok(selected
        .into_iter()
        .zip(outcomes.iter_mut())
        .map(|(plan, outcome)| {
            // Every run sent to the writers came back from them.
            let outcome = outcome.take().unwrap_or(RunOutcome::NotRun);
            (plan.clone(), outcome)
        })
        .collect())
}

/// A run's place in the selection and its outcome, unless the writers settle it (a finished
/// run counts as done once stored).
type Settled = (usize, Option<RunOutcome>);

/// A finished run on its way to the writer: its place in the selection, its recording and
/// what its `metrics.json` will hold.
struct ToStore<'a> {
    index: usize,
    plan: &'a RunPlan,
    recording: Box<Recording>,
    stored: Box<StoredRun>,
}

/// What computing a run gave: an outcome already settled (resumed, failed and stored as such)
/// or a finished run still to store.
enum Computed {
    Outcome(RunOutcome),
    Finished {
        recording: Box<Recording>,
        stored: Box<StoredRun>,
    },
}

/// The hash of a run's inputs.
pub fn inputs_hash(context_hash: &str, plan: &RunPlan) -> String {
    let digest = Sha256::new()
        .chain_update(context_hash.as_bytes())
        .chain_update([0])
        .chain_update(plan.key.as_bytes())
        .chain_update([0])
        .chain_update(plan.seed.to_le_bytes())
        .finalize();
    digest.iter().map(|b| format!("{b:02x}")).collect()
}

/// A run whose engine is to run it: its plan, its inputs' hash and its fidelity as drawn.
struct Ready<'a> {
    index: usize,
    plan: &'a RunPlan,
    hash: String,
    fidelity: Option<DrawnFidelity>,
    drawn_parameters: BTreeMap<String, f64>,
}

/// Computes a group of runs (one fidelity's, or a run alone): each is skipped when the
/// execution was stopped, its lab is silent or `--resume` finds it stored; the others run
/// together through their engine ([`crate::engine::Engine::run_together`]) and are measured.
fn execute_group<'a>(
    experiment: &Experiment,
    runs: &[(usize, &'a RunPlan)],
    out: &Path,
    options: &RunOptions,
    context_hash: &str,
    silent: &Mutex<BTreeSet<String>>,
) -> Vec<(usize, &'a RunPlan, Computed)> {
    let mut computed = Vec::with_capacity(runs.len());
    let mut ready = Vec::with_capacity(runs.len());
    for &(index, plan) in runs {
        let stopped = options.stop.as_ref().is_some_and(|s| s.load(Ordering::SeqCst));
        let hash = inputs_hash(context_hash, plan);
        let settled = if stopped {
            Some(RunOutcome::NotRun)
        } else if silent.lock().is_ok_and(|s| s.contains(&plan.fidelity)) {
            Some(RunOutcome::Failed(format!(
                "not started: the lab of fidelity `{}` did not answer an earlier run",
                plan.fidelity
            )))
        } else if options.resume {
            finished_run(out, plan, &hash).map(|stored| RunOutcome::Resumed(Box::new(stored)))
        } else {
            None
        };
        match settled {
            Some(outcome) => computed.push((index, plan, Computed::Outcome(outcome))),
            None => {
                let (fidelity, drawn_parameters) = drawn_fidelity(experiment, plan);
                ready.push(Ready {
                    index,
                    plan,
                    hash,
                    fidelity,
                    drawn_parameters,
                });
            }
        }
    }
    let context = EngineContext {
        stop: options.stop.as_deref(),
        operator: options.operator.as_ref(),
        timing: options.timing,
    };
    let results = run_engines(experiment, &ready, context);
    for (run, result) in ready.into_iter().zip(results) {
        let conclusion = conclude(experiment, &run, result, out, silent);
        computed.push((run.index, run.plan, conclusion));
    }
    computed
}

/// What became of a run its engine ran: measured and ready to store, or failed and stored as
/// such (with what it recorded, if anything).
fn conclude(
    experiment: &Experiment,
    run: &Ready<'_>,
    result: Result<Recording, RunFailure>,
    out: &Path,
    silent: &Mutex<BTreeSet<String>>,
) -> Computed {
    let plan = run.plan;
    let failed = |reason: String, notes: &[String], latency_s: &[f64]| {
        let failure = Failure {
            key: plan.key.clone(),
            seed: plan.seed,
            inputs_hash: run.hash.clone(),
            reason: reason.clone(),
            notes: notes.to_vec(),
            planning_latency_ms: milliseconds(latency_s),
        };
        match store_failure(out, plan, &failure) {
            Ok(()) => RunOutcome::Failed(reason),
            Err(e) => RunOutcome::Failed(format!("{reason}; cannot store failed.json: {e}")),
        }
    };
    let outcome = match result.and_then(|recording| {
        let metrics = measure(experiment, plan, &recording)?;
        Ok((recording, metrics))
    }) {
        Ok((recording, metrics)) => {
            let stored = StoredRun {
                key: plan.key.clone(),
                seed: plan.seed,
                inputs_hash: run.hash.clone(),
                notes: recording.notes.clone(),
                drawn_parameters: run.drawn_parameters.clone(),
                planning_latency_ms: milliseconds(&recording.latency_s),
                statistics: recording.statistics.clone(),
                metrics,
            };
            return Computed::Finished {
                recording: Box::new(recording),
                stored: Box::new(stored),
            };
        }
        Err(RunFailure::Partial { reason, recording }) => match store_partial(out, plan, &recording) {
            Ok(()) => failed(
                format!("{reason}; its trajectory.csv holds what was recorded"),
                &recording.notes,
                &recording.latency_s,
            ),
            Err(e) => RunOutcome::Failed(format!("{reason}; cannot store what was recorded: {e}")),
        },
        Err(RunFailure::Reason(reason)) => failed(reason, &earlier_recording(out, plan), &[]),
        Err(RunFailure::LabSilent(reason)) => {
            if let Ok(mut silent) = silent.lock() {
                silent.insert(plan.fidelity.clone());
            }
            failed(reason, &earlier_recording(out, plan), &[])
        }
    };
    Computed::Outcome(outcome)
}

/// Seconds as milliseconds, to the microsecond.
fn milliseconds(seconds: &[f64]) -> Vec<f64> {
    seconds.iter().map(|s| (s * 1e6).round() / 1e3).collect()
}

/// A note for the `failed.json` of an attempt that recorded nothing, when the folder keeps an
/// earlier attempt's `trajectory.csv` (never deleted: nothing recorded is lost).
fn earlier_recording(out: &Path, plan: &RunPlan) -> Vec<String> {
    if run_dir(out, plan).join("trajectory.csv").is_file() {
        vec![format!("{EARLIER_RECORDING}; this attempt recorded nothing")]
    } else {
        Vec::new()
    }
}

/// What the runner hands an engine besides the run: the stop flag, the operator and whether
/// to time the layers.
#[derive(Clone, Copy)]
struct EngineContext<'a> {
    stop: Option<&'a AtomicBool>,
    operator: Option<&'a Operator>,
    timing: bool,
}

/// Why a run has no result: a reason, and what it recorded before it failed, if anything.
enum RunFailure {
    Reason(String),
    /// The lab did not answer: later runs of the fidelity would wait in vain.
    LabSilent(String),
    Partial {
        reason: String,
        recording: Box<Recording>,
    },
}

impl From<String> for RunFailure {
    fn from(reason: String) -> Self {
        RunFailure::Reason(reason)
    }
}

impl From<RunError> for RunFailure {
    fn from(error: RunError) -> Self {
        match error {
            RunError::Partial { reason, recording } if !recording.times_s.is_empty() => RunFailure::Partial {
                reason: format!("{reason} after {} ticks", recording.times_s.len()),
                recording,
            },
            silent @ RunError::LabSilent { .. } => RunFailure::LabSilent(silent.to_string()),
            other => RunFailure::Reason(other.to_string()),
        }
    }
}

impl RunFailure {
    fn reason(self) -> String {
        match self {
            RunFailure::Reason(reason)
            | RunFailure::LabSilent(reason)
            | RunFailure::Partial { reason, .. } => reason,
        }
    }
}

/// Stores the recording of a failed run as its `trajectory.csv`, without `metrics.json`, so
/// that the run does not count as finished (a stale `metrics.json` is removed first).
fn store_partial(out: &Path, plan: &RunPlan, recording: &Recording) -> std::io::Result<()> {
    let dir = run_dir(out, plan);
    match std::fs::remove_file(dir.join("metrics.json")) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(e),
        _ => {}
    }
    let mut trajectory = Vec::new();
    recording
        .write_csv(&mut trajectory)
        .map_err(std::io::Error::other)?;
    write_atomic(&dir.join("trajectory.csv"), &trajectory)
}

/// Runs the engine of the plan's fidelity and measures the recording.
pub fn simulate(experiment: &Experiment, plan: &RunPlan) -> Result<(Recording, RunMetrics), String> {
    let (fidelity, _) = drawn_fidelity(experiment, plan);
    let context = EngineContext {
        stop: None,
        operator: None,
        timing: false,
    };
    let recording = run_engine(experiment, plan, fidelity.as_ref(), context).map_err(RunFailure::reason)?;
    let metrics = measure(experiment, plan, &recording)?;
    Ok((recording, metrics))
}

/// The plan's fidelity as its engine runs it, with its randomised parameters drawn for this
/// run (simulated fidelities only), and the values drawn by name.
fn drawn_fidelity(experiment: &Experiment, plan: &RunPlan) -> (Option<DrawnFidelity>, BTreeMap<String, f64>) {
    match experiment.spec.fidelities.get(&plan.fidelity) {
        Some(Fidelity::Simulated(f)) => {
            let (fidelity, drawn) = crate::randomise::draw_for_run(f, plan.seed);
            (Some(fidelity), drawn.into_iter().collect())
        }
        _ => (None, BTreeMap::new()),
    }
}

/// Runs the engine of the plan's fidelity (`drawn`: its layers as drawn for this run).
fn run_engine(
    experiment: &Experiment,
    plan: &RunPlan,
    drawn: Option<&DrawnFidelity>,
    context: EngineContext<'_>,
) -> Result<Recording, RunFailure> {
    let (engine, starts) = engine_and_starts(experiment, plan)?;
    Ok(engine.run(&run_inputs(experiment, plan, starts, drawn, context))?)
}

/// Runs the `ready` runs (of one fidelity, or one run) through their engine together.
fn run_engines(
    experiment: &Experiment,
    ready: &[Ready<'_>],
    context: EngineContext<'_>,
) -> Vec<Result<Recording, RunFailure>> {
    let mut results: Vec<Option<Result<Recording, RunFailure>>> = (0..ready.len()).map(|_| None).collect();
    let mut engine = None;
    let mut inputs = Vec::with_capacity(ready.len());
    let mut positions = Vec::with_capacity(ready.len());
    for (position, run) in ready.iter().enumerate() {
        match engine_and_starts(experiment, run.plan) {
            Ok((run_engine, starts)) => {
                engine = Some(run_engine);
                inputs.push(run_inputs(
                    experiment,
                    run.plan,
                    starts,
                    run.fidelity.as_ref(),
                    context,
                ));
                positions.push(position);
            }
            Err(failure) => results[position] = Some(Err(failure)),
        }
    }
    if let Some(engine) = engine {
        for (position, result) in positions.into_iter().zip(engine.run_together(&inputs)) {
            results[position] = Some(result.map_err(RunFailure::from));
        }
    }
    results
        .into_iter()
        .map(|result| result.expect("every run has a result"))
        .collect()
}

/// The engine of the plan's fidelity and the run's initial states.
fn engine_and_starts<'e>(
    experiment: &'e Experiment,
    plan: &RunPlan,
) -> Result<
    (
        &'static dyn crate::engine::Engine,
        &'e [crate::starts::InitialState],
    ),
    RunFailure,
> {
    let fidelity = experiment
        .spec
        .fidelities
        .get(&plan.fidelity)
        .ok_or_else(|| format!("the spec has no fidelity `{}`", plan.fidelity))?;
    let engine = engine_for(&plan.fidelity, fidelity).map_err(|e| e.to_string())?;
    let starts = experiment
        .start(plan)
        .ok_or_else(|| RunError::UnknownConfiguration(plan.initial_configuration.clone()).to_string())?;
    Ok((engine, starts))
}

/// What an engine is handed for a run.
fn run_inputs<'a>(
    experiment: &'a Experiment,
    plan: &'a RunPlan,
    starts: &'a [crate::starts::InitialState],
    drawn: Option<&'a DrawnFidelity>,
    context: EngineContext<'a>,
) -> RunInputs<'a> {
    RunInputs {
        experiment,
        plan,
        starts,
        fidelity: drawn,
        stop: context.stop,
        operator: context.operator,
        timing: context.timing,
    }
}

/// The spec's metrics of a planned run's recording, on its configuration's map (the same
/// function `cpmx evaluate` and `cpmx report` use).
pub fn measure(experiment: &Experiment, plan: &RunPlan, recording: &Recording) -> Result<RunMetrics, String> {
    let metrics = experiment
        .metrics_by_fidelity
        .get(&plan.fidelity)
        .unwrap_or(&experiment.metrics);
    let map = experiment.map_of(&plan.initial_configuration);
    measure_recording(map, &experiment.footprint, metrics, recording)
}

/// The metrics of a recording on `map` with the vehicle's footprint and the metric parameters.
pub fn measure_recording(
    map: &cpmx_world::Map,
    vehicle: &cpmx_vehicle::VehicleParams,
    metrics: &cpmx_metrics::MetricsConfig,
    recording: &Recording,
) -> Result<RunMetrics, String> {
    let paths: Vec<PathGeometry<'_>> = recording
        .ref_paths
        .iter()
        .map(|&id| {
            map.reference_path(id)
                .map(PathGeometry::from)
                .ok_or(format!("no reference path {id}"))
        })
        .collect::<Result<_, _>>()?;
    evaluate(recording, &paths, vehicle, metrics).map_err(|e| e.to_string())
}
