//! `mlp: {sigmarl: ...}` policies: the checkpoint found on the data path, the actor picked from
//! its folder, the observation its `*_data.json` describes, and an XP-MARL actor's `priority:`,
//! each problem located at the policy's node and naming the file.

use std::path::{Path, PathBuf};

use crate::check::CheckContext;
use crate::check_files::{CheckScope, missing_file};
use crate::diagnostic::Problem;
use crate::model::{MlpSpec, NeighbourActions, ObservationSpec, PrioritySpec, Spec};
use crate::paths::{DataPath, sha256_hex};
use crate::sigmarl;

/// What a SigmaRL checkpoint gives a policy: its actor's file and, from its `*_data.json`,
/// its observation.
#[derive(Debug, Default)]
pub(crate) struct FoundCheckpoint {
    pub policy: Option<PathBuf>,
    pub observation: Option<ObservationSpec>,
}

/// The checkpoint of policy `i` (whose `mlp` names one).
pub(crate) fn find_checkpoint(
    spec: &Spec,
    i: usize,
    mlp: &MlpSpec,
    data: &DataPath,
    scope: CheckScope,
    ctx: &mut CheckContext<'_>,
) -> FoundCheckpoint {
    let Some(name) = &mlp.sigmarl else {
        return FoundCheckpoint::default();
    };
    let policy = &spec.policies[i];
    let pointer = format!("/policies/{i}/mlp/sigmarl");
    let path = match data.find(name) {
        Ok(path) => path,
        Err(_) if scope == CheckScope::Measure => return FoundCheckpoint::default(),
        Err(tried) => {
            let span = ctx.span(&pointer);
            ctx.push(missing_file(
                "SigmaRL checkpoint",
                name,
                &tried,
                data.option,
                span,
            ));
            return FoundCheckpoint::default();
        }
    };
    if scope == CheckScope::Measure {
        return FoundCheckpoint::default();
    }
    let files = match sigmarl::locate(&path, mlp.pick) {
        Ok(files) => files,
        Err(reason) => {
            let span = if mlp.pick.is_some() && !path.is_dir() {
                ctx.span(&format!("/policies/{i}/mlp/pick"))
            } else {
                ctx.span(&pointer)
            };
            ctx.push(
                Problem::error(
                    "cpmx::check::checkpoint",
                    format!("policy `{}`: {reason}", policy.name),
                    span,
                    "no actor here",
                )
                .with_help(
                    "name a `*_policy.pth` file, or a folder of one SigmaRL training run (`pick: best` takes \
                     `reward<r>_policy.pth`, `pick: final` takes `final_policy.pth`)",
                ),
            );
            return FoundCheckpoint::default();
        }
    };
    if let Some(expected) = &mlp.sha256 {
        check_pinned(
            &policy.name,
            &files.policy,
            expected,
            &format!("/policies/{i}/mlp/sha256"),
            ctx,
        );
    }
    let observation = match (&files.data, &policy.observation) {
        // A resolved spec (a run folder's) writes the observation out: it must be the one the
        // checkpoint's data.json describes.
        (Some(data_file), Some(given)) => {
            match observation_of(spec, i, data_file, ctx) {
                Some(derived) if derived != *given => {
                    let spans = ctx.spans(&format!("/policies/{i}/observation"));
                    ctx.push(
                    Problem::error(
                        "cpmx::check::policy-kind",
                        format!(
                            "policy `{}` gives an observation other than the one its checkpoint was trained \
                             with ({})",
                            policy.name,
                            data_file.display()
                        ),
                        spans.key.unwrap_or(spans.value),
                        "observation given twice",
                    )
                    .with_help("remove `observation:`: the actor is run as its `*_data.json` says it was trained"),
                );
                    None
                }
                derived => derived,
            }
        }
        (None, Some(given)) => Some(given.clone()),
        (None, None) => {
            let span = ctx.span(&pointer);
            ctx.push(
                Problem::error(
                    "cpmx::check::checkpoint",
                    format!(
                        "policy `{}`: no `*_data.json` beside {}, so the observation it was trained with is \
                         unknown",
                        policy.name,
                        files.policy.display()
                    ),
                    span,
                    "which observation?",
                )
                .with_help(
                    "put SigmaRL's `*_data.json` of the run beside it, or give `observation:` (e.g. \
                     `stdlib:sigmarl`) with the policy",
                ),
            );
            None
        }
        (Some(data_file), None) => observation_of(spec, i, data_file, ctx),
    };
    FoundCheckpoint {
        policy: Some(files.policy),
        observation,
    }
}

