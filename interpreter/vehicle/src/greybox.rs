//! The CPM Lab's identified grey-box µCar (`mid_level_controller/src/VehicleModel.cxx`,
//! cpm-lab-interface.md §4): state `[px, py, ψ, v]`, inputs motor throttle `f`, steering servo
//! `δ` and battery voltage `V`, integrated by explicit Euler steps as the lab's simulated
//! vehicles do.
//!
//! This module owns the model equations, their integration and the ideal odometer and gyro
//! increments a step produces. It does not delay inputs, add sensor noise or estimate poses
//! (that is `cpmx-sensing`), and draws no random numbers.
//!
//! With `δ' = δ + p9`:
//!
//! ```text
//! ṗx = p1·v·(1 + p2·δ'²)·cos(ψ + p3·δ' + p10)
//! ṗy = p1·v·(1 + p2·δ'²)·sin(ψ + p3·δ' + p10)
//! ψ̇  = p4·v·δ'
//! v̇  = p5·v + (p6 + p7·V)·sign(f)·|f|^p8        (sign(0) = +1, as the lab's code)
//! ```

use thiserror::Error;

/// p1..p10 as hard-coded in the lab's `MpcController.hpp` and `SimulationVehicle.hpp`.
pub const LAB_GREYBOX_PARAMETERS: [f64; 10] = [
    1.004582, -0.142938, 0.195236, 3.560576, -2.190728, -9.726828, 2.515565, 1.321199, 0.032208, -0.012863,
];

/// Largest number of Euler substeps one [`GreyBoxVehicle::step`] may take.
pub const MAX_SUBSTEPS: u64 = 1_000_000;

/// Parameters of the grey-box model and its integration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GreyBoxParams {
    /// p1..p10 (index 0 holds p1).
    pub parameters: [f64; 10],
    /// Explicit Euler step [s] (the lab: 0.02).
    pub euler_step_s: f64,
    /// Battery voltage [V] that [`GreyBoxVehicle::input`] fills in (the lab's simulation: 7.8).
    pub battery_voltage_v: f64,
}

impl GreyBoxParams {
    /// The lab's simulated vehicle: identified parameters, 20 ms Euler step, 7.8 V.
    pub const LAB: GreyBoxParams = GreyBoxParams {
        parameters: LAB_GREYBOX_PARAMETERS,
        euler_step_s: 0.02,
        battery_voltage_v: 7.8,
    };
}

/// State of the grey-box model. Yaw is never wrapped.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GreyBoxState {
    /// Position (the IPS reference point), x [m].
    pub x_m: f64,
    /// Position, y [m].
    pub y_m: f64,
    /// Heading as the IPS measures it [rad], not wrapped.
    pub yaw_rad: f64,
    /// Odometer speed [m/s] (negative when reversing).
    pub speed_mps: f64,
}

/// Inputs of the model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GreyBoxInput {
    /// Motor throttle in [-1, 1] (1 full forward, 0 brake, -1 full reverse); clamped.
    pub throttle: f64,
    /// Steering servo command in [-1, 1] (1 full left); clamped. The offset p9 is added by
    /// the model.
    pub steering_servo: f64,
    /// Battery voltage [V].
    pub battery_voltage_v: f64,
}

/// Right-hand side of the model at a state and input.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GreyBoxDerivative {
    /// ṗx [m/s].
    pub x_mps: f64,
    /// ṗy [m/s].
    pub y_mps: f64,
    /// ψ̇ [rad/s].
    pub yaw_rate_rad_s: f64,
    /// v̇ [m/s²].
    pub accel_mps2: f64,
}

/// What [`GreyBoxVehicle::step`] yields.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GreyBoxStep {
    /// The new state.
    pub state: GreyBoxState,
    /// Velocity of the new state in the map frame [m/s] (direction ψ + p3·δ' + p10, magnitude
    /// p1·v·(1 + p2·δ'²), with the step's steering input), for recordings.
    pub velocity_mps: [f64; 2],
    /// Distance the odometer counted over the step [m]: Σ h·v after each substep, as the lab's
    /// simulated odometer integrates.
    pub odometer_increment_m: f64,
    /// Yaw change an ideal gyro integrated over the step [rad]: Σ h·ψ̇ at each substep's start
    /// (equals the change of `yaw_rad`).
    pub yaw_increment_rad: f64,
}

