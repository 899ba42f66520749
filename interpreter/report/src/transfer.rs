//! The transfer matrix: policies trained in different fidelities, evaluated in every
//! fidelity. For each fidelity a run was evaluated in, its runs are grouped by the fidelity
//! their policy was trained in (a cell of the matrix, over its independent units), and each
//! training fidelity is compared with the reference one in paired runs: the same training
//! seed, initial configuration and repetition (`compare`'s pairing, with the training
//! fidelity in the place of the fidelity and the training seed in the place of the policy).
//!
//! This module owns which runs form a cell and a pair; the statistics are `aggregate`'s and
//! `compare`'s.

use std::collections::BTreeMap;

use cpmx_spec::model::{GroupKey, ReportSpec};

use crate::RunRecord;
use crate::aggregate::{Group, group_runs, summarize_group};
use crate::compare::{Comparison, compare};
use crate::metric::Units;

/// Where a policy comes from: the fidelity it was trained in and the training seed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Origin {
    /// The fidelity `cpmx train` trained it in.
    pub trained_in: String,
    /// Its training seed.
    pub seed: u64,
}

/// The matrix and its comparisons.
#[derive(Debug, Clone, PartialEq)]
pub struct Transfer {
    /// Fidelities trained in, the reference first.
    pub trained_in: Vec<String>,
    /// Fidelities evaluated in, in order of their first run.
    pub evaluated_in: Vec<String>,
    /// One cell per evaluated and trained fidelity that has runs, evaluated-major.
    pub cells: Vec<TransferCell>,
    /// Per evaluated fidelity, every training fidelity against the reference one.
    pub comparisons: Vec<(String, Comparison)>,
}

/// The runs of policies trained in one fidelity, evaluated in one fidelity.
#[derive(Debug, Clone, PartialEq)]
pub struct TransferCell {
    /// The fidelity the policies were trained in.
    pub trained_in: String,
    /// The fidelity the runs were evaluated in.
    pub evaluated_in: String,
    /// Their statistics (the group's key is `[trained_in]`).
    pub group: Group,
}

impl Transfer {
    /// The cell of one training and one evaluation fidelity.
    pub fn cell(&self, trained_in: &str, evaluated_in: &str) -> Option<&TransferCell> {
        self.cells
            .iter()
            .find(|c| c.trained_in == trained_in && c.evaluated_in == evaluated_in)
    }
}

/// The transfer matrix of `runs`, when their policies were trained in at least two
/// fidelities (`origins` by policy name; other policies are left out); `reference` is the
/// training fidelity the others are compared with (else the first one met).
pub fn transfer(
    runs: &[RunRecord],
    origins: &BTreeMap<String, Origin>,
    reference: Option<&str>,
    report: &ReportSpec,
    units: Units,
) -> Option<Transfer> {
    let mut trained_in: Vec<String> = Vec::new();
    let mut evaluated_in: Vec<String> = Vec::new();
    // The runs with the training fidelity in the place of the fidelity and the training seed
    // in the place of the policy, by evaluated fidelity.
    let mut relabelled: Vec<(String, RunRecord)> = Vec::new();
    for run in runs {
        let Some(origin) = origins.get(&run.plan.policy) else {
            continue;
        };
        if !trained_in.contains(&origin.trained_in) {
            trained_in.push(origin.trained_in.clone());
        }
        if !evaluated_in.contains(&run.plan.fidelity) {
            evaluated_in.push(run.plan.fidelity.clone());
        }
        let mut as_trained = run.clone();
        as_trained.plan.fidelity = origin.trained_in.clone();
        as_trained.plan.policy = format!("seed {}", origin.seed);
        relabelled.push((run.plan.fidelity.clone(), as_trained));
    }
    if trained_in.len() < 2 {
        return None;
    }
    if let Some(at) = reference.and_then(|r| trained_in.iter().position(|t| t == r)) {
        let first = trained_in.remove(at);
        trained_in.insert(0, first);
    }
    let with_bootstrap = report
        .statistics
        .contains(&cpmx_spec::model::Statistic::Bootstrap)
        .then_some(&report.bootstrap);
    let mut cells = Vec::new();
    let mut comparisons = Vec::new();
    for evaluated in &evaluated_in {
        let subset: Vec<RunRecord> = relabelled
            .iter()
            .filter(|(e, _)| e == evaluated)
            .map(|(_, r)| r.clone())
            .collect();
        for (key, members) in group_runs(&subset, &[GroupKey::Fidelity]) {
            cells.push(TransferCell {
                trained_in: key[0].clone(),
                evaluated_in: evaluated.clone(),
                group: summarize_group(key, &members, units, with_bootstrap),
            });
        }
        comparisons.push((
            evaluated.clone(),
            compare(&subset, &trained_in[0], &report.bootstrap, false),
        ));
    }
    Some(Transfer {
        trained_in,
        evaluated_in,
        cells,
        comparisons,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metric::Metric;
    use crate::testing::{record, spec};

    fn origins() -> BTreeMap<String, Origin> {
        [
            ("a1", "sim", 1),
            ("a2", "sim", 2),
            ("b1", "twin", 1),
            ("b2", "twin", 2),
        ]
        .into_iter()
        .map(|(policy, fidelity, seed)| {
            (
                policy.to_owned(),
                Origin {
                    trained_in: fidelity.to_owned(),
                    seed,
                },
            )
        })
        .collect()
    }

    #[test]
    fn cells_group_by_training_fidelity_and_pairs_match_training_seeds() {
        let mut runs = Vec::new();
        for (k, evaluated) in ["sim", "twin"].into_iter().enumerate() {
            for (policy, speed) in [("a1", 0.5), ("a2", 0.6), ("b1", 0.7), ("b2", 0.9)] {
                for init in ["i1", "i2"] {
                    let cd = 0.01 * (k + 1) as f64;
                    runs.push(record(
                        evaluated,
                        policy,
                        init,
                        1,
                        [0.0, 10.0, cd, speed + 0.01 * k as f64],
                    ));
                }
            }
        }
        // A policy of unknown origin is left out.
        runs.push(record("sim", "other", "i1", 1, [0.0, 10.0, 0.5, 0.1]));
        let report = spec(&[GroupKey::Fidelity], false, None);
        let units = Units::of_runs(runs.iter().map(|r| &r.metrics));
        let t = transfer(&runs, &origins(), Some("twin"), &report, units).expect("two training fidelities");
        assert_eq!(t.trained_in, ["twin", "sim"], "the reference first");
        assert_eq!(t.evaluated_in, ["sim", "twin"]);
        let cell = t.cell("sim", "twin").unwrap();
        assert_eq!(cell.group.units, 4);
        let speed = cell.group.metric(Metric::As).unwrap().stats.mean;
        assert!((speed - 0.56).abs() < 1e-12, "{speed}");
        // sim-trained against twin-trained, evaluated in sim: pairs by seed and configuration.
        let (evaluated, comparison) = &t.comparisons[0];
        assert_eq!(evaluated, "sim");
        assert_eq!(comparison.reference, "twin");
        let paired = &comparison.fidelities[0].metrics[3];
        assert_eq!(paired.pairs, 4);
        assert!(
            (paired.mean_difference - -0.25).abs() < 1e-12,
            "{}",
            paired.mean_difference
        );
        // One training fidelity is no matrix.
        let sim_only: BTreeMap<String, Origin> = origins()
            .into_iter()
            .filter(|(_, o)| o.trained_in == "sim")
            .collect();
        assert!(transfer(&runs, &sim_only, None, &report, units).is_none());
    }
}
