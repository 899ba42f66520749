//! Sweeps: `{sweep: [v1, v2, ...]}` in place of a number makes that number an axis of the run
//! matrix (spec-language.md, "Communication, perception and sweeps").
//!
//! A sweep may stand for a numeric parameter of a fidelity's layers (`dynamics`, `sensing`,
//! `actuation`, `communication`, `perception`), of the metrics, or of the training section's
//! `algorithm` and `reward`. Sweeps are found in the JSON document after presets are
//! expanded; each point of their grid is the same document with every sweep replaced by one of
//! its values, checked by the schema and read as an ordinary spec. A fidelity swept (or any
//! fidelity, for a metric's sweep) becomes one fidelity per point, named
//! `fidelity@name=value,...` (`twin-delays@delay_ms=80`), so run keys, `cpmx plan`, grouping,
//! pairing, shards and `--resume` treat points as fidelities; a training section swept trains
//! each point's policies.
//!
//! This module owns where sweeps may stand, what a point is called, and the grids.

use std::borrow::Cow;

use serde_json::Value;

use crate::diagnostic::Problem;
use crate::yaml::SpannedDocument;

/// What a sweep varies.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SweepScope {
    /// A layer parameter of one fidelity.
    Fidelity(String),
    /// A metric parameter (every fidelity's runs are scored at each point).
    Metrics,
    /// A training hyperparameter (each point trains its own policies).
    Training,
}

/// One `{sweep: [...]}` of a spec.
#[derive(Debug, Clone, PartialEq)]
pub struct Sweep {
    /// JSON pointer of the swept value.
    pub pointer: String,
    /// Its values, in the spec's order.
    pub values: Vec<f64>,
    pub scope: SweepScope,
    /// How points name it: the parameter's key (`delay_ms`), or its dotted path below the
    /// fidelity, the metrics or the training section when two sweeps share a key.
    pub label: String,
}

/// The layers of a fidelity whose numbers may be swept.
const LAYERS: [&str; 5] = ["dynamics", "sensing", "actuation", "communication", "perception"];

/// The sweeps of a document.
pub(crate) struct Found {
    /// The sweeps that may stand where they are, with their values.
    pub sweeps: Vec<Sweep>,
    /// Why the others were refused.
    pub problems: Vec<Problem>,
    /// Pointers of the refused `{sweep: ...}` objects: the schema's complaints about those
    /// nodes would say the same thing again.
    pub refused: Vec<String>,
}

