//! Agreement with SigmaRL's `evaluate_single_run` on the reference data: the 20 synthetic
//! cases of `metrics/cases.json` and the rollout `rollouts/metrics_1.json`.
//!
//! Discrete results (event samples, violation samples, counts) must agree exactly.
//! Continuous ones are compared with the tolerances below, which are what an f64
//! computation can reach against the script's float32 arithmetic (see `TOLERANCES`).

mod common;

use std::collections::BTreeMap;

use common::*;
use cpmx_metrics::collision::{PlacedBox, sigmarl_mtv_distance_m};
use cpmx_metrics::{CollisionGeometry, MetricsConfig, PathGeometry, Rotate180, RunMetrics, evaluate};
use cpmx_vehicle::VehicleParams;
use serde_json::Value;

/// (output, relative tolerance, absolute floor): `|ours − ref| <= rel · |ref| + abs`.
///
/// The script computes step distances, speeds and centre-line distances in float32 and sums
/// the total distance and the speeds with torch's float32 reduction; this crate computes in
/// f64. Largest errors reached (20 cases / rollout): total_distance_m 9.8e-8 / 2.2e-8,
/// lane_violation_m 2.3e-8 / 2.1e-9, CRA_A_per_unit 7.0e-8 / 2.2e-8, LaneViolation_per_unit
/// 8.5e-8 / 2.4e-8, AS_mean_mps 2.1e-7 / 3.1e-8 (relative), CD_mean_m 4.9e-8 m / 5.5e-9 m
/// (absolute; a car on its centre line has a CD of float32 round-off, ~1e-8 m). Rounding our
/// step distances to float32 makes most of these exact but not all: torch's vectorised
/// float32 reduction order depends on the machine, so 1e-9 is out of reach in f64.
const TOLERANCES: [(&str, f64, f64); 6] = [
    ("total_distance_m", 2e-7, 0.0),
    ("lane_violation_m", 1e-7, 1e-12),
    ("CRA_A_per_unit", 2e-7, 0.0),
    ("LaneViolation_per_unit", 2e-7, 1e-12),
    ("CD_mean_m", 0.0, 1e-7),
    ("AS_mean_mps", 5e-7, 0.0),
];

fn ours(m: &RunMetrics, key: &str) -> f64 {
    match key {
        "total_distance_m" => m.distance_m,
        "lane_violation_m" => m.lane_violation_m,
        "CRA_A_per_unit" => m.cra_a,
        "LaneViolation_per_unit" => m.cra_l,
        "CD_mean_m" => m.cd_m,
        "AS_mean_mps" => m.as_mps,
        _ => unreachable!("unknown output {key}"),
    }
}

/// Compares one run's outputs; returns the problems found (empty = agreement).
fn compare(
    name: &str,
    m: &RunMetrics,
    reference: &Value,
    worst: &mut BTreeMap<&'static str, Worst>,
) -> Vec<String> {
    let mut problems = Vec::new();
    if m.num_samples as u64 != reference["num_steps"].as_u64().unwrap() {
        problems.push(format!(
            "{name}: num_steps {} vs {}",
            m.num_samples, reference["num_steps"]
        ));
    }
    if m.a2a_events as u64 != reference["raw_a2a_event_count"].as_u64().unwrap() {
        problems.push(format!(
            "{name}: raw_a2a_event_count {} vs {}",
            m.a2a_events, reference["raw_a2a_event_count"]
        ));
    }
    for (key, rel, abs) in TOLERANCES {
        let (a, b) = (ours(m, key), number(&reference[key]));
        worst.entry(key).or_default().record(a, b);
        let ok = (a.is_nan() && b.is_nan()) || (a - b).abs() <= rel * b.abs() + abs;
        if !ok {
            problems.push(format!(
                "{name}: {key} {a:e} vs {b:e} (rel {:e})",
                ((a - b) / b).abs()
            ));
        }
    }
    problems
}

