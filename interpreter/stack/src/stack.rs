//! One simulated µCar with the lab's on-board stack: plant, actuation delay, on-car sensing
//! and the 50 Hz MPC trajectory follower. The twin engine drives several of them from the
//! planner; `cpmx lab emulate` drives them from trajectories received over DDS.
//!
//! What a vehicle reports is what the lab's vehicles publish (`mid_level_controller/main.cxx`):
//! after each 20 ms step, the estimated pose after the step, the odometer speed and
//! `steering_servo` = the command the follower has just computed (not the delayed servo the
//! plant applies), stamped `valid_after = create + 60 ms`. The middleware lists, at each tick,
//! the newest state that is valid by then ([`VehicleStack::listed_state`]), so the planner sees
//! states 60 ms old, as in the lab. `create` is the time the pose holds (the step's end), as a
//! real car's estimate holds at its stamp; the lab's simulated vehicles stamp the post-step
//! pose with the step's start, 20 ms early, which would make every plan anchored at its state's
//! time (`twin.rs`) start 20 ms·v ahead of the car and the cars drive ~20 % faster than planned.
//!
//! Time: the vehicle's clock is integer nanoseconds (`timing.rs`), starting at
//! [`RUN_START_NS`]; the follower gets it as the lab's controller gets its `t_now`. The
//! on-car sensing keeps seconds since the run's start (from the nanoseconds, exactly
//! rounded), and the IPS age it reports is rounded back to whole nanoseconds for the follower.

use cpmx_follower::{
    Begun, Follower, FollowerConfig, Mpc, MpcConfig, Output, Solver, StateEstimate, Status,
    TrajectoryCommand, TrajectoryPoint,
};
use cpmx_recording::AgentSample;
use cpmx_sensing::{ActuationDelay, IpsParams, LocalizationParams, OdometryReading, OnCarSensing, Pose2};
use cpmx_spec::matrix::stream_key;
use cpmx_spec::model::{
    ActuationLayer, DrawnFidelity, DynamicsLayer, FollowerSolver, SensingLayer, SensingModel,
};
use cpmx_vehicle::{BicycleState, VehicleParams};
use std::collections::VecDeque;

use rand::SeedableRng;
use rand_chacha::ChaCha20Rng;

use crate::FollowerStops;
use crate::InitialState;
use crate::plants::{GreyBoxPlant, KinematicPlant, Plant};
use crate::timing::{RUN_START_NS, duration_ns};

/// The period of the vehicle-side loop [s] (the µCar's 50 Hz).
pub const CONTROL_PERIOD_S: f64 = 0.02;
/// The period of the vehicle-side loop [ns] (the lab's `period_nanoseconds`).
pub const CONTROL_PERIOD_NS: u64 = 20_000_000;

/// A vehicle's state becomes valid this long after its creation [s] (the lab's vehicles
/// stamp `valid_after = create + 60 ms`, `cpm::stamp_message(vehicleState, t_now, 60000000)`).
pub const STATE_VALID_AFTER_S: f64 = 0.06;
/// [`STATE_VALID_AFTER_S`] in nanoseconds.
pub const STATE_VALID_AFTER_NS: u64 = 60_000_000;

/// How many published states a vehicle keeps for the middleware to choose from.
const PUBLISHED_STATES: usize = 8;

/// The battery voltage a vehicle reports before it has measured one, and always with a plant
/// that has no battery (the lab's simulated vehicles' 7.8 V) [V].
pub const NOMINAL_BATTERY_V: f64 = 7.8;

/// A state as a vehicle publishes it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StampedState {
    /// The time its pose holds: the end of the 20 ms step that produced it [ns].
    pub create_ns: u64,
    /// Pose and odometer speed as estimated on the car, steering σ = σ_max · servo command.
    pub state: BicycleState,
    /// Time since the newest IPS fix the car received was measured, at `create_ns` [ns]
    /// (the lab's `IPS_update_age_nanoseconds`; 0 with ideal sensing).
    pub ips_update_age_ns: u64,
    /// The battery voltage the car measures [V].
    pub battery_voltage_v: f64,
}

impl StampedState {
    /// When the middleware may list it [ns].
    pub fn valid_after_ns(&self) -> u64 {
        self.create_ns + STATE_VALID_AFTER_NS
    }
}

/// A simulated vehicle with either plant.
#[derive(Debug)]
pub enum VehicleStack {
    Kinematic(Box<Vehicle<KinematicPlant, 5, 2>>),
    GreyBox(Box<Vehicle<GreyBoxPlant, 4, 2>>),
}

