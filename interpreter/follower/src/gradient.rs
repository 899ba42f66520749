//! The CPM Lab's own MPC solver (`MpcController.cxx:207-250`, `MpcController.m:25-71`, the
//! CasADi-generated `casadi_mpc_fn.c`): 20 steps of gradient descent with momentum on the
//! nonlinear prediction, learning rate 0.4, momentum 0.6, the inputs clipped to their bounds at
//! the start of every step, warm-started (unshifted) from the previous control period and reset
//! to 1e-12 after any of the MPC's rejections (not after the controller's own stops, which do not
//! call the MPC; `mpc.rs`).
//!
//! One step, with `u` the clipped iterate and `M` the momentum:
//! `J, g = objective(u), ∇J(u)`; `M ← 0.6·M − g`; `u_next ← u + 0.4·M`. The objective the lab
//! checks against 1.5 is the 20th step's `J` (at its `u`, before the update); the input applied
//! is the first move of the last `u_next`, clipped.
//!
//! The gradient is exact (reverse mode through the rollout, with the model's step Jacobians),
//! as CasADi's symbolic gradient is. This module owns the iteration and the gradient; the
//! reference window, the rejection rules and the history are `mpc.rs`'s.
//!
//! The solver is written once over [`Real`]: on `f64` for one vehicle, through a [`Prediction`]
//! of its model ([`ScalarPrediction`] for any [`Model`]), and the same operations in the same
//! order for several problems side by side in [`cpmx_math::Lanes`].

use cpmx_math::Real;

use crate::model::Model;
use crate::mpc::{CONTROL_MOVES, MOVE_OF_STEP, MpcConfig, PREDICTION_STEPS};

/// Gradient steps per control period (lab: 20).
pub const GRADIENT_ITERATIONS: usize = 20;
/// Learning rate (lab: 0.4).
pub const LEARNING_RATE: f64 = 0.4;
/// Momentum rate (lab: 0.6).
pub const MOMENTUM_RATE: f64 = 0.6;
/// What the lab's `reset_optimizer` writes into every variable (CasADi's gradient is wrong at
/// exactly zero).
pub const RESET_VALUE: f64 = 1e-12;

/// The solver's memory between control periods: the next iterate and the momentum.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WarmStart<const NU: usize, T = f64> {
    /// The iterate the next period starts from (not yet clipped).
    pub u_next: [[T; NU]; CONTROL_MOVES],
    /// The momentum.
    pub momentum: [[T; NU]; CONTROL_MOVES],
}

impl<const NU: usize, T: Real> WarmStart<NU, T> {
    /// The state after the lab's `reset_optimizer`.
    pub fn reset() -> Self {
        Self {
            u_next: [[T::splat(RESET_VALUE); NU]; CONTROL_MOVES],
            momentum: [[T::splat(RESET_VALUE); NU]; CONTROL_MOVES],
        }
    }
}

/// The result of one control period's iterations.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GradientResult<const NU: usize, T = f64> {
    /// The moves of the last iterate `u_next`, clipped.
    pub moves: [[T; NU]; CONTROL_MOVES],
    /// The objective at the last step's `u` (what the lab checks).
    pub objective: T,
    /// Predicted positions at the last step's `u`.
    pub predicted_m: [[T; 2]; PREDICTION_STEPS],
}

/// A step's state and input Jacobians, rows first: `a[r][c] = ∂x⁺_r/∂x_c`, `b[r][c] =
/// ∂x⁺_r/∂u_c`.
pub type StepJacobians<T, const NX: usize, const NU: usize> = ([T; NX], [[T; NX]; NX], [[T; NU]; NX]);

/// What the solver needs of a model, in numbers `T`.
pub trait Prediction<T: Real, const NX: usize, const NU: usize> {
    /// The state after holding `input` for `h_s` from `state`, with its Jacobians.
    fn step_jacobians(&self, state: &[T; NX], input: &[T; NU], h_s: f64) -> StepJacobians<T, NX, NU>;
    /// The tracked point of `state` [m].
    fn position_m(&self, state: &[T; NX]) -> [T; 2];
    /// `∂position/∂x`, rows first.
    fn position_jacobian(&self, state: &[T; NX]) -> [[T; NX]; 2];
    /// The inputs' lower and upper bounds.
    fn input_bounds(&self) -> ([T; NU], [T; NU]);
}

