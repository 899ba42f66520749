//! Text renderers of a [`Summary`]: Markdown, CSV, JSON and a LaTeX `tabular`, plus
//! `per_run.csv` of the runs themselves.
//!
//! This module owns the number formats of the tables. Every renderer is a pure function:
//! the same summary gives the same bytes on every machine (fixed decimals or
//! [`format_float`], no hash-map order, no timestamps). Nothing here computes a statistic.

mod csv;
mod json;
mod latex;
mod markdown;

use cpmx_spec::model::GroupKey;
pub use csv::per_run_csv;

use crate::Summary;
use crate::metric::Metric;

/// The formats of `cpmx report --format` and the summary files of a run folder.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Format {
    /// `summary.md`: Table 2 as Markdown, then the CI and comparison tables.
    Markdown,
    /// `summary.csv`: one row per group and metric, every statistic a column.
    Csv,
    /// `summary.json`: everything, machine-readable.
    Json,
    /// A LaTeX `tabular` shaped like the paper's Table 2 (not written to the run folder).
    Latex,
}

impl Format {
    /// Every format.
    pub const ALL: [Format; 4] = [Format::Markdown, Format::Csv, Format::Json, Format::Latex];

    /// Its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Format::Markdown => "markdown",
            Format::Csv => "csv",
            Format::Json => "json",
            Format::Latex => "latex",
        }
    }

    /// The format with this command-line name.
    pub fn from_name(name: &str) -> Option<Format> {
        Format::ALL.into_iter().find(|f| f.name() == name)
    }

    /// The summary file of a run folder in this format (`None`: LaTeX is printed only).
    pub fn file_name(self) -> Option<&'static str> {
        match self {
            Format::Markdown => Some("summary.md"),
            Format::Csv => Some("summary.csv"),
            Format::Json => Some("summary.json"),
            Format::Latex => None,
        }
    }
}

/// The summary in `format`: exactly the bytes of the run folder's summary file.
pub fn render(summary: &Summary, format: Format) -> String {
    match format {
        Format::Markdown => markdown::render(summary),
        Format::Csv => csv::summary_csv(summary),
        Format::Json => json::render(summary),
        Format::Latex => latex::render(summary),
    }
}

/// What an undefined statistic shows in the text tables.
const UNDEFINED: &str = "n/a";

/// `value` with `decimals` fixed decimals (`-0.00` shows as `0.00`); NaN is [`UNDEFINED`].
pub(crate) fn fixed(value: f64, decimals: usize) -> String {
    if value.is_nan() {
        return UNDEFINED.into();
    }
    let text = format!("{value:.decimals$}");
    match text.strip_prefix('-') {
        Some(rest) if rest.chars().all(|c| c == '0' || c == '.') => rest.to_owned(),
        _ => text,
    }
}

/// A p-value: three decimals, or `< 0.001`.
fn p_value(p: f64) -> String {
    if p < 0.001 { "< 0.001".into() } else { fixed(p, 3) }
}

/// The parts of a Table 2 cell that the spec asked for.
#[derive(Debug, Clone, Copy)]
struct CellParts {
    mean: bool,
    std: bool,
    iqm: bool,
    median: bool,
    trimmed_mean: bool,
}

impl CellParts {
    fn of(summary: &Summary) -> CellParts {
        use cpmx_spec::model::Statistic;
        let (std, iqm) = (summary.shows(Statistic::Std), summary.shows(Statistic::Iqm));
        let (median, trimmed_mean) = (
            summary.shows(Statistic::Median),
            summary.shows(Statistic::TrimmedMean),
        );
        // The mean is the cell's anchor: shown when asked for or when nothing else is.
        let mean = summary.shows(Statistic::Mean) || !(std || iqm || median || trimmed_mean);
        CellParts {
            mean,
            std,
            iqm,
            median,
            trimmed_mean,
        }
    }

    /// How the caption names the cell, e.g. `mean ± std (IQM)`, `mean (IQM), median`.
    fn caption(self) -> String {
        self.join(
            ["mean", "std", "IQM", "median", "trimmed mean"].map(String::from),
            " ± ",
        )
    }

    /// A cell; `emphasise` wraps the mean (bold in Markdown and LaTeX).
    fn cell(
        self,
        stats: &cpmx_metrics::stats::Summary,
        metric: Metric,
        pm: &str,
        emphasise: &dyn Fn(String) -> String,
    ) -> String {
        let d = metric.decimals();
        self.join(
            [
                emphasise(fixed(stats.mean, d)),
                fixed(stats.std, d),
                fixed(stats.iqm, d),
                fixed(stats.median, d),
                fixed(stats.trimmed_mean, d),
            ],
            pm,
        )
    }