/// Every sweep of `doc`, and the problems of those that may not stand where they are.
pub(crate) fn find(doc: &SpannedDocument) -> Found {
    let mut sites = Vec::new();
    collect(&doc.value, String::new(), &mut sites);
    let mut sweeps = Vec::new();
    let mut problems = Vec::new();
    let mut refused = Vec::new();
    for (pointer, list) in sites {
        let spans = doc.spans_at(&pointer);
        let at = spans.key.unwrap_or(spans.value);
        let segments: Vec<&str> = pointer.split('/').skip(1).collect();
        let inside_distribution = segments.iter().any(|s| *s == "uniform" || *s == "normal");
        let scope = match segments.as_slice() {
            _ if inside_distribution => None,
            ["fidelities", name, layer, ..] if LAYERS.contains(layer) => {
                Some(SweepScope::Fidelity(crate::yaml::unescape_pointer(name)))
            }
            ["metrics", _, ..] => Some(SweepScope::Metrics),
            ["training", "algorithm" | "reward", _, ..] => Some(SweepScope::Training),
            _ => None,
        };
        let Some(scope) = scope else {
            let message = if inside_distribution {
                "a sweep inside a distribution".to_owned()
            } else {
                format!(
                    "`{}` cannot be swept",
                    crate::schema::describe(&pointer).trim_matches('`')
                )
            };
            problems.push(
                Problem::error("cpmx::sweep::place", message, at, "not sweepable here").with_help(
                    "a sweep stands for a number of a fidelity's layers (dynamics, sensing, actuation, \
                     communication, perception), of `metrics`, or of `training.algorithm` or \
                     `training.reward`; to draw a value per run use a distribution instead",
                ),
            );
            refused.push(pointer);
            continue;
        };
        let values: Option<Vec<f64>> = list.iter().map(Value::as_f64).collect();
        if values.as_ref().is_none_or(Vec::is_empty) {
            refused.push(pointer.clone());
        }
        match values {
            None => problems.push(
                Problem::error(
                    "cpmx::sweep::values",
                    "a sweep lists numbers",
                    doc.spans_at(&format!("{pointer}/sweep")).value,
                    "not a list of numbers",
                )
                .with_help("e.g. `{sweep: [0, 40, 80]}`"),
            ),
            Some(values) if values.is_empty() => problems.push(
                Problem::error(
                    "cpmx::sweep::empty",
                    "an empty sweep",
                    doc.spans_at(&format!("{pointer}/sweep")).value,
                    "no value",
                )
                .with_help(
                    "list the values to run, e.g. `{sweep: [0, 40, 80]}`; for one value write the number",
                ),
            ),
            Some(values) => {
                let mut seen: Vec<f64> = Vec::new();
                for (k, v) in values.iter().enumerate() {
                    if seen.contains(v) {
                        problems.push(Problem::error(
                            "cpmx::sweep::values",
                            format!("the sweep lists {v} twice"),
                            doc.spans_at(&format!("{pointer}/sweep/{k}")).value,
                            "repeated",
                        ));
                    }
                    seen.push(*v);
                }
                sweeps.push(Sweep {
                    label: key_of(&pointer),
                    pointer,
                    values,
                    scope,
                });
            }
        }
    }
    disambiguate(&mut sweeps);
    Found {
        sweeps,
        problems,
        refused,
    }
}

/// Every `{sweep: ...}` object below `value` (exactly one key), with its pointer.
fn collect(value: &Value, pointer: String, out: &mut Vec<(String, Vec<Value>)>) {
    match value {
        Value::Object(map) => {
            if map.len() == 1
                && let Some(list) = map.get("sweep")
            {
                out.push((pointer, list.as_array().cloned().unwrap_or_default()));
                return;
            }
            for (key, child) in map {
                collect(
                    child,
                    format!("{pointer}/{}", crate::yaml::escape_pointer(key)),
                    out,
                );
            }
        }
        Value::Array(items) => {
            for (i, child) in items.iter().enumerate() {
                collect(child, format!("{pointer}/{i}"), out);
            }
        }
        _ => {}
    }
}

/// The last key of a pointer (`/fidelities/twin/actuation/delay_ms` → `delay_ms`).
fn key_of(pointer: &str) -> String {
    pointer.rsplit('/').next().unwrap_or_default().to_owned()
}

/// The path below the fidelity, the metrics or the training section.
fn path_of(sweep: &Sweep) -> String {
    let skip = match sweep.scope {
        SweepScope::Fidelity(_) => 3,
        SweepScope::Metrics | SweepScope::Training => 2,
    };
    sweep.pointer.split('/').skip(skip).collect::<Vec<_>>().join(".")
}

/// Sweeps of one matrix axis that share a key are named by their paths instead.
fn disambiguate(sweeps: &mut [Sweep]) {
    let labels: Vec<String> = sweeps.iter().map(|s| s.label.clone()).collect();
    for i in 0..sweeps.len() {
        let clash = (0..sweeps.len()).any(|j| j != i && labels[j] == labels[i]);
        if clash {
            sweeps[i].label = path_of(&sweeps[i]);
        }
    }
}

/// The document with the sweep at `pointer` replaced by `value`.
pub(crate) fn set(doc: &mut Value, pointer: &str, value: f64) {
    if let Some(slot) = doc.pointer_mut(pointer) {
        *slot = Value::from(value);
    }
}

/// The grid of `sweeps`: one list of value indices per point, the first sweep varying
/// slowest (one empty point without sweeps).
pub fn grid(sweeps: &[&Sweep]) -> Vec<Vec<usize>> {
    let mut points: Vec<Vec<usize>> = vec![Vec::new()];
    for sweep in sweeps {
        points = points
            .into_iter()
            .flat_map(|p| {
                (0..sweep.values.len()).map(move |k| {
                    let mut q = p.clone();
                    q.push(k);
                    q
                })
            })
            .collect();
    }
    points
}