/// A [`Model`] as the solver sees one vehicle: its own Jacobians, copied out of their matrices.
pub struct ScalarPrediction<'a, M>(pub &'a M);

impl<M: Model<NX, NU>, const NX: usize, const NU: usize> Prediction<f64, NX, NU> for ScalarPrediction<'_, M> {
    #[inline]
    fn step_jacobians(&self, state: &[f64; NX], input: &[f64; NU], h_s: f64) -> StepJacobians<f64, NX, NU> {
        let (next, a, b) = self.0.step_jacobians(state, input, h_s);
        (
            next,
            std::array::from_fn(|r| std::array::from_fn(|c| a[(r, c)])),
            std::array::from_fn(|r| std::array::from_fn(|c| b[(r, c)])),
        )
    }

    #[inline]
    fn position_m(&self, state: &[f64; NX]) -> [f64; 2] {
        self.0.position_m(state)
    }

    #[inline]
    fn position_jacobian(&self, state: &[f64; NX]) -> [[f64; NX]; 2] {
        let c = self.0.position_jacobian(state);
        std::array::from_fn(|r| std::array::from_fn(|k| c[(r, k)]))
    }

    #[inline]
    fn input_bounds(&self) -> ([f64; NU], [f64; NU]) {
        let limits = self.0.input_limits();
        (limits.lower, limits.upper)
    }
}

/// Runs the lab's iterations from `warm` (updated in place) for the delay-compensated state
/// `x0` and the reference positions `reference_m`. (Inlined always: in lanes it is compiled
/// inside `lanes.rs`'s functions for the CPU's vector extensions.)
#[inline(always)]
pub fn solve<T: Real, P: Prediction<T, NX, NU>, const NX: usize, const NU: usize>(
    prediction: &P,
    config: &MpcConfig<NU>,
    x0: &[T; NX],
    reference_m: &[[T; 2]; PREDICTION_STEPS],
    previous_input: &[T; NU],
    warm: &mut WarmStart<NU, T>,
) -> GradientResult<NU, T> {
    let (lower, upper) = prediction.input_bounds();
    // Loops, not `array::from_fn`: its closures are not always inlined into the lanes' vector
    // functions and then run in baseline code (the profile showed them).
    let clip = |moves: &[[T; NU]; CONTROL_MOVES]| {
        let mut clipped = *moves;
        for m in 0..CONTROL_MOVES {
            for i in 0..NU {
                clipped[m][i] = moves[m][i].clamp(lower[i], upper[i]);
            }
        }
        clipped
    };
    let (momentum_rate, learning_rate) = (T::splat(MOMENTUM_RATE), T::splat(LEARNING_RATE));
    let mut objective = T::splat(f64::INFINITY);
    let mut predicted_m = [[T::splat(0.0); 2]; PREDICTION_STEPS];
    for _ in 0..config.gradient_iterations {
        let u = clip(&warm.u_next);
        let (j, gradient, predicted) =
            objective_and_gradient(prediction, config, x0, reference_m, previous_input, &u);
        objective = j;
        predicted_m = predicted;
        for m in 0..CONTROL_MOVES {
            for i in 0..NU {
                warm.momentum[m][i] = momentum_rate * warm.momentum[m][i] - gradient[m][i];
                warm.u_next[m][i] = u[m][i] + learning_rate * warm.momentum[m][i];
            }
        }
    }
    GradientResult {
        moves: clip(&warm.u_next),
        objective,
        predicted_m,
    }
}

/// The objective's value, its gradient with respect to the moves, and the predicted positions.
pub type ObjectiveAndGradient<T, const NU: usize> = (T, [[T; NU]; CONTROL_MOVES], [[T; 2]; PREDICTION_STEPS]);

