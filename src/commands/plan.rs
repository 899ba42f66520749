//! `cpmx plan SPEC`: the run matrix as a table, CSV or JSON, with the start poses of every
//! initial configuration (sampled ones included): every run of a configuration starts from
//! them, whatever its fidelity, policy and repetition.

use std::fmt::Write as _;
use std::path::Path;

use cpmx_engine::{InitialState, Scoring, initial_states};
use cpmx_spec::RunPlan;

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
pub type Starts = [(String, Vec<InitialState>)];

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
        &scoring.map,
        &scoring.vehicle,
    )
    .map_err(|e| {
        eprintln!("error: {e}");
        Failure::InvalidInput
    })?;
    let mut text = render(&checked.plan(), format);
    match format {
        PlanFormat::Table => text.push_str(&starts_table(&starts)),
        PlanFormat::Json => text = starts_json(&checked.plan(), &starts),
        PlanFormat::Csv => {}
    }
    print!("{text}");
    Ok(())
}

/// The start poses as a table, after the matrix.
fn starts_table(starts: &Starts) -> String {
    let mut out = String::from("\nstart poses (every run of a configuration starts here):\n");
    let _ = writeln!(
        out,
        "{:<24} {:>5} {:>8} {:>8} {:>8} {:>8} {:>9}",
        "initial_configuration", "agent", "ref_path", "x [m]", "y [m]", "yaw [°]", "v [m/s]"
    );
    for (name, agents) in starts {
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

/// The matrix and the start poses as one JSON document.
fn starts_json(runs: &[RunPlan], starts: &Starts) -> String {
    let starts: serde_json::Map<String, serde_json::Value> = starts
        .iter()
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
            (name.clone(), serde_json::Value::from(agents))
        })
        .collect();
    let value = serde_json::json!({ "runs": runs, "starts": starts });
    format!("{}\n", serde_json::to_string_pretty(&value).unwrap_or_default())
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
