//! SigmaRL's kinematic bicycle (`KinematicBicycleModel` driven by `WorldCustom.step`):
//! commands become constant acceleration and steering rate over one step by a finite
//! difference, then one explicit Euler step with every right-hand side at the old state
//! (SigmaRL 1.5.0 on), or the motion integrated over the step ([`KinematicBicycle::step_rk4`],
//! as SigmaRL 1.4.0's dopri5 integrates it).

use crate::VehicleParams;

/// State of the kinematic bicycle. Yaw is never wrapped (it accumulates beyond ±π).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BicycleState {
    /// Centre of gravity, x [m].
    pub x_m: f64,
    /// Centre of gravity, y [m].
    pub y_m: f64,
    /// Heading [rad], not wrapped.
    pub yaw_rad: f64,
    /// Longitudinal speed [m/s] (negative when reversing).
    pub speed_mps: f64,
    /// Front steering angle [rad].
    pub steering_rad: f64,
}

/// A command: target speed and target steering angle.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Command {
    /// Target speed [m/s].
    pub speed_mps: f64,
    /// Target steering angle [rad].
    pub steering_rad: f64,
}

/// What one step yields besides the state: the velocity in the map frame and the slip angle,
/// both evaluated at the new state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepOutput {
    /// The new state.
    pub state: BicycleState,
    /// Velocity vector of the new state in the map frame [m/s].
    pub velocity_mps: [f64; 2],
    /// Slip angle of the new state [rad].
    pub sideslip_rad: f64,
}

/// The arithmetic of one step.
///
/// SigmaRL integrates in float32. [`Precision::F32`] repeats its operations in the same order
/// in f32 (true divisions by `dt`, clamps, `atan(l_r / l_wb * tan δ)`, one Euler step, the
/// steering wrap that rounds δ to the float32 grid around π); only the transcendental
/// functions differ (evaluated in f64 and rounded, where torch uses SLEEF), so results agree
/// with SigmaRL to within one float32 ulp. [`Precision::F64`] is the same model in f64 and
/// differs from SigmaRL by up to about 7e-7.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Precision {
    /// Plain f64 arithmetic (the project default).
    #[default]
    F64,
    /// float32 arithmetic in SigmaRL's operation order.
    F32,
}

/// The model with its parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KinematicBicycle {
    /// Geometry and limits.
    pub params: VehicleParams,
}

impl KinematicBicycle {
    /// A model with the given parameters.
    pub fn new(params: VehicleParams) -> Self {
        Self { params }
    }

    /// The command after SigmaRL's clamping to the speed and steering limits.
    pub fn clamp_command(&self, command: Command) -> Command {
        let p = &self.params;
        Command {
            speed_mps: command.speed_mps.clamp(-p.max_speed_mps, p.max_speed_mps),
            steering_rad: command
                .steering_rad
                .clamp(-p.max_steering_rad, p.max_steering_rad),
        }
    }

    /// Slip angle at the centre of gravity for a steering angle.
    pub fn sideslip_rad(&self, steering_rad: f64) -> f64 {
        (self.params.rear_axle_m / self.params.wheelbase_m * steering_rad.tan()).atan()
    }

    /// Velocity vector in the map frame of a state.
    pub fn velocity_mps(&self, state: &BicycleState) -> [f64; 2] {
        let heading = state.yaw_rad + self.sideslip_rad(state.steering_rad);
        [state.speed_mps * heading.cos(), state.speed_mps * heading.sin()]
    }

    /// One step of `dt_s` towards `command`, computed in f64 (what the project uses).
    pub fn step(&self, state: &BicycleState, command: Command, dt_s: f64) -> StepOutput {
        self.step_with_precision(state, command, dt_s, Precision::F64)
    }

    /// One step of `dt_s` towards `command` in the chosen arithmetic.
    pub fn step_with_precision(
        &self,
        state: &BicycleState,
        command: Command,
        dt_s: f64,
        precision: Precision,
    ) -> StepOutput {
        match precision {
            Precision::F64 => self.step_f64(state, command, dt_s),
            Precision::F32 => crate::bicycle_f32::step_f32(&self.params, state, command, dt_s),
        }
    }

    /// The command as constant acceleration [m/s²] and steering rate [rad/s] over a step of
    /// `dt_s`: finite differences to the clamped command, within the vehicle's limits.
    fn inputs(&self, state: &BicycleState, command: Command, dt_s: f64) -> (f64, f64) {
        let p = &self.params;
        let command = self.clamp_command(command);
        let accel = ((command.speed_mps - state.speed_mps) / dt_s).clamp(p.accel_mps2.0, p.accel_mps2.1);
        let steering_rate = ((command.steering_rad - state.steering_rad) / dt_s)
            .clamp(-p.max_steering_rate_rad_s, p.max_steering_rate_rad_s);
        (accel, steering_rate)
    }

