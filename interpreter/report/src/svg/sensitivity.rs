//! Sensitivity curves: a metric against a swept parameter. Every fidelity of a sweep's
//! points (`twin-v2v@latency_ms=100+drop_probability=0.3`) is a row of the summary; for each
//! fidelity, swept parameter and metric one plot puts the parameter's values on the x axis and
//! draws one line per combination of the other sweeps' values and the other grouping axes
//! (the policy, by default): each point the row's mean with its t 95 % interval. One plot per
//! metric, so that a page lays them out as wide as it is (three a row on a wide screen, one
//! on a phone); the value axis is the distributions' (a constant from zero to it, its value
//! written); lines take the agents' colour-blind-safe colours.

use std::fmt::Write;

use cpmx_spec::model::GroupKey;

use super::axis::Axis;
use super::{colour, escape, open, px};
use crate::Summary;
use crate::metric::Metric;

/// The narrowest drawing [px] (as the distributions: text keeps its size on a page).
const MIN_WIDTH_PX: f64 = 420.0;
/// Height of the value axis [px].
const PLOT_PX: f64 = 200.0;
/// Space left of the plot for tick labels [px].
const LEFT_PX: f64 = 70.0;
/// Space right of the plot [px].
const RIGHT_PX: f64 = 20.0;
/// Space above the plot for the title and the note [px].
const TOP_PX: f64 = 50.0;
/// Space below the plot for the parameter's values and name [px].
const BOTTOM_PX: f64 = 44.0;
/// Height of a legend line [px].
const LINE_PX: f64 = 16.0;
/// What the marks are.
const NOTE: &str = "points: a row's mean; bars: its t 95 % interval";

/// One plot: a metric against a swept parameter, at the points of one fidelity.
#[derive(Debug, Clone, PartialEq)]
pub struct SensitivityPlot {
    /// Its file's name: `sensitivity-<fidelity>-<parameter>-<metric id>`.
    pub name: String,
    /// The swept fidelity (without its point).
    pub fidelity: String,
    /// The parameter on the x axis.
    pub parameter: String,
    pub metric: Metric,
    /// What each line holds fixed (the other sweeps' values, the other grouping axes' values
    /// such as the policy), in the order of their colours.
    pub lines: Vec<String>,
    pub svg: String,
}

/// One row of the summary at a point of a sweep.
struct PointRow<'a> {
    base: &'a str,
    values: Vec<(&'a str, f64)>,
    /// The row's other grouping values (e.g. the policy).
    others: Vec<&'a str>,
    group: &'a crate::Group,
}

/// A fidelity's point parsed from its name: `base@a=1+b=2`.
fn parse(fidelity: &str) -> Option<(&str, Vec<(&str, f64)>)> {
    let (base, point) = fidelity.split_once('@')?;
    let values = point
        .split('+')
        .map(|pair| {
            let (label, value) = pair.split_once('=')?;
            Some((label, value.parse().ok()?))
        })
        .collect::<Option<Vec<_>>>()?;
    Some((base, values))
}

/// Every sensitivity plot of the summary, by fidelity, parameter and metric; none when no row
/// is a point of a sweep (or the rows are not grouped by fidelity).
pub fn sensitivity_svgs(summary: &Summary) -> Vec<SensitivityPlot> {
    let Some(fidelity_axis) = summary.group_by.iter().position(|&a| a == GroupKey::Fidelity) else {
        return Vec::new();
    };
    let rows: Vec<PointRow<'_>> = summary
        .groups
        .iter()
        .filter_map(|group| {
            let (base, values) = parse(group.key.get(fidelity_axis)?)?;
            let others = group
                .key
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != fidelity_axis)
                .map(|(_, v)| v.as_str())
                .collect();
            Some(PointRow {
                base,
                values,
                others,
                group,
            })
        })
        .collect();
    let mut bases: Vec<&str> = Vec::new();
    for row in &rows {
        if !bases.contains(&row.base) {
            bases.push(row.base);
        }
    }
    let mut plots = Vec::new();
    for base in bases {
        let of_base: Vec<&PointRow<'_>> = rows.iter().filter(|r| r.base == base).collect();
        let labels: Vec<&str> = of_base[0].values.iter().map(|(l, _)| *l).collect();
        for (axis, label) in labels.iter().enumerate() {
            let lines = lines(&of_base, axis);
            let keys: Vec<String> = lines.iter().map(|(key, _)| key.clone()).collect();
            for &metric in summary.units.metrics() {
                plots.push(SensitivityPlot {
                    name: format!("sensitivity-{base}-{label}-{}", metric.id()),
                    fidelity: base.to_owned(),
                    parameter: (*label).to_owned(),
                    metric,
                    lines: keys.clone(),
                    svg: plot(summary, metric, (base, label, axis), &of_base, &lines),
                });
            }
        }
    }
    plots
}

