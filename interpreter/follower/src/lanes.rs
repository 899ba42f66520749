//! The lab's solver for several vehicles at once: `L` problems of one [`RealModel`] gathered
//! into [`Lanes`], solved by the same code as one vehicle's ([`gradient::solve`]), and scattered
//! back. Every lane's result has the bits the vehicle's own solve gives (the tests below).
//!
//! This module owns gathering and scattering; the iteration and the model's step are
//! `gradient.rs`'s and the model's.

use std::cell::Cell;

use cpmx_math::{Lanes, Real};

use crate::gradient::{self, GradientResult, Prediction, StepJacobians, WarmStart};
use crate::model::{HELD_TERMS, Held, MODEL_NUMBERS, RealModel};
use crate::mpc::{CONTROL_MOVES, MpcConfig, PREDICTION_STEPS, Problem};

/// `L` models' numbers and input bounds, lane by lane.
pub struct LanesPrediction<M, const NU: usize, const L: usize> {
    numbers: [Lanes<L>; MODEL_NUMBERS],
    lower: [Lanes<L>; NU],
    upper: [Lanes<L>; NU],
    /// The last powers computed, by the bits of their bases (see [`Held`]).
    last_power: Cell<([u64; L], Lanes<L>)>,
    /// The last held terms computed, by the bits of the value they were computed from.
    last_terms: Cell<([u64; L], [Lanes<L>; HELD_TERMS])>,
    model: std::marker::PhantomData<M>,
}

impl<M, const NU: usize, const L: usize> Held<Lanes<L>> for LanesPrediction<M, NU, L> {
    /// `x^y` of each lane, remembered from the call before when every lane's base is the one
    /// before (the exponents are the models' numbers, fixed for a solve).
    #[inline(always)]
    fn power(&self, x: Lanes<L>, y: Lanes<L>) -> Lanes<L> {
        let (bits, power) = self.last_power.get();
        let base = lane_bits(x);
        if bits == base {
            return power;
        }
        let power = x.pow(y);
        self.last_power.set((base, power));
        power
    }

    /// The terms of each lane's `x`, when every lane's `x` is the one they were computed from.
    #[inline(always)]
    fn remembered_terms(&self, x: Lanes<L>) -> Option<[Lanes<L>; HELD_TERMS]> {
        let (bits, terms) = self.last_terms.get();
        (bits == lane_bits(x)).then_some(terms)
    }

    #[inline(always)]
    fn remember_terms(&self, x: Lanes<L>, terms: [Lanes<L>; HELD_TERMS]) {
        self.last_terms.set((lane_bits(x), terms));
    }
}

/// The bits of each lane.
#[inline(always)]
fn lane_bits<const L: usize>(x: Lanes<L>) -> [u64; L] {
    std::array::from_fn(|i| x.0[i].to_bits())
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
        M::predict(&self.numbers, state, input, h_s, self)
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

/// Solves `L` vehicles' problems together, each with its model and warm start (updated as
/// [`gradient::solve`] updates one): the results and warm starts have the bits of `L` separate
/// solves. All share `config` (the lab's).
pub fn solve_lanes<M: RealModel<NX, NU>, const NX: usize, const NU: usize, const L: usize>(
    models: [&M; L],
    config: &MpcConfig<NU>,
    problems: &[Problem<NX, NU>; L],
    warm: [&mut WarmStart<NU>; L],
) -> [GradientResult<NU>; L] {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512dq")
            && std::arch::is_x86_feature_detected!("avx512vl")
        {
            // SAFETY: the CPU has these extensions (checked above).
            return unsafe { solve_lanes_avx512(models, config, problems, warm) };
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked above).
            return unsafe { solve_lanes_avx2(models, config, problems, warm) };
        }
    }
    solve_lanes_portable(models, config, problems, warm)
}

