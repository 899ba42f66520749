//! What the spec tests share: checking a spec text with a stand-in for the interpreter, editing
//! a base spec, and the snapshot case of a rejected spec. Each test binary uses a part of it.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use cpmx_spec::{DataPath, InterpreterChecks, SpecDiagnostic, SpecSource};

/// Checks `text` as `spec.yaml` in a folder that does not exist, with `interpreter`.
pub fn check_with(
    text: &str,
    interpreter: &dyn InterpreterChecks,
) -> Result<cpmx_spec::CheckedSpec, Vec<SpecDiagnostic>> {
    let source = SpecSource {
        name: "spec.yaml".into(),
        dir: PathBuf::from("/nonexistent"),
        text: text.into(),
    };
    let data = DataPath::new(Path::new("/nonexistent"), &[], None);
    cpmx_spec::check(&source, &data, interpreter)
}

/// `base` with `from` replaced by `to` (which must occur).
pub fn edit(base: &str, from: &str, to: &str) -> String {
    assert!(base.contains(from), "{from:?} is not in the base spec");
    base.replacen(from, to, 1)
}

/// Asserts that `checked` was rejected with its first diagnostic at `line`:`column`, and
/// returns the rendering.
pub fn rejected_at(
    checked: Result<cpmx_spec::CheckedSpec, Vec<SpecDiagnostic>>,
    line: usize,
    column: usize,
) -> String {
    let diagnostics = checked.expect_err("the spec should be rejected");
    assert_eq!(
        (diagnostics[0].line, diagnostics[0].column),
        (line, column),
        "{}",
        cpmx_spec::render(&diagnostics, false)
    );
    cpmx_spec::render(&diagnostics, false)
}

/// A snapshot test of `diagnose(text, line, column)` (the test file's own `diagnose`).
#[macro_export]
macro_rules! case {
    ($name:ident, $text:expr, $line:expr, $column:expr) => {
        #[test]
        fn $name() {
            insta::assert_snapshot!(diagnose(&$text, $line, $column));
        }
    };
}
