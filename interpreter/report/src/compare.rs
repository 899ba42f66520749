//! The paired comparison of every fidelity with a reference fidelity, over runs that share
//! their policy, initial configuration and repetition (`RunPlan::pair_key`), or of every policy
//! with a reference policy, over runs that share their fidelity, initial configuration and
//! repetition.
//!
//! A pair whose two recordings are bit-identical to those of an earlier pair of the same
//! policy and initial configuration is a copy (both fidelities deterministic) and is used
//! once: the tests count independent pairs, not repetitions of one.
//!
//! This module owns which runs are paired and which way a difference points (test minus
//! reference); the statistics come from `cpmx_metrics::stats`.

use std::collections::{BTreeMap, BTreeSet};

use cpmx_metrics::stats::{self, Interval};
use cpmx_spec::model::Bootstrap;
use cpmx_spec::sweep::{is_reference, paired_reference};

use crate::RunRecord;
use crate::aggregate::CONFIDENCE;
use crate::metric::Metric;
use rayon::prelude::*;

/// Which axis of the run matrix a comparison runs along: every other fidelity with a
/// reference fidelity (the sim-to-real question), or every other policy with a reference policy
/// (which model is better, in each fidelity). The pairs share every other axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ComparedAxis {
    Fidelity,
    Policy,
}

impl ComparedAxis {
    /// The axis's name, as a table's column says it.
    pub fn name(self) -> &'static str {
        match self {
            ComparedAxis::Fidelity => "fidelity",
            ComparedAxis::Policy => "policy",
        }
    }

    /// The other axis of the two, within whose values the pairs are compared.
    pub fn other(self) -> ComparedAxis {
        match self {
            ComparedAxis::Fidelity => ComparedAxis::Policy,
            ComparedAxis::Policy => ComparedAxis::Fidelity,
        }
    }
}

/// Every other fidelity (or policy) compared with the reference.
#[derive(Debug, Clone, PartialEq)]
pub struct Comparison {
    /// Along which axis.
    pub axis: ComparedAxis,
    /// The reference fidelity or policy (`report.compare.reference`).
    pub reference: String,
    /// Runs of the reference found (0 when it is missing from the runs).
    pub reference_runs: usize,
    /// One entry per other fidelity (policy), in order of first appearance.
    pub fidelities: Vec<FidelityComparison>,
}

/// One fidelity (policy) against the reference, within one policy's (fidelity's) runs, or
/// every one's when pooled.
#[derive(Debug, Clone, PartialEq)]
pub struct FidelityComparison {
    /// The compared ("test") fidelity, or policy along [`ComparedAxis::Policy`].
    pub fidelity: String,
    /// The policy whose runs are paired (the fidelity along [`ComparedAxis::Policy`]), or
    /// `None` when the pairs pool them (a `group_by` without that axis, as at25 pools its
    /// training seeds).
    pub policy: Option<String>,
    /// One entry per metric the runs measure, in table order ([`crate::Units::metrics`]).
    pub metrics: Vec<PairedMetric>,
}

/// One metric of one fidelity against the reference, over matched runs.
#[derive(Debug, Clone, PartialEq)]
pub struct PairedMetric {
    /// Which metric.
    pub metric: Metric,
    /// Independent matched pairs used (no NaN on either side, copies counted once).
    pub pairs: usize,
    /// Matched pairs left out as copies of an earlier pair (both recordings identical).
    pub copies: usize,
    /// Distinct runs of the reference fidelity among the pairs used (fewer than `pairs` when
    /// a deterministic reference is paired with a stochastic fidelity).
    pub reference_units: usize,
    /// Runs whose pair key is present on one side only.
    pub unmatched: usize,
    /// Matched pairs dropped because a value was NaN.
    pub nan_pairs: usize,
    /// Mean of `test − reference` over the pairs (NaN without pairs).
    pub mean_difference: f64,
    /// Paired percentile bootstrap 95 % CI of that mean.
    pub ci95_bootstrap: Interval,
    /// Two-sided Wilcoxon signed-rank p-value of the differences.
    pub wilcoxon_p: f64,
    /// Differences above, below and equal to zero.
    pub signs: Signs,
    /// Probability that a paired run of the test fidelity is better than one of the
    /// reference (Mann-Whitney over the paired values; the direction is the metric's:
    /// lower CRA-A, CRA-L, CD, higher AS). 0.5 means no difference.
    pub probability_of_improvement: f64,
}

