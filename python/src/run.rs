//! `run(spec, out=None, policies=None, ...)`: `cpmx run` from Python, with the spec's
//! `python: {}` policies bound to callables. The run folder is the command line's (tables,
//! `report.html`, `--resume`); the runs go on in a thread of their own while the calling thread
//! waits with the GIL released, answering Ctrl-C by starting no further run.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use cpmx_engine::RunOutcome;
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};

use crate::CpmxError;

/// A Python callable deciding every agent's action: `callable(observations[A, O],
/// states[A, 5]) -> actions[A, 2]`.
#[derive(Debug)]
struct PyDecider {
    name: String,
    callable: Py<PyAny>,
}

impl cpmx_policy::Decider for PyDecider {
    fn decide(
        &self,
        observations: &[f32],
        observation_size: usize,
        states: &[f64],
        actions: &mut [f64],
    ) -> Result<(), String> {
        let fields = cpmx_policy::STATE_FIELDS.len();
        let agents = states.len() / fields;
        Python::attach(|py| -> PyResult<()> {
            let obs = PyArray1::from_slice(py, observations).reshape([agents, observation_size])?;
            let st = PyArray1::from_slice(py, states).reshape([agents, fields])?;
            let answer = self.callable.bind(py).call1((obs, st))?;
            let np = py.import("numpy")?;
            let answer = np.call_method1("ascontiguousarray", (answer, np.getattr("float64")?))?;
            let answer: PyReadonlyArray2<'_, f64> = answer.extract().map_err(|_| {
                pyo3::exceptions::PyValueError::new_err(format!(
                    "must return actions [{agents}, 2], a 2-d array"
                ))
            })?;
            if answer.shape() != [agents, 2] {
                return Err(pyo3::exceptions::PyValueError::new_err(format!(
                    "returned shape {:?}; expected [{agents}, 2] (speed m/s, steering rad per agent)",
                    answer.shape()
                )));
            }
            actions.copy_from_slice(answer.as_slice()?);
            Ok(())
        })
        .map_err(|e| format!("`{}` raised {e}", self.name))
    }
}

/// `only=` as `--only` arguments: a mapping `{axis: name or names}`, or strings `AXIS=a,b`.
fn only_arguments(only: Option<&Bound<'_, PyAny>>) -> PyResult<Vec<String>> {
    let Some(only) = only else {
        return Ok(Vec::new());
    };
    if let Ok(map) = only.cast::<PyDict>() {
        let mut out = Vec::new();
        for (axis, names) in map.iter() {
            let axis: String = axis.extract()?;
            let names: Vec<String> = match names.extract::<String>() {
                Ok(one) => vec![one],
                Err(_) => names.extract()?,
            };
            out.push(format!("{axis}={}", names.join(",")));
        }
        return Ok(out);
    }
    if only.is_instance_of::<PyString>() {
        return Ok(vec![only.extract()?]);
    }
    only.extract::<Vec<String>>().map_err(|_| {
        pyo3::exceptions::PyTypeError::new_err(
            "`only` must be a mapping like {\"fidelity\": [\"sim\", \"twin\"]} or strings like \"fidelity=sim,twin\"",
        )
    })
}