/// A point's name suffix: `@delay_ms=80+drop_probability=0.1` (empty without sweeps).
pub fn point_suffix(sweeps: &[&Sweep], point: &[usize]) -> String {
    if sweeps.is_empty() {
        return String::new();
    }
    let parts: Vec<String> = sweeps
        .iter()
        .zip(point)
        .map(|(s, &k)| format!("{}={}", s.label, s.values[k]))
        .collect();
    format!("@{}", parts.join("+"))
}

/// The fidelity of the run matrix that `fidelity` is paired with in the report's comparison
/// with `reference` (a fidelity of the spec, or one point of a swept one), among the run
/// matrix's fidelities `names`: for a point of a sweep (`twin@delay_ms=80+slack=0.1`), the
/// point of the reference whose swept values it shares (a metric parameter's sweep makes
/// `sim@slack=0.1`), else the reference itself. The result may not be a name of the matrix: a
/// swept reference has no run under its bare name (`cpmx validate` refuses that spec).
pub fn paired_reference<'a, 'n>(
    fidelity: &str,
    reference: &'a str,
    names: impl IntoIterator<Item = &'n str>,
) -> Cow<'a, str> {
    let Some((_, point)) = fidelity.split_once('@') else {
        return Cow::Borrowed(reference);
    };
    let values: Vec<&str> = point.split('+').collect();
    names
        .into_iter()
        .find(|name| {
            name.split_once('@').is_some_and(|(base, at)| {
                base == reference && at.split('+').all(|value| values.contains(&value))
            })
        })
        .map_or(Cow::Borrowed(reference), |name| Cow::Owned(name.to_owned()))
}

/// The spec's fidelity a name of the run matrix belongs to: `twin` for `twin@delay_ms=80`.
pub fn base_fidelity(name: &str) -> &str {
    name.split_once('@').map_or(name, |(base, _)| base)
}

/// Whether `fidelity` (a name of the run matrix) is the comparison's `reference`, or a point of
/// it when the reference fidelity is swept.
pub fn is_reference(fidelity: &str, reference: &str) -> bool {
    fidelity == reference || base_fidelity(fidelity) == reference
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_pair_with_the_reference_at_the_same_point_else_with_the_reference() {
        let names = [
            "sim@slack=0",
            "sim@slack=0.1",
            "twin@delay_ms=80+slack=0.1",
            "lab",
        ];
        assert_eq!(
            paired_reference("twin@delay_ms=80+slack=0.1", "sim", names),
            "sim@slack=0.1"
        );
        assert_eq!(paired_reference("lab", "sim", names), "sim");
        // One point of a swept fidelity as the reference: every other point pairs with it.
        assert_eq!(
            paired_reference("sim@slack=0.1", "sim@slack=0", names),
            "sim@slack=0"
        );
        assert!(is_reference("sim@slack=0.1", "sim") && is_reference("sim", "sim"));
        assert!(!is_reference("sim@slack=0.1", "sim@slack=0") && !is_reference("sim-mpc", "sim"));
    }

    fn sweep(label: &str, values: &[f64]) -> Sweep {
        Sweep {
            pointer: format!("/x/{label}"),
            values: values.to_vec(),
            scope: SweepScope::Metrics,
            label: label.into(),
        }
    }

    #[test]
    fn grids_vary_the_first_sweep_slowest() {
        let (a, b) = (sweep("a", &[1.0, 2.0]), sweep("b", &[0.0, 40.0, 80.0]));
        let points = grid(&[&a, &b]);
        assert_eq!(points.len(), 6);
        assert_eq!(points[0], [0, 0]);
        assert_eq!(points[1], [0, 1]);
        assert_eq!(points[3], [1, 0]);
        assert_eq!(point_suffix(&[&a, &b], &points[5]), "@a=2+b=80");
        assert_eq!(grid(&[]), vec![Vec::<usize>::new()]);
    }
}

