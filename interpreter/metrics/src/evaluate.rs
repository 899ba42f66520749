//! The per-run metrics of one recording: CRA-A, CRA-L, CD and AS with the raw counts behind
//! them, computed as SigmaRL's `evaluate_single_run` does (in f64).
//!
//! This module owns the order of the steps (resample, truncate, rotate, footprints,
//! distances, events, violations, means). It reads a `Recording` and the map's reference
//! paths only, never an engine.

use cpmx_recording::{AgentSample, Recording};
use cpmx_vehicle::{VehicleParams, Walls, footprint_corners, rectangles_cross};
use cpmx_world::{Point, Polyline, ReferencePath, SegmentBoxes, polyline::dist};

use crate::MetricsError;
use crate::collision::{PlacedBox, signed_distance_m};
use crate::config::{END_REACHED_M, EventCount, LaneBoundaries, MetricsConfig};
use crate::hysteresis::event_samples;
use crate::lane::Lane;
use crate::output::{AgentMetrics, PairEvent, RunMetrics};
use crate::resample::resample;

/// What the metrics need of a reference path: its id, centre line, own-lane and road boundaries.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathGeometry<'a> {
    /// The id agents refer to it by (`Recording::ref_paths`).
    pub id: usize,
    /// Centre line (CD is measured to it).
    pub center_line: &'a [Point],
    /// Own-lane left boundary, in driving direction.
    pub left_boundary: &'a [Point],
    /// Own-lane right boundary, in driving direction.
    pub right_boundary: &'a [Point],
    /// The road's left boundary (shared by the lanes of the same direction), in driving
    /// direction.
    pub road_left_boundary: &'a [Point],
    /// The road's right boundary.
    pub road_right_boundary: &'a [Point],
    /// Whether the path is a closed loop (it has no end to reach).
    pub is_loop: bool,
}

impl<'a> From<&'a ReferencePath> for PathGeometry<'a> {
    fn from(path: &'a ReferencePath) -> Self {
        Self {
            id: path.id,
            center_line: &path.center_line.points,
            left_boundary: &path.left_boundary.points,
            right_boundary: &path.right_boundary.points,
            road_left_boundary: &path.left_boundary_shared.points,
            road_right_boundary: &path.right_boundary_shared.points,
            is_loop: path.is_loop,
        }
    }
}

