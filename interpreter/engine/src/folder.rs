//! A whole run folder (cli.md): the resolved spec and its hash, `matrix.csv`, and the tables
//! and plots computed from the stored runs. `cpmx run` writes it; `cpmx report` reads folders
//! back and writes the same summaries, byte for byte.

use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use cpmx_report::{Format, RunRecord, Summary, per_run_csv, render, summarize};
use cpmx_spec::{CheckedSpec, RunPlan};

use cpmx_recording::Recording;

use crate::experiment::Scoring;
use crate::fresh::FreshRuns;
use crate::pipeline::pipelined;
use crate::runner::inputs_hash;
use crate::store::{read_stored, run_dir, write_atomic};

/// The resolved spec as a run folder records it: every file it names keeps the path the spec
/// gave (relative to the spec's folder or the data path) and is pinned by the SHA-256 of the
/// bytes that were used, so the folder finds the same files wherever it and the data move.
/// Made once per command ([`ResolvedSpec::of`] reads and hashes every file the spec names):
/// the folder's `spec.resolved.yaml`, its context hash and the comparison with a folder's
/// earlier spec all read the same value.
#[derive(Debug, Clone)]
pub struct ResolvedSpec(serde_json::Value);

impl ResolvedSpec {
    /// `checked`'s resolved spec with every file it names pinned by its SHA-256.
    pub fn of(checked: &CheckedSpec) -> ResolvedSpec {
        ResolvedSpec(pinned(checked))
    }

    /// The hash every run's input hash starts from: the resolved spec without its `report`
    /// section and description (reports do not change runs). The files it names enter through
    /// their pinned SHA-256.
    pub fn context_hash(&self) -> String {
        let mut resolved = self.0.clone();
        if let Some(root) = resolved.as_object_mut() {
            root.remove("report");
            root.remove("description");
        }
        without_lab_session_keys(&mut resolved);
        sha256_hex(resolved.to_string().as_bytes())
    }

    /// The text of `spec.resolved.yaml`: the hash line, then the resolved spec as YAML.
    pub fn text(&self) -> std::io::Result<String> {
        let yaml = serde_saphyr::to_string(&self.0).map_err(std::io::Error::other)?;
        Ok(format!(
            "{HASH_LINE_PREFIX}{}\n{yaml}",
            sha256_hex(yaml.as_bytes())
        ))
    }

    /// The top-level sections (report and description aside: they do not change runs) in which
    /// a folder's resolved spec (`existing`, YAML) differs from this one.
    pub fn differing_sections(&self, existing: &str) -> Vec<String> {
        let Ok(old) = serde_saphyr::from_str::<serde_json::Value>(existing) else {
            return vec!["(unreadable)".into()];
        };
        let (mut old, mut new) = (old, self.0.clone());
        without_lab_session_keys(&mut old);
        without_lab_session_keys(&mut new);
        let (Some(old), Some(new)) = (old.as_object(), new.as_object()) else {
            return vec!["(not a mapping)".into()];
        };
        let mut keys: Vec<&String> = old.keys().chain(new.keys()).collect();
        keys.dedup();
        let mut differing: Vec<String> = Vec::new();
        for key in keys {
            if key == "report" || key == "description" || differing.contains(key) {
                continue;
            }
            if old.get(key).map(numbers_as_f64) != new.get(key).map(numbers_as_f64) {
                differing.push(key.clone());
            }
        }
        differing
    }
}

