//! Reading and checking a spec as every command does: the spec's own checks, the
//! interpreter's (map, weights, starts), and whether the trained actors it names were trained
//! by its `training:` section as it stands.

use std::path::{Path, PathBuf};

use cpmx_spec::{CheckScope, CheckedSpec, DataPath, Problem, SpecDiagnostic, SpecSource};

/// Reads and checks the spec at `path` for `scope`, with `data` before `CPMX_DATA` on the
/// data path. The checked spec's `warnings` are every warning to show; `Err` holds every
/// diagnostic (errors and warnings), or a single line when the file cannot be read.
pub fn load(path: &Path, data: &[PathBuf], scope: CheckScope) -> Result<CheckedSpec, LoadError> {
    load_from(path, data, scope, cpmx_spec::data_option::COMMAND_LINE)
}

/// [`load`] for a caller whose way to add a data folder is `option` (the help lines name it:
/// `data=` from Python).
pub fn load_from(
    path: &Path,
    data: &[PathBuf],
    scope: CheckScope,
    option: &'static str,
) -> Result<CheckedSpec, LoadError> {
    let source = SpecSource::read(path)
        .map_err(|e| LoadError::Read(format!("cannot read spec `{}`: {e}", path.display())))?;
    let cpmx_data = std::env::var("CPMX_DATA").ok();
    let data_path = DataPath::new(&source.dir, data, cpmx_data.as_deref()).named(option);
    let mut checked = cpmx_spec::check_scoped(&source, &data_path, &cpmx_engine::BuildChecks, scope)
        .map_err(LoadError::Invalid)?;
    if scope == CheckScope::Run {
        let stale = trained_elsewhere(&checked);
        checked.warnings.extend(stale);
    }
    Ok(checked)
}

/// Why a spec could not be loaded.
#[derive(Debug)]
pub enum LoadError {
    /// The file could not be read.
    Read(String),
    /// The spec has errors: every diagnostic found, warnings included.
    Invalid(Vec<SpecDiagnostic>),
}

/// Warnings for trained actors (`mlp: {trained}`) that the spec's `training:` section as it
/// stands did not train (their `run.json` records other inputs), or whose folder does not say.
fn trained_elsewhere(checked: &CheckedSpec) -> Vec<SpecDiagnostic> {
    cpmx_train::trained_actors(checked)
        .into_iter()
        .filter_map(|(i, provenance)| {
            let name = &checked.spec.policies[i].name;
            let span = checked.key_span(&format!("/policies/{i}/mlp/trained"));
            let problem = match provenance {
                cpmx_train::Provenance::Same => return None,
                cpmx_train::Provenance::Other { recorded, expected } => Problem::warning(
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
                cpmx_train::Provenance::Unrecorded => Problem::warning(
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
