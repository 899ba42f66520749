//! A fidelity's `safety:` layer as every stepper runs it: the spec's CBF filter with each
//! agent's lane, applied to a step's commands, and what it did counted. The sim and twin
//! engines (one run's agents) and the training environments (agents that change lanes at
//! every placement) share it, so a policy trains through the same filter it is evaluated with.

use std::collections::BTreeMap;
use std::sync::Arc;

use cpmx_spec::model::SafetyLayer;
use cpmx_vehicle::{BicycleState, Command, VehicleParams};
use cpmx_world::Polyline;

use crate::{AgentRows, Boundary, CbfParameters, CbfState, Fallback, MarginPredictor, Vehicle, filter_step};

/// A lane the filter keeps a vehicle in: its left and right road boundaries.
pub type Lane = (Boundary, Boundary);

/// The filter of one stepper: its parameters, the lanes, which lane each agent drives in,
/// and its counts.
#[derive(Debug, Clone)]
pub struct LayerFilter {
    parameters: CbfParameters,
    lanes: Arc<[Lane]>,
    lane_of_agent: Vec<usize>,
    counts: Counts,
    /// Whether to time each step's filter (`with_timing`).
    timing: bool,
}

/// What the filter did (over a run, or since the counts were last taken).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Counts {
    /// Agent-steps filtered.
    pub agent_steps: u64,
    /// Agent-steps whose command it changed.
    pub changed: u64,
    /// Agent-steps where the QP had no solution and the clamped command went through.
    pub infeasible: u64,
    /// Agent-steps where a row or the state was not a number.
    pub not_finite: u64,
    /// Agent-steps where the solver stopped without an answer.
    pub unsolved: u64,
    /// Agent-steps whose rows were relaxed (slacks) to find an answer.
    pub relaxed: u64,
    /// Agent-steps on which a row between two vehicles held.
    pub kept_apart: u64,
    /// The largest change of the speed [m/s] and of the steering [rad] command.
    pub largest_change: [f64; 2],
    /// How long the filter took, when timed ([`LayerFilter::with_timing`]).
    pub solve_time: Option<SolveTime>,
}

/// The filter's wall-clock time (which differs between machines and runs).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SolveTime {
    /// Over every step filtered [s].
    pub total_s: f64,
    /// The longest step, per agent-step of it [s].
    pub largest_per_agent_s: f64,
}

/// A polyline as the filter's boundary (`f32`, as SigmaRL holds it); `None` with fewer than
/// two points.
pub fn boundary(line: &Polyline) -> Option<Boundary> {
    Boundary::new(line.points.iter().map(|p| [p[0] as f32, p[1] as f32]).collect())
}

/// The filter's parameters of `layer`, for a vehicle of `vehicle`'s geometry stepping every
/// `dt_s`, vehicles kept apart (where the layer asks) by circles that cover `footprint`, or by
/// the margin `predictor` (the network the layer names, loaded).
pub fn parameters(
    layer: &SafetyLayer,
    vehicle: &VehicleParams,
    footprint: &VehicleParams,
    dt_s: f64,
    predictor: Option<Arc<MarginPredictor>>,
) -> CbfParameters {
    let cbf = &layer.cbf;
    CbfParameters {
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
            predictor: predictor.clone(),
        }),
        slack_weight: cbf.slack_weight,
        arithmetic: crate::Arithmetic::Numpy2,
    }
}

impl LayerFilter {
    /// The filter with `parameters` over `lanes`; agent `i` drives in lane `lane_of_agent[i]`
    /// until [`LayerFilter::set_lane`] moves it.
    ///
    /// # Panics
    /// If an agent's lane is not one of `lanes`.
    pub fn new(parameters: CbfParameters, lanes: Arc<[Lane]>, lane_of_agent: Vec<usize>) -> LayerFilter {
        assert!(
            lane_of_agent.iter().all(|&l| l < lanes.len()),
            "every agent drives in one of the filter's lanes"
        );
        LayerFilter {
            parameters,
            lanes,
            lane_of_agent,
            counts: Counts::default(),
            timing: false,
        }
    }

    /// The filter, timing each step it filters when `timing` is set (the counts gain
    /// `solve_time`).
    pub fn with_timing(mut self, timing: bool) -> LayerFilter {
        self.timing = timing;
        if timing {
            self.counts.solve_time = Some(SolveTime::default());
        }
        self
    }

    /// Agent `agent` now drives in lane `lane` (a training environment's new placement).
    ///
    /// # Panics
    /// If `lane` is not one of the filter's lanes.
    pub fn set_lane(&mut self, agent: usize, lane: usize) {
        assert!(lane < self.lanes.len(), "lane {lane} of {}", self.lanes.len());
        self.lane_of_agent[agent] = lane;
    }

