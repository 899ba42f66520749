//! `cpmx plan SPEC`: the run matrix as a table, CSV or JSON, with the start poses of every
//! initial configuration (sampled ones included): every run of a configuration starts from
//! them, whatever its fidelity (and, but for measured starts per run, its policy and
//! repetition); then the training runs and the layer parameters that fidelities draw.

use std::fmt::Write as _;
use std::path::Path;

use cpmx_engine::{ConfigurationStarts, InitialState, Scoring, initial_states};
use cpmx_spec::model::{Distribution, Fidelity, Parameter};
use cpmx_spec::{RunPlan, Spec, TrainingPlan};

use super::{Failure, load_checked};
use crate::DataArgs;

/// Output formats of `cpmx plan`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum PlanFormat {
    Table,
    Csv,
    Json,
}

/// The start poses of each initial configuration, by name.
pub type Starts = [(String, ConfigurationStarts)];

/// Each start with what it is the start of: the configuration's name, or for a measured start
/// per run `configuration/policy/repN`.
fn labelled(starts: &Starts) -> Vec<(String, &[InitialState])> {
    starts
        .iter()
        .flat_map(|(name, starts)| {
            starts.each().into_iter().map(move |(run, states)| match run {
                None => (name.clone(), states),
                Some((policy, repetition)) => (format!("{name}/{policy}/rep{repetition}"), states),
            })
        })
        .collect()
}

pub fn run(spec: &Path, format: PlanFormat, data: &DataArgs) -> Result<(), Failure> {
    let checked = load_checked(spec, data)?;
    let scoring = Scoring::prepare(&checked).map_err(|e| {
        eprintln!("error: {e}");
        Failure::InvalidInput
    })?;
    let starts = initial_states(
        &checked.spec,
        &checked.configurations,
        &checked.resources,
        (&scoring.map, &scoring.configuration_maps),
        &scoring.vehicle,
    )
    .map_err(|e| {
        eprintln!("error: {e}");
        Failure::InvalidInput
    })?;
    let (runs, training) = (checked.plan(), checked.training_plan());
    let randomised = randomised_parameters(&checked.spec);
    let mut text = render(&runs, format);
    match format {
        // A spec that only trains has no matrix to show.
        PlanFormat::Table if runs.is_empty() => text = render_training(&training, format),
        PlanFormat::Table => {
            text.push_str(&starts_table(&starts));
            text.push_str(&render_training(&training, format));
        }
        PlanFormat::Json => text = plan_json(&runs, &starts, &training, &randomised),
        PlanFormat::Csv => {}
    }
    if format == PlanFormat::Table {
        text.push_str(&randomised_table(&randomised));
    }
    print!("{text}");
    Ok(())
}

/// A layer parameter some fidelity draws: (fidelity, parameter, distribution).
type Randomised = (String, String, Distribution);

/// Every distribution of the spec's fidelities, in the order the fidelities are declared and
/// their parameters drawn.
fn randomised_parameters(spec: &Spec) -> Vec<Randomised> {
    let mut out = Vec::new();
    for (name, fidelity) in &spec.fidelities {
        let Fidelity::Simulated(stack) = fidelity else {
            continue;
        };
        for parameter in stack.parameters() {
            if let Parameter::Drawn(distribution) = parameter.value {
                out.push((name.clone(), parameter.name, distribution));
            }
        }
    }
    out
}

/// The randomised parameters as a table (nothing when no fidelity draws any): what `cpmx run`
/// draws per run and `cpmx train` per episode.
fn randomised_table(randomised: &[Randomised]) -> String {
    if randomised.is_empty() {
        return String::new();
    }
    let rows: Vec<Vec<String>> = randomised
        .iter()
        .map(|(fidelity, parameter, distribution)| {
            vec![fidelity.clone(), parameter.clone(), distribution.to_string()]
        })
        .collect();
    let mut out =
        String::from("\nrandomised parameters (drawn per run by `cpmx run`, per episode by `cpmx train`):\n");
    out.push_str(&table(&["fidelity", "parameter", "distribution"], &rows));
    out
}

/// The start poses as a table, after the matrix.
fn starts_table(starts: &Starts) -> String {
    let mut out = String::from(
        "\nstart poses (every run of a configuration starts here; measured starts per run of a policy and repetition):\n",
    );
    let _ = writeln!(
        out,
        "{:<24} {:>5} {:>8} {:>8} {:>8} {:>8} {:>9}",
        "initial_configuration", "agent", "ref_path", "x [m]", "y [m]", "yaw [°]", "v [m/s]"
    );
    for (name, agents) in labelled(starts) {
        for (agent, s) in agents.iter().enumerate() {
            let _ = writeln!(
                out,
                "{:<24} {:>5} {:>8} {:>8.3} {:>8.3} {:>8.1} {:>9.3}",
                name,
                agent,
                s.ref_path,
                s.x_m,
                s.y_m,
                s.yaw_rad.to_degrees(),
                s.speed_mps
            );
        }
    }
    out
}