/// `checked.resolved` with the SHA-256 of every file it names beside the file's path.
fn pinned(checked: &CheckedSpec) -> serde_json::Value {
    let mut resolved = checked.resolved.clone();
    if let Some(path) = &checked.resources.map_file
        && let Some(map) = resolved.pointer_mut("/map").and_then(|m| m.as_object_mut())
        && let Ok(bytes) = std::fs::read(path)
    {
        map.insert("sha256".into(), sha256_hex(&bytes).into());
    }
    for (i, path) in checked.resources.configuration_map_files.iter().enumerate() {
        if let Some(path) = path
            && let Some(map) = resolved
                .pointer_mut(&format!("/initial_configurations/{i}/map"))
                .and_then(|m| m.as_object_mut())
            && let Ok(bytes) = std::fs::read(path)
        {
            map.insert("sha256".into(), sha256_hex(&bytes).into());
        }
    }
    for (i, weights) in checked.resources.weights.iter().enumerate() {
        for kind in ["mlp", "onnx"] {
            if let Some(path) = weights
                && let Some(network) = resolved
                    .pointer_mut(&format!("/policies/{i}/{kind}"))
                    .and_then(|m| m.as_object_mut())
                && let Ok(bytes) = std::fs::read(path)
            {
                network.insert("sha256".into(), sha256_hex(&bytes).into());
            }
        }
    }
    resolved
}

/// Lower-case hex SHA-256 of `bytes`.
pub fn sha256_hex(bytes: &[u8]) -> String {
    cpmx_spec::sha256_hex(bytes)
}

/// Keys of a lab fidelity that decide whether a lab run starts or goes on, or what the emulator
/// plays, but not what a finished run recorded: changing them leaves finished runs finished.
const LAB_SESSION_KEYS: [&str; 3] = ["preflight", "ips_age_limit_s", "faults"];

/// `spec` without its lab fidelities' [`LAB_SESSION_KEYS`].
fn without_lab_session_keys(spec: &mut serde_json::Value) {
    let Some(fidelities) = spec.get_mut("fidelities").and_then(|f| f.as_object_mut()) else {
        return;
    };
    for fidelity in fidelities.values_mut() {
        if let Some(lab) = fidelity.as_object_mut()
            && lab.contains_key("driver")
        {
            for key in LAB_SESSION_KEYS {
                lab.remove(key);
            }
        }
    }
}

/// Where the files of a folder's spec were found when it was made: the folders of the data
/// path, absolute. `cpmx report` searches them last (files are pinned by hash, so a folder
/// never picks up a different file of the same name).
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct Provenance {
    /// The spec file `cpmx run` was given.
    pub spec: PathBuf,
    /// The data path of that run, in order.
    pub data_path: Vec<PathBuf>,
    /// The builds that wrote runs into the folder, in order (`cpmx 0.1.0 (commit 09b1a77)`): a
    /// folder resumed by another build lists both.
    #[serde(default)]
    pub made_by: Vec<String>,
}

impl Provenance {
    /// Reads a folder's `provenance.json` (empty when absent or unreadable).
    pub fn read(dir: &Path) -> Provenance {
        std::fs::read_to_string(dir.join("provenance.json"))
            .ok()
            .and_then(|text| serde_json::from_str(&text).ok())
            .unwrap_or_default()
    }
}

/// The first line of `spec.resolved.yaml`: the SHA-256 of the rest of the file.
const HASH_LINE_PREFIX: &str = "# sha256: ";

/// The resolved spec of a run folder as YAML, checked against the hash in its first line.
pub fn read_resolved_spec(dir: &Path) -> Result<String, String> {
    let path = dir.join("spec.resolved.yaml");
    let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let (first, body) = text.split_once('\n').unwrap_or((&text, ""));
    let Some(recorded) = first.strip_prefix(HASH_LINE_PREFIX) else {
        return Err(format!(
            "{}: the first line should be `{HASH_LINE_PREFIX}<hash>`; this is not a file `cpmx run` wrote",
            path.display()
        ));
    };
    let actual = sha256_hex(body.as_bytes());
    if recorded.trim() != actual {
        return Err(format!(
            "{} was edited after `cpmx run` wrote it (its content no longer has the sha256 of its first \
             line), so it may not describe the runs in the folder; to score stored runs with other \
             metrics use `cpmx report DIR --metrics stdlib:NAME|FILE` instead of editing the file",
            path.display()
        ));
    }
    Ok(body.to_owned())
}

