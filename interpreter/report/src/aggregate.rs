//! Grouping runs and summarising each metric per group over its independent units (copies
//! of a repetition count once, see `units`): n, mean, std, IQM, Student-t 95 % CI within the
//! metric's range and, when asked for, stratified bootstrap CIs of the mean and the IQM.
//!
//! This module owns the [`Summary`] every renderer reads. It formats nothing and computes
//! no statistic itself: the formulas live in `cpmx_metrics::stats`.

use cpmx_metrics::stats::{self, Interval};
use cpmx_spec::RunPlan;
use cpmx_spec::model::{Bootstrap, GroupKey, ReportSpec, Statistic};

use crate::RunRecord;
use crate::compare::{Comparison, compare, compare_policies};
use crate::metric::{Metric, Units};
use crate::transfer::{Origin, Transfer, transfer};
use crate::units::distinct_units;
use cpmx_spec::sweep::is_reference;
use rayon::prelude::*;
use std::collections::BTreeMap;

/// Confidence of every interval of the report.
pub const CONFIDENCE: f64 = 0.95;

/// Everything the tables and plots show, computed once from the runs.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// The experiment's name (the spec's `name`).
    pub experiment: String,
    /// The axes that define a group (`report.group_by`).
    pub group_by: Vec<GroupKey>,
    /// The statistics the spec asked for (`report.statistics`); the tables show these.
    pub statistics: Vec<Statistic>,
    /// Resamples and seed of every bootstrap interval (stratified and paired).
    pub bootstrap: Bootstrap,
    /// The rates' normalising distances.
    pub units: Units,
    /// The groups, in order of their first run (matrix order).
    pub groups: Vec<Group>,
    /// The axes left out of `group_by` on which the runs differ, with their values in matrix
    /// order: what every row pools (policies pooled on purpose, initial configurations).
    pub pooled: Vec<(GroupKey, Vec<String>)>,
    /// The paired comparison with the reference fidelity, when `report.compare` is set.
    pub comparison: Option<Comparison>,
    /// The transfer matrix, when the runs' policies were trained in two fidelities or more.
    pub transfer: Option<Transfer>,
    /// The vehicle the runs drove and observed, and the footprint the metrics scored, when the
    /// spec gives the metrics a footprint of their own (`metrics.footprint`).
    pub vehicles: Option<VehicleNote>,
}

/// The run's vehicle and the metrics' footprint, length × width [m].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehicleNote {
    pub vehicle_m: [f64; 2],
    pub footprint_m: [f64; 2],
}

impl std::fmt::Display for VehicleNote {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let [vl, vw] = self.vehicle_m;
        let [fl, fw] = self.footprint_m;
        write!(
            f,
            "Runs drive and observe a {vl} m × {vw} m vehicle; the metrics score a {fl} m × {fw} m footprint."
        )
    }
}

impl Summary {
    /// Whether the spec asked for this statistic.
    pub fn shows(&self, statistic: Statistic) -> bool {
        self.statistics.contains(&statistic)
    }
}

/// The runs that share their values of the `group_by` axes.
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    /// One value per `group_by` axis, in that order.
    pub key: Vec<String>,
    /// Runs in the group (NaN values and copies included).
    pub runs: usize,
    /// Independent units among them: runs that are not bit-identical copies of an earlier
    /// repetition. Every statistic of the group is computed over these.
    pub units: usize,
    /// One summary per metric the runs measure, in table order ([`Units::metrics`]).
    pub metrics: Vec<MetricSummary>,
    /// What the fidelity's layers counted over every run of the group (all runs: a layer's
    /// counts are not a metric of independent units), by name: a `*.largest_*` statistic
    /// is the largest of the runs', every other the sum. Empty without such a layer.
    pub layer_counts: BTreeMap<String, f64>,
}

impl Group {
    /// The summary of one metric.
    pub fn metric(&self, metric: Metric) -> Option<&MetricSummary> {
        self.metrics.iter().find(|m| m.metric == metric)
    }
}

