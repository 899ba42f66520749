//! Sweeps and the neighbour layers in the language: a sweep multiplies its fidelity's runs
//! (points named in the run keys), a metric's sweep every fidelity's, a training sweep the
//! training runs; a sweep where none may stand, an empty one, one inside a distribution and a
//! value out of range are located diagnostics; `communication` and `perception` read with their
//! defaults.

#[macro_use]
mod common;

use cpmx_spec::model::Fidelity;
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
name: sweeps
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
  twin:
    control: trajectory
    dynamics: kinematic
    actuation: {delay_ms: 80}
planner: {control_horizon: 4, prediction_horizon: 12}
";

fn check(text: &str) -> Result<cpmx_spec::CheckedSpec, Vec<SpecDiagnostic>> {
    common::check_with(text, &Everything)
}

fn diagnose(text: &str, line: usize, column: usize) -> String {
    common::rejected_at(check(text), line, column)
}

#[test]
fn a_layer_sweep_multiplies_its_fidelitys_runs_and_names_its_points() {
    let text = common::edit(VALID, "{delay_ms: 80}", "{delay_ms: {sweep: [0, 80, 160]}}");
    let checked = check(&text).unwrap();
    let keys: Vec<String> = checked.plan().iter().map(|r| r.key.clone()).collect();
    assert_eq!(keys.len(), 1 + 3);
    assert_eq!(keys[1], "twin@delay_ms=0/base/sample1/rep1");
    assert_eq!(keys[3], "twin@delay_ms=160/base/sample1/rep1");
    // Points are paired like fidelities: the same seed as the sim run.
    let plan = checked.plan();
    assert!(plan.iter().all(|r| r.seed == plan[0].seed));
    let spec = checked.run_spec();
    let Some(Fidelity::Simulated(f)) = spec.fidelities.get("twin@delay_ms=160") else {
        panic!("{:?}", spec.fidelities.keys().collect::<Vec<_>>())
    };
    let Some(cpmx_spec::model::ActuationLayer::Model(a)) = &f.actuation else {
        panic!()
    };
    assert_eq!(a.delay_ms, cpmx_spec::model::Parameter::Fixed(160.0));
}

#[test]
fn two_sweeps_make_a_grid_and_a_metric_sweep_applies_to_every_fidelity() {
    let text = common::edit(
        VALID,
        "    actuation: {delay_ms: 80}\n",
        "    actuation: {delay_ms: {sweep: [0, 80]}}\n    communication: {drop_probability: {sweep: [0, 0.5]}}\n",
    ) + "metrics: {extends: stdlib:at25, cra_l: {slack: {sweep: [0, 0.1]}, per_distance_m: 100}}\n";
    let checked = check(&text).unwrap();
    let names: Vec<&String> = checked.fidelity_points.keys().collect();
    assert_eq!(names.len(), 2 + 8, "{names:?}");
    assert_eq!(names[0], "sim@slack=0");
    assert!(
        names.contains(&&"twin@delay_ms=80+drop_probability=0.5+slack=0.1".to_owned()),
        "{names:?}"
    );
    assert_eq!(
        checked.metrics_for("sim@slack=0.1").cra_l.as_ref().unwrap().slack,
        0.1
    );
    assert_eq!(
        checked.metrics_for("sim@slack=0").cra_l.as_ref().unwrap().slack,
        0.0
    );
}

#[test]
fn a_training_sweep_trains_each_points_policies() {
    let text = VALID.to_owned()
        + "training:\n  scenario: stdlib:sigmarl-intersection\n  reward: stdlib:sigmarl-reward\n  \
           algorithm: {extends: stdlib:mappo-sigmarl, mappo: {lr: {sweep: [1.0e-4, 3.0e-4]}}}\n  \
           iterations: 10\n  seeds: [1, 2]\n";
    let checked = check(&text).unwrap();
    let keys: Vec<String> = checked.training_plan().iter().map(|t| t.key.clone()).collect();
    assert_eq!(
        keys,
        [
            "train/lr=0.0001/1",
            "train/lr=0.0001/2",
            "train/lr=0.0003/1",
            "train/lr=0.0003/2"
        ]
    );
    assert_eq!(checked.training_points[1].training.algorithm.mappo.lr, 3.0e-4);
}