/// `value` with every number as an f64, so that `1` read back from YAML equals `1.0`.
fn numbers_as_f64(value: &serde_json::Value) -> serde_json::Value {
    use serde_json::Value;
    match value {
        Value::Number(n) => n.as_f64().map_or(Value::Null, Value::from),
        Value::Array(items) => Value::Array(items.iter().map(numbers_as_f64).collect()),
        Value::Object(map) => {
            Value::Object(map.iter().map(|(k, v)| (k.clone(), numbers_as_f64(v))).collect())
        }
        other => other.clone(),
    }
}

/// Writes `spec.resolved.yaml` (with the SHA-256 of its content in the first line),
/// `provenance.json` and `matrix.csv`.
pub fn write_header(
    out: &Path,
    checked: &CheckedSpec,
    resolved: &ResolvedSpec,
    plans: &[RunPlan],
    provenance: &Provenance,
) -> std::io::Result<()> {
    write_files(|write| {
        write(out.join("spec.resolved.yaml"), resolved.text()?.into_bytes());
        let provenance = serde_json::to_vec_pretty(provenance).map_err(std::io::Error::other)?;
        write(out.join("provenance.json"), provenance);
        let mut matrix = String::from("key,fidelity,policy,initial_configuration,repetition,seed\n");
        for p in plans {
            matrix.push_str(&format!(
                "{},{},{},{},{},{}\n",
                p.key, p.fidelity, p.policy, p.initial_configuration, p.repetition, p.seed
            ));
        }
        write(out.join("matrix.csv"), matrix.into_bytes());
        keep_learning_curves(out, checked, write);
        Ok(())
    })
}

/// The writer of [`write_files`]: a file's path and its bytes.
type Write<'a> = &'a (dyn Fn(PathBuf, Vec<u8>) + Sync);

