//! Sensitivity curves: a metric against a swept parameter. Every fidelity of a sweep's
//! points (`twin-v2v@latency_ms=100,drop_probability=0.3`) is a row of the summary; for each
//! fidelity and each swept parameter the plot puts the parameter's values on the x axis and
//! draws one line per combination of the other sweeps' values and the other grouping axes
//! (the policy, by default): each point the row's mean with its t 95 % interval.

use std::fmt::Write;

use cpmx_spec::model::GroupKey;

use super::{escape, open, px};
use crate::Summary;
use crate::metric::Metric;

const PANEL_W: f64 = 300.0;
const PANEL_H: f64 = 220.0;
const LEFT: f64 = 52.0;
const TOP: f64 = 34.0;
const BOTTOM: f64 = 40.0;
const RIGHT: f64 = 12.0;
/// Okabe–Ito's colours, for lines.
const LINES: [&str; 7] = [
    "#0072B2", "#E69F00", "#009E73", "#CC79A7", "#56B4E9", "#D55E00", "#F0E442",
];

/// One row of the summary at a point of a sweep.
struct PointRow<'a> {
    base: &'a str,
    values: Vec<(&'a str, f64)>,
    /// The row's other grouping values (e.g. the policy).
    others: Vec<&'a str>,
    group: &'a crate::Group,
}

/// A fidelity's point parsed from its name: `base@a=1,b=2`.
fn parse(fidelity: &str) -> Option<(&str, Vec<(&str, f64)>)> {
    let (base, point) = fidelity.split_once('@')?;
    let values = point
        .split(',')
        .map(|pair| {
            let (label, value) = pair.split_once('=')?;
            Some((label, value.parse().ok()?))
        })
        .collect::<Option<Vec<_>>>()?;
    Some((base, values))
}

/// Every sensitivity plot of the summary: `(name, svg)` with `name` =
/// `sensitivity-<fidelity>-<parameter>`; none when no row is a point of a sweep (or the rows
/// are not grouped by fidelity).
pub fn sensitivity_svgs(summary: &Summary) -> Vec<(String, String)> {
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
    let mut plots = Vec::new();
    let mut bases: Vec<&str> = Vec::new();
    for row in &rows {
        if !bases.contains(&row.base) {
            bases.push(row.base);
        }
    }
    for base in bases {
        let of_base: Vec<&PointRow<'_>> = rows.iter().filter(|r| r.base == base).collect();
        let labels: Vec<&str> = of_base[0].values.iter().map(|(l, _)| *l).collect();
        for (axis, label) in labels.iter().enumerate() {
            plots.push((
                format!("sensitivity-{base}-{label}"),
                plot(summary, base, label, axis, &of_base),
            ));
        }
    }
    plots
}

