//! `summary.md`: the paper's Table 2 as a Markdown table (rows: groups; columns: metrics
//! with unit and ↑/↓; cells `mean ± std (IQM)`), then the confidence intervals, the paired
//! comparison with the reference fidelity, and the transfer matrix when the policies were
//! trained in several fidelities.

use std::fmt::Write;

use cpmx_spec::model::Statistic;

use super::{CellParts, best_groups, exclusions, fixed, p_value, pairs_text};
use crate::Transfer;
use crate::aggregate::axis_name;
use crate::compare::{ComparedAxis, Comparison};
use crate::metric::Metric;
use crate::{Group, Summary};

/// The whole Markdown summary.
pub fn render(summary: &Summary) -> String {
    let mut out = format!("# {}\n\n", summary.experiment);
    if let Some(vehicles) = &summary.vehicles {
        let _ = writeln!(out, "{vehicles}\n");
    }
    main_table(&mut out, summary);
    layer_table(&mut out, summary);
    if summary.shows(Statistic::Ci95) || summary.shows(Statistic::Bootstrap) {
        interval_table(&mut out, summary);
    }
    if let Some(comparison) = &summary.comparison {
        comparison_table(&mut out, summary, comparison);
    }
    if let Some(transfer) = &summary.transfer {
        transfer_tables(&mut out, summary, transfer);
    }
    out
}

/// What the fidelities' layers counted (a safety filter's interventions, the lab's follower's
/// stops): a table per layer (the counts' names up to the first `.`), a row per group with
/// counts of that layer; nothing without such a layer.
fn layer_table(out: &mut String, summary: &Summary) {
    let mut layers: std::collections::BTreeMap<&str, std::collections::BTreeSet<&String>> =
        std::collections::BTreeMap::new();
    for name in summary.groups.iter().flat_map(|g| g.layer_counts.keys()) {
        let layer = name.split_once('.').map_or(name.as_str(), |(layer, _)| layer);
        layers.entry(layer).or_default().insert(name);
    }
    if layers.is_empty() {
        return;
    }
    let _ = writeln!(
        out,
        "\n## What the layers counted\n\nOver every run of the group: sums, but `largest` columns, the largest of the runs'.\n"
    );
    let axes: Vec<&str> = summary
        .group_by
        .iter()
        .map(|&a| crate::aggregate::axis_name(a))
        .collect();
    for (i, (layer, names)) in layers.iter().enumerate() {
        if i > 0 {
            let _ = writeln!(out);
        }
        let _ = writeln!(out, "### `{layer}`\n");
        let _ = writeln!(
            out,
            "| {} | runs | {} |",
            axes.join(" | "),
            names
                .iter()
                .map(|n| format!("`{n}`"))
                .collect::<Vec<_>>()
                .join(" | ")
        );
        let _ = writeln!(
            out,
            "|{}",
            " :-- |".repeat(axes.len()) + &" --: |".repeat(names.len() + 1)
        );
        let counted =
            |g: &&crate::aggregate::Group| names.iter().any(|name| g.layer_counts.contains_key(*name));
        for group in summary.groups.iter().filter(counted) {
            let cells: Vec<String> = names
                .iter()
                .map(|name| match group.layer_counts.get(*name) {
                    None => String::new(),
                    // Largest values and durations (`_s`) are measurements, the rest counts.
                    Some(v) if crate::aggregate::is_largest(name) || name.ends_with("_s") => {
                        format!("{v:.3}")
                    }
                    Some(v) => format!("{v:.0}"),
                })
                .collect();
            let _ = writeln!(
                out,
                "| {} | {} | {} |",
                group.key.join(" | "),
                group.runs,
                cells.join(" | ")
            );
        }
    }
}

