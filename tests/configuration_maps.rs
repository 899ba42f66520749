//! Initial configurations on maps of their own (`map:` on an explicit or `sample` entry): one
//! experiment evaluates on several maps. Each configuration's runs drive, are checked and are
//! measured on its map; a missing or damaged map is located at the entry; the lab keeps to the
//! spec's map; `cpmx evaluate` asks which configuration a recording drove on; a `sample` entry
//! drawn per repetition starts each repetition elsewhere, alike for every policy.

mod support;

use std::path::{Path, PathBuf};

use support::{cpmx_in, reference, scratch, unwrapped};

/// A spec on the CPM map with a configuration of its own on `roundabout_1` (8 agents drawn per
/// repetition) and an explicit one on `intersection_2`; `extra` is appended.
fn spec(dir: &Path, roundabout_map: &str, extra: &str) -> PathBuf {
    let text = format!(
        "cpmx: 1
name: two-maps
map: {{file: maps/cpm.xml, tag: 1.2.0}}
vehicle: {{length: 0.16, width: 0.08, wheelbase: 0.16, rear_axle: 0.08, max_steering_deg: 35, max_steering_rate_deg_s: 900, accel: [-20, 20], max_speed: 1.0}}
timing: {{dt: 0.05, steps: 30}}
agents: 3
policies:
  - {{name: m0, mlp: {{sigmarl: sigmarl-published/checkpoints/itsc24/M0, tag: 1.2.0}}}}
  - {{name: m3, mlp: {{sigmarl: sigmarl-published/checkpoints/itsc24/M3, tag: 1.2.0}}}}
initial_configurations:
  - {{name: cpm, sample: {{count: 1, seed: 7, min_gap: 0.22}}}}
  - name: roundabout
    map: {roundabout_map}
    sample: {{count: 1, seed: 7, min_gap: 0.22, agents: 8, draw: per-repetition}}
  - name: crossing
    map: {{sigmarl: intersection_2}}
    agents:
      - {{ref_path: 0, arc_length: 0.5}}
      - {{ref_path: 4, arc_length: 0.5}}
repetitions: 2
seed: 7
on_collision: continue
fidelities:
  sim: {{control: direct, dynamics: kinematic-vmas}}
metrics: stdlib:at25
{extra}"
    );
    let path = dir.join("two-maps.yaml");
    std::fs::write(&path, text).unwrap();
    path
}

fn cpmx(dir: &Path, args: &[&str]) -> (Option<i32>, String, String) {
    let out = cpmx_in(dir, args);
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        unwrapped(&out.stderr),
    )
}

fn data_args(reference: &Path) -> [String; 2] {
    ["--data".into(), reference.to_str().unwrap().into()]
}