    /// `mean ± std (iqm)`, then the median and the trimmed mean, each after a comma: the parts
    /// asked for, in that order.
    fn join(self, [mean, std, iqm, median, trimmed_mean]: [String; 5], pm: &str) -> String {
        let mut text = String::new();
        if self.mean {
            text.push_str(&mean);
        }
        if self.std {
            text.push_str(&if self.mean { format!("{pm}{std}") } else { std });
        }
        if self.iqm {
            if !text.is_empty() {
                text.push(' ');
            }
            text.push_str(&format!("({iqm})"));
        }
        for (shown, part) in [(self.median, median), (self.trimmed_mean, trimmed_mean)] {
            if shown {
                if !text.is_empty() {
                    text.push_str(", ");
                }
                text.push_str(&part);
            }
        }
        text
    }
}

/// For each metric of the summary, the index of the group with the best mean (none with fewer than two
/// groups with a finite mean, or when every finite mean is equal).
fn best_groups(summary: &Summary) -> Vec<Option<usize>> {
    use cpmx_metrics::stats::Direction;
    summary
        .units
        .metrics()
        .iter()
        .map(|&metric| {
            let means: Vec<(usize, f64)> = summary
                .groups
                .iter()
                .enumerate()
                .filter_map(|(i, g)| g.metric(metric).map(|m| (i, m.stats.mean)))
                .filter(|(_, v)| v.is_finite())
                .collect();
            let better = |a: f64, b: f64| match metric.direction() {
                Direction::LowerIsBetter => a < b,
                Direction::HigherIsBetter => a > b,
            };
            let (best, value) = means
                .iter()
                .copied()
                .reduce(|b, c| if better(c.1, b.1) { c } else { b })?;
            let distinct = means.iter().any(|&(_, v)| v != value);
            (means.len() >= 2 && distinct).then_some(best)
        })
        .collect()
}

/// Runs excluded as undefined per group and metric, e.g. `twin: CRA-A 1, CRA-L 1`
/// (empty when none were).
fn exclusions(summary: &Summary) -> Vec<String> {
    summary
        .groups
        .iter()
        .filter_map(|g| {
            let parts: Vec<String> = g
                .metrics
                .iter()
                .filter(|m| m.stats.nan_count > 0)
                .map(|m| format!("{} {}", m.metric.label(), m.stats.nan_count))
                .collect();
            (!parts.is_empty()).then(|| format!("{}: {}", g.key.join(" / "), parts.join(", ")))
        })
        .collect()
}

