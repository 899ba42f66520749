//! The fidelities' checks: horizons and the planner a fidelity needs, per-fidelity agent
//! counts and names, layer parameters given as distributions, and the fidelities this build
//! cannot run.

use std::collections::HashSet;

use crate::check::{CheckContext, InterpreterChecks};
use crate::diagnostic::Problem;
use crate::model::{
    ActuationLayer, Control, Distribution, DynamicsLayer, Fidelity, KinematicKeyword, OnCollision, Parameter,
    ParameterRange, SensingLayer, SimulatedFidelity, Spec,
};
use crate::yaml::escape_pointer;

pub(crate) fn needs_planner(fidelity: &Fidelity) -> bool {
    match fidelity {
        Fidelity::Simulated(SimulatedFidelity { control, .. }) => *control == Control::Trajectory,
        Fidelity::Lab(_) => true,
    }
}

pub(crate) fn check_fidelities(spec: &Spec, ctx: &mut CheckContext<'_>) {
    if let Some(planner) = &spec.planner
        && planner.control_horizon > planner.prediction_horizon
    {
        let span = ctx.span("/planner/control_horizon");
        ctx.push(
            Problem::error(
                "cpmx::check::horizon",
                format!(
                    "the control horizon Hc = {} exceeds the prediction horizon Hp = {}",
                    planner.control_horizon, planner.prediction_horizon
                ),
                span,
                "Hc > Hp",
            )
            .with_help("the policy is rolled out for Hc steps inside a trajectory of Hp steps: Hc ≤ Hp"),
        );
    }
    for (name, fidelity) in &spec.fidelities {
        let pointer = format!("/fidelities/{}", escape_pointer(name));
        check_replacement(spec, name, fidelity, ctx);
        if spec.planner.is_none() && needs_planner(fidelity) {
            let spans = ctx.spans(&pointer);
            ctx.push(
                Problem::error(
                    "cpmx::check::planner",
                    format!("fidelity `{name}` plans trajectories, but the spec has no `planner`"),
                    spans.key.unwrap_or(spans.value),
                    "needs `planner`",
                )
                .with_help("add `planner: {control_horizon: 4, prediction_horizon: 12}`"),
            );
        }
        if let Fidelity::Simulated(simulated) = fidelity {
            check_distributions(name, &pointer, simulated, ctx);
            check_direct_layers(name, &pointer, simulated, ctx);
            check_safety_layer(&pointer, simulated, ctx);
        }
        if let Fidelity::Lab(lab) = fidelity {
            for (i, c) in spec.initial_configurations.iter().enumerate() {
                if c.own_map().is_some() {
                    let span = ctx.span(&format!("/initial_configurations/{i}/map"));
                    ctx.push(
                        Problem::error(
                            "cpmx::check::lab-map",
                            format!(
                                "fidelity `{name}` is the lab, which drives on the spec's `map`; this configuration names its own"
                            ),
                            span,
                            "another map",
                        )
                        .with_help("run this configuration in an experiment without the lab fidelity"),
                    );
                }
            }
            if lab.vehicle_ids.len() != spec.agents as usize {
                let span = ctx.span(&format!("{pointer}/vehicle_ids"));
                ctx.push(
                    Problem::error(
                        "cpmx::check::agent-count",
                        format!(
                            "fidelity `{name}` names {} vehicle ids for {} agents",
                            lab.vehicle_ids.len(),
                            spec.agents
                        ),
                        span,
                        "one id per agent",
                    )
                    .with_help("list the lab's vehicle ids in agent order"),
                );
            }
            let mut seen = HashSet::new();
            for (k, id) in lab.vehicle_ids.iter().enumerate() {
                if !seen.insert(id) {
                    let span = ctx.span(&format!("{pointer}/vehicle_ids/{k}"));
                    ctx.push(Problem::error(
                        "cpmx::check::duplicate-name",
                        format!("vehicle id {id} is listed twice"),
                        span,
                        "second use",
                    ));
                }
            }
            if let Some(faults) = &lab.faults {
                crate::check_lab::check_faults(faults, &lab.vehicle_ids, &format!("{pointer}/faults"), ctx);
            }
        }
    }
}

