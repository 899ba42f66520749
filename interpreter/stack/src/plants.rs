//! The plants of the twin engine: how a vehicle model is stepped, read and followed.
//! `KinematicPlant` (sim-mpc: the kinematic bicycle, MPC inputs = speed and steering commands)
//! and `GreyBoxPlant` (the twin: the lab's identified model, MPC inputs = throttle and
//! steering servo, as the µCar's own MPC).

use std::cell::Cell;

use cpmx_follower::{
    BicycleModel, HELD_TERMS, Held, InputLimits, MODEL_NUMBERS, Model, RealModel, StepJacobians,
    TrajectorySample, as_matrices, unwrap_near,
};
use cpmx_math::Real;
use cpmx_sensing::Pose2;
use cpmx_spec::model::GreyBoxModel;
use cpmx_vehicle::{GreyBoxParams, GreyBoxState, GreyBoxVehicle, KinematicBicycle, VehicleParams};

use crate::InitialState;

/// One 20 ms step of a plant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantStep<const NX: usize> {
    pub state: [f64; NX],
    /// Velocity in the map frame after the step [m/s].
    pub velocity_mps: [f64; 2],
    /// Distance the odometer counted during the step [m].
    pub odometer_increment_m: f64,
    /// The battery voltage the vehicle measures after the step [V], if it has a battery.
    pub battery_voltage_v: Option<f64>,
}

/// A vehicle model as the twin engine drives it.
pub trait Plant<const NX: usize, const NU: usize> {
    /// The model its MPC follower predicts with.
    type Model: RealModel<NX, NU> + Clone;

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
    /// The steering angle the vehicle reports for the follower's current `command` [rad]: the
    /// lab's `VehicleState.steering_servo` is the command the MPC has just computed, and the
    /// planner reads it as σ = σ_max · servo (the paper's §Observation).
    fn reported_steering_rad(&self, state: &[f64; NX], command: &[f64; NU]) -> f64;
    /// The velocity a run records [m/s]: the odometer speed along the bicycle's course
    /// ψ + β(σ) with the reported steering σ, the quantity the lab driver records from a
    /// `VehicleState` (`lab::mapping::recorded_sample`).
    fn recorded_velocity_mps(&self, state: &[f64; NX], steering_rad: f64) -> [f64; 2];
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
            battery_voltage_v: None,
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
    /// The steering command (the bicycle's analogue of the lab's servo command).
    fn reported_steering_rad(&self, _: &[f64; 5], command: &[f64; 2]) -> f64 {
        let max = self.model.params.max_steering_rad;
        command[1].clamp(-max, max)
    }
    fn recorded_velocity_mps(&self, state: &[f64; 5], steering_rad: f64) -> [f64; 2] {
        let mut state = BicycleModel::to_state(state);
        state.steering_rad = steering_rad;
        self.model.velocity_mps(&state)
    }
}

/// The lab's identified grey-box model under its MPC (the twin).
#[derive(Debug, Clone)]
pub struct GreyBoxPlant {
    model: GreyBoxMpcModel,
    vehicle: VehicleParams,
}