/// One metric over the runs of one group.
#[derive(Debug, Clone, PartialEq)]
pub struct MetricSummary {
    /// Which metric.
    pub metric: Metric,
    /// The values of the group's independent units in run order, NaN (undefined) included.
    pub values: Vec<f64>,
    /// n (independent units, NaN excluded), NaN count, mean, std (n − 1), IQM, Student-t
    /// 95 % CI of the mean within the metric's range.
    pub stats: stats::Summary,
    /// Stratified bootstrap intervals, when `bootstrap` is among the statistics.
    pub bootstrap: Option<BootstrapIntervals>,
}

/// Percentile bootstrap 95 % intervals of a group, resampling its independent units within
/// each initial configuration (the strata), from `ChaCha8Rng::seed_from_u64(bootstrap.seed)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BootstrapIntervals {
    /// Of the mean.
    pub mean: Interval,
    /// Of the interquartile mean.
    pub iqm: Interval,
}

/// The name of a grouping axis as `per_run.csv` heads its column.
pub fn axis_name(axis: GroupKey) -> &'static str {
    match axis {
        GroupKey::Fidelity => "fidelity",
        GroupKey::Policy => "policy",
        GroupKey::InitialConfiguration => "initial_configuration",
    }
}

/// A run's value of a grouping axis.
pub fn axis_value(plan: &RunPlan, axis: GroupKey) -> &str {
    match axis {
        GroupKey::Fidelity => &plan.fidelity,
        GroupKey::Policy => &plan.policy,
        GroupKey::InitialConfiguration => &plan.initial_configuration,
    }
}

/// Where the policies of an experiment were trained: by policy name, and the training
/// fidelity the others are compared with (the first the spec trains in).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Origins {
    /// The training fidelity and seed of each policy `cpmx train` trained.
    pub policies: BTreeMap<String, Origin>,
    /// The reference training fidelity of the transfer matrix.
    pub reference: Option<String>,
}

impl Origins {
    /// The origins a spec declares: every policy `mlp: {trained}` with its training fidelity
    /// (`trained.fidelity`, else the spec's only one) and seed; the reference is the first
    /// fidelity of `training.fidelity`.
    pub fn of_spec(spec: &cpmx_spec::model::Spec) -> Origins {
        let training = spec.training.as_ref();
        let policies = spec
            .policies
            .iter()
            .filter_map(|p| {
                let trained = p.mlp.as_ref()?.trained.as_ref()?;
                Some((
                    p.name.clone(),
                    Origin {
                        trained_in: trained.trained_in(training)?.to_owned(),
                        seed: trained.seed,
                    },
                ))
            })
            .collect();
        Origins {
            policies,
            reference: training.and_then(|t| t.fidelity.names().first().cloned()),
        }
    }
}

/// Summarises `runs` as `report` asks: groups by `report.group_by` in order of first
/// appearance, every metric per group, the paired comparison of `report.compare`, and the
/// transfer matrix when `origins` names two training fidelities or more.
///
/// Total: no runs, empty groups, single runs and NaN values all give a summary (with NaN
/// statistics where they are undefined).
pub fn summarize(experiment: &str, runs: &[RunRecord], report: &ReportSpec, origins: &Origins) -> Summary {
    let with_bootstrap = report.statistics.contains(&Statistic::Bootstrap);
    let units = Units::of_runs(runs.iter().map(|r| &r.metrics));
    // Groups in parallel (their bootstraps are the summary's costliest part); each group's
    // streams are seeded on their own, so the summary does not depend on the threads.
    let groups = group_runs(runs, &report.group_by)
        .into_par_iter()
        .map(|(key, members)| {
            summarize_group(key, &members, units, with_bootstrap.then_some(&report.bootstrap))
        })
        .collect();
    Summary {
        experiment: experiment.to_owned(),
        group_by: report.group_by.clone(),
        statistics: report.statistics.clone(),
        bootstrap: report.bootstrap.clone(),
        units,
        groups,
        pooled: pooled_axes(runs, &report.group_by),
        comparison: report.compare.as_ref().map(|c| {
            // A reference that names a policy and no fidelity compares the policies.
            let fidelity = runs.iter().any(|r| is_reference(&r.plan.fidelity, &c.reference));
            if !fidelity && runs.iter().any(|r| r.plan.policy == c.reference) {
                compare_policies(
                    runs,
                    &c.reference,
                    &report.bootstrap,
                    report.group_by.contains(&GroupKey::Fidelity),
                )
            } else {
                compare(
                    runs,
                    &c.reference,
                    &report.bootstrap,
                    report.group_by.contains(&GroupKey::Policy),
                )
            }
        }),
        transfer: transfer(
            runs,
            &origins.policies,
            origins.reference.as_deref(),
            report,
            units,
        ),
        vehicles: None,
    }
}