/// The transfer matrix: per metric, training fidelities × evaluation fidelities; then every
/// training fidelity against the reference one in each evaluation fidelity.
fn transfer_tables(out: &mut String, summary: &Summary, transfer: &Transfer) {
    let reference = &transfer.trained_in[0];
    let _ = writeln!(out, "\n## Transfer: trained in × evaluated in\n");
    let _ = writeln!(
        out,
        "Policies that `cpmx train` trained in each fidelity (rows), evaluated in each fidelity \
         (columns): mean [t 95 % CI] (n independent units) over every training seed, initial \
         configuration and repetition."
    );
    for &metric in summary.units.metrics() {
        let d = metric.decimals();
        let _ = writeln!(out, "\n**{}**\n", metric_name(summary, metric));
        let mut header = vec!["trained in / evaluated in".to_owned()];
        header.extend(transfer.evaluated_in.iter().map(|e| escape(e)));
        row(out, &header);
        let mut align = vec![":--"];
        align.resize(header.len(), "--:");
        row(out, &align);
        for trained in &transfer.trained_in {
            let mut cells = vec![escape(trained)];
            for evaluated in &transfer.evaluated_in {
                cells.push(
                    transfer
                        .cell(trained, evaluated)
                        .and_then(|c| c.group.metric(metric))
                        .map_or_else(String::new, |m| {
                            format!(
                                "{} {} ({})",
                                fixed(m.stats.mean, d),
                                interval(m.stats.ci95, d),
                                m.stats.n
                            )
                        }),
                );
            }
            row(out, &cells);
        }
    }
    let _ = writeln!(out, "\n### Paired with policies trained in `{reference}`\n");
    let _ = writeln!(
        out,
        "Differences trained in X − trained in {reference}, evaluated in the same fidelity, over runs \
         with the same training seed, initial configuration and repetition; copies count once. CI: \
         paired percentile bootstrap, {} resamples, seed {}. p: two-sided Wilcoxon signed-rank test.\n",
        summary.bootstrap.resamples, summary.bootstrap.seed
    );
    let mut header = vec!["evaluated in", "trained in"];
    header.extend(PAIRED_HEADER);
    row(out, &header);
    let mut align = vec![":--", ":--"];
    align.extend(PAIRED_ALIGN);
    row(out, &align);
    for (evaluated, comparison) in &transfer.comparisons {
        for trained in &comparison.fidelities {
            for m in &trained.metrics {
                let mut cells = vec![escape(evaluated), escape(&trained.fidelity)];
                cells.extend(paired_cells(summary, m));
                row(out, &cells);
            }
        }
    }
}

/// Table 2: one row per group.
fn main_table(out: &mut String, summary: &Summary) {
    let parts = CellParts::of(summary);
    let _ = writeln!(
        out,
        "Per group: {} over its independent units. ↓ lower is better, ↑ higher is better; bold: the best mean of a column.\n",
        parts.caption()
    );
    let mut header = group_header(summary);
    header.extend(["runs".into(), "units".into()]);
    let mut align = vec![":--"; summary.group_by.len()];
    align.extend(["--:", "--:"]);
    for &metric in summary.units.metrics() {
        header.push(format!(
            "{} {} [{}]",
            metric.label(),
            metric.arrow(),
            summary.units.text(metric)
        ));
        align.push("--:");
    }
    row(out, &header);
    row(out, &align);

    let best = best_groups(summary);
    for (index, group) in summary.groups.iter().enumerate() {
        let mut cells = group_cells(group);
        cells.extend([group.runs.to_string(), group.units.to_string()]);
        for (&metric, best) in summary.units.metrics().iter().zip(&best) {
            let bold = |s: String| {
                if *best == Some(index) {
                    format!("**{s}**")
                } else {
                    s
                }
            };
            cells.push(
                group
                    .metric(metric)
                    .map_or_else(String::new, |m| parts.cell(&m.stats, metric, " ± ", &bold)),
            );
        }
        row(out, &cells);
    }
    if let Some(note) = super::pooled_note(summary) {
        let _ = writeln!(out, "\n{note}");
    }
    let _ = writeln!(out, "\n{}", super::units_note(summary));
    let _ = writeln!(
        out,
        "AS counts the time agents spend stopped, e.g. after reaching the end of an open path."
    );
    let excluded = exclusions(summary);
    if !excluded.is_empty() {
        let _ = writeln!(
            out,
            "\nExcluded as undefined (no distance travelled): {}.",
            excluded.join("; ")
        );
    }
}

/// One row per group and metric: the requested 95 % intervals.
fn interval_table(out: &mut String, summary: &Summary) {
    let (normal, bootstrap) = (
        summary.shows(Statistic::Ci95),
        summary.shows(Statistic::Bootstrap),
    );
    let _ = writeln!(out, "\n## 95 % confidence intervals\n");
    if normal {
        let _ = writeln!(
            out,
            "t: mean ± t(0.975; n − 1) · std / √n over the n independent units, cut to the values the \
             metric can take (rates, distances and speeds ≥ 0; CRA-L ≤ {}).",
            summary.units.cra_l_per_distance_m
        );
    }
    if bootstrap {
        let _ = writeln!(
            out,
            "Bootstrap: percentile, independent units resampled within each initial configuration; \
             {} resamples, seed {}.",
            summary.bootstrap.resamples, summary.bootstrap.seed
        );
    }
    out.push('\n');
    let mut header = group_header(summary);
    header.extend(["metric".into(), "n".into()]);
    if normal {
        header.push("mean (t)".into());
    }
    if bootstrap {
        header.extend(["mean (bootstrap)".into(), "IQM (bootstrap)".into()]);
    }
    let mut align = vec![":--"; summary.group_by.len() + 1];
    align.resize(header.len(), "--:");
    row(out, &header);
    row(out, &align);
    for group in &summary.groups {
        for m in &group.metrics {
            let d = m.metric.decimals();
            let mut cells = group_cells(group);
            cells.extend([metric_name(summary, m.metric), m.stats.n.to_string()]);
            if normal {
                cells.push(interval(m.stats.ci95, d));
            }
            if bootstrap {
                let (mean, iqm) = m.bootstrap.map_or((String::new(), String::new()), |b| {
                    (interval(b.mean, d), interval(b.iqm, d))
                });
                cells.extend([mean, iqm]);
            }
            row(out, &cells);
        }
    }
}

