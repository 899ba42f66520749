//! `builtin: lane-follow` on the built-in four-way intersection: no deadlock at simultaneous
//! arrivals, no overlapping footprints, a stop at the end of every (open) path.

use cpmx_policy::{AgentPaths, AgentState, LaneFollow, LaneFollowParams, ObservationInput, Policy};
use cpmx_vehicle::{BicycleState, Command, Footprint, KinematicBicycle, VehicleParams, footprint_corners};
use cpmx_world::{Map, Point, ReferencePath};

const STEPS: usize = 150;
const DT_S: f64 = 0.1;

/// What a run of one configuration gives.
struct Outcome {
    /// Final states.
    end: Vec<BicycleState>,
    /// Largest distance of each agent's centre from its centre line over the run [m].
    max_deviation_m: Vec<f64>,
    /// First step and pair whose footprints overlapped.
    overlap: Option<(usize, usize, usize)>,
}

fn simulate(map: &Map, ids: &[usize], arcs_m: &[f64], steps: usize) -> Outcome {
    let vehicle = VehicleParams::MU_CAR;
    let model = KinematicBicycle::new(vehicle);
    let paths: Vec<&ReferencePath> = ids.iter().map(|&id| map.reference_path(id).unwrap()).collect();
    let prepared = AgentPaths::new(paths.iter().copied());
    let mut policy = LaneFollow::new(LaneFollowParams::default());
    let mut states: Vec<BicycleState> = ids
        .iter()
        .zip(arcs_m)
        .map(|(&id, &s)| {
            let (x_m, y_m, yaw_rad) = map.pose_at(id, s).unwrap();
            BicycleState {
                x_m,
                y_m,
                yaw_rad,
                ..Default::default()
            }
        })
        .collect();
    let mut commands = vec![Command::default(); states.len()];
    let mut max_deviation_m = vec![0.0_f64; states.len()];
    let mut overlap = None;
    for step in 0..=steps {
        for (k, s) in states.iter().enumerate() {
            max_deviation_m[k] = max_deviation_m[k].max(paths[k].center_line.distance_m([s.x_m, s.y_m]));
        }
        let corners: Vec<Footprint> = states
            .iter()
            .map(|s| footprint_corners(&vehicle, s.x_m, s.y_m, s.yaw_rad))
            .collect();
        for a in 0..corners.len() {
            for b in 0..a {
                if overlap.is_none() && overlaps(&corners[a], &corners[b]) {
                    overlap = Some((step, b, a));
                }
            }
        }
        if step == steps {
            break;
        }
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
        for (s, c) in states.iter_mut().zip(&commands) {
            *s = model.step(s, *c, DT_S).state;
        }
    }
    Outcome {
        end: states,
        max_deviation_m,
        overlap,
    }
}

/// Separating-axis test of two convex quadrilaterals (touching counts as apart).
fn overlaps(a: &Footprint, b: &Footprint) -> bool {
    for poly in [a, b] {
        for k in 0..4 {
            let (p, q) = (poly[k], poly[(k + 1) % 4]);
            let axis = [q[1] - p[1], p[0] - q[0]];
            let range = |f: &Footprint| {
                f.iter()
                    .map(|c| c[0] * axis[0] + c[1] * axis[1])
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                        (lo.min(v), hi.max(v))
                    })
            };
            let (ra, rb) = (range(a), range(b));
            if ra.1 <= rb.0 || rb.1 <= ra.0 {
                return false;
            }
        }
    }
    true
}

