//! The plant models the MPC predicts with: a [`Model`] trait over fixed-size state and
//! input arrays, and its implementation for the kinematic bicycle of `cpmx-vehicle`.
//!
//! This module owns how a model is seen by the controller (one discrete step, the tracked
//! point, a feed-forward from the reference, limits, the stop input). It never solves
//! anything and never decides whether a trajectory is acceptable.
//!
//! An adapter for the lab's grey-box model (§4: state `[px, py, ψ, v]`, inputs
//! `[throttle, servo]`) implements `step` with the four Euler equations, `position_m` as
//! `[px, py]`, `feedforward` by inverting the steady state (servo from curvature, throttle
//! from speed), limits `[-1, 1]` without rate limits and the lab's stop signals
//! (`throttle = clamp(−0.5·v)`, servo 0); the tests of `mpc.rs` contain one.

use cpmx_math::Real;
use cpmx_vehicle::{BicycleState, Command, KinematicBicycle};
use nalgebra::SMatrix;

use crate::gradient::StepJacobians;

use crate::trajectory::TrajectorySample;

/// Bounds on the inputs; a rate limit of `f64::INFINITY` adds no constraint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InputLimits<const NU: usize> {
    /// Lower bound of each input.
    pub lower: [f64; NU],
    /// Upper bound of each input.
    pub upper: [f64; NU],
    /// Largest change of each input per second.
    pub max_rate_per_s: [f64; NU],
}

/// A discrete-time plant model with `NX` states and `NU` inputs.
pub trait Model<const NX: usize, const NU: usize> {
    /// The state after holding `input` for `dt_s` from `state`.
    fn step(&self, state: &[f64; NX], input: &[f64; NU], dt_s: f64) -> [f64; NX];

    /// Map-frame position of the point the trajectory refers to [m].
    fn position_m(&self, state: &[f64; NX]) -> [f64; 2];

    /// A state and an input that follow `sample` (the linearisation point); angles are
    /// unwrapped to lie within π of the same entries of `near`.
    fn feedforward(&self, sample: &TrajectorySample, near: &[f64; NX]) -> ([f64; NX], [f64; NU]);

    /// Input bounds and rate limits.
    fn input_limits(&self) -> InputLimits<NU>;

    /// The input that brings the vehicle to a halt from `state` (the lab's stop signals): what
    /// the follower applies when it stops, and what the MPC shifts into its input history after
    /// a large objective.
    fn stop_input(&self, state: &[f64; NX]) -> [f64; NU];

    /// [`Model::step`] with its Jacobians `∂x⁺/∂x` and `∂x⁺/∂u`; by default central
    /// differences (models override it with exact derivatives where speed matters).
    fn step_jacobians(
        &self,
        state: &[f64; NX],
        input: &[f64; NU],
        dt_s: f64,
    ) -> ([f64; NX], SMatrix<f64, NX, NX>, SMatrix<f64, NX, NU>) {
        let (a, b) = jacobians(self, state, input, dt_s);
        (self.step(state, input, dt_s), a, b)
    }

    /// `∂position/∂x`; by default central differences.
    fn position_jacobian(&self, state: &[f64; NX]) -> SMatrix<f64, 2, NX> {
        position_jacobian(self, state)
    }

    /// The measured battery voltage (low-pass filtered by the MPC) the model predicts with,
    /// for models whose motor depends on it; others ignore it.
    fn set_battery_voltage_v(&mut self, _voltage_v: f64) {}
}

/// Room for the numbers a model's prediction reads besides state and input (its parameters,
/// the battery voltage): [`RealModel::numbers`].
pub const MODEL_NUMBERS: usize = 12;

/// A model whose step and Jacobians are written once over [`Real`], so that the lab's solver
/// runs one vehicle's problem on `f64` and several side by side in lanes with the same
/// operations (`lanes.rs`). Its tracked point is the state's first two entries.
pub trait RealModel<const NX: usize, const NU: usize>: Model<NX, NU> {
    /// The numbers [`RealModel::predict`] reads (unused entries 0).
    fn numbers(&self) -> [f64; MODEL_NUMBERS];