/// Variants of [`solve_lanes`] compiled for vector extensions: the same body
/// ([`solve_lanes_portable`], inlined), its vectors as wide as the extensions allow.
macro_rules! compiled_for {
    ($($(#[doc = $doc:literal])* $name:ident: $features:literal;)*) => {$(
        $(#[doc = $doc])*
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        fn $name<M: RealModel<NX, NU>, const NX: usize, const NU: usize, const L: usize>(
            models: [&M; L],
            config: &MpcConfig<NU>,
            problems: &[Problem<NX, NU>; L],
            warm: [&mut WarmStart<NU>; L],
        ) -> [GradientResult<NU>; L] {
            solve_lanes_portable(models, config, problems, warm)
        }
    )*};
}

compiled_for! {
    /// AVX-512 (F; DQ for the conversions between integers and doubles; VL for the narrower
    /// vectors).
    solve_lanes_avx512: "avx512f,avx512dq,avx512vl,avx2";
    /// AVX2.
    solve_lanes_avx2: "avx2";
}

/// [`solve_lanes`]'s body, inlined into each variant.
#[inline(always)]
fn solve_lanes_portable<M: RealModel<NX, NU>, const NX: usize, const NU: usize, const L: usize>(
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
        last_power: Cell::new(([f64::NAN.to_bits(); L], Lanes::splat(f64::NAN))),
        last_terms: Cell::new(([f64::NAN.to_bits(); L], [Lanes::splat(f64::NAN); HELD_TERMS])),
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

/// One MPC's share of a solve together with others ([`solve_together`]): its model,
/// configuration and warm start ([`crate::Mpc::gradient_parts`]) and its pending problem.
pub struct LaneJob<'a, M, const NX: usize, const NU: usize> {
    /// The MPC's model.
    pub model: &'a M,
    /// The MPC's configuration.
    pub config: &'a MpcConfig<NU>,
    /// The MPC's warm start, updated by the solve.
    pub warm: &'a mut WarmStart<NU>,
    /// The problem [`crate::Mpc::begin`] left pending.
    pub problem: &'a Problem<NX, NU>,
}

/// The most problems solved side by side in one pass (eight `f64` lanes fill an AVX-512
/// register).
pub const WIDEST_LANES: usize = 8;

/// Solves every job's problem with its own model and warm start, in order: runs of up to
/// eight jobs with equal configurations at a time, in 1, 2, 4 or 8 lanes (the fewest that hold
/// the run; lanes beyond it solve a copy of its first job, and their results are dropped). Each
/// result and warm start has the bits of the job's own solve.
pub fn solve_together<M: RealModel<NX, NU>, const NX: usize, const NU: usize>(
    jobs: &mut [LaneJob<'_, M, NX, NU>],
) -> Vec<GradientResult<NU>> {
    let mut results = Vec::with_capacity(jobs.len());
    let mut rest = jobs;
    while let Some(first) = rest.first() {
        let alike = rest
            .iter()
            .take(WIDEST_LANES)
            .take_while(|job| job.config == first.config)
            .count();
        let (chunk, tail) = rest.split_at_mut(alike);
        match alike.next_power_of_two() {
            1 => results.extend(solve_chunk::<M, NX, NU, 1>(chunk)),
            2 => results.extend(solve_chunk::<M, NX, NU, 2>(chunk)),
            4 => results.extend(solve_chunk::<M, NX, NU, 4>(chunk)),
            _ => results.extend(solve_chunk::<M, NX, NU, 8>(chunk)),
        }
        rest = tail;
    }
    results
}

/// Up to `L` jobs of one configuration solved in `L` lanes; the results of the jobs given.
fn solve_chunk<M: RealModel<NX, NU>, const NX: usize, const NU: usize, const L: usize>(
    chunk: &mut [LaneJob<'_, M, NX, NU>],
) -> impl Iterator<Item = GradientResult<NU>> {
    let n = chunk.len();
    debug_assert!((1..=L).contains(&n));
    let job = |i: usize| &chunk[if i < n { i } else { 0 }];
    let models: [&M; L] = std::array::from_fn(|i| job(i).model);
    let problems: [Problem<NX, NU>; L] = std::array::from_fn(|i| *job(i).problem);
    let config = *chunk[0].config;
    // The padding lanes' warm starts are copies, whatever becomes of them.
    let mut padding: [WarmStart<NU>; L] = std::array::from_fn(|_| *chunk[0].warm);
    let mut own = chunk.iter_mut().map(|job| &mut *job.warm);
    let mut spare = padding.iter_mut();
    let warm: [&mut WarmStart<NU>; L] = std::array::from_fn(|_| match own.next() {
        Some(warm) => warm,
        None => spare.next().expect("L warm starts"),
    });
    solve_lanes(models, &config, &problems, warm).into_iter().take(n)
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

    /// The variants compiled for each vector extension this CPU has give the portable code's
    /// bits (what runs elsewhere gives what runs here).
    #[test]
    fn every_vector_extension_gives_the_portable_bits() {
        let mut rng = ChaCha8Rng::seed_from_u64(12);
        let config = MpcConfig::lab(BICYCLE_MOVE_WEIGHTS);
        let vehicle = BicycleModel {
            bicycle: KinematicBicycle::new(VehicleParams::MU_CAR),
        };
        let mut portable: [WarmStart<2>; 8] = std::array::from_fn(|_| WarmStart::reset());
        #[cfg(target_arch = "x86_64")]
        let (mut avx2, mut avx512) = (portable, portable);
        for period in 0..20 {
            let problems: [Problem<5, 2>; 8] = std::array::from_fn(|_| problem(&mut rng));
            let models = [&vehicle; 8];
            let expected = solve_lanes_portable(models, &config, &problems, portable.each_mut());
            let expected: Vec<u64> = expected.iter().flat_map(|r| bits(&r.moves)).collect();
            #[cfg(target_arch = "x86_64")]
            {
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU has AVX2 (checked above).
                    let got = unsafe { solve_lanes_avx2(models, &config, &problems, avx2.each_mut()) };
                    let got: Vec<u64> = got.iter().flat_map(|r| bits(&r.moves)).collect();
                    assert_eq!(got, expected, "period {period}: AVX2");
                }
                let avx512_here = std::arch::is_x86_feature_detected!("avx512f")
                    && std::arch::is_x86_feature_detected!("avx512dq")
                    && std::arch::is_x86_feature_detected!("avx512vl");
                if avx512_here {
                    // SAFETY: the CPU has these extensions (checked above).
                    let got = unsafe { solve_lanes_avx512(models, &config, &problems, avx512.each_mut()) };
                    let got: Vec<u64> = got.iter().flat_map(|r| bits(&r.moves)).collect();
                    assert_eq!(got, expected, "period {period}: AVX-512");
                }
            }
        }
    }
}