/// Invalid model parameters or step durations.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum GreyBoxError {
    /// A parameter p1..p10 is not finite.
    #[error("grey-box parameter p{number} = {value} is not finite")]
    Parameter {
        /// 1-based parameter number.
        number: usize,
        /// The value given.
        value: f64,
    },
    /// The Euler step is not a positive finite number.
    #[error("Euler step {euler_step_s} s must be positive and finite")]
    EulerStep {
        /// The value given [s].
        euler_step_s: f64,
    },
    /// The battery voltage is not a positive finite number.
    #[error("battery voltage {battery_voltage_v} V must be positive and finite")]
    BatteryVoltage {
        /// The value given [V].
        battery_voltage_v: f64,
    },
    /// A step duration is negative, not finite, or needs too many substeps.
    #[error("step of {dt_s} s must be finite, non-negative and at most {MAX_SUBSTEPS} Euler steps")]
    Duration {
        /// The value given [s].
        dt_s: f64,
    },
}

/// The grey-box µCar with validated parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GreyBoxVehicle {
    params: GreyBoxParams,
}

impl GreyBoxVehicle {
    /// A model; parameters must be finite, the Euler step and the voltage positive.
    pub fn new(params: GreyBoxParams) -> Result<Self, GreyBoxError> {
        if let Some((index, &value)) = params.parameters.iter().enumerate().find(|(_, p)| !p.is_finite()) {
            return Err(GreyBoxError::Parameter {
                number: index + 1,
                value,
            });
        }
        if !(params.euler_step_s.is_finite() && params.euler_step_s > 0.0) {
            return Err(GreyBoxError::EulerStep {
                euler_step_s: params.euler_step_s,
            });
        }
        if !(params.battery_voltage_v.is_finite() && params.battery_voltage_v > 0.0) {
            return Err(GreyBoxError::BatteryVoltage {
                battery_voltage_v: params.battery_voltage_v,
            });
        }
        Ok(Self { params })
    }

    /// The parameters.
    pub fn params(&self) -> &GreyBoxParams {
        &self.params
    }

    /// An input at the model's battery voltage.
    pub fn input(&self, throttle: f64, steering_servo: f64) -> GreyBoxInput {
        GreyBoxInput {
            throttle,
            steering_servo,
            battery_voltage_v: self.params.battery_voltage_v,
        }
    }

    /// The effective steering δ' = clamp(δ, -1, 1) + p9.
    pub fn effective_steering(&self, steering_servo: f64) -> f64 {
        steering_servo.clamp(-1.0, 1.0) + self.params.parameters[8]
    }

    /// Velocity of `state` in the map frame [m/s] under a steering servo command.
    pub fn velocity_mps(&self, state: &GreyBoxState, steering_servo: f64) -> [f64; 2] {
        let p = &self.params.parameters;
        let delta = self.effective_steering(steering_servo);
        let speed = p[0] * state.speed_mps * (1.0 + p[1] * delta * delta);
        let (sin, cos) = cpmx_math::sin_cos(state.yaw_rad + p[2] * delta + p[9]);
        [speed * cos, speed * sin]
    }

    /// The motor term's magnitude `|f|^p8` for a throttle command (clamped to [-1, 1]): the
    /// costliest number of a step, and the same for every step under the same throttle.
    pub fn motor_power(&self, throttle: f64) -> f64 {
        cpmx_math::pow(throttle.clamp(-1.0, 1.0).abs(), self.params.parameters[7])
    }

    /// The right-hand side of the model (inputs clamped to [-1, 1], as the lab's controller
    /// clips its outputs before the plant sees them).
    pub fn derivative(&self, state: &GreyBoxState, input: &GreyBoxInput) -> GreyBoxDerivative {
        self.derivative_with_power(state, input, self.motor_power(input.throttle))
    }