impl GreyBoxPlant {
    pub fn new(spec: &GreyBoxModel<f64>, vehicle: VehicleParams) -> Result<Self, String> {
        let params = GreyBoxParams {
            parameters: spec.parameters,
            euler_step_s: spec.euler_step_s,
            battery_voltage_v: spec.battery_voltage_v,
        };
        Ok(Self {
            model: GreyBoxMpcModel::new(params).map_err(|e| e.to_string())?,
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
                // The lab's simulated battery: V − 0.03·|v̇| (`SimulationVehicle.cxx`).
                battery_voltage_v: (dt_s > 0.0).then(|| {
                    grey_input.battery_voltage_v - 0.03 * ((out.state.speed_mps - state[3]) / dt_s).abs()
                }),
            },
            // The engine only asks for whole positive control periods; a refused step leaves
            // the car where it is rather than inventing motion.
            Err(_) => PlantStep {
                state: *state,
                velocity_mps: [0.0, 0.0],
                odometer_increment_m: 0.0,
                battery_voltage_v: None,
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
    /// σ = σ_max · servo, the servo command clipped to [-1, 1] as the lab's controller clips it
    /// (the paper's §Observation; `lab::mapping::policy_state` reads the lab's states so).
    fn reported_steering_rad(&self, _: &[f64; 4], command: &[f64; 2]) -> f64 {
        self.vehicle.max_steering_rad * command[1].clamp(-1.0, 1.0)
    }
    fn recorded_velocity_mps(&self, state: &[f64; 4], steering_rad: f64) -> [f64; 2] {
        KinematicBicycle::new(self.vehicle).velocity_mps(&cpmx_vehicle::BicycleState {
            x_m: state[0],
            y_m: state[1],
            yaw_rad: state[2],
            speed_mps: state[3],
            steering_rad,
        })
    }
}

/// Gain of the lab's stop signal on the measured speed [throttle per m/s].
pub const STOP_BRAKE_GAIN: f64 = 0.5;

/// The grey-box model as the MPC predicts with it: state `[x, y, yaw, speed]`, input
/// `[throttle, steering servo]`, one explicit Euler step per call whatever its length (the
/// lab's `VehicleModel::step`: 20 ms for the delay compensation, 50 ms per prediction step),
/// at the battery voltage the MPC's filter holds.
#[derive(Debug, Clone)]
pub struct GreyBoxMpcModel {
    model: GreyBoxVehicle,
    battery_voltage_v: f64,
    /// The last [`REMEMBERED_POWERS`] powers `|f|^p8` computed, by the bits of `|f|`, and the
    /// slot the next one goes to: the prediction holds each move for two steps, and the delay
    /// compensation steps through the last three inputs, two of which the decision before
    /// stepped through too (the same call, the same bits).
    powers: [Cell<(u64, f64)>; REMEMBERED_POWERS],
    next_power: Cell<usize>,
}

/// How many powers [`GreyBoxMpcModel`] remembers.
const REMEMBERED_POWERS: usize = 4;

impl GreyBoxMpcModel {
    /// The MPC model of a grey-box vehicle, predicting at its battery voltage until the MPC's
    /// filter says otherwise.
    pub fn new(params: GreyBoxParams) -> Result<Self, cpmx_vehicle::GreyBoxError> {
        Ok(Self {
            model: GreyBoxVehicle::new(params)?,
            battery_voltage_v: params.battery_voltage_v,
            powers: std::array::from_fn(|_| Cell::new((f64::NAN.to_bits(), f64::NAN))),
            next_power: Cell::new(0),
        })
    }
}

impl Held<f64> for GreyBoxMpcModel {
    /// `|throttle|^p8`, the motor term's magnitude, remembered from the calls before.
    #[inline(always)]
    fn power(&self, throttle_abs: f64, exponent: f64) -> f64 {
        let bits = throttle_abs.to_bits();
        if let Some(known) = self.powers.iter().find(|slot| slot.get().0 == bits) {
            return known.get().1;
        }
        let power = cpmx_math::pow(throttle_abs, exponent);
        let slot = self.next_power.get();
        self.powers[slot].set((bits, power));
        self.next_power.set((slot + 1) % REMEMBERED_POWERS);
        power
    }

    /// The grey-box car's step has no other held terms.
    #[inline(always)]
    fn remembered_terms(&self, _: f64) -> Option<[f64; HELD_TERMS]> {
        None
    }

    #[inline(always)]
    fn remember_terms(&self, _: f64, _: [f64; HELD_TERMS]) {}
}

impl Model<4, 2> for GreyBoxMpcModel {
    fn step(&self, state: &[f64; 4], input: &[f64; 2], dt_s: f64) -> [f64; 4] {
        let grey_input = cpmx_vehicle::GreyBoxInput {
            throttle: input[0],
            steering_servo: input[1],
            battery_voltage_v: self.battery_voltage_v,
        };
        // The car's own motor power (`GreyBoxVehicle::motor_power`), remembered.
        let power = self.power(input[0].clamp(-1.0, 1.0).abs(), self.model.params().parameters[7]);
        let out = self
            .model
            .euler_step_with_power(&grey_state(state), &grey_input, dt_s, power);
        [out.x_m, out.y_m, out.yaw_rad, out.speed_mps]
    }

    /// The Euler step's exact Jacobians ([`RealModel::predict`], with the last power
    /// remembered). Inlined into the gradient solver (called 120 times a decision).
    #[inline]
    fn step_jacobians(
        &self,
        state: &[f64; 4],
        input: &[f64; 2],
        h: f64,
    ) -> (
        [f64; 4],
        nalgebra::SMatrix<f64, 4, 4>,
        nalgebra::SMatrix<f64, 4, 2>,
    ) {
        as_matrices(Self::predict(&self.numbers(), state, input, h, self))
    }

    #[inline]
    fn position_jacobian(&self, _: &[f64; 4]) -> nalgebra::SMatrix<f64, 2, 4> {
        nalgebra::SMatrix::<f64, 2, 4>::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0)
    }

    fn set_battery_voltage_v(&mut self, voltage_v: f64) {
        if voltage_v.is_finite() && voltage_v > 0.0 {
            self.battery_voltage_v = voltage_v;
        }
    }

    #[inline]
    fn position_m(&self, state: &[f64; 4]) -> [f64; 2] {
        [state[0], state[1]]
    }

    /// Steady state along the reference: the servo whose curvature matches the reference's,
    /// and the throttle whose steady-state speed (v̇ = 0) is the reference speed.
    fn feedforward(&self, sample: &TrajectorySample, near: &[f64; 4]) -> ([f64; 4], [f64; 2]) {
        let p = &self.model.params().parameters;
        let voltage = self.battery_voltage_v;
        // Throttle whose steady-state speed is `speed`: 0 = p5·v + (p6 + p7·V)·sign(f)·|f|^p8.
        let motor = p[5] + p[6] * voltage;
        let throttle_for = |speed: f64| {
            if motor.abs() <= f64::EPSILON {
                return 0.0;
            }
            let ratio = -p[4] * speed / motor;
            (cpmx_math::pow(ratio.abs(), 1.0 / p[7]) * ratio.signum()).clamp(-1.0, 1.0)
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

    /// The lab's stop signals (`Controller::get_stop_signals`, `Controller.cxx:453-471`): a
    /// proportional brake on the measured speed, throttle = clip(0.5 · (0 − v), −1, 1), servo 0,
    /// clipped as the lab clips (`fmax(-1, fmin(1, ·))`, which takes a NaN to 1).
    #[allow(clippy::manual_clamp)] // `clamp` keeps a NaN, the lab's clip does not
    fn stop_input(&self, state: &[f64; 4]) -> [f64; 2] {
        [(STOP_BRAKE_GAIN * (0.0 - state[3])).min(1.0).max(-1.0), 0.0]
    }
}

/// Where the grey-box model's numbers sit: p1..p10, then the battery voltage.
const GREYBOX_VOLTAGE: usize = 10;

impl RealModel<4, 2> for GreyBoxMpcModel {
    fn numbers(&self) -> [f64; MODEL_NUMBERS] {
        let mut n = [0.0; MODEL_NUMBERS];
        n[..10].copy_from_slice(&self.model.params().parameters);
        n[GREYBOX_VOLTAGE] = self.battery_voltage_v;
        n
    }

    /// The Euler step's exact Jacobians (inputs inside [-1, 1], where the lab's solver keeps
    /// them; the motor term's slope `p8·|f|^(p8−1)` vanishes at f = 0 as CasADi's does).
    #[inline(always)]
    fn predict<T: Real>(
        p: &[T; MODEL_NUMBERS],
        state: &[T; 4],
        input: &[T; 2],
        h_s: f64,
        held: &impl Held<T>,
    ) -> StepJacobians<T, 4, 2> {
        let (zero, one, h) = (T::splat(0.0), T::splat(1.0), T::splat(h_s));
        let [x, y, yaw, v] = *state;
        let f = input[0].clamp(-one, one);
        let d = input[1].clamp(-one, one) + p[8];
        let gain = p[0] * (one + p[1] * d * d);
        let s = gain * v;
        let (sin, cos) = (yaw + p[2] * d + p[9]).sin_cos();
        let motor = p[5] + p[6] * p[GREYBOX_VOLTAGE];
        let magnitude = held.power(f.abs(), p[7]);
        let sign = T::select(f.ge(zero), one, -one);
        let next = [
            x + h * s * cos,
            y + h * s * sin,
            yaw + h * p[3] * v * d,
            v + h * (p[4] * v + motor * sign * magnitude),
        ];
        let a = [
            [one, zero, -h * s * sin, h * gain * cos],
            [zero, one, h * s * cos, h * gain * sin],
            [zero, zero, one, h * p[3] * d],
            [zero, zero, zero, one + h * p[4]],
        ];
        let ds = T::splat(2.0) * p[0] * p[1] * d * v;
        let motor_slope = T::select(f.eq(zero), zero, motor * p[7] * magnitude / f.abs());
        let b = [
            [zero, h * (ds * cos - s * sin * p[2])],
            [zero, h * (ds * sin + s * cos * p[2])],
            [zero, h * p[3] * v],
            [h * motor_slope, zero],
        ];
        (next, a, b)
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
        (0..80u64)
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
                    t_ns: k * 100_000_000,
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
        let spec: GreyBoxModel<f64> = GreyBoxModel {
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
        let mut state = [0.0, 0.0, 0.0, 0.5];
        let mut worst: f64 = 0.0;
        for k in 0..300u64 {
            let t_ns = k * 20_000_000;
            if k % 5 == 0 {
                let command = TrajectoryCommand {
                    create_stamp_ns: t_ns,
                    valid_after_ns: t_ns,
                    trajectory: Trajectory::new(points.clone()).unwrap(),
                };
                follower.receive(command);
            }
            let out = follower.control(
                t_ns,
                &StateEstimate {
                    state,
                    ips_update_age_ns: 0,
                },
            );
            state = plant.step(&state, &out.input, 0.02).state;
            let reference = Trajectory::new(points.clone())
                .unwrap()
                .sample(t_ns + 20_000_000)
                .unwrap();
            let err = (state[0] - reference.position_m[0]).hypot(state[1] - reference.position_m[1]);
            worst = worst.max(err);
        }
        assert!(worst < 0.03, "worst tracking error {worst} m");
    }

    /// The lab's stop signal (a P-brake on the measured speed) with the lab's 80 ms input
    /// delay stops a cruising car in the distances the review reproduced from the lab's code
    /// (6.2 / 11.0 / 15.9 cm from 0.25 / 0.5 / 0.8 m/s; coasting took 12.7 / 25.6 / 41.1 cm).
    #[test]
    fn the_lab_stop_signal_stops_in_the_labs_distances() {
        let spec = GreyBoxModel {
            parameters: cpmx_vehicle::LAB_GREYBOX_PARAMETERS,
            euler_step_s: 0.02,
            battery_voltage_v: 7.8,
        };
        let plant = GreyBoxPlant::new(&spec, VehicleParams::MU_CAR).unwrap();
        let model = plant.mpc_model();
        let p = cpmx_vehicle::LAB_GREYBOX_PARAMETERS;
        for (v0, expected_cm) in [(0.25, 6.2), (0.5, 11.0), (0.8, 15.9)] {
            // Cruising at v0: the delay line holds the steady-state throttle.
            let cruise = (-p[4] * v0 / (p[5] + p[6] * 7.8)).powf(1.0 / p[7]);
            let mut delay = cpmx_sensing::ActuationDelay::new(80.0, 0.02, [cruise, 0.0]).unwrap();
            let mut state = [0.0, 0.0, 0.0, v0];
            let mut distance_m = 0.0;
            let mut steps = 0;
            while state[3] >= 0.005 {
                let applied = delay.push(model.stop_input(&state));
                let step = plant.step(&state, &applied, 0.02);
                distance_m += step.odometer_increment_m;
                state = step.state;
                steps += 1;
                assert!(steps < 500, "the car does not stop from {v0} m/s");
            }
            let distance_cm = 100.0 * distance_m;
            assert!(
                (distance_cm - expected_cm).abs() < 0.1,
                "from {v0} m/s: {distance_cm:.2} cm, the lab {expected_cm} cm"
            );
        }
    }

    #[test]
    fn the_grey_box_jacobians_match_central_differences() {
        let spec = GreyBoxModel {
            parameters: cpmx_vehicle::LAB_GREYBOX_PARAMETERS,
            euler_step_s: 0.02,
            battery_voltage_v: 7.8,
        };
        let model = GreyBoxPlant::new(&spec, VehicleParams::MU_CAR)
            .unwrap()
            .mpc_model();
        for (x, u) in [
            ([0.3, -0.2, 0.7, 0.45], [0.2, -0.3]),
            ([1.0, 2.0, -2.0, 0.1], [-0.4, 0.6]),
        ] {
            let (next, a, b) = model.step_jacobians(&x, &u, 0.05);
            assert_eq!(next, model.step(&x, &u, 0.05));
            for col in 0..6 {
                let h = 1e-6;
                let (plus, minus) = if col < 4 {
                    let (mut p, mut m) = (x, x);
                    p[col] += h;
                    m[col] -= h;
                    (model.step(&p, &u, 0.05), model.step(&m, &u, 0.05))
                } else {
                    let (mut p, mut m) = (u, u);
                    p[col - 4] += h;
                    m[col - 4] -= h;
                    (model.step(&x, &p, 0.05), model.step(&x, &m, 0.05))
                };
                for row in 0..4 {
                    let numeric = (plus[row] - minus[row]) / (2.0 * h);
                    let exact = if col < 4 { a[(row, col)] } else { b[(row, col - 4)] };
                    assert!(
                        (exact - numeric).abs() < 1e-7,
                        "({row}, {col}): {exact} vs {numeric}"
                    );
                }
            }
        }
    }
}
