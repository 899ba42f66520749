//! Records the git commit the `cpmx` binary is built from (`CPMX_COMMIT`, empty outside a
//! git checkout), so that what `cpmx train` makes names the code that made it. A build from a
//! tree whose code differs from that commit (uncommitted changes to the sources the binary is
//! compiled from) says so: `<commit>, modified`, so that a training's `run.json` never names a
//! commit whose code did not make it.

use std::process::Command;

/// What the binary is compiled from: its crates' sources and the workspace's manifests.
const CODE: [&str; 7] = [
    "src",
    "spec",
    "stdlib",
    "interpreter",
    "Cargo.toml",
    "Cargo.lock",
    "build.rs",
];

fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git").args(args).output().ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_owned())
}

fn main() {
    let head = git(&["rev-parse", "HEAD"]).unwrap_or_default();
    let mut status = vec!["status", "--porcelain", "--untracked-files=no", "--"];
    status.extend(CODE);
    let modified = !head.is_empty() && git(&status).is_some_and(|changes| !changes.is_empty());
    let commit = if modified {
        format!("{head}, modified")
    } else {
        head
    };
    println!("cargo:rustc-env=CPMX_COMMIT={commit}");
    // Build again when HEAD moves (HEAD itself, the branch it names, packed refs), when the
    // index changes (a commit, `git add`), and when the code changes.
    let mut watched = vec!["HEAD".to_owned(), "packed-refs".to_owned(), "index".to_owned()];
    if let Some(branch) = git(&["symbolic-ref", "-q", "HEAD"]) {
        watched.push(branch);
    }
    for name in watched {
        // Only files that exist: cargo runs the script every time for a missing one.
        if let Some(path) = git(&["rev-parse", "--git-path", &name])
            && std::path::Path::new(&path).exists()
        {
            println!("cargo:rerun-if-changed={path}");
        }
    }
    for path in CODE {
        println!("cargo:rerun-if-changed={path}");
    }
}
