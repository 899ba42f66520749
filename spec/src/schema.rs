//! The JSON Schema of the language, and schema validation mapped back to spans.
//!
//! The published schema (`cpmx schema`, `cpmx.schema.json`) lets preset fields be a
//! `stdlib:NAME` string or an `extends` object. cpmx validates *after* expanding presets, with
//! a strict variant in which every such field is its inline object only, so a problem inside a
//! preset override is reported against the object's own fields.

use std::sync::OnceLock;

use jsonschema::error::{TypeKind, ValidationErrorKind};
use jsonschema::{ValidationError, Validator};
use serde_json::Value;

pub use published::{json_schema, json_schema_text};

use crate::diagnostic::Problem;
use crate::yaml::{SpannedDocument, escape_pointer, unescape_pointer};

/// The strict schema: every preset field reduced to its inline object.
fn strict_schema() -> &'static (Value, Option<Validator>) {
    static STRICT: OnceLock<(Value, Option<Validator>)> = OnceLock::new();
    STRICT.get_or_init(|| {
        let mut schema = json_schema();
        reduce_presets(&mut schema);
        let validator = jsonschema::options()
            .should_validate_formats(false)
            .build(&schema)
            .ok();
        (schema, validator)
    })
}

/// Whether the key at JSON pointer `pointer` is a named member of a mapping of the language
/// that has a default (`on_collision`, a metric's parameter): leaving it out then means its
/// default, not a missing part. Entries of user-named mappings (a fidelity, a policy's name)
/// and list items have none.
pub(crate) fn has_default(pointer: &str) -> bool {
    let (schema, _) = strict_schema();
    let segments: Vec<String> = pointer.split('/').skip(1).map(unescape_pointer).collect();
    let Some((last, parents)) = segments.split_last() else {
        return false;
    };
    parents
        .iter()
        .try_fold(schema, |node, segment| child_schema(schema, node, segment))
        .and_then(|node| property_schema(schema, node, last))
        .is_some_and(|property| property.get("default").is_some())
}

/// `node` with its `$ref`s followed.
fn resolve_refs<'a>(schema: &'a Value, mut node: &'a Value) -> &'a Value {
    while let Some(target) = node.get("$ref").and_then(Value::as_str) {
        match schema.pointer(target.trim_start_matches('#')) {
            Some(next) if !std::ptr::eq(next, node) => node = next,
            _ => break,
        }
    }
    node
}

/// The branches of a schema's `anyOf`, `oneOf` and `allOf`.
fn branches(node: &Value) -> impl Iterator<Item = &Value> {
    ["anyOf", "oneOf", "allOf"]
        .into_iter()
        .filter_map(|k| node.get(k).and_then(Value::as_array))
        .flatten()
}

/// The schema of property `key` of the object schema `node`, also in its branches: the
/// property's own node, whose `default` sits beside its `$ref`.
fn property_schema<'a>(schema: &'a Value, node: &'a Value, key: &str) -> Option<&'a Value> {
    let node = resolve_refs(schema, node);
    node.get("properties")
        .and_then(|p| p.get(key))
        .or_else(|| branches(node).find_map(|branch| property_schema(schema, branch, key)))
}

/// The schema of the value at `segment` below `node`: a property, else an entry of a mapping
/// or an item of a list.
fn child_schema<'a>(schema: &'a Value, node: &'a Value, segment: &str) -> Option<&'a Value> {
    property_schema(schema, node, segment).or_else(|| {
        let node = resolve_refs(schema, node);
        branches(node)
            .find_map(|branch| child_schema(schema, branch, segment))
            .or_else(|| node.get("additionalProperties").filter(|n| n.is_object()))
            .or_else(|| node.get("items").filter(|n| n.is_object()))
    })
}

