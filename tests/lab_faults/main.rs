//! The lab driver against `cpmx lab emulate` playing faults (`--faults FILE`, docs/lab.md's
//! table), in simulated time:
//!
//! - `faults_the_cars_do_not_feel_change_nothing_and_resume_completes_the_failed_runs` (a
//!   short soak; `soak_of_a_hundred_lab_runs` is the long one, `#[ignore]`d): lost, repeated,
//!   reordered and late samples, pauses, restarts and a clock offset leave a run as it is
//!   without them, while a car that loses its fixes or leaves the lists for good fails its
//!   run, naming the fault and keeping what was recorded. The folder stays consistent;
//!   `--resume` against a faultless lab completes the failed runs, and then every trajectory,
//!   `per_run.csv` and `summary.md` equal a faultless session's, byte for byte.
//! - `every_fault_of_a_run_is_recorded_or_ends_it_with_the_vehicles_stopped`: one run through
//!   three labs: fixes lost for good (failed, every vehicle commanded to stop and standing),
//!   a vehicle gone from the lists for good (failed), then a pause, a restart, a vehicle
//!   missing for a while and old fixes (complete, each recorded in `metrics.json`).
//! - `a_vehicle_off_its_start_is_refused_with_the_table_then_recorded`: the preflight refuses
//!   a car placed 10 cm off its start with the table; with `misplaced: record` the run starts
//!   and a `from_runs` configuration starts the simulated fidelities where the car stood.
//! - `ctrl_c_stops_the_vehicles_and_keeps_the_recording`.
//!
//! Every scenario runs in its own private network namespace when the sandbox allows it
//! (loopback-only discovery on a domain of its own otherwise), bounded by its budget; every
//! child is killed on every exit path.

#[path = "../common/mod.rs"]
mod common;
mod session;

use std::path::Path;
use std::process::Command;
use std::thread;
use std::time::{Duration, Instant};

use common::wait_until;
use session::{
    consistent_folder, emulator, every_run_stopped_its_vehicles, faults_file, in_namespace, lab_keys,
    lab_run, run_record, session, spec_text,
};

/// Seeded faults of every kind: those the cars do not feel in simulated time (samples,
/// pauses, restarts, clock offset) and those that end a run (fixes lost, a vehicle gone).
const SOAK_FAULTS: &str = "seed: 11
topics:
  vehicleStateList: {drop: 0.1, duplicate: 0.1, reorder: 0.1, delay: 0.1, delay_ms: {uniform: [10, 80]}}
  vehicleCommandTrajectory: {drop: 0.05, duplicate: 0.05, reorder: 0.05, delay: 0.05}
  systemTrigger: {drop: 0.3}
pauses:
  - {at_s: {uniform: [0.3, 2.0]}, for_s: 1.2, probability: 0.3}
restarts:
  - {at_s: {uniform: [0.3, 2.0]}, probability: 0.3}
clock_offset_ms: 1500
ips_loss:
  - {vehicle: 1, at_s: {uniform: [0.2, 1.5]}, probability: 0.25}
leave_lists:
  - {vehicle: 2, at_s: {uniform: [0.2, 1.5]}, probability: 0.25, listed: stale}
";

#[test]
fn faults_the_cars_do_not_feel_change_nothing_and_resume_completes_the_failed_runs() {
    in_namespace(
        "faults_the_cars_do_not_feel_change_nothing_and_resume_completes_the_failed_runs",
        Duration::from_secs(240),
        |dir, deadline| soak(dir, deadline, 2),
    );
}

/// `cargo test --test lab_faults -- --ignored soak` (5.5 minutes on two cores).
#[test]
#[ignore = "100 lab runs: the long soak"]
fn soak_of_a_hundred_lab_runs() {
    in_namespace(
        "soak_of_a_hundred_lab_runs",
        Duration::from_secs(3600),
        |dir, deadline| soak(dir, deadline, 50),
    );
}

