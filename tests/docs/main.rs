//! The documentation runs: README.md and every page of `docs/` are checked against the program,
//! so that a page that no longer matches it fails CI.
//!
//! - A ```yaml block with a `cpmx: 1` line is a whole spec: `cpmx validate` accepts it (with
//!   SigmaRL's reference data on `--data`). Below `<!-- file: PATH -->` it is PATH's content,
//!   verbatim (a shipped spec), or, where PATH is not in the repository, saved there for the
//!   commands that follow.
//! - Any other ```yaml block is a fragment: merged into `examples/first.yaml` (or the spec of a
//!   `<!-- base: PATH -->` marker, or `examples/first.yaml` with the page's block marked
//!   `<!-- name: NAME -->` for `<!-- base: NAME -->`), below the dotted path of an `<!-- at:
//!   a.b -->` marker, it passes every check but a missing file of the reader's own
//!   (`cpmx::check::missing-file`); `<!-- not validated: REASON -->` skips it.
//! - Every command of a ```sh or ```console block runs, in order, in a scratch copy of
//!   `experiments/` and `examples/` with `../shared/reference` beside it and `cpmx` on the
//!   `PATH` (`cargo run --release --` is read as the `cpmx` it builds), and exits 0, or the code
//!   of an `<!-- exit: N -->` marker. In a console block the lines below `$ COMMAND` are its
//!   output (`...` stands for any lines).
//! - Below `<!-- not run: REASON -->` (or `<!-- not run `PREFIX`: REASON -->`, for the lines
//!   that start with PREFIX) a command is not run: a `cpmx` command is parsed by cpmx's own
//!   argument parser (`CPMX_PARSE_ONLY=1`) and the specs it names must exist; a `cargo`
//!   command must name packages, tests, benches and examples that exist. A command that the
//!   test does not run without such a marker (cargo, pip, python, scripts) fails it.
//! - Inline `cpmx ...` code in the text is parsed the same way; written as a synopsis
//!   (`[--flag]`, `a|b`, `DIR...`), its subcommand must exist and `cpmx SUB --help` must list
//!   each of its flags.
//! - A table below `<!-- figures: FILE... -->` quotes only numbers those files hold, as written
//!   by the page's commands in its scratch copy (or SigmaRL's reference data,
//!   `../shared/reference/...`): a figure that no longer matches its command fails (`quotes.rs`).
//! - ```python blocks compile (`python/tests/test_docs.py` runs those not marked `not run`).
//! - Relative links name files that exist and headings that they have.
//!
//! `CPMX_DOCS_PAGES=docs/xp-marl.md,README.md cargo test --test docs` checks those pages alone;
//! `CPMX_DOCS_KEEP=1` keeps each page's scratch copy with what its commands wrote.

#[path = "../support/mod.rs"]
mod support;

mod fragments;
mod markdown;
mod quotes;
mod scratch;
mod shell;

use std::path::{Path, PathBuf};
use std::process::Stdio;

use fragments::{DEFAULT_BASE, base_spec, fragment_of, merge};
use markdown::{Block, Page};
use scratch::Scratch;
use support::root;

/// Programs a command of the documentation may run without a `not run` marker.
const RUNNABLE: [&str; 12] = [
    "cpmx", "printf", "echo", "cat", "ls", "mkdir", "cp", "head", "tail", "grep", "wc", "test",
];

#[test]
fn the_readme_is_a_few_screens() {
    let lines = Page::read(&root(), "README.md").text.lines().count();
    assert!(
        lines <= 250,
        "README.md has {lines} lines; the limit is 250: move detail into docs/"
    );
}

#[test]
fn every_whole_spec_in_the_docs_validates() {
    let mut failures = Vec::new();
    let mut validated = 0;
    for page in Page::all(&root()) {
        let scratch = Scratch::new(&page, "specs");
        for block in page
            .blocks()
            .iter()
            .filter(|b| b.lang == "yaml" && b.is_whole_spec())
        {
            let at = format!("{}:{}", page.name, block.line);
            let path = match block.marker("file") {
                Some(file) if root().join(file).is_file() => {
                    let shipped = std::fs::read_to_string(root().join(file)).unwrap();
                    if shipped != block.body {
                        failures.push(format!("{at}: the block is not {file} as shipped"));
                    }
                    file.to_owned()
                }
                Some(file) => {
                    scratch.write(file, &block.body);
                    file.to_owned()
                }
                None => {
                    let file = format!("{}-{}.yaml", page.stem(), block.line);
                    scratch.write(&file, &block.body);
                    file
                }
            };
            let run = scratch.bash(&format!("cpmx validate {path} --data ../shared/reference"), false);
            validated += 1;
            if run.code != Some(0) {
                failures.push(format!(
                    "{at}: `cpmx validate` of the spec failed:\n{}",
                    run.both()
                ));
            }
        }
    }
    eprintln!("docs: {validated} whole specs validated");
    report(&failures, true);
    assert!(
        Page::only().is_some() || validated >= 1,
        "no whole spec in the docs"
    );
}

