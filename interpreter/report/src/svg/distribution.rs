//! The distribution of one metric: per group, every run's value as a dot (jittered
//! sideways by a fixed sequence, so the plot is reproducible), the mean as a solid bar and
//! the IQM as a dashed bar. Undefined (NaN) runs are counted under the group's label.

use std::fmt::Write;

use super::{colour, escape, open, px};
use crate::Summary;
use crate::metric::Metric;
use crate::table::fixed;

/// Width of one group's column [px], at least: columns widen to fill the drawing.
const COLUMN_PX: f64 = 110.0;
/// The narrowest drawing [px] (about the width a page shows it at, so text keeps its size).
const MIN_WIDTH_PX: f64 = 420.0;
/// Height of the value axis [px].
const PLOT_PX: f64 = 240.0;
/// Space left of the axis for tick labels [px].
const LEFT_PX: f64 = 70.0;
/// Space above the plot for the title [px].
const TOP_PX: f64 = 50.0;
/// Space below the plot for group labels [px].
const BOTTOM_PX: f64 = 50.0;
/// The legend line under the title.
const LEGEND: &str = "dots: runs; solid: mean; dashed: IQM";

/// The SVG of `metric`'s per-run values in every group of `summary`. A metric with one value
/// in every run (zero everywhere, say) is drawn on an axis from zero to that value (0 to 1
/// for zero) and the value is written beside the legend.
pub fn distribution_svg(summary: &Summary, metric: Metric) -> String {
    let axis = Axis::of(summary, metric);
    let columns = summary.groups.len().max(1) as f64;
    let width_px = (LEFT_PX + COLUMN_PX * columns + 20.0).max(MIN_WIDTH_PX);
    let column_px = (width_px - LEFT_PX - 20.0) / columns;
    let mut out = open(width_px, TOP_PX + PLOT_PX + BOTTOM_PX);
    let title = format!(
        "{} {} [{}]",
        metric.label(),
        metric.arrow(),
        summary.units.text(metric)
    );
    let _ = writeln!(out, "<title>{}: {LEGEND}</title>", escape(&title));
    let _ = writeln!(
        out,
        "<text x=\"{}\" y=\"18\">{}</text>",
        px(LEFT_PX),
        escape(&title)
    );
    let _ = writeln!(
        out,
        "<text x=\"{}\" y=\"34\" font-size=\"10\">{LEGEND}</text>",
        px(LEFT_PX)
    );
    if let Some(value) = axis.constant {
        let _ = writeln!(
            out,
            "<text class=\"constant\" x=\"{}\" y=\"34\" text-anchor=\"end\" font-size=\"11\" font-weight=\"bold\">\
             every run: {}</text>",
            px(width_px - 20.0),
            fixed(value, metric.decimals())
        );
    }
    value_axis(&mut out, &axis, width_px);

    for (index, group) in summary.groups.iter().enumerate() {
        let Some(m) = group.metric(metric) else {
            continue;
        };
        let centre_px = LEFT_PX + column_px * (index as f64 + 0.5);
        let _ = writeln!(
            out,
            "<g class=\"group\" data-group=\"{}\">",
            escape(&group.key.join("/"))
        );
        for (j, &value) in m.values.iter().filter(|v| v.is_finite()).enumerate() {
            let _ = writeln!(
                out,
                "<circle class=\"run\" cx=\"{}\" cy=\"{}\" r=\"3\" fill=\"{}\" fill-opacity=\"0.7\"/>",
                px(centre_px + jitter(j) * COLUMN_PX * 0.5),
                px(axis.to_px(value)),
                colour(index)
            );
        }
        bar(&mut out, centre_px, axis.to_px(m.stats.mean), "mean", "");
        bar(
            &mut out,
            centre_px,
            axis.to_px(m.stats.iqm),
            "iqm",
            " stroke-dasharray=\"5 3\"",
        );
        let label_y = TOP_PX + PLOT_PX + 20.0;
        let _ = writeln!(
            out,
            "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}</text>",
            px(centre_px),
            px(label_y),
            escape(&group.key.join(" / "))
        );
        let count = match m.stats.nan_count {
            0 => format!("n = {}", m.stats.n),
            nan => format!("n = {} ({nan} NaN)", m.stats.n),
        };
        let _ = writeln!(
            out,
            "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\" font-size=\"10\">{count}</text>\n</g>",
            px(centre_px),
            px(label_y + 15.0)
        );
    }
    out.push_str("</svg>\n");
    out
}

/// A horizontal mark across the middle of a column (nothing for an undefined value).
fn bar(out: &mut String, centre_px: f64, y_px: f64, class: &str, style: &str) {
    if !y_px.is_finite() {
        return;
    }
    let half = COLUMN_PX * 0.3;
    let _ = writeln!(
        out,
        "<line class=\"{class}\" x1=\"{}\" y1=\"{y}\" x2=\"{}\" y2=\"{y}\" stroke=\"black\" stroke-width=\"2\"{style}/>",
        px(centre_px - half),
        px(centre_px + half),
        y = px(y_px)
    );
}

/// The `j`-th sideways offset in [−0.5, 0.5): the fractional parts of `j · φ` (golden
/// ratio), evenly spread and the same on every run.
fn jitter(j: usize) -> f64 {
    const PHI: f64 = 0.618_033_988_749_895;
    (j as f64 * PHI).fract() - 0.5
}

