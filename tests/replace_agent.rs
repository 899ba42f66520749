//! `on_collision: replace-agent` and `sample: {placement: sigmarl}`: SigmaRL's testing mode from
//! the command line. A car that collides leaves and a new agent drives in its slot, so every
//! sample has the spec's number of cars while the recording holds more agents; the run folder
//! counts the replacements, its metrics measure each agent over its own samples, `cpmx report`
//! recomputes them from the trajectories, and the runs are the same on any thread count.

mod support;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use support::{cpmx_in, reference, scratch, unwrapped};

/// Six cars of SigmaRL's published M0 on its `intersection_2`, placed as SigmaRL's testing mode
/// places them; within 15 s they reach their paths' ends (and some meet in the crossing).
fn spec(dir: &Path) -> PathBuf {
    let text = "cpmx: 1
name: replace
map: {sigmarl: intersection_2}
vehicle: {length: 0.16, width: 0.08, wheelbase: 0.16, rear_axle: 0.08, max_steering_deg: 35, max_steering_rate_deg_s: 900, accel: [-20, 20], max_speed: 1.0}
timing: {dt: 0.05, steps: 300}
agents: 6
policies:
  - {name: m0, mlp: {sigmarl: sigmarl-published/checkpoints/itsc24/M0, tag: 1.2.0}}
initial_configurations:
  - {name: crossing, sample: {count: 1, seed: 3, min_gap: 0.2147, placement: sigmarl, draw: per-repetition}}
repetitions: 2
seed: 11
on_collision: replace-agent
fidelities:
  sim: {control: direct, dynamics: kinematic-vmas}
metrics: {extends: stdlib:at25, per_sample_collisions: {}}
";
    let path = dir.join("replace.yaml");
    std::fs::write(&path, text).unwrap();
    path
}

fn run(dir: &Path, path: &Path, out: &Path, jobs: &str) {
    let reference = reference();
    let out = cpmx_in(
        dir,
        &[
            "run",
            path.to_str().unwrap(),
            "--data",
            reference.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--jobs",
            jobs,
        ],
    );
    assert!(out.status.success(), "{}", unwrapped(&out.stderr));
}

/// The agents present at each time of a run (in time order).
type Presence = Vec<(String, Vec<usize>)>;

