//! The `training:` section: presets expand to SigmaRL's setup, the plan lists one training
//! run per seed, and each class of mistake gets a located diagnostic (snapshot-tested).

#[macro_use]
mod common;

use cpmx_spec::model::{Fidelity, Lookahead, PathSetName, ResetScopeName, ValueLoss};
use cpmx_spec::{CheckContext, InterpreterChecks, Resources, Spec, SpecDiagnostic};

/// Stands in for the interpreter: runs everything, checks nothing more.
struct Everything;

impl InterpreterChecks for Everything {
    fn cannot_run(&self, _: &Fidelity) -> Option<String> {
        None
    }
    fn check(&self, _: &Spec, _: &Resources, _: &mut CheckContext<'_>) {}
}

const VALID: &str = "\
cpmx: 1
name: demo
map: stdlib:intersection
timing: {dt: 0.1, steps: 20}
agents: 2
policies:
  - {name: base, builtin: lane-follow}
initial_configurations:
  - sample: {count: 1, seed: 3, min_gap: 0.5}
repetitions: 1
seed: 5
fidelities:
  sim: {control: direct, dynamics: kinematic}
  lab: {driver: cpm-dds, domain: 21, vehicle_ids: [1, 2]}
planner: {control_horizon: 4, prediction_horizon: 12}
training:
  scenario: stdlib:sigmarl-intersection
  reward: stdlib:sigmarl-reward
  algorithm: stdlib:mappo-sigmarl
  iterations: 1000
  seeds: [1, 2, 3]
";

fn check(text: &str) -> Result<cpmx_spec::CheckedSpec, Vec<SpecDiagnostic>> {
    common::check_with(text, &Everything)
}

/// The valid spec with `from` replaced by `to` (which must occur).
fn edit(from: &str, to: &str) -> String {
    common::edit(VALID, from, to)
}

/// Checks `text`, asserts the first diagnostic's place and returns the rendering.
fn diagnose(text: &str, line: usize, column: usize) -> String {
    common::rejected_at(check(text), line, column)
}

/// A spec that only trains: no key of the run matrix.
const TRAINS_ONLY: &str = "\
cpmx: 1
name: just-training
map: stdlib:intersection
training:
  scenario: stdlib:sigmarl-intersection
  reward: stdlib:sigmarl-reward
  algorithm: stdlib:mappo-sigmarl
  iterations: 100
  seeds: [4]
";

#[test]
fn a_spec_may_only_train_in_sigmarls_simulation() {
    let checked = check(TRAINS_ONLY).unwrap();
    assert!(checked.plan().is_empty());
    let training = checked.training_plan();
    assert_eq!(training.len(), 1);
    assert_eq!(training[0].fidelity, "sim");
    assert!((checked.spec.timing.dt - 0.1).abs() < 1e-12);
    match &checked.spec.fidelities["sim"] {
        Fidelity::Simulated(sim) => assert_eq!(sim.control, cpmx_spec::model::Control::Direct),
        Fidelity::Lab(_) => panic!("sim is SigmaRL's simulation"),
    }
    // Naming the default, as the language reference writes it, is the same spec.
    let named = check(&TRAINS_ONLY.replace("training:\n", "training:\n  fidelity: sim\n")).unwrap();
    assert_eq!(named.spec.fidelities, checked.spec.fidelities);
    assert_eq!(named.training_plan(), training);
    // Another name needs the spec to define it.
    let other = TRAINS_ONLY.replace("training:\n", "training:\n  fidelity: sim-mpc\n");
    let problems = cpmx_spec::render(&check(&other).expect_err("sim-mpc is not defined"), false);
    assert!(problems.contains("which the spec does not define"), "{problems}");
    // One key of the matrix makes it an experiment again, which needs all of them.
    let partial = TRAINS_ONLY.replace("training:\n", "agents: 2\ntraining:\n");
    let problems = cpmx_spec::render(&check(&partial).expect_err("matrix keys missing"), false);
    for key in [
        "policies",
        "initial_configurations",
        "repetitions",
        "seed",
        "fidelities",
        "timing",
    ] {
        assert!(problems.contains(&format!("needs `{key}`")), "{key}: {problems}");
    }
    // Without `training:` nothing is filled in.
    let bare = TRAINS_ONLY[..TRAINS_ONLY.find("training:").unwrap()].to_owned() + "description: x\n";
    let problems = cpmx_spec::render(&check(&bare).expect_err("not a spec"), false);
    assert!(problems.contains("needs `timing`"), "{problems}");
}

#[test]
fn the_presets_are_sigmarls_setup_and_the_plan_has_one_run_per_seed() {
    let checked = check(VALID).unwrap();
    let t = checked.spec.training.as_ref().unwrap();
    assert_eq!(t.fidelity.single(), Some("sim"));
    let s = &t.scenario;
    assert_eq!(s.path_set, Some(PathSetName::Intersection));
    assert_eq!((s.agents, s.envs, s.episode_steps), (4, 32, 128));
    assert_eq!(
        (s.start.first_index, s.start.speed_mps, s.start.min_gap_m),
        (3, [0.0, 1.0], 0.36696082897224874)
    );
    assert_eq!(s.reset.on_collision, ResetScopeName::Environment);
    assert_eq!(s.reset.on_entry_or_exit_line, ResetScopeName::Agent);
    let r = &t.reward;
    let progress = r.progress.as_ref().unwrap();
    assert_eq!((progress.weight, progress.points, progress.spacing), (0.1, 3, 2));
    assert_eq!(r.near_boundary.as_ref().unwrap().within_m, 0.02);
    assert_eq!(r.near_agents_ttc.as_ref().unwrap().horizon_s, 3.75);
    assert_eq!(
        (r.collide_agents, r.collide_boundary, r.clamp),
        (Some(-2.0), Some(-2.0), Some([-1.0, 1.0]))
    );
    let m = &t.algorithm.mappo;
    assert_eq!((m.frames_per_iteration, m.minibatch, m.epochs), (4096, 512, 30));
    assert_eq!(
        (m.lr, m.lr_min, m.clip, m.gamma, m.lambda),
        (1e-4, 1e-5, 0.2, 0.99, 0.9)
    );
    assert_eq!(
        (m.entropy, m.max_grad_norm, m.value_loss),
        (5e-4, 1.0, ValueLoss::SmoothL1)
    );
    assert_eq!(t.network.hidden, vec![256, 256, 256]);
    assert_eq!(
        t.observation.observed_agents, 2,
        "observation defaults to stdlib:sigmarl"
    );
    let plan = checked.training_plan();
    let keys: Vec<&str> = plan.iter().map(|p| p.key.as_str()).collect();
    assert_eq!(keys, ["train/1", "train/2", "train/3"]);
    // The run matrix does not change.
    assert_eq!(checked.plan().len(), 2);
}

#[test]
fn overrides_and_trained_policies() {
    let text = edit(
        "  reward: stdlib:sigmarl-reward\n",
        "  reward: {extends: stdlib:sigmarl-reward, clamp: [-2, 2]}\n",
    )
    .replace(
        "  - {name: base, builtin: lane-follow}\n",
        "  - {name: base, builtin: lane-follow}\n  - {name: seed2, mlp: {trained: {seed: 2}}}\n",
    );
    let checked = check(&text).unwrap();
    assert_eq!(
        checked.spec.training.as_ref().unwrap().reward.clamp,
        Some([-2.0, 2.0])
    );
    // Not trained yet: a warning, and the policy has no weights.
    assert_eq!(checked.warnings.len(), 1);
    assert!(checked.warnings[0].to_string().contains("seed 2"));
    assert_eq!(checked.resources.weights[1], None);
    let trained = checked.spec.policies[1]
        .mlp
        .as_ref()
        .unwrap()
        .trained
        .as_ref()
        .unwrap();
    assert_eq!(
        trained.relative_file("demo", checked.spec.training.as_ref()),
        "out/demo-train/2/actor.safetensors"
    );
}

case!(
    unknown_reward_term,
    edit(
        "  reward: stdlib:sigmarl-reward\n",
        "  reward: {extends: stdlib:sigmarl-reward, speed_bonus: 0.1}\n"
    ),
    18,
    44
);
case!(
    scenario_without_paths,
    edit(
        "  scenario: stdlib:sigmarl-intersection\n",
        "  scenario: {agents: 4, envs: 8, episode_steps: 128, start: {first_index: 3, speed_mps: [0, 1], min_gap_m: 0.4},\n    reset: {on_collision: environment, on_entry_or_exit_line: agent}}\n"
    ),
    17,
    3
);
case!(
    negative_learning_rate,
    edit(
        "  algorithm: stdlib:mappo-sigmarl\n",
        "  algorithm: {extends: stdlib:mappo-sigmarl, mappo: {lr: -1.0e-4}}\n"
    ),
    19,
    58
);
case!(
    lr_min_above_lr,
    edit(
        "  algorithm: stdlib:mappo-sigmarl\n",
        "  algorithm: {extends: stdlib:mappo-sigmarl, mappo: {lr_min: 1.0e-3}}\n"
    ),
    19,
    62
);
case!(
    minibatch_above_frames,
    edit(
        "  algorithm: stdlib:mappo-sigmarl\n",
        "  algorithm: {extends: stdlib:mappo-sigmarl, mappo: {minibatch: 8192}}\n"
    ),
    19,
    65
);
case!(
    lab_fidelity,
    edit("training:\n", "training:\n  fidelity: lab\n"),
    17,
    13
);
case!(
    unknown_fidelity,
    edit("training:\n", "training:\n  fidelity: simm\n"),
    17,
    13
);
case!(
    trained_seed_not_trained,
    edit(
        "  - {name: base, builtin: lane-follow}\n",
        "  - {name: base, builtin: lane-follow}\n  - {name: s9, mlp: {trained: {seed: 9}}}\n"
    ),
    8,
    38
);
case!(
    duplicate_seed,
    edit("seeds: [1, 2, 3]", "seeds: [1, 2, 1]"),
    21,
    17
);
case!(
    empty_near_agents_ramp,
    edit(
        "  reward: stdlib:sigmarl-reward\n",
        "  reward: {extends: stdlib:sigmarl-reward, near_agents: {penalty: -0.2, from_m: 0.3, to_m: 0.2}}\n"
    ),
    18,
    92
);
case!(
    steering_change_threshold_beyond_the_limit,
    edit(
        "  reward: stdlib:sigmarl-reward\n",
        "  reward: {extends: stdlib:sigmarl-reward, steering_change: {penalty: -0.02, threshold_rad: 0.6}}\n"
    ),
    18,
    93
);
case!(
    time_without_progress_points,
    edit(
        "  reward: stdlib:sigmarl-reward\n",
        "  reward: {collide_boundary: -1, time: {weight: 0.05}}\n"
    ),
    18,
    34
);

#[test]
fn the_at25_presets_are_sigmarls_setup_when_the_papers_policies_were_trained() {
    let text = edit(
        "  scenario: stdlib:sigmarl-intersection\n  reward: stdlib:sigmarl-reward\n",
        "  scenario: stdlib:sigmarl-intersection-at25\n  reward: stdlib:sigmarl-at25-reward\n",
    );
    let checked = check(&text).unwrap();
    let t = checked.spec.training.as_ref().unwrap();
    let start = &t.scenario.start;
    assert_eq!(start.first_index, 6);
    // 1.2 x the µCar's diagonal.
    assert!((start.min_gap_m - 1.2 * 0.22f64.hypot(0.107)).abs() < 1e-12);
    let r = &t.reward;
    assert_eq!((r.collide_agents, r.collide_boundary), (Some(-1.0), Some(-1.0)));
    assert!(r.near_agents_ttc.is_none() && r.speed.is_none());
    let boundary = r.near_boundary.as_ref().unwrap();
    assert_eq!(boundary.shape, cpmx_spec::model::RampShape::Exponential);
    // SigmaRL's thresholds from the lane width (0.15 m) and the vehicle: 0.9 x (0.15 - W) / 2,
    // (L + W) / 2 to L + W, (0.15 - W) / 2.
    assert!((boundary.within_m - 0.9 * (0.15 - 0.107) / 2.0).abs() < 1e-12);
    let agents = r.near_agents.as_ref().unwrap();
    assert!((agents.from_m - (0.22 + 0.107) / 2.0).abs() < 1e-12);
    assert!((agents.to_m - (0.22 + 0.107)).abs() < 1e-12);
    assert!((r.centre_line.as_ref().unwrap().scale_m - (0.15 - 0.107) / 2.0).abs() < 1e-12);
    assert_eq!(r.velocity_to_points.as_ref().unwrap().against_path_factor, 2.0);
    assert_eq!(r.time.as_ref().unwrap().weight, 0.05);
    assert!((r.steering_change.as_ref().unwrap().threshold_rad - 10f64.to_radians()).abs() < 1e-15);
}
case!(
    training_fidelity_listed_twice,
    edit("training:\n", "training:\n  fidelity: [sim, sim]\n"),
    17,
    19
);
case!(
    trained_policy_of_a_spec_that_trains_in_several_fidelities,
    edit("training:\n", "training:\n  fidelity: [sim, mpc]\n")
        .replace("  sim: {control: direct, dynamics: kinematic}\n", "  sim: {control: direct, dynamics: kinematic}\n  mpc: {control: trajectory, dynamics: kinematic}\n")
        .replace(
            "  - {name: base, builtin: lane-follow}\n",
            "  - {name: base, builtin: lane-follow}\n  - {name: s2, mlp: {trained: {seed: 2}}}\n"
        ),
    8,
    22
);
case!(
    trained_in_a_fidelity_that_is_not_trained,
    edit(
        "  - {name: base, builtin: lane-follow}\n",
        "  - {name: base, builtin: lane-follow}\n  - {name: s2, mlp: {trained: {seed: 2, fidelity: lab}}}\n"
    ),
    8,
    51
);
case!(
    training_in_a_trajectory_fidelity_without_a_planner,
    edit("training:\n", "training:\n  fidelity: mpc\n")
        .replace("  sim: {control: direct, dynamics: kinematic}\n", "  sim: {control: direct, dynamics: kinematic}\n  mpc: {control: trajectory, dynamics: kinematic}\n")
        .replace("planner: {control_horizon: 4, prediction_horizon: 12}\n", ""),
    14,
    3
);

#[test]
fn a_spec_trains_in_several_fidelities_one_folder_each() {
    let text = edit("training:\n", "training:\n  fidelity: [sim, mpc]\n")
        .replace(
            "  sim: {control: direct, dynamics: kinematic}\n",
            "  sim: {control: direct, dynamics: kinematic}\n  mpc: {control: trajectory, dynamics: kinematic}\n",
        )
        .replace(
            "  - {name: base, builtin: lane-follow}\n",
            "  - {name: base, builtin: lane-follow}\n  - {name: s2, mlp: {trained: {seed: 2, fidelity: mpc}}}\n",
        );
    let checked = check(&text).unwrap();
    let plan = checked.training_plan();
    let keys: Vec<(&str, &str)> = plan
        .iter()
        .map(|p| (p.key.as_str(), p.fidelity.as_str()))
        .collect();
    assert_eq!(
        keys,
        [
            ("train/sim/1", "sim"),
            ("train/sim/2", "sim"),
            ("train/sim/3", "sim"),
            ("train/mpc/1", "mpc"),
            ("train/mpc/2", "mpc"),
            ("train/mpc/3", "mpc")
        ]
    );
    let training = checked.spec.training.as_ref();
    let trained = checked.spec.policies[1]
        .mlp
        .as_ref()
        .unwrap()
        .trained
        .as_ref()
        .unwrap();
    assert_eq!(
        trained.relative_file("demo", training),
        "out/demo-train/mpc/2/actor.safetensors"
    );
    assert_eq!(trained.trained_in(training), Some("mpc"));
}

/// An actor the spec trains is observed as it was trained: without `observation:` of its own,
/// the policy takes the training section's (here with the steering angles).
#[test]
fn a_trained_actor_is_observed_as_it_was_trained() {
    let text = edit(
        "  reward: stdlib:sigmarl-reward\n",
        "  reward: stdlib:sigmarl-reward\n  observation: {extends: stdlib:sigmarl, steering: true}\n",
    )
    .replace(
        "  - {name: base, builtin: lane-follow}\n",
        "  - {name: base, builtin: lane-follow}\n  - {name: s2, mlp: {trained: {seed: 2}}}\n",
    );
    let checked = check(&text).unwrap();
    let observation = checked.spec.policies[1].observation.as_ref().unwrap();
    assert!(observation.steering, "the training observation");
    assert!(
        checked.spec.policies[0].observation.is_none(),
        "a baseline observes nothing"
    );
}

#[test]
fn the_lookahead_is_the_actor_unless_held_and_concerns_only_the_planner() {
    let checked = check(VALID).unwrap();
    assert_eq!(checked.spec.training.unwrap().lookahead, Lookahead::Actor);
    // Training in sim only: holding changes nothing, and the spec says so at the key.
    let held = edit("  iterations: 1000\n", "  lookahead: hold\n  iterations: 1000\n");
    let checked = check(&held).unwrap();
    assert_eq!(checked.spec.training.as_ref().unwrap().lookahead, Lookahead::Hold);
    assert_eq!(checked.warnings.len(), 1);
    assert_eq!((checked.warnings[0].line, checked.warnings[0].column), (20, 3));
    insta::assert_snapshot!(cpmx_spec::render(&checked.warnings, false));
    // With a fidelity that plans, it is what the key is for.
    let planning = held
        .replace(
            "  lab: {driver",
            "  sim-mpc: {control: trajectory, dynamics: kinematic}\n  lab: {driver",
        )
        .replace("training:\n", "training:\n  fidelity: [sim, sim-mpc]\n");
    assert!(check(&planning).unwrap().warnings.is_empty());
    // Held through an actuation delay, the training environment punishes the delay far more
    // than driving does: said at the key, with what to do instead; a delay of 0 is no delay.
    let delayed = |delay: &str| {
        held.replace(
            "  lab: {driver",
            &format!(
                "  twin: {{control: trajectory, dynamics: kinematic, actuation: {{delay_ms: {delay}}}}}\n  lab: {{driver"
            ),
        )
        .replace("training:\n", "training:\n  fidelity: [sim, twin]\n")
    };
    let checked = check(&delayed("{uniform: [40, 120]}")).unwrap();
    assert_eq!(checked.warnings.len(), 1);
    insta::assert_snapshot!(cpmx_spec::render(&checked.warnings, false));
    assert!(check(&delayed("0")).unwrap().warnings.is_empty());
    assert!(
        check(&delayed("80").replace("  lookahead: hold\n", ""))
            .unwrap()
            .warnings
            .is_empty()
    );
    // Anything else is refused where it is written.
    insta::assert_snapshot!(diagnose(
        &edit(
            "  iterations: 1000\n",
            "  lookahead: greedy\n  iterations: 1000\n"
        ),
        20,
        14
    ));
}

/// The valid spec with a policy that names the actor of an iteration (`iteration`, and
/// `extra` after it in the same `trained:` map) and the training section's `keep`.
fn naming_iteration(iteration: u64, extra: &str, keep: &str) -> String {
    edit("  iterations: 1000\n", &format!("  iterations: 1000\n{keep}")).replace(
        "  - {name: base, builtin: lane-follow}\n",
        &format!(
            "  - {{name: base, builtin: lane-follow}}\n  - {{name: kept, mlp: {{trained: {{seed: 2, iteration: {iteration}{extra}}}}}}}\n"
        ),
    )
}

#[test]
fn a_policy_names_an_actor_the_training_keeps_by_iteration() {
    let checked = check(&naming_iteration(150, "", "  keep_actors_every: 50\n")).unwrap();
    let training = checked.spec.training.as_ref().unwrap();
    let kept = training.kept_actors();
    assert!(kept.keeps(150) && kept.keeps(50) && !kept.keeps(149) && !kept.keeps(1));
    let trained = checked.spec.policies[1]
        .mlp
        .as_ref()
        .unwrap()
        .trained
        .as_ref()
        .unwrap();
    assert_eq!(
        trained.relative_file("demo", Some(training)),
        "out/demo-train/2/actors/150.safetensors"
    );
}

case!(
    trained_iteration_without_kept_actors,
    naming_iteration(150, "", ""),
    8,
    54
);
case!(
    trained_iteration_between_kept_actors,
    naming_iteration(150, "", "  keep_actors_every: 100\n"),
    8,
    54
);
case!(
    trained_iteration_when_none_is_kept,
    naming_iteration(500, "", "  keep_actors_every: 2000\n"),
    8,
    54
);
case!(
    trained_iteration_beyond_the_training,
    naming_iteration(1500, "", "  keep_actors_every: 100\n"),
    8,
    54
);
case!(
    trained_iteration_and_the_last_actor,
    naming_iteration(150, ", which: last", "  keep_actors_every: 50\n"),
    8,
    54
);
