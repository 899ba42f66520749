//! A run folder is a small database: `--only` never shrinks its summary, a typo changes
//! nothing, another spec is refused without `--force`, a hand-edited resolved spec is caught,
//! and a folder reports the same wherever it and its data move (files are pinned by hash).

mod support;

use std::path::Path;

use support::{cpmx, files, ok, reference, root};

/// A scratch folder of this file's tests.
fn scratch(name: &str) -> std::path::PathBuf {
    support::scratch(&format!("folder-{name}"))
}

#[test]
fn the_quickstart_runs_without_a_warning() {
    let validate = cpmx(&["validate", "experiments/quickstart.yaml"]);
    assert!(validate.status.success());
    let stderr = String::from_utf8_lossy(&validate.stderr);
    assert!(stderr.trim().is_empty(), "{stderr}");
}

#[test]
fn copies_of_deterministic_repetitions_count_once() {
    let dir = scratch("units");
    let text = std::fs::read_to_string(root().join("experiments/quickstart.yaml")).unwrap();
    let spec = dir.join("copies.yaml");
    let twice = regex_free_replace(&text, "repetitions: 1", "repetitions: 2 #");
    std::fs::write(&spec, twice).unwrap();
    let out = dir.join("out");
    let table = ok(&cpmx(&[
        "run",
        spec.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]));
    // Four configurations × two repetitions of a deterministic fidelity and policy.
    assert!(table.contains("| runs | units |"), "{table}");
    assert!(table.contains("| sim | cautious | 8 | 4 |"), "{table}");
    assert!(table.contains("Here 12 of 24 runs are copies"), "{table}");
    let validate = cpmx(&["validate", spec.to_str().unwrap()]);
    assert!(validate.status.success());
    let warnings = String::from_utf8_lossy(&validate.stderr);
    assert!(warnings.contains("deterministic"), "{warnings}");
    assert!(warnings.contains("repetitions: 1"), "{warnings}");
    // Once for the spec, however many fidelities are deterministic.
    assert_eq!(
        warnings.matches("cpmx::check::deterministic-repetitions").count(),
        1,
        "{warnings}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// `text` with the first `from` replaced by `to`; panics when `from` is not there.
fn regex_free_replace(text: &str, from: &str, to: &str) -> String {
    assert!(text.contains(from), "`{from}` not in the text");
    text.replacen(from, to, 1)
}

#[test]
fn only_never_shrinks_the_summary_and_a_typo_changes_nothing() {
    let dir = scratch("only");
    let out = dir.join("out");
    let out_arg = out.to_str().unwrap();
    ok(&cpmx(&["run", "experiments/quickstart.yaml", "--out", out_arg]));
    let before = files(&out);

    // A name the spec does not have: a usage error naming the valid ones; nothing written.
    let typo = cpmx(&[
        "run",
        "experiments/quickstart.yaml",
        "--out",
        out_arg,
        "--only",
        "policy=nominl",
    ]);
    assert_eq!(typo.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&typo.stderr);
    assert!(stderr.contains("did you mean `nominal`"), "{stderr}");
    assert!(stderr.contains("cautious, nominal, eager"), "{stderr}");
    assert!(files(&out) == before, "a refused --only left the folder changed");

    // A subset re-run into the finished folder: its summary still covers every run.
    let eager_again = || {
        cpmx(&[
            "run",
            "experiments/quickstart.yaml",
            "--out",
            out_arg,
            "--only",
            "policy=eager",
        ])
    };
    ok(&eager_again());
    let summary = std::fs::read_to_string(out.join("summary.csv")).unwrap();
    let whole = before
        .iter()
        .find(|(p, _)| p == Path::new("summary.csv"))
        .unwrap();
    assert_eq!(summary.as_bytes(), whole.1.as_slice());
    let reported = ok(&cpmx(&["report", out_arg, "--format", "csv"]));
    assert_eq!(summary, reported);

    // A run whose metrics.json is damaged is named, not taken for a run never made.
    let damaged = out.join("runs/sim/cautious/crossing/rep1/metrics.json");
    std::fs::write(&damaged, "{not json").unwrap();
    let rerun = eager_again();
    assert!(rerun.status.success());
    let stderr = String::from_utf8_lossy(&rerun.stderr);
    assert!(
        stderr.contains(
            "1 runs' files cannot be read and are left out of the summary (e.g. sim/cautious/crossing/rep1:"
        ),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_folder_of_another_spec_is_refused_without_force() {
    let dir = scratch("force");
    let out = dir.join("out");
    let out_arg = out.to_str().unwrap();
    ok(&cpmx(&["run", "experiments/quickstart.yaml", "--out", out_arg]));
    let text = std::fs::read_to_string(root().join("experiments/quickstart.yaml")).unwrap();
    let other = dir.join("other.yaml");
    std::fs::write(&other, text.replace("seed: 2026", "seed: 7")).unwrap();
    let before = files(&out);

    let refused = cpmx(&["run", other.to_str().unwrap(), "--out", out_arg]);
    assert_eq!(refused.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(
        stderr.contains("different spec") && stderr.contains("seed"),
        "{stderr}"
    );
    assert!(files(&out) == before);

    // --force: the new spec is the folder's; runs it left alone are not summarised with it.
    let forced = cpmx(&[
        "run",
        other.to_str().unwrap(),
        "--out",
        out_arg,
        "--force",
        "--only",
        "policy=eager",
    ]);
    let table = ok(&forced);
    let stderr = String::from_utf8_lossy(&forced.stderr);
    assert!(stderr.contains("earlier spec"), "{stderr}");
    assert!(
        table.contains("| sim | eager | 4 |") && !table.contains("cautious"),
        "{table}"
    );
    assert_eq!(
        ok(&cpmx(&["report", out_arg, "--format", "csv"])),
        std::fs::read_to_string(out.join("summary.csv")).unwrap()
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn report_merges_only_one_specs_folders_and_rescores_into_another_folder() {
    let dir = scratch("merge");
    let (quickstart, other) = (dir.join("quickstart"), dir.join("other"));
    let (quickstart_arg, other_arg) = (quickstart.to_str().unwrap(), other.to_str().unwrap());
    ok(&cpmx(&[
        "run",
        "experiments/quickstart.yaml",
        "--out",
        quickstart_arg,
    ]));
    ok(&cpmx(&["run", "examples/minimal.yaml", "--out", other_arg]));

    // Another spec's folder would be left out of the first one's matrix without a word.
    let mixed = cpmx(&["report", quickstart_arg, other_arg]);
    assert_eq!(mixed.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&mixed.stderr);
    assert!(
        stderr.contains("another spec") && stderr.contains("minimal"),
        "{stderr}"
    );

    // Re-scored summaries in the folder itself would contradict its metrics.json files.
    let before = files(&quickstart);
    let into_itself = cpmx(&[
        "report",
        quickstart_arg,
        "--metrics",
        "stdlib:at25-paper",
        "--out",
        quickstart_arg,
    ]);
    assert_eq!(into_itself.status.code(), Some(2));
    assert!(files(&quickstart) == before);

    // The builds that wrote the runs.
    let provenance = std::fs::read_to_string(quickstart.join("provenance.json")).unwrap();
    assert!(
        provenance.contains("\"made_by\"") && provenance.contains("cpmx 0."),
        "{provenance}"
    );

    // A damaged metrics.json is named, not counted as a run never made.
    let damaged = quickstart.join("runs/sim/eager/crossing/rep1/metrics.json");
    std::fs::write(&damaged, "{not json").unwrap();
    let report = cpmx(&["report", quickstart_arg]);
    assert!(report.status.success());
    let stderr = String::from_utf8_lossy(&report.stderr);
    assert!(
        stderr.contains("cannot be read") && stderr.contains("eager/crossing/rep1/metrics.json"),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn stored_runs_are_regrouped_on_purpose() {
    let dir = scratch("group-by");
    let out = dir.join("out");
    let out_arg = out.to_str().unwrap();
    let by_policy = ok(&cpmx(&["run", "experiments/quickstart.yaml", "--out", out_arg]));
    let pooled = ok(&cpmx(&["report", out_arg, "--group-by", "fidelity"]));
    // The title says the rows pool what the spec keeps apart; one row for sim's 12 runs.
    let (title, table) = pooled.split_once('\n').unwrap();
    assert_eq!(title, "# quickstart (grouped by fidelity)");
    assert!(table.contains("| sim | 12 | 12 |"), "{table}");
    assert!(by_policy.contains("| sim | cautious | 4 | 4 |"), "{by_policy}");
    let by_configuration = ok(&cpmx(&[
        "report",
        out_arg,
        "--group-by",
        "fidelity,initial_configuration",
    ]));
    assert!(
        by_configuration.contains("| sim | turning | 3 |"),
        "{by_configuration}"
    );
    // The folder's own summaries follow its spec: other rows are written elsewhere.
    let before = files(&out);
    let into_itself = cpmx(&["report", out_arg, "--group-by", "fidelity", "--out", out_arg]);
    assert_eq!(into_itself.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&into_itself.stderr).contains("grouped by fidelity"));
    assert_eq!(files(&out), before);
    let misspelt = cpmx(&["report", out_arg, "--group-by", "polcy"]);
    assert_eq!(misspelt.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&misspelt.stderr).contains("use fidelity, policy or initial_configuration"),
        "{}",
        String::from_utf8_lossy(&misspelt.stderr)
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_hand_edited_resolved_spec_is_caught() {
    let dir = scratch("edited");
    let out = dir.join("out");
    ok(&cpmx(&[
        "run",
        "experiments/quickstart.yaml",
        "--out",
        out.to_str().unwrap(),
    ]));
    let path = out.join("spec.resolved.yaml");
    let text = std::fs::read_to_string(&path).unwrap();
    std::fs::write(&path, text.replace("slack: 0.0", "slack: 0.1")).unwrap();
    let report = cpmx(&["report", out.to_str().unwrap()]);
    assert_eq!(report.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&report.stderr);
    assert!(
        stderr.contains("was edited") && stderr.contains("--metrics"),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn stored_runs_are_rescored_with_other_metrics() {
    let dir = scratch("metrics");
    let out = dir.join("out");
    let out_arg = out.to_str().unwrap();
    let script = ok(&cpmx(&["run", "experiments/quickstart.yaml", "--out", out_arg]));
    let paper = ok(&cpmx(&["report", out_arg, "--metrics", "stdlib:at25-paper"]));
    assert_ne!(script, paper, "a 10 % lane slack changes CRA-L");
    // The title says what scored the table; the spec's own metrics did not.
    let (title, table) = paper.split_once('\n').unwrap();
    assert_eq!(title, "# quickstart (scored with --metrics stdlib:at25-paper)");
    assert!(script.starts_with("# quickstart\n"), "{script}");
    let file = dir.join("metrics.yaml");
    std::fs::write(
        &file,
        "{extends: stdlib:at25, cra_l: {slack: 0.1, per_distance_m: 100}}\n",
    )
    .unwrap();
    let from_file = ok(&cpmx(&["report", out_arg, "--metrics", file.to_str().unwrap()]));
    assert_eq!(
        from_file.split_once('\n').unwrap(),
        (
            format!("# quickstart (scored with --metrics {})", file.display()).as_str(),
            table
        )
    );
    let unknown = cpmx(&["report", out_arg, "--metrics", "stdlib:at52"]);
    assert_eq!(unknown.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&unknown.stderr).contains("stdlib:at25"));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn report_takes_run_folders_not_specs() {
    let out = cpmx(&["report", "experiments/quickstart.yaml"]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("takes run folders") && stderr.contains("cpmx run"),
        "{stderr}"
    );
}

#[test]
fn a_moved_folder_reports_the_same_with_its_data_elsewhere() {
    // A small spec on the CPM Lab map with SigmaRL's actor, both found on --data.
    let dir = scratch("moved");
    let data = dir.join("data");
    std::fs::create_dir_all(data.join("maps")).unwrap();
    std::fs::create_dir_all(data.join("policy")).unwrap();
    std::fs::copy(reference().join("maps/cpm.xml"), data.join("maps/cpm.xml")).unwrap();
    std::fs::copy(
        reference().join("policy/actor.safetensors"),
        data.join("policy/actor.safetensors"),
    )
    .unwrap();
    let spec = dir.join("small.yaml");
    std::fs::write(
        &spec,
        "cpmx: 1\nname: small\nmap: {file: maps/cpm.xml}\ntiming: {dt: 0.1, steps: 30}\nagents: 2\n\
         policies:\n  - {name: seed1, mlp: {weights: policy/actor.safetensors}}\n\
         initial_configurations:\n  - name: a\n    agents:\n      - {ref_path: 6, arc_length: 0.3}\n      - {ref_path: 2, arc_length: 0.3}\n\
         repetitions: 1\nseed: 1\nfidelities:\n  sim: {control: direct, dynamics: kinematic}\n",
    )
    .unwrap();
    let out = dir.join("out");
    ok(&cpmx(&[
        "run",
        spec.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--data",
        data.to_str().unwrap(),
    ]));
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    let resolved = std::fs::read_to_string(out.join("spec.resolved.yaml")).unwrap();
    assert!(
        !resolved.contains(dir.to_str().unwrap()),
        "no absolute path in the resolved spec"
    );
    assert!(resolved.contains("sha256"), "{resolved}");

    // Move the folder and the data; only the map is left.
    let (moved, elsewhere) = (dir.join("moved"), dir.join("elsewhere"));
    std::fs::rename(&out, &moved).unwrap();
    std::fs::rename(&data, &elsewhere).unwrap();
    std::fs::remove_file(elsewhere.join("policy/actor.safetensors")).unwrap();
    let lost = cpmx(&["report", moved.to_str().unwrap()]);
    assert_eq!(lost.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&lost.stderr);
    assert!(
        stderr.contains("maps/cpm.xml") && stderr.contains("sha256"),
        "{stderr}"
    );
    let found = ok(&cpmx(&[
        "report",
        moved.to_str().unwrap(),
        "--data",
        elsewhere.to_str().unwrap(),
    ]));
    assert_eq!(found, summary);

    // A different file of the same name is not taken for the pinned one.
    std::fs::write(elsewhere.join("maps/cpm.xml"), "<CommonRoad/>").unwrap();
    let other = cpmx(&[
        "report",
        moved.to_str().unwrap(),
        "--data",
        elsewhere.to_str().unwrap(),
    ]);
    assert_eq!(other.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&other.stderr).contains("other versions"));

    // evaluate needs only the map, too.
    std::fs::copy(reference().join("maps/cpm.xml"), elsewhere.join("maps/cpm.xml")).unwrap();
    let trajectory = moved.join("runs/sim/seed1/a/rep1/trajectory.csv");
    let metrics = ok(&cpmx(&[
        "evaluate",
        spec.to_str().unwrap(),
        trajectory.to_str().unwrap(),
        "--data",
        elsewhere.to_str().unwrap(),
    ]));
    assert!(metrics.contains("\"cd_m\""), "{metrics}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn agents_that_finish_early_can_leave_the_measurement() {
    let dir = scratch("end-agent");
    let text = std::fs::read_to_string(root().join("experiments/quickstart.yaml")).unwrap();
    let ended = dir.join("ended.yaml");
    std::fs::write(
        &ended,
        text.replace(
            "timing: {dt: 0.1, steps: 80}",
            "timing: {dt: 0.1, steps: 80, stop_at_path_end: end-agent}",
        )
        .replace("repetitions: 2", "repetitions: 1"),
    )
    .unwrap();
    let waiting = dir.join("waiting.yaml");
    std::fs::write(&waiting, text.replace("repetitions: 2", "repetitions: 1")).unwrap();
    let speed = |spec: &Path, out: &str| -> f64 {
        let out = dir.join(out);
        ok(&cpmx(&[
            "run",
            spec.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]));
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
        json["groups"][1]["metrics"]["as_mps"]["mean"].as_f64().unwrap()
    };
    let (waiting_as, ended_as) = (speed(&waiting, "waiting"), speed(&ended, "ended"));
    assert!(
        ended_as > waiting_as + 0.01,
        "waiting {waiting_as} m/s, ended {ended_as} m/s"
    );
    std::fs::remove_dir_all(&dir).ok();
}
