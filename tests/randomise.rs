//! Domain randomisation in `cpmx run`: layer parameters given as distributions are drawn per
//! run, recorded in the run's `metrics.json`, make repetitions differ, and give the same
//! folder for `--jobs 1` and `--jobs 2`.

mod support;

use support::{cpmx_in, files, ok, scratch, walk};

use std::path::Path;

/// `examples/sim-to-twin.yaml` with the twin's actuation delay and positioning latency
/// randomised.
fn randomised_spec(dir: &Path) {
    let example = std::fs::read_to_string(support::root().join("examples/sim-to-twin.yaml")).unwrap();
    let spec = example
        .replace(
            "    sensing: stdlib:cpm-ips\n    actuation: {delay_ms: 80}",
            "    sensing: {extends: stdlib:cpm-ips, latency_ms: {normal: {mean: 60, std: 20}}}\n    \
             actuation: {delay_ms: {uniform: [40, 120]}}",
        )
        .replace("name: sim-to-twin", "name: randomised")
        .replace("steps: 60", "steps: 30");
    assert!(spec.contains("uniform"), "the example's twin changed");
    std::fs::write(dir.join("spec.yaml"), spec).unwrap();
}

fn drawn(metrics: &Path) -> serde_json::Map<String, serde_json::Value> {
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(metrics).unwrap()).unwrap();
    json.get("drawn_parameters")
        .and_then(|d| d.as_object().cloned())
        .unwrap_or_default()
}

#[test]
fn drawn_parameters_are_recorded_per_run_and_do_not_depend_on_threads() {
    let dir = scratch("randomise");
    randomised_spec(&dir);
    ok(&cpmx_in(
        &dir,
        &["run", "spec.yaml", "--out", "one", "--jobs", "1"],
    ));
    ok(&cpmx_in(
        &dir,
        &["run", "spec.yaml", "--out", "two", "--jobs", "2"],
    ));

    let runs = dir.join("one/runs");
    let mut delays = Vec::new();
    for metrics in walk(&runs).into_iter().filter(|p| p.ends_with("metrics.json")) {
        let key = metrics
            .parent()
            .unwrap()
            .strip_prefix(&runs)
            .unwrap()
            .display()
            .to_string();
        let drawn = drawn(&metrics);
        if key.starts_with("twin/") {
            let delay = drawn["actuation.delay_ms"].as_f64().unwrap();
            let latency = drawn["sensing.latency_ms"].as_f64().unwrap();
            assert!((40.0..120.0).contains(&delay), "{key}: {delay}");
            assert!(latency >= 0.0, "{key}: {latency}");
            assert_eq!(drawn.len(), 2, "{key}: {drawn:?}");
            delays.push(delay);
        } else {
            assert!(drawn.is_empty(), "{key} draws nothing: {drawn:?}");
        }
    }
    // Two configurations × two repetitions of the twin, each with its own draw.
    assert_eq!(delays.len(), 4);
    delays.sort_by(f64::total_cmp);
    delays.dedup();
    assert_eq!(delays.len(), 4, "{delays:?}");

    // The same draws and results whatever the thread count: every run's files are equal.
    let runs = |root: &Path| -> Vec<(std::path::PathBuf, Vec<u8>)> {
        files(&root.join("runs"))
            .into_iter()
            .filter(|(p, _)| {
                p.file_name()
                    .is_some_and(|n| n == "metrics.json" || n == "trajectory.csv")
            })
            .collect()
    };
    // per_run.csv has a column per drawn parameter, empty for the fidelities that draw none.
    let per_run = std::fs::read_to_string(dir.join("one/per_run.csv")).unwrap();
    let mut lines = per_run.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let delay = header
        .iter()
        .position(|c| *c == "actuation.delay_ms")
        .expect("a delay column");
    assert!(header.contains(&"sensing.latency_ms"), "{header:?}");
    for line in lines {
        let fields: Vec<&str> = line.split(',').collect();
        assert_eq!(fields[1] == "twin", !fields[delay].is_empty(), "{line}");
    }

    let one = runs(&dir.join("one"));
    assert_eq!(one.len(), 3 * 2 * 2 * 2);
    assert_eq!(one, runs(&dir.join("two")));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn plan_lists_what_each_fidelity_draws() {
    let dir = scratch("randomise-plan");
    randomised_spec(&dir);
    let table = ok(&cpmx_in(&dir, &["plan", "spec.yaml"]));
    let section = table
        .split("randomised parameters")
        .nth(1)
        .expect("a section of randomised parameters");
    let rows: Vec<Vec<&str>> = section
        .lines()
        .skip(2)
        .map(|l| l.split("  ").map(str::trim).filter(|c| !c.is_empty()).collect())
        .collect();
    assert_eq!(
        rows,
        [
            vec!["twin", "sensing.latency_ms", "normal (mean 60, std 20)"],
            vec!["twin", "actuation.delay_ms", "uniform [40, 120]"],
        ]
    );
    let json = ok(&cpmx_in(&dir, &["plan", "spec.yaml", "--format", "json"]));
    let json: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(
        json["randomised"][1],
        serde_json::json!({
            "fidelity": "twin", "parameter": "actuation.delay_ms",
            "distribution": {"uniform": [40.0, 120.0]},
        })
    );
}