fn reduce_presets(node: &mut Value) {
    match node {
        Value::Object(map) => {
            if map.get("x-cpmx-preset") == Some(&Value::Bool(true)) {
                let inline = map
                    .get("anyOf")
                    .and_then(|a| a.get(0))
                    .cloned()
                    .unwrap_or(Value::Bool(true));
                *node = inline;
                reduce_presets(node);
                return;
            }
            map.values_mut().for_each(reduce_presets);
        }
        Value::Array(items) => items.iter_mut().for_each(reduce_presets),
        _ => {}
    }
}

/// Validates the expanded document against the strict schema; every error becomes a problem.
pub fn validate(doc: &SpannedDocument) -> Vec<Problem> {
    let (schema, validator) = strict_schema();
    validate_with(schema, validator.as_ref(), doc)
}

/// The schema of a faults file (`cpmx lab emulate --faults`): a lab fidelity's `faults`.
fn faults_schema() -> &'static (Value, Option<Validator>) {
    static FAULTS: OnceLock<(Value, Option<Validator>)> = OnceLock::new();
    FAULTS.get_or_init(|| {
        let schema = schemars::schema_for!(crate::model::LabFaults).to_value();
        let validator = jsonschema::options()
            .should_validate_formats(false)
            .build(&schema)
            .ok();
        (schema, validator)
    })
}

/// Validates a faults file against the schema of `faults`; every error becomes a problem.
pub(crate) fn validate_faults(doc: &SpannedDocument) -> Vec<Problem> {
    let (schema, validator) = faults_schema();
    validate_with(schema, validator.as_ref(), doc)
}

fn validate_with(schema: &Value, validator: Option<&Validator>, doc: &SpannedDocument) -> Vec<Problem> {
    let Some(validator) = validator else {
        return vec![Problem::error(
            "cpmx::internal",
            "cpmx's own schema does not compile; please report this",
            crate::diagnostic::ByteSpan::new(0, 0),
            "",
        )];
    };
    let mut problems = Vec::new();
    for error in validator.iter_errors(&doc.value) {
        map_error(schema, doc, &error, &mut problems);
    }
    // A missing key that an unknown key's "did you mean" already names is the same mistake.
    let suggested: Vec<String> = problems
        .iter()
        .filter(|p| p.code == "cpmx::schema::unknown-key")
        .filter_map(|p| p.suggestion.clone())
        .collect();
    problems.retain(|p| {
        p.code != "cpmx::schema::missing"
            || !suggested
                .iter()
                .any(|s| p.message.ends_with(&format!("needs `{s}`")))
    });
    problems.sort_by_key(|p| (p.span.offset, p.code));
    // The same words at the same place are one problem, whichever node the check reached it by.
    problems
        .dedup_by(|a, b| (a.code, &a.message, a.span, &a.label) == (b.code, &b.message, b.span, &b.label));
    problems
}