/// The lab's objective `Σ wₖ²·|p(xₖ) − rₖ|² + Σᵢ Rᵢ·Σⱼ (uⱼ,ᵢ − uⱼ₋₁,ᵢ)²` (u₋₁ = the previous
/// input), its gradient with respect to the moves, and the predicted positions.
#[inline(always)]
pub fn objective_and_gradient<T: Real, P: Prediction<T, NX, NU>, const NX: usize, const NU: usize>(
    prediction: &P,
    config: &MpcConfig<NU>,
    x0: &[T; NX],
    reference_m: &[[T; 2]; PREDICTION_STEPS],
    previous_input: &[T; NU],
    moves: &[[T; NU]; CONTROL_MOVES],
) -> ObjectiveAndGradient<T, NU> {
    let zero = T::splat(0.0);
    let two = T::splat(2.0);
    // Forward: states, Jacobians, position errors.
    let mut x = *x0;
    let mut state_jacobians = [[[zero; NX]; NX]; PREDICTION_STEPS];
    let mut input_jacobians = [[[zero; NU]; NX]; PREDICTION_STEPS];
    let mut position_grad = [[zero; NX]; PREDICTION_STEPS];
    let mut predicted_m = [[zero; 2]; PREDICTION_STEPS];
    let mut objective = zero;
    for k in 0..PREDICTION_STEPS {
        let (next, a, b) = prediction.step_jacobians(&x, &moves[MOVE_OF_STEP[k]], config.mpc_step_s);
        state_jacobians[k] = a;
        input_jacobians[k] = b;
        x = next;
        let p = prediction.position_m(&x);
        let w2 = T::splat(config.position_weights[k] * config.position_weights[k]);
        let e = [p[0] - reference_m[k][0], p[1] - reference_m[k][1]];
        objective = objective + w2 * (e[0] * e[0] + e[1] * e[1]);
        let c = prediction.position_jacobian(&x);
        position_grad[k] = transposed_times(&c, &[two * w2 * e[0], two * w2 * e[1]]);
        predicted_m[k] = p;
    }

    // Backward: λₖ = ∂J/∂xₖ₊₁ through the later steps.
    let mut gradient = [[zero; NU]; CONTROL_MOVES];
    let mut lambda = [zero; NX];
    for k in (0..PREDICTION_STEPS).rev() {
        for (l, g) in lambda.iter_mut().zip(&position_grad[k]) {
            *l = *l + *g;
        }
        let g = transposed_times(&input_jacobians[k], &lambda);
        for i in 0..NU {
            gradient[MOVE_OF_STEP[k]][i] = gradient[MOVE_OF_STEP[k]][i] + g[i];
        }
        lambda = transposed_times(&state_jacobians[k], &lambda);
    }

    // Move penalties.
    let mut before = *previous_input;
    for (j, m) in moves.iter().enumerate() {
        for i in 0..NU {
            let weight = T::splat(config.move_weights[i]);
            let d = m[i] - before[i];
            objective = objective + weight * d * d;
            gradient[j][i] = gradient[j][i] + two * weight * d;
            if j > 0 {
                gradient[j - 1][i] = gradient[j - 1][i] - two * weight * d;
            }
        }
        before = *m;
    }
    (objective, gradient, predicted_m)
}

