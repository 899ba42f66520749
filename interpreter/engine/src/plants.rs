//! The plants of the twin engine: how a vehicle model is stepped, read and followed.
//! `KinematicPlant` (sim-mpc: the kinematic bicycle, MPC inputs = speed and steering commands)
//! and `GreyBoxPlant` (the twin: the lab's identified model, MPC inputs = throttle and
//! steering servo, as the µCar's own MPC).

use cpmx_follower::{BicycleModel, InputLimits, Model, TrajectorySample, unwrap_near};
use cpmx_sensing::Pose2;
use cpmx_spec::model::GreyBoxModel;
use cpmx_vehicle::{GreyBoxParams, GreyBoxState, GreyBoxVehicle, KinematicBicycle, VehicleParams};

use crate::starts::InitialState;

/// One 20 ms step of a plant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantStep<const NX: usize> {
    pub state: [f64; NX],
    /// Velocity in the map frame after the step [m/s].
    pub velocity_mps: [f64; 2],
    /// Distance the odometer counted during the step [m].
    pub odometer_increment_m: f64,
}

/// A vehicle model as the twin engine drives it.
pub trait Plant<const NX: usize, const NU: usize> {
    /// The model its MPC follower predicts with.
    type Model: Model<NX, NU> + Clone;

    fn mpc_model(&self) -> Self::Model;
    /// Weights of input moves in the MPC cost.
    fn move_weights(&self) -> [f64; NU];
    fn initial_state(&self, start: &InitialState) -> [f64; NX];
    /// The input of a car at rest.
    fn neutral_input(&self) -> [f64; NU];
    fn step(&self, state: &[f64; NX], input: &[f64; NU], dt_s: f64) -> PlantStep<NX>;
    fn pose(&self, state: &[f64; NX]) -> Pose2;
    fn speed_mps(&self, state: &[f64; NX]) -> f64;
    /// The state with pose and speed replaced by an estimate (the rest is known on board).
    fn with_pose(&self, state: &[f64; NX], pose: Pose2, speed_mps: f64) -> [f64; NX];
    /// The steering angle the planner's bicycle sees [rad].
    fn steering_rad(&self, state: &[f64; NX], applied: &[f64; NU]) -> f64;
    fn velocity_mps(&self, state: &[f64; NX], applied: &[f64; NU]) -> [f64; 2];
}

/// The kinematic bicycle under MPC control (sim-mpc).
#[derive(Debug, Clone, Copy)]
pub struct KinematicPlant {
    model: KinematicBicycle,
}

impl KinematicPlant {
    pub fn new(vehicle: VehicleParams) -> Self {
        Self {
            model: KinematicBicycle::new(vehicle),
        }
    }
}

impl Plant<5, 2> for KinematicPlant {
    type Model = BicycleModel;

    fn mpc_model(&self) -> BicycleModel {
        BicycleModel { bicycle: self.model }
    }
    fn move_weights(&self) -> [f64; 2] {
        cpmx_follower::BICYCLE_MOVE_WEIGHTS
    }
    fn initial_state(&self, s: &InitialState) -> [f64; 5] {
        [s.x_m, s.y_m, s.yaw_rad, s.speed_mps, 0.0]
    }
    fn neutral_input(&self) -> [f64; 2] {
        [0.0, 0.0]
    }
    fn step(&self, state: &[f64; 5], input: &[f64; 2], dt_s: f64) -> PlantStep<5> {
        let out = self.model.step(
            &BicycleModel::to_state(state),
            BicycleModel::to_command(input),
            dt_s,
        );
        PlantStep {
            state: BicycleModel::from_state(&out.state),
            velocity_mps: out.velocity_mps,
            odometer_increment_m: state[3] * dt_s,
        }
    }
    fn pose(&self, state: &[f64; 5]) -> Pose2 {
        Pose2 {
            x_m: state[0],
            y_m: state[1],
            yaw_rad: state[2],
        }
    }
    fn speed_mps(&self, state: &[f64; 5]) -> f64 {
        state[3]
    }
    fn with_pose(&self, state: &[f64; 5], pose: Pose2, speed_mps: f64) -> [f64; 5] {
        [
            pose.x_m,
            pose.y_m,
            unwrap_near(pose.yaw_rad, state[2]),
            speed_mps,
            state[4],
        ]
    }
    fn steering_rad(&self, state: &[f64; 5], _: &[f64; 2]) -> f64 {
        state[4]
    }
    fn velocity_mps(&self, state: &[f64; 5], _: &[f64; 2]) -> [f64; 2] {
        self.model.velocity_mps(&BicycleModel::to_state(state))
    }
}

/// The lab's identified grey-box model under its MPC (the twin).
#[derive(Debug, Clone)]
pub struct GreyBoxPlant {
    model: GreyBoxMpcModel,
    vehicle: VehicleParams,
}

