//! One simulated µCar with the lab's on-board stack: plant, actuation delay, on-car sensing
//! and the 50 Hz MPC trajectory follower. The twin engine drives several of them from the
//! planner; `cpmx lab emulate` drives them from trajectories received over DDS.

use cpmx_follower::{
    Follower, FollowerConfig, Mpc, MpcConfig, StateEstimate, Status, TrajectoryCommand, TrajectoryPoint,
};
use cpmx_recording::AgentSample;
use cpmx_sensing::{ActuationDelay, IpsParams, LocalizationParams, OdometryReading, OnCarSensing, Pose2};
use cpmx_spec::matrix::stream_key;
use cpmx_spec::model::{ActuationLayer, DynamicsLayer, SensingLayer, SensingModel, SimulatedFidelity};
use cpmx_vehicle::{BicycleState, VehicleParams};
use rand::SeedableRng;
use rand_chacha::ChaCha20Rng;

use crate::plants::{GreyBoxPlant, KinematicPlant, Plant};
use crate::starts::InitialState;

/// The period of the vehicle-side loop [s] (the µCar's 50 Hz).
pub const CONTROL_PERIOD_S: f64 = 0.02;

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
    velocity_mps: [f64; 2],
    applied: [f64; NU],
    follower: Follower<P::Model, NX, NU>,
    delay: Option<ActuationDelay<[f64; NU]>>,
    sensing: Option<OnCarSensing>,
    /// The run's stream `sensing/<agent>`.
    rng: ChaCha20Rng,
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
        fidelity: &SimulatedFidelity,
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
    pub fn receive(&mut self, points: Vec<TrajectoryPoint>, create_stamp_s: f64, valid_after_s: f64) {
        each!(self, v => v.receive(points, create_stamp_s, valid_after_s))
    }

    /// One 20 ms step starting at `now_s`: estimate, follow, delay, move, sense. Returns the
    /// follower's status.
    pub fn step(&mut self, now_s: f64) -> Status {
        each!(self, v => v.step(now_s))
    }

    /// What the vehicle reports: its estimate (the truth with ideal sensing), with the steering
    /// angle the planner's bicycle expects.
    pub fn reported_state(&self) -> BicycleState {
        each!(self, v => v.reported_state())
    }

    /// The true state, as recorded.
    pub fn true_sample(&self) -> AgentSample {
        each!(self, v => v.true_sample())
    }

    /// The true pose.
    pub fn pose(&self) -> Pose2 {
        each!(self, v => v.plant.pose(&v.state))
    }
}

impl<P: Plant<NX, NU>, const NX: usize, const NU: usize> Vehicle<P, NX, NU> {
    fn new(
        plant: P,
        fidelity: &SimulatedFidelity,
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
        let mpc = Mpc::new(plant.mpc_model(), MpcConfig { delay_steps, ..lab });
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
        Ok(Self {
            velocity_mps: plant.velocity_mps(&state, &neutral),
            plant,
            state,
            applied: neutral,
            follower: Follower::new(mpc, FollowerConfig::default()),
            delay,
            sensing,
            rng: ChaCha20Rng::from_seed(stream_key(run_seed, &format!("sensing/{agent}"))),
        })
    }

    fn receive(&mut self, points: Vec<TrajectoryPoint>, create_stamp_s: f64, valid_after_s: f64) {
        // A malformed trajectory is dropped; the car keeps (or times out on) its previous
        // command, as in the lab.
        if let Ok(trajectory) = cpmx_follower::Trajectory::new(points) {
            let _ = self.follower.receive(TrajectoryCommand {
                create_stamp_s,
                valid_after_s,
                trajectory,
            });
        }
    }

    fn step(&mut self, now_s: f64) -> Status {
        let estimate = match &self.sensing {
            Some(sensing) => {
                let e = sensing.estimate();
                self.plant.with_pose(&self.state, e.pose, e.speed_mps)
            }
            None => self.state,
        };
        let output = self.follower.control(
            now_s,
            &StateEstimate {
                state: estimate,
                ips_update_age_s: 0.0,
            },
        );
        let input = match &mut self.delay {
            Some(delay) => delay.push(output.input),
            None => output.input,
        };
        let before = self.plant.pose(&self.state);
        let step = self.plant.step(&self.state, &input, CONTROL_PERIOD_S);
        self.state = step.state;
        self.velocity_mps = step.velocity_mps;
        self.applied = input;
        if let Some(sensing) = &mut self.sensing {
            let after = self.plant.pose(&self.state);
            let reading = OdometryReading {
                distance_increment_m: step.odometer_increment_m,
                yaw_increment_rad: cpmx_sensing::wrap_angle_rad(after.yaw_rad - before.yaw_rad),
                speed_mps: self.plant.speed_mps(&self.state),
            };
            sensing.step(now_s + CONTROL_PERIOD_S, after, &reading, &mut self.rng);
        }
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
            steering_rad: self.plant.steering_rad(&self.state, &self.applied),
        }
    }

    fn true_sample(&self) -> AgentSample {
        let pose = self.plant.pose(&self.state);
        AgentSample {
            x_m: pose.x_m,
            y_m: pose.y_m,
            yaw_rad: cpmx_sensing::wrap_angle_rad(pose.yaw_rad),
            velocity_mps: self.velocity_mps,
            steering_rad: self.plant.steering_rad(&self.state, &self.applied),
        }
    }
}

fn on_car_sensing(s: &SensingModel, pose: Pose2, speed_mps: f64) -> Result<OnCarSensing, String> {
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
