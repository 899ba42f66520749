//! Meaning checks of the `training:` section: the fidelity to train in, which paths the
//! scenario uses, ranges the schema cannot relate (`lr_min` ≤ `lr`, minibatch ≤ frames, frames
//! a multiple of the environments, speed and clamp ranges), point weights, duplicate seeds.
//! The policies that name its actors are checked in `check_trained`.

use std::collections::HashSet;

use crate::check::CheckContext;
use crate::diagnostic::Problem;
use crate::model::{ActuationLayer, Control, Fidelity, Lookahead, Parameter, Spec, TrainingSpec};

/// Every check of `training:` and of `mlp: {trained}`.
pub(crate) fn check_training(spec: &Spec, ctx: &mut CheckContext<'_>) {
    crate::check_trained::check_trained_policies(spec, ctx);
    let Some(training) = &spec.training else {
        return;
    };
    check_fidelity(spec, training, ctx);
    check_scenario(training, ctx);
    check_reward(spec, training, ctx);
    check_algorithm(training, ctx);
    check_network_and_seeds(training, ctx);
}

/// The key of a node when it has one (labels read better on `key:` than on a whole object).
pub(crate) fn key_span(ctx: &CheckContext<'_>, pointer: &str) -> crate::diagnostic::ByteSpan {
    let spans = ctx.spans(pointer);
    spans.key.unwrap_or(spans.value)
}

fn check_fidelity(spec: &Spec, training: &TrainingSpec, ctx: &mut CheckContext<'_>) {
    let names = training.fidelity.names();
    let pointer = |i: usize| {
        if training.fidelity.single().is_some() {
            "/training/fidelity".to_owned()
        } else {
            format!("/training/fidelity/{i}")
        }
    };
    for (i, name) in names.iter().enumerate() {
        if names[..i].contains(name) {
            let span = ctx.span(&pointer(i));
            ctx.push(
                Problem::error(
                    "cpmx::check::training-fidelity",
                    format!("`training.fidelity` lists `{name}` twice"),
                    span,
                    "listed before",
                )
                .with_help("each fidelity trains its policies once; drop the second"),
            );
            continue;
        }
        match spec.fidelities.get(name) {
            None => {
                let defined: Vec<String> = spec.fidelities.keys().cloned().collect();
                let span = ctx.span(&pointer(i));
                let p = Problem::error(
                    "cpmx::check::training-fidelity",
                    format!("`training.fidelity` names fidelity `{name}`, which the spec does not define"),
                    span,
                    "unknown fidelity",
                );
                ctx.push(match crate::schema::did_you_mean(name, &defined) {
                    Some(best) => p.with_suggestion(best),
                    None => p.with_help(format!(
                        "fidelities: {} (the default is `sim`)",
                        defined.join(", ")
                    )),
                });
            }
            Some(Fidelity::Lab(_)) => {
                let span = ctx.span(&pointer(i));
                ctx.push(
                    Problem::error(
                        "cpmx::check::training-fidelity",
                        format!("fidelity `{name}` drives the lab; policies train in simulation only"),
                        span,
                        "a lab driver",
                    )
                    .with_help("name a simulated fidelity of this spec (e.g. `sim`)"),
                );
            }
            Some(Fidelity::Simulated(_)) => {}
        }
    }
    let plans = |name: &String| matches!(spec.fidelities.get(name), Some(Fidelity::Simulated(f)) if f.control == Control::Trajectory);
    if training.lookahead == Lookahead::Hold && !names.iter().any(plans) {
        let span = key_span(ctx, "/training/lookahead");
        ctx.push(
            Problem::warning(
                "cpmx::check::training-lookahead",
                "`lookahead: hold` concerns the planner, and no fidelity this spec trains in plans \
                 (`control: trajectory`)",
                span,
                "changes nothing here",
            )
            .with_help("train in a `control: trajectory` fidelity, or drop the key"),
        );
    }
    // Holding the learner's action over Hc where the car's commands act late makes the
    // training environment punish the delay far more than driving does (docs/transfer.md).
    let delayed = |name: &&String| {
        matches!(spec.fidelities.get(*name), Some(Fidelity::Simulated(f))
            if f.control == Control::Trajectory
                && matches!(&f.actuation, Some(ActuationLayer::Model(a)) if a.delay_ms != Parameter::Fixed(0.0)))
    };
    if training.lookahead == Lookahead::Hold
        && let Some(name) = names.iter().find(delayed)
    {
        let span = key_span(ctx, "/training/lookahead");
        ctx.push(
            Problem::warning(
                "cpmx::check::training-lookahead-delay",
                format!(
                    "`lookahead: hold` with fidelity `{name}`'s actuation delay: the sim-trained actors collide \
                     three to seven times as often in such a training environment as in one with either alone, \
                     and the actors trained so keep their lanes worse (docs/transfer.md, \"The held lookahead \
                     and the delay\")"
                ),
                span,
                "held through a delay",
            )
            .with_help(
                "with a warm start (`initial_actor`) plan as the lab does, `lookahead: actor` (the default); \
                 or train in a fidelity without `actuation`",
            ),
        );
    }
}

