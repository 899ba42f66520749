//! A page's scratch copy of the repository, where its commands run.

use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::time::{Duration, Instant};

use crate::markdown::Page;
use crate::support::{self, root};

/// The longest a documented command may take before the test gives up on it.
const COMMAND_BUDGET: Duration = Duration::from_secs(600);

/// A page's scratch copy of the repository's specs: `<tmp>/cpmx-docs-<page>-<pid>/cpmx/` with
/// `experiments/` and `examples/` copied, `../shared/reference` beside it, `cpmx` on the PATH.
pub struct Scratch {
    pub repo: PathBuf,
    pub reference: PathBuf,
    bin: PathBuf,
}

/// What a command did.
pub struct Ran {
    pub code: Option<i32>,
    /// Its standard output and error in the order it wrote them, as a terminal shows them.
    pub output: String,
}

impl Ran {
    pub fn both(&self) -> String {
        self.output.clone()
    }
}

impl Scratch {
    /// A scratch copy for one test (`what`) of one page.
    pub fn new(page: &Page, what: &str) -> Scratch {
        let top = support::scratch(&format!("docs-{what}-{}", page.stem()));
        let repo = top.join("cpmx");
        for dir in ["experiments", "examples"] {
            copy_dir(&root().join(dir), &repo.join(dir));
        }
        std::os::unix::fs::symlink(root().join("cpmx.schema.json"), repo.join("cpmx.schema.json")).unwrap();
        std::fs::create_dir_all(top.join("shared")).unwrap();
        let reference = top.join("shared/reference");
        std::os::unix::fs::symlink(cpmx_testdata::reference_dir(), &reference).unwrap();
        let bin = top.join("bin");
        std::fs::create_dir_all(&bin).unwrap();
        std::os::unix::fs::symlink(env!("CARGO_BIN_EXE_cpmx"), bin.join("cpmx")).unwrap();
        Scratch { repo, reference, bin }
    }

    pub fn write(&self, file: &str, text: &str) {
        let path = self.repo.join(file);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, text).unwrap();
    }

    /// Runs `command` with bash in the scratch repository; `parse_only` stops cpmx after its
    /// argument parser.
    pub fn bash(&self, command: &str, parse_only: bool) -> Ran {
        let path = format!(
            "{}:{}",
            self.bin.display(),
            std::env::var("PATH").unwrap_or_default()
        );
        let out = self.repo.join("../output");
        let file = std::fs::File::create(&out).unwrap();
        let mut child = std::process::Command::new("bash")
            .args(["-c", command])
            .current_dir(&self.repo)
            .env("PATH", path)
            .env("NO_COLOR", "1")
            .env_remove("CPMX_DATA")
            .env("CPMX_PARSE_ONLY", if parse_only { "1" } else { "0" })
            .stdin(Stdio::null())
            .stdout(file.try_clone().unwrap())
            .stderr(file)
            .spawn()
            .expect("bash runs");
        let deadline = Instant::now() + COMMAND_BUDGET;
        let status = loop {
            if let Some(status) = child.try_wait().unwrap() {
                break Some(status);
            }
            if Instant::now() > deadline {
                let _ = child.kill();
                let _ = child.wait();
                break None;
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        Ran {
            code: status.and_then(|s| s.code()),
            output: std::fs::read_to_string(out).unwrap_or_default(),
        }
    }
}

impl Drop for Scratch {
    /// The scratch copy goes with its page (a failure's output is in the test's message), unless
    /// `CPMX_DOCS_KEEP` is set: then it stays, with what the page's commands wrote (to update a
    /// quoted table from them), and its path is printed.
    fn drop(&mut self) {
        let Some(top) = self.repo.parent() else {
            return;
        };
        if std::env::var_os("CPMX_DOCS_KEEP").is_some() {
            eprintln!("docs: kept {}", top.display());
        } else {
            let _ = std::fs::remove_dir_all(top);
        }
    }
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let path = entry.path();
        let target = to.join(entry.file_name());
        if path.is_dir() {
            copy_dir(&path, &target);
        } else {
            std::fs::copy(&path, &target).unwrap();
        }
    }
}