    /// The state after holding `input` for `h_s` from `state`, with its Jacobians, for the
    /// numbers `n`; what it computes from held inputs it asks `held` for (computed, or
    /// remembered from the call before).
    fn predict<T: Real>(
        n: &[T; MODEL_NUMBERS],
        state: &[T; NX],
        input: &[T; NU],
        h_s: f64,
        held: &impl Held<T>,
    ) -> StepJacobians<T, NX, NU>;
}

/// Values a model's step computes from an input the prediction holds for two steps (each move
/// is held for two prediction steps, so every second call sees the same value and, remembered,
/// gets the same bits without the work): `x^y` (the grey-box car's motor term of its
/// throttle) and [`HELD_TERMS`] terms of one held value (the bicycle's of its steering angle,
/// the clamped steering input of the step before). Computed each time ([`Computed`]) or
/// remembered from the call before. A trait rather than closures kept by the caller, so that
/// it is inlined into the step, also in lanes.
pub trait Held<T> {
    /// `x^y` ([`cpmx_math::pow`]).
    fn power(&self, x: T, y: T) -> T;

    /// The terms last remembered, if they were computed from `x` (the same bits). The terms
    /// depend on `x` and the model's numbers alone, which are fixed for a solve.
    fn remembered_terms(&self, x: T) -> Option<[T; HELD_TERMS]>;

    /// Remembers `terms`, computed from `x`.
    fn remember_terms(&self, x: T, terms: [T; HELD_TERMS]);
}

/// The number of terms [`Held::remembered_terms`] keeps.
pub const HELD_TERMS: usize = 6;

/// Held values computed each time.
#[derive(Debug, Clone, Copy, Default)]
pub struct Computed;

impl<T: Real> Held<T> for Computed {
    #[inline(always)]
    fn power(&self, x: T, y: T) -> T {
        x.pow(y)
    }

    #[inline(always)]
    fn remembered_terms(&self, _: T) -> Option<[T; HELD_TERMS]> {
        None
    }

    #[inline(always)]
    fn remember_terms(&self, _: T, _: [T; HELD_TERMS]) {}
}

/// `predict`'s Jacobians as nalgebra's matrices (for [`Model::step_jacobians`]).
pub fn as_matrices<const NX: usize, const NU: usize>(
    (next, a, b): StepJacobians<f64, NX, NU>,
) -> ([f64; NX], SMatrix<f64, NX, NX>, SMatrix<f64, NX, NU>) {
    (
        next,
        SMatrix::from_fn(|r, c| a[r][c]),
        SMatrix::from_fn(|r, c| b[r][c]),
    )
}

/// Finite-difference step used for Jacobians (relative to the magnitude of the entry).
const FD_STEP: f64 = 1e-6;

/// `∂step/∂x` and `∂step/∂u` at `(x, u)` by central differences.
pub(crate) fn jacobians<M: Model<NX, NU> + ?Sized, const NX: usize, const NU: usize>(
    model: &M,
    x: &[f64; NX],
    u: &[f64; NU],
    dt_s: f64,
) -> (SMatrix<f64, NX, NX>, SMatrix<f64, NX, NU>) {
    let mut a = SMatrix::<f64, NX, NX>::zeros();
    let mut b = SMatrix::<f64, NX, NU>::zeros();
    for col in 0..NX {
        let h = FD_STEP * x[col].abs().max(1.0);
        let (mut plus, mut minus) = (*x, *x);
        plus[col] += h;
        minus[col] -= h;
        let (fp, fm) = (model.step(&plus, u, dt_s), model.step(&minus, u, dt_s));
        for row in 0..NX {
            a[(row, col)] = (fp[row] - fm[row]) / (2.0 * h);
        }
    }
    for col in 0..NU {
        let h = FD_STEP * u[col].abs().max(1.0);
        let (mut plus, mut minus) = (*u, *u);
        plus[col] += h;
        minus[col] -= h;
        let (fp, fm) = (model.step(x, &plus, dt_s), model.step(x, &minus, dt_s));
        for row in 0..NX {
            b[(row, col)] = (fp[row] - fm[row]) / (2.0 * h);
        }
    }
    (a, b)
}