fn check_scenario(training: &TrainingSpec, ctx: &mut CheckContext<'_>) {
    let s = &training.scenario;
    let given = usize::from(s.path_set.is_some())
        + usize::from(s.ref_paths.is_some())
        + usize::from(s.region.is_some());
    if given == 0 || s.ref_paths.as_ref().is_some_and(Vec::is_empty) {
        let span = match &s.ref_paths {
            Some(_) => ctx.span("/training/scenario/ref_paths"),
            None => key_span(ctx, "/training/scenario"),
        };
        ctx.push(
            Problem::error(
                "cpmx::check::training-paths",
                "the training scenario names no reference paths",
                span,
                "agents have nowhere to drive",
            )
            .with_help("add `path_set: intersection` (SigmaRL's), `ref_paths: [IDS]` or `region: NAME`"),
        );
    } else if given > 1 {
        let span = key_span(ctx, "/training/scenario");
        ctx.push(
            Problem::error(
                "cpmx::check::training-paths",
                "the training scenario names its paths more than once",
                span,
                "`path_set`, `ref_paths` and `region` exclude each other",
            )
            .with_help("keep one of `path_set`, `ref_paths` and `region`"),
        );
    }
    let [low, high] = s.start.speed_mps;
    if low.partial_cmp(&high) != Some(std::cmp::Ordering::Less) {
        let span = ctx.span("/training/scenario/start/speed_mps");
        ctx.push(
            Problem::error(
                "cpmx::check::range",
                format!("the start speed range [{low}, {high}) is empty"),
                span,
                "low must be below high",
            )
            .with_help("e.g. `speed_mps: [0, 1]` (SigmaRL: U[0, 1) m/s)"),
        );
    }
}

fn check_reward(spec: &Spec, training: &TrainingSpec, ctx: &mut CheckContext<'_>) {
    let r = &training.reward;
    if let Some(a) = &r.near_agents
        && a.from_m.partial_cmp(&a.to_m) != Some(std::cmp::Ordering::Less)
    {
        let span = ctx.span("/training/reward/near_agents/to_m");
        ctx.push(
            Problem::error(
                "cpmx::check::range",
                format!(
                    "the near-agents ramp from {} m to {} m is empty",
                    a.from_m, a.to_m
                ),
                span,
                "not beyond `from_m`",
            )
            .with_help("the penalty falls from `from_m` to `to_m`, e.g. `{from_m: 0.16, to_m: 0.33}`"),
        );
    }
    if let Some(c) = &r.steering_change {
        let limit_rad = spec.vehicle.max_steering_deg.to_radians();
        if c.threshold_rad >= limit_rad {
            let span = ctx.span("/training/reward/steering_change/threshold_rad");
            ctx.push(
                Problem::error(
                    "cpmx::check::range",
                    format!(
                        "a steering-change threshold of {} rad is not below the vehicle's steering limit ({limit_rad:.5} rad)",
                        c.threshold_rad
                    ),
                    span,
                    "the penalty divides by 2 (limit - threshold)",
                )
                .with_help("e.g. `threshold_rad: 0.17453` (10°, SigmaRL's)"),
            );
        }
    }
    if (r.velocity_to_points.is_some() || r.time.is_some()) && r.progress.is_none() {
        let at = if r.velocity_to_points.is_some() {
            "velocity_to_points"
        } else {
            "time"
        };
        let span = key_span(ctx, &format!("/training/reward/{at}"));
        ctx.push(
            Problem::error(
                "cpmx::check::reward",
                format!("`{at}` needs the short-term reference points of `progress`"),
                span,
                "towards which points?",
            )
            .with_help(
                "add `progress: {weight: 0, points: 3}` to define the points without rewarding progress",
            ),
        );
    }
    if let Some([low, high]) = r.clamp
        && !matches!(
            low.partial_cmp(&high),
            Some(std::cmp::Ordering::Less | std::cmp::Ordering::Equal)
        )
    {
        let span = ctx.span("/training/reward/clamp");
        ctx.push(
            Problem::error(
                "cpmx::check::range",
                format!("the reward clamp [{low}, {high}] is empty"),
                span,
                "low above high",
            )
            .with_help("e.g. `clamp: [-1, 1]`"),
        );
    }
    if let Some(p) = &r.progress
        && let Some(w) = &p.point_weights
        && w.len() != p.points as usize
    {
        let span = ctx.span("/training/reward/progress/point_weights");
        ctx.push(
            Problem::error(
                "cpmx::check::reward",
                format!("{} point weights for {} progress points", w.len(), p.points),
                span,
                format!("{} weights", w.len()),
            )
            .with_help("give one weight per point, or leave `point_weights` out for SigmaRL's"),
        );
    }
    let any = r.progress.is_some()
        || r.near_boundary.is_some()
        || r.near_agents.is_some()
        || r.near_agents_ttc.is_some()
        || r.speed.is_some()
        || r.centre_line.is_some()
        || r.velocity_to_points.is_some()
        || r.time.is_some()
        || r.steering_change.is_some()
        || r.cbf_margins.is_some()
        || r.collide_agents.is_some()
        || r.collide_boundary.is_some();
    if !any {
        let span = key_span(ctx, "/training/reward");
        ctx.push(
            Problem::error(
                "cpmx::check::reward",
                "the reward has no terms",
                span,
                "always 0",
            )
            .with_help("add terms (`progress`, `near_boundary`, `near_agents_ttc`, `collide_agents`, `collide_boundary`), or use `stdlib:sigmarl-reward`"),
        );
    }
}