/// What every row pools: the values of the axes `report.group_by` leaves out, policies
/// first (pooling policies is a choice the reader must see), or `None` when the rows pool
/// nothing.
fn pooled_note(summary: &Summary) -> Option<String> {
    let list = |values: &[String]| {
        values
            .iter()
            .map(|v| format!("`{v}`"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut parts = Vec::new();
    let mut axes: Vec<&(GroupKey, Vec<String>)> = summary.pooled.iter().collect();
    axes.sort_by_key(|(axis, _)| *axis != GroupKey::Policy);
    for (axis, values) in axes {
        let noun = match axis {
            GroupKey::Fidelity => "fidelities",
            GroupKey::Policy => "policies",
            GroupKey::InitialConfiguration => "initial configurations",
        };
        parts.push(format!("the {} {noun} {}", values.len(), list(values)));
    }
    if parts.is_empty() {
        return None;
    }
    let policies = summary.pooled.iter().any(|(axis, _)| *axis == GroupKey::Policy);
    Some(format!(
        "Each row pools {}{}.",
        parts.join(" and "),
        if policies {
            " (`report.group_by` leaves out `policy`: add it for a row per policy)"
        } else {
            ""
        }
    ))
}

/// What the tables count as a sample, and how many copies the groups held.
fn units_note(summary: &Summary) -> String {
    let runs: usize = summary.groups.iter().map(|g| g.runs).sum();
    let units: usize = summary.groups.iter().map(|g| g.units).sum();
    let mut note = String::from(
        "Statistics count independent units: a repetition whose recording is bit-identical to an \
         earlier one of the same fidelity, policy and initial configuration (a deterministic \
         fidelity and policy) is a copy and counts once.",
    );
    if units < runs {
        note.push_str(&format!(
            " Here {} of {runs} runs are copies; n below is the number of units.",
            runs - units
        ));
    }
    note
}

/// Notes on a comparison: copies left out, references shared by several pairs, and every
/// metric whose confidence interval and p-value disagree, with the reason.
fn comparison_notes(comparison: &crate::Comparison) -> Vec<String> {
    let mut notes = Vec::new();
    for fidelity in &comparison.fidelities {
        let Some(first) = fidelity.metrics.first() else {
            continue;
        };
        // `twin`, or `twin` / `policy` when compared per policy.
        let label = match &fidelity.policy {
            Some(policy) => format!("`{}` / `{policy}`", fidelity.fidelity),
            None => format!("`{}`", fidelity.fidelity),
        };
        if first.copies > 0 {
            notes.push(format!(
                "{label}: {} pairs are copies of earlier pairs (both fidelities gave bit-identical \
                 repetitions) and are counted once: {} independent pairs.",
                first.copies, first.pairs
            ));
        }
        if first.reference_units > 0 && first.reference_units < first.pairs {
            notes.push(format!(
                "{label}: its {} pairs share {} distinct `{}` runs (the reference repeats itself), \
                 so the differences of one policy and initial configuration are not independent \
                 of each other; read the intervals as conditional on those reference runs.",
                first.pairs, first.reference_units, comparison.reference
            ));
        }
        for m in &fidelity.metrics {
            if let Some(reason) = disagreement(m) {
                notes.push(format!("{label} {}: {reason}", m.metric.label()));
            }
        }
    }
    notes
}

/// Why the bootstrap interval of the mean difference and the Wilcoxon p-value disagree
/// about a difference at the 5 % level, or `None` when they agree.
fn disagreement(m: &crate::PairedMetric) -> Option<String> {
    let (low, high, p) = (m.ci95_bootstrap.low, m.ci95_bootstrap.high, m.wilcoxon_p);
    if low.is_nan() || high.is_nan() || p.is_nan() {
        return None;
    }
    let ci_excludes_zero = low > 0.0 || high < 0.0;
    let test_rejects = p < 0.05;
    if ci_excludes_zero == test_rejects {
        return None;
    }
    let signs = m.signs;
    let nonzero = signs.positive + signs.negative;
    let mixed = format!(
        "{} differences are above zero, {} below{}",
        signs.positive,
        signs.negative,
        if signs.zero > 0 {
            format!(" and {} exactly zero (the test leaves those out)", signs.zero)
        } else {
            String::new()
        }
    );
    Some(if ci_excludes_zero {
        // Exact signed-rank test: with k non-zero differences the smallest two-sided p is 2 / 2^k.
        let smallest_p = 2.0 / 2f64.powi(nonzero as i32);
        let floor = if smallest_p >= 0.05 {
            format!(
                " With {nonzero} non-zero differences no p-value can fall below {}, whatever the data.",
                fixed(smallest_p, 3)
            )
        } else {
            String::new()
        };
        format!(
            "the interval of the mean difference excludes 0 but p = {}: the interval is about the mean, \
             which a few large differences can carry, while the signed-rank test weighs every pair by \
             rank; {mixed}. A percentile bootstrap of {} pairs is also narrower than it should be.{floor}",
            p_value(p),
            m.pairs
        )
    } else {
        format!(
            "p = {} but the interval of the mean difference includes 0: the ranks point one way ({mixed}) \
             while a few large differences the other way pull the mean toward zero.",
            p_value(p)
        )
    })
}

/// How many pairs a comparison used, e.g. `25 (2 unmatched, 1 NaN)`.
fn pairs_text(m: &crate::PairedMetric) -> String {
    let mut notes = Vec::new();
    if m.unmatched > 0 {
        notes.push(format!("{} unmatched", m.unmatched));
    }
    if m.nan_pairs > 0 {
        notes.push(format!("{} NaN", m.nan_pairs));
    }
    if m.copies > 0 {
        notes.push(format!("{} copies", m.copies));
    }
    if notes.is_empty() {
        m.pairs.to_string()
    } else {
        format!("{} ({})", m.pairs, notes.join(", "))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fixed_rounds_and_drops_negative_zero() {
        assert_eq!(fixed(0.375, 2), "0.38");
        assert_eq!(fixed(-0.0004, 3), "0.000");
        assert_eq!(fixed(-0.5, 1), "-0.5");
        assert_eq!(fixed(f64::NAN, 2), "n/a");
        assert_eq!(p_value(0.0004), "< 0.001");
        assert_eq!(p_value(0.0625), "0.062");
    }

    #[test]
    fn cells_show_what_was_asked_for() {
        let all = CellParts {
            mean: true,
            std: true,
            iqm: true,
            median: false,
            trimmed_mean: false,
        };
        assert_eq!(all.caption(), "mean ± std (IQM)");
        let iqm_only = CellParts {
            mean: false,
            std: false,
            iqm: true,
            ..all
        };
        assert_eq!(iqm_only.caption(), "(IQM)");
        let no_std = CellParts { std: false, ..all };
        assert_eq!(no_std.caption(), "mean (IQM)");
        let sigmarl = CellParts {
            std: false,
            iqm: false,
            median: true,
            trimmed_mean: true,
            ..all
        };
        assert_eq!(sigmarl.caption(), "mean, median, trimmed mean");
        let median_only = CellParts {
            mean: false,
            trimmed_mean: false,
            ..sigmarl
        };
        assert_eq!(median_only.caption(), "median");
    }

    #[test]
    fn formats_round_trip_their_names() {
        for f in Format::ALL {
            assert_eq!(Format::from_name(f.name()), Some(f));
        }
        assert_eq!(Format::from_name("html"), None);
    }
}
