//! `mlp: {sigmarl: ...}` policies: the checkpoint found on the data path, the actor picked from
//! its folder, and the observation its `*_data.json` describes, each problem located at the
//! policy's node and naming the file.

use std::path::PathBuf;

use crate::check::CheckContext;
use crate::check_files::{CheckScope, missing_file};
use crate::diagnostic::Problem;
use crate::model::{MlpSpec, ObservationSpec, Spec};
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
        let found = std::fs::read(&files.policy).map(|bytes| sha256_hex(&bytes));
        if found.as_ref().ok() != Some(expected) {
            let span = ctx.span(&format!("/policies/{i}/mlp/sha256"));
            ctx.push(
                Problem::error(
                    "cpmx::check::file-content",
                    format!(
                        "policy `{}`: {} does not have sha256 {expected}",
                        policy.name,
                        files.policy.display()
                    ),
                    span,
                    "pinned to other content",
                )
                .with_help("name the checkpoint of the pinned version, or remove `sha256` to take any"),
            );
        }
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
