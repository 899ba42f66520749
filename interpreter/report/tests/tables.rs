//! Snapshots of every text format for a fixed synthetic experiment, and the edge cases
//! (no runs, one run, no pairs) that must still render.

mod common;

use cpmx_report::{Format, Origins, per_run_csv, render, summarize};
use cpmx_spec::model::{GroupKey, ReportSpec, Statistic};

fn fixture() -> cpmx_report::Summary {
    summarize(
        "synthetic",
        &common::runs(),
        &common::report(&[GroupKey::Fidelity]),
        &Origins::default(),
    )
}

#[test]
fn markdown() {
    insta::assert_snapshot!(render(&fixture(), Format::Markdown));
}

#[test]
fn csv() {
    insta::assert_snapshot!(render(&fixture(), Format::Csv));
}

#[test]
fn json() {
    insta::assert_snapshot!(render(&fixture(), Format::Json));
}

#[test]
fn latex() {
    insta::assert_snapshot!(render(&fixture(), Format::Latex));
}

#[test]
fn per_run() {
    insta::assert_snapshot!(per_run_csv(&common::runs()));
}

#[test]
fn markdown_grouped_by_fidelity_and_policy_with_default_statistics() {
    let report = ReportSpec {
        group_by: vec![GroupKey::Fidelity, GroupKey::Policy],
        ..ReportSpec::default()
    };
    insta::assert_snapshot!(render(
        &summarize("synthetic", &common::runs(), &report, &Origins::default()),
        Format::Markdown
    ));
}

/// SigmaRL's evaluation statistics: the mean beside the median and the mean without the best and
/// the worst run, in the table's cells and its caption.
#[test]
fn markdown_with_the_median_and_the_trimmed_mean() {
    let report = ReportSpec {
        group_by: vec![GroupKey::Fidelity],
        statistics: vec![Statistic::Mean, Statistic::Median, Statistic::TrimmedMean],
        ..ReportSpec::default()
    };
    let markdown = render(
        &summarize("synthetic", &common::runs(), &report, &Origins::default()),
        Format::Markdown,
    );
    insta::assert_snapshot!(&markdown[..markdown.find("## Paired").unwrap_or(markdown.len())]);
}

/// Grouped by policy (the default), the paired comparison has a row per fidelity, policy and
/// metric: two policies' pairs are never pooled unless `group_by` pools them.
#[test]
fn the_comparison_is_per_policy_when_the_summary_groups_by_policy() {
    let summary = summarize(
        "synthetic",
        &common::runs(),
        &common::report(&[GroupKey::Fidelity, GroupKey::Policy]),
        &Origins::default(),
    );
    let markdown = render(&summary, Format::Markdown);
    let comparison = &markdown[markdown.find("## Paired comparison").unwrap()..];
    insta::assert_snapshot!(comparison);
    let json: serde_json::Value = serde_json::from_str(&render(&summary, Format::Json)).unwrap();
    let compared: Vec<(&str, &str)> = json["comparison"]["fidelities"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| (f["fidelity"].as_str().unwrap(), f["policy"].as_str().unwrap()))
        .collect();
    assert_eq!(
        compared,
        [
            ("twin", "seed1"),
            ("twin", "seed2"),
            ("lab", "seed1"),
            ("lab", "seed2")
        ]
    );
}

#[test]
fn rendering_is_byte_stable() {
    for format in Format::ALL {
        assert_eq!(render(&fixture(), format), render(&fixture(), format));
    }
}

#[test]
fn the_summary_json_parses_and_counts_the_nan_run() {
    let value: serde_json::Value = serde_json::from_str(&render(&fixture(), Format::Json)).unwrap();
    let lab = &value["groups"][2];
    assert_eq!(lab["key"]["fidelity"], "lab");
    assert_eq!(lab["metrics"]["cra_a"]["nan_count"], 1);
    assert_eq!(lab["metrics"]["cra_a"]["n"], 7);
    let twin = &value["comparison"]["fidelities"][0];
    assert_eq!(twin["metrics"]["cd_m"]["pairs"], 8);
}