#[test]
fn every_spec_fragment_in_the_docs_fits_a_spec() {
    let mut failures = Vec::new();
    let (mut checked, mut skipped) = (0, 0);
    for page in Page::all(&root()) {
        let scratch = Scratch::new(&page, "fragments");
        for block in page
            .blocks()
            .iter()
            .filter(|b| b.lang == "yaml" && !b.is_whole_spec())
        {
            let at = format!("{}:{}", page.name, block.line);
            if block.marker("not validated").is_some() {
                skipped += 1;
                continue;
            }
            let base = block.marker("base").unwrap_or(DEFAULT_BASE);
            let mut spec = match base_spec(&page, &scratch, base) {
                Ok(spec) => spec,
                Err(e) => {
                    failures.push(format!("{at}: {e}"));
                    continue;
                }
            };
            match fragment_of(block) {
                Ok(fragment) => merge(&mut spec, fragment),
                Err(e) => {
                    failures.push(format!("{at}: {e}"));
                    continue;
                }
            }
            // Named blocks stand for examples/first.yaml's folder (files resolve from there).
            let base = if base.ends_with(".yaml") {
                base
            } else {
                DEFAULT_BASE
            };
            let file = Path::new(base).with_file_name(format!(".{}-{}.yaml", page.stem(), block.line));
            scratch.write(
                &file.display().to_string(),
                &serde_json::to_string_pretty(&spec).unwrap(),
            );
            checked += 1;
            let data = [scratch.reference.clone()];
            let diagnostics =
                match cpmx_session::load(&scratch.repo.join(&file), &data, cpmx_spec::CheckScope::Run) {
                    Ok(_) => continue,
                    Err(cpmx_session::LoadError::Read(e)) => {
                        failures.push(format!("{at}: {e}"));
                        continue;
                    }
                    Err(cpmx_session::LoadError::Invalid(diagnostics)) => diagnostics,
                };
            for d in diagnostics.iter().filter(|d| d.is_error()) {
                if d.problem.code != "cpmx::check::missing-file" {
                    failures.push(format!(
                        "{at}: merged into {base}: {} ({}; {})",
                        d.problem.message, d.problem.code, d.problem.label
                    ));
                }
            }
        }
    }
    eprintln!("docs: {checked} spec fragments checked in a spec, {skipped} marked `not validated`");
    report(&failures, true);
}

