//! Reading YAML into a JSON value while remembering where every node came from.
//!
//! serde-saphyr parses the text (YAML 1.2, budgets against alias bombs and deep nesting) into
//! a tree of `Spanned` nodes; this module turns it into a `serde_json::Value`, which the schema
//! and the typed model read, and a map from JSON pointer to the byte spans of the node and of
//! its key, which every diagnostic uses to point back into the file.

use std::collections::HashMap;

use serde::Deserialize;
use serde_json::{Map, Number, Value};
use serde_saphyr::{Budget, Options, Spanned};

use crate::diagnostic::{ByteSpan, Problem};

/// Where a node of the document sits in the text.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NodeSpans {
    /// The value.
    pub value: ByteSpan,
    /// The key, for a mapping entry.
    pub key: Option<ByteSpan>,
}

/// A document: its JSON value and the spans of its nodes by JSON pointer.
#[derive(Debug, Clone, Default)]
pub struct SpannedDocument {
    pub value: Value,
    pub spans: HashMap<String, NodeSpans>,
}

impl SpannedDocument {
    /// Where to point for the node at `pointer`: a collection is labelled at its key (its own
    /// span only marks where it opens), a scalar at its value.
    pub fn label_span(&self, pointer: &str) -> ByteSpan {
        let spans = self.spans_at(pointer);
        match self.value.pointer(pointer) {
            Some(Value::Array(_) | Value::Object(_)) => spans.key.unwrap_or(spans.value),
            _ => spans.value,
        }
    }

    /// The spans of the node at `pointer`, or of its nearest ancestor that the text has (a value
    /// expanded from a preset points at the preset reference).
    pub fn spans_at(&self, pointer: &str) -> NodeSpans {
        let mut p = pointer;
        loop {
            if let Some(s) = self.spans.get(p) {
                return *s;
            }
            match p.rfind('/') {
                Some(i) => p = &p[..i],
                None => {
                    return NodeSpans {
                        value: ByteSpan::new(0, 0),
                        key: None,
                    };
                }
            }
        }
    }
}

/// A YAML node as serde-saphyr hands it over.
#[derive(Debug)]
enum Node {
    Null,
    Bool(bool),
    Int(i128),
    Float(f64),
    Str(String),
    Seq(Vec<Spanned<Node>>),
    Map(Vec<(Spanned<Node>, Spanned<Node>)>),
}

struct NodeVisitor;

impl<'de> serde::de::Visitor<'de> for NodeVisitor {
    type Value = Node;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("any YAML value")
    }
    fn visit_bool<E>(self, v: bool) -> Result<Node, E> {
        Ok(Node::Bool(v))
    }
    fn visit_i64<E>(self, v: i64) -> Result<Node, E> {
        Ok(Node::Int(v.into()))
    }
    fn visit_u64<E>(self, v: u64) -> Result<Node, E> {
        Ok(Node::Int(v.into()))
    }
    fn visit_i128<E>(self, v: i128) -> Result<Node, E> {
        Ok(Node::Int(v))
    }
    fn visit_u128<E>(self, v: u128) -> Result<Node, E> {
        Ok(i128::try_from(v).map_or(Node::Float(v as f64), Node::Int))
    }
    fn visit_f64<E>(self, v: f64) -> Result<Node, E> {
        Ok(Node::Float(v))
    }
    fn visit_str<E>(self, v: &str) -> Result<Node, E> {
        Ok(Node::Str(v.to_owned()))
    }
    fn visit_string<E>(self, v: String) -> Result<Node, E> {
        Ok(Node::Str(v))
    }
    fn visit_bytes<E: serde::de::Error>(self, _: &[u8]) -> Result<Node, E> {
        Err(E::custom("binary values are not part of the cpmx language"))
    }
    fn visit_unit<E>(self) -> Result<Node, E> {
        Ok(Node::Null)
    }
    fn visit_none<E>(self) -> Result<Node, E> {
        Ok(Node::Null)
    }
    fn visit_some<D: serde::Deserializer<'de>>(self, d: D) -> Result<Node, D::Error> {
        Node::deserialize(d)
    }
    fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut access: A) -> Result<Node, A::Error> {
        let mut items = Vec::new();
        while let Some(item) = access.next_element()? {
            items.push(item);
        }
        Ok(Node::Seq(items))
    }
    fn visit_map<A: serde::de::MapAccess<'de>>(self, mut access: A) -> Result<Node, A::Error> {
        let mut entries = Vec::new();
        while let Some(entry) = access.next_entry()? {
            entries.push(entry);
        }
        Ok(Node::Map(entries))
    }
}

impl<'de> Deserialize<'de> for Node {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Node, D::Error> {
        d.deserialize_any(NodeVisitor)
    }
}

/// Parser limits: a spec is a small file, so anything far larger is an attack or an accident.
fn options() -> Options {
    let mut budget = Budget::default();
    budget.max_events = 200_000;
    budget.max_aliases = 1_000;
    budget.max_anchors = 1_000;
    budget.max_depth = 64;
    budget.max_nodes = 100_000;
    budget.max_total_scalar_bytes = 4 * 1024 * 1024;
    let mut options = Options::default();
    options.budget = Some(budget);
    options.with_snippet = false;
    // Only `true` and `false` are booleans: `y`, `n`, `on`, `off` stay text (YAML 1.2).
    options.strict_booleans = true;
    options
}

