//! The float32 code path of the kinematic bicycle: SigmaRL's step with torch's operation
//! order, so that results agree with SigmaRL to within one float32 ulp.

use crate::{BicycleState, Command, StepOutput, VehicleParams};

/// Transcendental functions evaluated in f64 and rounded once to f32 (correctly rounded in
/// almost all cases; torch's SLEEF kernels are within 1 ulp of that).
fn tan(a: f32) -> f32 {
    f64::from(a).tan() as f32
}
fn atan(a: f32) -> f32 {
    f64::from(a).atan() as f32
}
fn cos(a: f32) -> f32 {
    f64::from(a).cos() as f32
}
fn sin(a: f32) -> f32 {
    f64::from(a).sin() as f32
}

/// One SigmaRL step in f32; inputs and outputs are widened f32 values.
pub(crate) fn step_f32(p: &VehicleParams, state: &BicycleState, command: Command, dt_s: f64) -> StepOutput {
    // Parameters as torch sees them: Python floats cast to the tensor dtype.
    let dt = dt_s as f32;
    let max_speed = p.max_speed_mps as f32;
    let max_steering = p.max_steering_rad as f32;
    let (min_accel, max_accel) = (p.accel_mps2.0 as f32, p.accel_mps2.1 as f32);
    let max_rate = p.max_steering_rate_rad_s as f32;
    let slip_ratio = (p.rear_axle_m / p.wheelbase_m) as f32;
    let wheelbase = p.wheelbase_m as f32;
    let (x, y, yaw) = (state.x_m as f32, state.y_m as f32, state.yaw_rad as f32);
    let (speed, steering) = (state.speed_mps as f32, state.steering_rad as f32);

    // Clamp the command, then turn it into constant inputs by a finite difference.
    let speed_cmd = (command.speed_mps as f32).clamp(-max_speed, max_speed);
    let steering_cmd = (command.steering_rad as f32).clamp(-max_steering, max_steering);
    let accel = ((speed_cmd - speed) / dt).clamp(min_accel, max_accel);
    let rate = ((steering_cmd - steering) / dt).clamp(-max_rate, max_rate);

    // Right-hand sides at the old state, then one explicit Euler step.
    let beta = atan(slip_ratio * tan(steering));
    let dx = speed * cos(yaw + beta);
    let dy = speed * sin(yaw + beta);
    let dyaw = (speed / wheelbase) * tan(steering) * cos(beta);
    let next_steering = steering + dt * rate;
    let next = [x + dt * dx, y + dt * dy, yaw + dt * dyaw, speed + dt * accel];

    // Steering wrap `((δ + π) mod 2π) − π`: in f32 this rounds δ to the grid around π.
    let pi = std::f32::consts::PI;
    let next_steering = (next_steering + pi).rem_euclid(2.0 * pi) - pi;

    // Velocity and slip of the new state.
    let beta1 = atan(slip_ratio * tan(next_steering));
    let course = next[2] + beta1;
    StepOutput {
        state: BicycleState {
            x_m: f64::from(next[0]),
            y_m: f64::from(next[1]),
            yaw_rad: f64::from(next[2]),
            speed_mps: f64::from(next[3]),
            steering_rad: f64::from(next_steering),
        },
        velocity_mps: [f64::from(next[3] * cos(course)), f64::from(next[3] * sin(course))],
        sideslip_rad: f64::from(beta1),
    }
}