fn sample_lists(v: &Value) -> Vec<Vec<usize>> {
    (0..3)
        .map(|i| {
            v[i.to_string()]
                .as_array()
                .unwrap()
                .iter()
                .map(|s| s.as_u64().unwrap() as usize)
                .collect()
        })
        .collect()
}

#[test]
fn every_metric_case_agrees_with_the_script() {
    let map = read_json(MAP);
    let lines = reference_paths(&map);
    let paths: Vec<PathGeometry> = lines.iter().map(PathLines::geometry).collect();
    let cases = read_json(CASES);
    let cases = cases["cases"].as_array().expect("cases");
    assert_eq!(cases.len(), 20);

    let mut problems = Vec::new();
    let mut worst = BTreeMap::new();
    let (mut worst_mtv_m, mut worst_cd_agent_m) = (0.0f64, 0.0f64);
    for case in cases {
        let name = case["name"].as_str().unwrap();
        let ids: Vec<usize> = case["ref_path_ids"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap() as usize)
            .collect();
        let vehicle = VehicleParams {
            width_m: case["veh_width"].as_f64().unwrap(),
            length_m: case["veh_length"].as_f64().unwrap(),
            ..VehicleParams::MU_CAR
        };
        let mut config = MetricsConfig::sigmarl_script(case["per_unit_m"].as_f64().unwrap());
        config.cra_a.hysteresis.enter = case["n1"].as_u64().unwrap() as usize;
        config.cra_a.hysteresis.exit = case["n2"].as_u64().unwrap() as usize;
        config.max_steps = case["max_steps"].as_u64().map(|m| m as usize);
        if case["rotate180"].as_bool().unwrap() {
            config.rotate180 = Some(Rotate180 {
                centre_m: map_centre(&map),
            });
        }
        let recording = recording(&case["pos"], &case["rot"], &case["vel"], ids);
        let m = evaluate(&recording, &paths, &vehicle, &config).expect("metrics");
        problems.extend(compare(name, &m, &case["metrics"], &mut worst));

        // Intermediates (absent for the rotated case).
        let inter = &case["intermediate"];
        if inter.is_null() {
            continue;
        }
        let events = sample_lists(&inter["collision_event_steps_per_agent"]);
        let violations = sample_lists(&inter["lane_violation_steps_per_agent"]);
        for (i, agent) in m.agents.iter().enumerate() {
            if agent.event_samples != events[i] {
                problems.push(format!(
                    "{name}: agent {i} events {:?} vs {:?}",
                    agent.event_samples, events[i]
                ));
            }
            if agent.violation_samples != violations[i] {
                problems.push(format!(
                    "{name}: agent {i} violations {:?} vs {:?}",
                    agent.violation_samples, violations[i]
                ));
            }
            let cd = inter["cd_mean_per_agent_m"][i].as_f64().unwrap();
            worst_cd_agent_m = worst_cd_agent_m.max((agent.cd_m - cd).abs());
        }
        for (pair, series) in inter["mtv_distance_pairs"].as_object().unwrap() {
            let (i, j) = pair.split_once('-').unwrap();
            let (i, j): (usize, usize) = (i.parse().unwrap(), j.parse().unwrap());
            for (k, d) in series.as_array().unwrap().iter().enumerate() {
                let at = |a: usize| {
                    let s = recording.samples[k][a];
                    PlacedBox::from_pose(&vehicle, s.x_m, s.y_m, s.yaw_rad).corners_m
                };
                let ours = sigmarl_mtv_distance_m(&at(i), &at(j));
                let reference = d.as_f64().unwrap();
                worst_mtv_m = worst_mtv_m.max((ours - reference).abs());
                if (ours < 0.0) != (reference < 0.0) {
                    problems.push(format!(
                        "{name}: pair {pair} sample {k}: sign of {ours} vs {reference}"
                    ));
                }
            }
        }
    }
    eprintln!("largest errors over the 20 cases: {worst:#?}");
    eprintln!("mtv_distance_pairs: largest absolute error {worst_mtv_m:e} m");
    eprintln!("cd_mean_per_agent_m: largest absolute error {worst_cd_agent_m:e} m");
    assert!(problems.is_empty(), "{}", problems.join("\n"));
    // The script builds corners and projections in float32 (positions of ~4 m: ulp 5e-7).
    assert!(worst_mtv_m < 1e-5, "mtv distances differ by {worst_mtv_m}");
    assert!(
        worst_cd_agent_m < 1e-7,
        "per-agent CD differs by {worst_cd_agent_m}"
    );
}

