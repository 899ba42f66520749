//! Spec fragments of the docs: the spec each is merged into and how it is laid over it.

use serde_json::Value;

use crate::markdown::{Block, Page};
use crate::scratch::Scratch;

/// The spec a fragment is merged into unless a `base:` marker names another.
pub const DEFAULT_BASE: &str = "examples/first.yaml";

/// The spec a fragment is merged into: a spec of the repository (`examples/first.yaml`, or the
/// `base:` marker's file), or, when the marker names a block of the same page (`<!-- name: N
/// -->` above it), that block merged into `examples/first.yaml`.
pub fn base_spec(page: &Page, scratch: &Scratch, base: &str) -> Result<Value, String> {
    let read = |file: &str| -> Result<Value, String> {
        let text = std::fs::read_to_string(scratch.repo.join(file)).map_err(|e| format!("{file}: {e}"))?;
        serde_saphyr::from_str::<Value>(&text).map_err(|e| format!("{file} is not YAML: {e}"))
    };
    if base.ends_with(".yaml") {
        return read(base);
    }
    let blocks = page.blocks();
    let named = blocks
        .iter()
        .find(|b| b.marker("name") == Some(base))
        .ok_or_else(|| format!("no block `<!-- name: {base} -->` in {}", page.name))?;
    let mut spec = read(DEFAULT_BASE)?;
    merge(&mut spec, fragment_of(named)?);
    Ok(spec)
}

/// A fragment's YAML, placed at its `at:` marker's dotted path (`fidelities.lab.faults`) when it
/// has one.
pub fn fragment_of(block: &Block) -> Result<Value, String> {
    let mut value =
        serde_saphyr::from_str::<Value>(&block.body).map_err(|e| format!("the fragment is not YAML: {e}"))?;
    if let Some(path) = block.marker("at") {
        for key in path.rsplit('.') {
            value = Value::Object([(key.to_owned(), value)].into_iter().collect());
        }
    }
    Ok(value)
}

/// `fragment` laid over `base`: mappings merged key by key, anything else replaced.
pub fn merge(base: &mut Value, fragment: Value) {
    match (base, fragment) {
        (Value::Object(base), Value::Object(fragment)) => {
            for (key, value) in fragment {
                match base.get_mut(&key) {
                    Some(existing) if existing.is_object() && value.is_object() => merge(existing, value),
                    _ => {
                        base.insert(key, value);
                    }
                }
            }
        }
        (base, fragment) => *base = fragment,
    }
}
