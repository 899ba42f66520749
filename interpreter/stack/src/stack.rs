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
    Follower, FollowerConfig, Mpc, MpcConfig, Solver, StateEstimate, Status, TrajectoryCommand,
    TrajectoryPoint,
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
        let estimate = match &self.sensing {
            Some(sensing) => {
                let e = sensing.estimate();
                self.plant.with_pose(&self.state, e.pose, e.speed_mps)
            }
            None => self.state,
        };
        let output = self.follower.control(
            now_ns,
            &StateEstimate {
                state: estimate,
                ips_update_age_ns: self.ips_update_age_ns(now_ns),
            },
        );
        let input = match &mut self.delay {
            Some(delay) => delay.push(output.input),
            None => output.input,
        };
        self.command = output.input;
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
mod tests {
    use super::*;
    use cpmx_follower::StopReason;
    use cpmx_spec::model::{ActuationModel, Control, GreyBoxModel, SimulatedFidelity};

    const MS: u64 = 1_000_000;

    fn twin_without_sensing() -> DrawnFidelity {
        SimulatedFidelity {
            control: Control::Trajectory,
            dynamics: DynamicsLayer::GreyBox(GreyBoxModel {
                parameters: cpmx_vehicle::LAB_GREYBOX_PARAMETERS,
                euler_step_s: 0.02,
                battery_voltage_v: 7.8,
            }),
            sensing: None,
            actuation: Some(ActuationLayer::Model(ActuationModel { delay_ms: 80.0 })),
            follower: None,
            communication: None,
            perception: None,
        }
    }

    /// A left arc of radius 0.5 m at 0.5 m/s from the origin, heading +x, points every 0.1 s
    /// from the run's start.
    fn left_arc() -> Vec<TrajectoryPoint> {
        let (speed, radius) = (0.5, 0.5);
        (0..30u64)
            .map(|k| {
                let t = k as f64 * 0.1;
                let a = speed * t / radius;
                TrajectoryPoint {
                    t_ns: RUN_START_NS + k * 100 * MS,
                    x_m: radius * a.sin(),
                    y_m: radius * (1.0 - a.cos()),
                    vx_mps: speed * a.cos(),
                    vy_mps: speed * a.sin(),
                }
            })
            .collect()
    }

    fn start() -> InitialState {
        InitialState {
            ref_path: 0,
            x_m: 0.0,
            y_m: 0.0,
            yaw_rad: 0.0,
            speed_mps: 0.5,
        }
    }

    /// The lab's vehicles report the servo command the MPC has just computed, and the
    /// planner reads it as σ = σ_max · servo: not the servo the plant applies 80 ms later, and
    /// not the grey-box curvature's angle with its offset p9.
    #[test]
    fn a_vehicle_reports_its_current_servo_command_as_sigma_max_times_servo() {
        let vehicle = VehicleParams::MU_CAR;
        let mut stack = VehicleStack::new(&twin_without_sensing(), vehicle, &start(), 1, 0).unwrap();
        stack.receive(left_arc(), RUN_START_NS, RUN_START_NS);
        let mut servos = Vec::new();
        for k in 0..10 {
            assert_eq!(
                stack.step(RUN_START_NS + k * CONTROL_PERIOD_NS),
                Status::Following
            );
            let servo = stack.command()[1];
            servos.push(servo);
            let reported = stack.reported_state();
            assert_eq!(
                reported.steering_rad,
                vehicle.max_steering_rad * servo.clamp(-1.0, 1.0)
            );
        }
        // The servo moves into the turn within the delay, so the delayed one would differ.
        assert!(servos[9] > 0.2 && servos[5] > servos[1] + 0.1, "{servos:?}");
        // What is recorded carries the same steering.
        let sample = stack.true_sample();
        assert_eq!(sample.steering_rad, stack.reported_state().steering_rad);
        let speed = sample.velocity_mps[0].hypot(sample.velocity_mps[1]);
        let VehicleStack::GreyBox(v) = &stack else {
            unreachable!("a grey-box vehicle")
        };
        assert!(
            (speed - v.plant.speed_mps(&v.state)).abs() < 1e-12,
            "odometer speed is recorded"
        );
    }

    /// The twin with the lab's positioning system, losing every frame with `lost`.
    fn twin_with_ips(drop_probability: f64) -> DrawnFidelity {
        SimulatedFidelity {
            sensing: Some(SensingLayer::Model(SensingModel {
                rate_hz: 50.0,
                latency_ms: 60.0,
                noise_position_m: 0.002,
                noise_yaw_rad: 0.01,
                drop_probability,
                fusion_gain: 0.3,
            })),
            ..twin_without_sensing()
        }
    }

