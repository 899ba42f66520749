//! The command line across crates: validate the shipped specs, plan the paper's design, the
//! schema file, exit codes, and identical run folders for any thread count.

mod support;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use support::{files, reference, root};

/// `cpmx ARGS` in the repository with the reference data on `CPMX_DATA`.
fn cpmx(args: &[&str]) -> Output {
    support::cpmx_with_data(args)
}

fn shipped_specs() -> Vec<String> {
    let mut specs = Vec::new();
    for dir in ["experiments", "examples"] {
        for entry in std::fs::read_dir(root().join(dir)).unwrap() {
            let path = entry.unwrap().path();
            if path.extension().is_some_and(|e| e == "yaml") {
                specs.push(path.strip_prefix(root()).unwrap().display().to_string());
            }
        }
    }
    specs.sort();
    specs
}

#[test]
fn every_shipped_spec_validates_and_names_the_schema() {
    reference(); // experiments/at25-cpmx.yaml reads the CPM Lab map and SigmaRL's actors
    let specs = shipped_specs();
    assert!(specs.len() >= 3);
    let mut args = vec!["validate"];
    args.extend(specs.iter().map(String::as_str));
    let out = cpmx(&args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for spec in &specs {
        let text = std::fs::read_to_string(root().join(spec)).unwrap();
        assert!(
            text.starts_with("# yaml-language-server: $schema=../cpmx.schema.json"),
            "{spec}"
        );
    }
}

#[test]
fn the_papers_design_plans_81_paired_runs() {
    reference();
    let out = cpmx(&["plan", "experiments/at25-cpmx.yaml", "--format", "json"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let plan: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let runs = plan["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 81);
    let seed_of = |key: &str| {
        runs.iter().find(|r| r["key"] == key).unwrap()["seed"]
            .as_u64()
            .unwrap()
    };
    // Paired: the fidelity does not change the seed; everything else does.
    assert_eq!(seed_of("sim/seed1/init2/rep3"), seed_of("twin/seed1/init2/rep3"));
    let mut seeds: Vec<u64> = runs
        .iter()
        .filter(|r| r["fidelity"] == "sim")
        .map(|r| r["seed"].as_u64().unwrap())
        .collect();
    seeds.sort();
    seeds.dedup();
    assert_eq!(seeds.len(), 27);
}

#[test]
fn a_shard_past_the_last_run_says_it_has_nothing_to_do() {
    // An array job of more tasks than runs: the extra task says so, writes no folder, exits 0.
    let out_dir = std::env::temp_dir().join(format!("cpmx-empty-shard-{}", std::process::id()));
    let out = cpmx(&[
        "run",
        "experiments/quickstart.yaml",
        "--shard",
        "20/20",
        "--out",
        out_dir.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(
        stderr.contains("shard 20/20 holds none of the matrix's 12 runs: nothing to run here"),
        "{stderr}"
    );
    assert!(String::from_utf8_lossy(&out.stdout).is_empty(), "no empty table");
    assert!(!out_dir.exists(), "no folder for an empty shard");
}

#[test]
fn plan_of_the_quickstart() {
    let out = cpmx(&["plan", "experiments/quickstart.yaml", "--format", "csv"]);
    assert!(out.status.success());
    insta::assert_snapshot!(String::from_utf8(out.stdout).unwrap());
}

#[test]
fn the_language_reference_is_current() {
    let shipped = std::fs::read_to_string(root().join("docs/language.md")).unwrap_or_default();
    assert!(
        shipped == cpmx_spec::reference::language_reference_markdown(),
        "docs/language.md is stale: run `cargo run -- schema --format markdown > docs/language.md`"
    );
}

#[test]
fn the_schema_file_is_current() {
    let shipped = std::fs::read_to_string(root().join("cpmx.schema.json")).unwrap();
    assert!(
        shipped == cpmx_spec::schema::json_schema_text(),
        "cpmx.schema.json is stale: run `cargo run -- schema > cpmx.schema.json`"
    );
}

#[test]
fn exit_codes_follow_the_cli_contract() {
    let dir = std::env::temp_dir().join(format!("cpmx-exit-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.yaml");
    std::fs::write(&bad, "cpmx: 1\nname: Bad Name\n").unwrap();
    assert_eq!(cpmx(&["validate", bad.to_str().unwrap()]).status.code(), Some(1));
    assert_eq!(
        cpmx(&["validate", dir.join("missing.yaml").to_str().unwrap()])
            .status
            .code(),
        Some(1)
    );
    assert_eq!(cpmx(&["plan"]).status.code(), Some(2));
    assert_eq!(
        cpmx(&["run", "experiments/quickstart.yaml", "--shard", "3/2"])
            .status
            .code(),
        Some(2)
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_far_start_is_located_beside_the_specs_other_problems_and_plan_does_not_blame_the_path() {
    let dir = support::scratch("far");
    let spec = dir.join("far.yaml");
    let quickstart = std::fs::read_to_string(root().join("experiments/quickstart.yaml")).unwrap();
    let far = quickstart.replace(
        "{ref_path: 1, arc_length: 0.3}",
        "{ref_path: 1, arc_length: 40.0}",
    ) + "planner: {control_horizon: 9, prediction_horizon: 4}\n";
    let line = far.lines().position(|l| l.contains("arc_length: 40.0")).unwrap() + 1;
    std::fs::write(&spec, &far).unwrap();
    let out = cpmx(&["validate", spec.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("cpmx::map::arc-length"), "{stderr}");
    assert!(
        stderr.contains(&format!("far.yaml:{line}:")),
        "located at line {line}: {stderr}"
    );
    assert!(
        stderr.contains("cpmx::check::horizon"),
        "both problems in one pass: {stderr}"
    );
    let out = cpmx(&["plan", spec.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("cpmx::map::arc-length") && !stderr.contains("has no reference path"),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn validate_draws_sampled_starts_as_run_will() {
    let dir = support::scratch("crowd");
    let spec = dir.join("crowd.yaml");
    let minimal = std::fs::read_to_string(root().join("examples/minimal.yaml")).unwrap();
    let crowd = minimal.replace("agents: 1\n", "agents: 40\n").replace(
        "  - name: straight\n    agents:\n      - {ref_path: 1, arc_length: 0.2}\n",
        "  - sample: {count: 2, seed: 1, min_gap: 0.5}\n",
    );
    assert_ne!(crowd, minimal);
    let line = crowd.lines().position(|l| l.contains("sample:")).unwrap() + 1;
    std::fs::write(&spec, &crowd).unwrap();
    let out = cpmx(&["validate", spec.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("cpmx::map::no-room") && stderr.contains(&format!("crowd.yaml:{line}:")),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// Runs `spec` with one and with two threads and asserts that every file is identical.
fn assert_identical_for_one_and_two_threads(spec: &str, min_files: usize) {
    let base = std::env::temp_dir().join(format!(
        "cpmx-jobs-{}-{}",
        std::process::id(),
        spec.replace('/', "_")
    ));
    let (one, two) = (base.join("one"), base.join("two"));
    for (dir, jobs) in [(&one, "1"), (&two, "2")] {
        let out = cpmx(&["run", spec, "--out", dir.to_str().unwrap(), "--jobs", jobs]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
    let (a, b) = (files(&one), files(&two));
    assert!(a.len() > min_files, "the folder holds every run's files");
    assert_eq!(a.len(), b.len());
    for ((pa, ca), (pb, cb)) in a.iter().zip(&b) {
        assert_eq!(pa, pb);
        assert!(
            ca == cb,
            "{spec}: {} differs between --jobs 1 and --jobs 2",
            pa.display()
        );
    }
    std::fs::remove_dir_all(&base).ok();
}

#[test]
fn run_folders_are_identical_for_one_and_two_threads() {
    assert_identical_for_one_and_two_threads("experiments/quickstart.yaml", 12 * 2);
}

#[test]
fn twin_run_folders_are_identical_for_one_and_two_threads() {
    // The twin draws sensor noise and frame drops from the runs' named streams.
    assert_identical_for_one_and_two_threads("examples/sim-to-twin.yaml", 12 * 2);
}

fn summary_of(dir: &Path) -> Vec<u8> {
    std::fs::read(dir.join("summary.csv")).unwrap()
}

#[test]
fn shards_merged_by_report_and_killed_runs_resumed_give_the_same_summary() {
    let base = std::env::temp_dir().join(format!("cpmx-shards-{}", std::process::id()));
    let whole = base.join("whole");
    let out = cpmx(&[
        "run",
        "experiments/quickstart.yaml",
        "--out",
        whole.to_str().unwrap(),
    ]);
    assert!(out.status.success());

    // Two shards, merged by `report`.
    let shards: Vec<PathBuf> = (1..=2).map(|k| base.join(format!("shard{k}"))).collect();
    for (k, dir) in shards.iter().enumerate() {
        let shard = format!("{}/2", k + 1);
        let out = cpmx(&[
            "run",
            "experiments/quickstart.yaml",
            "--out",
            dir.to_str().unwrap(),
            "--shard",
            &shard,
        ]);
        assert!(out.status.success());
    }
    let merged = cpmx(&[
        "report",
        shards[0].to_str().unwrap(),
        shards[1].to_str().unwrap(),
        "--format",
        "csv",
    ]);
    assert!(
        merged.status.success(),
        "{}",
        String::from_utf8_lossy(&merged.stderr)
    );
    assert!(
        merged.stdout == summary_of(&whole),
        "merged shards differ from one run of the matrix"
    );

    // Killed with SIGKILL at some point, then resumed.
    let killed = base.join("killed");
    let mut child = Command::new(env!("CARGO_BIN_EXE_cpmx"))
        .args([
            "run",
            "experiments/quickstart.yaml",
            "--jobs",
            "1",
            "--out",
            killed.to_str().unwrap(),
        ])
        .current_dir(root())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(40));
    child.kill().ok();
    child.wait().unwrap();
    // A run whose result was half written does not count as finished.
    let victim = killed.join("runs/sim/nominal/crossing/rep1");
    std::fs::create_dir_all(&victim).unwrap();
    std::fs::write(victim.join("metrics.json"), "{\"key\": \"sim/nominal/cross").unwrap();
    let resumed = cpmx(&[
        "run",
        "experiments/quickstart.yaml",
        "--resume",
        "--out",
        killed.to_str().unwrap(),
    ]);
    assert!(
        resumed.status.success(),
        "{}",
        String::from_utf8_lossy(&resumed.stderr)
    );
    assert!(
        summary_of(&killed) == summary_of(&whole),
        "resumed summary differs"
    );

    // A second resume runs nothing again.
    let again = cpmx(&[
        "run",
        "experiments/quickstart.yaml",
        "--resume",
        "--out",
        killed.to_str().unwrap(),
    ]);
    assert!(
        String::from_utf8_lossy(&again.stderr).contains("0 run, 12 resumed"),
        "{}",
        String::from_utf8_lossy(&again.stderr)
    );
    std::fs::remove_dir_all(&base).ok();
}

#[test]
fn evaluate_of_a_runs_trajectory_gives_its_metrics() {
    let dir = std::env::temp_dir().join(format!("cpmx-eval-{}", std::process::id()));
    assert!(
        cpmx(&[
            "run",
            "experiments/quickstart.yaml",
            "--out",
            dir.to_str().unwrap()
        ])
        .status
        .success()
    );
    let run = dir.join("runs/sim/eager/turning/rep1");
    let out = cpmx(&[
        "evaluate",
        "experiments/quickstart.yaml",
        run.join("trajectory.csv").to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let evaluated: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let stored: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(evaluated, stored["metrics"]);

    // A truncated recording is a diagnostic and exit 1, never a panic.
    let text = std::fs::read_to_string(run.join("trajectory.csv")).unwrap();
    let truncated = dir.join("truncated.csv");
    std::fs::write(&truncated, &text[..text.len() / 2]).unwrap();
    let out = cpmx(&[
        "evaluate",
        "experiments/quickstart.yaml",
        truncated.to_str().unwrap(),
    ]);
    assert_eq!(
        out.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn every_example_runs() {
    let base = std::env::temp_dir().join(format!("cpmx-examples-{}", std::process::id()));
    for spec in shipped_specs().into_iter().filter(|s| s.starts_with("examples/")) {
        let out_dir = base.join(spec.replace('/', "_"));
        let out = cpmx(&["run", &spec, "--out", out_dir.to_str().unwrap()]);
        // Some examples read the CPM Lab map from the reference data.
        assert!(
            out.status.success(),
            "{}{spec}: {}",
            support::reference_note(),
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(out_dir.join("summary.md").is_file(), "{spec}");
    }
    std::fs::remove_dir_all(&base).ok();
}

#[test]
fn from_runs_starts_where_the_recorded_runs_did() {
    let base = std::env::temp_dir().join(format!("cpmx-from-runs-{}", std::process::id()));
    let recorded = base.join("recorded");
    assert!(
        cpmx(&[
            "run",
            "examples/minimal.yaml",
            "--out",
            recorded.to_str().unwrap()
        ])
        .status
        .success()
    );

    // A spec whose starts are the measured initial poses of those runs.
    let spec = base.join("replay.yaml");
    let text = std::fs::read_to_string(root().join("examples/minimal.yaml"))
        .unwrap()
        .replace("name: minimal", "name: replay")
        .replace(
            "  - name: straight\n    agents:\n      - {ref_path: 1, arc_length: 0.2}\n",
            &format!("  - from_runs: {{dir: {}, fidelity: sim}}\n", recorded.display()),
        );
    assert!(
        text.contains("from_runs"),
        "the example changed; update this test"
    );
    std::fs::write(&spec, text).unwrap();
    let replay = base.join("replay");
    let out = cpmx(&["run", spec.to_str().unwrap(), "--out", replay.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));

    // The configuration is named after the recorded run, and the first samples agree.
    let first_row = |path: PathBuf| {
        std::fs::read_to_string(path)
            .unwrap()
            .lines()
            .nth(1)
            .unwrap()
            .to_owned()
    };
    let original = first_row(recorded.join("runs/sim/baseline/straight/rep1/trajectory.csv"));
    let replayed = first_row(replay.join("runs/sim/baseline/sim-baseline-straight-rep1/rep1/trajectory.csv"));
    let pose = |row: &str| {
        row.split(',')
            .skip(2)
            .take(3)
            .map(|v| v.parse::<f64>().unwrap())
            .collect::<Vec<_>>()
    };
    assert_eq!(pose(&original), pose(&replayed));
    std::fs::remove_dir_all(&base).ok();
}