/// The axes outside `group_by` that hold more than one value among `runs`, each with its
/// values in order of first appearance.
fn pooled_axes(runs: &[RunRecord], group_by: &[GroupKey]) -> Vec<(GroupKey, Vec<String>)> {
    [
        GroupKey::Fidelity,
        GroupKey::Policy,
        GroupKey::InitialConfiguration,
    ]
    .into_iter()
    .filter(|axis| !group_by.contains(axis))
    .filter_map(|axis| {
        let mut values: Vec<String> = Vec::new();
        for run in runs {
            let value = axis_value(&run.plan, axis);
            if !values.iter().any(|v| v == value) {
                values.push(value.to_owned());
            }
        }
        (values.len() > 1).then_some((axis, values))
    })
    .collect()
}

/// Puts `runs` in the order of `matrix` (runs whose key the matrix lacks go last, by key),
/// so that runs gathered from several folders or shards summarise exactly as one `cpmx run`
/// of the whole matrix does.
pub fn sort_by_matrix(runs: &mut [RunRecord], matrix: &[RunPlan]) {
    let position: std::collections::BTreeMap<&str, usize> = matrix
        .iter()
        .enumerate()
        .map(|(i, p)| (p.key.as_str(), i))
        .collect();
    runs.sort_by(|a, b| {
        let rank = |r: &RunRecord| position.get(r.plan.key.as_str()).copied().unwrap_or(usize::MAX);
        rank(a).cmp(&rank(b)).then_with(|| a.plan.key.cmp(&b.plan.key))
    });
}

/// The runs of each group, groups in order of their first run.
pub(crate) fn group_runs<'a>(
    runs: &'a [RunRecord],
    axes: &[GroupKey],
) -> Vec<(Vec<String>, Vec<&'a RunRecord>)> {
    let mut groups: Vec<(Vec<String>, Vec<&RunRecord>)> = Vec::new();
    for run in runs {
        let key: Vec<String> = axes
            .iter()
            .map(|&a| axis_value(&run.plan, a).to_owned())
            .collect();
        match groups.iter_mut().find(|(k, _)| *k == key) {
            Some((_, members)) => members.push(run),
            None => groups.push((key, vec![run])),
        }
    }
    groups
}

pub(crate) fn summarize_group(
    key: Vec<String>,
    members: &[&RunRecord],
    units: Units,
    bootstrap: Option<&Bootstrap>,
) -> Group {
    let independent = distinct_units(members.iter().copied());
    let metrics = units
        .metrics()
        .iter()
        .map(|&metric| {
            let values: Vec<f64> = independent.iter().map(|r| metric.of(&r.metrics)).collect();
            MetricSummary {
                metric,
                stats: stats::summarize(&values, metric.range(units)),
                bootstrap: bootstrap.map(|b| bootstrap_intervals(&independent, metric, b)),
                values,
            }
        })
        .collect();
    let mut layer_counts: BTreeMap<String, f64> = BTreeMap::new();
    for (name, &value) in members.iter().flat_map(|r| &r.statistics) {
        let total = layer_counts.entry(name.clone()).or_insert(0.0);
        *total = if is_largest(name) {
            total.max(value)
        } else {
            *total + value
        };
    }
    Group {
        key,
        runs: members.len(),
        units: independent.len(),
        metrics,
        layer_counts,
    }
}