/// Arc length of the projection of `p` onto a polyline.
fn arc_length_m(points: &[Point], p: Point) -> f64 {
    let (mut best, mut best_s, mut start) = (f64::INFINITY, 0.0, 0.0);
    for w in points.windows(2) {
        let (dx, dy) = (w[1][0] - w[0][0], w[1][1] - w[0][1]);
        let len = dx.hypot(dy);
        let t = if len > 0.0 {
            (((p[0] - w[0][0]) * dx + (p[1] - w[0][1]) * dy) / (len * len)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let d = (w[0][0] + t * dx - p[0]).hypot(w[0][1] + t * dy - p[1]);
        if d < best {
            best = d;
            best_s = start + t * len;
        }
        start += len;
    }
    best_s
}

/// Exit arm (N, E, S, W = 0..3) of path `id` = 3 * entry + movement (right, straight, left).
fn exit_of(id: usize) -> usize {
    let (entry, movement) = (id / 3, id % 3);
    // Entries N, E, S, W drive south, west, north, east; turning right from N leads west.
    match movement {
        0 => (entry + 3) % 4,
        1 => (entry + 2) % 4,
        _ => (entry + 1) % 4,
    }
}

/// Run one configuration and check everything; returns a description of failures.
fn check(map: &Map, ids: &[usize], arcs_m: &[f64]) -> Vec<String> {
    check_for(map, ids, arcs_m, STEPS)
}

/// [`check`] over `steps` steps.
fn check_for(map: &Map, ids: &[usize], arcs_m: &[f64], steps: usize) -> Vec<String> {
    let out = simulate(map, ids, arcs_m, steps);
    let vehicle = VehicleParams::MU_CAR;
    let mut failures = Vec::new();
    if let Some((step, a, b)) = out.overlap {
        failures.push(format!(
            "{ids:?}: footprints of agents {a} and {b} overlap at step {step}"
        ));
    }
    for (k, &id) in ids.iter().enumerate() {
        let path = map.reference_path(id).unwrap();
        let pts = &path.center_line.points;
        let length_m = path.center_line.length_m();
        let s = &out.end[k];
        let arc = arc_length_m(pts, [s.x_m, s.y_m]);
        let last = pts[pts.len() - 1];
        let to_end = (s.x_m - last[0]).hypot(s.y_m - last[1]);
        // Agents that share an exit lane queue up there: the later ones stop behind the earlier.
        let queued = ids
            .iter()
            .enumerate()
            .filter(|&(m, &other)| {
                m != k && exit_of(other) == exit_of(id) && {
                    let o = &out.end[m];
                    arc_length_m(pts, [o.x_m, o.y_m]) > arc
                }
            })
            .count() as f64;
        let slot_m = queued * (vehicle.length_m + LaneFollowParams::default().standstill_gap_m);
        if arc < length_m - 0.5 - slot_m {
            failures.push(format!(
                "{ids:?}: agent {k} (path {id}) ended at arc {arc:.3} of {length_m:.3} m"
            ));
        }
        if s.speed_mps.abs() >= 0.05 {
            failures.push(format!(
                "{ids:?}: agent {k} (path {id}) still moves at {:.3} m/s",
                s.speed_mps
            ));
        }
        if to_end > 0.3 + slot_m {
            failures.push(format!(
                "{ids:?}: agent {k} (path {id}) stopped {to_end:.3} m from the end"
            ));
        }
        if out.max_deviation_m[k] > 0.03 {
            failures.push(format!(
                "{ids:?}: agent {k} (path {id}) deviated {:.3} m from its centre line",
                out.max_deviation_m[k]
            ));
        }
    }
    failures
}

fn map() -> Map {
    Map::builtin("intersection").unwrap()
}

#[test]
fn four_simultaneous_arrivals_do_not_deadlock() {
    let map = map();
    let mut failures = check(&map, &[1, 4, 7, 11], &[0.3, 0.2, 0.3, 0.2]);
    failures.extend(check(&map, &[2, 5, 6, 9], &[0.2, 0.3, 0.2, 0.3]));
    failures.extend(check(&map, &[1, 4, 7, 10], &[0.3, 0.3, 0.3, 0.3]));
    failures.extend(check(&map, &[2, 5, 8, 11], &[0.3, 0.3, 0.3, 0.3]));
    failures.extend(check(&map, &[0, 4, 8, 10], &[0.2, 0.25, 0.3, 0.2]));
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn every_path_alone_ends_in_a_stop_at_its_end() {
    let map = map();
    let mut failures = Vec::new();
    for id in map.valid_path_ids() {
        failures.extend(check(&map, &[id], &[0.3]));
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn pairs_of_crossing_paths_pass_one_after_the_other() {
    let map = map();
    let mut failures = Vec::new();
    // Every pair of paths from different entries to different exits, arriving together.
    for a in 0..12 {
        for b in 0..12 {
            if a / 3 < b / 3 && exit_of(a) != exit_of(b) {
                failures.extend(check(&map, &[a, b], &[0.3, 0.3]));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn the_same_configuration_gives_the_same_result() {
    let map = map();
    let a = simulate(&map, &[1, 4, 7, 11], &[0.3, 0.2, 0.3, 0.2], STEPS).end;
    let b = simulate(&map, &[1, 4, 7, 11], &[0.3, 0.2, 0.3, 0.2], STEPS).end;
    assert_eq!(a, b);
}

#[test]
fn all_twelve_paths_at_once_get_through_without_contact() {
    // Twelve agents need more than 15 s: they cross one after the other (40 s here).
    let map = map();
    let ids: Vec<usize> = (0..12).collect();
    let arcs_m: Vec<f64> = ids.iter().map(|&id| [0.6, 0.3, 0.0][id % 3]).collect();
    let failures = check_for(&map, &ids, &arcs_m, 400);
    assert!(failures.is_empty(), "{failures:#?}");
}
