//! Meaning checks: what the schema cannot say. Duplicate names, horizons, agent counts,
//! combinations of keys, files that must exist, fidelities this build cannot run, and the
//! hook through which the interpreter adds the checks that need a map or a network.

use std::collections::HashSet;
use std::path::PathBuf;

use crate::diagnostic::{ByteSpan, Problem};
use crate::model::{ActionMode, Fidelity, InitialConfiguration, OutputHead, Parameter, Spec};
use crate::paths::DataPath;

pub(crate) use crate::check_fidelities::check_distribution;
use crate::check_fidelities::check_fidelities;
pub use crate::check_files::CheckScope;
use crate::check_files::find_files;
use crate::yaml::{NodeSpans, SpannedDocument, escape_pointer};

/// Files a spec names, found on the data path.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Resources {
    /// The map file, when the map is a file.
    pub map_file: Option<PathBuf>,
    /// The file of each initial-configuration entry's own `map`, when it names one that is a
    /// file (or SigmaRL's scenario table), by entry index.
    pub configuration_map_files: Vec<Option<PathBuf>>,
    /// The network file of each policy with an `mlp` (its weights) or an `onnx` (its file), by
    /// policy index.
    pub weights: Vec<Option<PathBuf>>,
    /// The priority network of each XP-MARL policy (`priority: {sigmarl}`), by policy index.
    pub priorities: Vec<Option<PathBuf>>,
    /// The observation of each policy that is a SigmaRL checkpoint, from its `*_data.json`, by
    /// policy index (the spec's policies get it before the interpreter's checks).
    pub observations: Vec<Option<crate::model::ObservationSpec>>,
    /// The folder of each `from_runs` entry, by initial-configuration index.
    pub from_runs: Vec<Option<PathBuf>>,
    /// The actor each seed of the training starts from (`training.initial_actor`, `{seed}`
    /// replaced), when found, by seed.
    pub initial_actors: std::collections::BTreeMap<u64, PathBuf>,
    /// The poses of each `from_poses` entry, read, by initial-configuration index.
    pub poses: Vec<Option<crate::poses::MeasuredPoses>>,
    /// The margin network each safety layer names (`safety.cbf.agents.predictor`), by the
    /// name the spec gives it.
    pub margin_predictors: std::collections::BTreeMap<String, PathBuf>,
    /// The spec's folder (where policy processes run).
    pub spec_dir: PathBuf,
}

/// Where checks report problems, with access to the spans of the spec's nodes.
pub struct CheckContext<'a> {
    doc: &'a SpannedDocument,
    problems: Vec<Problem>,
}

impl<'a> CheckContext<'a> {
    pub(crate) fn new(doc: &'a SpannedDocument) -> Self {
        Self {
            doc,
            problems: Vec::new(),
        }
    }

    /// The spans of the node at a JSON pointer (or its nearest ancestor).
    pub fn spans(&self, pointer: &str) -> NodeSpans {
        self.doc.spans_at(pointer)
    }

    /// Where to label the node at a JSON pointer: the value, or the key of a collection.
    pub fn span(&self, pointer: &str) -> ByteSpan {
        self.doc.label_span(pointer)
    }

    /// Reports a problem.
    pub fn push(&mut self, problem: Problem) {
        self.problems.push(problem);
    }

    pub(crate) fn into_problems(self) -> Vec<Problem> {
        self.problems
    }
}

/// Checks that need the interpreter: the map (reference path ids, starts that overlap or leave
/// the lane, regions), the networks (weights' shapes, observation size) and which fidelities
/// this build can run. The `cpmx` binary implements it with the interpreter's crates.
pub trait InterpreterChecks {
    /// Why this build cannot run `fidelity`, or `None` when it can.
    fn cannot_run(&self, fidelity: &Fidelity) -> Option<String>;