#[test]
fn degenerate_inputs_render_in_every_format() {
    let report = common::report(&[GroupKey::Fidelity, GroupKey::InitialConfiguration]);
    let single = vec![common::record(
        "lab",
        "p",
        "i",
        1,
        [f64::NAN, f64::NAN, f64::NAN, f64::NAN],
        0.0,
    )];
    let one = vec![common::record("sim", "p", "i", 1, [1.0, 2.0, 0.1, 0.5], 10.0)];
    for runs in [vec![], single, one] {
        let summary = summarize("edge", &runs, &report, &Origins::default());
        for format in Format::ALL {
            let text = render(&summary, format);
            assert!(text.ends_with('\n'), "{format:?}: {text}");
        }
        assert!(per_run_csv(&runs).starts_with("key,fidelity"));
    }
    // The lab-only run has no pairs: the comparison says so instead of failing.
    let lab = vec![common::record("lab", "p", "i", 1, [1.0, 2.0, 0.1, 0.5], 10.0)];
    let markdown = render(
        &summarize("edge", &lab, &report, &Origins::default()),
        Format::Markdown,
    );
    assert!(
        markdown.contains("The reference fidelity has no runs."),
        "{markdown}"
    );
    assert!(
        markdown
            .contains("| lab | CRA-A ↓ [events/100 m] | 0 (1 unmatched) | n/a | n/a | n/a | 0/0/0 | n/a |"),
        "{markdown}"
    );
}

/// The synthetic experiment's two policies read as trained in two fidelities (`seed1` in sim,
/// `seed2` in twin, both with training seed 1): the Markdown summary ends with the transfer
/// matrix and the paired differences with the sim-trained policy.
#[test]
fn markdown_with_the_transfer_matrix() {
    let origin = |trained_in: &str| cpmx_report::Origin {
        trained_in: trained_in.to_owned(),
        seed: 1,
    };
    let origins = Origins {
        policies: [
            ("seed1".to_owned(), origin("sim")),
            ("seed2".to_owned(), origin("twin")),
        ]
        .into_iter()
        .collect(),
        reference: Some("sim".to_owned()),
    };
    let summary = summarize(
        "synthetic",
        &common::runs(),
        &common::report(&[GroupKey::Fidelity]),
        &origins,
    );
    let markdown = render(&summary, Format::Markdown);
    let transfer = &markdown[markdown.find("## Transfer").expect("a transfer section")..];
    insta::assert_snapshot!(transfer);
}

/// A fidelity with a safety layer: its counts summed over the group's runs (copies included:
/// a layer's counts are not a metric of independent units), its largest values the largest.
#[test]
fn what_the_layers_counted_is_summed_and_its_largest_kept_in_a_table_per_layer() {
    let mut runs = common::runs();
    for (k, run) in runs
        .iter_mut()
        .enumerate()
        .filter(|(_, r)| r.plan.fidelity == "sim")
    {
        run.statistics = [
            ("safety.changed".to_owned(), k as f64),
            ("safety.largest_speed_change_mps".to_owned(), 0.1 * k as f64),
        ]
        .into_iter()
        .collect();
    }
    // The twin's runs count their follower's stops: a table of their own, without the sim.
    for (k, run) in runs
        .iter_mut()
        .enumerate()
        .filter(|(_, r)| r.plan.fidelity == "twin")
    {
        run.statistics = [
            ("follower.periods".to_owned(), 100.0),
            ("follower.stopped_refused".to_owned(), (k % 3) as f64),
        ]
        .into_iter()
        .collect();
    }
    let summary = summarize(
        "synthetic",
        &runs,
        &common::report(&[GroupKey::Fidelity]),
        &Origins::default(),
    );
    let sim: Vec<usize> = runs
        .iter()
        .enumerate()
        .filter(|(_, r)| r.plan.fidelity == "sim")
        .map(|(k, _)| k)
        .collect();
    let group = summary.groups.iter().find(|g| g.key == ["sim"]).unwrap();
    assert_eq!(
        group.layer_counts["safety.changed"],
        sim.iter().sum::<usize>() as f64
    );
    assert_eq!(
        group.layer_counts["safety.largest_speed_change_mps"],
        0.1 * *sim.iter().max().unwrap() as f64
    );
    assert!(
        summary
            .groups
            .iter()
            .filter(|g| g.key != ["sim"])
            .all(|g| !g.layer_counts.contains_key("safety.changed"))
    );
    let twin = summary.groups.iter().find(|g| g.key == ["twin"]).unwrap();
    assert_eq!(twin.layer_counts["follower.periods"], 100.0 * twin.runs as f64);
    assert!(
        summary
            .groups
            .iter()
            .find(|g| g.key == ["lab"])
            .unwrap()
            .layer_counts
            .is_empty()
    );
    insta::assert_snapshot!(render(&summary, Format::Markdown));
}