/// The parts of one vehicle, for one plant.
#[derive(Debug)]
pub struct Vehicle<P: Plant<NX, NU>, const NX: usize, const NU: usize> {
    plant: P,
    state: [f64; NX],
    /// The follower's current command (what the vehicle reports as its servo).
    command: [f64; NU],
    /// The newest published states, oldest first.
    published: VecDeque<StampedState>,
    follower: Follower<P::Model, NX, NU>,
    delay: Option<ActuationDelay<[f64; NU]>>,
    sensing: Option<OnCarSensing>,
    /// The run's stream `sensing/<agent>`.
    rng: ChaCha20Rng,
    /// Since when the positioning fixes do not reach the car (`cpmx lab emulate`'s fault) [ns].
    ips_lost_since_ns: Option<u64>,
    /// The battery voltage last measured [V].
    battery_voltage_v: f64,
    /// The periods stepped, and those in which the follower stopped the car.
    stops: FollowerStops,
}

macro_rules! each {
    ($self:expr, $v:ident => $body:expr) => {
        match $self {
            VehicleStack::Kinematic($v) => $body,
            VehicleStack::GreyBox($v) => $body,
        }
    };
}

impl VehicleStack {
    /// A vehicle of `fidelity` standing at `start`; `agent` names its random stream.
    pub fn new(
        fidelity: &DrawnFidelity,
        vehicle: VehicleParams,
        start: &InitialState,
        run_seed: u64,
        agent: usize,
    ) -> Result<VehicleStack, String> {
        Ok(match &fidelity.dynamics {
            DynamicsLayer::Kinematic(_) => VehicleStack::Kinematic(Box::new(Vehicle::new(
                KinematicPlant::new(vehicle),
                fidelity,
                start,
                run_seed,
                agent,
            )?)),
            DynamicsLayer::GreyBox(model) => VehicleStack::GreyBox(Box::new(Vehicle::new(
                GreyBoxPlant::new(model, vehicle)?,
                fidelity,
                start,
                run_seed,
                agent,
            )?)),
        })
    }

    /// The periods stepped so far, and those in which the follower stopped the car, by reason.
    pub fn stops(&self) -> FollowerStops {
        each!(self, v => v.stops)
    }

    /// Hands the follower a new trajectory (kept until it is valid, as on the car).
    pub fn receive(&mut self, points: Vec<TrajectoryPoint>, create_stamp_ns: u64, valid_after_ns: u64) {
        each!(self, v => v.receive(points, create_stamp_ns, valid_after_ns))
    }

    /// One 20 ms step starting at `now_ns`: estimate, follow, delay, move, sense. Returns the
    /// follower's status.
    pub fn step(&mut self, now_ns: u64) -> Status {
        each!(self, v => v.step(now_ns))
    }

    /// What the vehicle reports now: its estimate (the truth with ideal sensing), with the
    /// steering σ = σ_max · its current servo command.
    pub fn reported_state(&self) -> BicycleState {
        each!(self, v => v.reported_state())
    }

    /// The state the lab's middleware lists at `t_now_ns`: the newest published state whose
    /// `valid_after` has passed (before the first step, the start, stamped to be valid at the
    /// run's start).
    pub fn listed_state(&self, t_now_ns: u64) -> StampedState {
        each!(self, v => v.listed_state(t_now_ns))
    }

    /// The follower's current command (plant inputs).
    pub fn command(&self) -> [f64; 2] {
        each!(self, v => v.command)
    }

    /// The true state, as recorded.
    pub fn true_sample(&self) -> AgentSample {
        each!(self, v => v.true_sample())
    }

    /// The true pose.
    pub fn pose(&self) -> Pose2 {
        each!(self, v => v.plant.pose(&v.state))
    }

    /// From `now_ns` on, the positioning fixes stop reaching the car (`lost`) or reach it
    /// again: it drives on dead reckoning, the age of its newest fix grows, and its controller
    /// stops it once that passes 3 s. (With ideal sensing the age counts from `now_ns`.)
    pub fn lose_ips(&mut self, now_ns: u64, lost: bool) {
        each!(self, v => {
            if let Some(sensing) = &mut v.sensing {
                sensing.lose_fixes(lost);
            }
            v.ips_lost_since_ns = match (lost, v.ips_lost_since_ns) {
                (true, since) => since.or(Some(now_ns)),
                (false, _) => None,
            };
        })
    }
}