/// The plot of `label` (the `axis`-th swept value) for the rows of one fidelity.
fn plot(summary: &Summary, base: &str, label: &str, axis: usize, rows: &[&PointRow<'_>]) -> String {
    // Lines: rows sharing everything but this parameter's value.
    let line_key = |r: &PointRow<'_>| -> String {
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
    for row in rows {
        let key = line_key(row);
        match lines.iter_mut().find(|(k, _)| *k == key) {
            Some((_, members)) => members.push(row),
            None => lines.push((key, vec![row])),
        }
    }
    let xs: Vec<f64> = rows
        .iter()
        .filter_map(|r| r.values.get(axis).map(|v| v.1))
        .collect();
    let (x_min, x_max) = bounds(&xs);
    let legend_h = 16.0 * lines.len() as f64;
    let width = PANEL_W * Metric::ALL.len() as f64;
    let height = PANEL_H + legend_h + 10.0;
    let mut out = open(width, height);
    let _ = writeln!(
        out,
        "<title>{}</title>",
        escape(&format!("{base}: the metrics against {label}"))
    );
    for (m, metric) in Metric::ALL.iter().enumerate() {
        let x0 = PANEL_W * m as f64;
        let values: Vec<f64> = rows
            .iter()
            .filter_map(|r| r.group.metric(*metric))
            .flat_map(|s| [s.stats.ci95.low, s.stats.ci95.high, s.stats.mean])
            .filter(|v| v.is_finite())
            .collect();
        let (y_min, y_max) = bounds(&values);
        let to_x = |x: f64| x0 + LEFT + (x - x_min) / (x_max - x_min) * (PANEL_W - LEFT - RIGHT);
        let to_y = |y: f64| TOP + (1.0 - (y - y_min) / (y_max - y_min)) * (PANEL_H - TOP - BOTTOM);
        let _ = writeln!(
            out,
            "<text x=\"{}\" y=\"16\">{} {} [{}]</text>",
            px(x0 + LEFT),
            metric.label(),
            metric.arrow(),
            escape(&summary.units.text(*metric))
        );
        // Axes with their ends labelled.
        let (bottom, top) = (to_y(y_min), to_y(y_max));
        let _ = writeln!(
            out,
            "<path d=\"M{l} {t}V{b}H{r}\" fill=\"none\" stroke=\"#555\"/>",
            l = px(x0 + LEFT),
            t = px(top),
            b = px(bottom),
            r = px(x0 + PANEL_W - RIGHT)
        );
        for (y, anchor) in [(y_min, bottom), (y_max, top)] {
            let _ = writeln!(
                out,
                "<text x=\"{}\" y=\"{}\" text-anchor=\"end\" font-size=\"10\">{}</text>",
                px(x0 + LEFT - 4.0),
                px(anchor + 4.0),
                number(y)
            );
        }
        let mut ticks: Vec<f64> = xs.clone();
        ticks.sort_by(f64::total_cmp);
        ticks.dedup();
        for x in ticks {
            let _ = writeln!(
                out,
                "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\" font-size=\"10\">{}</text>",
                px(to_x(x)),
                px(bottom + 14.0),
                number(x)
            );
        }
        let _ = writeln!(
            out,
            "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\" font-size=\"11\">{}</text>",
            px(x0 + (LEFT + PANEL_W - RIGHT) / 2.0),
            px(bottom + 30.0),
            escape(label)
        );
        // One line per combination, with its intervals.
        for (l, (_, members)) in lines.iter().enumerate() {
            let colour = LINES[l % LINES.len()];
            let mut points: Vec<(f64, f64, f64, f64)> = members
                .iter()
                .filter_map(|r| {
                    let s = r.group.metric(*metric)?;
                    let x = r.values.get(axis)?.1;
                    s.stats
                        .mean
                        .is_finite()
                        .then_some((x, s.stats.mean, s.stats.ci95.low, s.stats.ci95.high))
                })
                .collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            let path: Vec<String> = points
                .iter()
                .enumerate()
                .map(|(i, p)| {
                    format!(
                        "{}{} {}",
                        if i == 0 { 'M' } else { 'L' },
                        px(to_x(p.0)),
                        px(to_y(p.1))
                    )
                })
                .collect();
            let _ = writeln!(
                out,
                "<path d=\"{}\" fill=\"none\" stroke=\"{colour}\" stroke-width=\"1.5\"/>",
                path.join("")
            );
            for &(x, mean, low, high) in &points {
                let (cx, cy) = (px(to_x(x)), px(to_y(mean)));
                if low.is_finite() && high.is_finite() {
                    let _ = writeln!(
                        out,
                        "<path d=\"M{cx} {}V{}\" stroke=\"{colour}\" opacity=\"0.6\"/>",
                        px(to_y(low)),
                        px(to_y(high))
                    );
                }
                let _ = writeln!(out, "<circle cx=\"{cx}\" cy=\"{cy}\" r=\"3\" fill=\"{colour}\"/>");
            }
        }
    }
    // The legend: what each line holds fixed.
    for (l, (key, _)) in lines.iter().enumerate() {
        let y = PANEL_H + 8.0 + 16.0 * l as f64;
        let colour = LINES[l % LINES.len()];
        let _ = writeln!(
            out,
            "<rect x=\"{}\" y=\"{}\" width=\"14\" height=\"3\" fill=\"{colour}\"/><text x=\"{}\" y=\"{}\" font-size=\"11\">{}</text>",
            px(LEFT),
            px(y - 4.0),
            px(LEFT + 20.0),
            px(y),
            escape(if key.is_empty() { base } else { key })
        );
    }
    out.push_str("</svg>\n");
    out
}

/// A range around `values` that is never empty (a constant metric gets one of the value's
/// size, and zero everywhere gets [0, 1]).
fn bounds(values: &[f64]) -> (f64, f64) {
    let (lo, hi) = values
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    if !(lo.is_finite() && hi.is_finite()) {
        return (0.0, 1.0);
    }
    if hi - lo > 1e-12 * hi.abs().max(lo.abs()).max(1e-300) {
        let pad = (hi - lo) * 0.05;
        return (
            (lo - pad).min(if lo >= 0.0 { lo.max(0.0) } else { lo - pad }),
            hi + pad,
        );
    }
    if lo == 0.0 {
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
    fn points_parse_and_bounds_never_collapse() {
        assert_eq!(
            parse("twin@delay_ms=80,drop_probability=0.1"),
            Some(("twin", vec![("delay_ms", 80.0), ("drop_probability", 0.1)]))
        );
        assert_eq!(parse("twin"), None);
        assert_eq!(bounds(&[0.0, 0.0]), (0.0, 1.0));
        let (lo, hi) = bounds(&[2.0, 2.0]);
        assert!(lo < 2.0 && hi > 2.0);
        assert_eq!(number(0.25), "0.25");
        assert_eq!(number(100.0), "100");
    }
}
