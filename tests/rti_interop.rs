//! The lab driver against RTI Connext DDS, the lab's own middleware vendor: RTI Connector for
//! Python (`rticonnextdds-connector`, RTI's DDS libraries) with the lab's types in RTI's XML
//! type format (`tests/rti/lab_types.xml`) and the lab's topics and QoS
//! (`tests/rti/lab_participants.xml`: localhost initial peers, unknown peers refused, no
//! multicast, UDPv4 only).
//!
//! - `rti_middleware_drives_the_cpmx_lab_driver`: `tests/rti/play_lab.py` plays the lab's
//!   middleware (waits for `hlc_<id>`, start trigger, ticks `VehicleStateList`, checks the
//!   trajectories' lead time, stop trigger) against `cpmx run` of a lab spec. The run must
//!   complete with the ticks the script sent, and end on the script's stop trigger.
//! - `rti_subscriber_reads_the_lab_emulator`: `tests/rti/read_emulator.py` reads what
//!   `cpmx lab emulate` publishes while `cpmx run` drives it, and checks the values; what it
//!   decoded must equal what the driver recorded.
//! - `rti_middleware_sees_the_driver_stop_a_car_that_lost_its_fixes`: `play_lab.py` plays a
//!   car whose positioning fixes stop (its IPS age grows); the driver must fail the run naming
//!   the fault, keep what it recorded, and command every vehicle to stop.
//!
//! Both move stamps above 2^53 (ns since 1970, the run seed in `next_start_stamp`) and the stop
//! stamp 2^64 - 1 between rustdds and RTI, which Connector handles exactly only through its
//! string and dictionary accessors (see `tests/rti/lab_rti.py`).
//!
//! The Python interpreter is the venv in `CPMX_RTI_PYTHON` (`.ci/run` makes it); without it the
//! tests fail. They are compiled only with the feature `rti-interop`. Each scenario runs in its
//! own private network namespace (`unshare --net --pid`, loopback up) and is bounded by
//! [`BUDGET`]; every child is killed on every exit path.
#![cfg(feature = "rti-interop")]

mod common;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::thread;
use std::time::{Duration, Instant};

use common::{Killed, Namespace, in_network_namespace, wait_until};
use serde_json::Value;

/// Each scenario's time budget.
const BUDGET: Duration = Duration::from_secs(60);

/// The budget the scripts get for themselves (they exit with a message when it runs out).
const SCRIPT_TIMEOUT_S: &str = "45";

/// The venv Python with `rticonnextdds-connector`.
const PYTHON_VAR: &str = "CPMX_RTI_PYTHON";

/// Set in the copy of a test that runs inside its network namespace.
const INSIDE_NAMESPACE: &str = "CPMX_RTI_INTEROP_IN_NETNS";

/// The middleware's local domain to its planners: the namespace is private, so the lab's own.
const DOMAIN: u32 = 1;

/// The lab's vehicle ids, one per agent.
const VEHICLE_IDS: &str = "1,2";

/// The spec's `timing.dt` as the middleware's period.
const PERIOD_MS: u64 = 100;

const HOW_TO_MAKE_THE_VENV: &str = "create the venv and point CPMX_RTI_PYTHON at it, as .ci/run does:
    python3 -m venv target/rti-venv && target/rti-venv/bin/pip install rticonnextdds-connector
    CPMX_RTI_PYTHON=$PWD/target/rti-venv/bin/python cargo test --features rti-interop --test rti_interop";

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The venv's Python, checked to import RTI Connector.
fn python() -> PathBuf {
    let Some(path) = std::env::var_os(PYTHON_VAR) else {
        panic!(
            "{PYTHON_VAR} is not set: the RTI interoperability tests need RTI Connector for Python; {HOW_TO_MAKE_THE_VENV}"
        );
    };
    let python = root().join(path);
    let import = Command::new(&python)
        .args(["-c", "import rticonnextdds_connector"])
        .output();
    match import {
        Ok(out) if out.status.success() => python,
        Ok(out) => panic!(
            "{} cannot import rticonnextdds_connector:\n{}\n{HOW_TO_MAKE_THE_VENV}",
            python.display(),
            String::from_utf8_lossy(&out.stderr)
        ),
        Err(e) => panic!(
            "{PYTHON_VAR}={} does not run ({e}); {HOW_TO_MAKE_THE_VENV}",
            python.display()
        ),
    }
}