fn soak(dir: &Path, deadline: Instant, repetitions: usize) {
    let steps = 30;
    let spec = dir.join("lab.yaml");
    std::fs::write(&spec, spec_text(steps, repetitions, "")).expect("spec");
    let faults = dir.join("faults.yaml");
    std::fs::write(&faults, SOAK_FAULTS).expect("faults");
    let faults = faults.to_str().expect("utf-8");
    let keys = lab_keys(repetitions);
    let runs = keys.len();

    // A lab with faults: every run ends, complete or failed naming its fault.
    let faulty = dir.join("faulty");
    let (status, logs) = session(
        dir,
        "faulty",
        &spec,
        &faulty,
        runs,
        &["--faults", faults],
        &[],
        deadline,
    );
    assert!(!logs.contains("panicked"), "{logs}");
    every_run_stopped_its_vehicles(&logs);
    let outcomes = consistent_folder(&faulty, &keys, &logs);
    let failed: Vec<&String> = outcomes.values().flatten().collect();
    assert_eq!(
        status.code(),
        Some(if failed.is_empty() { 0 } else { 3 }),
        "{logs}"
    );
    assert!(!failed.is_empty(), "the faults failed no run\n{logs}");
    assert!(failed.len() < runs, "the faults failed every run\n{logs}");
    for reason in &failed {
        assert!(
            reason.contains("positioning fixes stopped") || reason.contains("left the state lists"),
            "a failure that names no fault: {reason}\n{logs}"
        );
    }
    // Runs that completed lived through faults the cars do not feel (lost, repeated, late and
    // reordered lists, a pause or a restart), each noted; below they equal faultless runs.
    let complete: Vec<String> = keys
        .iter()
        .filter(|key| outcomes[*key].is_none())
        .map(|key| run_record(&faulty, key))
        .collect();
    let survived = complete.iter().filter(|notes| {
        notes.contains("repeated ticks")
            && (notes.contains("restarted after tick") || notes.contains("was silent for up to"))
    });
    assert!(
        survived.count() > 0,
        "no complete run lived through a pause or a restart: {complete:?}\n{logs}"
    );

    // The faults stop; --resume completes the failed runs.
    let (status, logs) = session(
        dir,
        "resumed",
        &spec,
        &faulty,
        failed.len(),
        &[],
        &["--resume"],
        deadline,
    );
    assert!(status.success(), "{logs}");
    every_run_stopped_its_vehicles(&logs);
    assert!(
        consistent_folder(&faulty, &keys, &logs)
            .values()
            .all(Option::is_none),
        "{logs}"
    );

    // A faultless session gives the same runs, to the byte.
    let faultless = dir.join("faultless");
    let (status, logs) = session(dir, "faultless", &spec, &faultless, runs, &[], &[], deadline);
    assert!(status.success(), "{logs}");
    every_run_stopped_its_vehicles(&logs);
    for key in &keys {
        let file = |out: &Path| std::fs::read(out.join("runs").join(key).join("trajectory.csv")).expect(key);
        assert!(
            file(&faulty) == file(&faultless),
            "{key}: the trajectories differ"
        );
    }
    for summary in ["per_run.csv", "summary.md"] {
        assert_eq!(
            common::read(&faulty.join(summary)),
            common::read(&faultless.join(summary)),
            "{summary}"
        );
    }
}

#[test]
fn every_fault_of_a_run_is_recorded_or_ends_it_with_the_vehicles_stopped() {
    in_namespace(
        "every_fault_of_a_run_is_recorded_or_ends_it_with_the_vehicles_stopped",
        Duration::from_secs(180),
        every_fault,
    );
}

