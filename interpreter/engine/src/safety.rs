//! A fidelity's `safety:` layer in the sim engine: each step's commands go through
//! `cpmx-safety`'s CBF filter (each agent against its lane's boundaries and, with
//! `agents:`, against the agents near it) before they move the cars, and what the filter did
//! is counted for the run's statistics and notes (the run folder's `metrics.json`;
//! `per_run.csv`'s `safety.*` columns).

use std::collections::BTreeMap;

use cpmx_safety::{AgentRows, Boundary, CbfParameters, CbfState, Fallback, Vehicle, filter_step};
use cpmx_spec::model::SafetyLayer;
use cpmx_vehicle::{BicycleState, Command, VehicleParams};
use cpmx_world::{Map, Polyline};

use crate::engine::RunError;
use crate::experiment::Experiment;

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
    relaxed: u64,
    kept_apart: u64,
    largest_change: [f64; 2],
}

impl SafetyFilter {
    /// The filter of a run whose fidelity has the safety `layer`, if any, for agents on
    /// `ref_paths` of `experiment`'s map.
    pub(crate) fn of_run(
        layer: Option<&SafetyLayer>,
        experiment: &Experiment,
        ref_paths: &[usize],
    ) -> Result<Option<SafetyFilter>, RunError> {
        layer
            .map(|layer| {
                SafetyFilter::new(
                    layer,
                    &experiment.vehicle,
                    &experiment.footprint,
                    experiment.spec.timing.dt,
                    &experiment.map,
                    ref_paths,
                )
                .ok_or(RunError::SafetyLanes)
            })
            .transpose()
    }

    /// The filter of `layer` for agents on `ref_paths` of `map`, each step `dt_s` long, the
    /// agents kept apart (where the layer asks) by circles that cover `footprint`; `None` when
    /// a path's boundaries have fewer than two points.
    fn new(
        layer: &SafetyLayer,
        vehicle: &VehicleParams,
        footprint: &VehicleParams,
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
            agents: cbf.agents.as_ref().map(|agents| AgentRows {
                length_m: footprint.length_m,
                width_m: footprint.width_m,
                range_m: agents.range_m,
            }),
            slack_weight: cbf.slack_weight,
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

    /// Filters every agent's command for its `state` (moving at `velocities`).
    pub(crate) fn apply(
        &mut self,
        states: &[BicycleState],
        velocities: &[[f64; 2]],
        commands: &mut [Command],
    ) {
        let vehicles: Vec<Vehicle<'_>> = states
            .iter()
            .zip(velocities)
            .zip(commands.iter())
            .zip(&self.lanes)
            .map(|(((state, velocity), command), (left, right))| Vehicle {
                // SigmaRL's filter sees the speed as the velocity's norm.
                state: CbfState {
                    x_m: state.x_m as f32,
                    y_m: state.y_m as f32,
                    yaw_rad: state.yaw_rad as f32,
                    speed_mps: velocity[0].hypot(velocity[1]) as f32,
                    steering_rad: state.steering_rad as f32,
                },
                nominal: [command.speed_mps as f32, command.steering_rad as f32],
                left,
                right,
            })
            .collect();
        let step = filter_step(&self.parameters, &vehicles);
        let c = &mut self.counts;
        let mut kept_apart = vec![false; commands.len()];
        for &k in &step.active_pairs {
            for v in step.pair_rows[k].vehicles {
                kept_apart[v] = true;
            }
        }
        c.kept_apart += kept_apart.iter().filter(|&&k| k).count() as u64;
        for ((outcome, vehicle), command) in step.vehicles.iter().zip(&vehicles).zip(commands) {
            c.agent_steps += 1;
            match outcome.fallback {
                Some(Fallback::Infeasible) => c.infeasible += 1,
                Some(Fallback::NotFinite) => c.not_finite += 1,
                Some(Fallback::Unsolved) => c.unsolved += 1,
                None => {}
            }
            c.relaxed += u64::from(outcome.relaxed);
            if outcome.action != vehicle.nominal {
                c.changed += 1;
                for ((largest, action), nominal) in c
                    .largest_change
                    .iter_mut()
                    .zip(outcome.action)
                    .zip(vehicle.nominal)
                {
                    *largest = largest.max(f64::from((action - nominal).abs()));
                }
            }
            *command = Command {
                speed_mps: f64::from(outcome.action[0]),
                steering_rad: f64::from(outcome.action[1]),
            };
        }
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
            ("safety.relaxed", c.relaxed as f64),
            ("safety.kept_apart", c.kept_apart as f64),
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
             {} kept from another agent, the rows relaxed where the QP had no solution {} times, \
             clamped nominal action kept where it had none {} times, a row was not finite {} \
             times, the solver stopped {} times",
            c.changed,
            c.agent_steps,
            c.largest_change[0],
            c.largest_change[1],
            c.kept_apart,
            c.relaxed,
            c.infeasible,
            c.not_finite,
            c.unsolved
        )
    }
}

/// In a planning fidelity the filter changes each step the planner rolls out.
impl cpmx_planner::CommandFilter for SafetyFilter {
    fn filter(&mut self, states: &[BicycleState], velocities_mps: &[[f64; 2]], commands: &mut [Command]) {
        self.apply(states, velocities_mps, commands);
    }
}
