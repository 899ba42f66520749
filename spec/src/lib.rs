//! The cpmx experiment language: types, YAML with spans, the JSON Schema, meaning checks with
//! miette diagnostics, `stdlib:` resolution, and the run matrix with its seeds.
//!
//! This crate is the syntax layer: it knows nothing about simulation. The interpreter adds the
//! checks that need a map or a network through [`InterpreterChecks`].
//!
//! ```text
//! text ──parse──► spanned JSON ──expand presets──► sweeps ──► schema (every point) ──► typed Spec
//!      ──► meaning checks ──► the fidelities of the run matrix (one per point of a sweep)
//! ```

mod check;
mod check_checkpoint;
mod check_compare;
mod check_configurations;
mod check_fidelities;
mod check_files;
mod check_lab;
mod check_poses;
mod check_trained;
mod check_training;
mod diagnostic;
pub mod matrix;
pub mod model;
mod paths;
pub mod poses;
pub mod reference;
mod resolve;
pub mod schema;
pub mod sigmarl;
pub mod sweep;
mod yaml;

use std::path::{Path, PathBuf};
use std::sync::Arc;

pub use check::{CheckContext, CheckScope, InterpreterChecks, Resources};
pub use diagnostic::{ByteSpan, Level, Problem, SpecDiagnostic, render};
pub use matrix::{ConfigurationSource, NamedConfiguration, RunPlan, TrainingPlan};
pub use model::Spec;
pub use paths::{DataPath, NotFound, sha256_hex};
/// How callers add a data folder, as help lines name it.
pub mod data_option {
    pub use crate::paths::{COMMAND_LINE, PYTHON};
}
pub use resolve::STDLIB_PREFIX;
pub use yaml::{NodeSpans, SpannedDocument};

/// A spec as read from disk (or given in memory).
#[derive(Debug, Clone)]
pub struct SpecSource {
    /// The name diagnostics show (usually the path as given).
    pub name: String,
    /// The folder relative files are resolved against first.
    pub dir: PathBuf,
    pub text: String,
}

impl SpecSource {
    /// Reads a spec file. Bytes that are not UTF-8 are a diagnostic, not a panic.
    pub fn read(path: &Path) -> Result<SpecSource, std::io::Error> {
        let bytes = std::fs::read(path)?;
        let text = String::from_utf8(bytes).map_err(|e| {
            std::io::Error::new(std::io::ErrorKind::InvalidData, format!("not UTF-8 text ({e})"))
        })?;
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let dir = if dir.as_os_str().is_empty() {
            PathBuf::from(".")
        } else {
            dir
        };
        Ok(SpecSource {
            name: path.display().to_string(),
            dir,
            text,
        })
    }
}

/// A spec that passed every check.
#[derive(Debug, Clone)]
pub struct CheckedSpec {
    pub spec: Spec,
    /// The spec with every preset expanded and every default filled in.
    pub resolved: serde_json::Value,
    pub resources: Resources,
    pub configurations: Vec<NamedConfiguration>,
    /// Problems that do not stop the spec (e.g. fidelities this build cannot run).
    pub warnings: Vec<SpecDiagnostic>,
    /// The spec's sweeps (`spec` holds every swept value at its first value).
    pub sweeps: Vec<sweep::Sweep>,
    /// The fidelities of the run matrix: each of the spec's, once per point of the sweeps
    /// that apply to it (`twin@delay_ms=80`), in matrix order.
    pub fidelity_points: indexmap::IndexMap<String, sweep::FidelityPoint>,
    /// The training section at every point of its sweeps (one point named `""` without
    /// them; none without `training:`).
    pub training_points: Vec<sweep::TrainingPoint>,
    /// Where every node of the spec's text is, for problems found after checking.
    doc: SpannedDocument,
    /// The spec's text, for those problems' diagnostics.
    source: Arc<miette::NamedSource<String>>,
}

impl CheckedSpec {
    /// Where to point for the node at the JSON `pointer` (e.g. `/policies/0/mlp/trained`): its
    /// key when it has one, else its value, else its nearest ancestor in the text.
    pub fn key_span(&self, pointer: &str) -> ByteSpan {
        let spans = self.doc.spans_at(pointer);
        spans.key.unwrap_or(spans.value)
    }

    /// A problem found after checking (by the interpreter, from files the checks do not read),
    /// as a diagnostic of this spec's text.
    pub fn diagnostic(&self, problem: Problem) -> SpecDiagnostic {
        SpecDiagnostic::new(problem, self.source.clone())
    }

    /// The run matrix.
    pub fn plan(&self) -> Vec<RunPlan> {
        matrix::expand_fidelities(
            &self.spec,
            self.fidelity_points.keys().map(String::as_str),
            &self.configurations,
        )
    }