fn map_error(schema: &Value, doc: &SpannedDocument, error: &ValidationError<'_>, out: &mut Vec<Problem>) {
    let pointer = error.instance_path().as_str().to_owned();
    let mut spans = doc.spans_at(&pointer);
    spans.value = doc.label_span(&pointer);
    let field = field_name(&pointer);
    let instance = error.instance();
    let problem = match error.kind() {
        ValidationErrorKind::AdditionalProperties { unexpected } => {
            let allowed = allowed_properties(schema, error.schema_path().as_str());
            for key in unexpected {
                let key_pointer = format!("{pointer}/{}", escape_pointer(key));
                let key_spans = doc.spans_at(&key_pointer);
                let span = key_spans.key.unwrap_or(key_spans.value);
                let mut p = Problem::error(
                    "cpmx::schema::unknown-key",
                    format!("unknown key `{key}` in {}", describe(&pointer)),
                    span,
                    "not a key of the language",
                )
                .at_pointer(key_pointer);
                p = match did_you_mean(key, &allowed) {
                    Some(best) => p.with_suggestion(best),
                    None if !allowed.is_empty() => {
                        p.with_help(format!("allowed keys: {}", allowed.join(", ")))
                    }
                    None => p,
                };
                out.push(p);
            }
            return;
        }
        ValidationErrorKind::AnyOf { context } | ValidationErrorKind::OneOfNotValid { context } => {
            if let Some(problem) = key_no_form_accepts(schema, doc, context, &pointer) {
                out.push(problem);
                return;
            }
            if let Some(names) = constants_of_every_branch(context, &pointer) {
                let problem = not_one_of(field, &names, spans.value, instance);
                out.push(with_layer_forms(problem, &pointer, instance).at_pointer(pointer));
                return;
            }
            if let Some(branch) = best_branch(context, &pointer) {
                for e in branch {
                    map_error(schema, doc, e, out);
                }
                return;
            }
            Problem::error(
                "cpmx::schema::shape",
                format!("{} has none of the accepted forms", describe(&pointer)),
                spans.value,
                "unexpected form",
            )
        }
        ValidationErrorKind::Required { property } => {
            let name = property.as_str().unwrap_or_default();
            Problem::error(
                "cpmx::schema::missing",
                format!("{} needs `{name}`", describe(&pointer)),
                spans.key.unwrap_or(spans.value),
                format!("`{name}` missing here"),
            )
            .with_help(format!("add `{name}:`; `cpmx schema` describes every key"))
        }
        ValidationErrorKind::Type { kind } => {
            let problem = Problem::error(
                "cpmx::schema::type",
                format!(
                    "{} must be {}, found {}",
                    if field.is_empty() {
                        "the spec".to_owned()
                    } else {
                        format!("`{field}`")
                    },
                    type_name(kind),
                    value_kind(instance)
                ),
                spans.value,
                format!("expected {}", type_name(kind)),
            );
            match quoted_value_help(kind, field, instance) {
                Some(help) => problem.with_help(help),
                None => problem,
            }
        }
        ValidationErrorKind::Enum { options } => {
            let names: Vec<String> = options
                .as_array()
                .map_or(vec![], |o| o.iter().map(plain).collect());
            not_one_of(field, &names, spans.value, instance)
        }
        ValidationErrorKind::Constant { expected_value } => {
            let expected = plain(expected_value);
            let mut p = Problem::error(
                "cpmx::schema::choice",
                format!("`{field}` must be `{expected}`"),
                spans.value,
                format!("{} is not `{expected}`", plain(instance)),
            );
            if did_you_mean(&plain(instance), std::slice::from_ref(&expected)).is_some() {
                p = p.with_suggestion(expected);
            }
            p
        }
        ValidationErrorKind::Minimum { limit } => range(field, spans.value, "at least", limit, instance),
        ValidationErrorKind::Maximum { limit } => range(field, spans.value, "at most", limit, instance),
        ValidationErrorKind::ExclusiveMinimum { limit } => {
            range(field, spans.value, "greater than", limit, instance)
        }
        ValidationErrorKind::ExclusiveMaximum { limit } => {
            range(field, spans.value, "less than", limit, instance)
        }
        ValidationErrorKind::MinItems { limit } => Problem::error(
            "cpmx::schema::length",
            format!(
                "`{field}` needs at least {limit} item{}",
                if *limit == 1 { "" } else { "s" }
            ),
            spans.value,
            "too few items",
        ),
        ValidationErrorKind::MaxItems { limit } => Problem::error(
            "cpmx::schema::length",
            format!("`{field}` takes at most {limit} items"),
            spans.value,
            "too many items",
        ),
        ValidationErrorKind::MinLength { .. } => Problem::error(
            "cpmx::schema::length",
            format!("`{field}` must not be empty"),
            spans.value,
            "empty",
        ),
        ValidationErrorKind::MaxLength { limit } => Problem::error(
            "cpmx::schema::length",
            format!("`{field}` is longer than {limit} characters"),
            spans.value,
            "too long",
        ),
        ValidationErrorKind::MinProperties { .. } => Problem::error(
            "cpmx::schema::length",
            format!("`{field}` must not be empty"),
            spans.value,
            "empty mapping",
        ),
        ValidationErrorKind::Pattern { .. } => Problem::error(
            "cpmx::schema::name",
            format!("`{field}`: {} is not a valid name", plain(instance)),
            spans.value,
            "invalid name",
        )
        .with_help("names use lower-case letters, digits and `-`, and start with a letter or digit"),
        other => Problem::error(
            "cpmx::schema::other",
            format!("{}: {}", describe(&pointer), other.keyword()),
            spans.value,
            "here",
        ),
    };
    let problem = with_layer_forms(problem, &pointer, instance.as_ref());
    out.push(problem.at_pointer(pointer));
}