/// One row per compared fidelity (or policy) and metric.
fn comparison_table(out: &mut String, summary: &Summary, comparison: &Comparison) {
    let (axis, within) = (comparison.axis.name(), comparison.axis.other().name());
    let axis_plural = match comparison.axis {
        ComparedAxis::Fidelity => "fidelities",
        ComparedAxis::Policy => "policies",
    };
    let grouped = comparison.fidelities.iter().any(|f| f.policy.is_some());
    match comparison.axis {
        ComparedAxis::Fidelity => {
            let _ = writeln!(out, "\n## Paired comparison with `{}`\n", comparison.reference);
        }
        ComparedAxis::Policy => {
            let _ = writeln!(
                out,
                "\n## Paired comparison with policy `{}`\n",
                comparison.reference
            );
        }
    }
    let _ = writeln!(
        out,
        "Differences {axis} − {} over runs with the same {}, initial configuration and repetition{}; \
         a pair whose two recordings repeat an earlier pair's (both {axis_plural} deterministic) counts once. \
         CI: paired percentile bootstrap, {} resamples, seed {}. p: two-sided Wilcoxon signed-rank test. \
         +/−/0: differences above, below and at zero. \
         P(better): probability that a run of the {axis} is better than one of the reference \
         (by the metric's arrow; 0.5: no difference).\n",
        comparison.reference,
        match comparison.axis {
            ComparedAxis::Fidelity => "policy",
            ComparedAxis::Policy => "fidelity",
        },
        if grouped {
            format!(", per {within}")
        } else {
            String::new()
        },
        summary.bootstrap.resamples,
        summary.bootstrap.seed
    );
    if comparison.reference_runs == 0 {
        let _ = writeln!(out, "The reference {axis} has no runs.\n");
    }
    // A column of the other axis when the pairs are compared per value of it (as the summary
    // groups them).
    let mut header = vec![axis];
    let mut align = vec![":--"];
    if grouped {
        header.push(within);
        align.push(":--");
    }
    header.extend(PAIRED_HEADER);
    header.push("P(better)");
    align.extend(PAIRED_ALIGN);
    align.push("--:");
    row(out, &header);
    row(out, &align);
    for fidelity in &comparison.fidelities {
        for m in &fidelity.metrics {
            let mut cells = vec![escape(&fidelity.fidelity)];
            if grouped {
                cells.push(escape(fidelity.policy.as_deref().unwrap_or("")));
            }
            cells.extend(paired_cells(summary, m));
            cells.push(fixed(m.probability_of_improvement, 2));
            row(out, &cells);
        }
    }
    let notes = super::comparison_notes(comparison);
    if !notes.is_empty() {
        out.push('\n');
        for note in notes {
            let _ = writeln!(out, "- {note}");
        }
    }
}

/// The columns of [`paired_cells`] and their alignment.
const PAIRED_HEADER: [&str; 6] = ["metric", "pairs", "difference", "95 % CI", "p", "+/−/0"];
const PAIRED_ALIGN: [&str; 6] = [":--", "--:", "--:", "--:", "--:", "--:"];

/// A paired metric's cells: metric, pairs, difference, its CI, p, signs.
fn paired_cells(summary: &Summary, m: &crate::PairedMetric) -> [String; 6] {
    let d = m.metric.decimals();
    [
        metric_name(summary, m.metric),
        pairs_text(m),
        fixed(m.mean_difference, d),
        interval(m.ci95_bootstrap, d),
        p_value(m.wilcoxon_p),
        format!("{}/{}/{}", m.signs.positive, m.signs.negative, m.signs.zero),
    ]
}

fn group_header(summary: &Summary) -> Vec<String> {
    summary
        .group_by
        .iter()
        .map(|&a| axis_name(a).to_owned())
        .collect()
}

fn group_cells(group: &Group) -> Vec<String> {
    group.key.iter().map(|k| escape(k)).collect()
}

fn metric_name(summary: &Summary, metric: Metric) -> String {
    format!(
        "{} {} [{}]",
        metric.label(),
        metric.arrow(),
        summary.units.text(metric)
    )
}

fn interval(i: cpmx_metrics::stats::Interval, decimals: usize) -> String {
    if i.low.is_nan() || i.high.is_nan() {
        return super::UNDEFINED.into();
    }
    format!("[{}, {}]", fixed(i.low, decimals), fixed(i.high, decimals))
}

/// A table cell's text with `|` escaped.
fn escape(text: &str) -> String {
    text.replace('|', "\\|")
}

fn row<S: AsRef<str>>(out: &mut String, cells: &[S]) {
    out.push('|');
    for cell in cells {
        out.push(' ');
        out.push_str(cell.as_ref());
        out.push_str(" |");
    }
    out.push('\n');
}