/// The agents present at each time of a run's trajectory, and each agent's reference path.
fn presence(out: &Path, key: &str) -> (Presence, BTreeMap<usize, String>) {
    let text = std::fs::read_to_string(out.join("runs").join(key).join("trajectory.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (t, agent, ref_path) = (col("t"), col("agent"), col("ref_path"));
    let mut at = Presence::new();
    let mut paths = BTreeMap::new();
    for line in lines {
        let cols: Vec<&str> = line.split(',').collect();
        let a: usize = cols[agent].parse().unwrap();
        match at.last_mut() {
            Some((time, agents)) if time == cols[t] => agents.push(a),
            _ => at.push((cols[t].to_owned(), vec![a])),
        }
        paths.insert(a, cols[ref_path].to_owned());
    }
    (at, paths)
}

#[test]
fn collided_cars_leave_and_new_agents_drive_in_their_slots() {
    let dir = scratch("replace-agent");
    let path = spec(&dir);
    let out = dir.join("out");
    run(&dir, &path, &out, "2");

    for key in ["sim/m0/crossing/rep1", "sim/m0/crossing/rep2"] {
        let (at, paths) = presence(&out, key);
        assert_eq!(at.len(), 300, "{key}: one time per step");
        // Six cars at every time; more agents over the run (the replaced ones and their
        // successors), each present over one unbroken range of times.
        assert!(at.iter().all(|(_, agents)| agents.len() == 6), "{key}: {at:?}");
        assert!(paths.len() > 6, "{key}: nobody was replaced: {paths:?}");
        let first_time = |a: usize| at.iter().position(|(_, agents)| agents.contains(&a));
        let times = |a: usize| at.iter().filter(|(_, agents)| agents.contains(&a)).count();
        for a in paths.keys() {
            let first = first_time(*a).unwrap();
            let last = at.iter().rposition(|(_, agents)| agents.contains(a)).unwrap();
            assert_eq!(last + 1 - first, times(*a), "{key}: agent {a} has a gap");
        }
        // Agents are numbered in the order they came.
        let firsts: Vec<usize> = paths.keys().map(|&a| first_time(a).unwrap()).collect();
        assert!(firsts.windows(2).all(|w| w[0] <= w[1]), "{firsts:?}");
    }

    // The run folder counts the replacements of each run and measures every agent.
    let per_run = std::fs::read_to_string(out.join("per_run.csv")).unwrap();
    let header: Vec<&str> = per_run.lines().next().unwrap().split(',').collect();
    let replaced = header
        .iter()
        .position(|h| *h == "replaced")
        .expect("a `replaced` column");
    let cd = header.iter().position(|h| *h == "cd_m").unwrap();
    let shares = ["cr_aa_pct", "cr_al_pct"].map(|c| header.iter().position(|h| *h == c).unwrap());
    for line in per_run.lines().skip(1) {
        let cols: Vec<&str> = line.split(',').collect();
        assert!(cols[replaced].parse::<f64>().unwrap() >= 1.0, "{line}");
        assert!(cols[cd].parse::<f64>().unwrap().is_finite(), "{line}");
        for share in shares {
            assert!(
                (0.0..=100.0).contains(&cols[share].parse::<f64>().unwrap()),
                "{line}"
            );
        }
    }
    let (_, paths) = presence(&out, "sim/m0/crossing/rep1");
    let metrics = std::fs::read_to_string(out.join("runs/sim/m0/crossing/rep1/metrics.json")).unwrap();
    assert!(
        metrics.contains(&format!("\"num_agents\": {}", paths.len())),
        "{metrics}"
    );

    // `cpmx report` recomputes the same table from the trajectories.
    let reference = reference();
    let report_of = |more: &[&str]| {
        let mut args = vec![
            "report",
            out.to_str().unwrap(),
            "--data",
            reference.to_str().unwrap(),
        ];
        args.extend_from_slice(more);
        let report = cpmx_in(&dir, &args);
        assert!(report.status.success(), "{}", unwrapped(&report.stderr));
        report
    };
    let report = report_of(&[]);
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert_eq!(String::from_utf8(report.stdout).unwrap(), summary);
    assert!(
        summary.contains("CR-AA ↓ [% of samples] | CR-AL ↓ [% of samples] |"),
        "{summary}"
    );

    // The folder's figures and page, drawn from the recordings the command kept in memory,
    // are those `cpmx report` draws from the files (agents that come and go included).
    let redrawn = dir.join("redrawn");
    report_of(&["--out", redrawn.to_str().unwrap()]);
    let drawn = support::files(&redrawn);
    assert!(
        drawn.iter().any(|(path, _)| path.starts_with("plots")),
        "{drawn:?}"
    );
    for (path, bytes) in drawn {
        let kept = std::fs::read(out.join(&path)).unwrap();
        assert!(kept == bytes, "{} differs", path.display());
    }

    // The same runs on one thread.
    let single = dir.join("single");
    run(&dir, &path, &single, "1");
    for key in ["sim/m0/crossing/rep1", "sim/m0/crossing/rep2"] {
        let file = |root: &Path| std::fs::read(root.join("runs").join(key).join("trajectory.csv")).unwrap();
        assert_eq!(file(&out), file(&single), "{key}");
    }
}

#[test]
fn sigmarl_placement_starts_cars_moving_on_centre_line_points() {
    let dir = scratch("replace-agent-starts");
    let path = spec(&dir);
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("steps: 300", "steps: 2");
    std::fs::write(&path, text).unwrap();
    let out = dir.join("out");
    run(&dir, &path, &out, "1");
    let trajectory = std::fs::read_to_string(out.join("runs/sim/m0/crossing/rep1/trajectory.csv")).unwrap();
    let mut lines = trajectory.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (t, vx, vy) = (col("t"), col("vx"), col("vy"));
    let speeds: Vec<f64> = lines
        .map(|l| l.split(',').collect::<Vec<_>>())
        .filter(|c| c[t] == "0")
        .map(|c| c[vx].parse::<f64>().unwrap().hypot(c[vy].parse::<f64>().unwrap()))
        .collect();
    assert_eq!(speeds.len(), 6);
    // Speeds drawn in [0, 1): moving, and not all alike.
    assert!(speeds.iter().all(|v| (0.0..1.0).contains(v)), "{speeds:?}");
    assert!(speeds.iter().any(|v| *v > 0.05), "{speeds:?}");
}