/// `problem` with the forms a fidelity layer accepts in its help, when the value at `pointer`
/// is a word that is none of them (`dynamics: greybox`).
fn with_layer_forms(problem: Problem, pointer: &str, instance: &Value) -> Problem {
    match (layer_forms(pointer), instance) {
        (Some(forms), Value::String(_)) => Problem {
            help: Some(match &problem.help {
                Some(help) => format!("{help} The valid forms: {forms}"),
                None => format!("the valid forms: {forms}"),
            }),
            ..problem
        },
        _ => problem,
    }
}

/// The forms a fidelity layer accepts, for a word that is none of them (`dynamics: greybox`).
fn layer_forms(pointer: &str) -> Option<&'static str> {
    let layer = pointer.rsplit('/').next()?;
    if !pointer.starts_with("/fidelities/") {
        return None;
    }
    match layer {
        "dynamics" => Some(
            "`kinematic` (SigmaRL's bicycle), `kinematic-rk4` (integrated over the step, as SigmaRL 1.4.0), \
             `kinematic-vmas` (as SigmaRL 1.2.0), `stdlib:mu-car-greybox` (the CPM Lab's identified model; \
             `cpmx stdlib mu-car-greybox` prints it), or an inline grey-box model \
             `{parameters: [p1, ..., p10], euler_step_s: 0.02, battery_voltage_v: 7.8}`",
        ),
        "sensing" => Some(
            "`ideal`, `stdlib:cpm-ips` (the lab's positioning system), or an inline model \
             `{rate_hz, latency_ms, noise_position_m, noise_yaw_rad, drop_probability, fusion_gain}`",
        ),
        "actuation" => Some("`ideal`, or `{delay_ms: 80}`"),
        _ => None,
    }
}

/// A value that is none of the words a key takes.
fn not_one_of(field: &str, names: &[String], span: crate::diagnostic::ByteSpan, instance: &Value) -> Problem {
    let p = Problem::error(
        "cpmx::schema::choice",
        format!("`{field}` must be one of {}", names.join(", ")),
        span,
        format!("{} is not one of them", plain(instance)),
    );
    match did_you_mean(&plain(instance), names) {
        Some(best) => p.with_suggestion(best),
        None => p,
    }
}

/// The words of a choice whose every branch is one constant (an enum whose variants have
/// doc comments becomes such a `oneOf`), when the value at `pointer` is none of them.
fn constants_of_every_branch(
    context: &[Vec<ValidationError<'static>>],
    pointer: &str,
) -> Option<Vec<String>> {
    context
        .iter()
        .map(|errors| {
            // A branch's constant, with or without its type's complaint (`on_collision: 5`
            // is neither a text nor `continue`).
            let mut constant = None;
            for e in errors {
                match e.kind() {
                    _ if e.instance_path().as_str() != pointer => return None,
                    ValidationErrorKind::Constant { expected_value } if constant.is_none() => {
                        constant = Some(plain(expected_value));
                    }
                    ValidationErrorKind::Type { .. } => {}
                    _ => return None,
                }
            }
            constant
        })
        .collect::<Option<Vec<String>>>()
        .filter(|names| names.len() > 1)
}

fn range(
    field: &str,
    span: crate::diagnostic::ByteSpan,
    relation: &str,
    limit: &Value,
    found: &Value,
) -> Problem {
    Problem::error(
        "cpmx::schema::range",
        format!("`{field}` must be {relation} {limit}, found {}", plain(found)),
        span,
        format!("out of range (must be {relation} {limit})"),
    )
}

/// The branch of an `anyOf` whose errors best explain the value: branches that reject the
/// value's type outright lose to branches that only object to its content; then fewer errors win.
fn best_branch<'a>(
    context: &'a [Vec<ValidationError<'static>>],
    pointer: &str,
) -> Option<&'a [ValidationError<'static>]> {
    context
        .iter()
        .enumerate()
        .min_by_key(|(i, errors)| {
            let rejects_type = errors.iter().any(|e| rejects_type(e, pointer));
            (rejects_type, errors.len(), *i)
        })
        .map(|(_, errors)| errors.as_slice())
}