/// Writes each file `make` hands its writer atomically ([`write_atomic`]) on writer threads of
/// their own while `make` goes on, so that the files' waits for the disk overlap; returns when
/// every file is written, with the first error of `make` or of a write.
fn write_files<R>(make: impl FnOnce(Write<'_>) -> std::io::Result<R>) -> std::io::Result<R> {
    const WRITERS: usize = 4;
    let (made, written) = pipelined(
        WRITERS,
        |(path, bytes): (PathBuf, Vec<u8>)| write_atomic(&path, &bytes),
        |sender| {
            make(&|path, bytes| {
                // Fails only when the writers are gone (one panicked: that reaches the caller).
                let _ = sender.send((path, bytes));
            })
        },
    );
    let made = made?;
    written.into_iter().collect::<std::io::Result<()>>()?;
    Ok(made)
}

/// Copies the learning curve of every policy trained by `cpmx train` (the
/// `learning_curve.csv` beside its actor) to `training/<policy>/learning_curve.csv`, so that the
/// folder and its report show how its policies were trained wherever the folder moves.
fn keep_learning_curves(out: &Path, checked: &CheckedSpec, write: Write<'_>) {
    for (policy, weights) in checked.spec.policies.iter().zip(&checked.resources.weights) {
        let trained = policy.mlp.as_ref().is_some_and(|m| m.trained.is_some());
        let curve = weights
            .as_deref()
            .and_then(Path::parent)
            .map(|dir| dir.join("learning_curve.csv"));
        if let (true, Some(curve)) = (trained, curve)
            && let Ok(text) = std::fs::read(&curve)
        {
            write(
                out.join("training").join(&policy.name).join("learning_curve.csv"),
                text,
            );
        }
    }
}

/// Writes `per_run.csv`, the summaries, the plots and `report.html` of `records` (in matrix
/// order), reading each run's trajectory from `out` (or from `sources`, the folders the runs
/// were found in, for `cpmx report` of several folders). The runs this command stored come
/// from `fresh` where it kept them.
pub fn write_summaries(
    out: &Path,
    scoring: &Scoring,
    records: &[RunRecord],
    fresh: &FreshRuns,
) -> std::io::Result<Summary> {
    summaries(out, &[out.to_path_buf()], scoring, records, fresh)
}

/// [`write_summaries`] with the runs' trajectories read from the first of `sources` that has them.
pub fn write_summaries_from(
    out: &Path,
    sources: &[PathBuf],
    scoring: &Scoring,
    records: &[RunRecord],
) -> std::io::Result<Summary> {
    summaries(out, sources, scoring, records, &FreshRuns::default())
}

fn summaries(
    out: &Path,
    sources: &[PathBuf],
    scoring: &Scoring,
    records: &[RunRecord],
    fresh: &FreshRuns,
) -> std::io::Result<Summary> {
    let mut summary = summarize(
        &scoring.spec.name,
        records,
        &scoring.spec.report,
        &cpmx_report::Origins::of_spec(&scoring.spec),
    );
    if scoring.spec.metrics.footprint.is_some() {
        summary.vehicles = Some(cpmx_report::VehicleNote {
            vehicle_m: [scoring.vehicle.length_m, scoring.vehicle.width_m],
            footprint_m: [scoring.footprint.length_m, scoring.footprint.width_m],
        });
    }
    write_files(|write| {
        write(out.join("per_run.csv"), per_run_csv(records).into_bytes());
        for format in Format::ALL {
            if let Some(name) = format.file_name() {
                write(out.join(name), render(&summary, format).into_bytes());
            }
        }
        // Each run's recording and figure on its own (rayon: in parallel on the command's pool).
        let recordings: Vec<Option<Arc<Recording>>> = records
            .par_iter()
            .map(|record| {
                fresh.recording(&record.plan.key).or_else(|| {
                    sources.iter().find_map(|dir| {
                        let file =
                            std::fs::File::open(run_dir(dir, &record.plan).join("trajectory.csv")).ok()?;
                        Recording::read_csv(file).ok().map(Arc::new)
                    })
                })
            })
            .collect();
        write_plots(out, scoring, records, &recordings, &summary, write);
        let page = cpmx_report_html::Page {
            summary: &summary,
            description: scoring.spec.description.as_deref(),
            maps: scoring.maps().into_iter().map(|map| map.as_ref()).collect(),
            vehicle: &scoring.footprint,
            runs: records
                .iter()
                .zip(&recordings)
                .filter_map(|(record, recording)| {
                    recording.as_ref().map(|recording| cpmx_report_html::PageRun {
                        record,
                        recording,
                        map: scoring.map_index(&record.plan.initial_configuration),
                    })
                })
                .collect(),
            learning_curves: learning_curves(out),
        };
        write(
            out.join("report.html"),
            cpmx_report_html::report_html(&page).into_bytes(),
        );
        Ok(())
    })?;
    Ok(summary)
}

/// The learning curves of trainings kept in the folder (`*/learning_curve.csv` and
/// `training/<policy>/learning_curve.csv`, by folder name): `episode_reward_mean` per
/// `iteration`.
fn learning_curves(out: &Path) -> Vec<cpmx_report_html::LearningCurve> {
    let subfolders = |dir: &Path| -> Vec<PathBuf> {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return Vec::new();
        };
        let mut folders: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
        folders.sort();
        folders
    };
    let mut folders = subfolders(out);
    folders.extend(subfolders(&out.join("training")));
    folders
        .into_iter()
        .filter_map(|dir| {
            let text = std::fs::read_to_string(dir.join("learning_curve.csv")).ok()?;
            let mut lines = text.lines();
            let header: Vec<&str> = lines.next()?.split(',').collect();
            let iteration = header.iter().position(|h| *h == "iteration")?;
            let reward = header.iter().position(|h| *h == "episode_reward_mean")?;
            let (mut iterations, mut rewards) = (Vec::new(), Vec::new());
            for line in lines {
                let cells: Vec<&str> = line.split(',').collect();
                let (Some(i), Some(r)) = (cells.get(iteration), cells.get(reward)) else {
                    continue;
                };
                if let (Ok(i), Ok(r)) = (i.parse::<f64>(), r.parse::<f64>()) {
                    iterations.push(i);
                    rewards.push(r);
                }
            }
            Some(cpmx_report_html::LearningCurve {
                name: dir.file_name()?.to_string_lossy().into_owned(),
                iterations,
                episode_reward_mean: rewards,
            })
        })
        .collect()
}