/// The observation the `parameters` of `data_file` describe, or every refusal as a problem.
fn observation_of(
    spec: &Spec,
    i: usize,
    data_file: &std::path::Path,
    ctx: &mut CheckContext<'_>,
) -> Option<ObservationSpec> {
    let policy = &spec.policies[i];
    let span = ctx.span(&format!("/policies/{i}/mlp/sigmarl"));
    let parameters = match sigmarl::read_parameters(data_file) {
        Ok(parameters) => parameters,
        Err(reason) => {
            ctx.push(
                Problem::error(
                    "cpmx::check::checkpoint",
                    format!("policy `{}`: {reason}", policy.name),
                    span,
                    "unreadable data.json",
                )
                .with_help("SigmaRL's `*_data.json` holds `{\"parameters\": {...}, ...}`"),
            );
            return None;
        }
    };
    match sigmarl::observation(&parameters, &spec.vehicle, spec.timing.dt) {
        Ok(mut observation) => {
            // The release's conventions (`tag`): 1.4.0 observes without the boundary lag.
            let tag = policy.mlp.as_ref().and_then(|m| m.tag).unwrap_or_default();
            observation.agent0_boundary_lag = tag.agent0_boundary_lag();
            Some(observation)
        }
        Err(refusals) => {
            for refusal in refusals {
                ctx.push(
                    Problem::error(
                        "cpmx::check::checkpoint-parameter",
                        format!("policy `{}` was trained with {refusal}", policy.name),
                        span,
                        "not supported",
                    )
                    .with_help(format!(
                        "{} says how the actor was trained; cpmx runs it only as trained",
                        data_file.display()
                    )),
                );
            }
            None
        }
    }
}