/// `on_collision: replace-agent` places new cars in the sim engine's loop: a fidelity that
/// plans trajectories for followers, filters actions or drives the lab cannot replace a car.
fn check_replacement(spec: &Spec, name: &str, fidelity: &Fidelity, ctx: &mut CheckContext<'_>) {
    if spec.on_collision != OnCollision::ReplaceAgent {
        return;
    }
    let reason = match fidelity {
        Fidelity::Lab(_) => "drives the lab, where a car cannot be taken off the track",
        Fidelity::Simulated(f) if f.control != Control::Direct => {
            "plans trajectories for followers (`control: trajectory`); cpmx replaces cars in `control: direct` fidelities only"
        }
        Fidelity::Simulated(f) if f.safety.is_some() => {
            "filters its actions (`safety:`), and the filter's paths do not follow a replaced car yet"
        }
        Fidelity::Simulated(_) => return,
    };
    let span = ctx.span("/on_collision");
    ctx.push(
        Problem::error(
            "cpmx::check::replace-agent",
            format!("`on_collision: replace-agent`, but fidelity `{name}` {reason}"),
            span,
            "replaces cars",
        )
        .with_help("run this fidelity in an experiment with `on_collision: continue` (or `end-run`)"),
    );
}

/// A safety filter's speed range must be a range.
fn check_safety_layer(pointer: &str, fidelity: &SimulatedFidelity, ctx: &mut CheckContext<'_>) {
    let Some(safety) = &fidelity.safety else {
        return;
    };
    let [low, high] = safety.cbf.speed_range_mps;
    if low >= high || low.is_nan() || high.is_nan() {
        let span = ctx.span(&format!("{pointer}/safety/cbf/speed_range_mps"));
        ctx.push(
            Problem::error(
                "cpmx::check::range",
                format!("`speed_range_mps` is [{low}, {high}]: its lowest speed must lie below its highest"),
                span,
                "not a range",
            )
            .with_help("write [lowest, highest], e.g. SigmaRL's [-0.5, 1.0]"),
        );
    }
}

/// `control: direct` applies each action to the kinematic bicycle with exact states (SigmaRL's
/// simulation): grey-box dynamics, a sensing or actuation model and a follower are layers of
/// the twin engine, which `control: trajectory` runs. Each such layer is an error at its key.
fn check_direct_layers(name: &str, pointer: &str, fidelity: &SimulatedFidelity, ctx: &mut CheckContext<'_>) {
    if fidelity.control != Control::Direct {
        if let DynamicsLayer::Kinematic(
            keyword @ (KinematicKeyword::KinematicRk4 | KinematicKeyword::KinematicVmas),
        ) = fidelity.dynamics
        {
            let keyword = match keyword {
                KinematicKeyword::KinematicVmas => "kinematic-vmas",
                _ => "kinematic-rk4",
            };
            let span = ctx.span(&format!("{pointer}/dynamics"));
            ctx.push(
                Problem::error(
                    "cpmx::check::kinematic-rk4",
                    format!(
                        "fidelity `{name}` plans (`control: trajectory`), and `{keyword}` integrates only \
                         `control: direct`'s steps so far"
                    ),
                    span,
                    "control: direct only",
                )
                .with_help("use `dynamics: kinematic` here, or `control: direct`"),
            );
        }
        return;
    }
    let layers = [
        (
            "dynamics",
            "grey-box dynamics",
            matches!(fidelity.dynamics, DynamicsLayer::GreyBox(_)),
        ),
        (
            "sensing",
            "a sensing model",
            matches!(fidelity.sensing, Some(SensingLayer::Model(_))),
        ),
        (
            "actuation",
            "an actuation model",
            matches!(fidelity.actuation, Some(ActuationLayer::Model(_))),
        ),
        ("follower", "a `follower`", fidelity.follower.is_some()),
    ];
    for (key, what) in layers
        .into_iter()
        .filter(|layer| layer.2)
        .map(|(key, what, _)| (key, what))
    {
        let spans = ctx.spans(&format!("{pointer}/{key}"));
        ctx.push(
            Problem::error(
                "cpmx::check::direct-control",
                format!(
                    "fidelity `{name}` has `control: direct`, which applies actions to the kinematic bicycle with exact \
                     states; {what} needs `control: trajectory`"
                ),
                spans.key.unwrap_or(spans.value),
                "needs `control: trajectory`",
            )
            .with_help(format!(
                "set `control: trajectory` (the lab's planner and MPC follower, as a twin runs; the spec then needs a \
                 `planner`), or remove `{key}`"
            )),
        );
    }
}