fn every_fault(dir: &Path, deadline: Instant) {
    let spec = dir.join("lab.yaml");
    std::fs::write(&spec, spec_text(40, 1, ", preflight: {wait_s: 1}")).expect("spec");
    let out = dir.join("out");
    let key = "lab/lane/crossing/rep1";
    let only = ["--only", "initial_configuration=crossing"];

    // Fixes lost for good: the run fails after the limit (1 s), every car is stopped.
    let lost = faults_file(dir, "lost", "ips_loss: [{vehicle: 1, at_s: 1.0}]\n");
    let (status, logs) = session(
        dir,
        "lost",
        &spec,
        &out,
        1,
        &["--faults", lost.to_str().expect("utf-8")],
        &only,
        deadline,
    );
    assert_eq!(status.code(), Some(3), "{logs}");
    let record = run_record(&out, key);
    assert!(
        record.contains("vehicle 1's positioning fixes stopped"),
        "{record}"
    );
    assert!(logs.contains("the planner stopped its vehicles after "), "{logs}");
    let rows = common::read(&out.join("runs").join(key).join("trajectory.csv"))
        .lines()
        .count()
        - 1;
    assert!((2 * 15..2 * 40).contains(&rows), "{rows} rows kept\n{logs}");
    assert!(
        logs.contains("vehicles commanded to stop: [1, 2]; standing at the run's end: [1, 2]"),
        "{logs}"
    );

    // A vehicle gone from the lists for good (listed as an empty entry): failed.
    let gone = faults_file(
        dir,
        "gone",
        "leave_lists: [{vehicle: 2, at_s: 1.5, listed: empty}]\n",
    );
    let (status, logs) = session(
        dir,
        "gone",
        &spec,
        &out,
        1,
        &["--faults", gone.to_str().expect("utf-8")],
        &["--resume", only[0], only[1]],
        deadline,
    );
    assert_eq!(status.code(), Some(3), "{logs}");
    let record = run_record(&out, key);
    assert!(record.contains("vehicle 2 left the state lists"), "{record}");
    assert!(logs.contains("vehicles commanded to stop: [1, 2]"), "{logs}");
    let recorded = std::fs::read(out.join("runs").join(key).join("trajectory.csv")).expect("kept");

    // A flat battery: the preflight holds the run, which fails without a tick; the folder
    // keeps what the attempt before recorded, and says so.
    let flat = faults_file(dir, "flat", "low_battery: [{vehicle: 1, voltage_v: 6.5}]\n");
    let (status, logs) = session(
        dir,
        "flat",
        &spec,
        &out,
        1,
        &["--faults", flat.to_str().expect("utf-8")],
        &["--resume", only[0], only[1]],
        deadline,
    );
    assert_eq!(status.code(), Some(3), "{logs}");
    let record = run_record(&out, key);
    assert!(record.contains("the preflight did not pass"), "{record}");
    assert!(record.contains("battery 6.50 V"), "{record}");
    assert!(record.contains("an earlier attempt recorded"), "{record}");
    consistent_folder(&out, &[key.to_owned()], &logs);
    assert!(
        std::fs::read(out.join("runs").join(key).join("trajectory.csv")).expect("kept") == recorded,
        "the earlier attempt's recording changed"
    );

    // Faults a run survives, each recorded: it completes.
    let survived = faults_file(
        dir,
        "survived",
        "pauses: [{at_s: 0.5, for_s: 1.2}]
restarts: [{at_s: 1.5}]
leave_lists: [{vehicle: 2, at_s: 2.0, for_s: 0.3}]
ips_loss: [{vehicle: 1, at_s: 2.5, for_s: 0.7}]
clock_offset_ms: -2500
",
    );
    let (status, logs) = session(
        dir,
        "survived",
        &spec,
        &out,
        1,
        &["--faults", survived.to_str().expect("utf-8")],
        &["--resume", only[0], only[1]],
        deadline,
    );
    assert!(status.success(), "{logs}");
    let record = run_record(&out, key);
    for noted in [
        "the lab was silent for up to 1.",
        "the lab's middleware restarted after tick 1",
        "vehicle 2 missing from 3 ticks",
        "vehicle 1: positioning fixes up to 0.",
        "the lab's clock is 2.",
        "s behind this machine's",
        "planning latency: median",
    ] {
        assert!(record.contains(noted), "`{noted}` not in {record}\n{logs}");
    }
    // Those faults the cars did not feel: their followers never stopped them.
    assert!(!logs.contains("the lab's follower stopped the cars"), "{logs}");

    // Fixes lost for good in a lab whose planner waits longer than the cars (10 s against the
    // lab's 3 s): the car's own follower stops it, and the emulator says for how long.
    let patient = dir.join("patient.yaml");
    std::fs::write(
        &patient,
        spec_text(40, 1, ", preflight: {wait_s: 1}, ips_age_limit_s: 10"),
    )
    .expect("spec");
    let lost_early = faults_file(dir, "lost-early", "ips_loss: [{vehicle: 1, at_s: 0.5}]\n");
    let (status, logs) = session(
        dir,
        "patient",
        &patient,
        &dir.join("out-patient"),
        1,
        &["--faults", lost_early.to_str().expect("utf-8")],
        &only,
        deadline,
    );
    assert!(status.success(), "{logs}");
    let follower = logs
        .lines()
        .find(|l| l.starts_with("the lab's follower stopped the cars in "))
        .unwrap_or_else(|| panic!("no follower stops reported\n{logs}"));
    // From 3 s after the last fix to the run's end at 4 s: 0.5 s at 50 Hz, and the periods
    // between that fix and the loss.
    let lost: u64 = follower
        .split(", ")
        .find_map(|part| part.strip_suffix(" with the positioning lost"))
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{follower}"));
    assert!((25..=30).contains(&lost), "{follower}");
}

