//! Which runs of a selection an engine computes together: runs of one fidelity whose engine
//! steps runs in lock-step (the twin's MPCs in SIMD lanes) share groups as large as the lanes
//! fill, without leaving a thread idle; every other run is a group of its own.

use std::collections::BTreeMap;

use cpmx_spec::RunPlan;

use crate::engine::engine_for;
use crate::experiment::Experiment;

/// The vehicles a group of runs stepped in lock-step fills: three passes of eight lanes.
const LOCKSTEP_VEHICLES: usize = 3 * cpmx_follower::WIDEST_LANES;

/// The selection's runs in groups (see [`group_runs`]): runs of one fidelity whose engine steps
/// runs together ([`crate::engine::Engine::steps_together`]) share groups, every other run is
/// alone. Which runs share a group changes no run's bits.
pub(crate) fn lockstep_groups(
    experiment: &Experiment,
    selected: &[&RunPlan],
    jobs: usize,
) -> Vec<Vec<usize>> {
    let runs: Vec<(Option<&str>, usize)> = selected
        .iter()
        .map(|plan| {
            let steps_together = experiment
                .spec
                .fidelities
                .get(&plan.fidelity)
                .and_then(|fidelity| engine_for(&plan.fidelity, fidelity).ok())
                .is_some_and(|engine| engine.steps_together());
            let vehicles = experiment.start(plan).map_or(1, <[_]>::len);
            (steps_together.then_some(plan.fidelity.as_str()), vehicles)
        })
        .collect();
    group_runs(&runs, jobs)
}

/// Groups runs given as (the key of the runs they may step with, if any; their vehicles), in
/// the order of each group's first run: runs of one key in groups of up to
/// [`LOCKSTEP_VEHICLES`] vehicles and, on several threads, of at most 1/(2 × jobs) of the key's
/// runs (so that each thread gets two of its groups); runs without a key alone.
fn group_runs(runs: &[(Option<&str>, usize)], jobs: usize) -> Vec<Vec<usize>> {
    let mut per_key: BTreeMap<&str, usize> = BTreeMap::new();
    for key in runs.iter().filter_map(|(key, _)| *key) {
        *per_key.entry(key).or_default() += 1;
    }
    let mut groups: Vec<Vec<usize>> = Vec::new();
    // The group still filling for each key, and its vehicles.
    let mut filling: BTreeMap<&str, (usize, usize)> = BTreeMap::new();
    for (index, &(key, vehicles)) in runs.iter().enumerate() {
        let Some(key) = key else {
            groups.push(vec![index]);
            continue;
        };
        let most_runs = if jobs > 1 {
            per_key[key].div_ceil(2 * jobs)
        } else {
            per_key[key]
        };
        let vehicles = vehicles.max(1);
        let open = filling.get(key).copied().filter(|&(group, group_vehicles)| {
            groups[group].len() < most_runs && group_vehicles + vehicles <= LOCKSTEP_VEHICLES
        });
        match open {
            Some((group, group_vehicles)) => {
                groups[group].push(index);
                filling.insert(key, (group, group_vehicles + vehicles));
            }
            None => {
                filling.insert(key, (groups.len(), vehicles));
                groups.push(vec![index]);
            }
        }
    }
    groups
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_of_a_key_share_groups_up_to_the_lanes_and_the_threads() {
        // at25's matrix order: the fidelity varies fastest; sim alone, twin and sim-mpc together.
        let runs: Vec<(Option<&str>, usize)> = (0..27)
            .flat_map(|_| [(None, 3), (Some("sim-mpc"), 3), (Some("twin"), 3)])
            .collect();
        let one_thread = group_runs(&runs, 1);
        let sizes = |groups: &[Vec<usize>], key: &str| -> Vec<usize> {
            groups
                .iter()
                .filter(|g| runs[g[0]].0 == Some(key))
                .map(Vec::len)
                .collect()
        };
        // Eight runs of three cars fill 24 lanes.
        assert_eq!(sizes(&one_thread, "twin"), [8, 8, 8, 3]);
        assert_eq!(sizes(&group_runs(&runs, 2), "twin"), [7, 7, 7, 6]);
        assert_eq!(sizes(&one_thread, "sim-mpc"), [8, 8, 8, 3]);
        for groups in [one_thread, group_runs(&runs, 2)] {
            assert_eq!(groups.iter().filter(|g| runs[g[0]].0.is_none()).count(), 27);
            assert!(
                groups
                    .iter()
                    .all(|g| g.iter().all(|&i| runs[i].0 == runs[g[0]].0))
            );
            assert!(groups.iter().all(|g| g.windows(2).all(|w| w[0] < w[1])));
            assert!(groups.windows(2).all(|w| w[0][0] < w[1][0]));
            let mut every: Vec<usize> = groups.concat();
            every.sort_unstable();
            assert_eq!(every, (0..runs.len()).collect::<Vec<_>>());
        }
        // A run larger than the lanes is a group of its own.
        assert_eq!(
            group_runs(&[(Some("a"), 30), (Some("a"), 30)], 1),
            [vec![0], vec![1]]
        );
    }
}
