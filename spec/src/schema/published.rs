//! The published JSON Schema (`cpmx schema`, `cpmx.schema.json`): schemars' schema of
//! [`Spec`] with the defaults a reader should see, preset keys optional with their preset as
//! default, and the run matrix's keys without serde's defaults for training-only specs.

use serde_json::Value;

use crate::model::Spec;

/// The published JSON Schema (draft 2020-12), as `cpmx schema` prints it.
pub fn json_schema() -> Value {
    let mut schema = schemars::schema_for!(Spec).to_value();
    if let Some(root) = schema.as_object_mut() {
        root.insert(
            "$id".into(),
            Value::from("https://cpmx.dev/schema/v1/cpmx.schema.json"),
        );
    }
    mark_preset_defaults(&mut schema);
    unmark_run_matrix_defaults(&mut schema);
    schema
}

/// The run matrix's keys (`agents`, `seed`, ...: the schema's `then` requires them unless the
/// spec only trains) carry serde's defaults for training-only specs; shown as their defaults
/// they would read as optional in an editor and in the language reference.
fn unmark_run_matrix_defaults(schema: &mut Value) {
    let keys: Vec<String> = schema
        .pointer("/then/required")
        .and_then(Value::as_array)
        .map(|keys| {
            keys.iter()
                .filter_map(|k| k.as_str().map(str::to_owned))
                .collect()
        })
        .unwrap_or_default();
    for key in keys {
        if let Some(property) = schema
            .pointer_mut(&format!("/properties/{key}"))
            .and_then(Value::as_object_mut)
        {
            property.remove("default");
        }
    }
}

/// The keys cpmx fills with a preset when a spec leaves them out (`vehicle`, `metrics`,
/// `training.observation`): optional, with that preset as their default, since serde sees
/// them only after `resolve` has inserted them.
fn mark_preset_defaults(schema: &mut Value) {
    for default in &crate::resolve::PRESET_DEFAULTS {
        let object = match default.definition {
            None => Some(&mut *schema),
            Some(name) => schema.pointer_mut(&format!("/$defs/{name}")),
        };
        let Some(object) = object.and_then(Value::as_object_mut) else {
            continue;
        };
        if let Some(required) = object.get_mut("required").and_then(Value::as_array_mut) {
            required.retain(|key| key != default.key);
        }
        if let Some(property) = object
            .get_mut("properties")
            .and_then(|p| p.get_mut(default.key))
            .and_then(Value::as_object_mut)
        {
            property.insert("default".into(), Value::from(default.value));
        }
    }
}

/// The published schema as pretty-printed text with a final newline (`cpmx.schema.json`).
pub fn json_schema_text() -> String {
    let mut text = serde_json::to_string_pretty(&json_schema()).unwrap_or_default();
    text.push('\n');
    text
}
