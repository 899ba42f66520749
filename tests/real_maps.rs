//! Real-world maps end to end: the Lanelet2 project's example map (from
//! `../shared/reference/maps/lanelet2/`) described by `cpmx validate` on a map-only spec, and
//! run with sampled starts and the lane-follow baseline, every start on the road; a broken
//! map gives a diagnostic naming the map file's line.

mod support;

use support::{cpmx_in as cpmx, temp, walk};

use std::path::{Path, PathBuf};

use cpmx_world::Map;

fn example_map() -> PathBuf {
    cpmx_testdata::reference_file("maps/lanelet2/mapping_example.osm")
}

#[test]
fn validate_on_a_map_only_spec_prints_what_the_map_holds() {
    let dir = temp("validate");
    std::fs::copy(example_map(), dir.join("karlsruhe.osm")).unwrap();
    std::fs::write(
        dir.join("map.yaml"),
        "cpmx: 1\nname: karlsruhe\nmap: {file: karlsruhe.osm}\n",
    )
    .unwrap();
    let out = cpmx(&dir, &["validate", "map.yaml"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // The header, the notes and the first paths, as a user reads them.
    let shown: Vec<&str> = stdout.lines().take_while(|l| !l.starts_with("    5:")).collect();
    insta::assert_snapshot!(shown.join("\n").replace(&dir.display().to_string(), "DIR"));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_lanelet2_example_runs_with_sampled_starts_and_lane_follow_on_the_road() {
    let dir = temp("run");
    std::fs::copy(example_map(), dir.join("karlsruhe.osm")).unwrap();
    let spec = "cpmx: 1
name: karlsruhe
map: {file: karlsruhe.osm}
timing: {dt: 0.1, steps: 40}
agents: 4
policies:
  - {name: baseline, builtin: lane-follow}
initial_configurations:
  - sample: {count: 3, seed: 5, min_gap: 1.0}
repetitions: 1
seed: 1
fidelities:
  sim: {control: direct, dynamics: kinematic}
";
    std::fs::write(dir.join("spec.yaml"), spec).unwrap();
    let out = cpmx(&dir, &["validate", "spec.yaml"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let out = cpmx(&dir, &["run", "spec.yaml", "--out", "out", "--jobs", "1"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));

    let map = Map::load(dir.join("karlsruhe.osm")).unwrap();
    assert_eq!(starts_on_the_road_and_drives(&map, &dir.join("out")), 3);
    std::fs::remove_dir_all(&dir).ok();
}

/// Every run's first sample: each car's footprint lies on its path's road; and the cars
/// drive (one may wait behind another). Returns the number of runs.
fn starts_on_the_road_and_drives(map: &Map, out: &Path) -> usize {
    let mut runs = 0;
    for entry in walk(out) {
        if entry.file_name().is_none_or(|n| n != "trajectory.csv") {
            continue;
        }
        runs += 1;
        let file = std::fs::File::open(&entry).unwrap();
        let recording = cpmx_recording::Recording::read_csv(file).expect("a trajectory");
        for (agent, sample) in recording.samples[0].iter().enumerate() {
            let (half_l, half_w) = (0.22 / 2.0, 0.107 / 2.0);
            let (s, c) = sample.yaw_rad.sin_cos();
            let corners = [
                [half_l, half_w],
                [half_l, -half_w],
                [-half_l, -half_w],
                [-half_l, half_w],
            ]
            .map(|[lx, ly]| [sample.x_m + lx * c - ly * s, sample.y_m + lx * s + ly * c]);
            assert_eq!(
                map.footprint_on_road(recording.ref_paths[agent], &corners),
                Some(true),
                "{} agent {agent}",
                entry.display()
            );
        }
        // The cars drive (one may wait behind another).
        let last = recording.samples.last().unwrap();
        let moved = recording.samples[0]
            .iter()
            .zip(last)
            .map(|(a, b)| (a.x_m - b.x_m).hypot(a.y_m - b.y_m))
            .fold(0.0, f64::max);
        assert!(moved > 0.5, "{}: moved {moved} m", entry.display());
    }
    runs
}

/// CommonRoad benchmark scenarios held back from the repository (the benchmark's licence
/// and size keep them out): every `*.xml` of `CPMX_COMMONROAD_SCENARIOS` with lanelets
/// validates, runs with sampled starts and the lane-follow baseline, and no run starts off
/// the road. Run with
/// `CPMX_COMMONROAD_SCENARIOS=DIR cargo test --test real_maps -- --ignored held_back`.
#[test]
#[ignore = "needs CommonRoad scenarios outside the repository in CPMX_COMMONROAD_SCENARIOS"]
fn held_back_commonroad_scenarios_validate_and_run_on_the_road() {
    let scenarios =
        PathBuf::from(std::env::var_os("CPMX_COMMONROAD_SCENARIOS").expect("CPMX_COMMONROAD_SCENARIOS=DIR"));
    let mut files: Vec<PathBuf> = std::fs::read_dir(&scenarios)
        .expect("a folder of CommonRoad scenarios")
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "xml"))
        .collect();
    files.sort();
    let dir = temp("held-back");
    let mut ran = 0;
    for file in &files {
        let Ok(map) = Map::load(file) else {
            let text = std::fs::read_to_string(file).unwrap_or_default();
            assert!(
                !text.contains("<lanelet"),
                "{} has lanelets and does not load",
                file.display()
            );
            continue;
        };
        let spec = format!(
            "cpmx: 1
name: held-back
map: {{file: \"{}\"}}
timing: {{dt: 0.1, steps: 40}}
agents: 3
policies:
  - {{name: baseline, builtin: lane-follow}}
initial_configurations:
  - sample: {{count: 2, seed: 5, min_gap: 1.0}}
repetitions: 1
seed: 1
fidelities:
  sim: {{control: direct, dynamics: kinematic}}
",
            file.display()
        );
        std::fs::write(dir.join("spec.yaml"), spec).unwrap();
        let out = cpmx(&dir, &["validate", "spec.yaml"]);
        assert!(
            out.status.success(),
            "{}: {}",
            file.display(),
            String::from_utf8_lossy(&out.stderr)
        );
        std::fs::remove_dir_all(dir.join("out")).ok();
        let out = cpmx(&dir, &["run", "spec.yaml", "--out", "out"]);
        assert!(
            out.status.success(),
            "{}: {}",
            file.display(),
            String::from_utf8_lossy(&out.stderr)
        );
        assert_eq!(
            starts_on_the_road_and_drives(&map, &dir.join("out")),
            2,
            "{}",
            file.display()
        );
        eprintln!("{}: validates and runs, starts on the road", file.display());
        ran += 1;
    }
    assert!(ran > 0, "no scenario with lanelets in {}", scenarios.display());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_truncated_map_is_reported_at_the_line_where_it_breaks_off() {
    let dir = temp("broken");
    let text = std::fs::read_to_string(example_map()).unwrap();
    let cut = &text[..text.len() / 2];
    std::fs::write(dir.join("karlsruhe.osm"), cut).unwrap();
    std::fs::write(
        dir.join("map.yaml"),
        "cpmx: 1\nname: karlsruhe\nmap: {file: karlsruhe.osm}\n",
    )
    .unwrap();
    let out = cpmx(&dir, &["validate", "map.yaml"]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    let line = cut.trim_end().lines().count();
    assert!(
        stderr.contains(&format!("karlsruhe.osm: {line}:")),
        "line {line}: {stderr}"
    );
    assert!(stderr.contains("the file ends inside <"), "{stderr}");
    std::fs::remove_dir_all(&dir).ok();
}

/// A spec path with a 64-bit id over negative lanelet ids (the reverses of two-way lanelets
/// 45482 and 45480) runs, and the id reaches the recording's `ref_path` column.
#[test]
fn sixty_four_bit_path_ids_over_negative_lanelet_ids_reach_the_recording() {
    let dir = temp("ids");
    std::fs::copy(example_map(), dir.join("karlsruhe.osm")).unwrap();
    let spec = "cpmx: 1
name: ids
map:
  file: karlsruhe.osm
  ref_paths: [{id: 8589934592, lanelets: [-45483, -45481]}]
timing: {dt: 0.1, steps: 20}
agents: 1
policies:
  - {name: baseline, builtin: lane-follow}
initial_configurations:
  - name: reverse
    agents: [{ref_path: 8589934592, arc_length: 2.0}]
repetitions: 1
seed: 1
fidelities:
  sim: {control: direct, dynamics: kinematic}
";
    std::fs::write(dir.join("spec.yaml"), spec).unwrap();
    let out = cpmx(&dir, &["run", "spec.yaml", "--out", "out"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let trajectory = walk(&dir.join("out"))
        .into_iter()
        .find(|p| p.ends_with("trajectory.csv"))
        .expect("a trajectory");
    let recording = cpmx_recording::Recording::read_csv(std::fs::File::open(trajectory).unwrap()).unwrap();
    assert_eq!(recording.ref_paths, vec![8_589_934_592]);

    // An unknown lanelet in a spec path is named with its 64-bit id.
    std::fs::write(
        dir.join("bad.yaml"),
        spec.replace("-45481", "-9000000000000000001"),
    )
    .unwrap();
    let out = cpmx(&dir, &["validate", "bad.yaml"]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("-9000000000000000001"), "{stderr}");
    std::fs::remove_dir_all(&dir).ok();
}