/// Runs the spec's matrix into its run folder; see `cpmx/_cpmx.pyi`.
#[pyfunction]
#[pyo3(signature = (spec, out=None, policies=None, jobs=None, only=None, data=None, resume=false, force=false))]
#[allow(clippy::too_many_arguments)]
pub fn run<'py>(
    py: Python<'py>,
    spec: PathBuf,
    out: Option<PathBuf>,
    policies: Option<&Bound<'py, PyDict>>,
    jobs: Option<usize>,
    only: Option<&Bound<'py, PyAny>>,
    data: Option<&Bound<'py, PyAny>>,
    resume: bool,
    force: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let data = crate::data_folders(data)?;
    let only = cpmx_session::parse_only(&only_arguments(only)?).map_err(|e| session_error(&e))?;
    let mut deciders: Vec<(String, Arc<dyn cpmx_policy::Decider>)> = Vec::new();
    if let Some(policies) = policies {
        for (name, callable) in policies.iter() {
            let name: String = name.extract()?;
            if !callable.is_callable() {
                return Err(pyo3::exceptions::PyTypeError::new_err(format!(
                    "policies[{name:?}] must be callable: f(observations[A, O], states[A, 5]) -> actions[A, 2]"
                )));
            }
            deciders.push((
                name.clone(),
                Arc::new(PyDecider {
                    name,
                    callable: callable.clone().unbind(),
                }),
            ));
        }
    }
    let checked = py.detach(|| crate::load(&spec, &data))?;
    for warning in &checked.warnings {
        let text = cpmx_spec::render(std::slice::from_ref(warning), false);
        PyErr::warn(
            py,
            &py.get_type::<pyo3::exceptions::PyUserWarning>(),
            &std::ffi::CString::new(text).unwrap_or_default(),
            1,
        )?;
    }
    let stop = Arc::new(AtomicBool::new(false));
    let request = cpmx_session::RunRequest {
        spec_path: spec,
        out,
        only,
        jobs,
        shard: None,
        resume,
        force,
        data,
        stop: Some(stop.clone()),
        operator: None,
        made_by: format!("cpmx Python package {}", env!("CARGO_PKG_VERSION")),
        timing: false,
    };

    // Run in a thread of its own; this one waits without the GIL and looks for Ctrl-C.
    let (sender, receiver) = std::sync::mpsc::channel();
    let receiver = std::sync::Mutex::new(receiver);
    std::thread::spawn(move || {
        let mut bind = |experiment: &mut cpmx_engine::Experiment| -> Result<(), String> {
            for (name, decider) in &deciders {
                experiment.bind(name, decider.clone())?;
            }
            Ok(())
        };
        let result = cpmx_session::run_matrix(&checked, &request, &mut bind, &|_| {}, &|_, _| {});
        let _ = sender.send(result);
    });
    let mut interrupted = None;
    let result = loop {
        let wait = || match receiver.lock() {
            Ok(receiver) => receiver.recv_timeout(Duration::from_millis(100)),
            Err(_) => Err(std::sync::mpsc::RecvTimeoutError::Disconnected),
        };
        match py.detach(wait) {
            Ok(result) => break result,
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
                if let Err(e) = py.check_signals() {
                    stop.store(true, Ordering::SeqCst);
                    interrupted.get_or_insert(e);
                }
            }
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => {
                return Err(CpmxError::new_err(
                    "the runs ended without a result (a thread panicked)",
                ));
            }
        }
    };
    let done = result.map_err(|e| session_error(&e))?;
    if let Some(e) = interrupted {
        return Err(e);
    }

    // What became of the runs.
    let outcome = PyDict::new(py);
    outcome.set_item("out", done.out.display().to_string())?;
    outcome.set_item("matrix_runs", done.matrix_runs)?;
    outcome.set_item("summarised", done.summarised)?;
    let failed = PyDict::new(py);
    let (mut finished, mut resumed) = (0usize, 0usize);
    for (plan, o) in &done.outcomes {
        match o {
            RunOutcome::Finished(_) => finished += 1,
            RunOutcome::Resumed(_) => resumed += 1,
            RunOutcome::Failed(reason) => failed.set_item(&plan.key, reason)?,
            RunOutcome::NotRun => {}
        }
    }
    outcome.set_item("finished", finished)?;
    outcome.set_item("resumed", resumed)?;
    outcome.set_item("failed", failed)?;
    outcome.set_item("notes", done.notes.clone())?;
    outcome.set_item(
        "summary",
        cpmx_report::render(&done.summary, cpmx_report::Format::Markdown),
    )?;
    Ok(outcome)
}

/// A session error as a `CpmxError` (with its help line).
fn session_error(e: &cpmx_session::RunError) -> PyErr {
    match e.help() {
        Some(help) => CpmxError::new_err(format!("{e}\nhelp: {help}")),
        None => CpmxError::new_err(e.to_string()),
    }
}
