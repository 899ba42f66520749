//! No input makes the spec checker panic: random bytes, truncations and byte mutations of a
//! valid spec all end in `Ok` or in diagnostics. Runs briefly as part of the test suite.

use std::path::Path;

use cpmx_spec::model::Fidelity;
use cpmx_spec::{CheckContext, DataPath, InterpreterChecks, Resources, Spec, SpecSource};
use proptest::prelude::*;

struct NoInterpreter;

impl InterpreterChecks for NoInterpreter {
    fn cannot_run(&self, _: &Fidelity) -> Option<String> {
        None
    }
    fn check(&self, _: &Spec, _: &Resources, _: &mut CheckContext<'_>) {}
}

const VALID: &str = include_str!("../../experiments/at25-cpmx.yaml");

fn check(text: String) {
    let source = SpecSource {
        name: "fuzz.yaml".into(),
        dir: "/nonexistent".into(),
        text,
    };
    let data = DataPath::new(Path::new("/nonexistent"), &[], None);
    if let Err(diagnostics) = cpmx_spec::check(&source, &data, &NoInterpreter) {
        assert!(!diagnostics.is_empty());
        // Rendering must not panic either (spans inside the text).
        let _ = cpmx_spec::render(&diagnostics, false);
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn truncated_specs(cut in 0usize..VALID.len()) {
        let mut end = cut;
        while !VALID.is_char_boundary(end) { end -= 1; }
        check(VALID[..end].to_owned());
    }

    #[test]
    fn mutated_specs(edits in prop::collection::vec((0usize..VALID.len(), any::<u8>()), 1..8)) {
        let mut bytes = VALID.as_bytes().to_vec();
        for (at, byte) in edits {
            bytes[at] = if byte.is_ascii() { byte } else { b':' };
        }
        check(String::from_utf8_lossy(&bytes).into_owned());
    }

    #[test]
    fn random_text(text in ".{0,400}") {
        check(text);
    }

    #[test]
    fn spliced_lines(a in 0usize..60, b in 0usize..60) {
        let lines: Vec<&str> = VALID.lines().collect();
        let (a, b) = (a % lines.len(), b % lines.len());
        let mut spliced = lines.clone();
        spliced.insert(a, lines[b]);
        check(spliced.join("\n"));
    }
}