    /// Checks that read the map or the weights; called on every spec that passed the schema,
    /// with the files the data path did not find left out of `resources` (their problems are
    /// already reported), so they check what is sound.
    fn check(&self, spec: &Spec, resources: &Resources, ctx: &mut CheckContext<'_>);
}

/// Runs every check that needs only the spec and the file system.
pub(crate) fn check_meaning(
    spec: &Spec,
    data: &DataPath,
    scope: CheckScope,
    ctx: &mut CheckContext<'_>,
) -> Resources {
    check_version(spec, ctx);
    check_names(spec, ctx);
    check_policies(spec, ctx);
    crate::check_configurations::check_configurations(spec, ctx);
    check_vehicle(spec, ctx);
    check_fidelities(spec, ctx);
    check_metrics(spec, ctx);
    crate::check_compare::check_report(spec, ctx);
    check_repetitions(spec, ctx);
    check_target_speeds(spec, ctx);
    crate::check_training::check_training(spec, ctx);
    find_files(spec, data, scope, ctx)
}

/// A baseline asked to drive faster than the vehicle can would silently drive at the
/// vehicle's maximum: refuse it.
fn check_target_speeds(spec: &Spec, ctx: &mut CheckContext<'_>) {
    for (i, policy) in spec.policies.iter().enumerate() {
        let Some(params) = &policy.lane_follow else {
            continue;
        };
        if params.target_speed > spec.vehicle.max_speed {
            let span = ctx.span(&format!("/policies/{i}/lane_follow/target_speed"));
            ctx.push(
                Problem::error(
                    "cpmx::check::target-speed",
                    format!(
                        "target speed {} m/s is above the vehicle's maximum speed {} m/s",
                        params.target_speed, spec.vehicle.max_speed
                    ),
                    span,
                    "faster than the vehicle can drive",
                )
                .with_help(format!(
                    "choose at most {} m/s, or raise `vehicle.max_speed` (e.g. `vehicle: {{extends: stdlib:mu-car, max_speed: {}}}`)",
                    spec.vehicle.max_speed, params.target_speed
                )),
            );
        }
    }
}

/// Whether a policy gives the same actions for the same states every time (a network's mean
/// action, a rule-based baseline). Unknown kinds count as stochastic.
fn policy_is_deterministic(policy: &crate::model::PolicySpec) -> bool {
    if policy.builtin.is_some() {
        true
    } else if policy.mlp.is_some() || policy.onnx.is_some() {
        policy.action != Some(crate::model::ActionMode::Sample)
    } else {
        false
    }
}

/// Whether a fidelity draws no random number: simulated, without sensing noise or frame
/// drops and without randomised parameters. The lab never repeats itself.
fn fidelity_is_deterministic(fidelity: &Fidelity) -> bool {
    use crate::model::SensingLayer;
    let zero = Parameter::Fixed(0.0);
    match fidelity {
        Fidelity::Lab(_) => false,
        Fidelity::Simulated(stack) if stack.is_randomised() => false,
        Fidelity::Simulated(stack) => match &stack.sensing {
            None | Some(SensingLayer::Ideal(_)) => true,
            Some(SensingLayer::Model(m)) => {
                m.noise_position_m == zero && m.noise_yaw_rad == zero && m.drop_probability == zero
            }
        },
    }
}

/// Warns when repetitions of a deterministic fidelity and policy would be copies of each
/// other (they are counted once in the statistics, so running them only costs time).
fn check_repetitions(spec: &Spec, ctx: &mut CheckContext<'_>) {
    // Measured starts per run, or a draw per repetition, make every repetition start elsewhere.
    let per_run_starts = spec.initial_configurations.iter().all(|c| match c {
        InitialConfiguration::FromPoses(_) => true,
        InitialConfiguration::Sampled(s) => s.sample.draw == crate::model::SampleDraw::PerRepetition,
        InitialConfiguration::Explicit(_) | InitialConfiguration::FromRuns(_) => false,
    });
    if spec.repetitions < 2 || per_run_starts {
        return;
    }
    let deterministic_policies: Vec<&str> = spec
        .policies
        .iter()
        .filter(|p| policy_is_deterministic(p))
        .map(|p| p.name.as_str())
        .collect();
    if deterministic_policies.is_empty() {
        return;
    }
    let fidelities: Vec<&str> = spec
        .fidelities
        .iter()
        .filter(|(_, fidelity)| fidelity_is_deterministic(fidelity))
        .map(|(name, _)| name.as_str())
        .collect();
    let Some(first) = fidelities.first() else {
        return;
    };
    let list = |names: &[&str]| {
        names
            .iter()
            .map(|n| format!("`{n}`"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let (fidelity_words, policy_words) = (
        if fidelities.len() == 1 {
            "fidelity"
        } else {
            "fidelities"
        },
        if deterministic_policies.len() == 1 {
            "policy"
        } else {
            "policies"
        },
    );
    let verb = if fidelities.len() == 1 { "is" } else { "are" };
    // One warning for the spec, at the first such fidelity, naming them all.
    let spans = ctx.spans(&format!("/fidelities/{}", escape_pointer(first)));
    ctx.push(
        Problem::warning(
            "cpmx::check::deterministic-repetitions",
            format!(
                "{fidelity_words} {} {verb} deterministic, and so {} {policy_words} {}: their {} \
                 repetitions will be identical copies",
                list(&fidelities),
                if deterministic_policies.len() == 1 {
                    "is"
                } else {
                    "are"
                },
                list(&deterministic_policies),
                spec.repetitions
            ),
            spans.key.unwrap_or(spans.value),
            "no random draw in this stack",
        )
        .with_help(
            "copies count once in the statistics (n is the number of distinct runs); for independent \
             repetitions use `action: sample`, give the fidelity sensing noise, or set `repetitions: 1`",
        ),
    );
}

fn check_version(spec: &Spec, ctx: &mut CheckContext<'_>) {
    if spec.cpmx != 1 {
        let span = ctx.span("/cpmx");
        ctx.push(
            Problem::error(
                "cpmx::check::version",
                format!("language version {} is not known to this cpmx", spec.cpmx),
                span,
                "unknown version",
            )
            .with_help("this cpmx reads `cpmx: 1`"),
        );
    }
}

/// Reports every name that appears twice in `names` (pointer, name).
fn report_duplicates(what: &str, plural: &str, names: &[(String, String)], ctx: &mut CheckContext<'_>) {
    let mut seen = HashSet::new();
    for (pointer, name) in names {
        if !seen.insert(name.as_str()) {
            let span = ctx.span(pointer);
            ctx.push(
                Problem::error(
                    "cpmx::check::duplicate-name",
                    format!("two {plural} are called `{name}`"),
                    span,
                    "second use of this name",
                )
                .with_help(format!(
                    "run keys are made of names, so every {what} needs its own"
                )),
            );
        }
    }
}

fn check_names(spec: &Spec, ctx: &mut CheckContext<'_>) {
    let policies: Vec<(String, String)> = spec
        .policies
        .iter()
        .enumerate()
        .map(|(i, p)| (format!("/policies/{i}/name"), p.name.clone()))
        .collect();
    report_duplicates("policy", "policies", &policies, ctx);

    let mut configurations = Vec::new();
    let sampled = crate::matrix::sampled_names(spec);
    for (i, c) in spec.initial_configurations.iter().enumerate() {
        match c {
            InitialConfiguration::Explicit(e) => {
                configurations.push((format!("/initial_configurations/{i}/name"), e.name.clone()))
            }
            InitialConfiguration::Sampled(s) => {
                let pointer = if s.name.is_some() {
                    format!("/initial_configurations/{i}/name")
                } else {
                    format!("/initial_configurations/{i}")
                };
                configurations.extend(
                    sampled
                        .iter()
                        .filter(|(entry, _, _)| *entry == i)
                        .map(|(_, _, name)| (pointer.clone(), name.clone())),
                );
            }
            InitialConfiguration::FromRuns(_) | InitialConfiguration::FromPoses(_) => {}
        }
    }
    report_duplicates(
        "initial configuration",
        "initial configurations",
        &configurations,
        ctx,
    );

    for name in spec.fidelities.keys() {
        let valid = !name.is_empty()
            && name
                .chars()
                .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-')
            && !name.starts_with('-');
        if !valid {
            let spans = ctx.spans(&format!("/fidelities/{}", escape_pointer(name)));
            ctx.push(
                Problem::error(
                    "cpmx::check::name",
                    format!("fidelity name `{name}` is not a valid name"),
                    spans.key.unwrap_or(spans.value),
                    "invalid name",
                )
                .with_help("names use lower-case letters, digits and `-`; they become folder names"),
            );
        }
    }
}

fn check_policies(spec: &Spec, ctx: &mut CheckContext<'_>) {
    for (i, p) in spec.policies.iter().enumerate() {
        let base = format!("/policies/{i}");
        let kinds: Vec<&str> = [
            ("mlp", p.mlp.is_some()),
            ("onnx", p.onnx.is_some()),
            ("process", p.process.is_some()),
            ("python", p.python.is_some()),
            ("builtin", p.builtin.is_some()),
        ]
        .into_iter()
        .filter_map(|(k, present)| present.then_some(k))
        .collect();
        let unused = |ctx: &mut CheckContext<'_>, key: &str, present: bool, why: String, label: &str| {
            if present {
                let spans = ctx.spans(&format!("{base}/{key}"));
                ctx.push(
                    Problem::error(
                        "cpmx::check::policy-kind",
                        why,
                        spans.key.unwrap_or(spans.value),
                        label,
                    )
                    .with_help(format!("remove `{key}`")),
                );
            }
        };
        match kinds[..] {
            [] => {
                let span = ctx.span(&format!("{base}/name"));
                ctx.push(
                    Problem::error(
                        "cpmx::check::policy-kind",
                        format!(
                            "policy `{}` names neither `mlp`, `onnx`, `process`, `python` nor `builtin`",
                            p.name
                        ),
                        span,
                        "what drives this policy?",
                    )
                    .with_help(
                        "add `mlp: {weights: FILE}`, `onnx: {file: FILE}`, `process: {command: [PROGRAM, ARGS...]}`, `python: {}` or `builtin: lane-follow`",
                    ),
                );
            }
            [first, second, ..] => {
                let span = ctx
                    .spans(&format!("{base}/{second}"))
                    .key
                    .unwrap_or(ctx.span(&base));
                ctx.push(
                    Problem::error(
                        "cpmx::check::policy-kind",
                        format!("policy `{}` has both `{first}` and `{second}`", p.name),
                        span,
                        "second kind of policy",
                    )
                    .with_help(
                        "a policy is a trained network (`mlp` or `onnx`), a policy process (`process`), a Python callable (`python`) or a built-in baseline (`builtin`); split it in two",
                    ),
                );
            }
            ["builtin"] => {
                for (key, present) in [
                    ("observation", p.observation.is_some()),
                    ("action", p.action.is_some()),
                ] {
                    let why = if key == "observation" {
                        format!(
                            "`{key}` belongs to `mlp`, `onnx` and `process` policies, and `{}` is built in",
                            p.name
                        )
                    } else {
                        format!(
                            "`{key}` belongs to `mlp` and `onnx` policies, and `{}` is built in",
                            p.name
                        )
                    };
                    unused(ctx, key, present, why, "not used by a built-in policy");
                }
            }
            [kind] => {
                let what = match kind {
                    "mlp" | "onnx" => "a network",
                    "python" => "a Python callable",
                    _ => "a policy process",
                };
                unused(
                    ctx,
                    "lane_follow",
                    p.lane_follow.is_some(),
                    format!(
                        "`lane_follow` configures the built-in baseline, and `{}` is {what}",
                        p.name
                    ),
                    &format!("not used by an {kind} policy"),
                );
                if kind == "process" || kind == "python" {
                    unused(
                        ctx,
                        "action",
                        p.action.is_some(),
                        format!(
                            "`action` chooses from a network's distribution, and `{}` is {what}",
                            p.name
                        ),
                        &format!("not used by a {kind} policy"),
                    );
                }
                let head = p
                    .mlp
                    .as_ref()
                    .map(|m| m.output)
                    .or(p.onnx.as_ref().map(|o| o.output));
                let deterministic = head.is_some_and(|h| h != OutputHead::SigmarlTanhNormal);
                if deterministic && p.action == Some(ActionMode::Sample) {
                    let span = ctx.span(&format!("{base}/action"));
                    ctx.push(
                        Problem::error(
                            "cpmx::check::policy-kind",
                            format!(
                                "policy `{}` samples, but its output head is deterministic",
                                p.name
                            ),
                            span,
                            "nothing to sample",
                        )
                        .with_help("`action: sample` needs `output: sigmarl-tanh-normal`; remove `action`"),
                    );
                }
            }
        }
    }
}

fn check_vehicle(spec: &Spec, ctx: &mut CheckContext<'_>) {
    let v = &spec.vehicle;
    if v.rear_axle > v.wheelbase {
        let span = ctx.span("/vehicle/rear_axle");
        ctx.push(
            Problem::error(
                "cpmx::check::vehicle",
                format!(
                    "`rear_axle` ({} m) is longer than the wheelbase ({} m)",
                    v.rear_axle, v.wheelbase
                ),
                span,
                "behind the rear axle",
            )
            .with_help("`rear_axle` is the distance from the centre of gravity to the rear axle"),
        );
    }
    if !(v.accel[0] < 0.0 && v.accel[1] > 0.0) {
        let span = ctx.span("/vehicle/accel");
        ctx.push(
            Problem::error(
                "cpmx::check::vehicle",
                format!(
                    "`accel` must be [braking < 0, accelerating > 0], found [{}, {}]",
                    v.accel[0], v.accel[1]
                ),
                span,
                "not a range around 0",
            )
            .with_help("e.g. `accel: [-5, 5]`"),
        );
    }
}

fn check_metrics(spec: &Spec, ctx: &mut CheckContext<'_>) {
    if let Some(cra_l) = &spec.metrics.cra_l
        && cra_l.slack >= 0.5
    {
        let span = ctx.span("/metrics/cra_l/slack");
        ctx.push(
            Problem::error(
                "cpmx::check::slack",
                format!(
                    "a lane slack of {} vehicle widths leaves no footprint to test",
                    cra_l.slack
                ),
                span,
                "must be below 0.5",
            )
            .with_help("the slack shrinks the footprint by slack × width on each side; the paper uses 0.10"),
        );
    }
}