/// Runs `scenario` inside its own network namespace; the test fails when there is none.
fn in_namespace(test_name: &str, scenario: fn(&Path, Instant)) {
    let started = Instant::now();
    let python = python();
    match in_network_namespace(test_name, INSIDE_NAMESPACE, started + BUDGET) {
        Namespace::RanInside => {}
        Namespace::Inside => scenario(&python, started + BUDGET),
        Namespace::Unavailable => panic!(
            "cannot make a private network namespace (`unshare --net --pid --fork`): the RTI \
             interoperability tests keep RTI's traffic inside one"
        ),
    }
}

/// The lab spec: built-in intersection, `builtin: lane-follow`, 2 agents, `steps` ticks, a twin
/// fidelity for the emulator and the lab fidelity on [`DOMAIN`], loopback only.
fn spec_text(steps: usize) -> String {
    format!(
        "cpmx: 1
name: rti-interop
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
repetitions: 1
seed: 7
fidelities:
  twin:
    control: trajectory
    dynamics: stdlib:mu-car-greybox
    sensing: stdlib:cpm-ips
    actuation: {{delay_ms: 80}}
  lab: {{driver: cpm-dds, domain: {DOMAIN}, vehicle_ids: [{VEHICLE_IDS}], initial_peers: [127.0.0.1], interface: 127.0.0.1, timeout_s: 20}}
planner:
  control_horizon: 4
  prediction_horizon: 12
  after_control_horizon: {{speed: hold, steering: linear-to-zero}}
on_collision: continue
metrics: stdlib:at25
"
    )
}

/// A fresh folder with the spec for `steps` ticks.
fn workspace(name: &str, steps: usize) -> (PathBuf, PathBuf) {
    let dir = std::env::temp_dir().join(format!("cpmx-rti-{name}-{}", common::test_process_id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp folder");
    let spec = dir.join("lab.yaml");
    std::fs::write(&spec, spec_text(steps)).expect("spec written");
    (dir, spec)
}

/// The spec's starts (`cpmx plan --format json`) as `play_lab.py --starts` wants them: a JSON
/// list of `[x, y, yaw]` per vehicle, for the configuration `crossing`.
fn starts_arg(spec: &Path) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_cpmx"))
        .arg("plan")
        .arg(spec)
        .args(["--format", "json"])
        .output()
        .expect("cpmx plan runs");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let plan: Value = serde_json::from_slice(&out.stdout).expect("cpmx plan's JSON");
    let poses: Vec<Value> = plan["starts"]["crossing"]
        .as_array()
        .expect("the configuration `crossing`")
        .iter()
        .map(|s| serde_json::json!([s["x_m"], s["y_m"], s["yaw_rad"]]))
        .collect();
    Value::from(poses).to_string()
}

/// A script of `tests/rti` with `args`, stdout and stderr to `<dir>/<log>.{json,log}`.
fn script(python: &Path, dir: &Path, name: &str, args: &[&str]) -> Killed {
    Killed(
        Command::new(python)
            .arg(root().join("tests/rti").join(name))
            .args(["--domain", &DOMAIN.to_string(), "--vehicle-ids", VEHICLE_IDS])
            .args([
                "--period-ms",
                &PERIOD_MS.to_string(),
                "--timeout-s",
                SCRIPT_TIMEOUT_S,
            ])
            .args(args)
            .env("PYTHONDONTWRITEBYTECODE", "1")
            .stdout(std::fs::File::create(dir.join(format!("{name}.json"))).expect("log file"))
            .stderr(std::fs::File::create(dir.join(format!("{name}.log"))).expect("log file"))
            .spawn()
            .unwrap_or_else(|e| panic!("{} {name} does not start: {e}", python.display())),
    )
}

/// `cpmx` with `args`, stderr to `<dir>/<log>`.
fn cpmx(dir: &Path, log: &str, args: &[&str]) -> Killed {
    Killed(
        Command::new(env!("CARGO_BIN_EXE_cpmx"))
            .args(args)
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(dir.join(log)).expect("log file"))
            .spawn()
            .expect("cpmx starts"),
    )
}

/// The lab run of the spec: `cpmx run SPEC --only fidelity=lab --out <dir>/out`.
fn lab_run(dir: &Path, spec: &Path) -> Killed {
    let spec = spec.to_str().expect("utf-8 path");
    let out = dir.join("out");
    cpmx(
        dir,
        "run.log",
        &[
            "run",
            spec,
            "--only",
            "fidelity=lab",
            "--out",
            out.to_str().expect("utf-8 path"),
        ],
    )
}

/// A script's JSON summary.
fn summary(dir: &Path, name: &str) -> Value {
    let text = common::read(&dir.join(format!("{name}.json")));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{name} printed no JSON summary ({e}):\n{text}"))
}

