//! The distribution of one metric: per group, every run's value as a dot (jittered
//! sideways by a fixed sequence, so the plot is reproducible), the mean as a solid bar and
//! the IQM as a dashed bar. Undefined (NaN) runs are counted under the group's label.

use std::fmt::Write;

use super::axis::Axis;
use super::{colour, escape, open, px};
use crate::Summary;
use crate::metric::Metric;

/// Width of one group's column [px], at least: columns widen for long labels and to fill the
/// drawing.
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
    let values = summary
        .groups
        .iter()
        .filter_map(|g| g.metric(metric))
        .flat_map(|m| m.values.iter().copied());
    let axis = Axis::of(values, TOP_PX, PLOT_PX);
    let columns = summary.groups.len().max(1) as f64;
    // Wide enough for the longest group label (sans-serif at 12 px: about 7 px a character).
    let label_px = summary
        .groups
        .iter()
        .map(|g| 7.0 * g.key.join(" / ").chars().count() as f64 + 10.0)
        .fold(COLUMN_PX, f64::max);
    let width_px = (LEFT_PX + label_px * columns + 20.0).max(MIN_WIDTH_PX);
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
    axis.note_constant(&mut out, "every run", metric.decimals(), width_px - 20.0, 34.0);
    axis.draw(&mut out, LEFT_PX, width_px - 20.0, 12);

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jitter_stays_in_its_lane() {
        assert!((0..100).map(jitter).all(|j| (-0.5..0.5).contains(&j)));
        assert_eq!(jitter(0), -0.5);
    }
}