/// Parses `text` into a spanned JSON document. A syntax error, a breached budget or a value
/// that JSON cannot hold (a non-string key, a non-finite number) is a problem at its place.
pub fn parse(text: &str) -> Result<SpannedDocument, Vec<Problem>> {
    let root: Spanned<Node> = serde_saphyr::from_str_with_options(text, options()).map_err(|err| {
        let span = err
            .location()
            .map_or(ByteSpan::new(0, 0), |l| location_span(text, &l));
        let message = strip_location(&err.to_string());
        vec![match duplicate_key(&message) {
            Some(key) => Problem::duplicate_key(key, span),
            None => Problem::yaml_syntax(message, span),
        }]
    })?;
    if matches!(root.value, Node::Null) {
        return Err(vec![Problem::empty_document()]);
    }
    let mut doc = SpannedDocument::default();
    let mut problems = Vec::new();
    doc.value = convert(text, root, String::new(), None, &mut doc.spans, &mut problems);
    if problems.is_empty() {
        Ok(doc)
    } else {
        Err(problems)
    }
}

/// The byte span of a serde-saphyr location, at least one character wide where the text has one.
fn location_span(text: &str, location: &serde_saphyr::Location) -> ByteSpan {
    let span = location.span();
    let start = span
        .byte_offset()
        .map_or_else(|| char_to_byte(text, span.offset()), |b| b as usize);
    let start = start.min(text.len());
    let len = span.byte_len().map_or(0, |l| l as usize);
    let len = if len == 0 {
        text[start..].chars().next().map_or(0, char::len_utf8)
    } else {
        len
    };
    ByteSpan::new(start, len.min(text.len() - start))
}

fn char_to_byte(text: &str, char_offset: u64) -> usize {
    text.char_indices()
        .nth(char_offset as usize)
        .map_or(text.len(), |(b, _)| b)
}

/// The key of serde-saphyr's duplicate-key message ("duplicate mapping key: seed, set
/// DuplicateKeyPolicy in Options if acceptable"), whose advice is for programmers.
fn duplicate_key(message: &str) -> Option<&str> {
    let rest = message.strip_prefix("duplicate mapping key: ")?;
    Some(
        rest.split_once(", set DuplicateKeyPolicy")
            .map_or(rest, |(key, _)| key),
    )
}

/// serde-saphyr's messages start with "line L column C: "; the diagnostic shows the place itself.
fn strip_location(message: &str) -> String {
    let first = message.lines().next().unwrap_or(message);
    let first = first.strip_prefix("error: ").unwrap_or(first);
    match first.split_once(": ") {
        Some((head, rest)) if head.starts_with("line ") => rest.to_owned(),
        _ => first.to_owned(),
    }
}

fn convert(
    text: &str,
    node: Spanned<Node>,
    pointer: String,
    key: Option<ByteSpan>,
    spans: &mut HashMap<String, NodeSpans>,
    problems: &mut Vec<Problem>,
) -> Value {
    let span = location_span(text, &node.referenced);
    spans.insert(pointer.clone(), NodeSpans { value: span, key });
    match node.value {
        Node::Null => Value::Null,
        Node::Bool(b) => Value::Bool(b),
        Node::Int(i) => match (i64::try_from(i), u64::try_from(i)) {
            (Ok(v), _) => Value::from(v),
            (_, Ok(v)) => Value::from(v),
            _ => {
                problems.push(Problem::number_out_of_range(span));
                Value::Null
            }
        },
        Node::Float(f) => Number::from_f64(f).map_or_else(
            || {
                problems.push(Problem::non_finite_number(span));
                Value::Null
            },
            Value::Number,
        ),
        Node::Str(s) => Value::String(s),
        Node::Seq(items) => Value::Array(
            items
                .into_iter()
                .enumerate()
                .map(|(i, item)| convert(text, item, format!("{pointer}/{i}"), None, spans, problems))
                .collect(),
        ),
        Node::Map(entries) => {
            let mut map = Map::new();
            for (k, v) in entries {
                let key_span = location_span(text, &k.referenced);
                let name = match k.value {
                    Node::Str(s) => s,
                    Node::Int(i) => i.to_string(),
                    Node::Bool(b) => b.to_string(),
                    _ => {
                        problems.push(Problem::non_scalar_key(key_span));
                        continue;
                    }
                };
                let child = format!("{pointer}/{}", escape_pointer(&name));
                if map.contains_key(&name) {
                    problems.push(Problem::duplicate_key(&name, key_span));
                    continue;
                }
                let value = convert(text, v, child, Some(key_span), spans, problems);
                map.insert(name, value);
            }
            Value::Object(map)
        }
    }
}

/// Escapes a key for a JSON pointer (RFC 6901).
pub fn escape_pointer(key: &str) -> String {
    key.replace('~', "~0").replace('/', "~1")
}

/// The key a segment of a JSON pointer names (the inverse of [`escape_pointer`]).
pub fn unescape_pointer(segment: &str) -> String {
    segment.replace("~1", "/").replace("~0", "~")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_node_has_a_span() {
        let text = "a: 1\nb:\n  c: [1, 2.5, x]\n";
        let doc = parse(text).unwrap();
        let c1 = doc.spans["/b/c/1"];
        assert_eq!(&text[c1.value.offset..c1.value.offset + c1.value.len], "2.5");
        let b = doc.spans["/b"].key.unwrap();
        assert_eq!(&text[b.offset..b.offset + b.len], "b");
    }

    #[test]
    fn nearest_ancestor_span_is_used_for_expanded_nodes() {
        let doc = parse("vehicle: stdlib:mu-car\n").unwrap();
        assert_eq!(doc.spans_at("/vehicle/width"), doc.spans["/vehicle"]);
    }
}
