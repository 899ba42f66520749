//! Runs stepped in lock-step ([`crate::Engine::run_together`]) have, each, the bits they have
//! alone: the twin's sim-mpc and randomised runs mixed in one group, of several seeds and
//! starts, with a run that cannot start beside them; the paper's benchmark's runs of every
//! engine, whose policies of one actor share its network passes.

use std::path::{Path, PathBuf};

use cpmx_recording::Recording;
use cpmx_spec::{DataPath, RunPlan, SpecSource};

use crate::engine::{Engine, RunError, RunInputs};
use crate::{Experiment, SimEngine, TwinEngine};

const SPEC: &str = "\
cpmx: 1
name: lockstep
map: stdlib:intersection
timing: {dt: 0.1, steps: 30}
agents: 2
policies:
  - {name: baseline, builtin: lane-follow}
initial_configurations:
  - name: following
    agents:
      - {ref_path: 7, arc_length: 0.8}
      - {ref_path: 7, arc_length: 0.2}
  - name: turning
    agents:
      - {ref_path: 2, arc_length: 0.3}
      - {ref_path: 9, arc_length: 0.3}
repetitions: 2
seed: 11
fidelities:
  sim-mpc: {control: trajectory, dynamics: kinematic}
  twin-random:
    control: trajectory
    dynamics: stdlib:mu-car-greybox
    sensing: {extends: stdlib:cpm-ips, noise_position_m: {uniform: [0, 0.004]}}
    actuation: {delay_ms: {uniform: [40, 120]}}
planner: {control_horizon: 4, prediction_horizon: 12}
";

/// A checked spec's experiment and plans (`data`: the folders `--data` names).
fn experiment(name: &str, dir: &Path, text: String, data: &[PathBuf]) -> (Experiment, Vec<RunPlan>) {
    let source = SpecSource {
        name: name.into(),
        dir: dir.to_owned(),
        text,
    };
    let checked = cpmx_spec::check(&source, &DataPath::new(dir, data, None), &crate::BuildChecks)
        .unwrap_or_else(|d| panic!("{}", cpmx_spec::render(&d, false)));
    (Experiment::prepare(&checked).unwrap(), checked.plan())
}

/// The paper's benchmark (`experiments/at25.yaml`, its actors read from the reference data),
/// checked as `cpmx run --data ../shared/reference` checks it.
fn at25() -> (Experiment, Vec<RunPlan>) {
    let experiments = cpmx_testdata::checkout().join("experiments");
    let text = std::fs::read_to_string(experiments.join("at25.yaml")).unwrap();
    experiment("at25.yaml", &experiments, text, &[cpmx_testdata::reference()])
}

/// Each plan's fidelity with its parameters drawn for the run, as the runner draws them.
fn drawn(experiment: &Experiment, plans: &[&RunPlan]) -> Vec<cpmx_spec::model::DrawnFidelity> {
    plans
        .iter()
        .map(|plan| match &experiment.spec.fidelities[&plan.fidelity] {
            cpmx_spec::model::Fidelity::Simulated(f) => crate::randomise::draw_for_run(f, plan.seed).0,
            other => panic!("not simulated: {other:?}"),
        })
        .collect()
}

/// What the runner hands an engine for each plan.
fn inputs<'a>(
    experiment: &'a Experiment,
    plans: &[&'a RunPlan],
    drawn: &'a [cpmx_spec::model::DrawnFidelity],
) -> Vec<RunInputs<'a>> {
    plans
        .iter()
        .zip(drawn)
        .map(|(plan, fidelity)| RunInputs {
            experiment,
            plan,
            starts: experiment.start(plan).unwrap(),
            fidelity: Some(fidelity),
            stop: None,
            operator: None,
            timing: false,
        })
        .collect()
}

#[test]
fn twin_runs_together_have_the_bits_of_runs_alone() {
    let (experiment, plans) = experiment("lockstep.yaml", Path::new("."), SPEC.into(), &[]);
    let plans: Vec<&RunPlan> = plans.iter().collect();
    assert_eq!(plans.len(), 8);
    let drawn = drawn(&experiment, &plans);
    let inputs = inputs(&experiment, &plans, &drawn);
    let alone: Vec<Recording> = inputs.iter().map(|i| TwinEngine.run(i).unwrap()).collect();
    // A run that cannot start (no drawn stack) fails alone; the others are untouched.
    let mut with_failing = inputs.clone();
    with_failing.insert(
        3,
        RunInputs {
            fidelity: None,
            ..inputs[0]
        },
    );
    let mut together = TwinEngine.run_together(&with_failing);
    assert!(matches!(together.remove(3), Err(RunError::Unsupported(..))));
    assert_eq!(together.len(), alone.len());
    for ((plan, alone), together) in plans.iter().zip(&alone).zip(together) {
        assert_eq!(alone.samples.len(), 30, "{}", plan.key);
        assert_eq!(&together.unwrap(), alone, "{}", plan.key);
    }
    // The randomised twin's runs differ from each other (the test compares real runs).
    assert_ne!(alone[4].samples, alone[6].samples);
}

#[test]
fn the_papers_runs_together_share_their_actors_passes_with_the_bits_of_runs_alone() {
    let (experiment, plans) = at25();
    // Every fidelity's runs of the first policy, and one start of each other policy.
    let plans: Vec<&RunPlan> = plans
        .iter()
        .filter(|plan| plan.policy == "seed1" || plan.initial_configuration == "init2")
        .collect();
    let drawn = drawn(&experiment, &plans);
    let inputs = inputs(&experiment, &plans, &drawn);
    let engines: [(&str, &dyn Engine); 2] = [("sim", &SimEngine), ("twin", &TwinEngine)];
    for (name, engine) in engines {
        let of_engine: Vec<usize> = (0..plans.len())
            .filter(|&i| (plans[i].fidelity == "sim") == (name == "sim"))
            .collect();
        assert!(of_engine.len() >= 10, "{name}: {} runs", of_engine.len());
        let group: Vec<RunInputs<'_>> = of_engine.iter().map(|&i| inputs[i]).collect();
        let together = engine.run_together(&group);
        for (&i, together) in of_engine.iter().zip(together) {
            let alone = engine.run(&inputs[i]).unwrap();
            assert_eq!(alone.samples.len(), 180, "{}", plans[i].key);
            assert_eq!(together.unwrap(), alone, "{}", plans[i].key);
        }
    }
}
