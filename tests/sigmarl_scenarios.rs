//! SigmaRL's scenarios by name (`map: {sigmarl: NAME}`): each of the 15 driving scenarios of
//! its table validates and runs from the reference data; an unknown name lists the known ones;
//! a damaged map file is reported at its line.

mod support;

use std::path::Path;

use support::{cpmx_in, reference, scratch, unwrapped};

/// A spec on scenario `map` (a `map:` value): one agent on path 0, the paper's actor of seed 1.
fn spec(dir: &Path, name: &str, map: &str) -> std::path::PathBuf {
    let text = format!(
        "cpmx: 1
name: {name}
map: {map}
vehicle: stdlib:sigmarl-2025
timing: {{dt: 0.1, steps: 20}}
agents: 1
policies:
  - {{name: paper, mlp: {{sigmarl: paper-at25/seed1}}, action: mean}}
initial_configurations:
  - name: start
    agents:
      - {{ref_path: 0, arc_length: 0.4}}
repetitions: 1
seed: 1
fidelities:
  sim: {{control: direct, dynamics: kinematic}}
metrics: stdlib:at25
"
    );
    let path = dir.join(format!("{name}.yaml"));
    std::fs::write(&path, text).unwrap();
    path
}

fn run(dir: &Path, command: &str, spec: &Path, data: &Path) -> (Option<i32>, String) {
    let mut args = vec![command, spec.to_str().unwrap(), "--data", data.to_str().unwrap()];
    let out_dir = dir.join("out");
    if command == "run" {
        args.extend(["--out", out_dir.to_str().unwrap()]);
    }
    let out = cpmx_in(dir, &args);
    let text = String::from_utf8_lossy(&out.stdout).into_owned() + &unwrapped(&out.stderr);
    (out.status.code(), text)
}

const SCENARIOS: [&str; 15] = [
    "intersection_1",
    "intersection_2",
    "intersection_3",
    "intersection_4",
    "intersection_5",
    "intersection_6",
    "intersection_7",
    "intersection_8",
    "interchange_1",
    "interchange_2",
    "interchange_3",
    "on_ramp_1",
    "on_ramp_2_multilane",
    "roundabout_1",
    "roundabout_2",
];

#[test]
fn every_scenario_validates_and_runs_by_name() {
    let reference = reference();
    for name in SCENARIOS {
        let dir = scratch(&format!("sigmarl-scenario-{name}"));
        let path = spec(&dir, &name.replace('_', "-"), &format!("{{sigmarl: {name}}}"));
        let (code, text) = run(&dir, "validate", &path, &reference);
        assert_eq!(code, Some(0), "{name}: {text}");
        let (code, text) = run(&dir, "run", &path, &reference);
        assert_eq!(code, Some(0), "{name}: {text}");
        let per_run = std::fs::read_to_string(dir.join("out/per_run.csv")).unwrap();
        assert_eq!(per_run.lines().count(), 2, "{name}: one run\n{per_run}");
    }
}

#[test]
fn an_unknown_scenario_lists_the_known_ones() {
    let reference = reference();
    let dir = scratch("sigmarl-scenario-unknown");
    let path = spec(&dir, "unknown", "{sigmarl: roundabout_9}");
    let (code, text) = run(&dir, "validate", &path, &reference);
    assert_eq!(code, Some(1), "{text}");
    assert!(text.contains("has no scenario `roundabout_9`"), "{text}");
    assert!(text.contains("roundabout_1, roundabout_2"), "{text}");
    // A table that is not on the data path is named.
    let path = spec(&dir, "no-table", "{sigmarl: roundabout_1, table: maps/none.json}");
    let (code, text) = run(&dir, "validate", &path, &reference);
    assert_eq!(code, Some(1), "{text}");
    assert!(
        text.contains("scenario table `maps/none.json` was not found"),
        "{text}"
    );
}

#[test]
fn a_damaged_scenario_map_is_reported_at_its_line() {
    // A copy of the published table and maps with one node's latitude broken.
    let reference = reference();
    let dir = scratch("sigmarl-scenario-damaged");
    let maps = dir.join("maps");
    std::fs::create_dir_all(&maps).unwrap();
    let published = reference.join("sigmarl-published/maps");
    std::fs::copy(published.join("scenarios.json"), maps.join("scenarios.json")).unwrap();
    let text = std::fs::read_to_string(published.join("roundabout_1.osm")).unwrap();
    let line = text.lines().position(|l| l.contains("<node")).unwrap() + 1;
    let broken = text.replacen(" lat='", " lat='north", 1);
    std::fs::write(maps.join("roundabout_1.osm"), broken).unwrap();
    let path = spec(
        &dir,
        "damaged",
        "{sigmarl: roundabout_1, table: maps/scenarios.json}",
    );
    let (code, text) = run(&dir, "validate", &path, &reference);
    assert_eq!(code, Some(1), "{text}");
    assert!(text.contains("roundabout_1.osm"), "{text}");
    assert!(
        text.contains(&format!("{line}:")) && text.contains("needs a finite `lat`"),
        "{text}"
    );
}

#[test]
fn a_map_only_spec_lists_the_scenarios_paths() {
    let reference = reference();
    let dir = scratch("sigmarl-scenario-look");
    let path = dir.join("look.yaml");
    std::fs::write(&path, "cpmx: 1\nname: look\nmap: {sigmarl: roundabout_1}\n").unwrap();
    let (code, text) = run(&dir, "validate", &path, &reference);
    assert_eq!(code, Some(0), "{text}");
    assert!(text.contains("  lanelets: 9\n"), "{text}");
    assert!(
        text.contains("reference paths (ref_path): 5, by SigmaRL's scenario table"),
        "{text}"
    );
    assert!(
        text.contains("    1: 4.18 m, open, lanelets 1 -> 3 -> 7 -> 9"),
        "{text}"
    );
}
