//! The run folder of cli.md: where each file goes, and writing them so that an interrupted run
//! never leaves something that looks finished. A run counts as finished when its
//! `metrics.json` exists and names the run's input hash; it is written last, by rename.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

use cpmx_metrics::RunMetrics;
use cpmx_recording::Recording;
use cpmx_spec::RunPlan;
use serde::{Deserialize, Serialize};

/// What `metrics.json` holds: the run, the hash of its inputs, and its metrics.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct StoredRun {
    pub key: String,
    pub seed: u64,
    /// SHA-256 of everything the run's result depends on (spec, key, seed, map and weights).
    pub inputs_hash: String,
    /// What the engine noticed without failing (e.g. late lab ticks).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
    /// The fidelity's randomised parameters as drawn for this run, by name
    /// (`actuation.delay_ms`).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub drawn_parameters: BTreeMap<String, f64>,
    /// A lab run's planning latency at each recorded tick [ms] (its notes summarise it).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub planning_latency_ms: Vec<f64>,
    /// Numbers the fidelity's layers counted over the run, by name (`safety.changed`).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub statistics: BTreeMap<String, f64>,
    pub metrics: RunMetrics,
}

/// The folder of one run.
pub fn run_dir(out: &Path, plan: &RunPlan) -> PathBuf {
    out.join("runs").join(&plan.key)
}

/// Writes `bytes` to `path` atomically: a temporary file in the same folder, then a rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent)?;
    }
    let file_name = path.file_name().and_then(|n| n.to_str()).unwrap_or("file");
    let tmp = path.with_file_name(format!(".{file_name}.tmp{}", std::process::id()));
    {
        let mut file = std::fs::File::create(&tmp)?;
        file.write_all(bytes)?;
        file.sync_all()?;
    }
    std::fs::rename(&tmp, path)
}

/// What `failed.json` holds: why a run failed, and what it noticed before (a lab run's
/// irregularities). The folder of a failed run holds it beside the `trajectory.csv` of what
/// was recorded, if anything was; the run finishing later removes it.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Failure {
    pub key: String,
    pub seed: u64,
    pub inputs_hash: String,
    pub reason: String,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub notes: Vec<String>,
    /// A lab run's planning latency at each tick it recorded [ms].
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub planning_latency_ms: Vec<f64>,
}

/// The name of a failed run's record.
pub const FAILED_FILE: &str = "failed.json";

/// The note of a failed run whose folder keeps the `trajectory.csv` an earlier attempt recorded.
pub const EARLIER_RECORDING: &str = "trajectory.csv holds what an earlier attempt recorded";

/// Stores why a run failed (`failed.json`). The run is not finished: a `metrics.json` of an
/// earlier attempt goes (its recording stays, and the notes say so).
pub fn store_failure(out: &Path, plan: &RunPlan, failure: &Failure) -> std::io::Result<()> {
    let dir = run_dir(out, plan);
    match std::fs::remove_file(dir.join("metrics.json")) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(e),
        _ => {}
    }
    let json = serde_json::to_vec_pretty(failure).map_err(std::io::Error::other)?;
    write_atomic(&dir.join(FAILED_FILE), &json)
}

/// Stores a finished run: trajectory first, then `metrics.json` (the "finished" mark).
/// Returns the SHA-256 of the `trajectory.csv` written.
pub fn store_run(
    out: &Path,
    plan: &RunPlan,
    recording: &Recording,
    stored: &StoredRun,
) -> std::io::Result<String> {
    let dir = run_dir(out, plan);
    let mut trajectory = Vec::new();
    recording
        .write_csv(&mut trajectory)
        .map_err(std::io::Error::other)?;
    write_atomic(&dir.join("trajectory.csv"), &trajectory)?;
    let json = serde_json::to_vec_pretty(stored).map_err(std::io::Error::other)?;
    write_atomic(&dir.join("metrics.json"), &json)?;
    match std::fs::remove_file(dir.join(FAILED_FILE)) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(e),
        _ => Ok(cpmx_spec::sha256_hex(&trajectory)),
    }
}

/// The stored result of a run, if it finished with the same inputs.
pub fn finished_run(out: &Path, plan: &RunPlan, inputs_hash: &str) -> Option<StoredRun> {
    let dir = run_dir(out, plan);
    let text = std::fs::read_to_string(dir.join("metrics.json")).ok()?;
    let stored: StoredRun = serde_json::from_str(&text).ok()?;
    (stored.inputs_hash == inputs_hash && stored.key == plan.key && dir.join("trajectory.csv").is_file())
        .then_some(stored)
}

/// Whether a folder holds the finished run (its `metrics.json` and trajectory).
pub fn finished(out: &Path, plan: &RunPlan) -> bool {
    let dir = run_dir(out, plan);
    dir.join("trajectory.csv").is_file()
        && read_stored(&dir).is_ok_and(|stored| stored.key == plan.key && stored.seed == plan.seed)
}

/// Reads a stored run's `metrics.json`.
pub fn read_stored(dir: &Path) -> Result<StoredRun, String> {
    let path = dir.join("metrics.json");
    let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))
}
