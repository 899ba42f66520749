//! Whether the actor a policy names with `mlp: {trained}` was trained by the spec's
//! `training:` section as it stands: the fingerprint its folder's `run.json` recorded against
//! the one the section gives now (training section for the fidelity trained in, vehicle,
//! `timing.dt`, map content; see [`TrainingSetup::prepare`]). A spec edited after training
//! would otherwise evaluate actors that its training section did not make.

use std::collections::HashMap;
use std::path::Path;

use cpmx_spec::CheckedSpec;

use crate::{RunInfo, TrainingSetup};

/// How a trained actor relates to the spec's training section.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Provenance {
    /// `run.json` records the fingerprint the section gives now.
    Same,
    /// `run.json` records another fingerprint: other inputs trained the actor.
    Other {
        /// The fingerprint `run.json` records.
        recorded: String,
        /// The fingerprint of the spec's section.
        expected: String,
    },
    /// No readable `run.json` beside the actor: nothing says what trained it.
    Unrecorded,
}

/// The provenance of every policy that names a trained actor the checks found, by policy
/// index. Policies of another kind, actors not there yet, and fidelities the section cannot
/// train in (then `cpmx train` says why) are left out; a spec without `training:` has none.
pub fn trained_actors(checked: &CheckedSpec) -> Vec<(usize, Provenance)> {
    let Some(training) = &checked.spec.training else {
        return Vec::new();
    };
    let mut setups: HashMap<(String, String), Option<TrainingSetup>> = HashMap::new();
    let mut out = Vec::new();
    for (i, policy) in checked.spec.policies.iter().enumerate() {
        let Some(trained) = policy.mlp.as_ref().and_then(|m| m.trained.as_ref()) else {
            continue;
        };
        let Some(actor) = checked.resources.weights.get(i).and_then(Option::as_ref) else {
            continue;
        };
        let fidelity = trained
            .fidelity
            .clone()
            .unwrap_or_else(|| training.fidelity.names()[0].clone());
        let point = trained.point.clone().unwrap_or_default();
        let setup = setups
            .entry((fidelity.clone(), point.clone()))
            .or_insert_with(|| TrainingSetup::prepare_at(checked, &fidelity, &point).ok());
        let Some(expected) = setup.as_ref().and_then(|s| s.fingerprint(trained.seed)) else {
            continue;
        };
        out.push((i, provenance_of(actor, expected)));
    }
    out
}

/// The provenance of the actor file `actor` against the fingerprint `expected`.
fn provenance_of(actor: &Path, expected: &str) -> Provenance {
    let info: Option<RunInfo> = actor
        .parent()
        .and_then(|dir| std::fs::read(dir.join("run.json")).ok())
        .and_then(|bytes| serde_json::from_slice(&bytes).ok());
    match info {
        None => Provenance::Unrecorded,
        Some(info) if info.fingerprint == expected => Provenance::Same,
        Some(info) => Provenance::Other {
            recorded: info.fingerprint,
            expected: expected.to_owned(),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_recorded_fingerprint_decides() {
        let dir = std::env::temp_dir().join(format!("cpmx-provenance-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let actor = dir.join("actor.safetensors");
        assert_eq!(provenance_of(&actor, "abc"), Provenance::Unrecorded);
        let info = |fingerprint: &str| {
            format!(
                r#"{{"spec": "s", "seed": 1, "fingerprint": "{fingerprint}", "iterations_done": 2,
                "iterations_planned": 2, "best_episode_reward_mean": 0.1, "best_iteration": 2,
                "made_by": ["cpmx"]}}"#
            )
        };
        std::fs::write(dir.join("run.json"), info("abc")).unwrap();
        assert_eq!(provenance_of(&actor, "abc"), Provenance::Same);
        assert_eq!(
            provenance_of(&actor, "def"),
            Provenance::Other {
                recorded: "abc".into(),
                expected: "def".into()
            }
        );
        std::fs::write(dir.join("run.json"), "{not json").unwrap();
        assert_eq!(provenance_of(&actor, "abc"), Provenance::Unrecorded);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