impl GreyBoxPlant {
    pub fn new(spec: &GreyBoxModel, vehicle: VehicleParams) -> Result<Self, String> {
        let params = GreyBoxParams {
            parameters: spec.parameters,
            euler_step_s: spec.euler_step_s,
            battery_voltage_v: spec.battery_voltage_v,
        };
        let model = GreyBoxVehicle::new(params).map_err(|e| e.to_string())?;
        Ok(Self {
            model: GreyBoxMpcModel { model },
            vehicle,
        })
    }
}

fn grey_state(state: &[f64; 4]) -> GreyBoxState {
    GreyBoxState {
        x_m: state[0],
        y_m: state[1],
        yaw_rad: state[2],
        speed_mps: state[3],
    }
}

impl Plant<4, 2> for GreyBoxPlant {
    type Model = GreyBoxMpcModel;

    fn mpc_model(&self) -> GreyBoxMpcModel {
        self.model.clone()
    }
    fn move_weights(&self) -> [f64; 2] {
        cpmx_follower::LAB_MOVE_WEIGHTS
    }
    fn initial_state(&self, s: &InitialState) -> [f64; 4] {
        [s.x_m, s.y_m, s.yaw_rad, s.speed_mps]
    }
    fn neutral_input(&self) -> [f64; 2] {
        [0.0, 0.0]
    }
    fn step(&self, state: &[f64; 4], input: &[f64; 2], dt_s: f64) -> PlantStep<4> {
        let m = &self.model.model;
        let grey_input = m.input(input[0], input[1]);
        match m.step(&grey_state(state), &grey_input, dt_s) {
            Ok(out) => PlantStep {
                state: [
                    out.state.x_m,
                    out.state.y_m,
                    out.state.yaw_rad,
                    out.state.speed_mps,
                ],
                velocity_mps: out.velocity_mps,
                odometer_increment_m: out.odometer_increment_m,
            },
            // The engine only asks for whole positive control periods; a refused step leaves
            // the car where it is rather than inventing motion.
            Err(_) => PlantStep {
                state: *state,
                velocity_mps: [0.0, 0.0],
                odometer_increment_m: 0.0,
            },
        }
    }
    fn pose(&self, state: &[f64; 4]) -> Pose2 {
        Pose2 {
            x_m: state[0],
            y_m: state[1],
            yaw_rad: state[2],
        }
    }
    fn speed_mps(&self, state: &[f64; 4]) -> f64 {
        state[3]
    }
    fn with_pose(&self, state: &[f64; 4], pose: Pose2, speed_mps: f64) -> [f64; 4] {
        [pose.x_m, pose.y_m, unwrap_near(pose.yaw_rad, state[2]), speed_mps]
    }
    /// The servo position as a steering angle: the bicycle steering whose curvature equals the
    /// grey-box model's curvature `p4·δ'/(p1·(1 + p2·δ'²))` at this servo position.
    fn steering_rad(&self, _: &[f64; 4], applied: &[f64; 2]) -> f64 {
        let p = &self.model.model.params().parameters;
        let effective = self.model.model.effective_steering(applied[1]);
        let curvature = p[3] * effective / (p[0] * (1.0 + p[1] * effective * effective));
        let (wheelbase, rear) = (self.vehicle.wheelbase_m, self.vehicle.rear_axle_m);
        // tan δ = κL / sqrt(1 − (κ l_r)²), clamped to the steering limit.
        let root = (1.0 - (curvature * rear).powi(2)).max(1e-9).sqrt();
        (curvature * wheelbase / root)
            .atan()
            .clamp(-self.vehicle.max_steering_rad, self.vehicle.max_steering_rad)
    }
    fn velocity_mps(&self, state: &[f64; 4], applied: &[f64; 2]) -> [f64; 2] {
        self.model.model.velocity_mps(&grey_state(state), applied[1])
    }
}

/// The grey-box model as the MPC predicts with it: state `[x, y, yaw, speed]`, input
/// `[throttle, steering servo]`.
#[derive(Debug, Clone)]
pub struct GreyBoxMpcModel {
    model: GreyBoxVehicle,
}

impl Model<4, 2> for GreyBoxMpcModel {
    fn step(&self, state: &[f64; 4], input: &[f64; 2], dt_s: f64) -> [f64; 4] {
        let grey_input = self.model.input(input[0], input[1]);
        match self.model.step(&grey_state(state), &grey_input, dt_s) {
            Ok(out) => [
                out.state.x_m,
                out.state.y_m,
                out.state.yaw_rad,
                out.state.speed_mps,
            ],
            Err(_) => *state,
        }
    }

    fn position_m(&self, state: &[f64; 4]) -> [f64; 2] {
        [state[0], state[1]]
    }

