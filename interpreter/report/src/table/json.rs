//! `summary.json`: every number of the summary, machine-readable. Numbers are rounded to
//! the 10 significant digits of the CSV files (so the file is the same on every machine);
//! undefined values are `null`. Keys keep their insertion order.

use cpmx_metrics::format_float;
use cpmx_metrics::stats::Interval;
use serde_json::{Map, Value, json};

use super::csv::better;
use crate::aggregate::{CONFIDENCE, axis_name};
use crate::compare::{Comparison, PairedMetric};
use crate::{Group, MetricSummary, Summary};

/// The pretty-printed JSON summary, ending in a newline.
pub fn render(summary: &Summary) -> String {
    let statistics: Vec<Value> = summary
        .statistics
        .iter()
        .map(|s| serde_json::to_value(s).unwrap_or(Value::Null))
        .collect();
    let mut document = json!({
        "experiment": summary.experiment,
        "units": super::units_note(summary),
        "group_by": summary.group_by.iter().map(|&a| axis_name(a)).collect::<Vec<_>>(),
        "pooled": summary
            .pooled
            .iter()
            .map(|(axis, values)| (axis_name(*axis).to_owned(), json!(values)))
            .collect::<serde_json::Map<String, Value>>(),
        "statistics": statistics,
        "confidence": CONFIDENCE,
        "bootstrap": {"resamples": summary.bootstrap.resamples, "seed": summary.bootstrap.seed},
        "metrics": summary.units.metrics().iter().map(|&m| json!({
            "id": m.id(),
            "label": m.label(),
            "unit": summary.units.text(m),
            "better": better(m.direction()),
            "decimals": m.decimals(),
        })).collect::<Vec<_>>(),
        "groups": summary.groups.iter().map(|g| group(summary, g)).collect::<Vec<_>>(),
        "comparison": summary.comparison.as_ref().map(comparison),
        "transfer": summary.transfer.as_ref().map(transfer),
    });
    if let Some(v) = &summary.vehicles {
        document["vehicle_m"] = json!(v.vehicle_m);
        document["footprint_m"] = json!(v.footprint_m);
    }
    let mut text = serde_json::to_string_pretty(&document).unwrap_or_default();
    text.push('\n');
    text
}

fn transfer(t: &crate::Transfer) -> Value {
    json!({
        "trained_in": t.trained_in,
        "evaluated_in": t.evaluated_in,
        "reference": t.trained_in.first(),
        "cells": t.cells.iter().map(|c| json!({
            "trained_in": c.trained_in,
            "evaluated_in": c.evaluated_in,
            "runs": c.group.runs,
            "units": c.group.units,
            "metrics": c.group.metrics.iter().map(|m| (m.metric.id().to_owned(), metric(m))).collect::<Map<String, Value>>(),
        })).collect::<Vec<_>>(),
        "comparisons": t.comparisons.iter().map(|(evaluated, c)| json!({
            "evaluated_in": evaluated,
            "comparison": comparison(c),
        })).collect::<Vec<_>>(),
    })
}

fn group(summary: &Summary, g: &Group) -> Value {
    let key: Map<String, Value> = summary
        .group_by
        .iter()
        .zip(&g.key)
        .map(|(&axis, value)| (axis_name(axis).to_owned(), json!(value)))
        .collect();
    let metrics: Map<String, Value> = g
        .metrics
        .iter()
        .map(|m| (m.metric.id().to_owned(), metric(m)))
        .collect();
    json!({"key": key, "runs": g.runs, "units": g.units, "metrics": metrics})
}

fn metric(m: &MetricSummary) -> Value {
    let s = &m.stats;
    json!({
        "n": s.n,
        "nan_count": s.nan_count,
        "mean": number(s.mean),
        "std": number(s.std),
        "iqm": number(s.iqm),
        "median": number(s.median),
        "trimmed_mean": number(s.trimmed_mean),
        "ci95": interval(s.ci95),
        "bootstrap": m.bootstrap.map(|b| json!({"mean": interval(b.mean), "iqm": interval(b.iqm)})),
    })
}

fn comparison(c: &Comparison) -> Value {
    let fidelities: Vec<Value> = c
        .fidelities
        .iter()
        .map(|f| {
            let metrics: Map<String, Value> = f
                .metrics
                .iter()
                .map(|m| (m.metric.id().to_owned(), paired(m)))
                .collect();
            let (axis, within) = (c.axis.name(), c.axis.other().name());
            let mut entry = Map::new();
            entry.insert(axis.into(), json!(f.fidelity));
            if let Some(value) = &f.policy {
                entry.insert(within.into(), json!(value));
            }
            entry.insert("metrics".into(), Value::Object(metrics));
            Value::Object(entry)
        })
        .collect();
    json!({
        "axis": c.axis.name(),
        "reference": c.reference,
        "reference_runs": c.reference_runs,
        "difference": format!("{} - reference", c.axis.name()),
        "fidelities": fidelities,
        "notes": super::comparison_notes(c),
    })
}

fn paired(m: &PairedMetric) -> Value {
    json!({
        "pairs": m.pairs,
        "copies": m.copies,
        "reference_units": m.reference_units,
        "unmatched": m.unmatched,
        "nan_pairs": m.nan_pairs,
        "mean_difference": number(m.mean_difference),
        "ci95_bootstrap": interval(m.ci95_bootstrap),
        "wilcoxon_p": number(m.wilcoxon_p),
        "signs": {"positive": m.signs.positive, "negative": m.signs.negative, "zero": m.signs.zero},
        "probability_of_improvement": number(m.probability_of_improvement),
    })
}

fn interval(i: Interval) -> Value {
    json!({"low": number(i.low), "high": number(i.high)})
}

/// A finite value rounded to 10 significant digits; `null` otherwise.
fn number(value: f64) -> Value {
    if !value.is_finite() {
        return Value::Null;
    }
    let rounded = format_float(value).parse::<f64>().unwrap_or(value);
    json!(rounded)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_rounded_and_nan_is_null() {
        assert_eq!(number(0.1 + 0.2), json!(0.3));
        assert_eq!(number(f64::NAN), Value::Null);
        assert_eq!(number(f64::INFINITY), Value::Null);
        assert_eq!(number(1.0 / 3.0).to_string(), "0.3333333333");
    }
}