    /// Straight along +x at 0.5 m/s, points every 0.1 s for 1.5 s from `from_ns`.
    fn straight(from_ns: u64) -> Vec<TrajectoryPoint> {
        (0..16)
            .map(|k| {
                let t_ns = from_ns + k * 100 * MS;
                TrajectoryPoint {
                    t_ns,
                    x_m: 0.5 * (t_ns - RUN_START_NS) as f64 * 1e-9,
                    y_m: 0.0,
                    vx_mps: 0.5,
                    vy_mps: 0.0,
                }
            })
            .collect()
    }

    /// Drives 4 s along a fresh straight trajectory every 0.1 s; the statuses and the
    /// reported IPS ages of every step.
    fn drive_straight(fidelity: &DrawnFidelity) -> (Vec<Status>, Vec<u64>) {
        let mut stack = VehicleStack::new(fidelity, VehicleParams::MU_CAR, &start(), 9, 0).unwrap();
        let (mut statuses, mut ages) = (Vec::new(), Vec::new());
        for k in 0..200 {
            let now_ns = RUN_START_NS + k * CONTROL_PERIOD_NS;
            if k % 5 == 0 {
                stack.receive(straight(now_ns), now_ns, now_ns);
            }
            statuses.push(stack.step(now_ns));
            ages.push(
                stack
                    .listed_state(now_ns + CONTROL_PERIOD_NS + STATE_VALID_AFTER_NS)
                    .ips_update_age_ns,
            );
        }
        (statuses, ages)
    }

    /// The lab's controller stops a car whose IPS updates are older than 3 s ("Lost IPS
    /// position reference"); the age comes from the positioning system, so a car that loses
    /// every frame stops 3 s into the run, and one that loses the lab's 1 in 20 never does.
    #[test]
    fn a_car_that_loses_its_positions_stops_after_3_s() {
        let (statuses, ages) = drive_straight(&twin_with_ips(1.0));
        for (k, status) in (0..).zip(&statuses) {
            // Since the run's start, the last fix: the lab stops above 3 s, not at 3 s.
            let since_start_ns = k * CONTROL_PERIOD_NS;
            let lost = matches!(status, Status::Stopped(StopReason::LostIps { .. }));
            assert_eq!(
                lost,
                since_start_ns > 3_000 * MS,
                "at {since_start_ns} ns: {status:?}"
            );
            assert_eq!(ages[k as usize], since_start_ns + CONTROL_PERIOD_NS);
        }

        let (statuses, ages) = drive_straight(&twin_with_ips(0.05));
        assert!(statuses.iter().all(|s| *s == Status::Following), "{statuses:?}");
        // The start counts as a fix until the first frame arrives (at 80 ms, 60 ms old).
        assert!(
            ages[2..].iter().all(|&a| (60 * MS..200 * MS).contains(&a)),
            "{ages:?}"
        );
        assert!(
            ages.iter().any(|&a| a > 70 * MS),
            "a dropped frame makes the age grow"
        );

        let (_, ages) = drive_straight(&twin_without_sensing());
        assert!(ages.iter().all(|&a| a == 0), "ideal sensing: {ages:?}");
    }

    /// The middleware lists the newest state whose `valid_after = create + 60 ms` has passed;
    /// before the first step, the start.
    #[test]
    fn the_middleware_lists_states_60_ms_after_their_creation() {
        let vehicle = VehicleParams::MU_CAR;
        let mut stack = VehicleStack::new(&twin_without_sensing(), vehicle, &start(), 1, 0).unwrap();
        let initial = stack.listed_state(RUN_START_NS);
        assert_eq!(initial.create_ns, RUN_START_NS - STATE_VALID_AFTER_NS);
        assert_eq!((initial.state.x_m, initial.state.speed_mps), (0.0, 0.5));
        stack.receive(left_arc(), RUN_START_NS, RUN_START_NS);
        let mut reports = Vec::new();
        for k in 0..5 {
            let now_ns = RUN_START_NS + k * CONTROL_PERIOD_NS;
            stack.step(now_ns);
            reports.push((now_ns + CONTROL_PERIOD_NS, stack.reported_state()));
        }
        // At the tick 100 ms after the start the states of 60, 80 and 100 ms are not valid yet;
        // the state of 40 ms is from 100 ms on, not a nanosecond earlier.
        let listed = stack.listed_state(RUN_START_NS + 100 * MS);
        assert_eq!(listed.create_ns, reports[1].0);
        assert_eq!(listed.state, reports[1].1);
        assert_eq!(
            stack.listed_state(RUN_START_NS + 100 * MS - 1).create_ns,
            reports[0].0
        );
        assert_eq!(stack.listed_state(RUN_START_NS + 80 * MS).create_ns, reports[0].0);
        assert_eq!(
            stack.listed_state(RUN_START_NS + 70 * MS).create_ns,
            RUN_START_NS - STATE_VALID_AFTER_NS
        );
    }
}
