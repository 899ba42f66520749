//! Behaviour of the `builtin: lane-follow` baseline on synthetic paths and on the CPM map.

mod common;

use cpmx_policy::{AgentPaths, AgentState, LaneFollow, LaneFollowParams, ObservationInput, Policy};
use cpmx_vehicle::{BicycleState, Command, KinematicBicycle, VehicleParams};
use cpmx_world::{Polyline, ReferencePath};

/// A reference path along `points` (boundaries are offsets are not needed by the baseline).
fn path(id: usize, points: Vec<[f64; 2]>, is_loop: bool) -> ReferencePath {
    let line = Polyline::new(points);
    ReferencePath {
        id,
        lanelet_ids: vec![],
        is_loop,
        center_line: line.clone(),
        left_boundary: line.clone(),
        right_boundary: line.clone(),
        left_boundary_shared: line.clone(),
        right_boundary_shared: line,
        center_line_yaw_rad: vec![],
    }
}

/// Simulate `steps` steps of 0.1 s; returns the final states.
fn simulate(
    paths: &[ReferencePath],
    start: &[BicycleState],
    steps: usize,
    frozen: &[bool],
) -> Vec<BicycleState> {
    let vehicle = VehicleParams::MU_CAR;
    let model = KinematicBicycle::new(vehicle);
    let prepared = AgentPaths::new(paths.iter());
    let mut policy = LaneFollow::new(LaneFollowParams::default());
    let mut states = start.to_vec();
    let mut commands = vec![Command::default(); states.len()];
    for _ in 0..steps {
        let agents: Vec<AgentState> = states
            .iter()
            .map(|s| AgentState::from_bicycle(s, model.velocity_mps(s)))
            .collect();
        let input = ObservationInput {
            agents: &agents,
            paths: &prepared,
            vehicle: &vehicle,
            previous_corners: None,
            neighbours: None,
        };
        policy.act(&input, &mut commands).unwrap();
        for (i, s) in states.iter_mut().enumerate() {
            if !frozen[i] {
                *s = model.step(s, commands[i], 0.1).state;
            }
        }
    }
    states
}

fn start(x_m: f64, y_m: f64, yaw_rad: f64) -> BicycleState {
    BicycleState {
        x_m,
        y_m,
        yaw_rad,
        ..Default::default()
    }
}

#[test]
fn follows_a_straight_path_within_2_cm() {
    let line = path(0, (0..=100).map(|k| [0.1 * f64::from(k), 0.0]).collect(), false);
    let end = simulate(&[line], &[start(0.0, 0.06, 0.1)], 100, &[false]);
    assert!(end[0].y_m.abs() < 0.02, "{:?}", end[0]);
    assert!((end[0].speed_mps - 0.5).abs() < 1e-6, "{:?}", end[0]);
}

#[test]
fn follows_a_curve_within_2_cm() {
    let radius_m = 0.6;
    let circle: Vec<[f64; 2]> = (0..=120)
        .map(|k| {
            let a = std::f64::consts::TAU * f64::from(k) / 120.0;
            [radius_m * a.cos(), radius_m * a.sin()]
        })
        .collect();
    let loop_path = path(0, circle, true);
    let end = simulate(&[loop_path], &[start(radius_m + 0.03, 0.0, 1.57)], 150, &[false]);
    let off = (end[0].x_m.hypot(end[0].y_m) - radius_m).abs();
    assert!(off < 0.02, "off the circle by {off} m");
}

#[test]
fn stops_behind_a_standing_car() {
    let line = path(0, (0..=100).map(|k| [0.1 * f64::from(k), 0.0]).collect(), false);
    let paths = [line.clone(), line];
    let end = simulate(
        &paths,
        &[start(0.0, 0.0, 0.0), start(3.0, 0.0, 0.0)],
        200,
        &[false, true],
    );
    let gap = end[1].x_m - end[0].x_m - VehicleParams::MU_CAR.length_m;
    assert!(end[0].speed_mps.abs() < 1e-3, "{:?}", end[0]);
    assert!(gap > 0.15 && gap < 0.4, "gap {gap}");
}
