//! The actors the repository ships (`experiments/policies/`) are the ones the experiments'
//! own `training:` sections trained: each folder's `run.json` carries the fingerprint of every
//! input that shaped the weights (the resolved training section for its fidelity, vehicle,
//! `timing.dt`, map content, and for a `control: trajectory` fidelity its layers and the
//! planner), which must equal the fingerprint of the spec as it stands; every planned
//! iteration was trained, the curve has a row per iteration, and the best actor is the one
//! SigmaRL's rule picks from that curve.

mod support;

use std::path::Path;

use cpmx_spec::{DataPath, SpecSource};
use cpmx_train::TrainingSetup;
use support::{reference, root};

/// Checks every shipped actor of the `mlp: {trained}` policies of `spec`; returns how many it
/// checked.
fn check_shipped(spec: &str) -> usize {
    let path = root().join(spec);
    let source = SpecSource::read(&path).unwrap();
    let data = DataPath::new(path.parent().unwrap(), &[reference()], None);
    let checked = cpmx_spec::check(&source, &data, &cpmx_engine::BuildChecks)
        .unwrap_or_else(|e| panic!("{spec}: {}", cpmx_spec::render(&e, false)));
    let training = checked.spec.training.as_ref().expect("a training section");
    let mut count = 0;
    for policy in &checked.spec.policies {
        let Some(trained) = policy.mlp.as_ref().and_then(|m| m.trained.as_ref()) else {
            continue;
        };
        let fidelity = trained
            .fidelity
            .clone()
            .unwrap_or_else(|| training.fidelity.names()[0].clone());
        let setup = TrainingSetup::prepare(&checked, &fidelity).unwrap();
        let actor = path
            .parent()
            .unwrap()
            .join(trained.relative_file(&checked.spec.name, Some(training)));
        let dir = actor.parent().unwrap();
        let what = format!("{spec}: policy `{}` ({})", policy.name, dir.display());
        if !actor.is_file() {
            // Not shipped (yet): the callers count the policies they expect.
            continue;
        }
        let run: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.join("run.json")).unwrap()).unwrap();
        assert_eq!(
            run["fingerprint"],
            setup.fingerprint(trained.seed).unwrap(),
            "{what}: trained by other inputs than the spec's (training section, vehicle, dt, map)"
        );
        assert_eq!(run["seed"], trained.seed, "{what}");
        let planned = setup.hyperparameters.n_iters;
        assert_eq!(run["iterations_done"], planned, "{what}: not trained to the end");
        assert_eq!(run["iterations_planned"], planned, "{what}");
        let made_by = run["made_by"].as_array().expect("made_by");
        assert!(
            !made_by.is_empty() && made_by.iter().all(|b| b.as_str().unwrap().contains("(commit ")),
            "{what}: names the commits that trained it"
        );
        check_curve(dir, planned, &run, &what);
        count += 1;
    }
    count
}

/// A row per iteration, and `run.json`'s best is the curve's highest `episode_reward_mean`
/// (the first of equals), as SigmaRL picks its best policy.
fn check_curve(dir: &Path, planned: u64, run: &serde_json::Value, what: &str) {
    let text = std::fs::read_to_string(dir.join("learning_curve.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (iteration, reward) = (column("iteration"), column("episode_reward_mean"));
    let rows: Vec<(u64, f64)> = lines
        .map(|l| {
            let cells: Vec<&str> = l.split(',').collect();
            (cells[iteration].parse().unwrap(), cells[reward].parse().unwrap())
        })
        .collect();
    assert_eq!(rows.len() as u64, planned, "{what}: curve rows");
    assert!(
        rows.iter().zip(1..).all(|(r, i)| r.0 == i),
        "{what}: iterations in order"
    );
    let best = rows
        .iter()
        .fold(rows[0], |best, &row| if row.1 > best.1 { row } else { best });
    assert_eq!(run["best_iteration"], best.0, "{what}: best iteration");
    assert_eq!(run["best_episode_reward_mean"], best.1, "{what}: best reward");
}

#[test]
fn the_shipped_actors_were_trained_by_the_experiments_training_sections() {
    // at25's three seeds as sim, and seeds 1-3 of sim-mpc and of the randomised twin.
    assert_eq!(check_shipped("experiments/transfer.yaml"), 9);
    assert_eq!(check_shipped("experiments/transfer-twin.yaml"), 3);
    assert_eq!(check_shipped("experiments/transfer-twin-no-delay.yaml"), 3);
    assert_eq!(check_shipped("experiments/transfer-twin-actor-lookahead.yaml"), 3);
    // The control: the sim actors continued in sim; its best actors and its last.
    assert_eq!(check_shipped("experiments/transfer-sim-continuation.yaml"), 6);
    assert_eq!(check_shipped("experiments/at25-cpmx.yaml"), 3);
    assert_eq!(check_shipped("experiments/domain-shift.yaml"), 3);
    assert_eq!(check_shipped("experiments/communication.yaml"), 1);
    assert_eq!(check_shipped("experiments/cbf-training.yaml"), 2);
    // The paper preset's seeds 1, 2 and 4 (the paper's training seeds).
    assert_eq!(check_shipped("experiments/at25-paper-training.yaml"), 3);
}

/// `training.lookahead` enters a fingerprint only where it changes what trains: a planning
/// fidelity with `hold`. Written as the default, or for SigmaRL's simulation, it leaves the
/// fingerprint as it was before the key existed (and the shipped actors' with it).
#[test]
fn the_lookahead_changes_only_a_planning_fidelitys_fingerprint() {
    let path = root().join("experiments/transfer.yaml");
    let shipped = SpecSource::read(&path).unwrap();
    assert!(shipped.text.contains("\n  lookahead: hold\n"));
    let fingerprints = |lookahead: &str| -> Vec<String> {
        let source = SpecSource {
            text: shipped.text.replace("\n  lookahead: hold\n", lookahead),
            ..shipped.clone()
        };
        let data = DataPath::new(path.parent().unwrap(), &[reference()], None);
        let checked = cpmx_spec::check(&source, &data, &cpmx_engine::BuildChecks).unwrap();
        ["sim", "sim-mpc", "twin-random"]
            .map(|f| {
                TrainingSetup::prepare(&checked, f)
                    .unwrap()
                    .fingerprint(1)
                    .unwrap()
                    .to_owned()
            })
            .to_vec()
    };
    let held = fingerprints("\n  lookahead: hold\n");
    let default = fingerprints("\n");
    assert_eq!(fingerprints("\n  lookahead: actor\n"), default);
    assert_eq!(held[0], default[0], "sim has no planner");
    assert_ne!(held[1], default[1]);
    assert_ne!(held[2], default[2]);
}