    /// The spec with the fidelities of the run matrix (one per point of a sweep) in place of
    /// its own: what engines run.
    pub fn run_spec(&self) -> Spec {
        let mut spec = self.spec.clone();
        spec.fidelities = self
            .fidelity_points
            .iter()
            .map(|(name, point)| (name.clone(), point.fidelity.clone()))
            .collect();
        spec
    }

    /// The metrics of runs in the matrix fidelity `fidelity` (a point of a metric's sweep has
    /// its own).
    pub fn metrics_for(&self, fidelity: &str) -> &model::MetricsSpec {
        self.fidelity_points
            .get(fidelity)
            .and_then(|p| p.metrics.as_ref())
            .unwrap_or(&self.spec.metrics)
    }

    /// The training runs of `cpmx train` (one per seed; none without `training:`).
    pub fn training_plan(&self) -> Vec<TrainingPlan> {
        self.training_points
            .iter()
            .flat_map(|p| matrix::training_runs_at(&p.training, &p.name))
            .collect()
    }
}

/// Reads and checks a spec: syntax, presets, schema, meaning, files, and the interpreter's own
/// checks. Returns every problem found at the stage where checking had to stop.
pub fn check(
    source: &SpecSource,
    data: &DataPath,
    interpreter: &dyn InterpreterChecks,
) -> Result<CheckedSpec, Vec<SpecDiagnostic>> {
    check_scoped(source, data, interpreter, CheckScope::Run)
}