/// Compares every fidelity of `runs` other than `reference` with it (points of a sweep with
/// the reference at the same point, see [`paired_reference`]): per policy when `by_policy` (as a
/// summary grouped by policy reads), else pooling the policies' pairs.
///
/// Each bootstrap interval uses `ChaCha8Rng::seed_from_u64(bootstrap.seed)` afresh, so any
/// interval can be recomputed from the printed seed alone.
pub fn compare(runs: &[RunRecord], reference: &str, bootstrap: &Bootstrap, by_policy: bool) -> Comparison {
    let names: BTreeSet<&str> = runs.iter().map(|r| r.plan.fidelity.as_str()).collect();
    let mut fidelities: Vec<&str> = Vec::new();
    let mut policies: Vec<&str> = Vec::new();
    for run in runs {
        let fidelity = run.plan.fidelity.as_str();
        if !is_reference(fidelity, reference) && !fidelities.contains(&fidelity) {
            fidelities.push(fidelity);
        }
        if !policies.contains(&run.plan.policy.as_str()) {
            policies.push(&run.plan.policy);
        }
    }
    let groups: Vec<Option<&str>> = if by_policy {
        policies.into_iter().map(Some).collect()
    } else {
        vec![None]
    };
    let measured = crate::Units::of_runs(runs.iter().map(|r| &r.metrics)).metrics();
    let mut compared = Vec::new();
    for fidelity in fidelities {
        let reference = paired_reference(fidelity, reference, names.iter().copied());
        for &policy in &groups {
            let compared_runs: Vec<&RunRecord> = runs
                .iter()
                .filter(|r| policy.is_none_or(|p| r.plan.policy == p))
                .collect();
            // A policy without runs in this fidelity has nothing to compare.
            if !compared_runs.iter().any(|r| r.plan.fidelity == fidelity) {
                continue;
            }
            let copies = copied_pairs(&compared_runs, fidelity, &reference);
            compared.push(FidelityComparison {
                fidelity: fidelity.to_owned(),
                policy: policy.map(str::to_owned),
                // The metrics' paired bootstraps in parallel (each seeded on its own).
                metrics: measured
                    .par_iter()
                    .map(|&metric| {
                        paired_metric(&compared_runs, &copies, fidelity, &reference, metric, bootstrap)
                    })
                    .collect(),
            });
        }
    }
    Comparison {
        axis: ComparedAxis::Fidelity,
        reference: reference.to_owned(),
        reference_runs: runs
            .iter()
            .filter(|r| is_reference(&r.plan.fidelity, reference))
            .count(),
        fidelities: compared,
    }
}

/// Compares every policy of `runs` other than `reference` with it, over runs that share their
/// fidelity, initial configuration and repetition (starts drawn alike for every policy make
/// them paired): per fidelity when `by_fidelity`, else pooling the fidelities' pairs. The same
/// rules as [`compare`], with the two axes' roles exchanged.
pub fn compare_policies(
    runs: &[RunRecord],
    reference: &str,
    bootstrap: &Bootstrap,
    by_fidelity: bool,
) -> Comparison {
    let exchanged: Vec<RunRecord> = runs
        .iter()
        .map(|run| {
            let mut run = run.clone();
            std::mem::swap(&mut run.plan.fidelity, &mut run.plan.policy);
            run
        })
        .collect();
    Comparison {
        axis: ComparedAxis::Policy,
        ..compare(&exchanged, reference, bootstrap, by_fidelity)
    }
}

/// How many paired differences are positive, negative and zero.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Signs {
    pub positive: usize,
    pub negative: usize,
    pub zero: usize,
}

impl Signs {
    fn of(differences: &[f64]) -> Signs {
        let mut signs = Signs::default();
        for &d in differences {
            if d > 0.0 {
                signs.positive += 1;
            } else if d < 0.0 {
                signs.negative += 1;
            } else {
                signs.zero += 1;
            }
        }
        signs
    }
}

/// The pair keys of `test` × `reference` that repeat an earlier pair of the same policy and
/// initial configuration with both recordings identical.
fn copied_pairs(runs: &[&RunRecord], test: &str, reference: &str) -> BTreeSet<String> {
    let digests = |fidelity: &str| -> BTreeMap<String, &RunRecord> {
        runs.iter()
            .filter(|r| r.plan.fidelity == fidelity)
            .map(|&r| (r.plan.pair_key(), r))
            .collect()
    };
    let (tests, references) = (digests(test), digests(reference));
    let mut seen: BTreeSet<(&str, &str, &str, &str)> = BTreeSet::new();
    let mut copies = BTreeSet::new();
    // Matrix order (repetition 1 first) decides which pair of a set of copies is kept.
    for run in runs.iter().filter(|r| r.plan.fidelity == test) {
        let key = run.plan.pair_key();
        let (Some(t), Some(r)) = (tests.get(&key), references.get(&key)) else {
            continue;
        };
        let signature = (
            t.plan.policy.as_str(),
            t.plan.initial_configuration.as_str(),
            t.recording_sha256.as_str(),
            r.recording_sha256.as_str(),
        );
        if !seen.insert(signature) {
            copies.insert(key);
        }
    }
    copies
}