/// Computes every metric of one run from its recording.
///
/// `ref_paths` must hold (at least) every reference path the recording's agents use, found by
/// their `id` (build them with `PathGeometry::from(&reference_path)`); `vehicle` gives the
/// footprint (length and width).
pub fn evaluate(
    recording: &Recording,
    ref_paths: &[PathGeometry<'_>],
    vehicle: &VehicleParams,
    config: &MetricsConfig,
) -> Result<RunMetrics, MetricsError> {
    // Check the parameters and the shape of the recording.
    config.validate()?;
    let agent_count = recording.agent_count();
    if agent_count == 0 || recording.times_s.is_empty() {
        return Err(MetricsError::EmptyRecording);
    }
    if recording.samples.len() != recording.times_s.len() {
        return Err(MetricsError::RaggedRecording {
            sample: recording.samples.len().min(recording.times_s.len()),
            found: recording.samples.len(),
            expected: recording.times_s.len(),
        });
    }
    for (sample, row) in recording.samples.iter().enumerate() {
        if row.len() != agent_count {
            return Err(MetricsError::RaggedRecording {
                sample,
                found: row.len(),
                expected: agent_count,
            });
        }
    }
    if recording
        .times_s
        .windows(2)
        .any(|w| w[1].partial_cmp(&w[0]) != Some(std::cmp::Ordering::Greater))
    {
        return Err(MetricsError::TimesNotIncreasing);
    }

    // Resample, truncate and (optionally) rotate.
    let resampled = resample(recording, config.sample_period_s);
    let kept = config
        .max_steps
        .map_or(resampled.samples.len(), |m| m.min(resampled.samples.len()));
    if kept == 0 {
        return Err(MetricsError::EmptyRecording);
    }
    let rotate = |p: Point| match config.rotate180 {
        Some(r) => [2.0 * r.centre_m[0] - p[0], 2.0 * r.centre_m[1] - p[1]],
        None => p,
    };
    let states: Vec<Vec<AgentSample>> = resampled.samples[..kept]
        .iter()
        .map(|row| {
            row.iter()
                .map(|s| match config.rotate180 {
                    Some(_) => {
                        let [x_m, y_m] = rotate([s.x_m, s.y_m]);
                        let yaw_rad = (s.yaw_rad + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU);
                        AgentSample {
                            x_m,
                            y_m,
                            yaw_rad,
                            ..*s
                        }
                    }
                    None => *s,
                })
                .collect()
        })
        .collect();

    // Each agent's centre line and own lane, in the same frame, and whether it has an end.
    let mut centre_lines = Vec::with_capacity(agent_count);
    let mut lanes = Vec::with_capacity(agent_count);
    let mut open_paths = Vec::with_capacity(agent_count);
    for (agent, &id) in recording.ref_paths.iter().enumerate() {
        let path = ref_paths
            .iter()
            .find(|p| p.id == id)
            .ok_or(MetricsError::UnknownRefPath { agent, id })?;
        let map = |line: &[Point]| -> Vec<Point> { line.iter().map(|&p| rotate(p)).collect() };
        centre_lines.push(SegmentBoxes::new(Polyline::new(map(path.center_line))));
        lanes.push(match config.cra_l.boundaries {
            LaneBoundaries::OwnLane => Lane::new(map(path.left_boundary), map(path.right_boundary)),
            LaneBoundaries::Road => Lane::new(map(path.road_left_boundary), map(path.road_right_boundary)),
        });
        open_paths.push(!path.is_loop);
    }

    // Footprints: the real one for collisions, the one shrunk by the slack for the lane.
    let slack_m = config.cra_l.slack * vehicle.width_m;
    let shrunk = VehicleParams {
        length_m: vehicle.length_m - 2.0 * slack_m,
        width_m: vehicle.width_m - 2.0 * slack_m,
        ..*vehicle
    };
    let boxes: Vec<Vec<PlacedBox>> = states
        .iter()
        .map(|row| {
            row.iter()
                .map(|s| PlacedBox::from_pose(vehicle, s.x_m, s.y_m, s.yaw_rad))
                .collect()
        })
        .collect();

    // The samples of each agent that are measured: those it is present in (an agent placed
    // instead of a collided one under `on_collision: replace-agent` comes later, the collided
    // one leaves), and with `end_at_path_end` only up to (and with) the one that reached the
    // end of an open path.
    let measured: Vec<std::ops::Range<usize>> = (0..agent_count)
        .map(|agent| {
            let present = |row: &Vec<AgentSample>| row[agent].is_present();
            let Some(first) = states.iter().position(present) else {
                return 0..0;
            };
            let end = states.iter().rposition(present).map_or(first, |last| last + 1);
            if !(config.end_at_path_end && open_paths[agent]) {
                return first..end;
            }
            let line = centre_lines[agent].polyline();
            let reached = (first..end)
                .find(|&k| line.remaining_m([states[k][agent].x_m, states[k][agent].y_m]) <= END_REACHED_M);
            first..reached.map_or(end, |k| k + 1)
        })
        .collect();

    // Agent-agent events per pair, through the hysteresis, while both agents are measured.
    let mut pair_events = Vec::new();
    let mut agent_events = vec![Vec::new(); agent_count];
    for i in 0..agent_count {
        for j in i + 1..agent_count {
            let both = measured[i].start.max(measured[j].start)..measured[i].end.min(measured[j].end);
            if both.is_empty() {
                continue;
            }
            let distances_m: Vec<f64> = boxes[both.clone()]
                .iter()
                .map(|row| signed_distance_m(config.cra_a.geometry, &row[i], &row[j]))
                .collect();
            for sample in event_samples(&distances_m, config.cra_a.hysteresis)
                .into_iter()
                .map(|k| k + both.start)
            {
                pair_events.push(PairEvent {
                    agents: [i, j],
                    sample,
                });
                agent_events[i].push(sample);
                agent_events[j].push(sample);
            }
        }
    }
    for events in &mut agent_events {
        events.sort_unstable();
    }

    // Per agent: step distances, lane violations, centre-line distance, speed.
    let mut agents = Vec::with_capacity(agent_count);
    for (agent, events) in agent_events.into_iter().enumerate() {
        let mut distance_m = 0.0;
        let mut lane_violation_m = 0.0;
        let mut violation_samples = Vec::new();
        let (mut cd_sum_m, mut speed_sum_mps) = (0.0, 0.0);
        let measured = measured[agent].clone();
        let counted = measured.len();
        for k in measured.clone() {
            let s = &states[k][agent];
            let step_m = if k == measured.start {
                0.0
            } else {
                let p = &states[k - 1][agent];
                dist([s.x_m, s.y_m], [p.x_m, p.y_m])
            };
            distance_m += step_m;
            let footprint = footprint_corners(&shrunk, s.x_m, s.y_m, s.yaw_rad);
            if lanes[agent].is_violated_by(&footprint) {
                violation_samples.push(k);
                lane_violation_m += step_m;
            }
            cd_sum_m += centre_lines[agent].distance_m([s.x_m, s.y_m]);
            speed_sum_mps += s.velocity_mps[0].hypot(s.velocity_mps[1]);
        }
        agents.push(AgentMetrics {
            ref_path: recording.ref_paths[agent],
            distance_m,
            lane_violation_m,
            cd_m: cd_sum_m / counted as f64,
            as_mps: speed_sum_mps / counted as f64,
            event_samples: events,
            violation_samples,
        });
    }

    // SigmaRL's per-sample collision rates, over the agents present in each sample.
    let (cr_aa_pct, cr_al_pct) = if config.per_sample_collisions {
        // One set of walls per path (a run replacing cars has many agents on few paths).
        let mut walls_of_path = std::collections::BTreeMap::new();
        for &id in &recording.ref_paths {
            walls_of_path.entry(id).or_insert_with(|| {
                let path = ref_paths
                    .iter()
                    .find(|p| p.id == id)
                    .expect("every path was found above");
                let map = |line: &[Point]| -> Vec<Point> { line.iter().map(|&p| rotate(p)).collect() };
                Walls::new(&[&map(path.road_left_boundary), &map(path.road_right_boundary)])
            });
        }
        let roads: Vec<&Walls> = recording.ref_paths.iter().map(|id| &walls_of_path[id]).collect();
        per_sample_collision_rates(&states, vehicle, &roads)
    } else {
        (f64::NAN, f64::NAN)
    };

    // Totals and the normalised rates (NaN when nothing moved).
    let distance_m: f64 = agents.iter().map(|a| a.distance_m).sum();
    let lane_violation_m: f64 = agents.iter().map(|a| a.lane_violation_m).sum();
    let a2a_events = match config.cra_a.count {
        EventCount::PerAgent => 2 * pair_events.len(),
        EventCount::PerPair => pair_events.len(),
    };
    let per_distance = |value: f64, per_distance_m: f64| {
        if distance_m > 0.0 {
            value / (distance_m / per_distance_m)
        } else {
            f64::NAN
        }
    };
    // Means over the agents measured in at least one sample (every agent, unless agents came
    // and went).
    let measured_agents = || agents.iter().filter(|a| !a.cd_m.is_nan());
    let n = measured_agents().count() as f64;
    Ok(RunMetrics {
        num_samples: kept,
        num_agents: agent_count,
        cra_a: per_distance(a2a_events as f64, config.cra_a.per_distance_m),
        cra_l: per_distance(lane_violation_m, config.cra_l.per_distance_m),
        cd_m: measured_agents().map(|a| a.cd_m).sum::<f64>() / n,
        as_mps: measured_agents().map(|a| a.as_mps).sum::<f64>() / n,
        cr_aa_pct,
        cr_al_pct,
        a2a_events,
        distance_m,
        lane_violation_m,
        config: *config,
        pair_events,
        agents,
    })
}

/// The shares of samples [%] in which two present agents' outlines cross and in which a
/// present agent's outline crosses its road's boundaries (`roads[agent]`): SigmaRL's
/// `interX` flags, counted per sample as its evaluation counts them.
fn per_sample_collision_rates(
    states: &[Vec<AgentSample>],
    vehicle: &VehicleParams,
    roads: &[&Walls],
) -> (f64, f64) {
    let (mut between_agents, mut off_road) = (0usize, 0usize);
    for row in states {
        let outlines: Vec<(usize, cpmx_vehicle::Footprint)> = row
            .iter()
            .enumerate()
            .filter(|(_, s)| s.is_present())
            .map(|(agent, s)| (agent, footprint_corners(vehicle, s.x_m, s.y_m, s.yaw_rad)))
            .collect();
        let crossing = outlines
            .iter()
            .enumerate()
            .any(|(k, (_, a))| outlines[k + 1..].iter().any(|(_, b)| rectangles_cross(a, b)));
        between_agents += usize::from(crossing);
        off_road += usize::from(outlines.iter().any(|(agent, o)| roads[*agent].crossed_by(o)));
    }
    let share = |count: usize| 100.0 * count as f64 / states.len() as f64;
    (share(between_agents), share(off_road))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{CollisionGeometry, Hysteresis};
    use proptest::prelude::*;

    /// A straight 0.15 m wide lane along +x from 0 to 20 m.
    struct Straight {
        centre: Vec<Point>,
        left: Vec<Point>,
        right: Vec<Point>,
    }

    impl Straight {
        fn new() -> Self {
            let xs = [0.0, 10.0, 20.0];
            Self {
                centre: xs.iter().map(|&x| [x, 0.0]).collect(),
                left: xs.iter().map(|&x| [x, 0.075]).collect(),
                right: xs.iter().map(|&x| [x, -0.075]).collect(),
            }
        }

        fn geometry(&self) -> [PathGeometry<'_>; 1] {
            [PathGeometry {
                id: 0,
                center_line: &self.centre,
                left_boundary: &self.left,
                right_boundary: &self.right,
                road_left_boundary: &self.left,
                road_right_boundary: &self.right,
                is_loop: false,
            }]
        }
    }

    fn sample(x_m: f64, y_m: f64, yaw_rad: f64) -> AgentSample {
        AgentSample {
            x_m,
            y_m,
            yaw_rad,
            velocity_mps: [1.0, 0.0],
            steering_rad: f64::NAN,
        }
    }

    /// Agents on path 0 whose poses are `rows[k][agent]`, every 0.1 s.
    fn recording(rows: Vec<Vec<AgentSample>>) -> Recording {
        Recording {
            notes: Vec::new(),
            latency_s: Vec::new(),
            statistics: Default::default(),
            times_s: (0..rows.len()).map(|k| k as f64 * 0.1).collect(),
            ref_paths: vec![0; rows.first().map_or(0, Vec::len)],
            samples: rows,
        }
    }

    #[test]
    fn an_agent_that_comes_later_is_measured_over_its_own_samples_only() {
        let lane = Straight::new();
        let gone = AgentSample::ABSENT;
        // Agent 0 drives throughout; agent 1 collides with it and leaves after sample 4; agent 2,
        // placed instead far behind, drives from sample 5 on, 0.04 m off the centre.
        let rows: Vec<Vec<AgentSample>> = (0..10)
            .map(|k| {
                let x = 1.0 + 0.1 * k as f64;
                let first = sample(x, 0.0, 0.0);
                let collided = if k < 5 { sample(x + 0.05, 0.01, 0.0) } else { gone };
                let later = if k >= 5 {
                    sample(10.0 + 0.2 * k as f64, 0.04, 0.0)
                } else {
                    gone
                };
                vec![first, collided, later]
            })
            .collect();
        let mut r = recording(rows.clone());
        let config = MetricsConfig::sigmarl_script(100.0);
        let m = evaluate(&r, &lane.geometry(), &VehicleParams::MU_CAR, &config).unwrap();
        // One event between agents 0 and 1, found from their first sample.
        assert_eq!(m.pair_events.len(), 1, "{:?}", m.pair_events);
        assert_eq!(m.pair_events[0].agents, [0, 1]);
        // Agent 2's distance has no jump from nowhere: 4 steps of 0.2 m.
        assert!(
            (m.agents[2].distance_m - 0.8).abs() < 1e-12,
            "{}",
            m.agents[2].distance_m
        );
        assert!((m.agents[1].distance_m - 0.4).abs() < 1e-12);
        // The means are over the samples present: agent 2's CD is its own 0.04 m.
        assert!((m.agents[2].cd_m - 0.04).abs() < 1e-12);
        assert!((m.cd_m - (0.01 + 0.04) / 3.0).abs() < 1e-12);
        // The same agent alone, with its own five samples, measures the same.
        r.samples = rows[5..].iter().map(|row| vec![row[2]]).collect();
        r.times_s.truncate(5);
        r.ref_paths.truncate(1);
        let alone = evaluate(&r, &lane.geometry(), &VehicleParams::MU_CAR, &config).unwrap();
        assert_eq!(alone.agents[0].distance_m, m.agents[2].distance_m);
        assert_eq!(alone.agents[0].cd_m, m.agents[2].cd_m);
        assert_eq!(alone.agents[0].as_mps, m.agents[2].as_mps);
    }

    #[test]
    fn per_sample_collision_rates_count_samples_with_any_crossing() {
        let lane = Straight::new();
        let gone = AgentSample::ABSENT;
        // Sample 0: apart; 1: agents 0 and 1 cross (and 2 is elsewhere); 2: agent 0 across the
        // road's left boundary; 3: agent 1 has left, agent 2 lies on agent 0 exactly (identical
        // outlines do not cross: SigmaRL's test).
        let rows = vec![
            vec![
                sample(1.0, 0.0, 0.0),
                sample(3.0, 0.0, 0.0),
                sample(6.0, 0.0, 0.0),
            ],
            vec![
                sample(1.1, 0.0, 0.0),
                sample(1.15, 0.01, 0.0),
                sample(6.1, 0.0, 0.0),
            ],
            vec![sample(1.2, 0.06, 0.0), gone, sample(6.2, 0.0, 0.0)],
            vec![sample(1.3, 0.0, 0.0), gone, sample(1.3, 0.0, 0.0)],
        ];
        let r = recording(rows);
        let mut config = MetricsConfig::default();
        let without = evaluate(&r, &lane.geometry(), &VehicleParams::MU_CAR, &config).unwrap();
        assert!(without.cr_aa_pct.is_nan() && without.cr_al_pct.is_nan());
        config.per_sample_collisions = true;
        let m = evaluate(&r, &lane.geometry(), &VehicleParams::MU_CAR, &config).unwrap();
        assert_eq!((m.cr_aa_pct, m.cr_al_pct), (25.0, 25.0));
    }

    #[test]
    fn a_lateral_offset_within_the_slack_is_no_violation() {
        let lane = Straight::new();
        // 2.15 cm of room per side; an offset of 3 cm leaves the lane by 0.85 cm < 0.1 W.
        let r = recording(
            (0..10)
                .map(|k| vec![sample(1.0 + 0.1 * k as f64, 0.03, 0.0)])
                .collect(),
        );
        let mut config = MetricsConfig::sigmarl_script(100.0);
        let strict = evaluate(&r, &lane.geometry(), &VehicleParams::MU_CAR, &config).unwrap();
        assert_eq!(strict.agents[0].violation_samples.len(), 10);
        assert!((strict.lane_violation_m - 0.9).abs() < 1e-12);
        assert!((strict.cra_l - 100.0).abs() < 1e-9);
        config.cra_l.slack = 0.10;
        let slack = evaluate(&r, &lane.geometry(), &VehicleParams::MU_CAR, &config).unwrap();
        assert!(slack.agents[0].violation_samples.is_empty());
        assert!((slack.cd_m - 0.03).abs() < 1e-12);
        assert!((slack.as_mps - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_car_in_the_next_lane_of_the_road_leaves_its_own_lane_only() {
        let lane = Straight::new();
        // A road of two lanes: the own lane and one 0.15 m to its left.
        let road_left: Vec<Point> = lane.left.iter().map(|p| [p[0], p[1] + 0.15]).collect();
        let geometry = [PathGeometry {
            road_left_boundary: &road_left,
            ..lane.geometry()[0]
        }];
        let r = recording(
            (0..10)
                .map(|k| vec![sample(1.0 + 0.1 * k as f64, 0.15, 0.0)])
                .collect(),
        );
        let mut config = MetricsConfig::sigmarl_script(100.0);
        let own = evaluate(&r, &geometry, &VehicleParams::MU_CAR, &config).unwrap();
        assert_eq!(own.agents[0].violation_samples.len(), 10);
        config.cra_l.boundaries = LaneBoundaries::Road;
        let road = evaluate(&r, &geometry, &VehicleParams::MU_CAR, &config).unwrap();
        assert!(
            road.agents[0].violation_samples.is_empty() && road.cra_l == 0.0,
            "{road:?}"
        );
        // Half a car further and it touches the road's edge too.
        let r = recording(
            (0..10)
                .map(|k| vec![sample(1.0 + 0.1 * k as f64, 0.2, 0.0)])
                .collect(),
        );
        let road = evaluate(&r, &geometry, &VehicleParams::MU_CAR, &config).unwrap();
        assert_eq!(road.agents[0].violation_samples.len(), 10);
    }

    #[test]
    fn nothing_moving_gives_nan_rates() {
        let lane = Straight::new();
        let r = recording(vec![vec![sample(1.0, 0.0, 0.0)]; 4]);
        let m = evaluate(
            &r,
            &lane.geometry(),
            &VehicleParams::MU_CAR,
            &MetricsConfig::default(),
        )
        .unwrap();
        assert_eq!(m.distance_m, 0.0);
        assert!(m.cra_a.is_nan() && m.cra_l.is_nan());
    }

    #[test]
    fn bad_inputs_are_errors() {
        let lane = Straight::new();
        let vehicle = VehicleParams::MU_CAR;
        let config = MetricsConfig::default();
        let mut r = recording(vec![vec![sample(1.0, 0.0, 0.0)]; 4]);
        r.ref_paths = vec![7];
        assert_eq!(
            evaluate(&r, &lane.geometry(), &vehicle, &config),
            Err(MetricsError::UnknownRefPath { agent: 0, id: 7 })
        );
        let mut ragged = recording(vec![vec![sample(1.0, 0.0, 0.0)]; 4]);
        ragged.samples[2].clear();
        assert!(matches!(
            evaluate(&ragged, &lane.geometry(), &vehicle, &config),
            Err(MetricsError::RaggedRecording { sample: 2, .. })
        ));
        let empty = recording(vec![]);
        assert_eq!(
            evaluate(&empty, &lane.geometry(), &vehicle, &config),
            Err(MetricsError::EmptyRecording)
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig { failure_persistence: None, ..ProptestConfig::default() })]
        #[test]
        fn per_pair_counts_are_half_the_per_agent_counts(
            rows in proptest::collection::vec(
                proptest::collection::vec((0.0..0.6f64, -0.1..0.1f64, -0.5..0.5f64), 3),
                1..40,
            ),
            geometry in prop_oneof![Just(CollisionGeometry::Mtv), Just(CollisionGeometry::SigmarlMtv)],
        ) {
            let lane = Straight::new();
            let r = recording(
                rows.into_iter()
                    .map(|row| row.into_iter().map(|(x, y, yaw)| sample(1.0 + x, y, yaw)).collect())
                    .collect(),
            );
            let mut config = MetricsConfig::default();
            config.cra_a.geometry = geometry;
            let per_agent = evaluate(&r, &lane.geometry(), &VehicleParams::MU_CAR, &config).unwrap();
            config.cra_a.count = EventCount::PerPair;
            let per_pair = evaluate(&r, &lane.geometry(), &VehicleParams::MU_CAR, &config).unwrap();
            prop_assert_eq!(per_agent.a2a_events, 2 * per_pair.a2a_events);
            prop_assert_eq!(per_pair.a2a_events, per_pair.pair_events.len());
            let listed: usize = per_agent.agents.iter().map(|a| a.event_samples.len()).sum();
            prop_assert_eq!(listed, per_agent.a2a_events);
        }
    }

    #[test]
    fn waiting_at_the_end_of_the_path_can_be_left_out() {
        // Drives 1 m/s to 0.1 m before the end of the 20 m lane, then waits for 10 samples.
        let mut rows: Vec<Vec<AgentSample>> = (0..=10)
            .map(|k| vec![sample(18.9 + k as f64 * 0.1, 0.0, 0.0)])
            .collect();
        for _ in 0..10 {
            let mut waiting = sample(19.9, 0.0, 0.0);
            waiting.velocity_mps = [0.0, 0.0];
            rows.push(vec![waiting]);
        }
        let lane = Straight::new();
        let recording = recording(rows);
        let mut config = MetricsConfig::default();
        let waiting = evaluate(&recording, &lane.geometry(), &VehicleParams::MU_CAR, &config).unwrap();
        assert!((waiting.as_mps - 11.0 / 21.0).abs() < 1e-12, "{}", waiting.as_mps);
        config.end_at_path_end = true;
        let ended = evaluate(&recording, &lane.geometry(), &VehicleParams::MU_CAR, &config).unwrap();
        // Sample 9 (x = 19.8 m, 0.2 m before the end up to round-off) or 10 is the first within
        // 0.2 m of the end: the waiting samples are left out either way.
        assert!((ended.as_mps - 1.0).abs() < 1e-12, "{}", ended.as_mps);
        assert!(
            (0.9 - 1e-9..=1.0 + 1e-9).contains(&ended.distance_m),
            "{}",
            ended.distance_m
        );
    }

    #[test]
    fn an_agent_that_left_the_measurement_collides_with_nobody() {
        // Agent 0 reaches the end at sample 10 and waits there; agent 1, 1 m behind on the same
        // path, drives into it at 1 m/s from sample 10 on: the two boxes overlap from about
        // sample 17 until both are measured no longer.
        let rows: Vec<Vec<AgentSample>> = (0..=30)
            .map(|k| {
                let first = if k <= 10 { 18.9 + k as f64 * 0.1 } else { 19.9 };
                let second = (17.9 + k as f64 * 0.1).min(19.8);
                vec![sample(first, 0.0, 0.0), sample(second, 0.0, 0.0)]
            })
            .collect();
        let lane = Straight::new();
        let recording = recording(rows);
        let mut config = MetricsConfig::default();
        config.cra_a.hysteresis = Hysteresis { enter: 1, exit: 1 };
        let waiting = evaluate(&recording, &lane.geometry(), &VehicleParams::MU_CAR, &config).unwrap();
        assert_eq!(waiting.pair_events.len(), 1, "waiting at the end, it is hit");
        config.end_at_path_end = true;
        let ended = evaluate(&recording, &lane.geometry(), &VehicleParams::MU_CAR, &config).unwrap();
        assert!(ended.pair_events.is_empty(), "{:?}", ended.pair_events);
    }
}
