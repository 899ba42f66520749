//! Fixtures of the unit tests.

use cpmx_metrics::{MetricsConfig, RunMetrics};
use cpmx_spec::RunPlan;
use cpmx_spec::model::{Bootstrap, Compare, GroupKey, PairedTest, ReportSpec, Statistic};

use crate::RunRecord;

/// A run with the given CRA-A, CRA-L, CD and AS.
pub fn record(fidelity: &str, policy: &str, init: &str, repetition: u32, values: [f64; 4]) -> RunRecord {
    RunRecord {
        plan: RunPlan {
            key: format!("{fidelity}/{policy}/{init}/rep{repetition}"),
            fidelity: fidelity.into(),
            policy: policy.into(),
            initial_configuration: init.into(),
            repetition,
            seed: u64::from(repetition),
        },
        metrics: RunMetrics {
            num_samples: 180,
            num_agents: 3,
            cra_a: values[0],
            cra_l: values[1],
            cd_m: values[2],
            as_mps: values[3],
            cr_aa_pct: f64::NAN,
            cr_al_pct: f64::NAN,
            a2a_events: 0,
            distance_m: 40.0,
            lane_violation_m: 0.0,
            config: MetricsConfig::default(),
            pair_events: vec![],
            agents: vec![],
        },
        recording_sha256: format!("recording of {fidelity}/{policy}/{init}/rep{repetition}"),
        drawn_parameters: Default::default(),
        statistics: Default::default(),
    }
}

/// Repetition `repetition` of `run`'s cell with a bit-identical recording (what a
/// deterministic fidelity and policy give).
pub fn copy_of(run: &RunRecord, repetition: u32) -> RunRecord {
    let mut copy = run.clone();
    copy.plan.repetition = repetition;
    copy.plan.seed = u64::from(repetition);
    copy.plan.key = format!(
        "{}/{}/{}/rep{repetition}",
        run.plan.fidelity, run.plan.policy, run.plan.initial_configuration
    );
    copy
}

/// A report section.
pub fn spec(group_by: &[GroupKey], bootstrap: bool, reference: Option<&str>) -> ReportSpec {
    let mut statistics = vec![Statistic::Mean, Statistic::Std, Statistic::Iqm, Statistic::Ci95];
    if bootstrap {
        statistics.push(Statistic::Bootstrap);
    }
    ReportSpec {
        group_by: group_by.to_vec(),
        statistics,
        bootstrap: Bootstrap {
            resamples: 500,
            seed: 7,
        },
        compare: reference.map(|r| Compare {
            reference: r.into(),
            test: PairedTest::Paired,
        }),
    }
}