    /// [`GreyBoxVehicle::derivative`] with the input's [`GreyBoxVehicle::motor_power`]
    /// computed by the caller (once for several steps under one throttle).
    pub fn derivative_with_power(
        &self,
        state: &GreyBoxState,
        input: &GreyBoxInput,
        motor_power: f64,
    ) -> GreyBoxDerivative {
        let p = &self.params.parameters;
        let delta = self.effective_steering(input.steering_servo);
        let throttle = input.throttle.clamp(-1.0, 1.0);
        let sign = if throttle >= 0.0 { 1.0 } else { -1.0 };
        let [x_mps, y_mps] = self.velocity_mps(state, input.steering_servo);
        GreyBoxDerivative {
            x_mps,
            y_mps,
            yaw_rate_rad_s: p[3] * state.speed_mps * delta,
            accel_mps2: p[4] * state.speed_mps + (p[5] + p[6] * input.battery_voltage_v) * sign * motor_power,
        }
    }

    /// One explicit Euler step of `h_s` (the lab's `VehicleModel::step`; the MPC predicts
    /// with single steps of 50 ms).
    pub fn euler_step(&self, state: &GreyBoxState, input: &GreyBoxInput, h_s: f64) -> GreyBoxState {
        self.euler_step_with_power(state, input, h_s, self.motor_power(input.throttle))
    }

    /// [`GreyBoxVehicle::euler_step`] with the input's [`GreyBoxVehicle::motor_power`]
    /// computed by the caller.
    pub fn euler_step_with_power(
        &self,
        state: &GreyBoxState,
        input: &GreyBoxInput,
        h_s: f64,
        motor_power: f64,
    ) -> GreyBoxState {
        let d = self.derivative_with_power(state, input, motor_power);
        GreyBoxState {
            x_m: state.x_m + h_s * d.x_mps,
            y_m: state.y_m + h_s * d.y_mps,
            yaw_rad: state.yaw_rad + h_s * d.yaw_rate_rad_s,
            speed_mps: state.speed_mps + h_s * d.accel_mps2,
        }
    }

    /// Advance `dt_s` under a constant input: whole Euler steps of `euler_step_s`, then one
    /// shorter step for any remainder (a remainder below 1e-9 of the Euler step is dropped, so
    /// that 0.1 s at 0.02 s is exactly five steps).
    pub fn step(
        &self,
        state: &GreyBoxState,
        input: &GreyBoxInput,
        dt_s: f64,
    ) -> Result<GreyBoxStep, GreyBoxError> {
        let h_s = self.params.euler_step_s;
        let ratio = dt_s / h_s;
        if !(dt_s.is_finite() && dt_s >= 0.0 && ratio <= MAX_SUBSTEPS as f64) {
            return Err(GreyBoxError::Duration { dt_s });
        }

        // Split the duration into whole Euler steps and a remainder.
        let tolerance = 1e-9;
        let whole = (ratio + tolerance).floor();
        let remainder_s = (ratio - whole) * h_s;
        let substeps = (0..whole as u64)
            .map(|_| h_s)
            .chain((remainder_s > tolerance * h_s).then_some(remainder_s));

        // Integrate, counting what the odometer and an ideal gyro see.
        let mut next = *state;
        let mut odometer_increment_m = 0.0;
        let motor_power = self.motor_power(input.throttle);
        for sub_s in substeps {
            next = self.euler_step_with_power(&next, input, sub_s, motor_power);
            odometer_increment_m += sub_s * next.speed_mps;
        }
        Ok(GreyBoxStep {
            velocity_mps: self.velocity_mps(&next, input.steering_servo),
            yaw_increment_rad: next.yaw_rad - state.yaw_rad,
            odometer_increment_m,
            state: next,
        })
    }

    /// Speed the model settles at under constant throttle and voltage [m/s]:
    /// `-(p6 + p7·V)·sign(f)·|f|^p8 / p5`.
    pub fn steady_state_speed_mps(&self, throttle: f64, battery_voltage_v: f64) -> f64 {
        let state = GreyBoxState::default();
        let input = GreyBoxInput {
            throttle,
            steering_servo: 0.0,
            battery_voltage_v,
        };
        -self.derivative(&state, &input).accel_mps2 / self.params.parameters[4]
    }
}

#[cfg(test)]
#[path = "greybox_tests.rs"]
mod tests;
