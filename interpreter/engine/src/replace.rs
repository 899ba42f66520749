//! `on_collision: replace-agent`: SigmaRL's testing mode in the sim engine. A car whose
//! outline crosses another car's, its road's boundaries or its path's entry or exit line
//! leaves the run, and a new agent is placed in its slot as SigmaRL's `reset_world_at` places
//! it: a reference path of the map drawn uniformly, a centre-line point drawn uniformly in
//! `[3, n - 3)`, redrawn until its centre is at least 1.2 of the car's diagonal from every
//! other car, heading along the segment that leaves the point, a speed drawn in `[0, max
//! speed)`.
//!
//! This module owns the tests and the draws; the sim loop owns when they happen (after the
//! policy acted on the collision's state, as SigmaRL's `done()` runs after the observation)
//! and the recording of the new agent. The crossing tests and the placement are cpmx-env's,
//! the training environment's, so that both follow one rule.

use std::sync::Arc;

use cpmx_env::{
    Placement, StartRule, TrainingPath, draw_placement, rectangle_crosses_segment, rectangles_cross,
};
use cpmx_policy::PreparedPath;
use cpmx_vehicle::{BicycleState, VehicleParams, footprint_corners};
use cpmx_world::Map;
use rand::SeedableRng;
use rand_chacha::ChaCha20Rng;

/// SigmaRL's smallest centre distance of a placed car to the others, in car diagonals.
const GAP_IN_DIAGONALS: f64 = 1.2;

/// Draws before a placement gives up on the gap (SigmaRL redraws forever).
const MAX_ATTEMPTS: u32 = 10_000;

/// Every path of a map prepared for SigmaRL's testing placements, with their ids.
#[derive(Debug, Clone)]
pub(crate) struct TestingPaths {
    ids: Vec<usize>,
    paths: Vec<TrainingPath>,
}

impl TestingPaths {
    /// The map's reference paths in id order.
    pub(crate) fn of_map(map: &Map) -> Result<Self, String> {
        let ids = map.valid_path_ids();
        if ids.is_empty() {
            return Err("the map has no reference paths".into());
        }
        let paths = ids
            .iter()
            .map(|&id| {
                let path = map.reference_path(id).expect("a listed id");
                TrainingPath::for_testing(path).map_err(|e| e.to_string())
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self { ids, paths })
    }

    /// Draws one car's placement clear of `avoid` by `min_gap_m`; `None` when no draw of
    /// [`MAX_ATTEMPTS`] was clear.
    pub(crate) fn draw(
        &self,
        rng: &mut ChaCha20Rng,
        min_gap_m: f64,
        max_speed_mps: f64,
        avoid: &[[f64; 2]],
    ) -> Option<(usize, Placement)> {
        let rule = StartRule {
            first_index: 3,
            speed_mps: (0.0, max_speed_mps),
            min_gap_m,
            max_attempts: MAX_ATTEMPTS,
        };
        let (placement, relaxed) = draw_placement(rng, &self.paths, &rule, avoid);
        (!relaxed).then(|| (self.ids[placement.path], placement))
    }

    fn index_of(&self, id: usize) -> Option<usize> {
        self.ids.binary_search(&id).ok()
    }
}

/// Why a car leaves the run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Leave {
    /// Its outline crosses another car's.
    Collision,
    /// Its outline crosses its road's boundaries.
    OffRoad,
    /// Its outline crosses its path's entry or exit line (reaching the end of its path).
    PathEnd,
}

impl Leave {
    /// The name of the run's count of replacements for this reason.
    pub(crate) fn statistic(self) -> &'static str {
        match self {
            Leave::Collision => "replaced.collision",
            Leave::OffRoad => "replaced.off_road",
            Leave::PathEnd => "replaced.path_end",
        }
    }
}

/// The replacements of one run: the map's paths, the run's `replace-agent` stream and the
/// path every slot follows now.
#[derive(Debug)]
pub(crate) struct Replacements {
    paths: TestingPaths,
    rng: ChaCha20Rng,
    vehicle: VehicleParams,
    /// Index into `paths` of each slot's current path.
    slot_paths: Vec<usize>,
}

impl Replacements {
    /// For a run on `map` whose slots start on `ref_paths`, drawing from `seed`.
    pub(crate) fn new(
        map: &Map,
        ref_paths: &[usize],
        vehicle: VehicleParams,
        seed: [u8; 32],
    ) -> Result<Self, String> {
        let paths = TestingPaths::of_map(map)?;
        let slot_paths = ref_paths
            .iter()
            .map(|&id| {
                paths
                    .index_of(id)
                    .ok_or_else(|| format!("the map has no reference path {id}"))
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            paths,
            rng: ChaCha20Rng::from_seed(seed),
            vehicle,
            slot_paths,
        })
    }

    /// Which slots' cars leave and why: their outline crosses another car's, their road's
    /// boundaries or their path's entry or exit line (SigmaRL's `interX` tests; the first
    /// reason that holds, in that order).
    pub(crate) fn leaving(&self, states: &[BicycleState]) -> Vec<Option<Leave>> {
        let outlines: Vec<_> = states
            .iter()
            .map(|s| footprint_corners(&self.vehicle, s.x_m, s.y_m, s.yaw_rad))
            .collect();
        let mut leaving = vec![None; states.len()];
        for i in 0..outlines.len() {
            for j in i + 1..outlines.len() {
                if rectangles_cross(&outlines[i], &outlines[j]) {
                    leaving[i] = Some(Leave::Collision);
                    leaving[j] = Some(Leave::Collision);
                }
            }
        }
        for (slot, outline) in outlines.iter().enumerate() {
            if leaving[slot].is_some() {
                continue;
            }
            let path = &self.paths.paths[self.slot_paths[slot]];
            if path.boundaries.crossed_by(outline) {
                leaving[slot] = Some(Leave::OffRoad);
            } else if [path.entry, path.exit]
                .iter()
                .flatten()
                .any(|&line| rectangle_crosses_segment(outline, line))
            {
                leaving[slot] = Some(Leave::PathEnd);
            }
        }
        leaving
    }

