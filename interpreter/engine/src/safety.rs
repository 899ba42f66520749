//! A fidelity's `safety:` layer in the sim engine: each agent's command goes through
//! `cpmx-safety`'s CBF filter against its lane's boundaries before it moves the car, and what
//! the filter did is counted for the run's statistics and notes (the run folder's
//! `metrics.json`; `per_run.csv`'s `safety.*` columns).

use std::collections::BTreeMap;

use cpmx_safety::{Boundary, CbfParameters, CbfState, Fallback, filter};
use cpmx_spec::model::SafetyLayer;
use cpmx_vehicle::{BicycleState, Command, VehicleParams};
use cpmx_world::{Map, Polyline};

/// The filter of one run: its parameters, each path's boundaries, and its counts.
pub(crate) struct SafetyFilter {
    parameters: CbfParameters,
    /// Each agent's lane: its path's left and right road boundaries, as `f32` polylines.
    lanes: Vec<(Boundary, Boundary)>,
    counts: Counts,
}

/// What the filter did over a run.
#[derive(Debug, Default)]
struct Counts {
    agent_steps: u64,
    changed: u64,
    infeasible: u64,
    not_finite: u64,
    unsolved: u64,
    largest_change: [f64; 2],
}

impl SafetyFilter {
    /// The filter of `layer` for agents on `ref_paths` of `map`, each step `dt_s` long; `None`
    /// when a path's boundaries have fewer than two points.
    pub(crate) fn new(
        layer: &SafetyLayer,
        vehicle: &VehicleParams,
        dt_s: f64,
        map: &Map,
        ref_paths: &[usize],
    ) -> Option<SafetyFilter> {
        let cbf = &layer.cbf;
        let parameters = CbfParameters {
            circles: cbf.circles as usize,
            length_m: vehicle.length_m,
            rear_axle_m: vehicle.rear_axle_m,
            wheelbase_m: vehicle.wheelbase_m,
            circle_radius_m: cbf.circle_radius_m,
            difference_step_m: cbf.difference_step_m,
            gain: cbf.gain,
            step_s: dt_s,
            weights: [cbf.weights.acceleration, cbf.weights.steering_rate],
            acceleration_limit_mps2: cbf.acceleration_limit_mps2,
            steering_rate_limit_radps: cbf.steering_rate_limit_radps,
            speed_range_mps: cbf.speed_range_mps.map(|v| v as f32),
            max_steering_rad: cbf.max_steering_deg.to_radians() as f32,
        };
        let boundary =
            |line: &Polyline| Boundary::new(line.points.iter().map(|p| [p[0] as f32, p[1] as f32]).collect());
        let mut by_path: BTreeMap<usize, (Boundary, Boundary)> = BTreeMap::new();
        let mut lanes = Vec::with_capacity(ref_paths.len());
        for &id in ref_paths {
            let lane = match by_path.entry(id) {
                std::collections::btree_map::Entry::Occupied(known) => known.get().clone(),
                std::collections::btree_map::Entry::Vacant(slot) => {
                    let path = map.reference_path(id)?;
                    let lane = (
                        boundary(&path.left_boundary_shared)?,
                        boundary(&path.right_boundary_shared)?,
                    );
                    slot.insert(lane).clone()
                }
            };
            lanes.push(lane);
        }
        Some(SafetyFilter {
            parameters,
            lanes,
            counts: Counts::default(),
        })
    }

    /// Filters agent `agent`'s `command` for its `state` (moving at `velocity_mps`).
    pub(crate) fn apply(
        &mut self,
        agent: usize,
        state: &BicycleState,
        velocity_mps: [f64; 2],
        command: &mut Command,
    ) {
        let (left, right) = &self.lanes[agent];
        // SigmaRL's filter sees the speed as the velocity's norm.
        let cbf_state = CbfState {
            x_m: state.x_m as f32,
            y_m: state.y_m as f32,
            yaw_rad: state.yaw_rad as f32,
            speed_mps: velocity_mps[0].hypot(velocity_mps[1]) as f32,
            steering_rad: state.steering_rad as f32,
        };
        let nominal = [command.speed_mps as f32, command.steering_rad as f32];
        let outcome = filter(&self.parameters, cbf_state, nominal, left, right);
        let c = &mut self.counts;
        c.agent_steps += 1;
        match outcome.fallback {
            Some(Fallback::Infeasible) => c.infeasible += 1,
            Some(Fallback::NotFinite) => c.not_finite += 1,
            Some(Fallback::Unsolved) => c.unsolved += 1,
            None => {}
        }
        if outcome.action != nominal {
            c.changed += 1;
            for ((largest, action), nominal) in c.largest_change.iter_mut().zip(outcome.action).zip(nominal) {
                *largest = largest.max(f64::from((action - nominal).abs()));
            }
        }
        *command = Command {
            speed_mps: f64::from(outcome.action[0]),
            steering_rad: f64::from(outcome.action[1]),
        };
    }

    /// What the filter did, by name, for the run's `statistics` (`per_run.csv`'s columns).
    pub(crate) fn statistics(&self) -> BTreeMap<String, f64> {
        let c = &self.counts;
        [
            ("safety.agent_steps", c.agent_steps as f64),
            ("safety.changed", c.changed as f64),
            ("safety.infeasible", c.infeasible as f64),
            ("safety.not_finite", c.not_finite as f64),
            ("safety.unsolved", c.unsolved as f64),
            ("safety.largest_speed_change_mps", c.largest_change[0]),
            ("safety.largest_steering_change_rad", c.largest_change[1]),
        ]
        .into_iter()
        .map(|(name, value)| (name.to_owned(), value))
        .collect()
    }

    /// What the filter did, in a line.
    pub(crate) fn note(&self) -> String {
        let c = &self.counts;
        format!(
            "safety filter (CBF): {} of {} agent-steps changed (at most {:.3} m/s and {:.3} rad), \
             clamped nominal action kept where the QP had no solution {} times, a row was not finite {} \
             times, the solver stopped {} times",
            c.changed,
            c.agent_steps,
            c.largest_change[0],
            c.largest_change[1],
            c.infeasible,
            c.not_finite,
            c.unsolved
        )
    }
}
