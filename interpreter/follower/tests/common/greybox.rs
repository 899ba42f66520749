//! The lab's grey-box model (`VehicleModel.cxx`) at the lab simulator's 7.8 V, implemented
//! here from the equations, as a [`Model`] for the tests.

use cpmx_follower::{InputLimits, Model, TrajectorySample, unwrap_near};

/// The identified parameters p₁…p₁₀ (`MpcController.hpp`).
const P: [f64; 10] = [
    1.004582, -0.142938, 0.195236, 3.560576, -2.190728, -9.726828, 2.515565, 1.321199, 0.032208, -0.012863,
];
/// Battery voltage of the lab's simulated vehicle [V].
const VOLTAGE_V: f64 = 7.8;

/// State `[px, py, ψ, v]`, input `[throttle, servo]`.
#[derive(Debug, Clone, Copy)]
pub struct GreyBox;

impl Model<4, 2> for GreyBox {
    fn step(&self, x: &[f64; 4], u: &[f64; 2], dt_s: f64) -> [f64; 4] {
        let [px, py, yaw, v] = *x;
        let d = u[1] + P[8];
        let s = P[0] * v * (1.0 + P[1] * d * d);
        let heading = yaw + P[2] * d + P[9];
        let motor = (P[5] + P[6] * VOLTAGE_V) * u[0].signum() * u[0].abs().powf(P[7]);
        [
            px + dt_s * s * heading.cos(),
            py + dt_s * s * heading.sin(),
            yaw + dt_s * P[3] * v * d,
            v + dt_s * (P[4] * v + motor),
        ]
    }
    fn position_m(&self, x: &[f64; 4]) -> [f64; 2] {
        [x[0], x[1]]
    }
    fn feedforward(&self, sample: &TrajectorySample, near: &[f64; 4]) -> ([f64; 4], [f64; 2]) {
        // κ = p₄δ'/(p₁(1 + p₂δ'²)), solved by two fixed-point steps; steady-state throttle.
        let kappa = sample.curvature_per_m();
        let mut d = kappa * P[0] / P[3];
        for _ in 0..2 {
            d = kappa * P[0] * (1.0 + P[1] * d * d) / P[3];
        }
        let v = sample.speed_mps() / (P[0] * (1.0 + P[1] * d * d));
        let yaw = unwrap_near(sample.yaw_rad() - P[2] * d - P[9], near[2]);
        let throttle = v.signum() * (-P[4] * v.abs() / (P[5] + P[6] * VOLTAGE_V)).powf(1.0 / P[7]);
        let [px, py] = sample.position_m;
        (
            [px, py, yaw, v],
            [throttle.clamp(-1.0, 1.0), (d - P[8]).clamp(-1.0, 1.0)],
        )
    }
    fn input_limits(&self) -> InputLimits<2> {
        InputLimits {
            lower: [-1.0; 2],
            upper: [1.0; 2],
            max_rate_per_s: [f64::INFINITY; 2],
        }
    }
    fn stop_input(&self, x: &[f64; 4]) -> [f64; 2] {
        [(-0.5 * x[3]).clamp(-1.0, 1.0), 0.0]
    }
}