/// One fidelity of the run matrix: a fidelity of the spec at one point of the sweeps that
/// apply to it (its own layers' and the metrics').
#[derive(Debug, Clone, PartialEq)]
pub struct FidelityPoint {
    /// The fidelity's name in the spec.
    pub base: String,
    /// The swept values of this point, by label.
    pub values: Vec<(String, f64)>,
    pub fidelity: crate::model::Fidelity,
    /// The metrics at this point, when a metric parameter is swept.
    pub metrics: Option<crate::model::MetricsSpec>,
}

/// Every fidelity of the run matrix, by name (`fidelity` or `fidelity@label=value,...`), in
/// the spec's order of fidelities and then grid order; `base` is the document with every sweep
/// at its first value.
pub(crate) fn fidelity_points(
    base: &Value,
    sweeps: &[Sweep],
    spec: &crate::model::Spec,
) -> Result<indexmap::IndexMap<String, FidelityPoint>, String> {
    let mut out = indexmap::IndexMap::new();
    for (name, fidelity) in &spec.fidelities {
        let applying: Vec<&Sweep> = sweeps
            .iter()
            .filter(|s| s.scope == SweepScope::Metrics || s.scope == SweepScope::Fidelity(name.clone()))
            .collect();
        if applying.is_empty() {
            out.insert(
                name.clone(),
                FidelityPoint {
                    base: name.clone(),
                    values: Vec::new(),
                    fidelity: fidelity.clone(),
                    metrics: None,
                },
            );
            continue;
        }
        let metric_swept = applying.iter().any(|s| s.scope == SweepScope::Metrics);
        for point in grid(&applying) {
            let mut doc = base.clone();
            for (sweep, &k) in applying.iter().zip(&point) {
                set(&mut doc, &sweep.pointer, sweep.values[k]);
            }
            let variant: crate::model::Spec = serde_json::from_value(doc)
                .map_err(|e| format!("a point of the sweeps cannot be read: {e}"))?;
            let Some(fidelity) = variant.fidelities.get(name).cloned() else {
                continue;
            };
            out.insert(
                format!("{name}{}", point_suffix(&applying, &point)),
                FidelityPoint {
                    base: name.clone(),
                    values: applying
                        .iter()
                        .zip(&point)
                        .map(|(s, &k)| (s.label.clone(), s.values[k]))
                        .collect(),
                    fidelity,
                    metrics: metric_swept.then_some(variant.metrics),
                },
            );
        }
    }
    Ok(out)
}

/// The training section at one point of its sweeps.
#[derive(Debug, Clone, PartialEq)]
pub struct TrainingPoint {
    /// `lr=0.001+epochs=10` (empty without training sweeps): the point's folder below
    /// `cpmx train`'s output folder, and what `mlp: {trained: {point}}` names.
    pub name: String,
    /// The section as it trains at this point.
    pub training: crate::model::TrainingSpec,
    /// Its resolved JSON (presets expanded), for the fingerprint.
    pub resolved: Value,
}

/// The training section at every point of the training sweeps (one point named `""` without
/// them); `base` is the document with every sweep at its first value.
pub(crate) fn training_points(base: &Value, sweeps: &[Sweep]) -> Result<Vec<TrainingPoint>, String> {
    let applying: Vec<&Sweep> = sweeps
        .iter()
        .filter(|s| s.scope == SweepScope::Training)
        .collect();
    grid(&applying)
        .into_iter()
        .filter_map(|point| {
            let mut doc = base.clone();
            for (sweep, &k) in applying.iter().zip(&point) {
                set(&mut doc, &sweep.pointer, sweep.values[k]);
            }
            let resolved = doc.get("training").cloned()?;
            let training = match serde_json::from_value(resolved.clone()) {
                Ok(t) => t,
                Err(e) => return Some(Err(format!("a point of the training sweeps cannot be read: {e}"))),
            };
            let name = point_suffix(&applying, &point).trim_start_matches('@').to_owned();
            Some(Ok(TrainingPoint {
                name,
                training,
                resolved,
            }))
        })
        .collect()
}
