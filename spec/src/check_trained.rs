//! Meaning checks of the policies that name an actor a `training:` section trains (`mlp:
//! {trained}`): one source of weights, the seed, the fidelity and the iteration among what the
//! section trains and keeps; and where the actor is found.

use std::path::PathBuf;

use crate::check::CheckContext;
use crate::check_training::key_span;
use crate::diagnostic::Problem;
use crate::model::{Spec, TrainedActor, TrainedChoice, TrainingSpec};
use crate::paths::DataPath;

/// `mlp: {trained}`, `weights` and `sigmarl`: one source of weights, and a trained actor's seed,
/// fidelity and iteration among what the spec's section trains.
pub(crate) fn check_trained_policies(spec: &Spec, ctx: &mut CheckContext<'_>) {
    for (i, p) in spec.policies.iter().enumerate() {
        let Some(mlp) = &p.mlp else { continue };
        let base = format!("/policies/{i}/mlp");
        let sources: Vec<&str> = [
            ("weights", mlp.weights.is_some()),
            ("trained", mlp.trained.is_some()),
            ("sigmarl", mlp.sigmarl.is_some()),
        ]
        .into_iter()
        .filter_map(|(key, given)| given.then_some(key))
        .collect();
        if sources.len() > 1 {
            let span = key_span(ctx, &format!("{base}/{}", sources[1]));
            ctx.push(
                Problem::error(
                    "cpmx::check::policy-kind",
                    format!(
                        "policy `{}` names its weights twice: `{}` and `{}`",
                        p.name, sources[0], sources[1]
                    ),
                    span,
                    "second source of weights",
                )
                .with_help("keep one of `weights: FILE`, `trained: {seed: N}` or `sigmarl: CHECKPOINT`"),
            );
            continue;
        }
        if mlp.pick.is_some() && mlp.sigmarl.is_none() {
            let span = key_span(ctx, &format!("{base}/pick"));
            ctx.push(
                Problem::error(
                    "cpmx::check::policy-kind",
                    format!(
                        "policy `{}` picks an actor, but names no SigmaRL checkpoint folder",
                        p.name
                    ),
                    span,
                    "pick from what?",
                )
                .with_help(
                    "`pick` goes with `sigmarl: FOLDER`; for trained actors use `trained: {which: last}`",
                ),
            );
        }
        if mlp.tag.is_some() && mlp.sigmarl.is_none() {
            let span = key_span(ctx, &format!("{base}/tag"));
            ctx.push(
                Problem::error(
                    "cpmx::check::policy-kind",
                    format!(
                        "policy `{}` gives a SigmaRL release's `tag`, but names no SigmaRL checkpoint",
                        p.name
                    ),
                    span,
                    "whose release?",
                )
                .with_help("`tag` goes with `sigmarl: CHECKPOINT`; remove it here"),
            );
        }
        match (&mlp.weights, &mlp.trained) {
            (Some(_), Some(_)) => {}
            (None, None) if mlp.sigmarl.is_some() => {}
            (None, None) => {
                let span = ctx.span(&base);
                ctx.push(
                    Problem::error(
                        "cpmx::check::policy-kind",
                        format!("policy `{}` has an `mlp` without weights", p.name),
                        span,
                        "which network?",
                    )
                    .with_help(
                        "add `weights: FILE`, `trained: {seed: N}` for an actor this spec trains, or \
                         `sigmarl: CHECKPOINT` for a SigmaRL checkpoint",
                    ),
                );
            }
            (None, Some(trained)) => match &spec.training {
                None => {
                    let span = key_span(ctx, &format!("{base}/trained"));
                    ctx.push(
                        Problem::error(
                            "cpmx::check::trained",
                            format!(
                                "policy `{}` names a trained actor, but the spec has no `training:`",
                                p.name
                            ),
                            span,
                            "nothing trains it",
                        )
                        .with_help("add a `training:` section, or name a weight file with `weights: FILE`"),
                    );
                }
                Some(t) if !t.seeds.contains(&trained.seed) => {
                    let span = ctx.span(&format!("{base}/trained/seed"));
                    let seeds: Vec<String> = t.seeds.iter().map(u64::to_string).collect();
                    ctx.push(
                        Problem::error(
                            "cpmx::check::trained",
                            format!(
                                "policy `{}` names seed {}, which `training.seeds` does not train",
                                p.name, trained.seed
                            ),
                            span,
                            "not a training seed",
                        )
                        .with_help(format!("training seeds: {}", seeds.join(", "))),
                    );
                }
                Some(t) => {
                    check_trained_fidelity(spec, t, i, trained, ctx);
                    check_trained_iteration(spec, t, i, trained, ctx);
                }
            },
            (Some(_), None) => {}
        }
    }
}

