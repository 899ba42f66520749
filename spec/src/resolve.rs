//! Expanding `stdlib:NAME` references and `extends:` overrides into the presets' content, and
//! filling in the preset-valued defaults (`vehicle`, `metrics`, `observation`).
//!
//! Expansion works on the JSON document before the schema sees it, so that a preset is checked
//! exactly like the same object written inline; a problem inside expanded content points at
//! the reference.

use cpmx_stdlib::PresetKind;
use serde_json::Value;

use crate::diagnostic::{ByteSpan, Problem};
use crate::yaml::{SpannedDocument, escape_pointer};

/// The prefix of a standard-library reference.
pub const STDLIB_PREFIX: &str = "stdlib:";

/// Where presets may appear: (pointer of the field, kind).
fn preset_fields(doc: &Value) -> Vec<(String, PresetKind)> {
    let mut fields = vec![
        ("/vehicle".to_owned(), PresetKind::Vehicle),
        ("/metrics".to_owned(), PresetKind::Metrics),
        // After `/metrics`: a preset of metrics expands first, then its footprint.
        ("/metrics/footprint".to_owned(), PresetKind::Vehicle),
    ];
    if let Some(policies) = doc.get("policies").and_then(Value::as_array) {
        for (i, _) in policies.iter().enumerate() {
            fields.push((format!("/policies/{i}/observation"), PresetKind::Observation));
        }
    }
    if doc.get("training").is_some_and(Value::is_object) {
        fields.push(("/training/scenario".to_owned(), PresetKind::TrainingScenario));
        fields.push(("/training/reward".to_owned(), PresetKind::Reward));
        fields.push(("/training/algorithm".to_owned(), PresetKind::Algorithm));
        fields.push(("/training/observation".to_owned(), PresetKind::Observation));
    }
    if let Some(fidelities) = doc.get("fidelities").and_then(Value::as_object) {
        for name in fidelities.keys() {
            let base = format!("/fidelities/{}", escape_pointer(name));
            fields.push((format!("{base}/dynamics"), PresetKind::Dynamics));
            fields.push((format!("{base}/sensing"), PresetKind::Sensing));
            fields.push((format!("{base}/safety"), PresetKind::Safety));
        }
    }
    fields
}

/// The keys of the run matrix, which a spec that only trains leaves out.
/// (`fidelities` may stay: a spec that only trains can define the fidelity it trains in.)
const MATRIX_KEYS: [&str; 5] = [
    "agents",
    "policies",
    "initial_configurations",
    "repetitions",
    "seed",
];

/// A key whose default is a preset, filled in before the schema sees the spec.
pub(crate) struct PresetDefault {
    /// The JSON pointer of the object that holds the key (`""`: the spec's top level).
    pub parent: &'static str,
    /// The schema definition of that object (`None`: the spec's top level).
    pub definition: Option<&'static str>,
    /// The key.
    pub key: &'static str,
    /// The preset it takes when the spec leaves it out.
    pub value: &'static str,
}

/// The preset-valued defaults. The published schema marks these keys optional with this
/// default (`schema.rs`), so the language reference never calls them required.
pub(crate) const PRESET_DEFAULTS: [PresetDefault; 3] = [
    PresetDefault {
        parent: "",
        definition: None,
        key: "vehicle",
        value: "stdlib:mu-car",
    },
    PresetDefault {
        parent: "",
        definition: None,
        key: "metrics",
        value: "stdlib:at25",
    },
    PresetDefault {
        parent: "/training",
        definition: Some("TrainingSpec"),
        key: "observation",
        value: "stdlib:sigmarl",
    },
];

/// Inserts the preset-valued defaults where the spec leaves them out.
fn insert_defaults(doc: &mut Value) {
    for default in &PRESET_DEFAULTS {
        if let Some(object) = doc.pointer_mut(default.parent).and_then(Value::as_object_mut) {
            object
                .entry(default.key)
                .or_insert_with(|| Value::from(default.value));
        }
    }
    let Some(root) = doc.as_object_mut() else { return };
    if root.get("training").is_some_and(Value::is_object) {
        // A spec that only trains (no key of the run matrix): SigmaRL's step and, unless it
        // defines its own fidelities, SigmaRL's simulation as `sim` (the default
        // `training.fidelity`, whether the section names it or not).
        let trains_only = MATRIX_KEYS.iter().all(|k| !root.contains_key(*k));
        if trains_only {
            root.entry("timing")
                .or_insert_with(|| serde_json::json!({"dt": 0.1, "steps": 180}));
            if !root.contains_key("fidelities") {
                root.insert(
                    "fidelities".to_owned(),
                    serde_json::json!({"sim": {"control": "direct", "dynamics": "kinematic"}}),
                );
            }
        }
    }
    // A network's observation: SigmaRL's, or for an actor this spec trains, the one it is
    // trained with.
    let trained_with = root
        .get("training")
        .and_then(|t| t.get("observation"))
        .cloned()
        .unwrap_or_else(|| Value::from("stdlib:sigmarl"));
    if let Some(policies) = root.get_mut("policies").and_then(Value::as_array_mut) {
        for policy in policies.iter_mut().filter_map(Value::as_object_mut) {
            let trained = policy.get("mlp").and_then(|m| m.get("trained")).is_some();
            // A SigmaRL checkpoint's observation comes from its `*_data.json` (check_files).
            let checkpoint = policy.get("mlp").and_then(|m| m.get("sigmarl")).is_some();
            if !checkpoint
                && (policy.contains_key("mlp")
                    || policy.contains_key("onnx")
                    || policy.contains_key("python"))
            {
                policy.entry("observation").or_insert_with(|| {
                    if trained {
                        trained_with.clone()
                    } else {
                        Value::from("stdlib:sigmarl")
                    }
                });
            }
        }
    }
}