    /// Filters every agent's command for its `state` (moving at `velocities`).
    pub fn apply(&mut self, states: &[BicycleState], velocities: &[[f64; 2]], commands: &mut [Command]) {
        let started = self.timing.then(std::time::Instant::now);
        let vehicles: Vec<Vehicle<'_>> = states
            .iter()
            .zip(velocities)
            .zip(commands.iter())
            .zip(&self.lane_of_agent)
            .map(|(((state, velocity), command), &lane)| Vehicle {
                // SigmaRL's filter sees the speed as the velocity's norm.
                state: CbfState {
                    x_m: state.x_m as f32,
                    y_m: state.y_m as f32,
                    yaw_rad: state.yaw_rad as f32,
                    speed_mps: velocity[0].hypot(velocity[1]) as f32,
                    steering_rad: state.steering_rad as f32,
                },
                nominal: [command.speed_mps as f32, command.steering_rad as f32],
                left: &self.lanes[lane].0,
                right: &self.lanes[lane].1,
            })
            .collect();
        let step = filter_step(&self.parameters, &vehicles);
        let c = &mut self.counts;
        if let (Some(started), Some(time)) = (started, &mut c.solve_time) {
            let seconds = started.elapsed().as_secs_f64();
            time.total_s += seconds;
            time.largest_per_agent_s = time
                .largest_per_agent_s
                .max(seconds / commands.len().max(1) as f64);
        }
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

    /// What the filter did so far.
    pub fn counts(&self) -> &Counts {
        &self.counts
    }

    /// What the filter did since the counts were last taken; the counts start again.
    pub fn take_counts(&mut self) -> Counts {
        let fresh = Counts {
            solve_time: self.timing.then(SolveTime::default),
            ..Counts::default()
        };
        std::mem::replace(&mut self.counts, fresh)
    }
}

impl Counts {
    /// Adds `other`'s counts (the largest changes: the larger).
    pub fn add(&mut self, other: &Counts) {
        self.agent_steps += other.agent_steps;
        self.changed += other.changed;
        self.infeasible += other.infeasible;
        self.not_finite += other.not_finite;
        self.unsolved += other.unsolved;
        self.relaxed += other.relaxed;
        self.kept_apart += other.kept_apart;
        for (mine, theirs) in self.largest_change.iter_mut().zip(other.largest_change) {
            *mine = mine.max(theirs);
        }
        if let Some(theirs) = other.solve_time {
            let mine = self.solve_time.get_or_insert_with(SolveTime::default);
            mine.total_s += theirs.total_s;
            mine.largest_per_agent_s = mine.largest_per_agent_s.max(theirs.largest_per_agent_s);
        }
    }

    /// The counts by name, for a run's `statistics` (`per_run.csv`'s columns).
    pub fn statistics(&self) -> BTreeMap<String, f64> {
        [
            ("safety.agent_steps", self.agent_steps as f64),
            ("safety.changed", self.changed as f64),
            ("safety.infeasible", self.infeasible as f64),
            ("safety.not_finite", self.not_finite as f64),
            ("safety.unsolved", self.unsolved as f64),
            ("safety.relaxed", self.relaxed as f64),
            ("safety.kept_apart", self.kept_apart as f64),
            ("safety.largest_speed_change_mps", self.largest_change[0]),
            ("safety.largest_steering_change_rad", self.largest_change[1]),
        ]
        .into_iter()
        .chain(self.solve_time.iter().flat_map(|t| {
            [
                ("safety.solve_s", t.total_s),
                ("safety.largest_solve_us", 1e6 * t.largest_per_agent_s),
            ]
        }))
        .map(|(name, value)| (name.to_owned(), value))
        .collect()
    }

    /// The counts in a line.
    pub fn note(&self) -> String {
        format!(
            "safety filter (CBF): {} of {} agent-steps changed (at most {:.3} m/s and {:.3} rad), \
             {} kept from another agent, the rows relaxed where the QP had no solution {} times, \
             clamped nominal action kept where it had none {} times, a row was not finite {} \
             times, the solver stopped {} times",
            self.changed,
            self.agent_steps,
            self.largest_change[0],
            self.largest_change[1],
            self.kept_apart,
            self.relaxed,
            self.infeasible,
            self.not_finite,
            self.unsolved
        )
    }
}

/// In a planning fidelity the filter changes each step the planner rolls out.
impl cpmx_planner::CommandFilter for LayerFilter {
    fn filter(&mut self, states: &[BicycleState], velocities_mps: &[[f64; 2]], commands: &mut [Command]) {
        self.apply(states, velocities_mps, commands);
    }
}