/// The value range of the plot.
struct Axis {
    low: f64,
    high: f64,
    /// The one value of every run, when there is exactly one.
    constant: Option<f64>,
}

impl Axis {
    /// The range of every finite value of `metric`, padded by 5 %. A constant metric gets
    /// the range from zero to its value (a metric that is zero everywhere, or has no defined
    /// value, gets [0, 1]): a flat sample shows as flat, at its true size.
    fn of(summary: &Summary, metric: Metric) -> Axis {
        let values = summary
            .groups
            .iter()
            .filter_map(|g| g.metric(metric))
            .flat_map(|m| m.values.iter().copied())
            .filter(|v| v.is_finite());
        let (low, high) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
            (l.min(v), h.max(v))
        });
        Axis::around(low, high)
    }

    /// The axis of values from `low` to `high` (`low > high`: no value).
    fn around(low: f64, high: f64) -> Axis {
        let constant = (low == high).then_some(low);
        let (low, high) = if low > high {
            (0.0, 1.0)
        } else if low == high {
            match low {
                0.0 => (0.0, 1.0),
                v => (v.min(0.0), v.max(0.0)),
            }
        } else {
            (low, high)
        };
        let pad = 0.05 * (high - low);
        Axis {
            low: low - pad,
            high: high + pad,
            constant,
        }
    }

    fn to_px(&self, value: f64) -> f64 {
        TOP_PX + PLOT_PX * (self.high - value) / (self.high - self.low)
    }
}

/// The axis line, and tick labels with light grid lines at round values.
fn value_axis(out: &mut String, axis: &Axis, width_px: f64) {
    let _ = writeln!(
        out,
        "<line class=\"axis\" x1=\"{x}\" y1=\"{}\" x2=\"{x}\" y2=\"{}\" stroke=\"black\"/>",
        px(TOP_PX),
        px(TOP_PX + PLOT_PX),
        x = px(LEFT_PX)
    );
    let (step, decimals) = nice_step((axis.high - axis.low) / 5.0);
    let first = (axis.low / step).ceil();
    for k in 0..12 {
        let value = (first + k as f64) * step;
        if value > axis.high {
            break;
        }
        let y = px(axis.to_px(value));
        let _ = writeln!(
            out,
            "<line x1=\"{}\" y1=\"{y}\" x2=\"{}\" y2=\"{y}\" stroke=\"#e0e0e0\"/>\
             <text x=\"{}\" y=\"{y}\" text-anchor=\"end\" dominant-baseline=\"middle\">{}</text>",
            px(LEFT_PX),
            px(width_px - 20.0),
            px(LEFT_PX - 6.0),
            fixed(value, decimals)
        );
    }
}

/// The smallest step of the form {1, 2, 5} x 10^k (k from -12) that is at least `raw`,
/// with the decimals it needs.
fn nice_step(raw: f64) -> (f64, usize) {
    for exponent in -12i32..=15 {
        for multiple in [1, 2, 5] {
            // Parsing gives the correctly rounded value of the decimal, with no accumulated error.
            let step: f64 = format!("{multiple}e{exponent}").parse().unwrap_or(f64::INFINITY);
            if step >= raw {
                return (step, (-exponent).max(0) as usize);
            }
        }
    }
    (raw.max(1e15), 0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jitter_stays_in_its_lane() {
        assert!((0..100).map(jitter).all(|j| (-0.5..0.5).contains(&j)));
        assert_eq!(jitter(0), -0.5);
    }

    #[test]
    fn constant_metrics_get_an_axis_of_their_size() {
        let range = |low, high| {
            let a = Axis::around(low, high);
            (a.low, a.high)
        };
        // Zero everywhere, and no value at all: [0, 1] (padded).
        assert_eq!(range(0.0, 0.0), (-0.05, 1.05));
        assert_eq!(range(f64::INFINITY, f64::NEG_INFINITY), (-0.05, 1.05));
        // A constant: from zero to it.
        let (low, high) = range(0.4, 0.4);
        assert!(
            (low + 0.02).abs() < 1e-12 && (high - 0.42).abs() < 1e-12,
            "{low} {high}"
        );
        let (low, high) = range(-2.0, -2.0);
        assert!(
            (low + 2.1).abs() < 1e-12 && (high - 0.1).abs() < 1e-12,
            "{low} {high}"
        );
        // Varying values: their range, padded.
        let (low, high) = range(1.0, 3.0);
        assert!((low - 0.9).abs() < 1e-12 && (high - 3.1).abs() < 1e-12);
        assert_eq!(Axis::around(0.0, 0.0).constant, Some(0.0));
        assert_eq!(Axis::around(1.0, 3.0).constant, None);
        assert_eq!(Axis::around(f64::INFINITY, f64::NEG_INFINITY).constant, None);
    }

    #[test]
    fn steps_are_round() {
        assert_eq!(nice_step(2.3), (5.0, 0));
        assert_eq!(nice_step(0.0013).1, 3);
        assert!((nice_step(0.0013).0 - 0.002).abs() < 1e-15);
        assert_eq!(nice_step(0.0), (1e-12, 12));
        assert_eq!(nice_step(f64::NAN).1, 0);
    }
}
