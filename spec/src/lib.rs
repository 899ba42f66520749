//! The cpmx experiment language: types, YAML with spans, the JSON Schema, meaning checks with
//! miette diagnostics, `stdlib:` resolution, and the run matrix with its seeds.
//!
//! This crate is the syntax layer: it knows nothing about simulation. The interpreter adds the
//! checks that need a map or a network through [`InterpreterChecks`].
//!
//! ```text
//! text ──parse──► spanned JSON ──expand presets──► schema ──► typed Spec ──► meaning checks
//! ```

mod check;
mod check_lab;
mod check_training;
mod diagnostic;
pub mod matrix;
pub mod model;
mod paths;
pub mod reference;
mod resolve;
pub mod schema;
mod yaml;

use std::path::{Path, PathBuf};
use std::sync::Arc;

pub use check::{CheckContext, CheckScope, InterpreterChecks, Resources};
pub use diagnostic::{ByteSpan, Level, Problem, SpecDiagnostic, render};
pub use matrix::{ConfigurationSource, NamedConfiguration, RunPlan, TrainingPlan};
pub use model::Spec;
pub use paths::{DataPath, NotFound, sha256_hex};
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
        matrix::expand(&self.spec, &self.configurations)
    }

    /// The training runs of `cpmx train` (one per seed; none without `training:`).
    pub fn training_plan(&self) -> Vec<TrainingPlan> {
        matrix::training_runs(&self.spec)
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

    // Expand presets, then check the shape of the whole document.
    let mut problems = resolve::expand_presets(&mut doc);
    problems.extend(schema::validate(&doc));
    if problems.iter().any(|p| p.level == Level::Error) {
        return Err(attach(problems));
    }
    let early_warnings = problems;
    let spec: Spec = match serde_json::from_value(doc.value.clone()) {
        Ok(spec) => spec,
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
    let mut ctx = CheckContext::new(&doc);
    if scope == CheckScope::Run {
        check::check_capabilities(&spec, interpreter, &mut ctx);
        // The interpreter's checks run on what is sound (a file not found is left out of
        // `resources`), so one pass reports a wrong `ref_path` beside a missing `planner`.
        interpreter.check(&spec, &resources, &mut ctx);
    }
    let mut problems = early_warnings;
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
    Ok(CheckedSpec {
        spec,
        resolved: doc.value.clone(),
        resources,
        configurations,
        warnings: attach(warnings),
        doc,
        source: named,
    })
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