/// A mapping whose one key no form of a choice accepts, when every form is a mapping with keys
/// of its own (`{uniform: ...}` or `{normal: ...}`): one unknown-key problem naming the keys of
/// all forms, instead of the closest form's complaints.
fn key_no_form_accepts(
    schema: &Value,
    doc: &SpannedDocument,
    context: &[Vec<ValidationError<'static>>],
    pointer: &str,
) -> Option<Problem> {
    let mut allowed: Vec<String> = Vec::new();
    let mut unexpected: Option<Vec<String>> = None;
    for branch in context {
        let extra = branch.iter().find_map(|e| match e.kind() {
            ValidationErrorKind::AdditionalProperties { unexpected }
                if e.instance_path().as_str() == pointer =>
            {
                Some((e, unexpected.clone()))
            }
            _ => None,
        });
        let (error, keys) = extra?;
        if unexpected.as_ref().is_some_and(|u| *u != keys) {
            return None;
        }
        unexpected = Some(keys);
        allowed.extend(allowed_properties(schema, error.schema_path().as_str()));
    }
    let [key] = &unexpected?[..] else { return None };
    allowed.dedup();
    let key_pointer = format!("{pointer}/{}", escape_pointer(key));
    let key_spans = doc.spans_at(&key_pointer);
    let problem = Problem::error(
        "cpmx::schema::unknown-key",
        format!("unknown key `{key}` in {}", describe(pointer)),
        key_spans.key.unwrap_or(key_spans.value),
        "not a key of the language",
    )
    .at_pointer(key_pointer);
    Some(match did_you_mean(key, &allowed) {
        Some(best) => problem.with_suggestion(best),
        None => problem.with_help(format!("one of: {}", allowed.join(", "))),
    })
}

/// Whether `error` says the value at `pointer` has the wrong kind or is not a listed constant
/// (also through a nested choice all of whose branches say so, as for the keyword `ideal`).
fn rejects_type(error: &ValidationError<'_>, pointer: &str) -> bool {
    if error.instance_path().as_str() != pointer {
        return false;
    }
    match error.kind() {
        ValidationErrorKind::Type { .. }
        | ValidationErrorKind::Enum { .. }
        | ValidationErrorKind::Constant { .. } => true,
        ValidationErrorKind::AnyOf { context } | ValidationErrorKind::OneOfNotValid { context } => context
            .iter()
            .all(|branch| branch.iter().any(|e| rejects_type(e, pointer))),
        _ => false,
    }
}

/// The property names the schema allows where an `additionalProperties` error arose.
fn allowed_properties(schema: &Value, schema_path: &str) -> Vec<String> {
    let parent = schema_path.rsplit_once('/').map_or("", |(p, _)| p);
    let mut node = schema;
    for segment in parent.split('/').filter(|s| !s.is_empty()) {
        let segment = unescape_pointer(segment);
        node = match node {
            Value::Object(map) if segment == "$ref" => {
                let target = map.get("$ref").and_then(Value::as_str).unwrap_or("");
                match schema.pointer(target.trim_start_matches('#')) {
                    Some(n) => n,
                    None => return vec![],
                }
            }
            Value::Object(map) => match map.get(&segment) {
                Some(n) => n,
                None => return vec![],
            },
            Value::Array(items) => match segment.parse::<usize>().ok().and_then(|i| items.get(i)) {
                Some(n) => n,
                None => return vec![],
            },
            _ => return vec![],
        };
    }
    resolve_refs(schema, node)
        .get("properties")
        .and_then(Value::as_object)
        .map_or(vec![], |p| p.keys().cloned().collect())
}

/// The closest candidate to `word`, if it is close enough to be a likely typo.
pub fn did_you_mean(word: &str, candidates: &[String]) -> Option<String> {
    candidates
        .iter()
        .map(|c| (strsim::jaro_winkler(word, c), c))
        .filter(|(score, _)| *score > 0.8)
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, c)| c.clone())
}

