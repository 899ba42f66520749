//! What the tests that run DDS participants in child processes share: children killed on
//! every exit path, bounded waits, and re-running a test inside a private network namespace
//! (`unshare --net --pid`, loopback up) so that no packet leaves it and every process in it
//! dies with it.

use std::path::Path;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::thread;
use std::time::{Duration, Instant};

/// A child process that is killed when dropped (panics and early returns included).
pub struct Killed(pub Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Waits for `child` until `deadline`; kills it and fails when the deadline passes.
pub fn wait_until(child: &mut Killed, deadline: Instant, what: &str) -> ExitStatus {
    loop {
        if let Some(status) = child.0.try_wait().expect("the child can be waited on") {
            return status;
        }
        assert!(
            Instant::now() < deadline,
            "{what} did not finish within the test's budget"
        );
        thread::sleep(Duration::from_millis(20));
    }
}

/// Where a test runs with respect to its private network namespace.
pub enum Namespace {
    /// This is the copy inside the namespace (loopback is up): run the scenario.
    Inside,
    /// The copy inside the namespace ran and passed: nothing left to do.
    RanInside,
    /// This sandbox cannot make a network namespace.
    Unavailable,
}

/// Runs the test `test_name` of this test binary again inside a private network and pid
/// namespace, marked by the environment variable `marker`, and waits for it until
/// `deadline` (killing it and failing when it passes, or when it fails). Inside, brings
/// loopback up.
pub fn in_network_namespace(test_name: &str, marker: &str, deadline: Instant) -> Namespace {
    if std::env::var_os(marker).is_some() {
        let up = Command::new("ip").args(["link", "set", "lo", "up"]).status();
        assert!(
            up.is_ok_and(|s| s.success()),
            "cannot bring loopback up in the namespace"
        );
        return Namespace::Inside;
    }
    if !namespace_available() {
        return Namespace::Unavailable;
    }
    let log = std::env::temp_dir().join(format!("cpmx-{test_name}-netns-{}.log", std::process::id()));
    let file = std::fs::File::create(&log).expect("log file");
    let mut child = Killed(
        Command::new("unshare")
            .args(["--net", "--pid", "--fork", "--kill-child", "--"])
            .arg(std::env::current_exe().expect("test binary"))
            // `--include-ignored`: an `#[ignore]`d test asked for (`-- --ignored`) runs inside too.
            .args([
                test_name,
                "--exact",
                "--nocapture",
                "--test-threads=1",
                "--include-ignored",
            ])
            .env(marker, "1")
            .env(OUTER_PID, test_process_id().to_string())
            .stdout(file.try_clone().expect("log file"))
            .stderr(file)
            .spawn()
            .expect("unshare starts"),
    );
    let status = wait_until(&mut child, deadline, "the namespaced test");
    let output = read(&log);
    let _ = std::fs::remove_file(&log);
    assert!(
        status.success(),
        "the test failed in its network namespace:\n{output}"
    );
    assert!(
        output.contains("test result: ok. 1 passed"),
        "the test did not run in its network namespace:\n{output}"
    );
    Namespace::RanInside
}

/// Set in the copy of a test that runs inside its network namespace: the process id outside.
const OUTER_PID: &str = "CPMX_TEST_OUTER_PID";

/// This test process's id, outside its namespace: inside a pid namespace every copy is process
/// 1, so scratch folders named by it would collide with another checkout's run of the test.
pub fn test_process_id() -> u32 {
    std::env::var(OUTER_PID)
        .ok()
        .and_then(|pid| pid.parse().ok())
        .unwrap_or_else(std::process::id)
}

/// Whether this sandbox lets us make a private network namespace with loopback up.
fn namespace_available() -> bool {
    Command::new("unshare")
        .args([
            "--net",
            "--pid",
            "--fork",
            "--kill-child",
            "sh",
            "-c",
            "ip link set lo up",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// A log file's text, empty when it cannot be read.
pub fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_default()
}