/// The first sample's (x, y) of every agent in a run's trajectory.
fn start_of(out: &Path, key: &str) -> Vec<(String, String)> {
    let text = std::fs::read_to_string(out.join("runs").join(key).join("trajectory.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (t, x, y) = (col("t"), col("x"), col("y"));
    lines
        .map(|l| l.split(',').collect::<Vec<_>>())
        .take_while(|c| c[t].parse::<f64>().unwrap() == 0.0)
        .map(|c| (c[x].to_owned(), c[y].to_owned()))
        .collect()
}

#[test]
fn configurations_run_and_are_measured_on_their_own_maps() {
    let reference = reference();
    let dir = scratch("configuration-maps-run");
    let path = spec(&dir, "{sigmarl: roundabout_1}", "");
    let [d, data] = data_args(&reference);
    let (code, stdout, stderr) = cpmx(&dir, &["validate", path.to_str().unwrap(), &d, &data]);
    assert_eq!(code, Some(0), "{stdout}{stderr}");
    assert!(stdout.contains("12 runs"), "{stdout}");
    let out = dir.join("out");
    let (code, stdout, stderr) = cpmx(
        &dir,
        &[
            "run",
            path.to_str().unwrap(),
            &d,
            &data,
            "--out",
            out.to_str().unwrap(),
        ],
    );
    assert_eq!(code, Some(0), "{stdout}{stderr}");
    // Each configuration's agent count: the spec's 3, the roundabout's 8, the crossing's 2.
    let per_run = std::fs::read_to_string(out.join("per_run.csv")).unwrap();
    let header: Vec<&str> = per_run.lines().next().unwrap().split(',').collect();
    let agents_col = header.iter().position(|h| *h == "num_agents").unwrap();
    for line in per_run.lines().skip(1) {
        let cols: Vec<&str> = line.split(',').collect();
        let expected = match cols[3] {
            "cpm" => "3",
            "roundabout" => "8",
            "crossing" => "2",
            other => panic!("unexpected configuration {other}"),
        };
        assert_eq!(cols[agents_col], expected, "{line}");
    }
    // Drawn per repetition: repetitions start apart, every policy from the same draw.
    let rep1 = start_of(&out, "sim/m0/roundabout/rep1");
    assert_eq!(rep1.len(), 8);
    assert_ne!(rep1, start_of(&out, "sim/m0/roundabout/rep2"));
    assert_eq!(rep1, start_of(&out, "sim/m3/roundabout/rep1"));
    // Drawn per configuration: both repetitions from one draw.
    assert_eq!(
        start_of(&out, "sim/m0/cpm/rep1"),
        start_of(&out, "sim/m0/cpm/rep2")
    );
    // The run folder pins each configuration's own map (SigmaRL's table) by its bytes.
    let resolved = std::fs::read_to_string(out.join("spec.resolved.yaml")).unwrap();
    let configurations = &resolved[resolved.find("initial_configurations:").unwrap()..];
    let configurations = &configurations[..configurations.find("\nrepetitions:").unwrap()];
    assert_eq!(configurations.matches("sha256: ").count(), 2, "{resolved}");
    // The report recomputes every run from its recording, on each run's map: the same table.
    let (code, report, stderr) = cpmx(&dir, &["report", out.to_str().unwrap(), &d, &data]);
    assert_eq!(code, Some(0), "{stderr}");
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert_eq!(report, summary, "the same bytes as the run's own summary");
    // The policies compared with each other, paired over the starts they share.
    let (code, report, stderr) = cpmx(
        &dir,
        &["report", out.to_str().unwrap(), &d, &data, "--compare", "m0"],
    );
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        report.contains("## Paired comparison with policy `m0`"),
        "{report}"
    );
    assert!(report.contains("| m3 | CRA-A ↓ [events/100 m] | 6 |"), "{report}");
    let (code, _, stderr) = cpmx(
        &dir,
        &["report", out.to_str().unwrap(), &d, &data, "--compare", "m9"],
    );
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("name one of sim, m0, m3"), "{stderr}");
    // A figure per run, each on its own map: the roundabout's 3.5 m x 2.0 m is drawn wider
    // than tall, the CPM map's 4.5 m x 4.0 m nearly square.
    let plot = |key: &str| std::fs::read_to_string(out.join("plots").join(format!("{key}.svg"))).unwrap();
    let aspect = |svg: String| {
        let number = |attribute: &str| -> f64 {
            let start = svg.find(&format!("{attribute}=\"")).unwrap() + attribute.len() + 2;
            svg[start..].split('"').next().unwrap().parse().unwrap()
        };
        number("width") / number("height")
    };
    assert!(aspect(plot("sim_m0_roundabout_rep1")) > 1.5);
    assert!(aspect(plot("sim_m0_cpm_rep1")) < 1.2);
    // `cpmx evaluate` asks which configuration a recording drove on, and measures it there.
    let trajectory = out.join("runs/sim/m0/roundabout/rep1/trajectory.csv");
    let (code, _, stderr) = cpmx(
        &dir,
        &[
            "evaluate",
            path.to_str().unwrap(),
            trajectory.to_str().unwrap(),
            &d,
            &data,
        ],
    );
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("--configuration NAME") && stderr.contains("roundabout"),
        "{stderr}"
    );
    let (code, json, stderr) = cpmx(
        &dir,
        &[
            "evaluate",
            path.to_str().unwrap(),
            trajectory.to_str().unwrap(),
            "--configuration",
            "roundabout",
            &d,
            &data,
        ],
    );
    assert_eq!(code, Some(0), "{stderr}");
    let metrics = std::fs::read_to_string(out.join("runs/sim/m0/roundabout/rep1/metrics.json")).unwrap();
    let value = |text: &str, key: &str| -> serde_json::Value {
        serde_json::from_str::<serde_json::Value>(text).unwrap()[key].clone()
    };
    let stored = &serde_json::from_str::<serde_json::Value>(&metrics).unwrap()["metrics"];
    for key in ["distance_m", "lane_violation_m", "cd_m"] {
        assert_eq!(value(&json, key), stored[key], "{key}: {json}\n{metrics}");
    }
    let (code, _, stderr) = cpmx(
        &dir,
        &[
            "evaluate",
            path.to_str().unwrap(),
            trajectory.to_str().unwrap(),
            "--configuration",
            "nowhere",
            &d,
            &data,
        ],
    );
    assert_eq!(code, Some(1));
    assert!(stderr.contains("no initial configuration `nowhere`"), "{stderr}");
}

