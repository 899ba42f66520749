//! `cpmx plan SPEC`: the run matrix as a table, CSV or JSON.

use std::fmt::Write as _;
use std::path::Path;

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

pub fn run(spec: &Path, format: PlanFormat, data: &DataArgs) -> Result<(), Failure> {
    let checked = load_checked(spec, data)?;
    print!("{}", render(&checked.plan(), format));
    Ok(())
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
