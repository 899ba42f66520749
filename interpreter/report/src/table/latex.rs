//! A LaTeX `tabular` shaped like the paper's Table 2 (booktabs rules, siunitx units, the
//! best mean of a column in bold). Only the table body is written: the caption and float
//! belong to the paper. Needs `\usepackage{booktabs,siunitx}`.

use std::fmt::Write;

use cpmx_spec::model::GroupKey;

use super::{CellParts, UNDEFINED, best_groups};
use crate::Summary;
use crate::metric::{Metric, Units};

/// The `tabular`, preceded by a comment naming the experiment and the cell layout.
pub fn render(summary: &Summary) -> String {
    let parts = CellParts::of(summary);
    let runs: Vec<String> = summary
        .groups
        .iter()
        .map(|g| format!("{} ({} independent)", g.runs, g.units))
        .collect();
    let mut out = format!(
        "% cpmx: {}; cells: {} over independent units; runs per row: {}\n% needs \\usepackage{{booktabs,siunitx}}\n",
        summary.experiment,
        parts.caption(),
        if runs.is_empty() {
            "none".into()
        } else {
            runs.join(", ")
        }
    );
    if let Some(note) = super::pooled_note(summary) {
        let _ = writeln!(out, "% {}", note.replace('`', ""));
    }
    let metrics = summary.units.metrics();
    let columns = "l".repeat(summary.group_by.len()) + &"c".repeat(metrics.len());
    let _ = writeln!(out, "\\begin{{tabular}}{{{columns}}}\n\\toprule");

    // The header: axis names, then one braced column head per metric.
    let axes: Vec<&str> = summary.group_by.iter().map(|&a| axis_title(a)).collect();
    let _ = writeln!(out, "{}", axes.join(" & "));
    for &metric in metrics {
        let _ = writeln!(
            out,
            "& {{{} ${}$ [{}]}}",
            metric.label(),
            arrow(metric),
            unit(summary.units, metric)
        );
    }
    out.push_str("\\\\\n\\midrule\n");

    // One row per group.
    let best = best_groups(summary);
    for (index, group) in summary.groups.iter().enumerate() {
        let keys: Vec<String> = group.key.iter().map(|k| escape(k)).collect();
        let _ = writeln!(out, "{}", keys.join(" & "));
        for (&metric, best) in metrics.iter().zip(&best) {
            let bold = |s: String| {
                if *best == Some(index) {
                    format!("\\textbf{{{s}}}")
                } else {
                    s
                }
            };
            let cell = group
                .metric(metric)
                .map_or_else(String::new, |m| parts.cell(&m.stats, metric, " $\\pm$ ", &bold));
            let _ = writeln!(out, "& {}", cell.replace(UNDEFINED, "--"));
        }
        out.push_str("\\\\\n");
    }
    out.push_str("\\bottomrule\n\\end{tabular}\n");
    out
}

fn axis_title(axis: GroupKey) -> &'static str {
    match axis {
        GroupKey::Fidelity => "Environment",
        GroupKey::Policy => "Policy",
        GroupKey::InitialConfiguration => "Initial configuration",
    }
}

fn arrow(metric: Metric) -> &'static str {
    match metric {
        Metric::As => "\\uparrow",
        _ => "\\downarrow",
    }
}

/// The unit in siunitx, as the paper writes it.
fn unit(units: Units, metric: Metric) -> String {
    match metric {
        Metric::CraA => format!(
            "\\si{{events\\per \\SI{{{}}}{{\\meter}}}}",
            units.cra_a_per_distance_m
        ),
        Metric::CraL => format!(
            "\\si{{\\meter\\per \\SI{{{}}}{{\\meter}}}}",
            units.cra_l_per_distance_m
        ),
        Metric::Cd => "\\si{\\meter}".into(),
        Metric::As => "\\si{\\meter\\per\\second}".into(),
        Metric::CrAa | Metric::CrAl => "\\si{\\percent}".into(),
    }
}

/// Text with LaTeX's special characters escaped.
fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' | '%' | '$' | '#' | '_' | '{' | '}' => {
                out.push('\\');
                out.push(c);
            }
            '~' => out.push_str("\\textasciitilde{}"),
            '^' => out.push_str("\\textasciicircum{}"),
            '\\' => out.push_str("\\textbackslash{}"),
            _ => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn special_characters_are_escaped() {
        assert_eq!(escape("a_b & 50%"), "a\\_b \\& 50\\%");
        assert_eq!(
            escape("~^\\"),
            "\\textasciitilde{}\\textasciicircum{}\\textbackslash{}"
        );
    }
}