/// The priority network of policy `i`, and the checks that tie `priority:` to what its actor
/// observes (`derived`: the observation its checkpoint's `*_data.json` describes): only a
/// SigmaRL checkpoint trained with XP-MARL's action propagation is ranked, and it must say how.
pub(crate) fn find_priority(
    spec: &Spec,
    i: usize,
    derived: Option<&ObservationSpec>,
    data: &DataPath,
    scope: CheckScope,
    ctx: &mut CheckContext<'_>,
) -> Option<PathBuf> {
    let policy = &spec.policies[i];
    let checkpoint = policy.mlp.as_ref().filter(|m| m.sigmarl.is_some());
    let Some(mlp) = checkpoint else {
        let given = policy.observation.as_ref().map(|o| o.neighbour_actions);
        if given.is_some_and(|a| !a.is_none()) {
            let span = ctx.span(&format!("/policies/{i}/observation/neighbour_actions"));
            ctx.push(
                Problem::error(
                    "cpmx::check::policy-kind",
                    format!(
                        "policy `{}` observes its neighbours' actions, which only a SigmaRL checkpoint's actor \
                         does (cpmx trains and runs other networks without them)",
                        policy.name
                    ),
                    span,
                    "not a SigmaRL checkpoint",
                )
                .with_help("remove `neighbour_actions`, or name the checkpoint with `mlp: {sigmarl: FOLDER}`"),
            );
        }
        if policy.priority.is_some() {
            let spans = ctx.spans(&format!("/policies/{i}/priority"));
            ctx.push(
                Problem::error(
                    "cpmx::check::policy-kind",
                    format!(
                        "`priority` ranks the agents of a SigmaRL checkpoint trained with XP-MARL's action \
                         propagation, and `{}` is no SigmaRL checkpoint",
                        policy.name
                    ),
                    spans.key.unwrap_or(spans.value),
                    "nothing to rank",
                )
                .with_help("remove `priority`"),
            );
        }
        return None;
    };
    let derived = derived?;
    let actions = derived.neighbour_actions;
    let priority = match (actions, &policy.priority) {
        (NeighbourActions::Propagated, None) => {
            let span = ctx.span(&format!("/policies/{i}/mlp/sigmarl"));
            ctx.push(
                Problem::error(
                    "cpmx::check::priority",
                    format!(
                        "policy `{}` was trained with XP-MARL's action propagation (`is_using_prioritized_marl: \
                         true`): its agents act in an order that the spec must give",
                        policy.name
                    ),
                    span,
                    "ranked how?",
                )
                .with_help(
                    "add `priority: {sigmarl: FOLDER}` (SigmaRL's learned priority policy, saved beside the actor), \
                     `priority: random` or `priority: none` (no order, empty action slots)",
                ),
            );
            return None;
        }
        (NeighbourActions::None | NeighbourActions::Tentative, Some(_)) => {
            let spans = ctx.spans(&format!("/policies/{i}/priority"));
            let observes = if actions == NeighbourActions::None {
                "no actions of its neighbours"
            } else {
                "its neighbours' tentative actions (opponent modelling), which need no order"
            };
            ctx.push(
                Problem::error(
                    "cpmx::check::priority",
                    format!(
                        "`priority` orders the agents of `{}`, whose actor observes {observes}",
                        policy.name
                    ),
                    spans.key.unwrap_or(spans.value),
                    "nothing to rank",
                )
                .with_help("remove `priority`: the checkpoint's `*_data.json` says how it observes"),
            );
            return None;
        }
        (_, Some(PrioritySpec::Sigmarl(priority))) => priority,
        _ => return None,
    };
    let pointer = format!("/policies/{i}/priority/sigmarl");
    let path = match data.find(&priority.sigmarl) {
        Ok(path) => path,
        Err(_) if scope == CheckScope::Measure => return None,
        Err(tried) => {
            let span = ctx.span(&pointer);
            ctx.push(missing_file(
                "SigmaRL priority policy",
                &priority.sigmarl,
                &tried,
                data.option,
                span,
            ));
            return None;
        }
    };
    let pick = priority.pick.or(mlp.pick).unwrap_or_default();
    let file = match sigmarl::locate_priority(&path, pick) {
        Ok(file) => file,
        Err(reason) => {
            let span = ctx.span(&pointer);
            ctx.push(
                Problem::error(
                    "cpmx::check::checkpoint",
                    format!("policy `{}`: {reason}", policy.name),
                    span,
                    "no priority policy here",
                )
                .with_help(
                    "name the folder of an XP-MARL run with a learned priority policy, or rank with \
                     `priority: random` / `priority: none`",
                ),
            );
            return None;
        }
    };
    if let Some(expected) = &priority.sha256
        && !check_pinned(
            &policy.name,
            &file,
            expected,
            &format!("/policies/{i}/priority/sha256"),
            ctx,
        )
    {
        return None;
    }
    Some(file)
}

/// Whether `file` has the SHA-256 `expected` that policy `name` pins it to (at `pointer`); a
/// problem there when not.
fn check_pinned(name: &str, file: &Path, expected: &str, pointer: &str, ctx: &mut CheckContext<'_>) -> bool {
    let found = std::fs::read(file).map(|bytes| sha256_hex(&bytes));
    if found.as_deref().ok() == Some(expected) {
        return true;
    }
    let span = ctx.span(pointer);
    ctx.push(
        Problem::error(
            "cpmx::check::file-content",
            format!(
                "policy `{name}`: {} does not have sha256 {expected}",
                file.display()
            ),
            span,
            "pinned to other content",
        )
        .with_help("name the file of the pinned version, or remove `sha256` to take any"),
    );
    false
}
