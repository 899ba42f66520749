//! The SVG plots: well-formed XML, one trajectory path per agent, footprints where the
//! metrics found events, one dot per defined run; a snapshot of a small trajectory plot.

mod common;

use cpmx_metrics::{MetricsConfig, PathGeometry, RunMetrics, evaluate};
use cpmx_recording::{AgentSample, Recording};
use cpmx_report::{
    AGENT_COLOURS, Metric, Origins, distribution_svg, sensitivity_svgs, summarize, trajectory_svg,
};
use cpmx_spec::model::GroupKey;
use cpmx_vehicle::VehicleParams;
use cpmx_world::Map;

/// Three agents on the built-in intersection for 2 s: agent 1 runs into agent 0 from behind
/// on path 1 (a collision event), agent 2 drifts out of its lane on path 4 (violations).
fn scene() -> (Map, Recording, RunMetrics) {
    let map = Map::builtin("intersection").unwrap();
    let pose = |path: usize, arc_m: f64, offset_m: f64, speed_mps: f64| {
        let (x, y, yaw) = map.pose_at(path, arc_m).unwrap();
        let (sin, cos) = yaw.sin_cos();
        AgentSample {
            x_m: x - offset_m * sin,
            y_m: y + offset_m * cos,
            yaw_rad: yaw,
            velocity_mps: [speed_mps * cos, speed_mps * sin],
            steering_rad: 0.0,
        }
    };
    let mut recording = Recording {
        notes: Vec::new(),
        latency_s: Vec::new(),
        statistics: Default::default(),
        times_s: vec![],
        ref_paths: vec![1, 1, 4],
        samples: vec![],
    };
    for k in 0..20 {
        let t = k as f64;
        recording.times_s.push(0.1 * t);
        recording.samples.push(vec![
            pose(1, 0.5 + 0.02 * t, 0.0, 0.2),
            pose(1, 0.1 + 0.06 * t, 0.0, 0.6),
            pose(4, 0.2 + 0.05 * t, 0.01 * t, 0.5),
        ]);
    }
    let metrics = measure(&map, &recording);
    (map, recording, metrics)
}

/// A recording's metrics on the built-in map (paths 1 and 4, the µCar, the paper's parameters).
fn measure(map: &Map, recording: &Recording) -> RunMetrics {
    let paths: Vec<PathGeometry> = [1, 4]
        .iter()
        .map(|&id| PathGeometry::from(map.reference_path(id).unwrap()))
        .collect();
    evaluate(
        recording,
        &paths,
        &VehicleParams::MU_CAR,
        &MetricsConfig::default(),
    )
    .unwrap()
}

fn count(doc: &roxmltree::Document, tag: &str, class: &str) -> usize {
    doc.descendants()
        .filter(|n| n.has_tag_name(tag) && n.attribute("class") == Some(class))
        .count()
}

#[test]
fn trajectory_plot_has_one_path_per_agent_and_marks_events() {
    let (map, recording, metrics) = scene();
    assert_eq!(metrics.pair_events.len(), 1, "{:?}", metrics.pair_events);
    assert!(!metrics.agents[2].violation_samples.is_empty());
    let svg = trajectory_svg(&map, &recording, &metrics, &VehicleParams::MU_CAR);
    let doc = roxmltree::Document::parse(&svg).unwrap();
    assert_eq!(count(&doc, "path", "trajectory"), 3);
    assert_eq!(count(&doc, "circle", "start"), 3);
    // Events in inks no agent takes, unfilled or translucent: they hide no trajectory.
    assert_eq!(count(&doc, "polygon", "collision"), 2);
    assert_eq!(count(&doc, "path", "collision-mark"), 1);
    assert_eq!(count(&doc, "circle", "violation"), 1);
    assert_eq!(count(&doc, "path", "violation-band"), 1);
    let agent_inks: Vec<&str> = doc
        .descendants()
        .filter(|n| n.attribute("class") == Some("trajectory"))
        .filter_map(|n| n.attribute("stroke"))
        .collect();
    for class in ["collision", "collision-mark", "violation", "violation-band"] {
        for mark in doc.descendants().filter(|n| n.attribute("class") == Some(class)) {
            assert!(
                matches!(mark.attribute("fill"), None | Some("none")),
                "{class} is not filled"
            );
            let ink = mark.attribute("stroke").unwrap();
            assert!(
                !agent_inks.contains(&ink),
                "{class} drawn in an agent's colour {ink}"
            );
        }
    }
    // The trajectories are drawn over the bands, the crosses and rings over the trajectories.
    let position = |class: &str| {
        doc.descendants()
            .position(|n| n.attribute("class") == Some(class))
            .unwrap()
    };
    assert!(position("violation-band") < position("trajectory"));
    assert!(position("trajectory") < position("collision-mark"));
    assert!(position("trajectory") < position("violation"));
    assert_eq!(count(&doc, "path", "ref-path"), 3);
    let lanelets = doc
        .descendants()
        .find(|n| n.attribute("class") == Some("lanelets"))
        .unwrap();
    assert_eq!(
        lanelets.children().filter(|n| n.has_tag_name("path")).count(),
        2 * map.lanelets().count()
    );
}