/// Expands every preset reference of `doc` in place; unknown names are errors, old names of
/// renamed presets warnings.
pub fn expand_presets(doc: &mut SpannedDocument) -> Vec<Problem> {
    insert_defaults(&mut doc.value);
    let mut problems = Vec::new();
    let mut renames = Vec::new();
    for (pointer, kind) in preset_fields(&doc.value) {
        let Some(node) = doc.value.pointer(&pointer).cloned() else {
            continue;
        };
        let spans = doc.spans_at(&pointer);
        let mut current = |reference: &str, span: ByteSpan| -> String {
            let name = &reference[STDLIB_PREFIX.len()..];
            match cpmx_stdlib::renamed(kind, name) {
                Some(new) => {
                    renames.push(
                        Problem::warning(
                            "cpmx::stdlib::renamed",
                            format!(
                                "`{reference}` as a {} is now called `{STDLIB_PREFIX}{new}`",
                                kind.label()
                            ),
                            span,
                            "old name",
                        )
                        .with_help(format!(
                            "write `{STDLIB_PREFIX}{new}`: every stdlib name now means one preset \
                             whatever field it is in (the old name still reads the same preset)"
                        )),
                    );
                    new.to_owned()
                }
                None => name.to_owned(),
            }
        };
        let expanded = match &node {
            Value::String(s) if s.starts_with(STDLIB_PREFIX) => {
                let name = current(s, spans.value);
                load_preset(kind, &name).map_err(|help| (spans.value, s.clone(), help))
            }
            Value::Object(map) => match map.get("extends") {
                Some(Value::String(s)) if s.starts_with(STDLIB_PREFIX) => {
                    let extends_span = doc.spans_at(&format!("{pointer}/extends")).value;
                    let name = current(s, extends_span);
                    load_preset(kind, &name)
                        .map(|mut base| {
                            let mut overrides = map.clone();
                            overrides.remove("extends");
                            merge(&mut base, Value::Object(overrides));
                            base
                        })
                        .map_err(|help| (extends_span, s.clone(), help))
                }
                _ => continue,
            },
            _ => continue,
        };
        match expanded {
            Ok(value) => {
                if let Some(slot) = doc.value.pointer_mut(&pointer) {
                    *slot = value;
                }
            }
            Err((span, reference, help)) => problems.push(
                Problem::error(
                    "cpmx::stdlib::unknown",
                    format!(
                        "the standard library has no {} called `{reference}`",
                        kind.label()
                    ),
                    span,
                    "unknown preset",
                )
                .with_help(help),
            ),
        }
    }
    problems.extend(renames);
    problems
}

/// The JSON content of a preset, or the help text that lists the available names.
fn load_preset(kind: PresetKind, name: &str) -> Result<Value, String> {
    match cpmx_stdlib::preset(kind, name) {
        Some(preset) => serde_saphyr::from_str::<Value>(preset.yaml)
            .map_err(|e| format!("the shipped preset `stdlib:{name}` is broken ({e}); please report this")),
        None => {
            let names: Vec<String> = cpmx_stdlib::names(kind).into_iter().map(str::to_owned).collect();
            Err(match crate::schema::did_you_mean(name, &names) {
                Some(best) => format!("did you mean `{STDLIB_PREFIX}{best}`? {}", available_help(kind)),
                None => available_help(kind),
            })
        }
    }
}

/// "available: stdlib:a, stdlib:b" for a kind.
pub fn available_help(kind: PresetKind) -> String {
    let names: Vec<String> = cpmx_stdlib::names(kind)
        .into_iter()
        .map(|n| format!("{STDLIB_PREFIX}{n}"))
        .collect();
    format!("available {}s: {}", kind.label(), names.join(", "))
}

/// Overrides `base` with `overrides`, recursively for objects.
fn merge(base: &mut Value, overrides: Value) {
    match (base, overrides) {
        (Value::Object(b), Value::Object(o)) => {
            for (k, v) in o {
                match b.get_mut(&k) {
                    Some(slot) => merge(slot, v),
                    None => {
                        b.insert(k, v);
                    }
                }
            }
        }
        (slot, v) => *slot = v,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::yaml::parse;

    #[test]
    fn every_shipped_preset_parses() {
        for p in cpmx_stdlib::PRESETS.iter().filter(|p| p.kind != PresetKind::Map) {
            assert!(load_preset(p.kind, p.name).unwrap().is_object(), "{}", p.name);
        }
    }

    #[test]
    fn extends_overrides_single_fields() {
        let mut doc = parse("vehicle: {extends: stdlib:mu-car, width: 0.2}\n").unwrap();
        assert!(expand_presets(&mut doc).is_empty());
        assert_eq!(doc.value["vehicle"]["width"], 0.2);
        assert_eq!(doc.value["vehicle"]["length"], 0.22);
        assert!(doc.value["vehicle"].get("extends").is_none());
    }

    #[test]
    fn unknown_names_list_the_available_ones() {
        let mut doc = parse("vehicle: stdlib:mu-cat\n").unwrap();
        let problems = expand_presets(&mut doc);
        assert_eq!(problems.len(), 1);
        assert!(problems[0].help.as_deref().unwrap().contains("stdlib:mu-car"));
    }
}
