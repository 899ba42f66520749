//! One module per subcommand, and what they share: reading and checking a spec.

pub mod evaluate;
pub mod lab;
pub mod plan;
pub mod report;
pub mod run;
pub mod stdlib;
pub mod train;
pub mod validate;

use std::io::IsTerminal;
use std::path::Path;

use cpmx_spec::{CheckedSpec, DataPath, SpecSource};

use crate::DataArgs;

/// How a command ends when it does not succeed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Failure {
    /// Invalid input: a spec, map, weights or recording (exit 1).
    InvalidInput = 1,
    /// A usage error (exit 2).
    Usage = 2,
    /// Some runs failed; the others are kept (exit 3).
    RunsFailed = 3,
}

/// Warnings for trained actors (`mlp: {trained}`) that the spec's `training:` section as it
/// stands did not train (their `run.json` records other inputs), or whose folder does not say.
fn trained_elsewhere(checked: &CheckedSpec) -> Vec<cpmx_spec::SpecDiagnostic> {
    cpmx_train::trained_actors(checked)
        .into_iter()
        .filter_map(|(i, provenance)| {
            let name = &checked.spec.policies[i].name;
            let span = checked.key_span(&format!("/policies/{i}/mlp/trained"));
            let problem = match provenance {
                cpmx_train::Provenance::Same => return None,
                cpmx_train::Provenance::Other { recorded, expected } => cpmx_spec::Problem::warning(
                    "cpmx::check::trained-elsewhere",
                    format!(
                        "policy `{name}` names an actor that other inputs trained: this spec's \
                         `training:` section, vehicle, `timing.dt` or map changed since"
                    ),
                    span,
                    "trained with other inputs",
                )
                .with_help(format!(
                    "its run.json records fingerprint {}…, this spec gives {}…; `cpmx train` \
                     into a new `--out` folder trains it again",
                    &recorded[..recorded.len().min(12)],
                    &expected[..expected.len().min(12)]
                )),
                cpmx_train::Provenance::Unrecorded => cpmx_spec::Problem::warning(
                    "cpmx::check::trained-elsewhere",
                    format!("policy `{name}` names an actor whose folder does not say what trained it"),
                    span,
                    "no run.json beside the actor",
                )
                .with_help("`cpmx train` writes run.json beside every actor it trains"),
            };
            Some(checked.diagnostic(problem))
        })
        .collect()
}

/// Reads and checks a spec; on failure prints every diagnostic to stderr.
pub fn load_checked(path: &Path, data: &DataArgs) -> Result<CheckedSpec, Failure> {
    load_checked_for(path, data, cpmx_spec::CheckScope::Run, &[])
}

/// [`load_checked`] for a purpose (`scope`), leaving out warnings with the codes in `quiet`
/// (e.g. `cpmx train` does not warn that what it is about to train is not there yet).
pub fn load_checked_for(
    path: &Path,
    data: &DataArgs,
    scope: cpmx_spec::CheckScope,
    quiet: &[&str],
) -> Result<CheckedSpec, Failure> {
    let source = match SpecSource::read(path) {
        Ok(source) => source,
        Err(e) => {
            eprintln!("error: cannot read spec `{}`: {e}", path.display());
            return Err(Failure::InvalidInput);
        }
    };
    let cpmx_data = std::env::var("CPMX_DATA").ok();
    let data_path = DataPath::new(&source.dir, &data.data, cpmx_data.as_deref());
    let colour = std::io::stderr().is_terminal();
    match cpmx_spec::check_scoped(&source, &data_path, &cpmx_engine::BuildChecks, scope) {
        Ok(mut checked) => {
            if scope == cpmx_spec::CheckScope::Run {
                let stale = trained_elsewhere(&checked);
                checked.warnings.extend(stale);
            }
            let warnings: Vec<_> = checked
                .warnings
                .iter()
                .filter(|w| !quiet.contains(&w.problem.code))
                .cloned()
                .collect();
            if !warnings.is_empty() {
                eprint!("{}", cpmx_spec::render(&warnings, colour));
            }
            Ok(checked)
        }
        Err(diagnostics) => {
            eprint!("{}", cpmx_spec::render(&diagnostics, colour));
            let errors = diagnostics.iter().filter(|d| d.is_error()).count();
            eprintln!(
                "{}: {errors} error{}",
                path.display(),
                if errors == 1 { "" } else { "s" }
            );
            Err(Failure::InvalidInput)
        }
    }
}
