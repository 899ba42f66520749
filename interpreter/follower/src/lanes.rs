//! The lab's solver for several vehicles at once: `L` problems of one [`RealModel`] gathered
//! into [`Lanes`], solved by the same code as one vehicle's ([`gradient::solve`]), and scattered
//! back. Every lane's result has the bits the vehicle's own solve gives (the tests below).
//!
//! This module owns gathering and scattering; the iteration and the model's step are
//! `gradient.rs`'s and the model's.

use cpmx_math::{Lanes, Real};

use crate::gradient::{self, GradientResult, Prediction, StepJacobians, WarmStart};
use crate::model::{MODEL_NUMBERS, RealModel};
use crate::mpc::{CONTROL_MOVES, MpcConfig, PREDICTION_STEPS};

/// `L` models' numbers and input bounds, lane by lane.
pub struct LanesPrediction<M, const NU: usize, const L: usize> {
    numbers: [Lanes<L>; MODEL_NUMBERS],
    lower: [Lanes<L>; NU],
    upper: [Lanes<L>; NU],
    model: std::marker::PhantomData<M>,
}

/// Lane `i` of `L` values `value(i)`.
fn gather<const L: usize>(value: impl Fn(usize) -> f64) -> Lanes<L> {
    Lanes(std::array::from_fn(value))
}

impl<M: RealModel<NX, NU>, const NX: usize, const NU: usize, const L: usize> Prediction<Lanes<L>, NX, NU>
    for LanesPrediction<M, NU, L>
{
    #[inline(always)]
    fn step_jacobians(
        &self,
        state: &[Lanes<L>; NX],
        input: &[Lanes<L>; NU],
        h_s: f64,
    ) -> StepJacobians<Lanes<L>, NX, NU> {
        M::predict(&self.numbers, state, input, h_s, Real::pow)
    }

    #[inline(always)]
    fn position_m(&self, state: &[Lanes<L>; NX]) -> [Lanes<L>; 2] {
        [state[0], state[1]]
    }

    #[inline(always)]
    fn position_jacobian(&self, _: &[Lanes<L>; NX]) -> [[Lanes<L>; NX]; 2] {
        std::array::from_fn(|r| std::array::from_fn(|c| Lanes::splat(if r == c { 1.0 } else { 0.0 })))
    }

    #[inline(always)]
    fn input_bounds(&self) -> ([Lanes<L>; NU], [Lanes<L>; NU]) {
        (self.lower, self.upper)
    }
}

/// One vehicle's problem: what [`gradient::solve`] takes besides the model and the
/// configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Problem<const NX: usize, const NU: usize> {
    /// The delay-compensated state.
    pub x0: [f64; NX],
    /// The reference positions [m].
    pub reference_m: [[f64; 2]; PREDICTION_STEPS],
    /// The input the first move is penalised against.
    pub previous_input: [f64; NU],
}

/// Solves `L` vehicles' problems together, each with its model and warm start (updated as
/// [`gradient::solve`] updates one): the results and warm starts have the bits of `L` separate
/// solves. All share `config` (the lab's).
pub fn solve_lanes<M: RealModel<NX, NU>, const NX: usize, const NU: usize, const L: usize>(
    models: [&M; L],
    config: &MpcConfig<NU>,
    problems: &[Problem<NX, NU>; L],
    warm: [&mut WarmStart<NU>; L],
) -> [GradientResult<NU>; L] {
    let numbers = models.map(|m| m.numbers());
    let limits = models.map(|m| m.input_limits());
    let prediction = LanesPrediction::<M, NU, L> {
        numbers: std::array::from_fn(|k| gather(|i| numbers[i][k])),
        lower: std::array::from_fn(|k| gather(|i| limits[i].lower[k])),
        upper: std::array::from_fn(|k| gather(|i| limits[i].upper[k])),
        model: std::marker::PhantomData,
    };
    let x0: [Lanes<L>; NX] = std::array::from_fn(|k| gather(|i| problems[i].x0[k]));
    let reference: [[Lanes<L>; 2]; PREDICTION_STEPS] =
        std::array::from_fn(|s| std::array::from_fn(|c| gather(|i| problems[i].reference_m[s][c])));
    let previous: [Lanes<L>; NU] = std::array::from_fn(|k| gather(|i| problems[i].previous_input[k]));
    let mut lanes_warm = WarmStart::<NU, Lanes<L>> {
        u_next: std::array::from_fn(|m| std::array::from_fn(|k| gather(|i| warm[i].u_next[m][k]))),
        momentum: std::array::from_fn(|m| std::array::from_fn(|k| gather(|i| warm[i].momentum[m][k]))),
    };
    let result = gradient::solve(&prediction, config, &x0, &reference, &previous, &mut lanes_warm);
    for (i, w) in warm.into_iter().enumerate() {
        for m in 0..CONTROL_MOVES {
            for k in 0..NU {
                w.u_next[m][k] = lanes_warm.u_next[m][k].0[i];
                w.momentum[m][k] = lanes_warm.momentum[m][k].0[i];
            }
        }
    }
    std::array::from_fn(|i| GradientResult {
        moves: result.moves.map(|m| m.map(|v| v.0[i])),
        objective: result.objective.0[i],
        predicted_m: result.predicted_m.map(|p| p.map(|v| v.0[i])),
    })
}

