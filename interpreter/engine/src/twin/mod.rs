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

use cpmx_planner::{PlannedTrajectory, Planner, PlannerParams, SteeringAfterHc};
use cpmx_policy::SharedPasses;
use cpmx_recording::Recording;
use cpmx_spec::model::{OnCollision, Planner as PlannerSpec};
use cpmx_vehicle::{BicycleState, VehicleParams};

use crate::engine::{Engine, RunError, RunInputs};
use cpmx_stack::{
    CONTROL_PERIOD_NS, CONTROL_PERIOD_S, DecisionSchedule, FollowerStops, RUN_START_NS, StampedState,
    VehicleStack, anchor_ns, max_state_age_ns, step_together, trajectory_points,
};
use planning::{Planning, plan_together};

mod planning;

/// The lab's control stack around simulated vehicles.
#[derive(Debug, Clone, Copy, Default)]
pub struct TwinEngine;

impl Engine for TwinEngine {
    fn run(&self, inputs: &RunInputs<'_>) -> Result<Recording, RunError> {
        crate::engine::run_alone(self, inputs)
    }

    /// The runs tick by tick in lock-step: each plans on its own predicted states, the calls
    /// of the policies that run one actor sharing its network pass ([`planning`]), then the
    /// 50 Hz loops of all their vehicles step together, so that one pass of SIMD lanes solves
    /// the MPCs of several runs. Runs share no state, and the kernels give each row and lane
    /// the bits it has alone, so each run has the bits it has alone (`together_tests.rs`).
    fn run_together(&self, inputs: &[RunInputs<'_>]) -> Vec<Result<Recording, RunError>> {
        let mut runs: Vec<Result<TwinRun<'_>, RunError>> = inputs.iter().map(TwinRun::new).collect();
        let Some(steps) = runs.iter().flatten().map(|run| run.steps).max() else {
            return runs.into_iter().map(|run| run.map(TwinRun::finish)).collect();
        };
        let mut passes = SharedPasses::default();
        for tick in 0..steps {
            // Every run plans, the policies' calls of one actor in one network pass.
            let plannings: Vec<(usize, Planning<'_>)> = runs
                .iter_mut()
                .enumerate()
                .filter_map(|(i, slot)| match slot {
                    Ok(run) if run.is_driving(tick) => Some((i, run.begin_plan(tick))),
                    _ => None,
                })
                .collect();
            let planned = plan_together(plannings, &mut passes);
            for (i, plan) in planned {
                match plan {
                    Ok((trajectories, listed)) => {
                        if let Ok(run) = &mut runs[i] {
                            run.receive(tick, &trajectories, &listed);
                        }
                    }
                    Err(error) => runs[i] = Err(error),
                }
            }
            // The vehicles' 50 Hz loops until the next policy period; runs of one spec share
            // its schedule, so their vehicles' clocks agree.
            let driving = |run: &&mut TwinRun<'_>| run.is_driving(tick);
            let periods = runs
                .iter_mut()
                .flatten()
                .filter(driving)
                .map(|run| run.schedule.periods_after(u64::from(tick)))
                .max()
                .unwrap_or(0);
            for sub in 0..periods {
                step_together(
                    runs.iter_mut()
                        .flatten()
                        .filter(driving)
                        .filter(|run| sub < run.schedule.periods_after(u64::from(tick)))
                        .flat_map(|run| {
                            let now_ns = run.tick_ns(tick) + sub * CONTROL_PERIOD_NS;
                            run.vehicles.iter_mut().map(move |vehicle| (vehicle, now_ns))
                        }),
                );
            }
            for run in runs.iter_mut().flatten().filter(driving) {
                run.end_of_tick();
            }
        }
        runs.into_iter().map(|run| run.map(TwinRun::finish)).collect()
    }

    fn steps_together(&self) -> bool {
        true
    }
}

/// A twin run under way: its vehicles, planner, policy and layers, and what it recorded.
struct TwinRun<'a> {
    inputs: &'a RunInputs<'a>,
    steps: u32,
    schedule: DecisionSchedule,
    /// The oldest state a plan may be anchored at.
    max_age_ns: u64,
    vehicles: Vec<VehicleStack>,
    planner: Planner,
    policy: Box<dyn cpmx_policy::Policy>,
    paths: cpmx_policy::AgentPaths,
    safety: Option<cpmx_safety::layer::LayerFilter>,
    knowledge: cpmx_sensing::NeighbourKnowledge,
    model: cpmx_vehicle::KinematicBicycle,
    recording: Recording,
    /// Ended early (`on_collision: end-run`).
    ended: bool,
}

impl<'a> TwinRun<'a> {
    /// Places the vehicles and prepares the planner.
    fn new(inputs: &'a RunInputs<'a>) -> Result<Self, RunError> {
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
        let starts = inputs.starts;
        let paths = inputs.agent_paths()?;
        let vehicles = starts
            .iter()
            .enumerate()
            .map(|(i, start)| VehicleStack::new(fidelity, experiment.vehicle, start, inputs.plan.seed, i))
            .collect::<Result<Vec<_>, _>>()
            .map_err(&unsupported)?;
        let ref_paths: Vec<usize> = starts.iter().map(|s| s.ref_path).collect();
        let safety = crate::safety::filter_of_run(fidelity.safety.as_ref(), inputs, &ref_paths)?;
        let dt_ns = schedule.step_ns();
        // A plan must reach the next decision, which comes up to a period late on a step that
        // is no whole number of periods.
        let max_age_ns = max_state_age_ns(planner_spec.prediction_horizon, dt_ns)
            .saturating_sub(schedule.longest_gap_ns() - dt_ns);
        Ok(TwinRun {
            inputs,
            steps: spec.timing.steps,
            schedule,
            max_age_ns,
            vehicles,
            planner: planner(planner_spec, dt_s, experiment.vehicle),
            policy: inputs.policy()?,
            paths,
            safety,
            knowledge: inputs.neighbour_knowledge(),
            model: cpmx_vehicle::KinematicBicycle::new(experiment.vehicle),
            recording: Recording {
                notes: Vec::new(),
                latency_s: Vec::new(),
                statistics: Default::default(),
                times_s: Vec::with_capacity(spec.timing.steps as usize),
                ref_paths,
                samples: Vec::with_capacity(spec.timing.steps as usize),
            },
            ended: false,
        })
    }