/// `∂position/∂x` by central differences.
pub(crate) fn position_jacobian<M: Model<NX, NU> + ?Sized, const NX: usize, const NU: usize>(
    model: &M,
    x: &[f64; NX],
) -> SMatrix<f64, 2, NX> {
    let mut c = SMatrix::<f64, 2, NX>::zeros();
    for col in 0..NX {
        let h = FD_STEP * x[col].abs().max(1.0);
        let (mut plus, mut minus) = (*x, *x);
        plus[col] += h;
        minus[col] -= h;
        let (pp, pm) = (model.position_m(&plus), model.position_m(&minus));
        for row in 0..2 {
            c[(row, col)] = (pp[row] - pm[row]) / (2.0 * h);
        }
    }
    c
}

/// Below this reference speed [m/s] a model's feed-forward keeps the car's own heading and
/// steering: the reference's direction and curvature are not defined well enough there.
pub const LOW_SPEED_MPS: f64 = 0.05;

/// `near + wrap(angle − near)`: the representative of `angle_rad` closest to `near_rad`.
pub fn unwrap_near(angle_rad: f64, near_rad: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    near_rad + (angle_rad - near_rad + PI).rem_euclid(TAU) - PI
}

/// The kinematic bicycle as an MPC model: state `[x, y, yaw, speed, steering]` (centre of
/// gravity), input `[speed command, steering command]` ([`Command`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BicycleModel {
    /// The vehicle model (its parameters give the limits).
    pub bicycle: KinematicBicycle,
}

impl BicycleModel {
    /// Index of the state array as a [`BicycleState`].
    pub fn to_state(state: &[f64; 5]) -> BicycleState {
        BicycleState {
            x_m: state[0],
            y_m: state[1],
            yaw_rad: state[2],
            speed_mps: state[3],
            steering_rad: state[4],
        }
    }

    /// A [`BicycleState`] as the state array.
    pub fn from_state(state: &BicycleState) -> [f64; 5] {
        [
            state.x_m,
            state.y_m,
            state.yaw_rad,
            state.speed_mps,
            state.steering_rad,
        ]
    }

    /// The input array as a [`Command`].
    pub fn to_command(input: &[f64; 2]) -> Command {
        Command {
            speed_mps: input[0],
            steering_rad: input[1],
        }
    }
}

impl Model<5, 2> for BicycleModel {
    /// The prediction reaches the commanded speed and steering within the step: the plant's
    /// acceleration and steering-rate clamps are left out, because a clamp that saturates
    /// makes the linearisation say the input has no effect (and the planner's trajectories
    /// steer at exactly the rate limit). The QP's rate constraints keep the moves feasible
    /// instead. The step of [`Model::step_jacobians`], so that the MPC predicts with one
    /// formula (and cpmx-math's functions, as the whole follower).
    fn step(&self, state: &[f64; 5], input: &[f64; 2], dt_s: f64) -> [f64; 5] {
        self.step_jacobians(state, input, dt_s).0
    }

    fn position_m(&self, state: &[f64; 5]) -> [f64; 2] {
        [state[0], state[1]]
    }