/// A JSON number as an exact u64 (serde_json keeps integers exact).
fn u64_of(value: &Value) -> u64 {
    value.as_u64().unwrap_or_else(|| panic!("{value} is not a u64"))
}

/// The stored lab run: its seed (`per_run.csv`) and its recording's rows
/// (`trajectory.csv`: t, agent, x, y).
fn stored_run(dir: &Path) -> (u64, Vec<[f64; 4]>) {
    let out = dir.join("out");
    let per_run = common::read(&out.join("per_run.csv"));
    let mut lines = per_run.lines();
    let header: Vec<&str> = lines.next().expect("per_run.csv header").split(',').collect();
    let row: HashMap<&str, &str> = header
        .iter()
        .copied()
        .zip(lines.next().expect("one run").split(','))
        .collect();
    let seed = row["seed"].parse().expect("seed");
    let trajectory = common::read(&out.join("runs/lab/lane/crossing/rep1/trajectory.csv"));
    let rows = trajectory
        .lines()
        .skip(1)
        .map(|line| {
            let f: Vec<f64> = line
                .split(',')
                .take(4)
                .map(|v| v.parse().expect("number"))
                .collect();
            [f[0], f[1], f[2], f[3]]
        })
        .collect();
    (seed, rows)
}

/// The distinct times of a recording, in order.
fn times(rows: &[[f64; 4]]) -> Vec<f64> {
    let mut times: Vec<f64> = rows.iter().map(|r| r[0]).collect();
    times.dedup();
    times
}

/// The ticks a script reports, as seconds since the first.
fn tick_times(summary: &Value) -> Vec<f64> {
    let ticks: Vec<u64> = summary["ticks_ns"]
        .as_array()
        .expect("ticks_ns")
        .iter()
        .map(u64_of)
        .collect();
    ticks.iter().map(|t| (t - ticks[0]) as f64 / 1e9).collect()
}

fn assert_same_times(recorded: &[f64], sent: &[f64], context: &str) {
    assert_eq!(recorded.len(), sent.len(), "{context}: {recorded:?} vs {sent:?}");
    for (r, s) in recorded.iter().zip(sent) {
        assert!((r - s).abs() < 1e-9, "{context}: recorded {r} s, tick at {s} s");
    }
}

#[test]
fn rti_middleware_drives_the_cpmx_lab_driver() {
    in_namespace("rti_middleware_drives_the_cpmx_lab_driver", middleware_scenario);
}

/// The script sends this many ticks, then the stop trigger; the spec asks for more.
const SCRIPT_TICKS: usize = 30;
const SPEC_STEPS: usize = 36;