#[test]
fn every_command_in_the_docs_runs_or_parses() {
    let mut failures = Vec::new();
    let (mut ran, mut parsed, mut cargo, mut not_run) = (0, 0, 0, 0);
    // What each run command cost, for the summary's slowest (CI's budget is spent here).
    let mut costs: Vec<(std::time::Duration, String)> = Vec::new();
    for page in Page::all(&root()) {
        let scratch = Scratch::new(&page, "commands");
        for block in page.blocks() {
            let console = block.lang == "console";
            if !(console || matches!(block.lang.as_str(), "sh" | "bash" | "shell")) {
                continue;
            }
            let expected: Option<i32> = block.marker("exit").map(|c| c.parse().expect("exit: N"));
            if console
                && let Some((i, first)) = block.body.lines().enumerate().find(|(_, l)| !l.trim().is_empty())
                && !first.starts_with("$ ")
            {
                failures.push(format!(
                    "{}:{}: a console block starts with `$ COMMAND`, not `{first}`",
                    page.name,
                    block.line + 1 + i
                ));
            }
            for command in shell::commands(&block.body, block.line + 1, console) {
                let at = format!("{}:{}", page.name, command.line);
                let program = command.program();
                let first = program.first().copied().unwrap_or_default();
                if !is_run(&block, &command.text) {
                    // What a command that is not run names in the repository exists.
                    for missing in missing_repository_files(&command.text) {
                        failures.push(format!("{at}: `{missing}` does not exist"));
                    }
                    if command.runs_cpmx() {
                        parsed += 1;
                        let text = command.text.trim_end_matches('&').trim_end();
                        let run = scratch.bash(text, true);
                        if run.code != Some(0) {
                            failures.push(format!("{at}: cpmx does not parse `{text}`:\n{}", run.both()));
                        }
                    } else if first == "cargo" {
                        cargo += 1;
                        if let Err(e) = check_cargo(&program) {
                            failures.push(format!("{at}: `{}`: {e}", command.text));
                        }
                    } else {
                        not_run += 1;
                    }
                    continue;
                }
                if !RUNNABLE.contains(&first) {
                    failures.push(format!(
                        "{at}: `{}` is not run by this test: run it here or mark the block \
                         `<!-- not run: REASON -->`",
                        command.text
                    ));
                    continue;
                }
                ran += 1;
                let started = std::time::Instant::now();
                let run = scratch.bash(&command.text, false);
                costs.push((started.elapsed(), format!("{at}: {}", command.text)));
                let want = expected.unwrap_or(0);
                if run.code != Some(want) {
                    failures.push(format!(
                        "{at}: `{}` exited with {:?}, the page says {want}:\n{}",
                        command.text,
                        run.code,
                        run.both()
                    ));
                } else if !command.output.is_empty() && !shell::output_matches(&command.output, &run.both()) {
                    failures.push(format!(
                        "{at}: `{}` printed\n{}\nthe page shows\n{}",
                        command.text,
                        run.both(),
                        command.output.join("\n")
                    ));
                }
            }
        }
        // The figures the page quotes, against what its commands wrote.
        failures.extend(quotes::check(&page, &scratch.repo));
    }
    eprintln!(
        "docs: {ran} commands run, {parsed} cpmx commands parsed only, {cargo} cargo commands \
         checked, {not_run} other commands marked `not run`"
    );
    costs.sort_by_key(|cost| std::cmp::Reverse(cost.0));
    let total: std::time::Duration = costs.iter().map(|(d, _)| *d).sum();
    eprintln!(
        "docs: the commands run took {:.0} s; the slowest:",
        total.as_secs_f64()
    );
    for (took, command) in costs.iter().take(10) {
        eprintln!("  {:6.1} s  {command}", took.as_secs_f64());
    }
    report(&failures, true);
    assert!(
        Page::only().is_some() || (ran >= 10 && parsed >= 5),
        "{ran} commands run, {parsed} parsed: fewer than the docs have"
    );
}

#[test]
fn every_cpmx_command_named_in_the_text_parses() {
    let mut failures = Vec::new();
    let (mut parsed, mut synopses) = (0, 0);
    let scratch = Scratch::new(&Page::read(&root(), "README.md"), "inline");
    for page in Page::all(&root()) {
        for (line, code) in page.inline_code() {
            if !code.starts_with("cpmx ") {
                continue;
            }
            let at = format!("{}:{line}", page.name);
            let words: Vec<&str> = code.split_whitespace().collect();
            // A command's name alone (`cpmx run`, `cpmx lab emulate`) is checked as a synopsis.
            let name_only = words.len() <= if words.get(1) == Some(&"lab") { 3 } else { 2 };
            let synopsis = name_only
                || code.contains('[')
                || code.contains('|')
                || code.contains("...")
                || words.iter().any(|w| is_placeholder(w));
            if words.get(1).is_some_and(|w| is_placeholder(w)) {
                // `cpmx ARGS`: cpmx with any arguments; nothing to check.
                continue;
            }
            if !synopsis {
                parsed += 1;
                let run = scratch.bash(&code, true);
                if run.code != Some(0) {
                    failures.push(format!("{at}: cpmx does not parse `{code}`:\n{}", run.both()));
                }
                continue;
            }
            synopses += 1;
            let sub: Vec<&str> = match words.get(1) {
                Some(&"lab") => words[1..3.min(words.len())].to_vec(),
                Some(w) => vec![w],
                None => vec![],
            };
            let help = scratch.bash(&format!("cpmx {} --help", sub.join(" ")), false);
            if help.code != Some(0) {
                failures.push(format!("{at}: `cpmx {}` is not a command", sub.join(" ")));
                continue;
            }
            for flag in words.iter().filter_map(|w| flag_of(w)) {
                if !help.output.contains(&format!("{flag} ")) && !help.output.contains(&format!("{flag}=")) {
                    failures.push(format!("{at}: `cpmx {}` has no flag {flag}", sub.join(" ")));
                }
            }
        }
    }
    eprintln!("docs: {parsed} inline cpmx commands parsed, {synopses} synopses checked against --help");
    report(&failures, false);
    assert!(
        Page::only().is_some() || synopses >= 5,
        "the README's command table has gone"
    );
}

