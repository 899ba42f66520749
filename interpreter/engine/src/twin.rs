//! The twin engine (`control: trajectory`): the CPM Lab's control stack. Every policy period
//! the planner rolls the policy out over Hc/Hp from the states the vehicles *report* and hands
//! each vehicle a timed trajectory; each vehicle ([`VehicleStack`]) then runs its 50 Hz loop
//! until the next period. With `dynamics: kinematic` this is sim-mpc, with the grey-box model,
//! the IPS and the actuation delay it is the digital twin. The recording holds the true state
//! at every policy period, as the sim engine's does.

use cpmx_follower::TrajectoryPoint;
use cpmx_planner::{PlannedPoint, PlannedTrajectory, Planner, PlannerParams, SteeringAfterHc};
use cpmx_recording::Recording;
use cpmx_spec::model::{Fidelity, OnCollision, Planner as PlannerSpec};
use cpmx_vehicle::{BicycleState, VehicleParams};

use crate::engine::{Engine, RunError, RunInputs};
use crate::stack::{CONTROL_PERIOD_S, VehicleStack};

/// The lab's control stack around simulated vehicles.
#[derive(Debug, Clone, Copy, Default)]
pub struct TwinEngine;

impl Engine for TwinEngine {
    fn run(&self, inputs: &RunInputs<'_>) -> Result<Recording, RunError> {
        let experiment = inputs.experiment;
        let spec = &experiment.spec;
        let unsupported = |reason: String| RunError::Unsupported(inputs.plan.fidelity.clone(), reason);
        let Some(Fidelity::Simulated(fidelity)) = spec.fidelities.get(&inputs.plan.fidelity) else {
            return Err(unsupported("not a simulated stack".into()));
        };
        let dt_s = spec.timing.dt;
        let substeps = control_periods(dt_s).ok_or_else(|| {
            unsupported(format!(
                "`timing.dt` must be a multiple of the vehicles' {CONTROL_PERIOD_S} s period"
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

        let mut recording = Recording {
            notes: Vec::new(),
            times_s: Vec::with_capacity(spec.timing.steps as usize),
            ref_paths: starts.iter().map(|s| s.ref_path).collect(),
            samples: Vec::with_capacity(spec.timing.steps as usize),
        };
        let mut previous: Option<Vec<PlannedTrajectory>> = None;
        for tick in 0..spec.timing.steps {
            let t_s = (f64::from(tick) * dt_s * 1e9).round() / 1e9;

            // Record the true states.
            recording.times_s.push(t_s);
            recording
                .samples
                .push(vehicles.iter().map(VehicleStack::true_sample).collect());

            // Plan from what the vehicles report; every vehicle gets its trajectory.
            let reported: Vec<BicycleState> = vehicles
                .iter()
                .enumerate()
                .map(|(i, vehicle)| {
                    planning_state(vehicle, previous.as_ref().and_then(|plans| plans[i].get(1)))
                })
                .collect();
            let trajectories = planner.plan(policy.as_mut(), &reported, &paths, t_s)?;
            for (vehicle, trajectory) in vehicles.iter_mut().zip(&trajectories) {
                vehicle.receive(trajectory_points(trajectory), t_s, t_s);
            }
            previous = Some(trajectories);

            // The vehicles' 50 Hz loops until the next policy period.
            for sub in 0..substeps {
                let now_s = t_s + sub as f64 * CONTROL_PERIOD_S;
                for vehicle in &mut vehicles {
                    vehicle.step(now_s);
                }
            }

            if spec.on_collision == OnCollision::EndRun
                && crate::sim::any_overlap(vehicles.iter().map(VehicleStack::pose), &experiment.vehicle)
            {
                break;
            }
        }
        Ok(recording)
    }
}

/// The state the planner starts from: the vehicle's reported position and speed, with heading
/// and steering continued from the previous plan (see [`continue_heading`]).
fn planning_state(vehicle: &VehicleStack, planned_now: Option<&PlannedPoint>) -> BicycleState {
    continue_heading(vehicle.reported_state(), planned_now)
}

/// A measured state with heading and steering taken from the plan's point at this time. This is
/// part of the control architecture (sim-mpc, twin and lab alike): a µCar's heading and
/// steering are not the planner's bicycle states (it reports a 50 Hz servo command and an IPS
/// heading with its own slip), and replanning from them feeds servo jitter and the slip
/// mismatch back into every plan, so that the car turns the wrong way in tight curves.
/// Position and speed still come from the measurement. For the kinematic plant the planned
/// and the measured heading agree, so sim-mpc is unchanged by the rule.
pub fn continue_heading(measured: BicycleState, planned_now: Option<&PlannedPoint>) -> BicycleState {
    match planned_now {
        Some(plan) => BicycleState {
            yaw_rad: plan.yaw_rad,
            steering_rad: plan.steering_rad,
            ..measured
        },
        None => measured,
    }
}

/// Control periods per policy period, if `dt_s` is a whole multiple of the control period.
pub fn control_periods(dt_s: f64) -> Option<usize> {
    let n = (dt_s / CONTROL_PERIOD_S).round() as usize;
    (n > 0 && (n as f64 * CONTROL_PERIOD_S - dt_s).abs() < 1e-9).then_some(n)
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

/// A planned trajectory in the lab's form.
pub fn trajectory_points(trajectory: &PlannedTrajectory) -> Vec<TrajectoryPoint> {
    trajectory
        .iter()
        .map(|p| TrajectoryPoint {
            t_s: p.t_s,
            x_m: p.x_m,
            y_m: p.y_m,
            vx_mps: p.velocity_mps[0],
            vy_mps: p.velocity_mps[1],
        })
        .collect()
}
