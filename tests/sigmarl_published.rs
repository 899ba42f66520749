//! The models SigmaRL's authors published at tag 1.2.0, in that release's loop. XP-MARL's
//! (`sigmarl-published/checkpoints/icra25`): the shipped experiment runs from the data path, a
//! random ranking is a stream of the run (same seed, same trajectories; another order than
//! none), and `priority:` is refused with a located diagnostic wherever it cannot mean what it
//! says. ITSC 2024's (`.../itsc24`) on an unseen scenario, with their sensor noise.

mod support;

use std::path::{Path, PathBuf};

use support::{cpmx_in, reference, root, scratch, unwrapped};

/// The shipped spec with `steps` steps, `count` drawn starts (repetitions) and `policies`
/// instead of its own (YAML list items; the shipped ones when `None`), written into `dir`.
fn variant(dir: &Path, steps: u32, count: u32, policies: Option<&str>) -> PathBuf {
    let shipped = std::fs::read_to_string(root().join("experiments/xp-marl.yaml")).unwrap();
    let mut text = shipped
        .replace("steps: 1199", &format!("steps: {steps}"))
        .replace("repetitions: 32", &format!("repetitions: {count}"));
    assert_ne!(text, shipped, "the shipped spec's steps and repetitions");
    if let Some(policies) = policies {
        let start = text.find("policies:\n").unwrap();
        let end = text.find("initial_configurations:").unwrap();
        text.replace_range(start..end, &format!("policies:\n{policies}"));
    }
    let path = dir.join("xp-marl.yaml");
    std::fs::write(&path, text).unwrap();
    path
}

/// `cpmx COMMAND SPEC --data REFERENCE [ARGS]` in `dir`: exit code and unwrapped stderr.
fn cpmx_spec(dir: &Path, command: &str, spec: &Path, args: &[&str]) -> (Option<i32>, String, String) {
    let reference = reference();
    let mut all = vec![
        command,
        spec.to_str().unwrap(),
        "--data",
        reference.to_str().unwrap(),
    ];
    all.extend_from_slice(args);
    let out = cpmx_in(dir, &all);
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        unwrapped(&out.stderr),
    )
}

#[test]
fn the_five_models_run_and_a_random_ranking_is_the_runs_stream() {
    let dir = scratch("xp-marl-run");
    let spec = variant(&dir, 40, 2, None);
    let (code, _, stderr) = cpmx_spec(&dir, "run", &spec, &["--out", "a"]);
    assert_eq!(code, Some(0), "{stderr}");
    let trajectory = |folder: &str, policy: &str| {
        std::fs::read(
            dir.join(folder)
                .join(format!("runs/sim/{policy}/cpm-entire/rep1/trajectory.csv")),
        )
        .unwrap()
    };
    for policy in [
        "m1-xp-marl",
        "m2-baseline",
        "m3-opponent-modelling",
        "m5-xp-marl-noise",
    ] {
        assert!(!trajectory("a", policy).is_empty());
    }
    // The random order is drawn from the run's own stream: a second run gives the same
    // trajectories, and they are not those of the unranked model.
    let (code, _, stderr) = cpmx_spec(&dir, "run", &spec, &["--out", "b", "--only", "policy=m4-random"]);
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(trajectory("a", "m4-random"), trajectory("b", "m4-random"));
    assert_ne!(trajectory("a", "m4-random"), trajectory("a", "m4-unranked"));
}

#[test]
fn priority_is_refused_where_it_cannot_rank() {
    let dir = scratch("xp-marl-refused");
    let icra = "sigmarl-published/checkpoints/icra25";
    let cases = [
        // An XP-MARL actor without a ranking.
        (
            format!("  - {{name: m1, mlp: {{sigmarl: {icra}/M1, tag: 1.2.0}}}}\n"),
            "was trained with XP-MARL's action propagation (`is_using_prioritized_marl: true`)",
        ),
        // A ranking for an actor that observes no actions, or tentative ones.
        (
            format!("  - {{name: m2, mlp: {{sigmarl: {icra}/M2, tag: 1.2.0}}, priority: random}}\n"),
            "`priority` orders the agents of `m2`, whose actor observes no actions of its neighbours",
        ),
        (
            format!("  - {{name: m3, mlp: {{sigmarl: {icra}/M3, tag: 1.2.0}}, priority: none}}\n"),
            "observes its neighbours' tentative actions (opponent modelling)",
        ),
        // A learned ranking from a run that saved none (random priorities).
        (
            format!(
                "  - {{name: m4, mlp: {{sigmarl: {icra}/M4, tag: 1.2.0}}, priority: {{sigmarl: {icra}/M4}}}}\n"
            ),
            "holds no `reward<r>_priority_policy.pth`",
        ),
        // A ranking for a policy that is no SigmaRL checkpoint.
        (
            "  - {name: base, builtin: lane-follow, priority: random}\n".to_owned(),
            "`priority` ranks the agents of a SigmaRL checkpoint trained with XP-MARL's action propagation",
        ),
    ];
    for (policies, expected) in cases {
        let spec = variant(&dir, 10, 1, Some(&policies));
        let (code, _, stderr) = cpmx_spec(&dir, "validate", &spec, &[]);
        assert_eq!(code, Some(1), "{policies}{stderr}");
        assert!(stderr.contains(expected), "{policies}: {stderr}");
        assert!(stderr.contains("xp-marl.yaml:"), "located: {stderr}");
    }
}