#[test]
fn every_python_snippet_compiles() {
    let mut failures = Vec::new();
    let mut compiled = 0;
    for page in Page::all(&root()) {
        for block in page.blocks().iter().filter(|b| b.lang == "python") {
            let at = format!("{}:{}", page.name, block.line);
            let child = std::process::Command::new("python3")
                .args([
                    "-c",
                    "import sys; compile(sys.stdin.read(), sys.argv[1], 'exec')",
                    &at,
                ])
                .stdin(Stdio::piped())
                .stdout(Stdio::piped())
                .stderr(Stdio::piped())
                .spawn();
            let Ok(mut child) = child else {
                eprintln!("skipped: every_python_snippet_compiles: needs python3 on the PATH");
                return;
            };
            use std::io::Write;
            child
                .stdin
                .take()
                .unwrap()
                .write_all(block.body.as_bytes())
                .unwrap();
            let out = child.wait_with_output().unwrap();
            compiled += 1;
            if !out.status.success() {
                failures.push(format!("{at}: {}", String::from_utf8_lossy(&out.stderr)));
            }
        }
    }
    eprintln!("docs: {compiled} Python snippets compiled");
    report(&failures, false);
}

#[test]
fn every_link_in_the_docs_resolves() {
    let mut failures = Vec::new();
    let mut links = 0;
    for page in Page::all(&root()) {
        let dir = page.path.parent().unwrap().to_path_buf();
        for (line, target) in page.links() {
            links += 1;
            let at = format!("{}:{line}", page.name);
            let (file, anchor) = match target.split_once('#') {
                Some((file, anchor)) => (file, Some(anchor)),
                None => (target.as_str(), None),
            };
            let path = if file.is_empty() {
                page.path.clone()
            } else {
                dir.join(file)
            };
            if !path.exists() {
                failures.push(format!("{at}: `{target}`: {} does not exist", path.display()));
                continue;
            }
            if let Some(anchor) = anchor
                && path.extension().is_some_and(|e| e == "md")
            {
                let name = path.strip_prefix(root()).unwrap_or(&path).display().to_string();
                let target_page = Page {
                    name,
                    text: std::fs::read_to_string(&path).unwrap(),
                    path: path.clone(),
                };
                if !target_page.anchors().iter().any(|a| a == anchor) {
                    failures.push(format!(
                        "{at}: `{target}`: no heading `#{anchor}` in {}",
                        target_page.name
                    ));
                }
            }
        }
    }
    eprintln!("docs: {links} links followed");
    report(&failures, false);
}

/// The files of the repository a command names (`experiments/…`, `examples/…`, `scripts/…`,
/// `python/…`, `docs/…`) that do not exist.
fn missing_repository_files(command: &str) -> Vec<String> {
    const FOLDERS: [&str; 6] = [
        "experiments/",
        "examples/",
        "scripts/",
        "python/",
        "docs/",
        "tests/",
    ];
    command
        .split_whitespace()
        .map(|w| w.trim_matches(['\'', '"']))
        .map(|w| w.split_once('=').map_or(w, |(_, value)| value))
        .filter(|w| FOLDERS.iter().any(|f| w.starts_with(f)) && !w.contains('*'))
        .filter(|w| !root().join(w).exists())
        .map(str::to_owned)
        .collect()
}

/// Whether a command of `block` runs (no `not run` marker covers it).
fn is_run(block: &Block, command: &str) -> bool {
    block.not_run().iter().all(|prefix| match prefix {
        None => false,
        Some(prefix) => !command.starts_with(prefix.as_str()),
    })
}