#[test]
fn a_vehicle_off_its_start_is_refused_with_the_table_then_recorded() {
    in_namespace(
        "a_vehicle_off_its_start_is_refused_with_the_table_then_recorded",
        Duration::from_secs(120),
        misplaced,
    );
}

fn misplaced(dir: &Path, deadline: Instant) {
    let out = dir.join("out");
    let key = "lab/lane/crossing/rep1";
    let off = "faults: {misplaced: [{vehicle: 2, offset_m: [0.1, 0.0]}]}";

    // Waiting for the operator, who does not come: refused with the table.
    let spec = dir.join("wait.yaml");
    std::fs::write(
        &spec,
        spec_text(20, 1, &format!(", preflight: {{wait_s: 1}}, {off}")),
    )
    .expect("spec");
    let (status, logs) = session(dir, "wait", &spec, &out, 2, &[], &[], deadline);
    assert_eq!(status.code(), Some(3), "{logs}");
    let record = run_record(&out, key);
    assert!(record.contains("the preflight did not pass"), "{record}");
    assert!(
        record.contains("1 of 2 vehicles off their planned start"),
        "{record}"
    );
    assert!(!out.join("runs").join(key).join("trajectory.csv").exists());
    // The table: vehicle 2, where it is, where it should be, 10 cm off.
    let line = logs
        .lines()
        .find(|l| l.trim_start().starts_with("2 ") && l.contains("off its start"))
        .unwrap_or_else(|| panic!("no table row of vehicle 2:\n{logs}"));
    assert!(line.contains("10.0 cm"), "{line}");
    let poses: Vec<&str> = line.split(['(', ')']).filter(|p| p.contains(',')).collect();
    assert_eq!(poses.len(), 3, "{line}");
    let x = |pose: &str| pose.split(',').next().unwrap().trim().parse::<f64>().unwrap();
    assert!((x(poses[0]) - x(poses[1]) - 0.1).abs() < 0.005, "{line}");

    // `misplaced: record` (the preflight does not enter the runs' inputs, so the same folder
    // resumes): the runs start where the cars stand and note it.
    let spec = dir.join("record.yaml");
    std::fs::write(
        &spec,
        spec_text(20, 1, &format!(", preflight: {{misplaced: record}}, {off}")),
    )
    .expect("spec");
    let (status, logs) = session(dir, "record", &spec, &out, 2, &[], &["--resume"], deadline);
    assert!(status.success(), "{logs}");
    let record = run_record(&out, key);
    assert!(record.contains("started off the planned start"), "{record}");
    assert!(record.contains("vehicle 2 at ("), "{record}");

    // The simulated fidelities start where the lab's cars stood.
    let paired = dir.join("paired.yaml");
    std::fs::write(
        &paired,
        spec_text(20, 1, "").replace(
            "initial_configurations:\n",
            &format!(
                "initial_configurations:\n  - from_runs: {{dir: {}, fidelity: lab}}\n",
                out.display()
            ),
        ),
    )
    .expect("spec");
    let plan = Command::new(env!("CARGO_BIN_EXE_cpmx"))
        .arg("plan")
        .arg(&paired)
        .args(["--format", "json"])
        .output()
        .expect("cpmx plan");
    assert!(plan.status.success(), "{}", String::from_utf8_lossy(&plan.stderr));
    let plan: serde_json::Value = serde_json::from_slice(&plan.stdout).expect("json");
    let recorded = &plan["starts"]["lab-lane-crossing-rep1"];
    let planned = &plan["starts"]["crossing"];
    let dx = recorded[1]["x_m"].as_f64().unwrap() - planned[1]["x_m"].as_f64().unwrap();
    assert!(
        (dx - 0.1).abs() < 0.005,
        "vehicle 2 starts {dx} m along x from its plan: {plan}"
    );
    let dx = recorded[0]["x_m"].as_f64().unwrap() - planned[0]["x_m"].as_f64().unwrap();
    assert!(
        dx.abs() < 0.005,
        "vehicle 1 starts {dx} m along x from its plan: {plan}"
    );
}