    /// Steady state along the reference: the servo whose curvature matches the reference's,
    /// and the throttle whose steady-state speed (v̇ = 0) is the reference speed.
    fn feedforward(&self, sample: &TrajectorySample, near: &[f64; 4]) -> ([f64; 4], [f64; 2]) {
        let p = &self.model.params().parameters;
        let voltage = self.model.params().battery_voltage_v;
        // Throttle whose steady-state speed is `speed`: 0 = p5·v + (p6 + p7·V)·sign(f)·|f|^p8.
        let motor = p[5] + p[6] * voltage;
        let throttle_for = |speed: f64| {
            if motor.abs() <= f64::EPSILON {
                return 0.0;
            }
            let ratio = -p[4] * speed / motor;
            (ratio.abs().powf(1.0 / p[7]) * ratio.signum()).clamp(-1.0, 1.0)
        };
        if sample.speed_mps() < cpmx_follower::LOW_SPEED_MPS {
            // Near standstill keep the heading and linearise at a creeping throttle: at f = 0
            // the motor term |f|^p8 has no slope, so the linearised throttle would do nothing.
            let state = [sample.position_m[0], sample.position_m[1], near[2], near[3]];
            return (state, [throttle_for(cpmx_follower::LOW_SPEED_MPS), 0.0]);
        }
        // Curvature κ ≈ p4·δ'/p1 (the p2 term is second order for the lab's small servo moves).
        let effective = sample.curvature_per_m() * p[0] / p[3];
        let servo = (effective - p[8]).clamp(-1.0, 1.0);
        let speed = sample.speed_mps() / (p[0] * (1.0 + p[1] * effective * effective));
        let heading = sample.yaw_rad() - p[2] * effective - p[9];
        let state = [
            sample.position_m[0],
            sample.position_m[1],
            unwrap_near(heading, near[2]),
            speed,
        ];
        (state, [throttle_for(speed), servo])
    }

    fn input_limits(&self) -> InputLimits<2> {
        InputLimits {
            lower: [-1.0, -1.0],
            upper: [1.0, 1.0],
            max_rate_per_s: [f64::INFINITY, f64::INFINITY],
        }
    }

    fn stop_input(&self, _: &[f64; 4]) -> [f64; 2] {
        [0.0, 0.0]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cpmx_follower::{
        Follower, FollowerConfig, Mpc, MpcConfig, StateEstimate, Trajectory, TrajectoryCommand,
        TrajectoryPoint,
    };

    /// A straight run into a left arc of radius 0.525 m at 0.5 m/s, points every 0.1 s.
    fn left_turn() -> Vec<TrajectoryPoint> {
        let (speed, radius) = (0.5, 0.525);
        (0..80)
            .map(|k| {
                let t = k as f64 * 0.1;
                let s = speed * t;
                let (x, y, yaw) = if s < 1.0 {
                    (s, 0.0, 0.0)
                } else {
                    let a = (s - 1.0) / radius;
                    (1.0 + radius * a.sin(), radius * (1.0 - a.cos()), a)
                };
                TrajectoryPoint {
                    t_s: t,
                    x_m: x,
                    y_m: y,
                    vx_mps: speed * yaw.cos(),
                    vy_mps: speed * yaw.sin(),
                }
            })
            .collect()
    }

    #[test]
    fn the_grey_box_follower_tracks_a_left_turn() {
        let spec: GreyBoxModel = GreyBoxModel {
            parameters: cpmx_vehicle::LAB_GREYBOX_PARAMETERS,
            euler_step_s: 0.02,
            battery_voltage_v: 7.8,
        };
        let plant = GreyBoxPlant::new(&spec, VehicleParams::MU_CAR).unwrap();
        let mut follower = Follower::new(
            Mpc::new(
                plant.mpc_model(),
                MpcConfig {
                    delay_steps: 0,
                    ..MpcConfig::lab(plant.move_weights())
                },
            ),
            FollowerConfig::default(),
        );
        let points = left_turn();
        follower
            .receive(TrajectoryCommand {
                create_stamp_s: 0.0,
                valid_after_s: 0.0,
                trajectory: Trajectory::new(points.clone()).unwrap(),
            })
            .unwrap();
        let mut state = [0.0, 0.0, 0.0, 0.5];
        let mut worst: f64 = 0.0;
        for k in 0..300 {
            let t = k as f64 * 0.02;
            if k % 5 == 0 {
                let command = TrajectoryCommand {
                    create_stamp_s: t,
                    valid_after_s: t,
                    trajectory: Trajectory::new(points.clone()).unwrap(),
                };
                follower.receive(command).unwrap();
            }
            let out = follower.control(
                t,
                &StateEstimate {
                    state,
                    ips_update_age_s: 0.0,
                },
            );
            state = plant.step(&state, &out.input, 0.02).state;
            let reference = Trajectory::new(points.clone()).unwrap().sample(t + 0.02).unwrap();
            let err = (state[0] - reference.position_m[0]).hypot(state[1] - reference.position_m[1]);
            worst = worst.max(err);
        }
        assert!(worst < 0.03, "worst tracking error {worst} m");
    }
}
