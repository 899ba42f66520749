//! Ctrl-C (SIGINT) in `cpmx run` and `cpmx train`: the step under way finishes, what is kept is
//! said, the exit code is 130, and the printed command resumes to a complete folder.

mod support;

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use support::{ok, reference, root, scratch};

/// Sends SIGINT to `child` once `ready` holds (or after two minutes), and returns its exit
/// code and stderr.
fn interrupt_when(child: Child, ready: impl Fn() -> bool) -> (Option<i32>, String) {
    let deadline = Instant::now() + Duration::from_secs(120);
    while !ready() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(5));
    }
    let sent = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(sent.success());
    let out = child.wait_with_output().expect("cpmx ends");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The command after `resume with: ` in `stderr`, run from `dir`.
fn run_resume_command(stderr: &str, dir: &Path) -> std::process::Output {
    let line = stderr
        .lines()
        .find_map(|l| l.strip_prefix("resume with: "))
        .unwrap_or_else(|| panic!("no resume command in:\n{stderr}"));
    let words: Vec<&str> = line.split_whitespace().collect();
    assert_eq!(words[0], "cpmx", "{line}");
    Command::new(env!("CARGO_BIN_EXE_cpmx"))
        .args(&words[1..])
        .current_dir(dir)
        .env_remove("CPMX_DATA")
        .output()
        .expect("cpmx runs")
}

#[test]
fn an_interrupted_run_keeps_its_finished_runs_and_says_how_to_resume() {
    let dir = scratch("interrupt-run");
    let text = std::fs::read_to_string(root().join("experiments/quickstart.yaml")).unwrap();
    // Enough runs that the interrupt arrives while they are under way.
    let spec = dir.join("many.yaml");
    std::fs::write(&spec, text.replacen("repetitions: 1", "repetitions: 40 #", 1)).unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_cpmx"))
        .args(["run", "many.yaml", "--out", "out", "--jobs", "1"])
        .current_dir(&dir)
        .env_remove("CPMX_DATA")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let first = dir.join("out/runs/sim/cautious/crossing/rep1/metrics.json");
    let (code, stderr) = interrupt_when(child, || first.is_file());
    assert_eq!(code, Some(130), "{stderr}");
    assert!(
        stderr.contains("interrupted: every finished run is kept"),
        "{stderr}"
    );
    assert!(stderr.contains("not started"), "{stderr}");
    // The folder is consistent: its summary covers what finished, and the printed command
    // completes it.
    assert!(dir.join("out/summary.md").is_file());
    let resumed = run_resume_command(&stderr, &dir);
    ok(&resumed);
    let summary = std::fs::read_to_string(dir.join("out/summary.csv")).unwrap();
    assert!(
        summary.contains("sim,eager,cra_a,events/100 m,lower,160,"),
        "{summary}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn an_interrupted_training_finishes_its_iteration_and_resumes() {
    let dir = scratch("interrupt-train");
    let spec = dir.join("small.yaml");
    std::fs::write(
        &spec,
        "cpmx: 1\nname: small\nmap: {file: maps/cpm.xml}\ntraining:\n  scenario: {extends: \
         stdlib:sigmarl-intersection, envs: 4, agents: 2, episode_steps: 32}\n  reward: \
         stdlib:sigmarl-reward\n  algorithm: {extends: stdlib:mappo-sigmarl, mappo: \
         {frames_per_iteration: 128, minibatch: 64, epochs: 1}}\n  network: {hidden: [16], \
         activation: tanh}\n  iterations: 400\n  seeds: [1]\n",
    )
    .unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_cpmx"))
        .args(["train", "small.yaml", "--out", "out", "--data"])
        .arg(reference())
        .current_dir(&dir)
        .env_remove("CPMX_DATA")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let run_json = dir.join("out/1/run.json");
    let started = || {
        std::fs::read_to_string(&run_json)
            .ok()
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
            .and_then(|v| v["iterations_done"].as_u64())
            .is_some_and(|done| done >= 2)
    };
    let (code, stderr) = interrupt_when(child, started);
    assert_eq!(code, Some(130), "{stderr}");
    assert!(
        stderr.contains("interrupted: seed 1 stopped after iteration"),
        "{stderr}"
    );
    let resumed = run_resume_command(&stderr, &dir);
    let resumed_err = String::from_utf8_lossy(&resumed.stderr).into_owned();
    ok(&resumed);
    assert!(resumed_err.contains("resuming after iteration"), "{resumed_err}");
    let info: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&run_json).unwrap()).unwrap();
    assert_eq!(info["iterations_done"], 400);
    std::fs::remove_dir_all(&dir).ok();
}
