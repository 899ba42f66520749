//! A lab whose middleware ticks at another period than `timing.dt` is refused at its first
//! tick, with a message that says how to set the lab's period (issue 15): `cpmx lab emulate`
//! plays a middleware with the Lab Control Center's default period of 400 ms (its spec has
//! `dt: 0.4`) while `cpmx run` drives a spec with `dt: 0.1`. The run fails with the reason
//! (exit 3), nothing is measured, and the emulator is killed. Runs inside a private network
//! namespace when the sandbox allows it, loopback-only discovery otherwise.

mod common;

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{Killed, Namespace, in_network_namespace, wait_until};

const INSIDE_NAMESPACE: &str = "CPMX_LAB_PERIOD_IN_NETNS";
const TEST_NAME: &str = "a_middleware_period_other_than_dt_is_refused";

/// A one-configuration spec with the given policy period, its lab fidelity on `domain`.
fn spec_text(dt_s: f64, domain: u32) -> String {
    format!(
        "cpmx: 1\nname: period\nmap: stdlib:intersection\ntiming: {{dt: {dt_s}, steps: 10}}\nagents: 2\n\
         policies:\n  - {{name: lane, builtin: lane-follow}}\n\
         initial_configurations:\n  - name: a\n    agents:\n      - {{ref_path: 1, arc_length: 0.3}}\n      - {{ref_path: 7, arc_length: 0.3}}\n\
         repetitions: 1\nseed: 1\nfidelities:\n  \
         twin: {{control: trajectory, dynamics: stdlib:mu-car-greybox}}\n  \
         lab: {{driver: cpm-dds, domain: {domain}, vehicle_ids: [1, 2], initial_peers: [127.0.0.1], interface: 127.0.0.1, timeout_s: 20}}\n\
         planner: {{control_horizon: 4, prediction_horizon: 12}}\n"
    )
}

#[test]
fn a_middleware_period_other_than_dt_is_refused() {
    let started = Instant::now();
    let deadline = started + Duration::from_secs(60);
    match in_network_namespace(TEST_NAME, INSIDE_NAMESPACE, deadline) {
        Namespace::RanInside => return,
        Namespace::Inside | Namespace::Unavailable => {}
    }
    let cpmx = env!("CARGO_BIN_EXE_cpmx");
    let dir = std::env::temp_dir().join(format!("cpmx-lab-period-{}", common::test_process_id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    // A domain of its own (lab_silent.rs and lab_e2e.rs use 100 + pid % 100).
    let domain = 100 + (std::process::id() + 50) % 100;
    let lab_spec = dir.join("lab-400ms.yaml");
    let run_spec = dir.join("run-100ms.yaml");
    std::fs::write(&lab_spec, spec_text(0.4, domain)).unwrap();
    std::fs::write(&run_spec, spec_text(0.1, domain)).unwrap();

    // The lab: a middleware ticking every 400 ms.
    let _emulator = Killed(
        Command::new(cpmx)
            .args(["lab", "emulate"])
            .arg(&lab_spec)
            .args(["--runs", "1"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("cpmx lab emulate starts"),
    );
    let log = dir.join("run.log");
    let mut run = Killed(
        Command::new(cpmx)
            .arg("run")
            .arg(&run_spec)
            .arg("--out")
            .arg(dir.join("out"))
            .args(["--only", "fidelity=lab", "--jobs", "1"])
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&log).unwrap())
            .spawn()
            .expect("cpmx run starts"),
    );
    let status = wait_until(&mut run, deadline, "cpmx run");
    let stderr = common::read(&log);
    assert_eq!(status.code(), Some(3), "{stderr}");
    assert!(
        stderr.contains(
            "failed: lab/lane/a/rep1: the lab's middleware ticks every 400 ms, but `timing.dt` is 100 ms"
        ),
        "{stderr}"
    );
    assert!(
        stderr.contains(
            "set the Lab Control Center's parameter `middleware_period_ms` to 100 \
             (lab_control_center/parameters.yaml, default 400) and restart the middleware"
        ),
        "{stderr}"
    );
    assert!(!dir.join("out/runs/lab/lane/a/rep1/metrics.json").exists());
    std::fs::remove_dir_all(&dir).ok();
}