    fn feedforward(&self, sample: &TrajectorySample, near: &[f64; 5]) -> ([f64; 5], [f64; 2]) {
        let p = &self.bicycle.params;
        let speed = sample.speed_mps();

        // Near standstill the reference's direction and curvature are interpolation noise
        // (curvature divides by |v|³): keep the car's own heading and steering there.
        if speed < LOW_SPEED_MPS {
            let [x, y] = sample.position_m;
            return ([x, y, near[2], speed, near[4]], [speed, near[4]]);
        }

        // Path curvature at the centre of gravity is cos β·tan δ / L with tan β = l_r/L·tan δ,
        // hence tan δ = κL / sqrt(1 − (κ l_r)²).
        let kappa_lr = (sample.curvature_per_m() * p.rear_axle_m).clamp(-0.99, 0.99);
        let tan_delta = sample.curvature_per_m() * p.wheelbase_m / (1.0 - kappa_lr * kappa_lr).sqrt();
        let steering = cpmx_math::atan(tan_delta).clamp(-p.max_steering_rad, p.max_steering_rad);

        // The velocity points along yaw + β, β = atan(l_r/L·tan δ).
        let sideslip = cpmx_math::atan(p.rear_axle_m / p.wheelbase_m * cpmx_math::tan(steering));
        let yaw = unwrap_near(sample.yaw_rad() - sideslip, near[2]);
        let [x, y] = sample.position_m;
        ([x, y, yaw, speed, steering], [speed, steering])
    }

    fn input_limits(&self) -> InputLimits<2> {
        let p = &self.bicycle.params;
        InputLimits {
            lower: [-p.max_speed_mps, -p.max_steering_rad],
            upper: [p.max_speed_mps, p.max_steering_rad],
            max_rate_per_s: [p.accel_mps2.1.max(-p.accel_mps2.0), p.max_steering_rate_rad_s],
        }
    }

    fn stop_input(&self, _state: &[f64; 5]) -> [f64; 2] {
        [0.0, 0.0]
    }

    /// Exact Jacobians of [`Model::step`]: the speed and steering become the (clamped)
    /// commands, the pose moves by one Euler step at the old state ([`RealModel::predict`]).
    fn step_jacobians(
        &self,
        state: &[f64; 5],
        input: &[f64; 2],
        h: f64,
    ) -> ([f64; 5], SMatrix<f64, 5, 5>, SMatrix<f64, 5, 2>) {
        as_matrices(Self::predict(&self.numbers(), state, input, h, &Computed))
    }

    fn position_jacobian(&self, _: &[f64; 5]) -> SMatrix<f64, 2, 5> {
        SMatrix::<f64, 2, 5>::new(1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    }
}

/// The bicycle's numbers: l_r/L, L, the largest speed and steering.
const BICYCLE_REAR_RATIO: usize = 0;
const BICYCLE_WHEELBASE: usize = 1;
const BICYCLE_MAX_SPEED: usize = 2;
const BICYCLE_MAX_STEERING: usize = 3;

impl RealModel<5, 2> for BicycleModel {
    fn numbers(&self) -> [f64; MODEL_NUMBERS] {
        let p = &self.bicycle.params;
        let mut n = [0.0; MODEL_NUMBERS];
        n[BICYCLE_REAR_RATIO] = p.rear_axle_m / p.wheelbase_m;
        n[BICYCLE_WHEELBASE] = p.wheelbase_m;
        n[BICYCLE_MAX_SPEED] = p.max_speed_mps;
        n[BICYCLE_MAX_STEERING] = p.max_steering_rad;
        n
    }

