//! A fixed synthetic experiment: 3 fidelities x 2 policies x 2 initial configurations x
//! 2 repetitions, values from fixed formulas, one lab run without distance (NaN rates).

use cpmx_metrics::{MetricsConfig, RunMetrics};
use cpmx_report::RunRecord;
use cpmx_spec::RunPlan;
use cpmx_spec::model::{Bootstrap, Compare, GroupKey, PairedTest, ReportSpec, Statistic};

/// The runs, in matrix order.
pub fn runs() -> Vec<RunRecord> {
    let mut runs = Vec::new();
    for (f, fidelity) in ["sim", "twin", "lab"].into_iter().enumerate() {
        for (p, policy) in ["seed1", "seed2"].into_iter().enumerate() {
            for (i, init) in ["init1", "init2"].into_iter().enumerate() {
                for r in 1..=2u32 {
                    let k = (f * 7 + p * 3 + i * 5 + r as usize * 11) % 9;
                    let mut values = [
                        k as f64 * 0.37 * (1 + f) as f64,
                        38.0 + f as f64 * 2.5 + ((p * 13 + i * 7 + r as usize * 3) % 10) as f64 * 1.1,
                        0.040 + 0.002 * f as f64 + 0.001 * ((p + i + r as usize) % 5) as f64,
                        0.76 - 0.01 * f as f64 + 0.004 * ((p * 2 + i + r as usize * 3) % 7) as f64,
                    ];
                    let stuck = fidelity == "lab" && policy == "seed2" && init == "init1" && r == 2;
                    if stuck {
                        values = [f64::NAN, f64::NAN, values[2], 0.0];
                    }
                    runs.push(record(
                        fidelity,
                        policy,
                        init,
                        r,
                        values,
                        if stuck { 0.0 } else { 40.0 + k as f64 },
                    ));
                }
            }
        }
    }
    runs
}

/// One run with CRA-A, CRA-L, CD and AS given.
pub fn record(
    fidelity: &str,
    policy: &str,
    init: &str,
    repetition: u32,
    values: [f64; 4],
    distance_m: f64,
) -> RunRecord {
    RunRecord {
        plan: RunPlan {
            key: format!("{fidelity}/{policy}/{init}/rep{repetition}"),
            fidelity: fidelity.into(),
            policy: policy.into(),
            initial_configuration: init.into(),
            repetition,
            seed: 1000 + u64::from(repetition),
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
            a2a_events: if values[0].is_nan() {
                0
            } else {
                (values[0] * distance_m / 100.0).round() as usize
            },
            distance_m,
            lane_violation_m: if values[1].is_nan() {
                0.0
            } else {
                values[1] * distance_m / 100.0
            },
            config: MetricsConfig::default(),
            pair_events: vec![],
            agents: vec![],
        },
        recording_sha256: format!("recording of {fidelity}/{policy}/{init}/rep{repetition}"),
        drawn_parameters: Default::default(),
        statistics: Default::default(),
    }
}

/// Every statistic, a small bootstrap, compared with `sim`.
pub fn report(group_by: &[GroupKey]) -> ReportSpec {
    ReportSpec {
        group_by: group_by.to_vec(),
        statistics: vec![
            Statistic::Mean,
            Statistic::Std,
            Statistic::Iqm,
            Statistic::Ci95,
            Statistic::Bootstrap,
        ],
        bootstrap: Bootstrap {
            resamples: 1000,
            seed: 7,
        },
        compare: Some(Compare {
            reference: "sim".into(),
            test: PairedTest::Paired,
        }),
    }
}
