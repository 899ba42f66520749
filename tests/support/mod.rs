//! What the command-line tests share: the repository and reference-data folders, running the
//! `cpmx` binary, scratch folders, a folder's files with their bytes, and small MLP weight
//! files. Each test binary uses a part of it.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The repository.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// SigmaRL's reference data beside the repository (`../shared/reference`, or
/// `CPMX_REFERENCE_DIR`); tests that need it call this first, so that without it they fail
/// with one line naming the folder.
#[track_caller]
pub fn reference() -> PathBuf {
    cpmx_testdata::reference()
}

/// The first line of a failure that may come from missing reference data: the line naming the
/// folder when it is not there, nothing when it is.
pub fn reference_note() -> String {
    if cpmx_testdata::reference_available() {
        String::new()
    } else {
        format!("{}\n", cpmx_testdata::missing(&cpmx_testdata::reference_dir()))
    }
}

/// The Python interpreter of the test venv (`CPMX_PYTHON`, set by `scripts/test`), or `None`
/// after saying on stderr that the calling test is skipped; with `CPMX_REQUIRE_PYTHON=1` a
/// missing interpreter fails the test instead.
pub fn python(test: &str) -> Option<PathBuf> {
    match std::env::var_os("CPMX_PYTHON") {
        Some(python) => Some(PathBuf::from(python)),
        None if std::env::var_os("CPMX_REQUIRE_PYTHON").is_some_and(|v| v == "1") => {
            panic!("{test}: CPMX_PYTHON is not set (scripts/test sets it to the test venv's python)")
        }
        None => {
            eprintln!("skipped: {test}: needs the test venv's python in CPMX_PYTHON (scripts/test sets it)");
            None
        }
    }
}

/// `cpmx ARGS` in the repository, without `CPMX_DATA`.
pub fn cpmx(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cpmx"))
        .args(args)
        .current_dir(root())
        .env_remove("CPMX_DATA")
        .output()
        .expect("cpmx runs")
}

/// `cpmx ARGS` in the repository with the reference data on `CPMX_DATA` when it is there.
pub fn cpmx_with_data(args: &[&str]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_cpmx"));
    command.args(args).current_dir(root());
    let data = cpmx_testdata::reference_dir();
    if data.is_dir() {
        command.env("CPMX_DATA", data);
    } else {
        command.env_remove("CPMX_DATA");
    }
    command.output().expect("cpmx runs")
}

/// An empty folder of this test process, `<tmp>/cpmx-<name>-<pid>`.
pub fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("cpmx-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Every file under `dir` with its bytes, sorted by path.
pub fn files(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else {
                out.push((
                    path.strip_prefix(dir).unwrap().to_path_buf(),
                    std::fs::read(&path).unwrap(),
                ));
            }
        }
    }
    out.sort();
    out
}

/// The standard output of a command that must have succeeded (its stderr otherwise).
pub fn ok(out: &Output) -> String {
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout.clone()).unwrap()
}

/// Diagnostics with miette's line wrapping undone: a message continues on lines that start
/// with `│`, which are joined to the line before with a space.
pub fn unwrapped(stderr: &[u8]) -> String {
    let text = String::from_utf8_lossy(stderr);
    let mut out = String::new();
    for line in text.lines() {
        match line.trim_start().strip_prefix('│') {
            Some(rest) => {
                out.push(' ');
                out.push_str(rest.trim());
            }
            None => {
                out.push('\n');
                out.push_str(line);
            }
        }
    }
    out
}

/// `cpmx ARGS` run in `dir` (relative files of a spec there resolve from it).
pub fn cpmx_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cpmx"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("cpmx runs")
}

/// A folder of this test process, `<tmp>/cpmx-<name>-<pid>`, kept if it exists.
pub fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("cpmx-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Every file below `dir`, depth first.
pub fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let path = entry.path();
        if path.is_dir() {
            out.extend(walk(&path));
        } else {
            out.push(path);
        }
    }
    out
}

/// A safetensors file of an MLP with layer `sizes` (`actor.N.weight` / `actor.N.bias`).
pub fn write_mlp(path: &Path, sizes: &[usize]) {
    let mut header = Vec::new();
    let mut data: Vec<u8> = Vec::new();
    for (l, pair) in sizes.windows(2).enumerate() {
        let (inputs, outputs) = (pair[0], pair[1]);
        let w = (0..inputs * outputs).map(|i| ((i * 7 + l) as f32 * 0.37).sin() / (inputs as f32).sqrt());
        let b = (0..outputs).map(|j| (j as f32 * 0.21).cos() * 0.05);
        for (kind, values, shape) in [
            ("weight", w.collect::<Vec<f32>>(), format!("[{outputs},{inputs}]")),
            ("bias", b.collect::<Vec<f32>>(), format!("[{outputs}]")),
        ] {
            let start = data.len();
            data.extend(values.iter().flat_map(|v| v.to_le_bytes()));
            header.push(format!(
                "\"actor.{l}.{kind}\":{{\"dtype\":\"F32\",\"shape\":{shape},\"data_offsets\":[{start},{}]}}",
                data.len()
            ));
        }
    }
    let header = format!("{{{}}}", header.join(","));
    let mut bytes = (header.len() as u64).to_le_bytes().to_vec();
    bytes.extend(header.as_bytes());
    bytes.extend(data);
    std::fs::write(path, bytes).unwrap();
}
