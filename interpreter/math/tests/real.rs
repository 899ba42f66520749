//! Code written once over [`Real`] gives, in every lane of [`Lanes`], the bits of its scalar
//! instance: a grey-box Euler step with its Jacobian's terms (every operation and function the
//! trait offers), on ordinary and special arguments.

use cpmx_math::{Lanes, Real};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// One Euler step of a grey-box car (state x, y, yaw, v; inputs throttle f, servo d) and two of
/// its Jacobian's terms, as a model of the MPC computes them.
fn step<T: Real>(state: [T; 4], input: [T; 2], p: [T; 4], h: T) -> [T; 9] {
    let [x, y, yaw, v] = state;
    let one = T::splat(1.0);
    let f = input[0].clamp(-one, one);
    let d = input[1].clamp(-one, one) + p[3];
    let gain = p[0] * (one + p[1] * d * d);
    let (sin, cos) = (yaw + p[2] * d).sin_cos();
    let sign = T::select(f.ge(T::splat(0.0)), one, -one);
    let magnitude = f.abs().pow(T::splat(1.321199));
    let slope = T::select(f.eq(T::splat(0.0)), T::splat(0.0), magnitude / f.abs());
    let heading = (v * sin).atan2(v * cos);
    let steer = (p[1] * d.tan()).atan();
    let speed = (v * cos).hypot(v * sin);
    let decay = (-(h * v * v)).exp();
    let root = (v * v + d * d).sqrt();
    let limited = T::select(v.lt(T::splat(0.1)), T::splat(0.1), v);
    [
        x + h * gain * v * cos,
        y + h * gain * v * sin,
        yaw + h * p[2] * v * d,
        v + h * (sign * magnitude - p[0] * v),
        slope,
        heading + steer,
        speed * decay,
        root / limited,
        -gain,
    ]
}

fn draw(rng: &mut ChaCha8Rng) -> f64 {
    const SPECIAL: [f64; 10] = [
        0.0,
        -0.0,
        1.0,
        -1.0,
        1e-300,
        5e-324,
        1e300,
        f64::INFINITY,
        f64::NAN,
        0.5,
    ];
    if rng.random_range(0..8) == 0 {
        SPECIAL[rng.random_range(0..SPECIAL.len())]
    } else {
        rng.random_range(-3.0..3.0)
    }
}

fn same_bits(a: f64, b: f64) -> bool {
    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
}

fn lanes_give_the_scalar_bits<const L: usize>(seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for _ in 0..2_000 {
        let values: Vec<[f64; L]> = (0..11).map(|_| std::array::from_fn(|_| draw(&mut rng))).collect();
        let lane = |k: usize| Lanes(values[k]);
        let got = step(
            [lane(0), lane(1), lane(2), lane(3)],
            [lane(4), lane(5)],
            [lane(6), lane(7), lane(8), lane(9)],
            lane(10),
        );
        let per_lane: Vec<[f64; 11]> = (0..L).map(|i| std::array::from_fn(|k| values[k][i])).collect();
        for (i, a) in per_lane.iter().enumerate() {
            let want = step(
                [a[0], a[1], a[2], a[3]],
                [a[4], a[5]],
                [a[6], a[7], a[8], a[9]],
                a[10],
            );
            for (j, (w, g)) in want.iter().zip(&got).enumerate() {
                assert!(
                    same_bits(*w, g.0[i]),
                    "output {j}, lane {i} of {L}: scalar {w:e}, lanes {:e} (arguments {a:?})",
                    g.0[i]
                );
            }
        }
    }
}

#[test]
fn lanes_of_every_width_give_the_scalar_bits() {
    lanes_give_the_scalar_bits::<1>(1);
    lanes_give_the_scalar_bits::<4>(2);
    lanes_give_the_scalar_bits::<8>(3);
    lanes_give_the_scalar_bits::<5>(4);
}

#[test]
fn clamp_and_select_follow_the_scalar_rules() {
    let nan = f64::NAN;
    let x = Lanes([nan, -2.0, 0.5, 2.0]);
    let clamped = x.clamp(Real::splat(-1.0), Real::splat(1.0));
    assert!(clamped.0[0].is_nan());
    assert_eq!(&clamped.0[1..], &[-1.0, 0.5, 1.0]);
    assert_eq!(x.lt(Real::splat(1.0)), [false, true, true, false]);
    let chosen = Lanes::select([true, false, true, false], x, Real::splat(7.0));
    assert!(chosen.0[0].is_nan());
    assert_eq!(&chosen.0[1..], &[7.0, 0.5, 7.0]);
}
