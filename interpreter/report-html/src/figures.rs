//! The page's SVG figures, each in a `<figure>` of the page's grid with a caption that names
//! the policies it shows: the metric distributions and the sensitivity curves of a sweep. A
//! drawing grows with its column up to 1.5 times its natural width (the CSS reads it from
//! `--natural-width`); one wider than a column (many groups) spans two columns of a wide
//! window, one much wider the whole row.

use std::fmt::Write as _;

use cpmx_report::{Metric, SensitivityPlot, Summary, distribution_svg};
use cpmx_spec::model::GroupKey;

use crate::tables::escape;
use crate::{PageRun, data};

/// The distributions' section.
pub(crate) fn distributions(out: &mut String, summary: &Summary, runs: &[PageRun<'_>]) {
    out.push_str("<section id=\"distributions\"><h2>Metric distributions</h2><div class=\"panels\">\n");
    let policies = data::distinct(runs.iter().map(|run| &run.record.plan.policy));
    for &metric in summary.units.metrics() {
        let caption = distribution_caption(summary, metric, &policies);
        figure(out, &distribution_svg(summary, metric), &caption);
    }
    out.push_str("</div></section>\n");
}

/// The sensitivity section of `plots` (nothing when no fidelity is swept).
pub(crate) fn sensitivity(
    out: &mut String,
    summary: &Summary,
    runs: &[PageRun<'_>],
    plots: &[SensitivityPlot],
) {
    if plots.is_empty() {
        return;
    }
    out.push_str(
        "<section id=\"sensitivity\"><h2>Sensitivity</h2>\n<p>Each metric against a swept parameter: per line \
         the other sweeps' values and the policy held fixed; points are a row's mean over its independent \
         units, bars its t 95 % interval.</p><div class=\"panels\">\n",
    );
    for plot in plots {
        let prefix = format!("{}@", plot.fidelity);
        let policies = data::distinct(
            runs.iter()
                .filter(|run| run.record.plan.fidelity.starts_with(&prefix))
                .map(|run| &run.record.plan.policy),
        );
        figure(out, &plot.svg, &sensitivity_caption(summary, plot, &policies));
    }
    out.push_str("</div></section>\n");
}

/// One SVG in a figure of the grid, with its caption.
fn figure(out: &mut String, svg: &str, caption: &str) {
    let width_px = svg_width_px(svg).unwrap_or(0.0);
    let _ = write!(
        out,
        "<figure class=\"panel{}\" style=\"--natural-width: {width_px}px\">",
        match width_px {
            w if w > 900.0 => " full",
            w if w > 600.0 => " wide",
            _ => "",
        }
    );
    out.push_str(svg);
    let _ = writeln!(out, "<figcaption>{}</figcaption></figure>", escape(caption));
}

/// Which policies a figure shows: `per_policy` ("A column per policy") when the summary's
/// rows keep them apart, `pooled` ("Each column pools") when a row pools several.
fn policies_sentence(summary: &Summary, policies: &[&str], per_policy: &str, pooled: &str) -> String {
    let list = policies.join(", ");
    match policies {
        [] => "No runs yet.".to_owned(),
        [one] => format!("Policy {one}."),
        _ if summary.group_by.contains(&GroupKey::Policy) => format!("{per_policy}: {list}."),
        _ => format!("{pooled} the policies {list}."),
    }
}

/// The caption of a distribution: what a column is, and which policies it shows.
pub(crate) fn distribution_caption(summary: &Summary, metric: Metric, policies: &[&str]) -> String {
    let axes: Vec<&str> = summary
        .group_by
        .iter()
        .map(|axis| match axis {
            GroupKey::Fidelity => "fidelity",
            GroupKey::Policy => "policy",
            GroupKey::InitialConfiguration => "initial configuration",
        })
        .collect();
    format!(
        "{} of every run, a column per row of the summary ({}). {}",
        metric.label(),
        axes.join(" · "),
        policies_sentence(summary, policies, "A column per policy", "Each column pools")
    )
}

/// The caption of a sensitivity plot: the metric, the parameter, the fidelity, the policies.
fn sensitivity_caption(summary: &Summary, plot: &SensitivityPlot, policies: &[&str]) -> String {
    format!(
        "{} against {} at the points of fidelity {}. {}",
        plot.metric.label(),
        plot.parameter,
        plot.fidelity,
        policies_sentence(summary, policies, "Lines per policy", "Each point pools")
    )
}

/// The `width` of an SVG's root element [px].
fn svg_width_px(svg: &str) -> Option<f64> {
    let tag = &svg[svg.find("<svg")?..];
    let tag = &tag[..tag.find('>')?];
    let start = tag.find(" width=\"")? + " width=\"".len();
    tag[start..start + tag[start..].find('"')?].parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn captions_name_the_policies() {
        use cpmx_spec::model::{Bootstrap, ReportSpec, Statistic};
        let summary = |group_by| {
            let report = ReportSpec {
                group_by,
                statistics: vec![Statistic::Mean],
                bootstrap: Bootstrap {
                    resamples: 10,
                    seed: 1,
                },
                compare: None,
            };
            cpmx_report::summarize("captions", &[], &report, &cpmx_report::Origins::default())
        };
        let by_policy = summary(vec![GroupKey::Fidelity, GroupKey::Policy]);
        let pooled = summary(vec![GroupKey::Fidelity]);
        let caption = distribution_caption(&by_policy, Metric::Cd, &["a", "b"]);
        assert!(caption.ends_with("A column per policy: a, b."), "{caption}");
        let caption = distribution_caption(&pooled, Metric::Cd, &["a", "b"]);
        assert!(
            caption.ends_with("Each column pools the policies a, b."),
            "{caption}"
        );
        let caption = distribution_caption(&pooled, Metric::Cd, &["a"]);
        assert!(caption.ends_with("Policy a."), "{caption}");
        let plot = SensitivityPlot {
            name: "sensitivity-twin-delay_ms-cd_m".into(),
            fidelity: "twin".into(),
            parameter: "delay_ms".into(),
            metric: Metric::Cd,
            lines: vec!["a".into(), "b".into()],
            svg: String::new(),
        };
        let caption = sensitivity_caption(&by_policy, &plot, &["a", "b"]);
        assert_eq!(
            caption,
            "CD against delay_ms at the points of fidelity twin. Lines per policy: a, b."
        );
    }

    #[test]
    fn svg_widths_are_read() {
        assert_eq!(
            svg_width_px("<svg a=\"1\" width=\"420.0\" height=\"3\">"),
            Some(420.0)
        );
        assert_eq!(svg_width_px("<p>"), None);
    }
}
