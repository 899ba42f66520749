//! One module per subcommand, and what they share: reading and checking a spec.

pub mod evaluate;
#[cfg(feature = "onnx")]
pub mod export;
pub mod lab;
pub mod plan;
pub mod report;
pub mod run;
pub mod stdlib;
pub mod train;
pub mod validate;

use std::io::IsTerminal;
use std::path::Path;

use cpmx_spec::CheckedSpec;

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
    /// Interrupted (Ctrl-C): what was finished is kept, and how to resume was printed (exit 130).
    Interrupted = crate::interrupt::EXIT_CODE as isize,
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
    let colour = std::io::stderr().is_terminal();
    match cpmx_session::load(path, &data.data, scope) {
        Ok(checked) => {
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
        Err(cpmx_session::LoadError::Read(message)) => {
            eprintln!("error: {message}");
            Err(Failure::InvalidInput)
        }
        Err(cpmx_session::LoadError::Invalid(diagnostics)) => {
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
