//! One wrong spec per class of problem: the rendered diagnostics are snapshot-tested, and the
//! line and column of the first one are asserted.

#[macro_use]
mod common;

use cpmx_spec::model::Fidelity;
use cpmx_spec::{CheckContext, InterpreterChecks, Resources, Spec, SpecDiagnostic};

/// Stands in for the interpreter: a build without the twin's grey-box model or a lab.
struct NoTwin;

impl InterpreterChecks for NoTwin {
    fn cannot_run(&self, fidelity: &Fidelity) -> Option<String> {
        match fidelity {
            Fidelity::Simulated(s) if !matches!(s.dynamics, cpmx_spec::model::DynamicsLayer::GreyBox(_)) => {
                None
            }
            _ => Some("no twin or lab in this test".into()),
        }
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
  - name: one
    agents:
      - {ref_path: 1, arc_length: 0.2}
      - {ref_path: 4, arc_length: 0.2}
repetitions: 1
seed: 5
fidelities:
  sim: {control: direct, dynamics: kinematic}
";

fn check(text: &str) -> Result<cpmx_spec::CheckedSpec, Vec<SpecDiagnostic>> {
    common::check_with(text, &NoTwin)
}

/// The valid spec with `from` replaced by `to` (which must occur).
fn edit(from: &str, to: &str) -> String {
    common::edit(VALID, from, to)
}

/// Checks `text`, asserts the first diagnostic's place and returns the rendering.
fn diagnose(text: &str, line: usize, column: usize) -> String {
    common::rejected_at(check(text), line, column)
}

#[test]
fn the_base_spec_is_valid() {
    let checked = check(VALID).unwrap();
    assert_eq!(checked.plan().len(), 1);
    assert!(checked.warnings.is_empty());
}

case!(yaml_syntax, edit("agents: 2\n", "agents: [2\n"), 6, 9);
case!(empty_document, "# nothing here\n", 1, 1);
case!(duplicate_key, edit("seed: 5\n", "seed: 5\nseed: 6\n"), 15, 1);
case!(
    unknown_key_with_suggestion,
    edit("repetitions: 1", "repetitons: 1"),
    13,
    1
);
case!(unknown_nested_key, edit("steps: 20", "step: 20"), 4, 19);
case!(wrong_type, edit("agents: 2", "agents: two"), 5, 9);
case!(out_of_range, edit("dt: 0.1", "dt: 0"), 4, 14);
case!(missing_key, edit("seed: 5\n", ""), 1, 1);
case!(unknown_choice, format!("{VALID}on_collision: crash\n"), 17, 15);
case!(invalid_name, edit("name: demo", "name: My Demo"), 2, 7);
case!(
    unknown_stdlib_name,
    format!("{VALID}vehicle: stdlib:mu-cat\n"),
    17,
    10
);
case!(
    unknown_extended_preset,
    format!("{VALID}vehicle: {{extends: stdlib:micro-car, width: 0.1}}\n"),
    17,
    20
);
case!(
    preset_override_out_of_range,
    format!("{VALID}vehicle: {{extends: stdlib:mu-car, width: -0.1}}\n"),
    17,
    42
);
case!(
    duplicate_policy_name,
    edit(
        "  - {name: base, builtin: lane-follow}\n",
        "  - {name: base, builtin: lane-follow}\n  - {name: base, builtin: lane-follow}\n"
    ),
    8,
    12
);
case!(
    duplicate_configuration_name,
    format!(
        "{}",
        VALID.replace(
            "repetitions: 1",
            "  - name: one\n    agents: [{ref_path: 1}, {ref_path: 4}]\nrepetitions: 1"
        )
    ),
    13,
    11
);
case!(
    control_horizon_exceeds_prediction_horizon,
    format!("{VALID}planner: {{control_horizon: 8, prediction_horizon: 4}}\n"),
    17,
    28
);
case!(
    agent_count,
    edit("      - {ref_path: 4, arc_length: 0.2}\n", ""),
    10,
    5
);
case!(
    missing_map_file,
    edit("map: stdlib:intersection", "map: {file: maps/nowhere.xml}"),
    3,
    13
);
case!(
    missing_weights,
    edit(
        "{name: base, builtin: lane-follow}",
        "{name: net, mlp: {weights: nets/actor.safetensors}}"
    ),
    7,
    32
);
case!(
    missing_onnx_file,
    edit(
        "{name: base, builtin: lane-follow}",
        "{name: net, onnx: {file: nets/actor.onnx}}"
    ),
    7,
    30
);
case!(
    onnx_and_mlp_in_one_policy,
    edit(
        "{name: base, builtin: lane-follow}",
        "{name: net, mlp: {weights: a.safetensors}, onnx: {file: a.onnx}}"
    ),
    7,
    32
);
case!(
    onnx_that_samples_a_deterministic_head,
    edit(
        "{name: base, builtin: lane-follow}",
        "{name: net, onnx: {file: a.onnx, output: deterministic-clip}, action: sample}"
    ),
    7,
    30
);
case!(
    policy_with_two_kinds,
    edit(
        "builtin: lane-follow}",
        "builtin: lane-follow, mlp: {weights: a.safetensors}}"
    ),
    7,
    18
);
case!(
    policy_without_kind,
    edit("{name: base, builtin: lane-follow}", "{name: base}"),
    7,
    12
);
case!(
    observation_on_builtin,
    edit("builtin: lane-follow}", "builtin: lane-follow, action: sample}"),
    7,
    40
);
case!(
    slack_outside_unit_interval,
    format!("{VALID}metrics: {{sample_period_s: 0.1, cra_l: {{slack: 1.5, per_distance_m: 100}}}}\n"),
    17,
    48
);
case!(
    unknown_reference_fidelity,
    format!("{VALID}report: {{compare: {{reference: simm, test: paired}}}}\n"),
    17,
    31
);
case!(unknown_language_version, edit("cpmx: 1", "cpmx: 2"), 1, 7);
case!(
    start_given_twice,
    edit(
        "{ref_path: 1, arc_length: 0.2}",
        "{ref_path: 1, arc_length: 0.2, pose: {x: 1, y: 1}}"
    ),
    11,
    40
);
case!(
    heading_given_twice,
    edit(
        "{ref_path: 1, arc_length: 0.2}",
        "{ref_path: 1, pose: {x: 1, y: 1, yaw: 0, yaw_deg: 0}}"
    ),
    11,
    42
);
case!(non_finite_number, edit("dt: 0.1", "dt: .inf"), 4, 14);
case!(
    lab_vehicle_ids,
    format!(
        "{VALID}  lab: {{driver: cpm-dds, domain: 21, vehicle_ids: [1, 2, 3]}}\nplanner: {{control_horizon: 4, prediction_horizon: 12}}\n"
    ),
    17,
    38
);
case!(
    planner_missing,
    format!("{VALID}  mpc: {{control: trajectory, dynamics: kinematic}}\n"),
    17,
    3
);
case!(
    empty_list,
    edit(
        "policies:\n  - {name: base, builtin: lane-follow}\n",
        "policies: []\n"
    ),
    6,
    1
);
case!(
    layer_keyword_typo,
    edit("dynamics: kinematic", "dynamics: kinematc"),
    16,
    36
);
case!(
    rear_axle_behind_wheelbase,
    format!("{VALID}vehicle: {{extends: stdlib:mu-car, rear_axle: 0.3}}\n"),
    17,
    46
);
case!(
    alias_bomb,
    "a: &a [x, x, x, x, x, x, x, x, x, x]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a, *a]\nc: &c [*b, *b, *b, *b, *b, *b, *b, *b, *b, *b]\nd: &d [*c, *c, *c, *c, *c, *c, *c, *c, *c, *c]\ne: &e [*d, *d, *d, *d, *d, *d, *d, *d, *d, *d]\nf: [*e, *e, *e, *e, *e, *e, *e, *e, *e, *e]\n",
    5,
    36
);

#[test]
fn unsupported_fidelities_are_warnings_not_errors() {
    let text = format!(
        "{VALID}  mpc: {{control: trajectory, dynamics: stdlib:mu-car-greybox}}\nplanner: {{control_horizon: 4, prediction_horizon: 12}}\n"
    );
    let checked = check(&text).unwrap();
    assert_eq!(checked.plan().len(), 2);
    assert_eq!(checked.warnings.len(), 1);
    assert_eq!((checked.warnings[0].line, checked.warnings[0].column), (17, 3));
    insta::assert_snapshot!(cpmx_spec::render(&checked.warnings, false));
}

#[test]
fn repetitions_of_a_deterministic_stack_are_a_warning() {
    let text = VALID.replace("repetitions: 1", "repetitions: 3");
    let checked = check(&text).unwrap();
    assert_eq!(checked.warnings.len(), 1);
    assert_eq!((checked.warnings[0].line, checked.warnings[0].column), (16, 3));
    insta::assert_snapshot!(cpmx_spec::render(&checked.warnings, false));
    // A noisy fidelity's repetitions differ: still one warning, for `sim` only.
    let noisy = format!(
        "{text}  twin:\n    control: trajectory\n    dynamics: kinematic\n    sensing: stdlib:cpm-ips\n\
         planner: {{control_horizon: 4, prediction_horizon: 12}}\n"
    );
    let checked = check(&noisy).unwrap();
    let copies: Vec<String> = checked
        .warnings
        .iter()
        .filter(|w| w.problem.code == "cpmx::check::deterministic-repetitions")
        .map(ToString::to_string)
        .collect();
    assert_eq!(copies.len(), 1, "{copies:?}");
    assert!(copies[0].contains("`sim`"));
}

#[test]
fn a_target_speed_above_the_vehicle_maximum_is_refused() {
    let text = VALID.replace(
        "- {name: base, builtin: lane-follow}",
        "- {name: base, builtin: lane-follow, lane_follow: {target_speed: 2.5}}",
    );
    let problems = check(&text).unwrap_err();
    assert_eq!(problems.len(), 1);
    insta::assert_snapshot!(cpmx_spec::render(&problems, false));
}

#[test]
fn a_layer_word_that_is_no_form_lists_the_forms() {
    let text = VALID.replace(
        "  sim: {control: direct, dynamics: kinematic}",
        "  sim: {control: direct, dynamics: greybox}",
    );
    let problems = check(&text).unwrap_err();
    let rendered = cpmx_spec::render(&problems, false);
    assert!(
        rendered.contains("valid forms: `kinematic`") && rendered.contains("stdlib:mu-car-greybox"),
        "{rendered}"
    );
}

#[test]
fn an_unknown_preset_gets_a_did_you_mean() {
    let problems = check(&format!("{VALID}vehicle: stdlib:mucar\n")).unwrap_err();
    let text = cpmx_spec::render(&problems, false);
    assert!(text.contains("did you mean `stdlib:mu-car`?"), "{text}");
    // Said once: not again as "`vehicle` must be a mapping".
    assert_eq!(problems.len(), 1, "{text}");
}

#[test]
fn a_misspelt_key_does_not_hide_the_problems_of_meaning() {
    let text = edit("name: demo\n", "name: demo\ndescripton: typo\n").replace(
        "  - {name: base, builtin: lane-follow}\n",
        "  - {name: base, builtin: lane-follow}\n  - {name: base, builtin: lane-follow}\n",
    );
    let problems = check(&text).unwrap_err();
    let codes: Vec<&str> = problems.iter().map(|p| p.problem.code).collect();
    assert_eq!(
        codes,
        ["cpmx::schema::unknown-key", "cpmx::check::duplicate-name"],
        "{}",
        cpmx_spec::render(&problems, false)
    );
    assert!(cpmx_spec::render(&problems, false).contains("two policies are called `base`"));
}

/// The valid spec with a second policy called `base`, which only the checks of meaning find.
fn with_duplicate_policy(text: &str) -> String {
    common::edit(
        text,
        "  - {name: base, builtin: lane-follow}\n",
        "  - {name: base, builtin: lane-follow}\n  - {name: base, builtin: lane-follow}\n",
    )
}

/// The codes of `text`'s problems, in order.
fn codes(text: &str) -> Vec<&'static str> {
    let problems = check(text).unwrap_err();
    eprintln!("{}", cpmx_spec::render(&problems, false));
    problems.iter().map(|p| p.problem.code).collect()
}

#[test]
fn a_wrong_value_of_a_key_with_a_default_does_not_hide_the_problems_of_meaning() {
    // A word where a list belongs and a word that is none of the choices: the checks of meaning
    // run with their defaults and find the duplicate policy.
    let text = with_duplicate_policy(&edit(
        "seed: 5\n",
        "seed: 5\non_collision: halt\nreport: {group_by: fidelity}\n",
    ));
    assert_eq!(
        codes(&text),
        [
            "cpmx::check::duplicate-name",
            "cpmx::schema::choice",
            "cpmx::schema::type"
        ]
    );
    // A later value of a sweep out of range: the checks run with the first.
    let swept = with_duplicate_policy(&format!(
        "{VALID}metrics: {{sample_period_s: {{sweep: [0.1, -0.1]}}}}\n"
    ));
    assert_eq!(
        codes(&swept),
        ["cpmx::check::duplicate-name", "cpmx::schema::range"]
    );
}

#[test]
fn a_wrong_item_of_a_list_with_a_default_does_not_hide_the_problems_of_meaning() {
    // A misspelt `group_by` entry: the default grouping stands in, and the unknown reference
    // fidelity of `compare` is said in the same pass.
    let text = format!(
        "{VALID}report: {{group_by: [fidelity, polcy], compare: {{reference: simm, test: paired}}}}\n"
    );
    assert_eq!(codes(&text), ["cpmx::schema::choice", "cpmx::check::reference"]);
}

#[test]
fn a_number_where_a_choice_belongs_names_every_choice() {
    let problems = check(&edit("seed: 5\n", "seed: 5\non_collision: 5\n")).unwrap_err();
    let messages: Vec<&str> = problems.iter().map(|p| p.problem.message.as_str()).collect();
    assert_eq!(
        messages,
        ["`on_collision` must be one of continue, reset-agent, end-run, replace-agent"]
    );
}

#[test]
fn a_wrong_value_without_a_default_stops_before_the_checks_of_meaning() {
    // Without the key the checks of meaning would say more about its absence than the spec's
    // other problems: the schema's error is said alone.
    for (from, to, code) in [
        ("agents: 2\n", "agents: -1\n", "cpmx::schema::range"),
        ("seed: 5\n", "seed: 5\nplanner: [4, 12]\n", "cpmx::schema::type"),
        (
            "seed: 5\n",
            "seed: 5\ndescription: [a, b]\n",
            "cpmx::schema::type",
        ),
        ("seed: 5\n", "seed: 5\nmetrics: at25\n", "cpmx::schema::type"),
        (
            "sim: {control: direct,",
            "sim: {control: directt,",
            "cpmx::schema::choice",
        ),
    ] {
        assert_eq!(codes(&with_duplicate_policy(&edit(from, to))), [code], "{to}");
    }
    let builtin = edit("builtin: lane-follow}", "builtin: lane-folow}");
    assert_eq!(codes(&builtin), ["cpmx::schema::choice"]);
}

case!(
    direct_control_with_an_actuation_model,
    edit(
        "sim: {control: direct, dynamics: kinematic}",
        "sim: {control: direct, dynamics: kinematic, actuation: {delay_ms: 80}, sensing: stdlib:cpm-ips}"
    ),
    16,
    47
);

#[test]
fn kinematic_rk4_integrates_direct_control_and_tag_goes_with_a_checkpoint() {
    assert!(check(&edit("dynamics: kinematic}", "dynamics: kinematic-rk4}")).is_ok());
    let planning = edit(
        "sim: {control: direct, dynamics: kinematic}",
        "sim: {control: trajectory, dynamics: kinematic-rk4}",
    );
    assert!(codes(&planning).contains(&"cpmx::check::kinematic-rk4"));
    let tag = edit(
        "{name: base, builtin: lane-follow}",
        "{name: base, mlp: {weights: actor.safetensors, tag: 1.4.0}}",
    );
    let problems = check(&tag).unwrap_err();
    assert!(
        problems.iter().any(|p| p
            .problem
            .message
            .contains("release's `tag`, but names no SigmaRL checkpoint")),
        "{}",
        cpmx_spec::render(&problems, false)
    );
    let unknown = edit(
        "{name: base, builtin: lane-follow}",
        "{name: base, mlp: {sigmarl: ckpt, tag: 1.3.0}}",
    );
    assert!(codes(&unknown).contains(&"cpmx::schema::choice"));
}

#[test]
fn deep_nesting_is_a_diagnostic() {
    let text = format!("a: {}{}\n", "[".repeat(500), "]".repeat(500));
    assert!(check(&text).is_err());
}

case!(
    slack_without_footprint,
    format!("{VALID}metrics: {{sample_period_s: 0.1, cra_l: {{slack: 0.6, per_distance_m: 100}}}}\n"),
    17,
    48
);

#[test]
fn from_runs_needs_runs_of_that_fidelity() {
    let dir = std::env::temp_dir().join(format!("cpmx-from-runs-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("matrix.csv"),
        "key,fidelity,policy,initial_configuration,repetition,seed\nsim/a/b/rep1,sim,a,b,1,7\n",
    )
    .unwrap();
    let text = VALID.replace(
        "repetitions: 1",
        &format!(
            "  - from_runs: {{dir: {}, fidelity: lab}}\nrepetitions: 1",
            dir.display()
        ),
    );
    let diagnostics = check(&text).expect_err("no lab runs there");
    assert_eq!(diagnostics[0].problem.code, "cpmx::check::from-runs");
    assert_eq!(diagnostics[0].line, 13);
    let ok = text.replace("fidelity: lab", "fidelity: sim");
    let checked = check(&ok).unwrap();
    assert_eq!(checked.configurations.len(), 2, "one explicit, one recorded");
    assert_eq!(checked.configurations[1].name, "sim-a-b-rep1");
    std::fs::remove_dir_all(&dir).ok();
}

// Randomised layer parameters: a distribution must be one, inside the parameter's range.

/// The valid spec whose `sim` plans trajectories through an actuation layer `{layer}`.
fn with_actuation(layer: &str) -> String {
    edit(
        "sim: {control: direct, dynamics: kinematic}",
        &format!("sim: {{control: trajectory, dynamics: kinematic, actuation: {{{layer}}}}}"),
    ) + "planner: {control_horizon: 4, prediction_horizon: 12}\n"
}

case!(
    reversed_uniform_range,
    with_actuation("delay_ms: {uniform: [120, 40]}"),
    16,
    74
);
case!(
    empty_uniform_range,
    with_actuation("delay_ms: {uniform: [50, 50]}"),
    16,
    74
);
case!(
    uniform_range_outside_the_parameter,
    with_actuation("delay_ms: {uniform: [-10, 40]}"),
    16,
    74
);
case!(
    normal_without_spread,
    with_actuation("delay_ms: {normal: {mean: 80, std: 0}}"),
    16,
    98
);
case!(
    unknown_distribution,
    with_actuation("delay_ms: {gaussian: {mean: 80, std: 5}}"),
    16,
    74
);
case!(
    distribution_over_a_parameter_that_does_not_exist,
    with_actuation("delay_s: {uniform: [0.04, 0.12]}"),
    16,
    63
);

/// A randomised fidelity is not deterministic: no warning that its repetitions are copies.
#[test]
fn a_randomised_fidelity_has_repetitions_worth_running() {
    let text = with_actuation("delay_ms: {uniform: [40, 120]}").replace("repetitions: 1", "repetitions: 3");
    let checked = check(&text).unwrap();
    assert!(checked.warnings.is_empty(), "{:?}", checked.warnings);
    let deterministic = check(&VALID.replace("repetitions: 1", "repetitions: 3")).unwrap();
    assert!(!deterministic.warnings.is_empty());
}

/// The valid spec with a lab fidelity whose mapping continues with `lab_tail` (indented by
/// four spaces), and a planner.
fn with_lab(lab_tail: &str) -> String {
    edit(
        "  sim: {control: direct, dynamics: kinematic}\n",
        &format!(
            "  sim: {{control: direct, dynamics: kinematic}}\n  lab:\n    driver: cpm-dds\n    domain: 1\n    \
             vehicle_ids: [1, 2]\n{lab_tail}"
        ),
    ) + "planner: {control_horizon: 4, prediction_horizon: 12}\n"
}

#[test]
fn a_lab_fidelity_takes_a_preflight_and_faults() {
    let text = with_lab(
        "    preflight: {position_tolerance_m: 0.05, misplaced: record}\n    ips_age_limit_s: 2\n    faults:\n      \
         seed: 3\n      topics: {vehicleStateList: {drop: 0.1, delay: 0.2, delay_ms: {uniform: [10, 50]}}}\n      \
         ips_loss: [{vehicle: 2, at_s: {uniform: [1, 2]}, probability: 0.5}]\n      \
         leave_lists: [{vehicle: 1, at_s: 1, for_s: 0.5, listed: stale}]\n      restarts: [{at_s: 2}]\n",
    );
    let checked = check(&text).expect("valid");
    let Some(Fidelity::Lab(lab)) = checked.spec.fidelities.get("lab") else {
        panic!("no lab fidelity");
    };
    assert_eq!(lab.preflight().misplaced, cpmx_spec::model::Misplaced::Record);
    assert_eq!(lab.preflight().heading_tolerance_deg, 5.0, "a default");
    assert_eq!(lab.ips_age_limit_s(), 2.0);
    let faults = lab.faults.as_ref().expect("faults");
    assert_eq!((faults.seed, faults.restarts.len()), (3, 1));
}

#[test]
fn faults_name_the_lab_s_vehicles_and_times_that_are_times() {
    let text = with_lab(
        "    faults:\n      ips_loss: [{vehicle: 3, at_s: 1.0}]\n      pauses: [{at_s: {uniform: [2, 1]}, for_s: -1}]\n",
    );
    let diagnostics = check(&text).expect_err("rejected");
    let messages: Vec<(usize, usize, &str)> = diagnostics
        .iter()
        .map(|d| (d.line, d.column, d.problem.message.as_str()))
        .collect();
    assert_eq!(
        messages[0],
        (
            22,
            28,
            "the faults name vehicle 3, which the lab fidelity does not drive"
        ),
        "{messages:?}"
    );
    assert!(
        messages
            .iter()
            .any(|(_, _, m)| m.contains("`at_s` is drawn from a reversed range [2, 1]")),
        "{messages:?}"
    );
    assert!(
        messages
            .iter()
            .any(|(_, _, m)| m.contains("`for_s` of a fault is -1, outside (0, inf]")),
        "{messages:?}"
    );
}

#[test]
fn a_faults_file_is_checked_as_the_spec_s_faults_are() {
    let source = |text: &str| cpmx_spec::SpecSource {
        name: "faults.yaml".into(),
        dir: ".".into(),
        text: text.into(),
    };
    let faults = cpmx_spec::check_faults(
        &source("seed: 4\nmisplaced: [{vehicle: 2, offset_m: [0.1, 0]}]\n"),
        &[1, 2],
    )
    .expect("valid");
    assert_eq!(faults.misplaced[0].offset_m, [0.1, 0.0]);
    let typo = cpmx_spec::check_faults(&source("topics: {vehicleStateList: {drops: 0.1}}\n"), &[1, 2])
        .expect_err("a typo");
    assert_eq!((typo[0].line, typo[0].column), (1, 29), "{typo:?}");
    assert_eq!(typo[0].problem.help.as_deref(), Some("did you mean `drop`?"));
    let stranger = cpmx_spec::check_faults(&source("low_battery: [{vehicle: 9, voltage_v: 6}]\n"), &[1, 2])
        .expect_err("not the lab's vehicle");
    assert!(stranger[0].problem.message.contains("vehicle 9"), "{stranger:?}");
}

#[test]
fn sample_entries_are_named_by_their_name_or_numbered() {
    let text = VALID.replace(
        "repetitions: 1",
        "  - {name: crowd, sample: {count: 2, seed: 1}}\n  - {sample: {count: 2, seed: 2}}\n  \
         - {name: alone, sample: {count: 1, seed: 3}}\nrepetitions: 1",
    );
    let checked = check(&text).unwrap();
    let names: Vec<&str> = checked.configurations.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["one", "crowd1", "crowd2", "sample1", "sample2", "alone"]);
    // A name given twice is one problem, at the second entry's `name`.
    let text = VALID.replace(
        "repetitions: 1",
        "  - {name: one, sample: {count: 1, seed: 1}}\nrepetitions: 1",
    );
    let rendered = diagnose(&text, 13, 12);
    assert!(rendered.contains("`one`"), "{rendered}");
}

#[test]
fn draws_per_repetition_are_independent_repetitions() {
    // Every configuration drawn per repetition: no warning of copies.
    let text = VALID
        .replace(
            "  - name: one\n    agents:\n      - {ref_path: 1, arc_length: 0.2}\n      - {ref_path: 4, arc_length: 0.2}\n",
            "  - {name: many, sample: {count: 1, seed: 1, draw: per-repetition}}\n",
        )
        .replace("repetitions: 1", "repetitions: 3");
    let checked = check(&text).unwrap();
    assert!(checked.warnings.is_empty(), "{:?}", checked.warnings);
    // Another agent count than the spec's needs the entry's own map.
    let text = text.replace("draw: per-repetition}", "draw: per-repetition, agents: 3}");
    let rendered = diagnose(&text, 9, 76);
    assert!(
        rendered.contains("places 3 agents, but the spec has `agents: 2`"),
        "{rendered}"
    );
}

#[test]
fn replacing_cars_is_refused_for_a_fidelity_that_plans_trajectories_and_for_the_lab() {
    let text = edit(
        "  sim: {control: direct, dynamics: kinematic}\n",
        "  sim: {control: direct, dynamics: kinematic}\n  \
         sim-mpc: {control: trajectory, dynamics: kinematic}\n  \
         lab: {driver: cpm-dds, domain: 21, vehicle_ids: [1, 2]}\n\
         planner: {control_horizon: 4, prediction_horizon: 12}\n\
         on_collision: replace-agent\n",
    );
    let problems = check(&text).unwrap_err();
    let replace: Vec<_> = problems
        .iter()
        .filter(|p| p.problem.code == "cpmx::check::replace-agent")
        .cloned()
        .collect();
    assert_eq!(replace.len(), 2, "{problems:?}");
    insta::assert_snapshot!(cpmx_spec::render(&replace, false));
    // The sim alone may replace cars.
    assert!(check(&edit("seed: 5\n", "seed: 5\non_collision: replace-agent\n")).is_ok());
}
