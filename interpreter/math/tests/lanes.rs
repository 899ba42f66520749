//! The lanes and slices give the scalar functions' bits, on this machine's widest vectors and
//! on the portable path, including the arguments their kernels send to the slow path.

use cpmx_math::{
    exp, exp_lanes, exp_slice, pow, pow_lanes, pow_slice, sin_cos, sin_cos_lanes, sin_cos_slice,
};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Arguments of every kind: ordinary, tiny, huge, signed zeros, infinities, NaN, subnormals.
fn arguments(n: usize, seed: u64) -> Vec<f64> {
    let special = [
        0.0,
        -0.0,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NAN,
        f64::MIN_POSITIVE,
        5e-324,
        -5e-324,
        1e-300,
        1e300,
        -1e22,
        1_647_098.9,
        1_647_099.5,
        709.9,
        -745.3,
        1.0,
        -1.0,
        2.0,
        -2.0,
        0.5,
    ];
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out: Vec<f64> = special.to_vec();
    while out.len() < n {
        let magnitude = 2f64.powf(rng.random_range(-40.0..40.0));
        out.push(if rng.random::<bool>() {
            magnitude
        } else {
            -magnitude
        });
        out.push(rng.random_range(-10.0..10.0));
    }
    out.truncate(n);
    out
}

fn same_bits(a: f64, b: f64) -> bool {
    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
}

#[test]
fn sin_cos_lanes_and_slices_give_the_scalar_bits() {
    let x = arguments(4_003, 1);
    let (mut sin, mut cos) = (vec![0.0; x.len()], vec![0.0; x.len()]);
    sin_cos_slice(&x, &mut sin, &mut cos);
    for (i, &v) in x.iter().enumerate() {
        let (s, c) = sin_cos(v);
        assert!(
            same_bits(s, sin[i]) && same_bits(c, cos[i]),
            "sin_cos({v:e}): slice differs"
        );
    }
    for block in x.chunks_exact(4) {
        let (s4, c4) = sin_cos_lanes::<4>(block.try_into().unwrap());
        for (i, &v) in block.iter().enumerate() {
            let (s, c) = sin_cos(v);
            assert!(
                same_bits(s, s4[i]) && same_bits(c, c4[i]),
                "sin_cos({v:e}): lanes differ"
            );
        }
    }
}

#[test]
fn exp_lanes_and_slices_give_the_scalar_bits() {
    let x: Vec<f64> = arguments(4_003, 2).into_iter().map(|v| v * 20.0).collect();
    let mut out = vec![0.0; x.len()];
    exp_slice(&x, &mut out);
    for (i, &v) in x.iter().enumerate() {
        assert!(same_bits(exp(v), out[i]), "exp({v:e}): slice differs");
    }
    for block in x.chunks_exact(8) {
        let lanes = exp_lanes::<8>(block.try_into().unwrap());
        for (i, &v) in block.iter().enumerate() {
            assert!(same_bits(exp(v), lanes[i]), "exp({v:e}): lanes differ");
        }
    }
}

#[test]
fn pow_lanes_and_slices_give_the_scalar_bits() {
    let x = arguments(4_003, 3);
    let y: Vec<f64> = arguments(4_003, 4).into_iter().rev().collect();
    let mut out = vec![0.0; x.len()];
    pow_slice(&x, &y, &mut out);
    for i in 0..x.len() {
        assert!(
            same_bits(pow(x[i], y[i]), out[i]),
            "pow({:e}, {:e}): slice differs",
            x[i],
            y[i]
        );
    }
    for (bx, by) in x.chunks_exact(2).zip(y.chunks_exact(2)) {
        let lanes = pow_lanes::<2>(bx.try_into().unwrap(), by.try_into().unwrap());
        for i in 0..2 {
            assert!(
                same_bits(pow(bx[i], by[i]), lanes[i]),
                "pow({:e}, {:e}): lanes differ",
                bx[i],
                by[i]
            );
        }
    }
}

#[test]
fn special_values_follow_c99() {
    let nan = f64::NAN;
    let inf = f64::INFINITY;
    assert!(same_bits(sin_cos(-0.0).0, -0.0) && sin_cos(-0.0).1 == 1.0);
    assert!(sin_cos(inf).0.is_nan() && sin_cos(nan).1.is_nan());
    assert_eq!(exp(0.0), 1.0);
    assert_eq!(exp(-inf), 0.0);
    assert_eq!(exp(inf), inf);
    assert_eq!(exp(710.0), inf);
    assert_eq!(exp(-746.0), 0.0);
    assert!(exp(nan).is_nan());
    assert_eq!(exp(-740.0), 4.2e-322); // a subnormal, as the correctly rounded value
    assert_eq!(pow(nan, 0.0), 1.0);
    assert_eq!(pow(1.0, nan), 1.0);
    assert!(pow(-2.0, 0.5).is_nan());
    assert_eq!(pow(-2.0, 3.0), -8.0);
    assert_eq!(pow(-2.0, -2.0), 0.25);
    assert!(same_bits(pow(-0.0, 3.0), -0.0));
    assert_eq!(pow(-0.0, -3.0), -inf);
    assert_eq!(pow(0.0, -2.0), inf);
    assert_eq!(pow(0.0, 2.0), 0.0);
    assert_eq!(pow(-1.0, inf), 1.0);
    assert_eq!(pow(0.5, inf), 0.0);
    assert_eq!(pow(0.5, -inf), inf);
    assert_eq!(pow(inf, -1.0), 0.0);
    assert_eq!(pow(-inf, 3.0), -inf);
    assert_eq!(pow(-inf, 2.0), inf);
    assert_eq!(pow(2.0, 1024.0), inf);
    assert_eq!(pow(2.0, -1074.0), 5e-324);
    assert_eq!(pow(5e-324, 0.5), 2.2227587494850775e-162);
    assert_eq!(pow(4.0, 0.5), 2.0);
    assert_eq!(pow(10.0, 2.0), 100.0);
}