    /// One step of `dt_s` towards `command` with the same inputs as [`KinematicBicycle::step`],
    /// the motion integrated over the step by classical Runge–Kutta in `substeps` substeps:
    /// SigmaRL 1.4.0 integrates it with dopri5 (its ITSC 2025 checkpoints drove that), which
    /// 5 substeps follow to about 1e-6 m. Unlike one Euler step, the step's acceleration and
    /// steering already move the car within the step.
    pub fn step_rk4(&self, state: &BicycleState, command: Command, dt_s: f64, substeps: u32) -> StepOutput {
        let p = &self.params;
        let (accel, steering_rate) = self.inputs(state, command, dt_s);
        let rate = |s: &[f64; 5]| -> [f64; 5] {
            let beta = self.sideslip_rad(s[4]);
            let heading = s[2] + beta;
            [
                s[3] * heading.cos(),
                s[3] * heading.sin(),
                s[3] / p.wheelbase_m * s[4].tan() * beta.cos(),
                accel,
                steering_rate,
            ]
        };
        let along =
            |s: &[f64; 5], k: &[f64; 5], h: f64| -> [f64; 5] { std::array::from_fn(|i| s[i] + h * k[i]) };
        let substeps = substeps.max(1);
        let h = dt_s / f64::from(substeps);
        let mut s = [
            state.x_m,
            state.y_m,
            state.yaw_rad,
            state.speed_mps,
            state.steering_rad,
        ];
        for _ in 0..substeps {
            let k1 = rate(&s);
            let k2 = rate(&along(&s, &k1, 0.5 * h));
            let k3 = rate(&along(&s, &k2, 0.5 * h));
            let k4 = rate(&along(&s, &k3, h));
            for i in 0..5 {
                s[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
            }
        }
        let next = BicycleState {
            x_m: s[0],
            y_m: s[1],
            yaw_rad: s[2],
            speed_mps: s[3],
            steering_rad: wrap_to_pi(s[4]),
        };
        StepOutput {
            velocity_mps: self.velocity_mps(&next),
            sideslip_rad: self.sideslip_rad(next.steering_rad),
            state: next,
        }
    }

    fn step_f64(&self, state: &BicycleState, command: Command, dt_s: f64) -> StepOutput {
        let p = &self.params;
        // Commands become constant inputs over the step.
        let (accel, steering_rate) = self.inputs(state, command, dt_s);

        // One explicit Euler step, right-hand sides at the old state.
        let beta = self.sideslip_rad(state.steering_rad);
        let heading = state.yaw_rad + beta;
        let yaw_rate = state.speed_mps / p.wheelbase_m * state.steering_rad.tan() * beta.cos();
        let steering = state.steering_rad + steering_rate * dt_s;
        let next = BicycleState {
            x_m: state.x_m + state.speed_mps * heading.cos() * dt_s,
            y_m: state.y_m + state.speed_mps * heading.sin() * dt_s,
            yaw_rad: state.yaw_rad + yaw_rate * dt_s,
            speed_mps: state.speed_mps + accel * dt_s,
            steering_rad: wrap_to_pi(steering),
        };
        StepOutput {
            velocity_mps: self.velocity_mps(&next),
            sideslip_rad: self.sideslip_rad(next.steering_rad),
            state: next,
        }
    }
}

/// `((a + π) mod 2π) − π` with a floored modulo, as torch computes it.
fn wrap_to_pi(angle_rad: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    (angle_rad + PI).rem_euclid(TAU) - PI
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn standing_start_reaches_half_a_metre_per_second_after_one_step() {
        let model = KinematicBicycle::new(VehicleParams::MU_CAR);
        let out = model.step(
            &BicycleState::default(),
            Command {
                speed_mps: 1.0,
                steering_rad: 0.0,
            },
            0.1,
        );
        assert_eq!(out.state.x_m, 0.0);
        assert!((out.state.speed_mps - 0.5).abs() < 1e-12);
    }

    #[test]
    fn integrated_over_the_step_the_car_moves_in_its_first_step_and_holds_a_circle() {
        let model = KinematicBicycle::new(VehicleParams::MU_CAR);
        let go = Command {
            speed_mps: 1.0,
            steering_rad: 0.0,
        };
        // From rest at 5 m/s² for 0.1 s: x = a·t²/2 (exact for Runge–Kutta), where one Euler
        // step leaves the car where it stood.
        let out = model.step_rk4(&BicycleState::default(), go, 0.1, 5);
        assert!((out.state.x_m - 0.025).abs() < 1e-15, "{}", out.state.x_m);
        assert!((out.state.speed_mps - 0.5).abs() < 1e-12);
        // At constant speed and steering the car drives a circle of radius L/(cos β·tan δ).
        let steering_rad = 0.3;
        let start = BicycleState {
            speed_mps: 0.5,
            steering_rad,
            ..Default::default()
        };
        let hold = Command {
            speed_mps: 0.5,
            steering_rad,
        };
        let p = VehicleParams::MU_CAR;
        let beta = model.sideslip_rad(steering_rad);
        let yaw_rate = 0.5 / p.wheelbase_m * steering_rad.tan() * beta.cos();
        let radius = 0.5 / yaw_rate;
        let mut state = start;
        for _ in 0..20 {
            state = model.step_rk4(&state, hold, 0.05, 5).state;
        }
        let (t, heading0) = (1.0, beta);
        let heading = heading0 + yaw_rate * t;
        let exact = [
            radius * (heading.sin() - heading0.sin()),
            radius * (heading0.cos() - heading.cos()),
        ];
        assert!(
            (state.x_m - exact[0]).abs() < 1e-9 && (state.y_m - exact[1]).abs() < 1e-9,
            "{state:?} {exact:?}"
        );
        assert!((state.yaw_rad - yaw_rate * t).abs() < 1e-12);
    }
}
