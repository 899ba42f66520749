//! A lab that does not answer costs one timeout, not one per run: the first run of the lab
//! fidelity waits `timeout_s` and fails with the reason; the fidelity's later runs fail at
//! once, saying why; the folder keeps its other runs. Runs inside a private network namespace
//! (nothing answers there, and no packet leaves it), loopback-only discovery otherwise.

mod common;

use std::process::Command;
use std::time::{Duration, Instant};

use common::{Namespace, in_network_namespace};

const INSIDE_NAMESPACE: &str = "CPMX_LAB_SILENT_IN_NETNS";
const TEST_NAME: &str = "a_silent_lab_costs_one_timeout";

#[test]
fn a_silent_lab_costs_one_timeout() {
    let started = Instant::now();
    match in_network_namespace(TEST_NAME, INSIDE_NAMESPACE, started + Duration::from_secs(60)) {
        Namespace::RanInside => return,
        Namespace::Inside | Namespace::Unavailable => {}
    }
    let dir = std::env::temp_dir().join(format!("cpmx-lab-silent-{}", common::test_process_id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let domain = 100 + std::process::id() % 100;
    let spec = dir.join("silent.yaml");
    std::fs::write(
        &spec,
        format!(
            "cpmx: 1\nname: silent\nmap: stdlib:intersection\ntiming: {{dt: 0.1, steps: 10}}\nagents: 2\n\
             policies:\n  - {{name: lane, builtin: lane-follow}}\n\
             initial_configurations:\n  - name: a\n    agents:\n      - {{ref_path: 1, arc_length: 0.3}}\n      - {{ref_path: 7, arc_length: 0.3}}\n\
             repetitions: 3\nseed: 1\nfidelities:\n  sim: {{control: direct, dynamics: kinematic}}\n  \
             lab: {{driver: cpm-dds, domain: {domain}, vehicle_ids: [1, 2], initial_peers: [127.0.0.1], interface: 127.0.0.1, timeout_s: 1}}\n\
             planner: {{control_horizon: 4, prediction_horizon: 12}}\n"
        ),
    )
    .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_cpmx"))
        .args([
            "run",
            spec.to_str().unwrap(),
            "--out",
            dir.join("out").to_str().unwrap(),
            "--jobs",
            "1",
        ])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{stderr}");
    // Each failure is listed once at the end (and once more as it happens on a terminal).
    let waited = stderr
        .matches("failed: lab/lane/a/rep1: the lab did not answer")
        .count();
    assert!(waited >= 1, "{stderr}");
    assert_eq!(
        stderr.matches("did not answer an earlier run").count(),
        2 * waited,
        "{stderr}"
    );
    // The sim runs are kept and summarised.
    assert!(dir.join("out/runs/sim/lane/a/rep3/metrics.json").is_file());
    std::fs::remove_dir_all(&dir).ok();
}