#[test]
fn agents_that_come_and_go_are_drawn_where_they_are_present() {
    let (map, mut recording, _) = scene();
    // Agent 2 leaves after sample 9 and a new agent 3 drives its last ten samples.
    recording.ref_paths.push(4);
    for (k, row) in recording.samples.iter_mut().enumerate() {
        let later = if k >= 10 { row[2] } else { AgentSample::ABSENT };
        if k >= 10 {
            row[2] = AgentSample::ABSENT;
        }
        row.push(later);
    }
    let metrics = measure(&map, &recording);
    let svg = trajectory_svg(&map, &recording, &metrics, &VehicleParams::MU_CAR);
    assert!(!svg.contains("NaN"), "absent samples are not drawn");
    let doc = roxmltree::Document::parse(&svg).unwrap();
    assert_eq!(count(&doc, "path", "trajectory"), 4);
    assert_eq!(count(&doc, "circle", "start"), 4);
}

#[test]
fn trajectory_plot_snapshot() {
    let (map, recording, metrics) = scene();
    // Only the path's own lanelets keep the snapshot small.
    let small = map.with_region("intersection").unwrap();
    insta::assert_snapshot!(trajectory_svg(
        &small,
        &recording,
        &metrics,
        &VehicleParams::MU_CAR
    ));
}

#[test]
fn out_of_range_event_samples_are_skipped() {
    let (map, mut recording, mut metrics) = scene();
    recording.samples.truncate(1);
    recording.times_s.truncate(1);
    metrics.agents[0].violation_samples = vec![50, 51];
    let svg = trajectory_svg(&map, &recording, &metrics, &VehicleParams::MU_CAR);
    let doc = roxmltree::Document::parse(&svg).unwrap();
    assert_eq!(count(&doc, "polygon", "collision"), 0);
    assert_eq!(count(&doc, "circle", "violation"), 0);
    assert_eq!(count(&doc, "path", "violation-band"), 0);
}

#[test]
fn distribution_plot_has_one_dot_per_defined_run() {
    let summary = summarize(
        "synthetic",
        &common::runs(),
        &common::report(&[GroupKey::Fidelity]),
        &Origins::default(),
    );
    for metric in Metric::ALL {
        let svg = distribution_svg(&summary, metric);
        let doc = roxmltree::Document::parse(&svg).unwrap();
        let defined: usize = summary
            .groups
            .iter()
            .map(|g| g.metric(metric).unwrap().stats.n)
            .sum();
        assert_eq!(count(&doc, "circle", "run"), defined, "{metric:?}");
        assert_eq!(count(&doc, "line", "mean"), 3);
        assert_eq!(count(&doc, "line", "iqm"), 3);
    }
    insta::assert_snapshot!(distribution_svg(&summary, Metric::CraA));
}

#[test]
fn distribution_plot_of_nothing_is_still_svg() {
    let summary = summarize(
        "empty",
        &[],
        &common::report(&[GroupKey::Fidelity]),
        &Origins::default(),
    );
    let svg = distribution_svg(&summary, Metric::As);
    roxmltree::Document::parse(&svg).unwrap();
    let nan = vec![common::record("lab", "p", "i", 1, [f64::NAN; 4], 0.0)];
    let svg = distribution_svg(
        &summarize(
            "nan",
            &nan,
            &common::report(&[GroupKey::Fidelity]),
            &Origins::default(),
        ),
        Metric::CraA,
    );
    let doc = roxmltree::Document::parse(&svg).unwrap();
    assert_eq!(count(&doc, "circle", "run"), 0);
    assert_eq!(count(&doc, "line", "mean"), 0);
}