#[cfg(test)]
mod tests {
    //! Several vehicles' problems solved together in lanes give, lane by lane, the bits of each
    //! vehicle's own solve: results and warm starts, over random problems, warm starts carried
    //! across periods and inputs at and beyond the limits.

    use super::*;
    use crate::gradient::ScalarPrediction;
    use crate::model::BicycleModel;
    use crate::mpc::BICYCLE_MOVE_WEIGHTS;
    use cpmx_vehicle::{KinematicBicycle, VehicleParams};
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn problem(rng: &mut ChaCha8Rng) -> Problem<5, 2> {
        let speed = rng.random_range(0.0..1.2);
        let yaw: f64 = rng.random_range(-3.0..3.0);
        let x0 = [
            rng.random_range(-2.0..2.0),
            rng.random_range(-2.0..2.0),
            yaw,
            speed,
            rng.random_range(-0.6..0.6),
        ];
        let turn = rng.random_range(-1.5..1.5);
        let reference_m = std::array::from_fn(|k| {
            let t = 0.05 * (k + 1) as f64;
            let heading = yaw + turn * t;
            [
                x0[0] + speed * t * heading.cos(),
                x0[1] + speed * t * heading.sin(),
            ]
        });
        Problem {
            x0,
            reference_m,
            previous_input: [rng.random_range(-1.5..1.5), rng.random_range(-0.8..0.8)],
        }
    }

    fn bits<const N: usize>(values: &[[f64; N]]) -> Vec<u64> {
        values.iter().flatten().map(|v| v.to_bits()).collect()
    }

    #[test]
    fn bicycles_in_lanes_give_each_vehicles_bits() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let config = MpcConfig::lab(BICYCLE_MOVE_WEIGHTS);
        let vehicles: [BicycleModel; 4] = std::array::from_fn(|i| {
            let mut params = VehicleParams::MU_CAR;
            params.max_speed_mps *= 1.0 + 0.1 * i as f64;
            BicycleModel {
                bicycle: KinematicBicycle::new(params),
            }
        });
        let mut lanes_warm: [WarmStart<2>; 4] = std::array::from_fn(|_| WarmStart::reset());
        let mut own_warm = lanes_warm;
        for period in 0..30 {
            let problems: [Problem<5, 2>; 4] = std::array::from_fn(|_| problem(&mut rng));
            let together = solve_lanes(vehicles.each_ref(), &config, &problems, lanes_warm.each_mut());
            for i in 0..4 {
                let p = &problems[i];
                let alone = gradient::solve(
                    &ScalarPrediction(&vehicles[i]),
                    &config,
                    &p.x0,
                    &p.reference_m,
                    &p.previous_input,
                    &mut own_warm[i],
                );
                assert_eq!(
                    bits(&together[i].moves),
                    bits(&alone.moves),
                    "period {period}, vehicle {i}: moves"
                );
                assert_eq!(
                    together[i].objective.to_bits(),
                    alone.objective.to_bits(),
                    "objective"
                );
                assert_eq!(
                    bits(&together[i].predicted_m),
                    bits(&alone.predicted_m),
                    "predicted positions"
                );
                assert_eq!(
                    bits(&lanes_warm[i].u_next),
                    bits(&own_warm[i].u_next),
                    "warm start"
                );
                assert_eq!(
                    bits(&lanes_warm[i].momentum),
                    bits(&own_warm[i].momentum),
                    "momentum"
                );
            }
        }
    }
}