    /// Places a new car in `slot`, clear of the other cars of `states`: its reference path id,
    /// prepared path and state. `None` when no draw was clear.
    pub(crate) fn place(
        &mut self,
        slot: usize,
        states: &[BicycleState],
    ) -> Option<(usize, Arc<PreparedPath>, BicycleState)> {
        let avoid: Vec<[f64; 2]> = states
            .iter()
            .enumerate()
            .filter(|(other, _)| *other != slot)
            .map(|(_, s)| [s.x_m, s.y_m])
            .collect();
        let min_gap_m = GAP_IN_DIAGONALS * self.vehicle.length_m.hypot(self.vehicle.width_m);
        let (id, placement) =
            self.paths
                .draw(&mut self.rng, min_gap_m, self.vehicle.max_speed_mps, &avoid)?;
        self.slot_paths[slot] = placement.path;
        let prepared = Arc::clone(&self.paths.paths[placement.path].prepared);
        Some((id, prepared, placement.state))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map() -> Map {
        Map::builtin("intersection").unwrap()
    }

    fn car(x_m: f64, y_m: f64, yaw_rad: f64) -> BicycleState {
        BicycleState {
            x_m,
            y_m,
            yaw_rad,
            ..BicycleState::default()
        }
    }

    /// A car on the centre line of `path` at `arc_m`, heading along it.
    fn on_path(map: &Map, path: usize, arc_m: f64) -> BicycleState {
        let (x, y, yaw) = map.pose_at(path, arc_m).unwrap();
        car(x, y, yaw)
    }

    #[test]
    fn cars_leave_when_they_cross_each_other_their_road_or_its_end() {
        let map = map();
        let ids = map.valid_path_ids();
        // Two paths that do not start in the same lane.
        let a = ids[0];
        let start_a = on_path(&map, a, 0.5);
        let b = *ids
            .iter()
            .find(|&&b| {
                let s = on_path(&map, b, 0.5);
                (s.x_m - start_a.x_m).hypot(s.y_m - start_a.y_m) > 1.0
            })
            .unwrap();
        let replacements = Replacements::new(&map, &[a, a, b], VehicleParams::MU_CAR, [0; 32]).unwrap();
        // Far apart on their lanes: nobody leaves.
        let length_a = map.reference_path(a).unwrap().center_line.length_m();
        let apart = [
            on_path(&map, a, 0.5),
            on_path(&map, a, 1.5),
            on_path(&map, b, 0.5),
        ];
        assert!(
            length_a >= 2.0,
            "the built-in map's paths are shorter than the test assumes"
        );
        assert_eq!(replacements.leaving(&apart), [None, None, None]);
        // Two cars overlapping with crossing outlines both leave.
        let mut overlap = apart;
        overlap[1] = BicycleState {
            x_m: apart[0].x_m + 0.05,
            y_m: apart[0].y_m + 0.02,
            ..apart[0]
        };
        let collided = Some(Leave::Collision);
        assert_eq!(replacements.leaving(&overlap), [collided, collided, None]);
        // Turned across its lane, a car crosses its road's boundary.
        let mut across = apart;
        across[2].yaw_rad += std::f64::consts::FRAC_PI_2;
        assert_eq!(
            replacements.leaving(&across),
            [None, None, Some(Leave::OffRoad)],
            "a car sideways in its lane"
        );
        // At the end of its path a car touches the exit line.
        let mut at_end = apart;
        at_end[0] = on_path(&map, a, length_a);
        assert_eq!(replacements.leaving(&at_end), [Some(Leave::PathEnd), None, None]);
    }

    #[test]
    fn new_cars_are_placed_clear_of_the_others_at_an_inner_centre_line_point() {
        let map = map();
        let ids = map.valid_path_ids();
        let vehicle = VehicleParams::MU_CAR;
        let gap_m = 1.2 * vehicle.length_m.hypot(vehicle.width_m);
        let mut replacements = Replacements::new(&map, &[ids[0], ids[1]], vehicle, [3; 32]).unwrap();
        let mut again = Replacements::new(&map, &[ids[0], ids[1]], vehicle, [3; 32]).unwrap();
        let mut states = vec![on_path(&map, ids[0], 0.5), on_path(&map, ids[1], 0.5)];
        for round in 0..200 {
            let slot = round % 2;
            let (id, prepared, state) = replacements.place(slot, &states).unwrap();
            let (id2, _, state2) = again.place(slot, &states).unwrap();
            assert_eq!((id, state), (id2, state2), "the same stream places the same car");
            let other = &states[1 - slot];
            assert!((state.x_m - other.x_m).hypot(state.y_m - other.y_m) >= gap_m - 1e-6);
            let points = &prepared.center_points;
            let index = points
                .iter()
                .position(|p| (p[0] - state.x_m).abs() < 1e-6 && (p[1] - state.y_m).abs() < 1e-6)
                .expect("placed on a centre-line point");
            assert!(
                (3..points.len() - 3).contains(&index),
                "index {index} of {}",
                points.len()
            );
            assert!((0.0..vehicle.max_speed_mps).contains(&state.speed_mps));
            assert_eq!(
                replacements.slot_paths[slot],
                replacements.paths.index_of(id).unwrap()
            );
            states[slot] = state;
        }
    }
}
