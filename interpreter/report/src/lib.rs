//! Summaries of cpmx runs: grouped statistics, paired comparisons between fidelities, the
//! tables of a run folder (`per_run.csv`, `summary.md`, `summary.csv`, `summary.json`, and a
//! LaTeX `tabular` shaped like the paper's Table 2) and SVG plots.
//!
//! Modules: `metric` (names, units, directions, precision, bounds), `units` (which runs are
//! independent units and which are copies), `aggregate` (groups and their statistics),
//! `compare` (paired differences with the reference fidelity), `transfer` (policies trained in
//! several fidelities, evaluated in every one), `table` (text renderers),
//! `svg` (plots written as SVG text).
//!
//! Every renderer is a pure function of its input and byte-stable: fixed number formats,
//! no hash-map order, no clock. This crate reads no files and runs no engine; the
//! statistics' formulas live in `cpmx_metrics::stats`.

mod aggregate;
mod compare;
mod metric;
mod svg;
mod table;
#[cfg(test)]
mod testing;
mod transfer;
mod units;

pub use aggregate::{
    BootstrapIntervals, CONFIDENCE, Group, MetricSummary, Origins, Summary, VehicleNote, axis_name,
    axis_value, sort_by_matrix, summarize,
};
pub use compare::{ComparedAxis, Comparison, FidelityComparison, PairedMetric, Signs};
pub use metric::{Metric, Units};
pub use svg::{
    AGENT_COLOURS, COLLISION_INK, MapDrawing, SensitivityPlot, VIOLATION_INK, distribution_svg,
    sensitivity_svgs, trajectory_svg,
};
pub use table::{Format, per_run_csv, render};
pub use transfer::{Origin, Transfer, TransferCell};
pub use units::distinct_units;

use cpmx_metrics::RunMetrics;
use cpmx_spec::RunPlan;
use std::collections::BTreeMap;

/// One finished run: where it sits in the matrix, its metrics, and the digest of its
/// recording.
#[derive(Debug, Clone, PartialEq)]
pub struct RunRecord {
    /// Its row of the run matrix.
    pub plan: RunPlan,
    /// Its metrics (`metrics.json`).
    pub metrics: RunMetrics,
    /// SHA-256 of its `trajectory.csv`: two repetitions with the same digest are one
    /// independent unit, not two (see `units`).
    pub recording_sha256: String,
    /// The fidelity's randomised parameters as drawn for the run, by name (empty when its
    /// fidelity has none).
    pub drawn_parameters: BTreeMap<String, f64>,
    /// Numbers the fidelity's layers counted over the run, by name (`safety.changed`; empty
    /// without such a layer).
    pub statistics: BTreeMap<String, f64>,
}
