//! What the repository's tests promise about themselves: they find SigmaRL's reference data only
//! through `cpmx-testdata` (so that without it every one of them names the folder), and a
//! failing property test leaves no regressions file in the tree.

mod support;

use std::path::{Path, PathBuf};

use support::root;

/// Every Rust file of the workspace but the build output.
fn rust_files() -> Vec<PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).into_iter().flatten().flatten() {
            let path = entry.path();
            let name = entry.file_name();
            if path.is_dir() {
                if name != "target" && name != ".git" && name != "out" {
                    walk(&path, out);
                }
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }
    let mut out = Vec::new();
    walk(&root(), &mut out);
    out.sort();
    out
}

/// The file's lines that are not comments.
fn code_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l))
        .filter(|(_, l)| !l.trim_start().starts_with("//"))
}

#[test]
fn tests_find_the_reference_data_only_through_cpmx_testdata() {
    // The helper itself, this test, and the documentation's test, whose scratch copy puts the
    // folder where the pages say it is.
    let allowed = |f: &PathBuf| {
        *f == root().join("testdata/src/lib.rs")
            || *f == root().join("tests/repository.rs")
            || f.starts_with(root().join("tests/docs"))
    };
    let mut found = Vec::new();
    for file in rust_files().into_iter().filter(|f| !allowed(f)) {
        let text = std::fs::read_to_string(&file).unwrap();
        for (line, code) in code_lines(&text) {
            if code.contains("shared/reference") {
                found.push(format!(
                    "{}:{line}: {}",
                    file.strip_prefix(root()).unwrap().display(),
                    code.trim()
                ));
            }
        }
    }
    assert!(
        found.is_empty(),
        "use cpmx_testdata::{{reference, reference_file, read_reference}} instead, so that a missing \
         folder is named:\n{}",
        found.join("\n")
    );
}

#[test]
fn property_tests_keep_their_regressions_out_of_the_tree() {
    let mut missing = Vec::new();
    let mut blocks = 0;
    for file in rust_files() {
        let text = std::fs::read_to_string(&file).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        for (i, line) in lines.iter().enumerate() {
            if line.trim_start().starts_with("proptest! {") {
                blocks += 1;
                // The config is the block's first inner attribute, before its first test.
                let config = lines[i + 1..]
                    .iter()
                    .take_while(|l| !l.contains("fn "))
                    .any(|l| l.contains("failure_persistence: None"));
                if !config {
                    missing.push(format!(
                        "{}:{}",
                        file.strip_prefix(root()).unwrap().display(),
                        i + 1
                    ));
                }
            }
        }
    }
    assert!(blocks >= 5, "found {blocks} proptest blocks");
    assert!(
        missing.is_empty(),
        "proptest blocks without `#![proptest_config(ProptestConfig {{ failure_persistence: None, .. }})]` \
         (a failure would write a proptest-regressions file into the tree):\n{}",
        missing.join("\n")
    );
}
