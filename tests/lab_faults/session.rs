//! What the lab-fault tests share: a scenario in a network namespace of its own, the spec,
//! `cpmx lab emulate` and `cpmx run` as children killed on every exit path, one session of
//! both, and what a consistent run folder holds.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use super::common::{self, Killed, Namespace, in_network_namespace, wait_until};

/// Set in the copy of a test that runs inside its network namespace.
const INSIDE_NAMESPACE: &str = "CPMX_LAB_FAULTS_IN_NETNS";

/// Runs `scenario` in a namespace of its own (or here, when there is none) within `budget`.
pub(crate) fn in_namespace(test_name: &str, budget: Duration, scenario: fn(&Path, Instant)) {
    let started = Instant::now();
    let deadline = started + budget;
    match in_network_namespace(test_name, INSIDE_NAMESPACE, deadline) {
        Namespace::RanInside => {}
        Namespace::Inside | Namespace::Unavailable => {
            let dir = std::env::temp_dir().join(format!("cpmx-{test_name}-{}", common::test_process_id()));
            let _ = std::fs::remove_dir_all(&dir);
            std::fs::create_dir_all(&dir).expect("temp folder");
            scenario(&dir, deadline);
            let _ = std::fs::remove_dir_all(&dir);
        }
    }
}

/// A spec of `agents` lane-following cars on the intersection, `steps` ticks, two initial
/// configurations × `repetitions`, a twin fidelity and a lab fidelity (`lab_extra` appended
/// to its mapping) on a domain of its own, loopback only.
pub(crate) fn spec_text(steps: usize, repetitions: usize, lab_extra: &str) -> String {
    let domain = 100 + std::process::id() % 100;
    format!(
        "cpmx: 1
name: lab-faults
map: stdlib:intersection
vehicle: stdlib:mu-car
timing: {{dt: 0.1, steps: {steps}}}
agents: 2
policies:
  - name: lane
    builtin: lane-follow
initial_configurations:
  - name: crossing
    agents:
      - {{ref_path: 1, arc_length: 0.3}}
      - {{ref_path: 4, arc_length: 0.2}}
  - name: turning
    agents:
      - {{ref_path: 2, arc_length: 0.2}}
      - {{ref_path: 5, arc_length: 0.3}}
repetitions: {repetitions}
seed: 7
fidelities:
  twin:
    control: trajectory
    dynamics: stdlib:mu-car-greybox
    sensing: stdlib:cpm-ips
    actuation: {{delay_ms: 80}}
  lab: {{driver: cpm-dds, domain: {domain}, vehicle_ids: [1, 2], initial_peers: [127.0.0.1], interface: 127.0.0.1, timeout_s: 4{lab_extra}}}
planner:
  control_horizon: 4
  prediction_horizon: 12
  after_control_horizon: {{speed: hold, steering: linear-to-zero}}
on_collision: continue
metrics: stdlib:at25
"
    )
}

/// `cpmx lab emulate SPEC --runs N [args]`, its stderr to `log`.
pub(crate) fn emulator(spec: &Path, runs: usize, args: &[&str], log: &Path) -> Killed {
    Killed(
        Command::new(env!("CARGO_BIN_EXE_cpmx"))
            .args(["lab", "emulate"])
            .arg(spec)
            .args(["--runs", &runs.to_string()])
            .args(args)
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(log).expect("log file"))
            .spawn()
            .expect("cpmx lab emulate starts"),
    )
}

/// `cpmx run SPEC --only fidelity=lab --out OUT [args]`, its stderr to `log`.
pub(crate) fn lab_run(spec: &Path, out: &Path, args: &[&str], log: &Path) -> Killed {
    Killed(
        Command::new(env!("CARGO_BIN_EXE_cpmx"))
            .arg("run")
            .arg(spec)
            .args(["--only", "fidelity=lab", "--jobs", "1", "--out"])
            .arg(out)
            .args(args)
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(log).expect("log file"))
            .spawn()
            .expect("cpmx run starts"),
    )
}