fn write_plots(
    out: &Path,
    scoring: &Scoring,
    records: &[RunRecord],
    recordings: &[Option<Arc<Recording>>],
    summary: &Summary,
    write: Write<'_>,
) {
    let plots = out.join("plots");
    for &metric in summary.units.metrics() {
        let svg = cpmx_report::distribution_svg(summary, metric);
        write(
            plots.join(format!("distribution-{}.svg", metric.id())),
            svg.into_bytes(),
        );
    }
    for plot in cpmx_report::sensitivity_svgs(summary) {
        write(
            plots.join(format!("{}.svg", plot.name.replace('/', "_"))),
            plot.svg.into_bytes(),
        );
    }
    // One drawing of each road per frame, shared by the runs' figures on it.
    let drawings: Vec<cpmx_report::MapDrawing<'_>> = scoring
        .maps()
        .into_iter()
        .map(|map| cpmx_report::MapDrawing::new(map))
        .collect();
    records
        .par_iter()
        .zip(recordings)
        .for_each(|(record, recording)| {
            if let Some(recording) = recording {
                let drawing = &drawings[scoring.map_index(&record.plan.initial_configuration)];
                let svg = drawing.trajectory_svg(recording, &record.metrics, &scoring.footprint);
                write(
                    plots.join(format!("{}.svg", record.plan.key.replace('/', "_"))),
                    svg.into_bytes(),
                );
            }
        });
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

/// What a folder holds of a matrix.
#[derive(Debug, Default)]
pub struct FolderRuns {
    /// Finished runs made from the folder's spec, in matrix order.
    pub records: Vec<RunRecord>,
    /// Runs whose files are there but cannot be read (a damaged `metrics.json`): left out of
    /// every summary, with the reason; `--resume` runs them again.
    pub unreadable: Vec<(String, String)>,
    /// Runs finished from an earlier spec (their inputs differ): left out of every summary
    /// until they are run again.
    pub stale: Vec<String>,
}

/// The finished runs of a folder whose inputs match `context_hash` (see
/// [`ResolvedSpec::context_hash`]), in matrix order. The trajectories of runs in `fresh` are
/// not read again: their hash is known.
pub fn read_records(dir: &Path, plans: &[RunPlan], context_hash: &str, fresh: &FreshRuns) -> FolderRuns {
    let mut runs = FolderRuns::default();
    for plan in plans {
        let run = run_dir(dir, plan);
        let stored = match read_stored(&run) {
            Ok(stored) => Some(stored).filter(|s| s.key == plan.key),
            // Not there: not finished (or failed). There but unreadable: say so.
            Err(reason) if run.join("metrics.json").exists() => {
                runs.unreadable.push((plan.key.clone(), reason));
                continue;
            }
            Err(_) => None,
        };
        let trajectory_sha256 = || match fresh.trajectory_sha256(&plan.key) {
            Some(known) => run.join("trajectory.csv").is_file().then_some(known),
            None => std::fs::read(run.join("trajectory.csv"))
                .ok()
                .map(|bytes| sha256_hex(&bytes)),
        };
        match (stored, trajectory_sha256()) {
            (Some(stored), Some(_)) if stored.inputs_hash != inputs_hash(context_hash, plan) => {
                runs.stale.push(plan.key.clone());
            }
            (Some(stored), Some(recording_sha256)) => runs.records.push(RunRecord {
                plan: plan.clone(),
                metrics: stored.metrics,
                recording_sha256,
                drawn_parameters: stored.drawn_parameters,
                statistics: stored.statistics,
            }),
            _ => {}
        }
    }
    runs
}