/// One metric over the pairs of `runs` (`copies`: the pair keys [`copied_pairs`] leaves out).
fn paired_metric(
    runs: &[&RunRecord],
    copies: &BTreeSet<String>,
    test: &str,
    reference: &str,
    metric: Metric,
    bootstrap: &Bootstrap,
) -> PairedMetric {
    let side = |fidelity: &str| -> Vec<(String, f64)> {
        runs.iter()
            .filter(|r| r.plan.fidelity == fidelity && !copies.contains(&r.plan.pair_key()))
            .map(|r| (r.plan.pair_key(), metric.of(&r.metrics)))
            .collect()
    };
    let pairs = stats::match_pairs(side(test), side(reference));
    let differences: Vec<f64> = pairs.a.iter().zip(&pairs.b).map(|(t, r)| t - r).collect();
    let reference_units: BTreeSet<(&str, &str, &str)> = runs
        .iter()
        .filter(|r| r.plan.fidelity == reference && pairs.keys.binary_search(&r.plan.pair_key()).is_ok())
        .map(|r| {
            (
                r.plan.policy.as_str(),
                r.plan.initial_configuration.as_str(),
                r.recording_sha256.as_str(),
            )
        })
        .collect();
    PairedMetric {
        metric,
        pairs: pairs.keys.len(),
        copies: copies.len(),
        reference_units: reference_units.len(),
        signs: Signs::of(&differences),
        unmatched: pairs.unmatched,
        nan_pairs: pairs.nan_pairs,
        mean_difference: stats::mean(&differences),
        ci95_bootstrap: stats::paired_bootstrap_ci(
            &pairs.a,
            &pairs.b,
            bootstrap.resamples as usize,
            bootstrap.seed,
            CONFIDENCE,
        ),
        wilcoxon_p: stats::wilcoxon_signed_rank_p(&pairs.a, &pairs.b),
        probability_of_improvement: stats::probability_of_improvement(&pairs.a, &pairs.b, metric.direction()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{copy_of, record};

    fn settings() -> Bootstrap {
        Bootstrap {
            resamples: 200,
            seed: 7,
        }
    }

    #[test]
    fn differences_point_from_reference_to_test() {
        let runs = vec![
            record("sim", "p", "i", 1, [0.0, 40.0, 0.05, 0.70]),
            record("sim", "p", "i", 2, [1.0, 41.0, 0.05, 0.71]),
            record("lab", "p", "i", 2, [3.0, 44.0, 0.06, 0.69]),
            record("lab", "p", "i", 1, [2.0, 42.0, 0.06, 0.65]),
            record("lab", "p", "i", 3, [9.0, 42.0, 0.06, 0.65]),
        ];
        let c = compare(&runs, "sim", &settings(), false);
        assert_eq!(c.reference_runs, 2);
        let cra_a = &c.fidelities[0].metrics[0];
        assert_eq!((cra_a.pairs, cra_a.unmatched), (2, 1));
        assert_eq!(cra_a.mean_difference, 2.0);
        // Lab collides more in both pairs: never an improvement on a ↓ metric.
        assert_eq!(cra_a.probability_of_improvement, 0.0);
        // AS: the lab is slower in both pairs: never an improvement on a ↑ metric either.
        assert_eq!(c.fidelities[0].metrics[3].probability_of_improvement, 0.0);
    }

    #[test]
    fn deterministic_pairs_count_once() {
        let mut runs = Vec::new();
        for init in ["i1", "i2", "i3"] {
            let sim = record("sim", "p", init, 1, [0.0, 40.0, 0.05, 0.70]);
            let mpc = record("sim-mpc", "p", init, 1, [0.0, 40.0, 0.09, 0.70]);
            runs.extend([copy_of(&sim, 2), sim.clone(), copy_of(&sim, 3)]);
            runs.extend([mpc.clone(), copy_of(&mpc, 2), copy_of(&mpc, 3)]);
            // A stochastic twin: every repetition its own recording.
            for rep in 1..=3 {
                runs.push(record("twin", "p", init, rep, [0.0, 40.0, 0.1, 0.70]));
            }
        }
        let c = compare(&runs, "sim", &settings(), false);
        let mpc = &c.fidelities[0].metrics[2];
        assert_eq!(c.fidelities[0].fidelity, "sim-mpc");
        assert_eq!((mpc.pairs, mpc.copies, mpc.reference_units), (3, 6, 3));
        assert_eq!(mpc.signs.positive, 3);
        let twin = &c.fidelities[1].metrics[2];
        assert_eq!((twin.pairs, twin.copies, twin.reference_units), (9, 0, 3));
    }

    #[test]
    fn a_missing_reference_gives_zero_pairs() {
        let runs = vec![record("lab", "p", "i", 1, [1.0, 1.0, 1.0, 1.0])];
        let c = compare(&runs, "sim", &settings(), false);
        let m = &c.fidelities[0].metrics[0];
        assert_eq!((m.pairs, m.unmatched, c.reference_runs), (0, 1, 0));
        assert!(m.mean_difference.is_nan() && m.wilcoxon_p.is_nan() && m.ci95_bootstrap.low.is_nan());
    }

    #[test]
    fn by_policy_each_policy_is_compared_alone() {
        // A careful policy barely changes in the twin, a careless one collides there: pooled,
        // the two hide each other; by policy, each has its own row.
        let mut runs = Vec::new();
        for init in ["i1", "i2"] {
            runs.push(record("sim", "careful", init, 1, [0.0, 40.0, 0.05, 0.70]));
            runs.push(record("sim", "careless", init, 1, [0.0, 40.0, 0.05, 0.90]));
            runs.push(record("twin", "careful", init, 1, [0.0, 40.0, 0.05, 0.69]));
            runs.push(record("twin", "careless", init, 1, [4.0, 40.0, 0.05, 0.90]));
        }
        let pooled = compare(&runs, "sim", &settings(), false);
        assert_eq!(pooled.fidelities.len(), 1);
        assert_eq!(pooled.fidelities[0].policy, None);
        assert_eq!(pooled.fidelities[0].metrics[0].pairs, 4);
        assert_eq!(pooled.fidelities[0].metrics[0].mean_difference, 2.0);

        let by_policy = compare(&runs, "sim", &settings(), true);
        let rows = first_metric_rows(&by_policy);
        assert_eq!(
            rows,
            [
                ("twin", Some("careful"), 2, 0.0),
                ("twin", Some("careless"), 2, 4.0)
            ]
        );
        assert_eq!(by_policy.reference_runs, 4);
    }

    /// Each compared entry's names, and its first metric's pairs and mean difference.
    fn first_metric_rows(c: &Comparison) -> Vec<(&str, Option<&str>, usize, f64)> {
        c.fidelities
            .iter()
            .map(|f| {
                (
                    f.fidelity.as_str(),
                    f.policy.as_deref(),
                    f.metrics[0].pairs,
                    f.metrics[0].mean_difference,
                )
            })
            .collect()
    }

    #[test]
    fn policies_compare_within_each_fidelity() {
        let runs = vec![
            record("sim", "base", "i", 1, [2.0, 40.0, 0.05, 0.70]),
            record("sim", "base", "i", 2, [3.0, 41.0, 0.05, 0.71]),
            record("sim", "new", "i", 1, [1.0, 40.0, 0.05, 0.72]),
            record("sim", "new", "i", 2, [1.5, 41.0, 0.05, 0.73]),
            record("twin", "base", "i", 1, [2.0, 40.0, 0.05, 0.70]),
            record("twin", "new", "i", 1, [4.0, 40.0, 0.05, 0.70]),
        ];
        let c = compare_policies(&runs, "base", &settings(), true);
        assert_eq!(c.axis, ComparedAxis::Policy);
        assert_eq!(c.reference_runs, 3);
        let rows = first_metric_rows(&c);
        // `new` − `base` in sim over repetitions 1 and 2, in the twin over repetition 1.
        assert_eq!(
            rows,
            [("new", Some("sim"), 2, -1.25), ("new", Some("twin"), 1, 2.0)]
        );
        let pooled = compare_policies(&runs, "base", &settings(), false);
        assert_eq!(pooled.fidelities.len(), 1);
        assert_eq!(pooled.fidelities[0].metrics[0].pairs, 3);
    }
}
