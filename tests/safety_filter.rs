//! A fidelity's `safety:` layer (`stdlib:sigmarl-cbf`): the paper's actor driven through
//! SigmaRL's CBF filter in sim and in the twin's planner, what the filter did kept in each
//! run's notes; SigmaRL's MTV-based margin between cars; the integration the training
//! environments do not run refused.

mod support;

use std::path::Path;

use support::{cpmx_in, reference, scratch, unwrapped};

/// A spec with the paper's seed-1 actor from the lab's starts, in `fidelities` (YAML lines).
fn spec(dir: &Path, fidelities: &str, training: &str) -> std::path::PathBuf {
    let text = format!(
        "cpmx: 1
name: safety
map: {{file: maps/cpm.xml}}
vehicle: stdlib:sigmarl-2025
timing: {{dt: 0.1, steps: 40}}
agents: 3
policies:
  - {{name: paper, mlp: {{sigmarl: paper-at25/seed1}}, action: mean}}
initial_configurations:
  - from_poses: {{file: paper-at25/poses.csv, policies: {{paper: seed1}}}}
repetitions: 1
seed: 1
fidelities:
{fidelities}
planner:
  control_horizon: 4
  prediction_horizon: 12
  after_control_horizon: {{speed: hold, steering: linear-to-zero}}
metrics: {{extends: stdlib:at25, footprint: stdlib:mu-car}}
{training}"
    );
    let path = dir.join("safety.yaml");
    std::fs::write(&path, text).unwrap();
    path
}

/// A `training:` section of one iteration of the paper's setup in `fidelity`.
fn one_iteration_in(fidelity: &str) -> String {
    format!(
        "training:
  fidelity: {fidelity}
  scenario: stdlib:sigmarl-intersection-at25-paper
  reward: stdlib:sigmarl-at25-paper-reward
  algorithm: stdlib:mappo-sigmarl
  observation: stdlib:sigmarl-at25-paper
  iterations: 1
  seeds: [1]
"
    )
}