#[test]
fn a_configuration_map_that_is_wrong_is_located_at_its_entry() {
    let reference = reference();
    let dir = scratch("configuration-maps-wrong");
    let [d, data] = data_args(&reference);
    // An unknown scenario: said at the entry's `map`, with the known names.
    let path = spec(&dir, "{sigmarl: roundabout_9}", "");
    let (code, _, stderr) = cpmx(&dir, &["validate", path.to_str().unwrap(), &d, &data]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("roundabout_9") && stderr.contains("roundabout_1"),
        "{stderr}"
    );
    assert!(
        stderr.contains("two-maps.yaml:13"),
        "located at the entry's map: {stderr}"
    );
    // A map file the data path does not hold.
    let path = spec(&dir, "{file: maps/nowhere.xml}", "");
    let (code, _, stderr) = cpmx(&dir, &["validate", path.to_str().unwrap(), &d, &data]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("nowhere.xml") && stderr.contains("two-maps.yaml:13"),
        "{stderr}"
    );
    // A path id the configuration's map has not (intersection_2 has 6).
    let text = std::fs::read_to_string(spec(&dir, "{sigmarl: roundabout_1}", ""))
        .unwrap()
        .replace("{ref_path: 4, arc_length: 0.5}", "{ref_path: 9, arc_length: 0.5}");
    std::fs::write(&path, text).unwrap();
    let (code, _, stderr) = cpmx(&dir, &["validate", path.to_str().unwrap(), &d, &data]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("no reference path 9"), "{stderr}");
    // Another agent count on the spec's own map.
    let text = std::fs::read_to_string(spec(&dir, "{sigmarl: roundabout_1}", ""))
        .unwrap()
        .replace("seed: 7, min_gap: 0.22}}", "seed: 7, min_gap: 0.22, agents: 4}}");
    std::fs::write(&path, text).unwrap();
    let (code, _, stderr) = cpmx(&dir, &["validate", path.to_str().unwrap(), &d, &data]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("places 4 agents, but the spec has `agents: 3`"),
        "{stderr}"
    );
}

#[test]
fn the_lab_drives_on_the_specs_map_only() {
    let reference = reference();
    let dir = scratch("configuration-maps-lab");
    let [d, data] = data_args(&reference);
    let path = spec(&dir, "{sigmarl: roundabout_1}", "");
    let text = std::fs::read_to_string(&path).unwrap().replace(
        "fidelities:\n",
        "fidelities:\n  lab: {driver: cpm-dds, domain: 21, vehicle_ids: [1, 2, 3], interface: 127.0.0.1}\n",
    );
    std::fs::write(&path, text).unwrap();
    let (code, _, stderr) = cpmx(&dir, &["validate", path.to_str().unwrap(), &d, &data]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("drives on the spec's `map`"), "{stderr}");
}