#[test]
fn the_rollout_agrees_with_the_script() {
    let map = read_json(MAP);
    let lines = reference_paths(&map);
    let paths: Vec<PathGeometry> = lines.iter().map(PathLines::geometry).collect();
    let rollout = read_json(ROLLOUT);
    let expected = read_json(ROLLOUT_METRICS);
    let steps = rollout["steps"].as_array().expect("steps");
    let field =
        |key: &str, count: usize| Value::Array(steps[..count].iter().map(|s| s[key].clone()).collect());
    let ids: Vec<usize> = expected["ref_path_ids"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap() as usize)
        .collect();

    let mut problems = Vec::new();
    let mut worst = BTreeMap::new();
    for (key, count) in [("states_0_to_179", 180), ("states_0_to_180", 181)] {
        let recording = recording(
            &field("pos", count),
            &field("rot", count),
            &field("vel", count),
            ids.clone(),
        );
        let config = MetricsConfig::sigmarl_script(expected["per_unit_m"].as_f64().unwrap());
        let m = evaluate(&recording, &paths, &VehicleParams::MU_CAR, &config).expect("metrics");
        problems.extend(compare(key, &m, &expected["metrics"][key], &mut worst));
    }
    eprintln!("largest errors on the rollout: {worst:#?}");
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// The paper's variants on the same cases: the 10 % slack only removes violation samples.
/// (The event counts of both geometries are printed; on these cases they are equal.)
#[test]
fn the_paper_variants_relax_the_script_consistently() {
    let map = read_json(MAP);
    let lines = reference_paths(&map);
    let paths: Vec<PathGeometry> = lines.iter().map(PathLines::geometry).collect();
    let cases = read_json(CASES);
    for case in cases["cases"].as_array().expect("cases") {
        if case["rotate180"].as_bool().unwrap() {
            continue;
        }
        let name = case["name"].as_str().unwrap();
        let ids = case["ref_path_ids"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap() as usize)
            .collect();
        let recording = recording(&case["pos"], &case["rot"], &case["vel"], ids);
        let mut config = MetricsConfig::sigmarl_script(100.0);
        config.max_steps = case["max_steps"].as_u64().map(|m| m as usize);
        let script = evaluate(&recording, &paths, &VehicleParams::MU_CAR, &config).unwrap();
        config.cra_l.slack = 0.10;
        config.cra_a.geometry = CollisionGeometry::Mtv;
        let paper = evaluate(&recording, &paths, &VehicleParams::MU_CAR, &config).unwrap();
        for (s, p) in script.agents.iter().zip(&paper.agents) {
            assert!(
                p.violation_samples
                    .iter()
                    .all(|k| s.violation_samples.contains(k)),
                "{name}: slack adds violations"
            );
        }
        assert!(paper.lane_violation_m <= script.lane_violation_m, "{name}");
        eprintln!(
            "{name}: events script {} / mtv {}; violation samples script {} / slack 0.1 {}",
            script.a2a_events,
            paper.a2a_events,
            script
                .agents
                .iter()
                .map(|a| a.violation_samples.len())
                .sum::<usize>(),
            paper
                .agents
                .iter()
                .map(|a| a.violation_samples.len())
                .sum::<usize>(),
        );
    }
}