impl<P: Plant<NX, NU>, const NX: usize, const NU: usize> Vehicle<P, NX, NU> {
    fn new(
        plant: P,
        fidelity: &DrawnFidelity,
        start: &InitialState,
        run_seed: u64,
        agent: usize,
    ) -> Result<Self, String> {
        let state = plant.initial_state(start);
        let neutral = plant.neutral_input();
        // The µCar's MPC compensates a fixed 60 ms (3 periods) of actuation delay; with ideal
        // actuation there is nothing to compensate.
        let lab = MpcConfig::lab(plant.move_weights());
        let delay_steps = if matches!(fidelity.actuation, Some(ActuationLayer::Model(_))) {
            lab.delay_steps
        } else {
            0
        };
        let solver = match fidelity.follower.unwrap_or_default().solver {
            FollowerSolver::Gradient => Solver::Gradient,
            FollowerSolver::Qp => Solver::Qp,
        };
        let mpc = Mpc::new(
            plant.mpc_model(),
            MpcConfig {
                delay_steps,
                solver,
                ..lab
            },
        );
        let delay = match &fidelity.actuation {
            Some(ActuationLayer::Model(a)) => {
                Some(ActuationDelay::new(a.delay_ms, CONTROL_PERIOD_S, neutral).map_err(|e| e.to_string())?)
            }
            _ => None,
        };
        let sensing = match &fidelity.sensing {
            Some(SensingLayer::Model(s)) => Some(on_car_sensing(s, plant.pose(&state), start.speed_mps)?),
            _ => None,
        };
        let mut vehicle = Self {
            plant,
            state,
            command: neutral,
            published: VecDeque::with_capacity(PUBLISHED_STATES + 1),
            follower: Follower::new(mpc, FollowerConfig::default()),
            delay,
            sensing,
            rng: ChaCha20Rng::from_seed(stream_key(run_seed, &format!("sensing/{agent}"))),
            ips_lost_since_ns: None,
            battery_voltage_v: NOMINAL_BATTERY_V,
            stops: FollowerStops::default(),
        };
        // The vehicle stood at its start before the run: that state is valid at the run's
        // start (for a start with speed, it is 60 ms early).
        vehicle.publish(RUN_START_NS - STATE_VALID_AFTER_NS);
        Ok(vehicle)
    }

    /// Publishes the current report stamped `create_ns`.
    fn publish(&mut self, create_ns: u64) {
        let state = self.reported_state();
        let ips_update_age_ns = self.ips_update_age_ns(create_ns);
        self.published.push_back(StampedState {
            create_ns,
            state,
            ips_update_age_ns,
            battery_voltage_v: self.battery_voltage_v,
        });
        if self.published.len() > PUBLISHED_STATES {
            self.published.pop_front();
        }
    }

    fn listed_state(&self, t_now_ns: u64) -> StampedState {
        self.published
            .iter()
            .rev()
            .find(|s| s.valid_after_ns() <= t_now_ns)
            .or(self.published.front())
            .copied()
            .unwrap_or(StampedState {
                create_ns: t_now_ns,
                state: self.reported_state(),
                ips_update_age_ns: self.ips_update_age_ns(t_now_ns),
                battery_voltage_v: self.battery_voltage_v,
            })
    }

    /// Time since the newest IPS fix that reached the car was measured [ns]: what the lab's
    /// controller stops on after 3 s; 0 with ideal sensing (the car always knows its pose).
    fn ips_update_age_ns(&self, now_ns: u64) -> u64 {
        match (&self.sensing, self.ips_lost_since_ns) {
            (Some(sensing), _) => duration_ns(sensing.ips_update_age_s(sensing_time_s(now_ns))),
            (None, Some(since_ns)) => now_ns.saturating_sub(since_ns),
            (None, None) => 0,
        }
    }

    fn receive(&mut self, points: Vec<TrajectoryPoint>, create_stamp_ns: u64, valid_after_ns: u64) {
        // A malformed trajectory is dropped; the car keeps (or times out on) its previous
        // command, as in the lab.
        if let Ok(trajectory) = cpmx_follower::Trajectory::new(points) {
            self.follower.receive(TrajectoryCommand {
                create_stamp_ns,
                valid_after_ns,
                trajectory,
            });
        }
    }

