//! The lab driver end to end over DDS: `cpmx lab emulate` plays the CPM Lab from the twin
//! fidelity of a spec while `cpmx run` drives the spec's lab fidelity (built-in intersection,
//! `builtin: lane-follow`, 3 agents, 50 steps, 2 initial configurations). The lab runs must
//! complete, be stored, and agree with the same spec's twin runs.
//!
//! Why they agree, and the bound: the emulator serves the twin's vehicle stacks in lock-step
//! with the run's seed, so the planner sees the same reported states as in the twin run and
//! the vehicles drive the same trajectories. What differs is what is recorded: the lab run
//! records the states the vehicles *report* (on-car estimates from the simulated IPS, 60 ms old,
//! moved by their velocity to the tick), the twin run the true states. Bound: every recorded
//! position within 3 cm of the twin's (measured: within 1 cm), the same collision events,
//! |ΔAS| ≤ 0.02 m/s, |ΔCD| ≤ 5 mm, distance within 2 %, lane violation within
//! 0.3 m + 12 % of the distance.
//!
//! Every DDS packet stays on this host: the test re-runs itself inside a private network
//! namespace (`unshare --net`, loopback up) when the sandbox allows it, and otherwise uses
//! loopback-only discovery on a domain derived from the process id. The whole test is
//! bounded by [`BUDGET`]; the emulator is killed on every exit path.

mod common;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{Killed, Namespace, in_network_namespace, wait_until};

/// The whole test's time budget.
const BUDGET: Duration = Duration::from_secs(60);

/// Set in the copy of this test that runs inside the network namespace.
const INSIDE_NAMESPACE: &str = "CPMX_LAB_E2E_IN_NETNS";

/// This test's name, for re-running it alone.
const TEST_NAME: &str = "lab_runs_through_the_emulator_match_the_twin_runs";

const STEPS: usize = 50;
const AGENTS: usize = 3;

#[test]
fn lab_runs_through_the_emulator_match_the_twin_runs() {
    let started = Instant::now();
    // In a private network (and pid) namespace when the sandbox allows it: no packet
    // leaves it, and everything in it dies with it.
    match in_network_namespace(TEST_NAME, INSIDE_NAMESPACE, started + BUDGET) {
        Namespace::RanInside => return,
        Namespace::Inside | Namespace::Unavailable => {}
    }
    scenario(started + BUDGET);
}

/// The spec: a twin fidelity and a lab fidelity on `domain`, loopback only.
fn spec_text(domain: u32) -> String {
    format!(
        "cpmx: 1
name: lab-e2e
map: stdlib:intersection
vehicle: stdlib:mu-car
timing: {{dt: 0.1, steps: {STEPS}}}
agents: {AGENTS}
policies:
  - name: lane
    builtin: lane-follow
initial_configurations:
  - name: crossing
    agents:
      - {{ref_path: 1, arc_length: 0.3}}
      - {{ref_path: 4, arc_length: 0.2}}
      - {{ref_path: 7, arc_length: 0.3}}
  - name: turning
    agents:
      - {{ref_path: 2, arc_length: 0.2}}
      - {{ref_path: 5, arc_length: 0.3}}
      - {{ref_path: 6, arc_length: 0.2}}
repetitions: 1
seed: 7
fidelities:
  twin:
    control: trajectory
    dynamics: stdlib:mu-car-greybox
    sensing: stdlib:cpm-ips
    actuation: {{delay_ms: 80}}
  lab: {{driver: cpm-dds, domain: {domain}, vehicle_ids: [1, 2, 3], initial_peers: [127.0.0.1], interface: 127.0.0.1, timeout_s: 20}}
planner:
  control_horizon: 4
  prediction_horizon: 12
  after_control_horizon: {{speed: hold, steering: linear-to-zero}}
on_collision: continue
metrics: stdlib:at25
"
    )
}