fn check_algorithm(training: &TrainingSpec, ctx: &mut CheckContext<'_>) {
    let m = &training.algorithm.mappo;
    if m.lr_min > m.lr {
        let span = ctx.span("/training/algorithm/mappo/lr_min");
        ctx.push(
            Problem::error(
                "cpmx::check::range",
                format!("`lr_min` = {} exceeds `lr` = {}", m.lr_min, m.lr),
                span,
                "lr_min > lr",
            )
            .with_help("the learning rate decays from `lr` towards `lr_min`: lr_min ≤ lr"),
        );
    }
    if m.minibatch > m.frames_per_iteration {
        let span = ctx.span("/training/algorithm/mappo/minibatch");
        ctx.push(
            Problem::error(
                "cpmx::check::range",
                format!(
                    "a minibatch of {} env-steps exceeds the {} collected per iteration",
                    m.minibatch, m.frames_per_iteration
                ),
                span,
                "minibatch > frames_per_iteration",
            )
            .with_help("minibatches are drawn from one iteration's batch: minibatch ≤ frames_per_iteration"),
        );
    }
    if m.critic_warmup_iterations >= training.iterations {
        let span = ctx.span("/training/algorithm/mappo/critic_warmup_iterations");
        ctx.push(
            Problem::error(
                "cpmx::check::range",
                format!(
                    "a critic warm-up of {} iterations leaves none of the {} `iterations` to the actor",
                    m.critic_warmup_iterations, training.iterations
                ),
                span,
                "not fewer than `iterations`",
            )
            .with_help("the actor learns after the warm-up: critic_warmup_iterations < iterations"),
        );
    }
    let envs = training.scenario.envs;
    if envs > 0 && !m.frames_per_iteration.is_multiple_of(envs) {
        let span = ctx.span("/training/algorithm/mappo/frames_per_iteration");
        ctx.push(
            Problem::error(
                "cpmx::check::range",
                format!(
                    "{} frames per iteration do not split evenly over {} environments",
                    m.frames_per_iteration, envs
                ),
                span,
                "not a multiple of `envs`",
            )
            .with_help(format!(
                "every environment collects the same number of steps: use a multiple of {envs}"
            )),
        );
    }
}

fn check_network_and_seeds(training: &TrainingSpec, ctx: &mut CheckContext<'_>) {
    // What training environments observe: SigmaRL's design without sensor noise or actions.
    let observation = &training.observation;
    for (key, given) in [
        ("uniform_noise", observation.uniform_noise > 0.0),
        ("neighbour_actions", !observation.neighbour_actions.is_none()),
    ] {
        if given {
            let span = ctx.span(&format!("/training/observation/{key}"));
            ctx.push(
                Problem::error(
                    "cpmx::check::training-observation",
                    format!("training environments do not observe with `{key}` yet"),
                    span,
                    "not in training",
                )
                .with_help(format!("remove `{key}` from the training's observation")),
            );
        }
    }
    for (i, width) in training.network.hidden.iter().enumerate() {
        if *width == 0 {
            let span = ctx.span(&format!("/training/network/hidden/{i}"));
            ctx.push(Problem::error(
                "cpmx::check::network",
                "a hidden layer of width 0",
                span,
                "no units",
            ));
        }
    }
    let mut seen = HashSet::new();
    for (i, seed) in training.seeds.iter().enumerate() {
        if !seen.insert(seed) {
            let span = ctx.span(&format!("/training/seeds/{i}"));
            ctx.push(
                Problem::error(
                    "cpmx::check::duplicate-name",
                    format!("seed {seed} is listed twice"),
                    span,
                    "second use",
                )
                .with_help("each seed trains one policy into its own folder"),
            );
        }
    }
}