#[test]
fn ideal_layers_read_with_their_defaults() {
    let text = common::edit(
        VALID,
        "  sim: {control: direct, dynamics: kinematic}\n",
        "  sim: {control: direct, dynamics: kinematic, communication: {}, perception: {range_m: 2}}\n",
    );
    let checked = check(&text).unwrap();
    let Some(Fidelity::Simulated(f)) = checked.spec.fidelities.get("sim") else {
        panic!()
    };
    let c = f.communication.as_ref().unwrap();
    assert!(c.latency_ms.is_none() && c.range_m.is_none() && c.max_age_ms.is_none());
    assert_eq!(
        f.perception.as_ref().unwrap().range_m,
        Some(cpmx_spec::model::Parameter::Fixed(2.0))
    );
}

case!(
    a_sweep_of_a_key_the_layer_lacks,
    common::edit(VALID, "{delay_ms: 80}", "{delay_ms: 80, lag_ms: {sweep: [0, 1]}}"),
    17,
    31
);
case!(
    an_empty_sweep,
    common::edit(VALID, "{delay_ms: 80}", "{delay_ms: {sweep: []}}"),
    17,
    35
);
case!(
    a_sweep_inside_a_distribution,
    common::edit(
        VALID,
        "{delay_ms: 80}",
        "{delay_ms: {uniform: [{sweep: [0, 40]}, 120]}}"
    ),
    17,
    38
);
case!(
    a_swept_value_out_of_range,
    common::edit(VALID, "{delay_ms: 80}", "{delay_ms: {sweep: [0, 80, -5]}}"),
    17,
    43
);
case!(
    a_sweep_where_none_may_stand,
    common::edit(VALID, "agents: 2", "agents: {sweep: [2, 3]}"),
    5,
    1
);

/// `report:` comparing with `reference`.
fn comparing_with(text: &str, reference: &str) -> String {
    format!("{text}report:\n  compare: {{reference: {reference}, test: paired}}\n")
}

case!(
    a_swept_reference_that_the_others_cannot_pair_with,
    comparing_with(
        &common::edit(VALID, "{delay_ms: 80}", "{delay_ms: {sweep: [0, 80]}}"),
        "twin"
    ),
    20,
    24
);
case!(
    a_reference_point_the_sweep_does_not_have,
    comparing_with(
        &common::edit(VALID, "{delay_ms: 80}", "{delay_ms: {sweep: [0, 80]}}"),
        "twin@delay_ms=40"
    ),
    20,
    24
);

#[test]
fn a_reference_is_a_fidelity_swept_alike_or_one_point_of_a_swept_one() {
    let swept = common::edit(VALID, "{delay_ms: 80}", "{delay_ms: {sweep: [0, 80]}}");
    let checked = check(&comparing_with(&swept, "twin@delay_ms=0")).unwrap();
    assert_eq!(checked.plan().len(), 3);
    check(&comparing_with(&swept, "sim")).unwrap();
    // A metric's sweep sweeps every fidelity alike: each point pairs with the reference's.
    let metric = format!("{VALID}metrics: {{extends: stdlib:at25, cra_l: {{slack: {{sweep: [0, 0.1]}}}}}}\n");
    check(&comparing_with(&metric, "sim")).unwrap();
}

#[test]
fn a_refused_sweep_does_not_hide_the_specs_other_problems() {
    let text = common::edit(VALID, "agents: 2", "agents: {sweep: [2, 3]}")
        .replace(
            "map: stdlib:intersection",
            "map: {file: nowhere.xml}\ndescripton: typo",
        )
        .replace("planner:", "plannr:");
    let problems = check(&text).unwrap_err();
    let codes: Vec<&str> = problems.iter().map(|p| p.problem.code).collect();
    // `plannr` is read as `planner`: `twin` is not also said to lack one.
    assert!(!codes.contains(&"cpmx::check::planner"), "{codes:?}");
    for code in [
        "cpmx::sweep::place",
        "cpmx::schema::unknown-key",
        "cpmx::check::missing-file",
    ] {
        assert!(
            codes.contains(&code),
            "{code}: {}",
            cpmx_spec::render(&problems, false)
        );
    }
}

#[test]
fn a_fidelity_swept_beside_a_metric_pairs_with_the_reference_at_the_metrics_point() {
    let text = format!(
        "{}metrics: {{extends: stdlib:at25, cra_l: {{slack: {{sweep: [0, 0.1]}}}}}}\n\
         report:\n  compare: {{reference: sim, test: paired}}\n",
        common::edit(VALID, "{delay_ms: 80}", "{delay_ms: {sweep: [0, 80]}}")
    );
    let checked = check(&text).unwrap();
    assert_eq!(checked.plan().len(), 2 + 4);
}