/// The matrix, the start poses and the training runs (when the spec trains) as one JSON
/// document.
fn plan_json(
    runs: &[RunPlan],
    starts: &Starts,
    training: &[TrainingPlan],
    randomised: &[Randomised],
) -> String {
    let starts: serde_json::Map<String, serde_json::Value> = labelled(starts)
        .into_iter()
        .map(|(name, agents)| {
            let agents: Vec<serde_json::Value> = agents
                .iter()
                .map(|s| {
                    serde_json::json!({
                        "ref_path": s.ref_path, "x_m": s.x_m, "y_m": s.y_m,
                        "yaw_rad": s.yaw_rad, "speed_mps": s.speed_mps,
                    })
                })
                .collect();
            (name, serde_json::Value::from(agents))
        })
        .collect();
    let mut value = serde_json::json!({ "runs": runs, "starts": starts });
    if !training.is_empty() {
        value["training"] = serde_json::json!(training);
    }
    if !randomised.is_empty() {
        value["randomised"] = randomised
            .iter()
            .map(|(fidelity, parameter, distribution)| {
                serde_json::json!({
                    "fidelity": fidelity, "parameter": parameter, "distribution": distribution,
                })
            })
            .collect();
    }
    format!("{}\n", serde_json::to_string_pretty(&value).unwrap_or_default())
}

/// The training runs as a second table after the run matrix (nothing for a spec without
/// `training:`, and nothing in CSV, which holds the run matrix only; JSON puts them beside
/// the runs as `"training": [...]`).
pub fn render_training(runs: &[TrainingPlan], format: PlanFormat) -> String {
    if runs.is_empty() {
        return String::new();
    }
    match format {
        PlanFormat::Csv | PlanFormat::Json => String::new(),
        PlanFormat::Table => {
            let header = [
                "key",
                "fidelity",
                "seed",
                "iterations",
                "envs",
                "agents",
                "frames/iteration",
            ];
            let rows: Vec<Vec<String>> = runs
                .iter()
                .map(|r| {
                    vec![
                        r.key.clone(),
                        r.fidelity.clone(),
                        r.seed.to_string(),
                        r.iterations.to_string(),
                        r.envs.to_string(),
                        r.agents.to_string(),
                        r.frames_per_iteration.to_string(),
                    ]
                })
                .collect();
            let mut out = String::from("\n");
            out.push_str(&table(&header, &rows));
            let _ = writeln!(out, "{} training runs", runs.len());
            out
        }
    }
}

/// Left-aligned columns separated by two spaces.
fn table(header: &[&str], rows: &[Vec<String>]) -> String {
    let mut widths: Vec<usize> = header.iter().map(|h| h.len()).collect();
    for row in rows {
        for (w, cell) in widths.iter_mut().zip(row) {
            *w = (*w).max(cell.len());
        }
    }
    let line = |cells: Vec<&str>| {
        cells
            .iter()
            .zip(&widths)
            .map(|(c, w)| format!("{c:<w$}"))
            .collect::<Vec<_>>()
            .join("  ")
            .trim_end()
            .to_owned()
    };
    let mut out = String::new();
    let _ = writeln!(out, "{}", line(header.to_vec()));
    for row in rows {
        let _ = writeln!(out, "{}", line(row.iter().map(String::as_str).collect()));
    }
    out
}

/// The matrix in `format`.
pub fn render(runs: &[RunPlan], format: PlanFormat) -> String {
    match format {
        PlanFormat::Json => {
            let value = serde_json::json!({ "runs": runs });
            format!("{}\n", serde_json::to_string_pretty(&value).unwrap_or_default())
        }
        PlanFormat::Csv => {
            let mut out = String::from("key,fidelity,policy,initial_configuration,repetition,seed\n");
            for r in runs {
                let _ = writeln!(
                    out,
                    "{},{},{},{},{},{}",
                    r.key, r.fidelity, r.policy, r.initial_configuration, r.repetition, r.seed
                );
            }
            out
        }
        PlanFormat::Table => {
            let header = [
                "key",
                "fidelity",
                "policy",
                "initial_configuration",
                "rep",
                "seed",
            ];
            let rows: Vec<[String; 6]> = runs
                .iter()
                .map(|r| {
                    [
                        r.key.clone(),
                        r.fidelity.clone(),
                        r.policy.clone(),
                        r.initial_configuration.clone(),
                        r.repetition.to_string(),
                        r.seed.to_string(),
                    ]
                })
                .collect();
            let mut widths = header.map(str::len);
            for row in &rows {
                for (w, cell) in widths.iter_mut().zip(row) {
                    *w = (*w).max(cell.len());
                }
            }
            let mut out = String::new();
            let line = |cells: &[&str]| {
                cells
                    .iter()
                    .zip(widths)
                    .map(|(c, w)| format!("{c:<w$}"))
                    .collect::<Vec<_>>()
                    .join("  ")
                    .trim_end()
                    .to_owned()
            };
            let _ = writeln!(out, "{}", line(&header));
            for row in &rows {
                let cells: Vec<&str> = row.iter().map(String::as_str).collect();
                let _ = writeln!(out, "{}", line(&cells));
            }
            let _ = writeln!(out, "{} runs", runs.len());
            out
        }
    }
}