fn scenario(deadline: Instant) {
    let cpmx = env!("CARGO_BIN_EXE_cpmx");
    let dir = std::env::temp_dir().join(format!("cpmx-lab-e2e-{}", common::test_process_id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp folder");
    let spec = dir.join("lab.yaml");
    // A domain of its own: the lab uses 21 and 1, the lab crate's tests 217..=219.
    let domain = 100 + std::process::id() % 100;
    std::fs::write(&spec, spec_text(domain)).expect("spec written");

    // The lab, for the two lab runs of the matrix.
    let emulator_log = dir.join("emulator.log");
    let mut emulator = Killed(
        Command::new(cpmx)
            .args(["lab", "emulate"])
            .arg(&spec)
            .args(["--runs", "2"])
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&emulator_log).expect("log file"))
            .spawn()
            .expect("cpmx lab emulate starts"),
    );

    // The matrix: 2 twin runs and 2 lab runs.
    let out = dir.join("out");
    let run_log = dir.join("run.log");
    let mut run = Killed(
        Command::new(cpmx)
            .arg("run")
            .arg(&spec)
            .arg("--out")
            .arg(&out)
            .args(["--jobs", "2"])
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&run_log).expect("log file"))
            .spawn()
            .expect("cpmx run starts"),
    );
    let status = wait_until(&mut run, deadline, "cpmx run");
    let run_stderr = common::read(&run_log);
    let emulator_status = wait_until(&mut emulator, deadline, "cpmx lab emulate --runs 2");
    let emulator_stderr = common::read(&emulator_log);
    assert!(
        status.success(),
        "cpmx run failed:\n{run_stderr}\nemulator:\n{emulator_stderr}"
    );
    assert!(
        emulator_status.success(),
        "the emulator failed:\n{emulator_stderr}"
    );
    assert_eq!(
        emulator_stderr
            .matches(&format!("run finished after {STEPS} ticks"))
            .count(),
        2,
        "{emulator_stderr}"
    );

    // Every lab run is stored and agrees with its twin run.
    let rows = per_run(&out);
    assert_eq!(rows.len(), 4, "{rows:?}");
    for configuration in ["crossing", "turning"] {
        let lab = &rows[&format!("lab/lane/{configuration}/rep1")];
        let twin = &rows[&format!("twin/lane/{configuration}/rep1")];
        let key = format!("{configuration}: lab {lab:?}, twin {twin:?}");
        assert_eq!(lab["num_samples"], STEPS as f64, "{key}");
        assert_eq!(lab["a2a_events"], twin["a2a_events"], "{key}");
        assert!((lab["as_mps"] - twin["as_mps"]).abs() <= 0.02, "{key}");
        assert!((lab["cd_m"] - twin["cd_m"]).abs() <= 0.005, "{key}");
        assert!(
            (lab["distance_m"] / twin["distance_m"] - 1.0).abs() <= 0.02,
            "{key}"
        );
        // Lane violation counts the distance driven while beyond the marking's slack: a car
        // that rides the marking (the turning configuration's lane-follow cars do, CRA-L 20–30)
        // flips in and out with millimetres of estimation noise, so it agrees less closely
        // than the positions do.
        assert!(
            (lab["lane_violation_m"] - twin["lane_violation_m"]).abs() <= 0.3 + 0.12 * twin["distance_m"],
            "{key}"
        );

        let lab_path = trajectory(&out, &format!("lab/lane/{configuration}/rep1"));
        let twin_path = trajectory(&out, &format!("twin/lane/{configuration}/rep1"));
        assert_eq!(lab_path.len(), STEPS * AGENTS);
        assert_eq!(lab_path.len(), twin_path.len());
        for (l, t) in lab_path.iter().zip(&twin_path) {
            assert_eq!((l[0], l[1]), (t[0], t[1]), "same time and agent");
            let gap_m = (l[2] - t[2]).hypot(l[3] - t[3]);
            assert!(
                gap_m <= 0.03,
                "{configuration}: t = {} s agent {}: {gap_m} m apart",
                l[0],
                l[1]
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `per_run.csv` as key → column → number.
fn per_run(out: &Path) -> HashMap<String, HashMap<String, f64>> {
    let text = std::fs::read_to_string(out.join("per_run.csv")).expect("per_run.csv");
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    lines
        .map(|line| {
            let fields: Vec<&str> = line.split(',').collect();
            let numbers = header
                .iter()
                .zip(&fields)
                .filter_map(|(h, f)| Some(((*h).to_owned(), f.parse::<f64>().ok()?)))
                .collect();
            (fields[0].to_owned(), numbers)
        })
        .collect()
}

/// The `t, agent, x, y` columns of a stored run's `trajectory.csv`.
fn trajectory(out: &Path, key: &str) -> Vec<[f64; 4]> {
    let path: PathBuf = out.join("runs").join(key).join("trajectory.csv");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    text.lines()
        .skip(1)
        .map(|line| {
            let f: Vec<f64> = line
                .split(',')
                .take(4)
                .map(|v| v.parse().expect("number"))
                .collect();
            [f[0], f[1], f[2], f[3]]
        })
        .collect()
}