/// Whether a synopsis word is a placeholder: `SPEC`, `DIR...`, `N`, `RECORDING.csv`,
/// `stdlib:NAME`, `K/N` (its upper-case part names what the reader puts there).
fn is_placeholder(word: &str) -> bool {
    let word = word.trim_matches(['[', ']', '(', ')', '.', ',']);
    let word = word.rsplit(['=', ':']).next().unwrap_or_default();
    let stem = word.split('.').next().unwrap_or_default();
    !stem.starts_with('-')
        && stem.chars().any(|c| c.is_ascii_uppercase())
        && stem
            .chars()
            .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == '_' || c == '/')
}

/// The flag of a synopsis word: `--out` of `[--out`, `--only` of `--only=a`.
fn flag_of(word: &str) -> Option<&str> {
    let word = word.trim_start_matches(['[', '(']);
    let word = word.split(['=', ']', ')', '|', ',']).next().unwrap_or_default();
    (word.starts_with("--") && word.len() > 2).then_some(word)
}

/// A cargo command that is not run names what exists: its packages (`-p`), tests, benches and
/// examples, and `--path` folders.
fn check_cargo(words: &[&str]) -> Result<(), String> {
    let packages = workspace_packages();
    let mut package: Option<PathBuf> = None;
    let mut i = 1;
    while i < words.len() {
        let value = words.get(i + 1).copied().unwrap_or_default();
        match words[i] {
            "-p" | "--package" => {
                let dir = packages
                    .iter()
                    .find(|(name, _)| name == value)
                    .map(|(_, dir)| dir.clone())
                    .ok_or_else(|| format!("no package `{value}` in the workspace"))?;
                package = Some(dir);
            }
            kind @ ("--test" | "--bench" | "--example") => {
                let dir = package.clone().unwrap_or_else(root);
                let folder = match kind {
                    "--test" => "tests",
                    "--bench" => "benches",
                    _ => "examples",
                };
                let exists = dir.join(folder).join(format!("{value}.rs")).is_file()
                    || dir.join(folder).join(value).join("main.rs").is_file();
                if !exists {
                    return Err(format!("no {folder}/{value}.rs in {}", dir.display()));
                }
            }
            "--path" if !root().join(value).is_dir() => {
                return Err(format!("no folder `{value}`"));
            }
            "--locked" if !root().join("Cargo.lock").is_file() => {
                return Err("`--locked` without a Cargo.lock".to_owned());
            }
            _ => {
                i += 1;
                continue;
            }
        }
        i += 2;
    }
    Ok(())
}

/// Every package of the workspace with its folder.
fn workspace_packages() -> Vec<(String, PathBuf)> {
    let manifest = std::fs::read_to_string(root().join("Cargo.toml")).unwrap();
    let members: Vec<&str> = manifest
        .split("members = [")
        .nth(1)
        .and_then(|m| m.split(']').next())
        .unwrap_or_default()
        .split(',')
        .map(|m| m.trim().trim_matches('"'))
        .filter(|m| !m.is_empty())
        .collect();
    members
        .iter()
        .filter_map(|member| {
            let dir = root().join(member);
            let text = std::fs::read_to_string(dir.join("Cargo.toml")).ok()?;
            let name = text
                .lines()
                .find_map(|l| l.strip_prefix("name = "))?
                .trim()
                .trim_matches('"')
                .to_owned();
            Some((name, dir))
        })
        .collect()
}

/// Fails with every failure; without the reference data, says first that it is missing.
fn report(failures: &[String], needs_reference: bool) {
    if failures.is_empty() {
        return;
    }
    let heading = if needs_reference && !cpmx_testdata::reference_available() {
        format!(
            "{}; the docs' commands and specs that use it fail ({} problems in the docs):",
            cpmx_testdata::missing(&cpmx_testdata::reference_dir()),
            failures.len()
        )
    } else {
        format!("{} problems in the docs:", failures.len())
    };
    panic!("{heading}\n{}", failures.join("\n\n"));
}

#[test]
fn placeholders_make_a_synopsis() {
    for word in [
        "SPEC",
        "DIR...",
        "N]",
        "RECORDING.csv",
        "stdlib:NAME",
        "K/N]",
        "ARGS",
    ] {
        assert!(is_placeholder(word), "{word}");
    }
    for word in [
        "--out",
        "seed=1,3",
        "experiments/at25-cpmx.yaml",
        "fidelity=sim-mpc",
        "run",
        "1",
    ] {
        assert!(!is_placeholder(word), "{word}");
    }
}
