//! `cpmx plan SPEC`: the run matrix as a table, CSV or JSON.

use std::fmt::Write as _;
use std::path::Path;

use cpmx_spec::{RunPlan, TrainingPlan};

use super::{Failure, load_checked};
use crate::DataArgs;

/// Output formats of `cpmx plan`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum PlanFormat {
    Table,
    Csv,
    Json,
}

pub fn run(spec: &Path, format: PlanFormat, data: &DataArgs) -> Result<(), Failure> {
    let checked = load_checked(spec, data)?;
    let (runs, training) = (checked.plan(), checked.training_plan());
    if format == PlanFormat::Json && !training.is_empty() {
        let value = serde_json::json!({ "runs": runs, "training": training });
        println!("{}", serde_json::to_string_pretty(&value).unwrap_or_default());
    } else {
        print!("{}", render(&runs, format));
        print!("{}", render_training(&training, format));
    }
    Ok(())
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