/// The last key of a pointer ("the spec" for the root).
fn field_name(pointer: &str) -> &str {
    let mut segments = pointer.rsplit('/');
    let last = segments.next().unwrap_or("");
    if last.parse::<usize>().is_ok() {
        segments.next().unwrap_or(last)
    } else {
        last
    }
}

/// "`vehicle`", "`policies[1]`", "the spec" for messages.
pub fn describe(pointer: &str) -> String {
    if pointer.is_empty() {
        return "the spec".into();
    }
    let mut out = String::new();
    for segment in pointer.split('/').skip(1) {
        if segment.parse::<usize>().is_ok() {
            out.push_str(&format!("[{segment}]"));
        } else {
            if !out.is_empty() {
                out.push('.');
            }
            out.push_str(&unescape_pointer(segment));
        }
    }
    format!("`{out}`")
}

fn type_name(kind: &TypeKind) -> String {
    let name = |t: &jsonschema::JsonType| match t.to_string().as_str() {
        "object" => "a mapping".to_owned(),
        "array" => "a list".to_owned(),
        "integer" => "a whole number".to_owned(),
        "number" => "a number".to_owned(),
        "string" => "a text".to_owned(),
        "boolean" => "true or false".to_owned(),
        "null" => "empty".to_owned(),
        other => other.to_owned(),
    };
    match kind {
        TypeKind::Single(t) => name(t),
        TypeKind::Multiple(ts) => ts.iter().map(|t| name(&t)).collect::<Vec<_>>().join(" or "),
    }
}

/// A help line for a number or a boolean written in quotes (YAML reads `"120"` as text).
fn quoted_value_help(kind: &TypeKind, field: &str, instance: &Value) -> Option<String> {
    let Value::String(text) = instance else {
        return None;
    };
    let accepts = |wanted: &[&str]| match kind {
        TypeKind::Single(t) => wanted.contains(&t.to_string().as_str()),
        TypeKind::Multiple(ts) => ts.iter().any(|t| wanted.contains(&t.to_string().as_str())),
    };
    let trimmed = text.trim();
    let number = trimmed.parse::<f64>().is_ok_and(f64::is_finite);
    let integer = trimmed.parse::<i64>().is_ok();
    let boolean = matches!(trimmed, "true" | "false");
    let fits = (integer && accepts(&["integer", "number"]))
        || (number && accepts(&["number"]))
        || (boolean && accepts(&["boolean"]));
    fits.then(|| format!("remove the quotes: `{field}: {trimmed}` (in quotes YAML reads it as text)"))
}

fn value_kind(v: &Value) -> String {
    match v {
        Value::Null => "nothing".into(),
        Value::Bool(b) => format!("`{b}`"),
        Value::Number(n) => format!("`{n}`"),
        Value::String(s) => format!("the text `{s}`"),
        Value::Array(_) => "a list".into(),
        Value::Object(_) => "a mapping".into(),
    }
}

fn plain(v: &Value) -> String {
    match v {
        Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

mod published;
#[cfg(test)]
mod tests;