    #[inline(always)]
    fn predict<T: Real>(
        n: &[T; MODEL_NUMBERS],
        state: &[T; 5],
        input: &[T; 2],
        h_s: f64,
        held: &impl Held<T>,
    ) -> StepJacobians<T, 5, 2> {
        let (zero, one, h) = (T::splat(0.0), T::splat(1.0), T::splat(h_s));
        let (k, wheelbase) = (n[BICYCLE_REAR_RATIO], n[BICYCLE_WHEELBASE]);
        let (max_speed, max_steering) = (n[BICYCLE_MAX_SPEED], n[BICYCLE_MAX_STEERING]);
        let [x, y, yaw, v, delta] = *state;
        // The steering angle's terms: after the first step it is the steering input held for
        // two steps, so every second step's are the step's before.
        let [tan, sec2, beta, dbeta, sin_b, cos_b] = match held.remembered_terms(delta) {
            Some(terms) => terms,
            None => {
                let tan = delta.tan();
                let sec2 = one + tan * tan;
                let beta = (k * tan).atan();
                let dbeta = k * sec2 / (one + k * k * tan * tan);
                let (sin_b, cos_b) = beta.sin_cos();
                let terms = [tan, sec2, beta, dbeta, sin_b, cos_b];
                held.remember_terms(delta, terms);
                terms
            }
        };
        let (sin, cos) = (yaw + beta).sin_cos();
        let mut a = [[zero; 5]; 5];
        a[0][0] = one;
        a[0][2] = -h * v * sin;
        a[0][3] = h * cos;
        a[0][4] = -h * v * sin * dbeta;
        a[1][1] = one;
        a[1][2] = h * v * cos;
        a[1][3] = h * sin;
        a[1][4] = h * v * cos * dbeta;
        a[2][2] = one;
        a[2][3] = h / wheelbase * tan * cos_b;
        a[2][4] = h * v / wheelbase * (sec2 * cos_b - tan * sin_b * dbeta);
        let inside = |u: T, limit: T| T::select(u.abs().lt(limit), one, zero);
        let mut b = [[zero; 2]; 5];
        b[3][0] = inside(input[0], max_speed);
        b[4][1] = inside(input[1], max_steering);
        // The step itself, from the same trigonometry (what [`Model::step`] returns).
        let next = [
            x + h * v * cos,
            y + h * v * sin,
            yaw + h * v / wheelbase * tan * cos_b,
            input[0].clamp(-max_speed, max_speed),
            input[1].clamp(-max_steering, max_steering),
        ];
        (next, a, b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use cpmx_vehicle::VehicleParams;

    #[test]
    fn unwrap_near_picks_the_closest_turn() {
        use std::f64::consts::PI;
        assert_relative_eq!(
            unwrap_near(-PI + 0.1, 3.0 * PI - 0.1),
            3.0 * PI + 0.1,
            epsilon = 1e-12
        );
        assert_relative_eq!(unwrap_near(0.2, 0.0), 0.2, epsilon = 1e-15);
    }

    #[test]
    fn feedforward_holds_a_circle() {
        // Driving the feed-forward of a circle keeps curvature 1/r.
        let model = BicycleModel {
            bicycle: KinematicBicycle::new(VehicleParams::MU_CAR),
        };
        let (r, v) = (0.6, 0.5);
        let sample = TrajectorySample {
            t_ns: 0,
            position_m: [r, 0.0],
            velocity_mps: [0.0, v],
            acceleration_mps2: [-v * v / r, 0.0],
        };
        let (state, input) = model.feedforward(&sample, &[0.0; 5]);
        let next = model.step(&state, &input, 0.001);
        let yaw_rate = (next[2] - state[2]) / 0.001;
        assert_relative_eq!(yaw_rate, v / r, max_relative = 1e-9);
        let [vx, vy] = model.bicycle.velocity_mps(&BicycleModel::to_state(&state));
        assert_relative_eq!(vx, 0.0, epsilon = 1e-12);
        assert_relative_eq!(vy, v, epsilon = 1e-12);
    }

    #[test]
    fn exact_jacobians_match_central_differences() {
        let model = BicycleModel {
            bicycle: KinematicBicycle::new(VehicleParams::MU_CAR),
        };
        let (x, u) = ([0.3, -0.2, 0.7, 0.45, 0.2], [0.5, -0.1]);
        let (next, a, b) = model.step_jacobians(&x, &u, 0.05);
        let (fd_a, fd_b) = jacobians(&model, &x, &u, 0.05);
        let step = model.step(&x, &u, 0.05);
        assert!(
            next.iter().zip(&step).all(|(a, b)| (a - b).abs() < 1e-12),
            "{next:?} vs {step:?}"
        );
        assert!((a - fd_a).abs().max() < 1e-7, "{a} vs {fd_a}");
        assert!((b - fd_b).abs().max() < 1e-7, "{b} vs {fd_b}");
    }
}
