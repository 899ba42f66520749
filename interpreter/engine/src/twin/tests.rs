//! Runs stepped in lock-step have, each, the bits they have alone: sim-mpc's and the
//! randomised twin's runs mixed in one group, of several seeds and starts, with a run
//! that cannot start beside them.

use std::path::PathBuf;

use cpmx_spec::{DataPath, SpecSource};

use super::*;
use crate::Experiment;

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

fn experiment() -> (Experiment, Vec<cpmx_spec::RunPlan>) {
    let source = SpecSource {
        name: "lockstep.yaml".into(),
        dir: PathBuf::from("."),
        text: SPEC.into(),
    };
    let checked = cpmx_spec::check(
        &source,
        &DataPath::new(&source.dir, &[], None),
        &crate::BuildChecks,
    )
    .unwrap_or_else(|d| panic!("{}", cpmx_spec::render(&d, false)));
    (Experiment::prepare(&checked).unwrap(), checked.plan())
}

#[test]
fn runs_together_have_the_bits_of_runs_alone() {
    let (experiment, plans) = experiment();
    assert_eq!(plans.len(), 8);
    let drawn: Vec<_> = plans
        .iter()
        .map(|plan| match &experiment.spec.fidelities[&plan.fidelity] {
            cpmx_spec::model::Fidelity::Simulated(f) => crate::randomise::draw_for_run(f, plan.seed).0,
            other => panic!("not simulated: {other:?}"),
        })
        .collect();
    let inputs: Vec<RunInputs<'_>> = plans
        .iter()
        .zip(&drawn)
        .map(|(plan, fidelity)| RunInputs {
            experiment: &experiment,
            plan,
            starts: experiment.start(plan).unwrap(),
            fidelity: Some(fidelity),
            stop: None,
            operator: None,
            timing: false,
        })
        .collect();
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

/// The paper's benchmark (`experiments/at25.yaml`, its actors read from the reference data),
/// checked as `cpmx run --data ../shared/reference` checks it.
fn at25() -> (Experiment, Vec<cpmx_spec::RunPlan>) {
    let experiments = cpmx_testdata::checkout().join("experiments");
    let source = SpecSource {
        name: "at25.yaml".into(),
        dir: experiments.clone(),
        text: std::fs::read_to_string(experiments.join("at25.yaml")).unwrap(),
    };
    let data = [cpmx_testdata::reference()];
    let checked = cpmx_spec::check(
        &source,
        &DataPath::new(&experiments, &data, None),
        &crate::BuildChecks,
    )
    .unwrap_or_else(|d| panic!("{}", cpmx_spec::render(&d, false)));
    (Experiment::prepare(&checked).unwrap(), checked.plan())
}

#[test]
fn the_papers_runs_together_share_their_actors_passes_with_the_bits_of_runs_alone() {
    let (experiment, plans) = at25();
    // The twin's and sim-mpc's runs of the first policy, and one run of each other policy.
    let plans: Vec<&cpmx_spec::RunPlan> = plans
        .iter()
        .filter(|plan| plan.fidelity != "sim")
        .filter(|plan| plan.policy == "seed1" || plan.initial_configuration == "init2")
        .collect();
    assert!(plans.len() >= 20, "{} runs", plans.len());
    let drawn: Vec<_> = plans
        .iter()
        .map(|plan| match &experiment.spec.fidelities[&plan.fidelity] {
            cpmx_spec::model::Fidelity::Simulated(f) => crate::randomise::draw_for_run(f, plan.seed).0,
            other => panic!("not simulated: {other:?}"),
        })
        .collect();
    let inputs: Vec<RunInputs<'_>> = plans
        .iter()
        .zip(&drawn)
        .map(|(plan, fidelity)| RunInputs {
            experiment: &experiment,
            plan,
            starts: experiment.start(plan).unwrap(),
            fidelity: Some(fidelity),
            stop: None,
            operator: None,
            timing: false,
        })
        .collect();
    let together = TwinEngine.run_together(&inputs);
    for ((plan, inputs), together) in plans.iter().zip(&inputs).zip(together) {
        let alone = TwinEngine.run(inputs).unwrap();
        assert_eq!(alone.samples.len(), 180, "{}", plan.key);
        assert_eq!(together.unwrap(), alone, "{}", plan.key);
    }
}
