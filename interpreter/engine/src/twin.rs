//! The twin engine (`control: trajectory`): the CPM Lab's control stack. Every policy period
//! the planner rolls the policy out over Hc/Hp from the states the vehicles *report* and hands
//! each vehicle a timed trajectory; each vehicle ([`VehicleStack`]) then runs its 50 Hz loop
//! until the next period. With `dynamics: kinematic` this is sim-mpc, with the grey-box model,
//! the IPS and the actuation delay it is the digital twin. A `safety:` filter changes the
//! policy's commands of every step the planner rolls out, on the states it predicts from the
//! listed ones. The recording holds the true state
//! at every policy period, as the sim engine's does.
//!
//! The planner starts from the states the lab's middleware would list at the tick (position
//! and yaw as estimated, σ = σ_max · servo command, speed through the slip angle; at least
//! 60 ms old, see `stack.rs`), and each plan is anchored at its state's time: point k of an
//! agent's trajectory is at `create + k·dt` ([`anchor_ns`], `docs/lab.md`), so the reference
//! does not fall behind the car by speed × state age. The vehicles' clock is integer
//! nanoseconds from [`RUN_START_NS`] (tick `k` at `RUN_START_NS + k·dt`, control periods
//! 20,000,000 ns apart), as the lab's stamps are, so every time the follower compares is a
//! whole-nanosecond sum.

use cpmx_planner::{Planner, PlannerParams, SteeringAfterHc};
use cpmx_recording::Recording;
use cpmx_spec::model::{OnCollision, Planner as PlannerSpec};
use cpmx_vehicle::{BicycleState, VehicleParams};

use crate::engine::{Engine, RunError, RunInputs};
use cpmx_stack::{
    CONTROL_PERIOD_NS, CONTROL_PERIOD_S, DecisionSchedule, RUN_START_NS, StampedState, VehicleStack,
    anchor_ns, max_state_age_ns, step_together, trajectory_points,
};

/// The lab's control stack around simulated vehicles.
#[derive(Debug, Clone, Copy, Default)]
pub struct TwinEngine;

impl Engine for TwinEngine {
    fn run(&self, inputs: &RunInputs<'_>) -> Result<Recording, RunError> {
        let experiment = inputs.experiment;
        let spec = &experiment.spec;
        let unsupported = |reason: String| RunError::Unsupported(inputs.plan.fidelity.clone(), reason);
        let Some(fidelity) = inputs.fidelity else {
            return Err(unsupported("not a simulated stack".into()));
        };
        let dt_s = spec.timing.dt;
        let schedule = DecisionSchedule::new(dt_s).ok_or_else(|| {
            unsupported(format!(
                "`timing.dt` must be at least the vehicles' {CONTROL_PERIOD_S} s period"
            ))
        })?;
        let planner_spec = spec
            .planner
            .as_ref()
            .ok_or_else(|| unsupported("the spec has no `planner`".into()))?;

        // Place the vehicles and prepare the planner.
        let starts = inputs.starts;
        let paths = inputs.agent_paths()?;
        let mut vehicles = starts
            .iter()
            .enumerate()
            .map(|(i, start)| VehicleStack::new(fidelity, experiment.vehicle, start, inputs.plan.seed, i))
            .collect::<Result<Vec<_>, _>>()
            .map_err(&unsupported)?;
        let mut planner = planner(planner_spec, dt_s, experiment.vehicle);
        let mut policy = inputs.policy()?;
        let ref_paths: Vec<usize> = starts.iter().map(|s| s.ref_path).collect();
        let mut safety = crate::safety::filter_of_run(fidelity.safety.as_ref(), inputs, &ref_paths)?;
        let mut knowledge = inputs.neighbour_knowledge();
        let model = cpmx_vehicle::KinematicBicycle::new(experiment.vehicle);

        let mut recording = Recording {
            notes: Vec::new(),
            latency_s: Vec::new(),
            statistics: Default::default(),
            times_s: Vec::with_capacity(spec.timing.steps as usize),
            ref_paths,
            samples: Vec::with_capacity(spec.timing.steps as usize),
        };
        let dt_ns = schedule.step_ns();
        // A plan must reach the next decision, which comes up to a period late on a step that
        // is no whole number of periods.
        let max_age_ns = max_state_age_ns(planner_spec.prediction_horizon, dt_ns)
            .saturating_sub(schedule.longest_gap_ns() - dt_ns);
        for tick in 0..spec.timing.steps {
            let offset_ns = schedule.offset_ns(u64::from(tick));
            let t_s = if schedule.is_exact() {
                (f64::from(tick) * dt_s * 1e9).round() / 1e9
            } else {
                offset_ns as f64 / 1e9
            };
            let tick_ns = RUN_START_NS + offset_ns;

            // Record the true states.
            recording.times_s.push(t_s);
            recording
                .samples
                .push(vehicles.iter().map(VehicleStack::true_sample).collect());

            // Plan from what the middleware lists; every vehicle gets its trajectory, anchored
            // at its state's time and valid from the tick on.
            let listed: Vec<StampedState> = vehicles.iter().map(|v| v.listed_state(tick_ns)).collect();
            let states: Vec<BicycleState> = listed.iter().map(|s| s.state).collect();
            if knowledge.is_active() {
                // What each agent knows of the others, from the states the middleware lists.
                let agents: Vec<cpmx_policy::AgentState> = states
                    .iter()
                    .map(|s| cpmx_policy::AgentState::from_bicycle(s, model.velocity_mps(s)))
                    .collect();
                planner.set_neighbours(Some(knowledge.step(t_s, &agents)));
            }
            let trajectories = match &mut safety {
                None => planner.plan(policy.as_mut(), &states, &paths, 0.0)?,
                Some(filter) => planner.plan_filtered(policy.as_mut(), filter, &states, &paths, 0.0)?,
            };
            for ((vehicle, trajectory), state) in vehicles.iter_mut().zip(&trajectories).zip(&listed) {
                let anchor = anchor_ns(state.create_ns, tick_ns, max_age_ns);
                vehicle.receive(trajectory_points(trajectory, anchor, dt_ns), tick_ns, tick_ns);
            }

            // The vehicles' 50 Hz loops until the next policy period.
            for sub in 0..schedule.periods_after(u64::from(tick)) {
                let now_ns = tick_ns + sub * CONTROL_PERIOD_NS;
                step_together(vehicles.iter_mut().map(|vehicle| (vehicle, now_ns)));
            }

            if spec.on_collision == OnCollision::EndRun
                && crate::sim::any_overlap(vehicles.iter().map(VehicleStack::pose), &experiment.vehicle)
            {
                break;
            }
        }
        if let Some(filter) = &safety {
            crate::safety::record(filter, &mut recording);
        }
        Ok(recording)
    }
}

/// The planner a spec asks for.
pub fn planner(spec: &PlannerSpec, dt_s: f64, vehicle: VehicleParams) -> Planner {
    Planner::new(
        PlannerParams {
            control_horizon: spec.control_horizon as usize,
            prediction_horizon: spec.prediction_horizon as usize,
            step_s: dt_s,
            steering_after: match spec.after_control_horizon.steering {
                cpmx_spec::model::SteeringAfterHc::LinearToZero => SteeringAfterHc::LinearToZero,
                cpmx_spec::model::SteeringAfterHc::Hold => SteeringAfterHc::Hold,
            },
        },
        vehicle,
    )
}