#[test]
fn a_metric_zero_everywhere_gets_an_axis_from_zero_to_one_and_says_so() {
    let zeros = vec![
        common::record("sim", "p", "i", 1, [0.0; 4], 0.0),
        common::record("sim", "p", "i", 2, [0.0; 4], 0.0),
    ];
    let summary = summarize(
        "zeros",
        &zeros,
        &common::report(&[GroupKey::Fidelity]),
        &Origins::default(),
    );
    let svg = distribution_svg(&summary, Metric::CraA);
    let doc = roxmltree::Document::parse(&svg).unwrap();
    let ticks: Vec<f64> = doc
        .descendants()
        .filter(|n| n.has_tag_name("text") && n.attribute("class") == Some("tick"))
        .filter_map(|n| n.text()?.parse().ok())
        .collect();
    assert_eq!(ticks.first(), Some(&0.0), "{ticks:?}");
    assert_eq!(ticks.last(), Some(&1.0), "{ticks:?}");
    let constant = doc
        .descendants()
        .find(|n| n.attribute("class") == Some("constant"))
        .expect("the value written");
    assert_eq!(constant.text(), Some("every run: 0.00"));
}

#[test]
fn sensitivity_plots_are_one_metric_each_in_the_agents_colours() {
    // Two policies at three points of a swept delay: CRA-A zero everywhere.
    let mut runs = Vec::new();
    for delay in [0, 40, 80] {
        for (p, policy) in ["a", "b"].into_iter().enumerate() {
            for r in 1..=2 {
                let cd = 0.01 + 0.001 * f64::from(delay) / 40.0 + 0.002 * p as f64 + 0.0005 * f64::from(r);
                let fidelity = format!("twin@delay_ms={delay}");
                runs.push(common::record(
                    &fidelity,
                    policy,
                    "i",
                    r,
                    [0.0, 1.0, cd, 0.5],
                    10.0,
                ));
            }
        }
    }
    let summary = summarize(
        "sweep",
        &runs,
        &common::report(&[GroupKey::Fidelity, GroupKey::Policy]),
        &Origins::default(),
    );
    let plots = sensitivity_svgs(&summary);
    let names: Vec<&str> = plots.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "sensitivity-twin-delay_ms-cra_a",
            "sensitivity-twin-delay_ms-cra_l",
            "sensitivity-twin-delay_ms-cd_m",
            "sensitivity-twin-delay_ms-as_mps"
        ]
    );
    for plot in &plots {
        assert_eq!(plot.lines, ["a", "b"]);
        let doc = roxmltree::Document::parse(&plot.svg).unwrap();
        let svg = doc.root_element();
        assert!(svg.attribute("viewBox").is_some());
        let width: f64 = svg.attribute("width").unwrap().parse().unwrap();
        assert!((400.0..=600.0).contains(&width), "a column's width: {width}");
        let inks: Vec<&str> = doc
            .descendants()
            .filter(|n| n.attribute("class") == Some("line"))
            .map(|n| n.attribute("stroke").unwrap())
            .collect();
        assert_eq!(inks, AGENT_COLOURS[..2]);
        assert_eq!(count(&doc, "circle", "point"), 6);
    }
    // Zero everywhere: an axis from 0 to 1, and the value written.
    let doc = roxmltree::Document::parse(&plots[0].svg).unwrap();
    let ticks: Vec<f64> = doc
        .descendants()
        .filter(|n| n.attribute("class") == Some("tick"))
        .filter_map(|n| n.text()?.parse().ok())
        .collect();
    assert_eq!(
        (ticks.first(), ticks.last()),
        (Some(&0.0), Some(&1.0)),
        "{ticks:?}"
    );
    let constant = doc
        .descendants()
        .find(|n| n.attribute("class") == Some("constant"))
        .expect("the value written");
    assert_eq!(constant.text(), Some("every point: 0.00"));
    // CD varies: no note.
    let doc = roxmltree::Document::parse(&plots[2].svg).unwrap();
    assert!(
        doc.descendants()
            .all(|n| n.attribute("class") != Some("constant"))
    );
}
