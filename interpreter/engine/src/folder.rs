//! A whole run folder (cli.md): the resolved spec and its hash, `matrix.csv`, and the tables
//! and plots computed from the stored runs. `cpmx run` writes it; `cpmx report` reads folders
//! back and writes the same summaries, byte for byte.

use std::path::{Path, PathBuf};

use cpmx_report::{Format, RunRecord, Summary, per_run_csv, render, summarize};
use cpmx_spec::{CheckedSpec, RunPlan};
use sha2::{Digest, Sha256};

use crate::experiment::Experiment;
use crate::store::{read_stored, run_dir, write_atomic};

/// The resolved spec with the files it names replaced by the paths where they were found.
pub fn resolved_spec(checked: &CheckedSpec) -> serde_json::Value {
    let mut resolved = checked.resolved.clone();
    if let Some(path) = &checked.resources.map_file
        && let Some(slot) = resolved.pointer_mut("/map/file")
    {
        *slot = serde_json::Value::from(absolute(path));
    }
    for (i, weights) in checked.resources.weights.iter().enumerate() {
        if let Some(path) = weights
            && let Some(slot) = resolved.pointer_mut(&format!("/policies/{i}/mlp/weights"))
        {
            *slot = serde_json::Value::from(absolute(path));
        }
    }
    resolved
}

fn absolute(path: &Path) -> String {
    std::fs::canonicalize(path)
        .unwrap_or_else(|_| path.to_path_buf())
        .display()
        .to_string()
}

fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

/// The hash every run's input hash starts from: the resolved spec without its `report`
/// section (reports do not change runs), and the bytes of the map and weight files.
pub fn context_hash(checked: &CheckedSpec) -> String {
    let mut resolved = resolved_spec(checked);
    if let Some(root) = resolved.as_object_mut() {
        root.remove("report");
        root.remove("description");
    }
    let mut hasher = Sha256::new();
    hasher.update(resolved.to_string().as_bytes());
    let files: Vec<&PathBuf> = checked
        .resources
        .map_file
        .iter()
        .chain(checked.resources.weights.iter().flatten())
        .collect();
    for file in files {
        hasher.update([0]);
        hasher.update(std::fs::read(file).unwrap_or_default());
    }
    hasher.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

/// Writes `spec.resolved.yaml` (with its SHA-256 in the first line) and `matrix.csv`.
pub fn write_header(out: &Path, checked: &CheckedSpec, plans: &[RunPlan]) -> std::io::Result<()> {
    let resolved = resolved_spec(checked);
    let yaml = serde_saphyr::to_string(&resolved).map_err(std::io::Error::other)?;
    let text = format!(
        "# sha256: {}\n{yaml}",
        sha256_hex(resolved.to_string().as_bytes())
    );
    write_atomic(&out.join("spec.resolved.yaml"), text.as_bytes())?;
    let mut matrix = String::from("key,fidelity,policy,initial_configuration,repetition,seed\n");
    for p in plans {
        matrix.push_str(&format!(
            "{},{},{},{},{},{}\n",
            p.key, p.fidelity, p.policy, p.initial_configuration, p.repetition, p.seed
        ));
    }
    write_atomic(&out.join("matrix.csv"), matrix.as_bytes())
}

/// Writes `per_run.csv`, the summaries and the plots of `records` (in matrix order).
pub fn write_summaries(
    out: &Path,
    experiment: &Experiment,
    records: &[RunRecord],
) -> std::io::Result<Summary> {
    let summary = summarize(&experiment.spec.name, records, &experiment.spec.report);
    write_atomic(&out.join("per_run.csv"), per_run_csv(records).as_bytes())?;
    for format in Format::ALL {
        if let Some(name) = format.file_name() {
            write_atomic(&out.join(name), render(&summary, format).as_bytes())?;
        }
    }
    write_plots(out, experiment, records, &summary)?;
    Ok(summary)
}

fn write_plots(
    out: &Path,
    experiment: &Experiment,
    records: &[RunRecord],
    summary: &Summary,
) -> std::io::Result<()> {
    let plots = out.join("plots");
    for metric in cpmx_report::Metric::ALL {
        let svg = cpmx_report::distribution_svg(summary, metric);
        write_atomic(
            &plots.join(format!("distribution-{}.svg", metric.id())),
            svg.as_bytes(),
        )?;
    }
    for record in records {
        let dir = run_dir(out, &record.plan);
        let Ok(file) = std::fs::File::open(dir.join("trajectory.csv")) else {
            continue;
        };
        let Ok(recording) = cpmx_recording::Recording::read_csv(file) else {
            continue;
        };
        let svg =
            cpmx_report::trajectory_svg(&experiment.map, &recording, &record.metrics, &experiment.vehicle);
        write_atomic(
            &plots.join(format!("{}.svg", record.plan.key.replace('/', "_"))),
            svg.as_bytes(),
        )?;
    }
    Ok(())
}

/// The runs listed in a folder's `matrix.csv`.
pub fn read_matrix(dir: &Path) -> Result<Vec<RunPlan>, String> {
    let path = dir.join("matrix.csv");
    let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut plans = Vec::new();
    for (n, line) in text.lines().enumerate().skip(1) {
        let cols: Vec<&str> = line.split(',').collect();
        let bad = || format!("{}:{}: not a row of the run matrix", path.display(), n + 1);
        let [key, fidelity, policy, initial_configuration, repetition, seed] = cols.as_slice() else {
            return Err(bad());
        };
        plans.push(RunPlan {
            key: key.to_string(),
            fidelity: fidelity.to_string(),
            policy: policy.to_string(),
            initial_configuration: initial_configuration.to_string(),
            repetition: repetition.parse().map_err(|_| bad())?,
            seed: seed.parse().map_err(|_| bad())?,
        });
    }
    Ok(plans)
}

/// The finished runs of a folder, in matrix order (unfinished ones are reported as missing).
pub fn read_records(dir: &Path, plans: &[RunPlan]) -> (Vec<RunRecord>, Vec<String>) {
    let mut records = Vec::new();
    let mut missing = Vec::new();
    for plan in plans {
        match read_stored(&run_dir(dir, plan)) {
            Ok(stored) => records.push(RunRecord {
                plan: plan.clone(),
                metrics: stored.metrics,
            }),
            Err(_) => missing.push(plan.key.clone()),
        }
    }
    (records, missing)
}