    /// Whether the run still drives at `tick`.
    fn is_driving(&self, tick: u32) -> bool {
        !self.ended && tick < self.steps
    }

    /// The vehicles' clock at `tick`.
    fn tick_ns(&self, tick: u32) -> u64 {
        RUN_START_NS + self.schedule.offset_ns(u64::from(tick))
    }

    /// Records the true states at `tick` and begins the plan from what the middleware lists
    /// (the policy's calls are made by [`planning::plan_together`], perhaps beside other runs').
    fn begin_plan(&mut self, tick: u32) -> Planning<'_> {
        let dt_s = self.inputs.experiment.spec.timing.dt;
        let t_s = if self.schedule.is_exact() {
            (f64::from(tick) * dt_s * 1e9).round() / 1e9
        } else {
            self.schedule.offset_ns(u64::from(tick)) as f64 / 1e9
        };
        let tick_ns = self.tick_ns(tick);

        // Record the true states.
        self.recording.times_s.push(t_s);
        self.recording
            .samples
            .push(self.vehicles.iter().map(VehicleStack::true_sample).collect());

        let listed: Vec<StampedState> = self.vehicles.iter().map(|v| v.listed_state(tick_ns)).collect();
        let states: Vec<BicycleState> = listed.iter().map(|s| s.state).collect();
        if self.knowledge.is_active() {
            // What each agent knows of the others, from the states the middleware lists.
            let agents: Vec<cpmx_policy::AgentState> = states
                .iter()
                .map(|s| cpmx_policy::AgentState::from_bicycle(s, self.model.velocity_mps(s)))
                .collect();
            self.planner
                .set_neighbours(Some(self.knowledge.step(t_s, &agents)));
        }
        Planning::new(
            self.planner.begin(&states, &self.paths, 0.0),
            self.policy.as_mut(),
            self.safety.as_mut(),
            listed,
        )
    }

    /// Hands every vehicle its trajectory of the plan made at `tick`, anchored at its listed
    /// state's time and valid from the tick on.
    fn receive(&mut self, tick: u32, trajectories: &[PlannedTrajectory], listed: &[StampedState]) {
        let tick_ns = self.tick_ns(tick);
        let dt_ns = self.schedule.step_ns();
        for ((vehicle, trajectory), state) in self.vehicles.iter_mut().zip(trajectories).zip(listed) {
            let anchor = anchor_ns(state.create_ns, tick_ns, self.max_age_ns);
            vehicle.receive(trajectory_points(trajectory, anchor, dt_ns), tick_ns, tick_ns);
        }
    }

    /// After the vehicles' loops of a tick: ends the run at an overlap if the spec says so.
    fn end_of_tick(&mut self) {
        let experiment = self.inputs.experiment;
        if experiment.spec.on_collision == OnCollision::EndRun
            && crate::sim::any_overlap(self.vehicles.iter().map(VehicleStack::pose), &experiment.vehicle)
        {
            self.ended = true;
        }
    }

    /// What the run recorded, with its safety layer's counts and how often the lab's follower
    /// stopped its cars.
    fn finish(mut self) -> Recording {
        if let Some(filter) = &self.safety {
            crate::safety::record(filter, &mut self.recording);
        }
        let stops: FollowerStops = self.vehicles.iter().map(VehicleStack::stops).sum();
        self.recording.notes.extend(stops.note());
        self.recording.statistics.extend(stops.statistics());
        self.recording
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