/// The models act every 0.05 s, which is no whole number of the lab's vehicle periods
/// (0.02 s): a simulated planning fidelity decides at the first period at or after each step
/// (0.06 s and 0.04 s in turn; validate warns), while the lab, and a training through such a
/// fidelity, are refused before any run, at `timing.dt`.
#[test]
fn a_planning_fidelity_at_the_models_step_decides_on_the_vehicles_periods() {
    let dir = scratch("xp-marl-twin");
    let spec = variant(&dir, 6, 1, None);
    // A planning fidelity replaces no cars (SigmaRL's testing mode is the sim's).
    let sim = "  sim: {control: direct, dynamics: kinematic-vmas}\n";
    let with_twin = "  sim: {control: direct, dynamics: kinematic-vmas}\n  \
                     twin: {control: trajectory, dynamics: stdlib:mu-car-greybox}\n\
                     planner: {control_horizon: 4, prediction_horizon: 12, after_control_horizon: {speed: hold, steering: linear-to-zero}}\n";
    let planning = std::fs::read_to_string(&spec)
        .unwrap()
        .replace("on_collision: replace-agent", "on_collision: continue")
        .replace(sim, with_twin);
    std::fs::write(&spec, &planning).unwrap();
    let (code, _, stderr) = cpmx_spec(&dir, "validate", &spec, &[]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("`timing.dt: 0.05` is no multiple of the vehicles' 0.02 s control period: in fidelity `twin` the policy decides at the first period at or after each step"),
        "{stderr}"
    );
    let (code, _, stderr) = cpmx_spec(
        &dir,
        "run",
        &spec,
        &["--out", "out", "--only", "policy=m2-baseline"],
    );
    assert_eq!(code, Some(0), "{stderr}");
    let trajectory =
        std::fs::read_to_string(dir.join("out/runs/twin/m2-baseline/cpm-entire/rep1/trajectory.csv"))
            .unwrap();
    let mut times: Vec<&str> = trajectory
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap())
        .collect();
    times.dedup();
    let times: Vec<f64> = times.iter().map(|t| t.parse().unwrap()).collect();
    assert_eq!(
        times,
        [0.0, 0.06, 0.1, 0.16, 0.2, 0.26],
        "decisions on the vehicles' periods"
    );
    // The lab acts on whole periods only.
    let lab = planning.replace(
        "  twin: {control: trajectory, dynamics: stdlib:mu-car-greybox}\n",
        "  twin: {control: trajectory, dynamics: stdlib:mu-car-greybox}\n  \
         lab: {driver: cpm-dds, domain: 21, vehicle_ids: [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15], interface: 127.0.0.1}\n",
    );
    std::fs::write(&spec, lab).unwrap();
    let (code, _, stderr) = cpmx_spec(&dir, "validate", &spec, &[]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("`timing.dt: 0.05` is no multiple of the vehicles' 0.02 s control period, which fidelity `lab` runs on"),
        "{stderr}"
    );
    // A training steps its environments on whole periods: training through the twin is refused.
    let shipped = std::fs::read_to_string(root().join("experiments/transfer-twin.yaml")).unwrap();
    let training = dir.join("transfer-twin.yaml");
    std::fs::write(
        &training,
        shipped.replace("timing: {dt: 0.1,", "timing: {dt: 0.05,"),
    )
    .unwrap();
    let (code, _, stderr) = cpmx_spec(&dir, "validate", &training, &[]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("runs on (and the training steps through)"),
        "{stderr}"
    );
}

/// ITSC 2024's models on an unseen scenario (docs/maps.md's spec): those whose observation
/// cpmx makes (the bird's-eye view among them) run, with SigmaRL 1.2.0's sensor noise drawn
/// from the run's stream (same seed, same trajectory; another seed, another); the boundary
/// points are refused by name.
#[test]
fn itsc24_models_run_on_an_unseen_scenario_with_their_noise() {
    let dir = scratch("itsc24");
    let spec = |seed: u32, policies: &str| {
        let text = format!(
            "cpmx: 1\nname: unseen\nmap: {{sigmarl: roundabout_1}}\n\
             vehicle: {{length: 0.16, width: 0.08, wheelbase: 0.16, rear_axle: 0.08, max_steering_deg: 35, \
             max_steering_rate_deg_s: 900, accel: [-20, 20], max_speed: 1.0}}\n\
             timing: {{dt: 0.05, steps: 30}}\nagents: 8\npolicies:\n{policies}\
             initial_configurations:\n  - sample: {{count: 1, seed: 1, min_gap: 0.25}}\n\
             repetitions: 1\nseed: {seed}\nfidelities:\n  sim: {{control: direct, dynamics: kinematic-vmas}}\n"
        );
        let path = dir.join(format!("unseen-{seed}.yaml"));
        std::fs::write(&path, text).unwrap();
        path
    };
    let itsc = "sigmarl-published/checkpoints/itsc24";
    let runnable: String = ["M0", "M1", "M2", "M3", "M5"]
        .iter()
        .map(|m| {
            format!(
                "  - {{name: {}, mlp: {{sigmarl: {itsc}/{m}, tag: 1.2.0}}}}\n",
                m.to_lowercase()
            )
        })
        .collect();
    let trajectory = |seed: u32| {
        let out = format!("out-{seed}");
        let (code, _, stderr) = cpmx_spec(&dir, "run", &spec(seed, &runnable), &["--out", &out]);
        assert_eq!(code, Some(0), "{stderr}");
        std::fs::read(dir.join(out).join("runs/sim/m0/sample1/rep1/trajectory.csv")).unwrap()
    };
    let first = trajectory(1);
    std::fs::remove_dir_all(dir.join("out-1")).unwrap();
    assert_eq!(first, trajectory(1));
    assert_ne!(first, trajectory(2));
    let policies = format!("  - {{name: m, mlp: {{sigmarl: {itsc}/M4, tag: 1.2.0}}}}\n");
    let (code, _, stderr) = cpmx_spec(&dir, "validate", &spec(3, &policies), &[]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("`is_observe_distance_to_boundaries: false`"),
        "M4: {stderr}"
    );
}