/// [`check`] for a purpose: [`CheckScope::Measure`] (scoring recorded runs) needs only the
/// map, runs none of the interpreter's checks and gives no warnings.
pub fn check_scoped(
    source: &SpecSource,
    data: &DataPath,
    interpreter: &dyn InterpreterChecks,
    scope: CheckScope,
) -> Result<CheckedSpec, Vec<SpecDiagnostic>> {
    let named = Arc::new(miette::NamedSource::new(&source.name, source.text.clone()).with_language("yaml"));
    let attach = |problems: Vec<Problem>| -> Vec<SpecDiagnostic> {
        problems
            .into_iter()
            .map(|p| SpecDiagnostic::new(p, named.clone()))
            .collect()
    };

    // Parse, keeping every node's place.
    let mut doc = yaml::parse(&source.text).map_err(&attach)?;

    // Expand presets; find the sweeps; check the shape of the document at every sweep's
    // every value (the others at their first).
    let mut problems = resolve::expand_presets(&mut doc);
    let sweep::Found {
        sweeps,
        problems: sweep_problems,
        mut refused,
    } = sweep::find(&doc);
    problems.extend(sweep_problems);
    // A preset that does not exist stays a name where a mapping belongs: the schema would say
    // so again, less helpfully.
    refused.extend(
        doc.spans
            .iter()
            .filter(|(_, spans)| {
                problems
                    .iter()
                    .any(|p| p.code == "cpmx::stdlib::unknown" && p.span == spans.value)
            })
            .map(|(pointer, _)| pointer.strip_suffix("/extends").unwrap_or(pointer).to_owned()),
    );
    // The spans of every node of a refused sweep or preset (mappings' spans only mark where
    // they open).
    let refused_spans: Vec<ByteSpan> = doc
        .spans
        .iter()
        .filter(|(pointer, _)| {
            refused.iter().any(|r| {
                pointer
                    .strip_prefix(r.as_str())
                    .is_some_and(|rest| rest.is_empty() || rest.starts_with('/'))
            })
        })
        .flat_map(|(_, spans)| [Some(spans.value), spans.key])
        .flatten()
        .collect();
    let about_a_refused_node = |p: &Problem| refused_spans.contains(&p.span);
    let mut base = doc.value.clone();
    for s in &sweeps {
        sweep::set(&mut base, &s.pointer, s.values[0]);
    }
    let at_first = SpannedDocument {
        value: base.clone(),
        spans: doc.spans.clone(),
    };
    problems.extend(
        schema::validate(&at_first)
            .into_iter()
            .filter(|p| !about_a_refused_node(p)),
    );
    for s in &sweeps {
        let site = doc.spans_at(&s.pointer).value;
        for (k, &value) in s.values.iter().enumerate().skip(1) {
            let mut variant = at_first.clone();
            sweep::set(&mut variant.value, &s.pointer, value);
            for mut p in schema::validate(&variant) {
                // A value of this sweep is out of range: point at it.
                if p.span == site {
                    let value_pointer = format!("{}/sweep/{k}", s.pointer);
                    p.span = doc.spans_at(&value_pointer).value;
                    p.pointer = Some(value_pointer);
                    if !problems.contains(&p) {
                        problems.push(p);
                    }
                }
            }
        }
    }
    if problems.iter().any(|p| p.level == Level::Error) {
        // Errors about one node do not stop the checks of meaning: they run without it, so one
        // pass reports `descripton` or a negative `sample_period_s` beside a wrong `ref_path` or
        // a missing file (the errors are kept).
        match repaired_for_meaning(&base, &problems, &refused) {
            Some(repaired) => base = repaired,
            None => return Err(attach(problems)),
        }
    }
    let early_problems = problems;
    let spec: Spec = match serde_json::from_value(base.clone()) {
        Ok(spec) => spec,
        // A repaired spec that does not read (a key whose default only the schema knows): the
        // schema's errors are the answer.
        Err(_) if early_problems.iter().any(|p| p.level == Level::Error) => {
            return Err(attach(early_problems));
        }
        Err(e) => {
            return Err(attach(vec![Problem::error(
                "cpmx::internal",
                format!("the spec passed the schema but cannot be read ({e}); please report this"),
                ByteSpan::new(0, 0),
                "",
            )]));
        }
    };

    // Check meaning, files, and what only the interpreter knows.
    let mut ctx = CheckContext::new(&doc);
    let resources = check::check_meaning(&spec, data, scope, &mut ctx);
    let before_interpreter = ctx.into_problems();
    // A SigmaRL checkpoint's observation, read from its `*_data.json`, is the policy's.
    let mut spec = spec;
    for (i, observation) in resources.observations.iter().enumerate() {
        if let Some(observation) = observation {
            spec.policies[i].observation = Some(observation.clone());
            if let (Some(policy), Ok(value)) = (
                doc.value
                    .pointer_mut(&format!("/policies/{i}"))
                    .and_then(serde_json::Value::as_object_mut),
                serde_json::to_value(observation),
            ) {
                policy.insert("observation".to_owned(), value);
            }
        }
    }
    let mut ctx = CheckContext::new(&doc);
    if scope == CheckScope::Run {
        check_fidelities::check_capabilities(&spec, interpreter, &mut ctx);
        // The interpreter's checks run on what is sound (a file not found is left out of
        // `resources`), so one pass reports a wrong `ref_path` beside a missing `planner`.
        interpreter.check(&spec, &resources, &mut ctx);
    }
    let mut problems = early_problems;
    problems.extend(before_interpreter);
    problems.extend(ctx.into_problems());
    if scope == CheckScope::Measure {
        problems.retain(|p| p.level == Level::Error);
    }
    problems.sort_by_key(|p| p.span.offset);
    let (errors, warnings): (Vec<Problem>, Vec<Problem>) =
        problems.into_iter().partition(|p| p.level == Level::Error);
    if !errors.is_empty() {
        let mut all = errors;
        all.extend(warnings);
        return Err(attach(all));
    }

    let configurations = matrix::configurations(&spec, &resources);
    let fidelity_points = sweep::fidelity_points(&base, &sweeps, &spec).map_err(|e| {
        attach(vec![Problem::error(
            "cpmx::internal",
            format!("{e}; please report this"),
            ByteSpan::new(0, 0),
            "",
        )])
    })?;
    // Scoring a folder made before this check existed still works (its comparison is empty).
    let reference_problems = match scope {
        CheckScope::Run => check_compare::check_reference(&spec, &fidelity_points, &doc),
        CheckScope::Measure => Vec::new(),
    };
    if !reference_problems.is_empty() {
        let mut all = reference_problems;
        all.extend(warnings);
        return Err(attach(all));
    }
    let training_points = sweep::training_points(&base, &sweeps).map_err(|e| {
        attach(vec![Problem::error(
            "cpmx::internal",
            format!("{e}; please report this"),
            ByteSpan::new(0, 0),
            "",
        )])
    })?;
    Ok(CheckedSpec {
        spec,
        resolved: doc.value.clone(),
        training_points,
        resources,
        configurations,
        warnings: attach(warnings),
        sweeps,
        fidelity_points,
        doc,
        source: named,
    })
}

