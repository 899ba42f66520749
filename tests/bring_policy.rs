//! Bringing a policy end to end: an MLP of other layer sizes written by the test runs; a
//! mis-shaped one is refused by `cpmx validate` naming the tensor and the shapes; the reference
//! Python client of the policy-process protocol drives a quickstart-sized spec in the sim and
//! in a trajectory fidelity (with predictions); a process that exits mid-run or hangs fails only
//! its own runs, with its stderr.

mod support;

use support::{cpmx_in as cpmx, root, temp, walk, write_mlp};

const QUICKSTART_SIZED: &str = "cpmx: 1
name: bring
map: stdlib:intersection
timing: {dt: 0.1, steps: 50}
agents: 4
initial_configurations:
  - name: crossing
    agents:
      - {ref_path: 1, arc_length: 0.3}
      - {ref_path: 4, arc_length: 0.2}
      - {ref_path: 7, arc_length: 0.3}
      - {ref_path: 11, arc_length: 0.2}
  - sample: {count: 2, seed: 11, min_gap: 0.5}
repetitions: 2
seed: 2026
";

#[test]
fn a_32_64_64_64_4_relu_actor_runs_and_a_mis_shaped_one_is_named() {
    let dir = temp("mlp");
    write_mlp(&dir.join("relu.safetensors"), &[32, 64, 64, 64, 4]);
    write_mlp(&dir.join("wrong.safetensors"), &[30, 64, 64, 64, 4]);
    let spec = format!(
        "{QUICKSTART_SIZED}policies:
  - {{name: relu-actor, mlp: {{weights: relu.safetensors, activation: relu}}}}
fidelities:
  sim: {{control: direct, dynamics: kinematic}}
"
    );
    std::fs::write(dir.join("spec.yaml"), &spec).unwrap();
    let out = cpmx(&dir, &["run", "spec.yaml", "--out", "out"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(dir.join("out/summary.md").is_file());

    std::fs::write(
        dir.join("wrong.yaml"),
        spec.replace("relu.safetensors", "wrong.safetensors"),
    )
    .unwrap();
    let out = cpmx(&dir, &["validate", "wrong.yaml"]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    // The words of the diagnostic, whatever the terminal width wraps.
    let flat = stderr
        .split_whitespace()
        .filter(|w| *w != "│")
        .collect::<Vec<_>>()
        .join(" ");
    assert!(
        flat.contains(
            "tensor `actor.0.weight` has shape [64, 30], expected [64, 32]: the first layer takes the observation's 32 values"
        ),
        "{stderr}"
    );
    assert!(
        flat.contains("set `observation:` to the design this network was trained with"),
        "{stderr}"
    );
    assert!(!stderr.contains("the observation `"), "{stderr}");
    std::fs::remove_dir_all(&dir).ok();
}

fn planner() -> String {
    root()
        .join("examples/policy-process/planner.py")
        .display()
        .to_string()
}

#[test]
fn the_reference_python_client_drives_the_sim_and_a_trajectory_fidelity() {
    let dir = temp("process");
    let spec = format!(
        "{QUICKSTART_SIZED}policies:
  - name: python
    process: {{command: [python3, \"{}\", --require-observation]}}
    observation: stdlib:sigmarl
fidelities:
  sim: {{control: direct, dynamics: kinematic}}
  sim-mpc: {{control: trajectory, dynamics: kinematic}}
planner:
  control_horizon: 3
  prediction_horizon: 8
  after_control_horizon: {{speed: hold, steering: linear-to-zero}}
",
        planner()
    );
    std::fs::write(dir.join("spec.yaml"), &spec).unwrap();
    let out = cpmx(&dir, &["run", "spec.yaml", "--out", "out", "--jobs", "2"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // 3 configurations x 2 repetitions x 2 fidelities, each with its metrics.
    let metrics = walk(&dir.join("out"))
        .into_iter()
        .filter(|p| p.ends_with("metrics.json"))
        .count();
    assert_eq!(metrics, 12);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_process_that_exits_or_hangs_fails_only_its_own_runs_with_its_stderr() {
    let dir = temp("crash");
    let spec = format!(
        "{QUICKSTART_SIZED}policies:
  - name: quitter
    process: {{command: [python3, \"{}\", --exit-at-step, \"5\"]}}
  - name: sleeper
    process: {{command: [python3, -c, \"import time; time.sleep(30)\"], timeout_s: 0.5}}
  - {{name: baseline, builtin: lane-follow}}
fidelities:
  sim: {{control: direct, dynamics: kinematic}}
",
        planner()
    );
    std::fs::write(dir.join("spec.yaml"), &spec).unwrap();
    let out = cpmx(&dir, &["run", "spec.yaml", "--out", "out"]);
    assert_eq!(
        out.status.code(),
        Some(3),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    // Failed run keys (the progress bar may print them too).
    let failed: std::collections::BTreeSet<&str> = stderr
        .lines()
        .filter_map(|l| l.trim_start().strip_prefix("failed: "))
        .filter_map(|l| l.split(": ").next())
        .collect();
    // 3 configurations x 2 repetitions for each of the two processes.
    assert_eq!(
        failed.iter().filter(|l| l.contains("quitter")).count(),
        6,
        "{stderr}"
    );
    assert_eq!(
        failed.iter().filter(|l| l.contains("sleeper")).count(),
        6,
        "{stderr}"
    );
    assert!(!failed.iter().any(|l| l.contains("baseline")), "{stderr}");
    assert!(
        stderr.contains("giving up at step 5 (--exit-at-step)"),
        "{stderr}"
    );
    assert!(stderr.contains("exited with status 3"), "{stderr}");
    assert!(
        stderr.contains("did not answer the hello within 0.5 s"),
        "{stderr}"
    );
    // The baseline's runs have their metrics.
    let metrics = walk(&dir.join("out"))
        .into_iter()
        .filter(|p| p.ends_with("metrics.json"))
        .count();
    assert_eq!(metrics, 6);
    std::fs::remove_dir_all(&dir).ok();
}
