//! The page's data for a small folder: two fidelities of one policy and configuration on the
//! built-in intersection, measured by the real metrics. Snapshot the data, not the pixels.

use cpmx_metrics::{MetricsConfig, PathGeometry, evaluate};
use cpmx_recording::{AgentSample, Recording};
use cpmx_report::{Origins, RunRecord, summarize};
use cpmx_report_html::{Page, PageRun, page_data, report_html};
use cpmx_spec::RunPlan;
use cpmx_spec::model::{Bootstrap, Compare, GroupKey, PairedTest, ReportSpec, Statistic};
use cpmx_vehicle::VehicleParams;
use cpmx_world::Map;

/// Two agents driving along reference paths 1 and 4 for 1 s, `offset_m` to the side.
fn recording(map: &Map, offset_m: f64) -> Recording {
    let ref_paths = vec![1, 4];
    let times_s: Vec<f64> = (0..=10).map(|k| k as f64 * 0.1).collect();
    let samples = times_s
        .iter()
        .enumerate()
        .map(|(k, _)| {
            ref_paths
                .iter()
                .map(|&id| {
                    let points = &map.reference_path(id).unwrap().center_line.points;
                    let (a, b) = (points[k], points[k + 1]);
                    let yaw_rad = (b[1] - a[1]).atan2(b[0] - a[0]);
                    AgentSample {
                        x_m: a[0] - offset_m * yaw_rad.sin(),
                        y_m: a[1] + offset_m * yaw_rad.cos(),
                        yaw_rad,
                        velocity_mps: [(b[0] - a[0]) / 0.1, (b[1] - a[1]) / 0.1],
                        steering_rad: 0.0,
                    }
                })
                .collect()
        })
        .collect();
    Recording {
        times_s,
        ref_paths,
        samples,
        notes: vec![],
        latency_s: Vec::new(),
        statistics: Default::default(),
    }
}

fn record(map: &Map, fidelity: &str, recording: &Recording) -> RunRecord {
    let paths: Vec<PathGeometry<'_>> = recording
        .ref_paths
        .iter()
        .map(|&id| PathGeometry::from(map.reference_path(id).unwrap()))
        .collect();
    let metrics = evaluate(
        recording,
        &paths,
        &VehicleParams::MU_CAR,
        &MetricsConfig::default(),
    )
    .unwrap();
    RunRecord {
        plan: RunPlan {
            key: format!("{fidelity}/p/init1/rep1"),
            fidelity: fidelity.into(),
            policy: "p".into(),
            initial_configuration: "init1".into(),
            repetition: 1,
            seed: 1,
        },
        metrics,
        recording_sha256: format!("digest of {fidelity}"),
        drawn_parameters: Default::default(),
        statistics: Default::default(),
    }
}

#[test]
fn page_data_of_a_small_folder() {
    let map = Map::builtin("intersection").unwrap();
    let (sim, twin) = (recording(&map, 0.0), recording(&map, 0.02));
    let records = [record(&map, "sim", &sim), record(&map, "twin", &twin)];
    let report = ReportSpec {
        group_by: vec![GroupKey::Fidelity],
        statistics: vec![Statistic::Mean, Statistic::Std],
        bootstrap: Bootstrap {
            resamples: 100,
            seed: 7,
        },
        compare: Some(Compare {
            reference: "sim".into(),
            test: PairedTest::Paired,
        }),
    };
    let summary = summarize("small", &records, &report, &Origins::default());
    let vehicle = VehicleParams::MU_CAR;
    let page = Page {
        summary: &summary,
        description: Some("two fidelities"),
        maps: vec![&map],
        vehicle: &vehicle,
        runs: vec![
            PageRun {
                record: &records[0],
                recording: &sim,
                map: 0,
            },
            PageRun {
                record: &records[1],
                recording: &twin,
                map: 0,
            },
        ],
        learning_curves: vec![],
    };
    let data = serde_json::to_value(page_data(&page)).unwrap();
    // The runs of one pair replay together; Figure 3 picks a run per fidelity.
    assert_eq!(data["pairs"][0]["runs"], serde_json::json!([0, 1]));
    assert_eq!(data["figure3"][0]["representatives"].as_array().unwrap().len(), 2);
    insta::assert_json_snapshot!(data, {
        ".maps[].lanelets" => "[lanelet boundaries]",
        ".maps[].paths.*" => "[centre line]",
    });

    // The page: self-contained (no address to fetch), the data embedded, the tables in HTML.
    let html = report_html(&page);
    assert!(!html.contains("src=\"http") && !html.contains("<link") && !html.contains("url(http"));
    assert!(html.contains("<script id=\"cpmx-data\" type=\"application/json\">"));
    assert!(
        html.contains("<th>CRA-A ↓ [events/100 m]</th>"),
        "the summary table is in the page"
    );
}

#[test]
fn agents_that_come_and_go_are_drawn_over_their_own_samples_and_long_folders_thinned() {
    // Four agents on path 1 for 400,000 samples: agents 0 and 3 throughout, agent 1 until the
    // middle, agent 2 (placed instead) from the middle on: 1.2 million vehicle samples, more
    // than the page holds.
    let map = Map::builtin("intersection").unwrap();
    let count = 400_001;
    let half = 200_000;
    let at = |k: usize, lane: f64| AgentSample {
        x_m: (k % 1000) as f64 * 0.001,
        y_m: lane,
        yaw_rad: 0.0,
        velocity_mps: [0.5, 0.0],
        steering_rad: 0.0,
    };
    let samples: Vec<Vec<AgentSample>> = (0..count)
        .map(|k| {
            let first = if k < half { at(k, 1.0) } else { AgentSample::ABSENT };
            let later = if k >= half {
                at(k, 2.0)
            } else {
                AgentSample::ABSENT
            };
            vec![at(k, 0.0), first, later, at(k, 3.0)]
        })
        .collect();
    let recording = Recording {
        times_s: (0..count).map(|k| k as f64 * 0.1).collect(),
        ref_paths: vec![1; 4],
        samples,
        ..Recording::default()
    };
    let records = [record(&map, "sim", &recording)];
    let summary = summarize("long", &records, &ReportSpec::default(), &Origins::default());
    let vehicle = VehicleParams::MU_CAR;
    let page = Page {
        summary: &summary,
        description: None,
        maps: vec![&map],
        vehicle: &vehicle,
        runs: vec![PageRun {
            record: &records[0],
            recording: &recording,
            map: 0,
        }],
        learning_curves: vec![],
    };
    let data = serde_json::to_value(page_data(&page)).unwrap();
    assert_eq!(data["stride"], 2);
    let run = &data["runs"][0];
    assert_eq!(run["samples"], 200_001);
    assert!((run["dt"].as_f64().unwrap() - 0.2).abs() < 1e-12);
    let agents = run["agents"].as_array().unwrap();
    let span = |a: &serde_json::Value| (a["first"].as_u64().unwrap(), a["x"].as_array().unwrap().len());
    assert_eq!(span(&agents[0]), (0, 200_001));
    assert_eq!(span(&agents[1]), (0, 100_000));
    assert_eq!(span(&agents[2]), (100_000, 100_001));
    let html = report_html(&page);
    assert!(html.contains("Runs are drawn at one sample in 2 of the metrics' grid"));
}