#[test]
fn ctrl_c_stops_the_vehicles_and_keeps_the_recording() {
    in_namespace(
        "ctrl_c_stops_the_vehicles_and_keeps_the_recording",
        Duration::from_secs(90),
        ctrl_c,
    );
}

fn ctrl_c(dir: &Path, deadline: Instant) {
    let spec = dir.join("lab.yaml");
    std::fs::write(&spec, spec_text(100_000, 1, "")).expect("spec");
    let out = dir.join("out");
    let emulator_log = dir.join("emulator.log");
    let run_log = dir.join("run.log");
    let mut lab = emulator(&spec, 1, &[], &emulator_log);
    let mut run = lab_run(
        &spec,
        &out,
        &["--only", "initial_configuration=crossing"],
        &run_log,
    );

    // Mid-run (the lab has served a while), Ctrl-C.
    while !common::read(&emulator_log).contains("started") {
        assert!(Instant::now() < deadline, "{}", common::read(&emulator_log));
        thread::sleep(Duration::from_millis(50));
    }
    thread::sleep(Duration::from_secs(3));
    let kill = Command::new("kill")
        .args(["-INT", &run.0.id().to_string()])
        .status()
        .expect("kill");
    assert!(kill.success());
    let status = wait_until(&mut run, deadline, "cpmx run");
    let _ = wait_until(&mut lab, deadline, "cpmx lab emulate");
    let logs = format!(
        "cpmx run ({status}):\n{}\nemulator:\n{}",
        common::read(&run_log),
        common::read(&emulator_log)
    );
    assert_eq!(status.code(), Some(130), "{logs}");
    let record = run_record(&out, "lab/lane/crossing/rep1");
    assert!(record.contains("interrupted (Ctrl-C)"), "{record}");
    let rows = common::read(&out.join("runs/lab/lane/crossing/rep1/trajectory.csv"))
        .lines()
        .count();
    assert!(rows > 10, "{rows} rows kept\n{logs}");
    assert!(
        logs.contains("vehicles commanded to stop: [1, 2]; standing at the run's end: [1, 2]"),
        "{logs}"
    );
}