/// `trained.fidelity`: one of the fidelities the spec trains in (any of its fidelities for
/// an actor in another folder, `dir`), and needed when it trains in several.
fn check_trained_fidelity(
    spec: &Spec,
    training: &TrainingSpec,
    i: usize,
    trained: &TrainedActor,
    ctx: &mut CheckContext<'_>,
) {
    let base = format!("/policies/{i}/mlp/trained");
    let listed = training.fidelity.names();
    match &trained.fidelity {
        None if trained.dir.is_none() && training.fidelity.several() => {
            let span = key_span(ctx, &base);
            ctx.push(
                Problem::error(
                    "cpmx::check::trained",
                    format!(
                        "policy `{}` names seed {}, and the spec trains in {} fidelities",
                        spec.policies[i].name,
                        trained.seed,
                        listed.len()
                    ),
                    span,
                    "trained in which?",
                )
                .with_help(format!("add `fidelity: NAME`, one of: {}", listed.join(", "))),
            );
        }
        Some(name)
            if !listed.contains(name) && (trained.dir.is_none() || !spec.fidelities.contains_key(name)) =>
        {
            let span = ctx.span(&format!("{base}/fidelity"));
            let (what, names): (&str, Vec<String>) = if trained.dir.is_none() {
                ("`training.fidelity` does not list", listed.to_vec())
            } else {
                (
                    "the spec does not define",
                    spec.fidelities.keys().cloned().collect(),
                )
            };
            let p = Problem::error(
                "cpmx::check::trained",
                format!(
                    "policy `{}` was trained in fidelity `{name}`, which {what}",
                    spec.policies[i].name
                ),
                span,
                "unknown training fidelity",
            );
            ctx.push(match crate::schema::did_you_mean(name, &names) {
                Some(best) => p.with_suggestion(best),
                None => p.with_help(format!("one of: {}", names.join(", "))),
            });
        }
        _ => {}
    }
}

/// `trained.iteration`: an iteration the training keeps (`keep_actors_every`), within its
/// `iterations`, and not beside `which: last`.
fn check_trained_iteration(
    spec: &Spec,
    training: &TrainingSpec,
    i: usize,
    trained: &TrainedActor,
    ctx: &mut CheckContext<'_>,
) {
    let Some(iteration) = trained.iteration else {
        return;
    };
    let name = &spec.policies[i].name;
    let span = ctx.span(&format!("/policies/{i}/mlp/trained/iteration"));
    let problem = |message: String, label: &str, help: String| {
        Problem::error("cpmx::check::trained", message, span, label).with_help(help)
    };
    if trained.which == TrainedChoice::Last {
        ctx.push(problem(
            format!("policy `{name}` names both the last actor and the actor of iteration {iteration}"),
            "which one?",
            "keep `which: last` or `iteration: N`".to_owned(),
        ));
    } else if iteration > u64::from(training.iterations) {
        ctx.push(problem(
            format!(
                "policy `{name}` names the actor of iteration {iteration}, and the training has {} iterations",
                training.iterations
            ),
            "beyond the training",
            format!("an iteration up to {}", training.iterations),
        ));
    } else if !training.kept_actors().keeps(iteration) {
        let help = match training.keep_actors_every {
            None => "add `keep_actors_every: N` to `training:` and train again, or name \
                     `which: best` or `which: last`"
                .to_owned(),
            Some(every) => {
                let below = iteration / u64::from(every) * u64::from(every);
                let kept: Vec<String> = [below, below + u64::from(every)]
                    .into_iter()
                    .filter(|k| *k > 0 && *k <= u64::from(training.iterations))
                    .map(|k| k.to_string())
                    .collect();
                if kept.is_empty() {
                    format!(
                        "`keep_actors_every: {every}` keeps none of the training's {} iterations; \
                         name `which: best` or `which: last`",
                        training.iterations
                    )
                } else {
                    format!(
                        "`keep_actors_every: {every}` keeps the actors of iterations {every}, {}, …; \
                         the nearest: {}",
                        2 * u64::from(every),
                        kept.join(", ")
                    )
                }
            }
        };
        ctx.push(problem(
            format!(
                "policy `{name}` names the actor of iteration {iteration}, which the training does not keep"
            ),
            "not kept",
            help,
        ));
    }
}

/// The actor a policy's `mlp: {trained}` names: on the data path, then in the current
/// directory (where `cpmx train` writes by default). Missing is a warning, not an error, so
/// that the spec can be planned and trained first; `cpmx run` then refuses the policy.
pub(crate) fn find_trained(
    spec: &Spec,
    i: usize,
    trained: &TrainedActor,
    data: &DataPath,
    ctx: &mut CheckContext<'_>,
) -> Option<PathBuf> {
    let file = trained.relative_file(&spec.name, spec.training.as_ref());
    match data.find(&file) {
        Ok(path) => Some(path),
        Err(_) if PathBuf::from(&file).is_file() => Some(PathBuf::from(&file)),
        Err(mut tried) => {
            tried.push(PathBuf::from(&file));
            let spans = ctx.spans(&format!("/policies/{i}/mlp/trained"));
            let places: Vec<String> = tried.iter().map(|p| format!("  {}", p.display())).collect();
            ctx.push(
                Problem::warning(
                    "cpmx::check::not-trained",
                    format!(
                        "policy `{}` names the actor trained with seed {}, which is not there yet",
                        spec.policies[i].name, trained.seed
                    ),
                    spans.key.unwrap_or(spans.value),
                    "not trained yet",
                )
                .with_help(format!(
                    "looked for `{file}` in:\n{}\nrun `cpmx train` first (`cpmx run` refuses this policy until then)",
                    places.join("\n")
                )),
            );
            None
        }
    }
}