/// A layer parameter given as a distribution must be one: a uniform range with `low < high`
/// inside the parameter's range, a normal with `std > 0` whose mean is in the range.
fn check_distributions(name: &str, pointer: &str, fidelity: &SimulatedFidelity, ctx: &mut CheckContext<'_>) {
    for parameter in fidelity.parameters() {
        let Parameter::Drawn(distribution) = parameter.value else {
            continue;
        };
        let at = format!("{pointer}/{}", parameter.name.replace('.', "/"));
        let what = format!("`{}` of fidelity `{name}`", parameter.name);
        check_distribution(&what, &at, distribution, parameter.range, ctx);
    }
}

/// A distribution must be one: a uniform range with `low < high` inside the parameter's range,
/// a normal with `std > 0` whose mean is in the range. `what` names the parameter
/// (`` `x` of fidelity `f` ``), `at` is its pointer.
pub(crate) fn check_distribution(
    what: &str,
    at: &str,
    distribution: Distribution,
    range: ParameterRange,
    ctx: &mut CheckContext<'_>,
) {
    let problem = match distribution {
        Distribution::Uniform([low, high]) if low.is_nan() || high.is_nan() || low >= high => Some((
            "/uniform".to_owned(),
            format!(
                "{what} is drawn from {} range [{low}, {high}]",
                if low == high { "an empty" } else { "a reversed" }
            ),
            "low must be below high".to_owned(),
            "write `{uniform: [LOW, HIGH]}` with LOW < HIGH, or the number itself".to_owned(),
        )),
        Distribution::Uniform([low, high]) if !range.contains(low) || !range.contains(high) => Some((
            "/uniform".to_owned(),
            format!("{what} is drawn from [{low}, {high}], outside its range {range}"),
            format!("outside {range}"),
            format!("keep both ends in {range}"),
        )),
        Distribution::Normal(n) if n.std.is_nan() || n.std <= 0.0 || n.std.is_infinite() => Some((
            "/normal/std".to_owned(),
            format!("{what} is drawn from a normal with standard deviation {}", n.std),
            "must be above 0".to_owned(),
            "give a positive `std`, or the number itself".to_owned(),
        )),
        Distribution::Normal(n) if !range.contains(n.mean) => Some((
            "/normal/mean".to_owned(),
            format!(
                "{what} is drawn from a normal with mean {}, outside its range {range}",
                n.mean
            ),
            format!("outside {range}"),
            format!("draws outside {range} are drawn again, so the mean must lie in it"),
        )),
        _ => None,
    };
    if let Some((suffix, message, label, help)) = problem {
        let span = ctx.span(&format!("{at}{suffix}"));
        ctx.push(Problem::error("cpmx::check::distribution", message, span, label).with_help(help));
    }
}

/// Warns about fidelities this build cannot run (they still plan; `cpmx run` refuses them);
/// when no fidelity of the spec can run, each is an error: nothing could be run.
pub(crate) fn check_capabilities(
    spec: &Spec,
    interpreter: &dyn InterpreterChecks,
    ctx: &mut CheckContext<'_>,
) {
    let unrunnable: Vec<(&String, String)> = spec
        .fidelities
        .iter()
        .filter_map(|(name, fidelity)| interpreter.cannot_run(fidelity).map(|reason| (name, reason)))
        .collect();
    let none_runs = !spec.fidelities.is_empty() && unrunnable.len() == spec.fidelities.len();
    for (name, reason) in unrunnable {
        let spans = ctx.spans(&format!("/fidelities/{}", escape_pointer(name)));
        let message = format!("this build of cpmx cannot run fidelity `{name}`: {reason}");
        let span = spans.key.unwrap_or(spans.value);
        ctx.push(if none_runs {
            Problem::error(
                "cpmx::check::unsupported-fidelity",
                message,
                span,
                "no fidelity of this spec can run here",
            )
            .with_help("add a fidelity this build runs (e.g. `sim: {control: direct, dynamics: kinematic}`)")
        } else {
            Problem::warning(
                "cpmx::check::unsupported-fidelity",
                message,
                span,
                "planned, but not runnable here",
            )
            .with_help("`cpmx run` refuses it; run the other fidelities with `--only fidelity=NAME,...`")
        });
    }
}
