//! `validate(spec, data=None)`: every diagnostic of a spec as objects.

use std::path::PathBuf;

use pyo3::prelude::*;

/// One problem of a spec, as `cpmx validate` prints it.
#[pyclass(module = "cpmx._cpmx", frozen, get_all)]
#[derive(Debug, Clone)]
pub struct Diagnostic {
    /// `"error"` or `"warning"`.
    pub level: String,
    /// A stable identifier of the kind of problem, e.g. `cpmx::schema::type`.
    pub code: String,
    pub message: String,
    /// The spec file.
    pub file: String,
    /// 1-based line and column of the node the problem is about.
    pub line: usize,
    pub column: usize,
    /// What the label under the node says.
    pub label: String,
    /// What to do about it, when cpmx knows.
    pub help: Option<String>,
    /// The diagnostic as `cpmx validate` renders it (without colour).
    pub text: String,
}

#[pymethods]
impl Diagnostic {
    fn __repr__(&self) -> String {
        format!(
            "Diagnostic({}:{}:{}: {}: {})",
            self.file, self.line, self.column, self.level, self.message
        )
    }

    fn __str__(&self) -> String {
        self.text.clone()
    }
}

impl Diagnostic {
    fn of(d: &cpmx_spec::SpecDiagnostic) -> Diagnostic {
        Diagnostic {
            level: if d.is_error() { "error" } else { "warning" }.to_owned(),
            code: d.problem.code.to_owned(),
            message: d.problem.message.clone(),
            file: d.source.name().to_owned(),
            line: d.line,
            column: d.column,
            label: d.problem.label.clone(),
            help: d.problem.help.clone(),
            text: cpmx_spec::render(std::slice::from_ref(d), false),
        }
    }
}

/// Every problem `cpmx validate` finds in `spec` (errors and warnings; an empty list for a
/// spec without any). A file that cannot be read raises `CpmxError`.
#[pyfunction]
#[pyo3(signature = (spec, data=None))]
pub fn validate(py: Python<'_>, spec: PathBuf, data: Option<&Bound<'_, PyAny>>) -> PyResult<Vec<Diagnostic>> {
    let data = crate::data_folders(data)?;
    let loaded = py.detach(|| {
        cpmx_session::load_from(
            &spec,
            &data,
            cpmx_spec::CheckScope::Run,
            cpmx_spec::data_option::PYTHON,
        )
    });
    match loaded {
        Ok(checked) => Ok(checked.warnings.iter().map(Diagnostic::of).collect()),
        Err(cpmx_session::LoadError::Invalid(diagnostics)) => {
            Ok(diagnostics.iter().map(Diagnostic::of).collect())
        }
        Err(cpmx_session::LoadError::Read(message)) => Err(crate::CpmxError::new_err(message)),
    }
}