    fn step(&mut self, now_ns: u64) -> Status {
        let output = match self.begin_step(now_ns) {
            Begun::Decided(output) => output,
            Begun::Gradient(pending) => {
                let result = self.follower.mpc_mut().solve_pending(&pending);
                self.follower.finish(&pending, result)
            }
        };
        self.end_step(now_ns, output)
    }

    /// The first half of a step: the estimate and the follower's decision up to its MPC's
    /// gradient solve (`together.rs` solves several vehicles' together).
    pub(crate) fn begin_step(&mut self, now_ns: u64) -> Begun<Output<NU>, NX, NU> {
        let estimate = match &self.sensing {
            Some(sensing) => {
                let e = sensing.estimate();
                self.plant.with_pose(&self.state, e.pose, e.speed_mps)
            }
            None => self.state,
        };
        self.follower.begin(
            now_ns,
            &StateEstimate {
                state: estimate,
                ips_update_age_ns: self.ips_update_age_ns(now_ns),
            },
        )
    }

    /// The follower, for a solve of its MPC's pending problem together with other vehicles'.
    pub(crate) fn follower_mut(&mut self) -> &mut Follower<P::Model, NX, NU> {
        &mut self.follower
    }

    /// The second half of a step, with the follower's `output`: delay, move, sense, publish.
    pub(crate) fn end_step(&mut self, now_ns: u64, output: Output<NU>) -> Status {
        let input = match &mut self.delay {
            Some(delay) => delay.push(output.input),
            None => output.input,
        };
        self.command = output.input;
        self.stops.count(&output.status);
        let before = self.plant.pose(&self.state);
        let step = self.plant.step(&self.state, &input, CONTROL_PERIOD_S);
        self.state = step.state;
        if let Some(voltage_v) = step.battery_voltage_v {
            self.follower.measure_battery_voltage(voltage_v);
            self.battery_voltage_v = voltage_v;
        }
        if let Some(sensing) = &mut self.sensing {
            let after = self.plant.pose(&self.state);
            let reading = OdometryReading {
                distance_increment_m: step.odometer_increment_m,
                yaw_increment_rad: cpmx_sensing::wrap_angle_rad(after.yaw_rad - before.yaw_rad),
                speed_mps: self.plant.speed_mps(&self.state),
            };
            sensing.step(
                sensing_time_s(now_ns + CONTROL_PERIOD_NS),
                after,
                &reading,
                &mut self.rng,
            );
        }
        self.publish(now_ns + CONTROL_PERIOD_NS);
        output.status
    }

    fn reported_state(&self) -> BicycleState {
        let (pose, speed_mps) = match &self.sensing {
            Some(sensing) => {
                let e = sensing.estimate();
                (e.pose, e.speed_mps)
            }
            None => (self.plant.pose(&self.state), self.plant.speed_mps(&self.state)),
        };
        BicycleState {
            x_m: pose.x_m,
            y_m: pose.y_m,
            yaw_rad: pose.yaw_rad,
            speed_mps,
            steering_rad: self.plant.reported_steering_rad(&self.state, &self.command),
        }
    }

    /// The true pose and speed, with the reported steering and the velocity the lab driver
    /// would record of them.
    fn true_sample(&self) -> AgentSample {
        let pose = self.plant.pose(&self.state);
        let steering_rad = self.plant.reported_steering_rad(&self.state, &self.command);
        AgentSample {
            x_m: pose.x_m,
            y_m: pose.y_m,
            yaw_rad: cpmx_sensing::wrap_angle_rad(pose.yaw_rad),
            velocity_mps: self.plant.recorded_velocity_mps(&self.state, steering_rad),
            steering_rad,
        }
    }
}

/// The on-car sensing's time for the vehicle clock's `t_ns`: seconds since the run's start
/// (negative before it), from whole nanoseconds.
fn sensing_time_s(t_ns: u64) -> f64 {
    (t_ns as f64 - RUN_START_NS as f64) / 1e9
}

fn on_car_sensing(s: &SensingModel<f64>, pose: Pose2, speed_mps: f64) -> Result<OnCarSensing, String> {
    let ips = IpsParams {
        rate_hz: s.rate_hz,
        latency_ms: s.latency_ms,
        noise_position_m: s.noise_position_m,
        noise_yaw_rad: s.noise_yaw_rad,
        drop_probability: s.drop_probability,
    };
    let localization = LocalizationParams {
        fusion_gain: s.fusion_gain,
        ..LocalizationParams::LAB
    };
    OnCarSensing::new(&ips, &localization, pose, speed_mps, 0.0).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests;