/// `mᵀ v` for `m` given rows first, summed as nalgebra's `gemv` sums `m.transpose() * v`
/// (element `i` is `Σⱼ m[j][i]·v[j]` in increasing `j` from the first product), so that the
/// solver keeps the bits it had over nalgebra's matrices.
/// (A loop, not `array::from_fn`, whose closure the lanes' vector functions did not inline.)
#[inline(always)]
fn transposed_times<T: Real, const R: usize, const C: usize>(m: &[[T; C]; R], v: &[T; R]) -> [T; C] {
    let mut product = m[0];
    for (i, element) in product.iter_mut().enumerate() {
        let mut sum = m[0][i] * v[0];
        for j in 1..R {
            sum = sum + m[j][i] * v[j];
        }
        *element = sum;
    }
    product
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::BicycleModel;
    use cpmx_vehicle::{KinematicBicycle, VehicleParams};

    fn setup() -> (BicycleModel, MpcConfig<2>, [f64; 5], [[f64; 2]; PREDICTION_STEPS]) {
        let model = BicycleModel {
            bicycle: KinematicBicycle::new(VehicleParams::MU_CAR),
        };
        let config = MpcConfig::lab(crate::mpc::BICYCLE_MOVE_WEIGHTS);
        let x0 = [0.0, 0.0, 0.1, 0.4, 0.05];
        let reference = std::array::from_fn(|k| {
            let t = 0.05 * (k + 1) as f64;
            [0.5 * t, 0.2 * t * t]
        });
        (model, config, x0, reference)
    }

    fn rows<const R: usize, const C: usize>(m: &nalgebra::SMatrix<f64, R, C>) -> [[f64; C]; R] {
        std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)]))
    }

    /// `transposed_times` gives the bits of nalgebra's `m.transpose() * v`, zeros of both signs
    /// and infinities included.
    #[test]
    fn transposed_times_has_nalgebras_bits() {
        let special = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            1e-300,
            1e300,
            f64::INFINITY,
            f64::NAN,
            0.1,
            -3.7,
        ];
        let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            if seed.is_multiple_of(3) {
                special[(seed >> 8) as usize % special.len()]
            } else {
                f64::from_bits(seed >> 2) * 1e-300
            }
        };
        for _ in 0..20_000 {
            let a = nalgebra::SMatrix::<f64, 4, 4>::from_fn(|_, _| next());
            let b = nalgebra::SMatrix::<f64, 4, 2>::from_fn(|_, _| next());
            let c = nalgebra::SMatrix::<f64, 2, 5>::from_fn(|_, _| next());
            let v4 = [next(), next(), next(), next()];
            let v2 = [next(), next()];
            // Bits, with every NaN one NaN (which NaN an addition of two returns is the
            // operands' order, which the compiler may swap).
            let bits = |x: &[f64]| {
                x.iter()
                    .map(|v| {
                        if v.is_nan() {
                            f64::NAN.to_bits()
                        } else {
                            v.to_bits()
                        }
                    })
                    .collect::<Vec<_>>()
            };
            let expected_a = a.transpose() * nalgebra::SVector::<f64, 4>::from(v4);
            let expected_b = b.transpose() * nalgebra::SVector::<f64, 4>::from(v4);
            let expected_c = c.transpose() * nalgebra::SVector::<f64, 2>::from(v2);
            assert_eq!(
                bits(&transposed_times(&rows(&a), &v4)),
                bits(expected_a.as_slice())
            );
            assert_eq!(
                bits(&transposed_times(&rows(&b), &v4)),
                bits(expected_b.as_slice())
            );
            assert_eq!(
                bits(&transposed_times(&rows(&c), &v2)),
                bits(expected_c.as_slice())
            );
        }
    }

    #[test]
    fn the_gradient_matches_central_differences() {
        let (model, config, x0, reference) = setup();
        let moves = [[0.45, 0.1], [0.5, 0.2], [0.55, -0.1]];
        let previous = [0.4, 0.0];
        let (_, gradient, _) = objective_and_gradient(
            &ScalarPrediction(&model),
            &config,
            &x0,
            &reference,
            &previous,
            &moves,
        );
        for j in 0..CONTROL_MOVES {
            for i in 0..2 {
                let h = 1e-6;
                let (mut plus, mut minus) = (moves, moves);
                plus[j][i] += h;
                minus[j][i] -= h;
                let f = |m: &[[f64; 2]; CONTROL_MOVES]| {
                    objective_and_gradient(&ScalarPrediction(&model), &config, &x0, &reference, &previous, m)
                        .0
                };
                let numeric = (f(&plus) - f(&minus)) / (2.0 * h);
                assert!(
                    (gradient[j][i] - numeric).abs() < 1e-6 * numeric.abs().max(1.0),
                    "move {j} input {i}: {} vs {numeric}",
                    gradient[j][i]
                );
            }
        }
    }

    #[test]
    fn iterations_lower_the_objective_and_warm_start_carries_on() {
        let (model, config, x0, reference) = setup();
        let prediction = ScalarPrediction(&model);
        let previous = [0.4, 0.0];
        let mut warm = WarmStart::reset();
        let first = solve(&prediction, &config, &x0, &reference, &previous, &mut warm);
        let reset = WarmStart::<2>::reset().u_next;
        let start = objective_and_gradient(&prediction, &config, &x0, &reference, &previous, &reset).0;
        assert!(first.objective < start, "{} vs {start}", first.objective);
        assert_ne!(warm, WarmStart::reset());
        let second = solve(&prediction, &config, &x0, &reference, &previous, &mut warm);
        assert!(second.objective <= first.objective + 1e-12);
    }
}