/// `value` repaired so that the checks of meaning can still run, when the rest then passes the
/// schema; `None` otherwise. Keys that are not keys of the language are read as the key they
/// most likely mean (or left out), sweeps refused where they stand (`refused`) as their first
/// value, a sweep's later value out of range as the first, which is in range, and a wrong value
/// (type, range, choice) of a key with a default is left out, so that the default stands in.
/// Any other error stops: without the key (`planner`, a policy's `builtin`, a fidelity) the
/// checks of meaning would mostly say that it is missing. The errors themselves are kept and
/// reported.
fn repaired_for_meaning(
    value: &serde_json::Value,
    problems: &[Problem],
    refused: &[String],
) -> Option<serde_json::Value> {
    let mut repaired = value.clone();
    // A refused sweep stands for its first value; without one (`{sweep: []}`) any number put
    // there could raise problems of its own.
    for pointer in refused {
        let first = value
            .pointer(&format!("{pointer}/sweep/0"))
            .filter(|v| v.is_number())?;
        *repaired.pointer_mut(pointer)? = first.clone();
    }
    let errors = problems
        .iter()
        .filter(|p| p.level == Level::Error && !p.code.starts_with("cpmx::sweep::"));
    for problem in errors {
        // An error about no one node (or about a preset that does not exist) stops here.
        let pointer = problem.pointer.as_deref()?;
        match problem.code {
            // `plannr` is read as `planner`: the checks then do not also say the planner is
            // missing.
            "cpmx::schema::unknown-key" => move_member(&mut repaired, pointer, problem.suggestion.as_deref()),
            "cpmx::schema::missing" => return None,
            // A later value of a sweep: `repaired` holds the first.
            _ if pointer
                .rsplit_once('/')
                .is_some_and(|(p, _)| p.ends_with("/sweep")) => {}
            _ if schema::has_default(pointer) => move_member(&mut repaired, pointer, None),
            // A wrong item of a list whose key has a default (`group_by: [fidelity, polcy]`):
            // the default list stands in.
            _ if schema::has_default(list_of(pointer)) => move_member(&mut repaired, list_of(pointer), None),
            _ => return None,
        }
    }
    let clean = SpannedDocument {
        value: repaired,
        spans: Default::default(),
    };
    (!schema::validate(&clean).iter().any(|p| p.level == Level::Error)).then_some(clean.value)
}

/// The pointer of the list an item's pointer is in (`/report/group_by` of `/report/group_by/1`),
/// or the pointer itself when it is not a list item.
fn list_of(pointer: &str) -> &str {
    match pointer.rsplit_once('/') {
        Some((list, index)) if !index.is_empty() && index.bytes().all(|b| b.is_ascii_digit()) => list,
        _ => pointer,
    }
}

/// Moves the member at JSON pointer `pointer` to key `to` of the same mapping when that key is
/// free, else (or without `to`) removes it; nothing to do when an enclosing node is gone.
fn move_member(value: &mut serde_json::Value, pointer: &str, to: Option<&str>) {
    let Some((parent, key)) = pointer.rsplit_once('/') else {
        return;
    };
    let key = yaml::unescape_pointer(key);
    let Some(object) = value
        .pointer_mut(parent)
        .and_then(serde_json::Value::as_object_mut)
    else {
        return;
    };
    if let Some(member) = object.remove(&key)
        && let Some(to) = to.filter(|to| !object.contains_key(*to))
    {
        object.insert(to.to_owned(), member);
    }
}

/// Reads and checks a faults file (`cpmx lab emulate --faults FILE`): the mapping of a lab
/// fidelity's `faults`, for a lab that drives `vehicle_ids`.
pub fn check_faults(
    source: &SpecSource,
    vehicle_ids: &[u8],
) -> Result<model::LabFaults, Vec<SpecDiagnostic>> {
    let named = Arc::new(miette::NamedSource::new(&source.name, source.text.clone()).with_language("yaml"));
    let attach = |problems: Vec<Problem>| -> Vec<SpecDiagnostic> {
        problems
            .into_iter()
            .map(|p| SpecDiagnostic::new(p, named.clone()))
            .collect()
    };
    let doc = yaml::parse(&source.text).map_err(&attach)?;
    let problems = schema::validate_faults(&doc);
    if problems.iter().any(|p| p.level == Level::Error) {
        return Err(attach(problems));
    }
    let faults: model::LabFaults = serde_json::from_value(doc.value.clone()).map_err(|e| {
        attach(vec![Problem::error(
            "cpmx::internal",
            format!("the faults passed the schema but cannot be read ({e}); please report this"),
            ByteSpan::new(0, 0),
            "",
        )])
    })?;
    let mut ctx = CheckContext::new(&doc);
    check_lab::check_faults(&faults, vehicle_ids, "", &mut ctx);
    let problems = ctx.into_problems();
    if problems.is_empty() {
        Ok(faults)
    } else {
        Err(attach(problems))
    }
}

/// Keys a map-only spec may have.
const MAP_ONLY_KEYS: [&str; 4] = ["cpmx", "name", "description", "map"];

/// The map of a map-only spec (a spec with nothing but `cpmx`, `name`, `description` and
/// `map`, which `cpmx validate` answers with what the map holds), or `None` for any other
/// text, which [`check`] then judges.
pub fn map_only(source: &SpecSource) -> Option<model::MapSpec> {
    let doc = yaml::parse(&source.text).ok()?;
    let object = doc.value.as_object()?;
    if !object.contains_key("map") || object.keys().any(|k| !MAP_ONLY_KEYS.contains(&k.as_str())) {
        return None;
    }
    serde_json::from_value(object.get("map")?.clone()).ok()
}