/// The rows of a run folder's `per_run.csv`, each cell by its column's name.
fn per_run(out: &Path) -> Vec<std::collections::HashMap<String, String>> {
    let text = std::fs::read_to_string(out.join("per_run.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    lines
        .map(|line| {
            header
                .iter()
                .map(|h| h.to_string())
                .zip(line.split(',').map(str::to_owned))
                .collect()
        })
        .collect()
}

/// `cpmx VERB SPEC --data REFERENCE [--out OUT]` in `dir`: its exit code, and its output with
/// miette's wrapping undone.
fn cpmx(dir: &Path, verb: &str, spec: &Path, out: Option<&Path>) -> (Option<i32>, String) {
    let reference = reference();
    let mut args = vec![
        verb,
        spec.to_str().unwrap(),
        "--data",
        reference.to_str().unwrap(),
    ];
    if let Some(out) = out {
        args.extend(["--out", out.to_str().unwrap()]);
    }
    let out = cpmx_in(dir, &args);
    let text = String::from_utf8_lossy(&out.stdout).into_owned() + &unwrapped(&out.stderr);
    (out.status.code(), text)
}

#[test]
fn the_filter_runs_between_the_actor_and_the_car_and_says_what_it_did() {
    let dir = scratch("safety-filter-run");
    let path = spec(
        &dir,
        "  sim: {control: direct, dynamics: kinematic}\n  sim-cbf: {control: direct, dynamics: kinematic, safety: stdlib:sigmarl-cbf}",
        "",
    );
    let out = dir.join("out");
    let (code, text) = cpmx(&dir, "run", &path, Some(&out));
    assert_eq!(code, Some(0), "{text}");
    let run = |fidelity: &str| -> (String, String) {
        let folder = out.join(format!("runs/{fidelity}/paper/init1/rep1"));
        (
            std::fs::read_to_string(folder.join("metrics.json")).unwrap(),
            std::fs::read_to_string(folder.join("trajectory.csv")).unwrap(),
        )
    };
    let (filtered_metrics, filtered) = run("sim-cbf");
    let (plain_metrics, plain) = run("sim");
    assert!(
        filtered_metrics.contains("safety filter (CBF): "),
        "{filtered_metrics}"
    );
    assert!(
        filtered_metrics.contains("of 120 agent-steps changed"),
        "{filtered_metrics}"
    );
    assert!(!plain_metrics.contains("safety filter"), "{plain_metrics}");
    // The filter changes the actions, so the cars drive otherwise.
    assert_ne!(filtered, plain);
    // per_run.csv counts it, for the filtered runs only.
    for row in per_run(&out) {
        if row["fidelity"] == "sim-cbf" {
            assert_eq!(
                row["safety.agent_steps"].parse::<f64>().unwrap(),
                120.0,
                "{row:?}"
            );
            assert!(row["safety.changed"].parse::<f64>().unwrap() > 0.0, "{row:?}");
            assert!(
                !row.contains_key("safety.solve_s"),
                "timed only when asked: {row:?}"
            );
        } else {
            assert_eq!(row["safety.agent_steps"], "", "{row:?}");
        }
    }
    // `--timing` adds the filter's time, the same trajectories.
    let timed = dir.join("timed");
    let reference = reference();
    let output = cpmx_in(
        &dir,
        &[
            "run",
            path.to_str().unwrap(),
            "--data",
            reference.to_str().unwrap(),
            "--out",
            timed.to_str().unwrap(),
            "--timing",
        ],
    );
    assert!(output.status.success(), "{}", unwrapped(&output.stderr));
    let row = per_run(&timed)
        .into_iter()
        .find(|r| r["fidelity"] == "sim-cbf")
        .unwrap();
    assert!(row["safety.solve_s"].parse::<f64>().unwrap() > 0.0, "{row:?}");
    assert!(
        row["safety.largest_solve_us"].parse::<f64>().unwrap() > 0.0,
        "{row:?}"
    );
    let timed_trajectory =
        std::fs::read_to_string(timed.join("runs/sim-cbf/paper/init1/rep1/trajectory.csv")).unwrap();
    assert_eq!(timed_trajectory, filtered);
}

#[test]
fn a_bad_speed_range_is_refused() {
    let dir = scratch("safety-filter-refused");
    let path = spec(
        &dir,
        "  sim-cbf: {control: direct, dynamics: kinematic, safety: {cbf: {circles: 3, circle_radius_m: 0.05, \
         difference_step_m: 0.02, gain: 0.1, weights: {acceleration: 30, steering_rate: 1}, \
         acceleration_limit_mps2: 40, steering_rate_limit_radps: 40, speed_range_mps: [1.0, -0.5], max_steering_deg: 45}}}",
        "",
    );
    let (code, text) = cpmx(&dir, "validate", &path, None);
    assert_eq!(code, Some(1), "{text}");
    assert!(text.contains("`speed_range_mps` is [1, -0.5]"), "{text}");
}

#[test]
fn the_papers_actors_that_collide_from_the_labs_starts_are_kept_apart_by_the_filter_in_sim_and_twin() {
    let dir = scratch("safety-filter-agents");
    let path = spec(
        &dir,
        "  sim: {control: direct, dynamics: kinematic}\n  \
         sim-cbf: {control: direct, dynamics: kinematic, safety: stdlib:sigmarl-cbf}\n  \
         twin: {control: trajectory, dynamics: stdlib:mu-car-greybox, sensing: stdlib:cpm-ips, actuation: {delay_ms: 80}}\n  \
         twin-cbf: {control: trajectory, dynamics: stdlib:mu-car-greybox, sensing: stdlib:cpm-ips, actuation: {delay_ms: 80}, \
         safety: stdlib:sigmarl-cbf}\n  \
         sim-mtv-cbf: {control: direct, dynamics: kinematic, safety: {extends: stdlib:sigmarl-cbf, \
         cbf: {agents: {range_m: 1.0, predictor: sigmarl-published/checkpoints/ecc25/sm_predictor.pth}}}}",
        "",
    );
    // The paper's three actors, each from its own lab runs' starts, for the whole 18 s.
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace(
            "  - {name: paper, mlp: {sigmarl: paper-at25/seed1}, action: mean}",
            "  - {name: seed1, mlp: {sigmarl: paper-at25/seed1}, action: mean}\n  \
             - {name: seed2, mlp: {sigmarl: paper-at25/seed2}, action: mean}\n  \
             - {name: seed3, mlp: {sigmarl: paper-at25/seed3}, action: mean}",
        )
        .replace(
            "from_poses: {file: paper-at25/poses.csv, policies: {paper: seed1}}",
            "from_poses: {file: paper-at25/poses.csv}",
        )
        .replace("steps: 40", "steps: 180")
        .replace("repetitions: 1", "repetitions: 3");
    std::fs::write(&path, text).unwrap();
    let out = dir.join("out");
    let (code, text) = cpmx(&dir, "run", &path, Some(&out));
    assert_eq!(code, Some(0), "{text}");
    let rows = per_run(&out);
    let (mut collisions, mut runs, mut kept) = (std::collections::BTreeMap::new(), 0, 0.0);
    let mut colliding_sim_runs = 0;
    for row in &rows {
        let run_events = row["a2a_events"].parse::<f64>().unwrap();
        *collisions.entry(row["fidelity"].clone()).or_insert(0.0) += run_events;
        colliding_sim_runs += usize::from(row["fidelity"] == "sim" && run_events > 0.0);
        if row["fidelity"].ends_with("-cbf") {
            runs += 1;
            kept += row["safety.kept_apart"].parse::<f64>().unwrap();
        }
    }
    assert_eq!(runs, 81);
    assert!(kept > 0.0, "the rows between the cars never held");
    // docs/specs.md: "collide in 4 of their 27 sim runs".
    assert_eq!(colliding_sim_runs, 4, "{rows:?}");
    assert!(collisions["twin"] > 0.0, "{collisions:?}");
    // Through the planner of the twin too: the filter changes every rolled-out step.
    // And with SigmaRL's MTV-based margin between the cars (ECC 2025's network).
    assert_eq!(
        collisions["sim-cbf"] + collisions["twin-cbf"] + collisions["sim-mtv-cbf"],
        0.0,
        "{collisions:?}"
    );
}

#[test]
fn a_margin_network_that_is_missing_or_is_no_margin_network_is_refused() {
    let dir = scratch("safety-filter-predictor");
    let fidelity = |file: &str| {
        format!(
            "  sim-mtv: {{control: direct, dynamics: kinematic, safety: {{extends: stdlib:sigmarl-cbf, \
             cbf: {{agents: {{range_m: 1.0, predictor: {file}}}}}}}}}"
        )
    };
    let path = spec(&dir, &fidelity("ecc25/no_such_predictor.pth"), "");
    let (code, text) = cpmx(&dir, "validate", &path, None);
    assert_eq!(code, Some(1), "{text}");
    assert!(text.contains("ecc25/no_such_predictor.pth"), "{text}");
    assert!(text.contains("safety.yaml:"), "located: {text}");
    // An actor's checkpoint is a torch file, but not the margin network.
    let path = spec(&dir, &fidelity("paper-at25/seed1/final_policy.pth"), "");
    let out = dir.join("out");
    let (code, text) = cpmx(&dir, "run", &path, Some(&out));
    assert_ne!(code, Some(0), "{text}");
    assert!(text.contains("the safety layer's margin network"), "{text}");
}

#[test]
fn the_itsc25_policy_in_sigmarl_1_4_0s_loop_touches_the_edge_where_sigmarls_own_code_does() {
    // research/itsc25-sigmarl.md: from these ten starts SigmaRL 1.4.0's own code, filter on,
    // crosses the road's edge on path 5 only; in the later loop (one Euler step) cpmx crossed
    // it on seven paths.
    let dir = scratch("safety-filter-itsc25");
    let itsc25 = support::root().join("experiments/safety-filter-itsc25.yaml");
    let out = dir.join("out");
    let (code, text) = cpmx(&dir, "run", &itsc25, Some(&out));
    assert_eq!(code, Some(0), "{text}");
    let rows = per_run(&out);
    let touching = |which: &str| -> Vec<&str> {
        rows.iter()
            .filter(|r| r["fidelity"] == which && r["cra_l"].parse::<f64>().unwrap() > 0.0)
            .map(|r| r["initial_configuration"].as_str())
            .collect()
    };
    assert_eq!(touching("sim").len(), 10);
    assert_eq!(touching("sim-cbf"), ["path5"]);
    assert!(touching("sim-cbf-margin-7cm").is_empty());

    // The integration over the step is not in the training environment.
    let path = spec(
        &dir,
        "  sim-rk4: {control: direct, dynamics: kinematic-rk4}",
        &one_iteration_in("sim-rk4"),
    );
    let (code, text) = cpmx(&dir, "train", &path, Some(&dir.join("train")));
    assert_ne!(code, Some(0), "{text}");
    assert!(text.contains("integrates with `kinematic-rk4`"), "{text}");
}