/// Whether a layer's statistic is a largest value (kept as the group's largest), not a count.
pub fn is_largest(name: &str) -> bool {
    name.contains(".largest_")
}

/// Stratified bootstrap intervals of one metric; strata are the initial configurations
/// in order of first appearance.
fn bootstrap_intervals(members: &[&RunRecord], metric: Metric, settings: &Bootstrap) -> BootstrapIntervals {
    let mut strata: Vec<(&str, Vec<f64>)> = Vec::new();
    for run in members {
        let configuration = run.plan.initial_configuration.as_str();
        let value = metric.of(&run.metrics);
        match strata.iter_mut().find(|(c, _)| *c == configuration) {
            Some((_, values)) => values.push(value),
            None => strata.push((configuration, vec![value])),
        }
    }
    let slices: Vec<&[f64]> = strata.iter().map(|(_, v)| v.as_slice()).collect();
    let interval = |statistic| {
        stats::stratified_bootstrap_ci(
            &slices,
            statistic,
            settings.resamples as usize,
            settings.seed,
            CONFIDENCE,
        )
    };
    BootstrapIntervals {
        mean: interval(stats::Statistic::Mean),
        iqm: interval(stats::Statistic::Iqm),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{copy_of, record, spec};

    #[test]
    fn groups_keep_matrix_order_and_exclude_nan() {
        let runs = vec![
            record("twin", "p1", "init1", 1, [1.0, 40.0, 0.04, 0.7]),
            record("sim", "p1", "init1", 1, [0.0, 45.0, 0.05, 0.75]),
            record("twin", "p1", "init2", 1, [f64::NAN, f64::NAN, 0.05, 0.0]),
            record("twin", "p1", "init3", 1, [3.0, 42.0, 0.06, 0.8]),
        ];
        let summary = summarize(
            "x",
            &runs,
            &spec(&[GroupKey::Fidelity], false, None),
            &Origins::default(),
        );
        let keys: Vec<&str> = summary.groups.iter().map(|g| g.key[0].as_str()).collect();
        assert_eq!(keys, ["twin", "sim"]);
        let cra_a = summary.groups[0].metric(Metric::CraA).unwrap();
        assert_eq!((cra_a.stats.n, cra_a.stats.nan_count), (2, 1));
        assert_eq!(cra_a.stats.mean, 2.0);
        assert!(cra_a.bootstrap.is_none());
        assert_eq!(summary.groups[0].runs, 3);
    }

    #[test]
    fn the_summary_does_not_depend_on_threads() {
        // Groups and their bootstraps are summarised in parallel; each is seeded on its own.
        let mut runs = Vec::new();
        for (f, fidelity) in ["sim", "twin"].into_iter().enumerate() {
            for p in 0..4 {
                for i in 0..3 {
                    for rep in 1..=3 {
                        let x = (f * 37 + p * 11 + i * 5 + rep as usize) as f64;
                        runs.push(record(
                            fidelity,
                            &format!("p{p}"),
                            &format!("init{i}"),
                            rep,
                            [x % 3.0, 40.0 + x % 7.0, 0.04 + 0.001 * x, 0.7 + 0.002 * x],
                        ));
                    }
                }
            }
        }
        let report = spec(&[GroupKey::Fidelity, GroupKey::Policy], true, Some("sim"));
        let with_threads = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a thread pool")
                .install(|| {
                    crate::render(
                        &summarize("x", &runs, &report, &Origins::default()),
                        crate::Format::Json,
                    )
                })
        };
        let one = with_threads(1);
        assert!(
            one.contains("bootstrap"),
            "the summary has its bootstrap intervals"
        );
        assert_eq!(one, with_threads(4));
    }

    #[test]
    fn copies_count_once() {
        let a = record("sim", "p", "init1", 1, [0.0, 40.0, 0.04, 0.7]);
        let b = record("sim", "p", "init2", 1, [0.0, 44.0, 0.08, 0.6]);
        let runs = vec![
            a.clone(),
            copy_of(&a, 2),
            copy_of(&a, 3),
            b.clone(),
            copy_of(&b, 2),
            copy_of(&b, 3),
        ];
        let summary = summarize(
            "x",
            &runs,
            &spec(&[GroupKey::Fidelity], true, None),
            &Origins::default(),
        );
        let group = &summary.groups[0];
        assert_eq!((group.runs, group.units), (6, 2));
        let cd = group.metric(Metric::Cd).unwrap();
        assert_eq!(cd.stats.n, 2);
        assert!((cd.stats.mean - 0.06).abs() < 1e-15);
        // Two units: t(0.975; 1) = 12.706 makes the interval wide, not six-copies narrow.
        let half = cd.stats.ci95.high - cd.stats.mean;
        assert!(
            (half - 12.706_204_736 * cd.stats.std / 2f64.sqrt()).abs() < 1e-6,
            "{half}"
        );
    }

    #[test]
    fn a_collision_rate_has_no_negative_interval() {
        let runs: Vec<RunRecord> = (1..=9)
            .map(|i| {
                let collisions = if i == 9 { 6.0 } else { 0.0 };
                record("twin", "p", &format!("init{i}"), 1, [collisions, 40.0, 0.04, 0.7])
            })
            .collect();
        let summary = summarize(
            "x",
            &runs,
            &spec(&[GroupKey::Fidelity], false, None),
            &Origins::default(),
        );
        let cra_a = summary.groups[0].metric(Metric::CraA).unwrap();
        assert_eq!(cra_a.stats.ci95.low, 0.0);
    }

    #[test]
    fn bootstrap_uses_the_spec_seed_and_is_reproducible() {
        let runs: Vec<RunRecord> = (0..6)
            .map(|i| {
                let init = if i % 2 == 0 { "init1" } else { "init2" };
                record("sim", "p1", init, 1 + i / 2, [i as f64, 1.0, 0.1, 0.5])
            })
            .collect();
        let report = spec(&[GroupKey::Fidelity], true, None);
        let a = summarize("x", &runs, &report, &Origins::default());
        let b = summarize("x", &runs, &report, &Origins::default());
        assert_eq!(a, b);
        let ci = a.groups[0].metric(Metric::CraA).unwrap().bootstrap.unwrap();
        assert!(ci.mean.low < 2.5 && 2.5 < ci.mean.high, "{ci:?}");
    }

    #[test]
    fn shards_are_put_back_in_matrix_order() {
        let matrix: Vec<RunPlan> = ["sim", "twin", "lab"]
            .iter()
            .map(|f| record(f, "p", "i", 1, [0.0; 4]).plan)
            .collect();
        let mut runs = vec![
            record("zeta", "p", "i", 1, [0.0; 4]),
            record("lab", "p", "i", 1, [0.0; 4]),
            record("alpha", "p", "i", 1, [0.0; 4]),
            record("sim", "p", "i", 1, [0.0; 4]),
        ];
        sort_by_matrix(&mut runs, &matrix);
        let order: Vec<&str> = runs.iter().map(|r| r.plan.fidelity.as_str()).collect();
        assert_eq!(order, ["sim", "lab", "alpha", "zeta"]);
    }

    #[test]
    fn no_runs_give_no_groups() {
        let summary = summarize(
            "x",
            &[],
            &spec(&[GroupKey::Policy], true, Some("sim")),
            &Origins::default(),
        );
        assert!(summary.groups.is_empty());
        assert!(summary.comparison.unwrap().fidelities.is_empty());
    }
}