/// The rows of one fidelity in lines: rows sharing everything but the `axis`-th swept value,
/// each line named by what it holds fixed.
fn lines<'r, 'a>(rows: &[&'r PointRow<'a>], axis: usize) -> Vec<(String, Vec<&'r PointRow<'a>>)> {
    let key = |r: &PointRow<'_>| -> String {
        let mut parts: Vec<String> = r
            .values
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != axis)
            .map(|(_, (l, v))| format!("{l}={v}"))
            .collect();
        parts.extend(r.others.iter().map(|o| (*o).to_owned()));
        parts.join(", ")
    };
    let mut lines: Vec<(String, Vec<&PointRow<'_>>)> = Vec::new();
    for &row in rows {
        let key = key(row);
        match lines.iter_mut().find(|(k, _)| *k == key) {
            Some((_, members)) => members.push(row),
            None => lines.push((key, vec![row])),
        }
    }
    lines
}

/// The plot of `metric` against the `axis`-th swept value (`label`) of fidelity `base`.
fn plot(
    summary: &Summary,
    metric: Metric,
    (base, label, axis): (&str, &str, usize),
    rows: &[&PointRow<'_>],
    lines: &[(String, Vec<&PointRow<'_>>)],
) -> String {
    let names: Vec<&str> = lines
        .iter()
        .map(|(key, _)| if key.is_empty() { base } else { key.as_str() })
        .collect();
    // Sans-serif at 11 px: about 6 px a character, after a 20 px swatch.
    let legend_px = names
        .iter()
        .map(|n| 20.0 + 6.0 * n.chars().count() as f64)
        .fold(0.0, f64::max);
    let width_px = (LEFT_PX + legend_px + RIGHT_PX).max(MIN_WIDTH_PX);
    let (plot_left, plot_right) = (LEFT_PX, width_px - RIGHT_PX);
    let height_px = TOP_PX + PLOT_PX + BOTTOM_PX + LINE_PX * lines.len() as f64 + 8.0;

    let xs: Vec<f64> = rows
        .iter()
        .filter_map(|r| r.values.get(axis).map(|v| v.1))
        .collect();
    let (x_min, x_max) = x_range(&xs);
    let to_x = |x: f64| plot_left + 10.0 + (x - x_min) / (x_max - x_min) * (plot_right - plot_left - 20.0);
    // A row's (mean, interval's low end, high end).
    let stats = |r: &PointRow<'_>| {
        r.group
            .metric(metric)
            .map(|m| (m.stats.mean, m.stats.ci95.low, m.stats.ci95.high))
    };
    let values = rows
        .iter()
        .filter_map(|&r| stats(r))
        .flat_map(|(mean, low, high)| [mean, low, high]);
    let y = Axis::of(values, TOP_PX, PLOT_PX);

    let mut out = open(width_px, height_px);
    let title = format!(
        "{} {} [{}] against {label}",
        metric.label(),
        metric.arrow(),
        summary.units.text(metric)
    );
    let _ = writeln!(
        out,
        "<title>{}</title>",
        escape(&format!("{title}, at the points of {base}: {NOTE}"))
    );
    let _ = writeln!(
        out,
        "<text x=\"{}\" y=\"18\">{}</text>",
        px(plot_left),
        escape(&title)
    );
    let _ = writeln!(
        out,
        "<text x=\"{}\" y=\"34\" font-size=\"10\">{NOTE}</text>",
        px(plot_left)
    );
    y.note_constant(&mut out, "every point", metric.decimals(), plot_right, 34.0);
    y.draw(&mut out, plot_left, plot_right, 11);

    // The parameter's values under the plot, and its name.
    let bottom = TOP_PX + PLOT_PX;
    let mut ticks = xs.clone();
    ticks.sort_by(f64::total_cmp);
    ticks.dedup();
    for x in ticks {
        let _ = writeln!(
            out,
            "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\" font-size=\"11\">{}</text>",
            px(to_x(x)),
            px(bottom + 15.0),
            number(x)
        );
    }
    let _ = writeln!(
        out,
        "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\" font-size=\"11\">{}</text>",
        px((plot_left + plot_right) / 2.0),
        px(bottom + 32.0),
        escape(label)
    );

    // One line per combination, with its intervals.
    for (l, (_, members)) in lines.iter().enumerate() {
        let ink = colour(l);
        let mut points: Vec<(f64, f64, f64, f64)> = members
            .iter()
            .filter_map(|&r| {
                let (mean, low, high) = stats(r)?;
                let x = r.values.get(axis)?.1;
                mean.is_finite().then_some((x, mean, low, high))
            })
            .collect();
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        let path = super::path_data(points.iter().map(|p| (to_x(p.0), y.to_px(p.1))));
        let _ = writeln!(
            out,
            "<path class=\"line\" d=\"{path}\" fill=\"none\" stroke=\"{ink}\" stroke-width=\"1.5\"/>"
        );
        for &(x, mean, low, high) in &points {
            let (cx, cy) = (px(to_x(x)), px(y.to_px(mean)));
            if low.is_finite() && high.is_finite() {
                let _ = writeln!(
                    out,
                    "<path d=\"M{cx} {}V{}\" stroke=\"{ink}\" opacity=\"0.6\"/>",
                    px(y.to_px(low)),
                    px(y.to_px(high))
                );
            }
            let _ = writeln!(
                out,
                "<circle class=\"point\" cx=\"{cx}\" cy=\"{cy}\" r=\"3\" fill=\"{ink}\"/>"
            );
        }
    }

    // The legend: what each line holds fixed.
    for (l, name) in names.iter().enumerate() {
        let y = bottom + BOTTOM_PX + 8.0 + LINE_PX * l as f64;
        let _ = writeln!(
            out,
            "<rect x=\"{}\" y=\"{}\" width=\"14\" height=\"3\" fill=\"{}\"/><text x=\"{}\" y=\"{}\" font-size=\"11\">{}</text>",
            px(plot_left),
            px(y - 4.0),
            colour(l),
            px(plot_left + 20.0),
            px(y),
            escape(name)
        );
    }
    out.push_str("</svg>\n");
    out
}

/// The x range around the parameter's values: theirs, or one value's size around a single
/// value (zero: [0, 1]).
fn x_range(values: &[f64]) -> (f64, f64) {
    let (lo, hi) = values
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    if !(lo.is_finite() && hi.is_finite()) {
        (0.0, 1.0)
    } else if hi > lo {
        (lo, hi)
    } else if lo == 0.0 {
        (0.0, 1.0)
    } else {
        let half = lo.abs() * 0.5;
        (lo - half, hi + half)
    }
}

/// A tick label: up to 4 significant digits, no trailing zeros.
fn number(value: f64) -> String {
    if value == 0.0 {
        return "0".into();
    }
    let digits = (3 - value.abs().log10().floor() as i32).clamp(0, 6) as usize;
    let text = format!("{value:.digits$}");
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.').to_owned()
    } else {
        text
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_parse_and_ranges_never_collapse() {
        assert_eq!(
            parse("twin@delay_ms=80+drop_probability=0.1"),
            Some(("twin", vec![("delay_ms", 80.0), ("drop_probability", 0.1)]))
        );
        assert_eq!(parse("twin"), None);
        assert_eq!(x_range(&[0.0, 0.0]), (0.0, 1.0));
        assert_eq!(x_range(&[0.0, 0.5, 1.0]), (0.0, 1.0));
        let (lo, hi) = x_range(&[2.0, 2.0]);
        assert!(lo < 2.0 && hi > 2.0);
        assert_eq!(number(0.25), "0.25");
        assert_eq!(number(100.0), "100");
    }
}
