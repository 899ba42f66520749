//! `per_run.csv` (one row per run) and `summary.csv` (one row per group and metric, every
//! statistic a column). Floats use the metrics crate's [`format_float`] (10 significant
//! digits; empty for an undefined value). The paired comparison is in `summary.json` and
//! `summary.md` only: its rows are fidelities, not groups.

use cpmx_metrics::stats::{Direction, Interval};
use cpmx_metrics::{RunMetrics, format_float};

use crate::aggregate::axis_name;
use crate::{RunRecord, Summary};

/// The run columns that `per_run.csv` puts before the metrics crate's columns.
const RUN_COLUMNS: [&str; 6] = [
    "key",
    "fidelity",
    "policy",
    "initial_configuration",
    "repetition",
    "seed",
];

/// `per_run.csv`: the run's matrix columns, then [`RunMetrics::CSV_COLUMNS`] (and
/// [`RunMetrics::PER_SAMPLE_CSV_COLUMNS`] when any run measures them), then a column
/// per randomised layer parameter of any run (`actuation.delay_ms`, by name; empty where a
/// run's fidelity does not draw it), then a column per number a layer counted in any run
/// (`safety.changed`, by name; empty where a run's fidelity has no such layer), in run order.
pub fn per_run_csv(runs: &[RunRecord]) -> String {
    let mut out = String::new();
    let drawn: std::collections::BTreeSet<&str> = runs
        .iter()
        .flat_map(|r| r.drawn_parameters.keys().map(String::as_str))
        .collect();
    let counted: std::collections::BTreeSet<&str> = runs
        .iter()
        .flat_map(|r| r.statistics.keys().map(String::as_str))
        .collect();
    let per_sample = runs.iter().any(|r| r.metrics.config.per_sample_collisions);
    let per_sample_columns: &[&str] = if per_sample {
        &RunMetrics::PER_SAMPLE_CSV_COLUMNS
    } else {
        &[]
    };
    let header: Vec<&str> = RUN_COLUMNS
        .iter()
        .chain(&RunMetrics::CSV_COLUMNS)
        .chain(per_sample_columns)
        .copied()
        .chain(drawn.iter().copied())
        .chain(counted.iter().copied())
        .collect();
    record(&mut out, &header);
    for run in runs {
        let p = &run.plan;
        let mut fields = vec![
            p.key.clone(),
            p.fidelity.clone(),
            p.policy.clone(),
            p.initial_configuration.clone(),
            p.repetition.to_string(),
            p.seed.to_string(),
        ];
        fields.extend(run.metrics.csv_row());
        if per_sample {
            fields.extend(run.metrics.per_sample_csv_row());
        }
        fields.extend(drawn.iter().map(|name| {
            run.drawn_parameters
                .get(*name)
                .map_or(String::new(), |v| format_float(*v))
        }));
        fields.extend(counted.iter().map(|name| {
            run.statistics
                .get(*name)
                .map_or(String::new(), |v| format_float(*v))
        }));
        record(&mut out, &fields);
    }
    out
}

/// The statistic columns of `summary.csv`, after one column per `group_by` axis.
const SUMMARY_COLUMNS: [&str; 21] = [
    "metric",
    "unit",
    "better",
    "runs",
    "units",
    "n",
    "nan_count",
    "mean",
    "std",
    "iqm",
    "median",
    "trimmed_mean",
    "ci95_low",
    "ci95_high",
    "bootstrap_mean_low",
    "bootstrap_mean_high",
    "bootstrap_iqm_low",
    "bootstrap_iqm_high",
    "bootstrap_resamples",
    "bootstrap_seed",
    "decimals",
];

/// `summary.csv`. Bootstrap columns are empty when the spec did not ask for bootstrap CIs.
pub fn summary_csv(summary: &Summary) -> String {
    let mut out = String::new();
    let header: Vec<&str> = summary
        .group_by
        .iter()
        .map(|&a| axis_name(a))
        .chain(SUMMARY_COLUMNS)
        .collect();
    record(&mut out, &header);
    for group in &summary.groups {
        for m in &group.metrics {
            let mut fields = group.key.clone();
            let s = &m.stats;
            fields.extend([
                m.metric.id().to_owned(),
                summary.units.text(m.metric),
                better(m.metric.direction()).to_owned(),
                group.runs.to_string(),
                group.units.to_string(),
                s.n.to_string(),
                s.nan_count.to_string(),
                format_float(s.mean),
                format_float(s.std),
                format_float(s.iqm),
                format_float(s.median),
                format_float(s.trimmed_mean),
            ]);
            fields.extend(interval(s.ci95));
            match m.bootstrap {
                Some(b) => {
                    fields.extend(interval(b.mean));
                    fields.extend(interval(b.iqm));
                    fields.push(summary.bootstrap.resamples.to_string());
                    fields.push(summary.bootstrap.seed.to_string());
                }
                None => fields.extend(std::iter::repeat_n(String::new(), 6)),
            }
            fields.push(m.metric.decimals().to_string());
            record(&mut out, &fields);
        }
    }
    out
}

/// `lower` or `higher`: which values are better.
pub(super) fn better(direction: Direction) -> &'static str {
    match direction {
        Direction::LowerIsBetter => "lower",
        Direction::HigherIsBetter => "higher",
    }
}

fn interval(i: Interval) -> [String; 2] {
    [format_float(i.low), format_float(i.high)]
}

/// One CSV record (RFC 4180: a field with a comma, quote or line break is quoted).
fn record<S: AsRef<str>>(out: &mut String, fields: &[S]) {
    for (i, field) in fields.iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        let field = field.as_ref();
        if field.contains([',', '"', '\n', '\r']) {
            out.push('"');
            out.push_str(&field.replace('"', "\"\""));
            out.push('"');
        } else {
            out.push_str(field);
        }
    }
    out.push('\n');
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_with_separators_are_quoted() {
        let mut out = String::new();
        record(&mut out, &["a,b", "say \"hi\"", "plain"]);
        assert_eq!(out, "\"a,b\",\"say \"\"hi\"\"\",plain\n");
    }
}
