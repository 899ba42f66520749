//! `cpmx._cpmx`: cpmx for Python, a thin layer over cpmx's crates. It converts at the boundary
//! and calls what the command line calls: the training environment of `cpmx train`
//! ([`env::VecEnv`]), the runs of `cpmx run` with policies bound from Python ([`run::run`]),
//! and the checks of `cpmx validate` ([`check::validate`]). Arrays cross as numpy arrays
//! without element-wise conversion, the GIL is released while cpmx works, and every cpmx
//! problem reaches Python as a `CpmxError` carrying the diagnostic's text.
//!
//! The Python package beside this crate (`python/cpmx/`) holds the adapters (TorchRL,
//! BenchMARL, PettingZoo), the type stubs and the documentation of everything here.

mod check;
mod env;
mod run;
mod safety;

use std::path::PathBuf;

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;

create_exception!(
    _cpmx,
    CpmxError,
    PyException,
    "A problem cpmx found: an invalid spec (the text holds every diagnostic with file:line:col \
     and help), a map or weights it cannot use, or a run folder it cannot write."
);

/// The folders of a `data=` argument: `None`, one path, or a sequence of paths.
pub(crate) fn data_folders(data: Option<&Bound<'_, PyAny>>) -> PyResult<Vec<PathBuf>> {
    let Some(data) = data else {
        return Ok(Vec::new());
    };
    if let Ok(one) = data.extract::<PathBuf>() {
        return Ok(vec![one]);
    }
    data.extract::<Vec<PathBuf>>().map_err(|_| {
        pyo3::exceptions::PyTypeError::new_err(
            "`data` must be a path or a list of paths (folders to look up maps and weights in)",
        )
    })
}

/// Reads and checks a spec as the command line does; a spec with errors raises `CpmxError`
/// with every diagnostic.
pub(crate) fn load(spec: &std::path::Path, data: &[PathBuf]) -> PyResult<cpmx_spec::CheckedSpec> {
    match cpmx_session::load_from(
        spec,
        data,
        cpmx_spec::CheckScope::Run,
        cpmx_spec::data_option::PYTHON,
    ) {
        Ok(checked) => Ok(checked),
        Err(cpmx_session::LoadError::Read(message)) => Err(CpmxError::new_err(message)),
        Err(cpmx_session::LoadError::Invalid(diagnostics)) => {
            let errors = diagnostics.iter().filter(|d| d.is_error()).count();
            Err(CpmxError::new_err(format!(
                "{}: {errors} error{}\n{}",
                spec.display(),
                if errors == 1 { "" } else { "s" },
                cpmx_spec::render(&diagnostics, false)
            )))
        }
    }
}

#[pymodule]
fn _cpmx(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("CpmxError", m.py().get_type::<CpmxError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<env::VecEnv>()?;
    m.add_class::<check::Diagnostic>()?;
    m.add_function(wrap_pyfunction!(check::validate, m)?)?;
    m.add_function(wrap_pyfunction!(run::run, m)?)?;
    m.add_function(wrap_pyfunction!(safety::_cbf_filter, m)?)?;
    m.add_function(wrap_pyfunction!(env::_training_rollout, m)?)?;
    Ok(())
}