/// One lab session: the emulator with `emulate_args` for `runs` runs, `cpmx run` with
/// `run_args`; both must end by `deadline`. Returns the run's status and both logs.
#[allow(clippy::too_many_arguments)]
pub(crate) fn session(
    dir: &Path,
    name: &str,
    spec: &Path,
    out: &Path,
    runs: usize,
    emulate_args: &[&str],
    run_args: &[&str],
    deadline: Instant,
) -> (ExitStatus, String) {
    let emulator_log = dir.join(format!("{name}.emulator.log"));
    let run_log = dir.join(format!("{name}.run.log"));
    let mut lab = emulator(spec, runs, emulate_args, &emulator_log);
    let mut run = lab_run(spec, out, run_args, &run_log);
    let status = wait_until(&mut run, deadline, &format!("{name}: cpmx run"));
    // The emulator serves its last run until the driver's timeout when that run failed.
    let _ = wait_until(&mut lab, deadline, &format!("{name}: cpmx lab emulate"));
    let logs = format!(
        "{name}: cpmx run ({status}):\n{}\n{name}: emulator:\n{}",
        common::read(&run_log),
        common::read(&emulator_log)
    );
    (status, logs)
}

/// The runs of a folder by key: `finished` (metrics.json and trajectory.csv, no
/// failed.json) or `failed` (failed.json, trajectory.csv when ticks were recorded, no
/// metrics.json); anything else fails the test.
pub(crate) fn consistent_folder(out: &Path, keys: &[String], logs: &str) -> BTreeMap<String, Option<String>> {
    keys.iter()
        .map(|key| {
            let dir = out.join("runs").join(key);
            let metrics = dir.join("metrics.json").is_file();
            let failed = dir.join("failed.json").is_file();
            let trajectory = dir.join("trajectory.csv").is_file();
            assert!(
                metrics != failed,
                "{key}: metrics.json {metrics}, failed.json {failed}\n{logs}"
            );
            if metrics {
                assert!(trajectory, "{key}: finished without trajectory.csv\n{logs}");
                (key.clone(), None)
            } else {
                let failure: serde_json::Value =
                    serde_json::from_str(&common::read(&dir.join("failed.json"))).expect("failed.json");
                let reason = failure["reason"].as_str().expect("a reason").to_owned();
                let earlier = failure["notes"].as_array().is_some_and(|notes| {
                    notes.iter().any(|n| {
                        n.as_str()
                            .is_some_and(|n| n.contains("an earlier attempt recorded"))
                    })
                });
                assert_eq!(
                    trajectory,
                    reason.contains("trajectory.csv holds what was recorded") || earlier,
                    "{key}: {failure}"
                );
                (key.clone(), Some(reason))
            }
        })
        .collect()
}

/// However a run ended, its vehicles were commanded to stop and stood a second later: the
/// emulator says so once per run it started (`logs` of one session).
pub(crate) fn every_run_stopped_its_vehicles(logs: &str) {
    let started = logs
        .lines()
        .filter(|l| l.starts_with("run ") && l.contains(") started"))
        .count();
    let stopped = logs
        .lines()
        .filter(|l| *l == "vehicles commanded to stop: [1, 2]; standing at the run's end: [1, 2]")
        .count();
    assert!(started > 0, "{logs}");
    assert_eq!(
        started, stopped,
        "runs started and runs whose vehicles were stopped\n{logs}"
    );
}

/// The lab run keys of the spec (`crossing`, `turning` × repetitions).
pub(crate) fn lab_keys(repetitions: usize) -> Vec<String> {
    ["crossing", "turning"]
        .iter()
        .flat_map(|c| (1..=repetitions).map(move |r| format!("lab/lane/{c}/rep{r}")))
        .collect()
}

/// `faults` as a file in `dir`; its path.
pub(crate) fn faults_file(dir: &Path, name: &str, faults: &str) -> PathBuf {
    let path = dir.join(format!("{name}.yaml"));
    std::fs::write(&path, faults).expect("faults file");
    path
}

/// A finished or failed run's notes or reason, as JSON text.
pub(crate) fn run_record(out: &Path, key: &str) -> String {
    let dir = out.join("runs").join(key);
    let metrics = common::read(&dir.join("metrics.json"));
    if metrics.is_empty() {
        common::read(&dir.join("failed.json"))
    } else {
        metrics
    }
}