fn middleware_scenario(python: &Path, deadline: Instant) {
    let (dir, spec) = workspace("middleware", SPEC_STEPS);
    let starts = starts_arg(&spec);
    let mut middleware = script(
        python,
        &dir,
        "play_lab.py",
        &["--ticks", &SCRIPT_TICKS.to_string(), "--starts", &starts],
    );
    let mut run = lab_run(&dir, &spec);
    let run_status = wait_until(&mut run, deadline, "cpmx run");
    let script_status = wait_until(&mut middleware, deadline, "play_lab.py");
    let logs = format!(
        "cpmx run:\n{}\nplay_lab.py:\n{}",
        common::read(&dir.join("run.log")),
        common::read(&dir.join("play_lab.py.log"))
    );
    assert!(script_status.success(), "play_lab.py failed\n{logs}");
    assert!(run_status.success(), "cpmx run failed\n{logs}");

    // The recording has exactly the ticks the script sent. The spec asks for more: the run
    // succeeded with fewer only because the driver took RTI's stop trigger (2^64 - 1) for
    // one (a silent lab fails the run after `timeout_s`).
    let played = summary(&dir, "play_lab.py");
    let sent = tick_times(&played);
    assert_eq!(sent.len(), SCRIPT_TICKS);
    let (seed, rows) = stored_run(&dir);
    assert_eq!(rows.len(), SCRIPT_TICKS * 2, "{logs}");
    assert_same_times(&times(&rows), &sent, "recording vs RTI ticks");

    // The announcements carried the run seed (a u64 beyond 2^53) to RTI exactly.
    let announced = played["announced"].as_object().expect("announced");
    for id in VEHICLE_IDS.split(',') {
        let stamp = announced
            .get(&format!("hlc_{id}"))
            .unwrap_or_else(|| panic!("no hlc_{id} in {announced:?}"));
        assert_eq!(u64_of(stamp), seed, "hlc_{id}'s next_start_stamp is the run seed");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn rti_subscriber_reads_the_lab_emulator() {
    in_namespace("rti_subscriber_reads_the_lab_emulator", emulator_scenario);
}

/// The emulated run's ticks (the spec's steps).
const EMULATED_STEPS: usize = 30;

fn emulator_scenario(python: &Path, deadline: Instant) {
    let (dir, spec) = workspace("emulator", EMULATED_STEPS);
    let spec_path = spec.to_str().expect("utf-8 path");
    let mut emulator = cpmx(
        &dir,
        "emulator.log",
        &["lab", "emulate", spec_path, "--runs", "1"],
    );
    let ready = dir.join("reader.ready");
    let mut reader = script(
        python,
        &dir,
        "read_emulator.py",
        &[
            "--ticks",
            &EMULATED_STEPS.to_string(),
            "--ready-file",
            ready.to_str().expect("utf-8 path"),
        ],
    );

    // The planner starts once RTI has matched the emulator's writers: the start comes at once.
    while !ready.exists() {
        if let Some(status) = reader.0.try_wait().expect("the reader can be waited on") {
            panic!(
                "read_emulator.py ended ({status}) before it matched the emulator:\n{}\nemulator:\n{}",
                common::read(&dir.join("read_emulator.py.log")),
                common::read(&dir.join("emulator.log"))
            );
        }
        assert!(
            Instant::now() < deadline,
            "read_emulator.py did not match the emulator's writers within the budget:\n{}",
            common::read(&dir.join("read_emulator.py.log"))
        );
        thread::sleep(Duration::from_millis(20));
    }
    let mut run = lab_run(&dir, &spec);
    let run_status = wait_until(&mut run, deadline, "cpmx run");
    let emulator_status = wait_until(&mut emulator, deadline, "cpmx lab emulate --runs 1");
    let reader_status = wait_until(&mut reader, deadline, "read_emulator.py");
    let logs = format!(
        "cpmx run:\n{}\nemulator:\n{}\nread_emulator.py:\n{}",
        common::read(&dir.join("run.log")),
        common::read(&dir.join("emulator.log")),
        common::read(&dir.join("read_emulator.py.log"))
    );
    assert!(run_status.success(), "cpmx run failed\n{logs}");
    assert!(emulator_status.success(), "the emulator failed\n{logs}");
    assert!(reader_status.success(), "read_emulator.py failed\n{logs}");
    assert!(
        logs.contains(&format!("run finished after {EMULATED_STEPS} ticks")),
        "{logs}"
    );

    // RTI saw every tick, the start and the exact stop stamp.
    let read = summary(&dir, "read_emulator.py");
    assert_eq!(u64_of(&read["stop_ns"]), u64::MAX);
    let seen = tick_times(&read);
    let (_, rows) = stored_run(&dir);
    assert_same_times(&times(&rows), &seen, "recording vs ticks RTI read");

    // What RTI decoded is what the driver decoded: the last tick's positions, which the driver
    // records moved by the state's velocity over its age (|velocity| = |speed|).
    let final_poses = read["final_poses"].as_object().expect("final_poses");
    let last_t = *seen.last().expect("ticks");
    for (agent, id) in VEHICLE_IDS.split(',').enumerate() {
        let pose = final_poses[id].as_array().expect("pose");
        let recorded = rows
            .iter()
            .find(|r| (r[0] - last_t).abs() < 1e-9 && r[1] == agent as f64)
            .unwrap_or_else(|| panic!("agent {agent} at {last_t} s not recorded"));
        let (x, y) = (pose[0].as_f64().expect("x"), pose[1].as_f64().expect("y"));
        let (speed, age_s) = (pose[2].as_f64().expect("speed"), pose[3].as_f64().expect("age"));
        let moved_m = (recorded[2] - x).hypot(recorded[3] - y);
        assert!(
            (moved_m - speed.abs() * age_s).abs() < 1e-6,
            "vehicle {id}: RTI read ({x}, {y}) at {speed} m/s, {age_s} s old; the driver recorded ({}, {}), \
             {moved_m} m away",
            recorded[2],
            recorded[3]
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn rti_middleware_sees_the_driver_stop_a_car_that_lost_its_fixes() {
    in_namespace(
        "rti_middleware_sees_the_driver_stop_a_car_that_lost_its_fixes",
        lost_fixes_scenario,
    );
}

/// The tick after which vehicle 2's positioning fixes stop.
const STALL_AFTER: usize = 8;

fn lost_fixes_scenario(python: &Path, deadline: Instant) {
    let (dir, spec) = workspace("lost-fixes", SPEC_STEPS);
    let starts = starts_arg(&spec);
    let mut middleware = script(
        python,
        &dir,
        "play_lab.py",
        &[
            "--ticks",
            &SPEC_STEPS.to_string(),
            "--starts",
            &starts,
            "--ips-stall-after",
            &STALL_AFTER.to_string(),
            "--ips-stall-vehicle",
            "2",
        ],
    );
    let mut run = lab_run(&dir, &spec);
    let run_status = wait_until(&mut run, deadline, "cpmx run");
    let script_status = wait_until(&mut middleware, deadline, "play_lab.py");
    let logs = format!(
        "cpmx run:\n{}\nplay_lab.py:\n{}",
        common::read(&dir.join("run.log")),
        common::read(&dir.join("play_lab.py.log"))
    );
    assert!(script_status.success(), "play_lab.py failed\n{logs}");
    assert_eq!(run_status.code(), Some(3), "the run fails\n{logs}");
    assert!(
        logs.contains("vehicle 2's positioning fixes stopped"),
        "the reason names the fault\n{logs}"
    );

    // What was recorded before is kept: the ticks until the fixes were 1 s old.
    let run_dir = dir.join("out/runs/lab/lane/crossing/rep1");
    assert!(!run_dir.join("metrics.json").exists(), "{logs}");
    let failed = common::read(&run_dir.join("failed.json"));
    assert!(failed.contains("positioning fixes stopped"), "{failed}");
    let recorded = common::read(&run_dir.join("trajectory.csv")).lines().count() - 1;
    assert!(
        (STALL_AFTER * 2..SPEC_STEPS * 2).contains(&recorded),
        "{recorded} rows\n{logs}"
    );

    // Every vehicle was commanded to stop, at the tick the driver noticed.
    let played = summary(&dir, "play_lab.py");
    let stopped = played["stopped"].as_object().expect("stopped");
    for id in VEHICLE_IDS.split(',') {
        assert!(stopped.contains_key(id), "vehicle {id} was not stopped: {played}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn rti_middleware_whose_clock_sticks_fails_the_run_within_its_timeout() {
    in_namespace(
        "rti_middleware_whose_clock_sticks_fails_the_run_within_its_timeout",
        stuck_clock_scenario,
    );
}

/// The tick after which the middleware's lists repeat that tick.
const STUCK_AFTER: usize = 6;

/// The lab's lists keep coming but bring no new tick: the driver answers the repeats, then
/// fails the run after `timeout_s` (no hang), keeps what it recorded and stops every vehicle.
fn stuck_clock_scenario(python: &Path, deadline: Instant) {
    let (dir, spec) = workspace("stuck-clock", SPEC_STEPS);
    let text = common::read(&spec);
    assert!(text.contains("timeout_s: 20"), "{text}");
    std::fs::write(&spec, text.replace("timeout_s: 20", "timeout_s: 3")).expect("spec");
    let starts = starts_arg(&spec);
    let mut middleware = script(
        python,
        &dir,
        "play_lab.py",
        &[
            "--ticks",
            &SPEC_STEPS.to_string(),
            "--starts",
            &starts,
            "--stuck-after",
            &STUCK_AFTER.to_string(),
        ],
    );
    let started = Instant::now();
    let mut run = lab_run(&dir, &spec);
    let run_status = wait_until(&mut run, deadline, "cpmx run");
    let took = started.elapsed();
    let script_status = wait_until(&mut middleware, deadline, "play_lab.py");
    let logs = format!(
        "cpmx run:\n{}\nplay_lab.py:\n{}",
        common::read(&dir.join("run.log")),
        common::read(&dir.join("play_lab.py.log"))
    );
    assert!(script_status.success(), "play_lab.py failed\n{logs}");
    assert_eq!(run_status.code(), Some(3), "the run fails\n{logs}");
    assert!(took < Duration::from_secs(15), "the run took {took:?}\n{logs}");
    let run_dir = dir.join("out/runs/lab/lane/crossing/rep1");
    let failed = common::read(&run_dir.join("failed.json"));
    assert!(
        failed.contains("the lab sent no new tick for 3 s"),
        "{failed}\n{logs}"
    );
    assert!(failed.contains("repeated ticks (answered again)"), "{failed}");
    let recorded = common::read(&run_dir.join("trajectory.csv")).lines().count() - 1;
    assert_eq!(recorded, (STUCK_AFTER + 1) * 2, "{logs}");
    let played = summary(&dir, "play_lab.py");
    let stopped = played["stopped"].as_object().expect("stopped");
    for id in VEHICLE_IDS.split(',') {
        assert!(stopped.contains_key(id), "vehicle {id} was not stopped: {played}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
