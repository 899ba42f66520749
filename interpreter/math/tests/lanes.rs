//! The lanes and slices give the scalar functions' bits, on this machine's widest vectors and
//! on the portable path, including the arguments their kernels send to the slow path.

use cpmx_math::{
    atan, atan2, atan2_lanes, atan2_slice, exp, exp_lanes, exp_slice, hypot, hypot_lanes, hypot_slice, pow,
    pow_lanes, pow_slice, sin_cos, sin_cos_lanes, sin_cos_slice, tan, tan_lanes, tan_slice,
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
fn tan_lanes_and_slices_give_the_scalar_bits() {
    let x = arguments(4_003, 9);
    let mut out = vec![0.0; x.len()];
    tan_slice(&x, &mut out);
    for (i, &v) in x.iter().enumerate() {
        assert!(same_bits(tan(v), out[i]), "tan({v:e}): slice differs");
    }
    for block in x.chunks_exact(4) {
        let lanes = tan_lanes::<4>(block.try_into().unwrap());
        for (i, &v) in block.iter().enumerate() {
            assert!(same_bits(tan(v), lanes[i]), "tan({v:e}): lanes differ");
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

/// A two-argument function's lanes and slices against its scalar bits, over every pairing of
/// the arguments above (the special values against each other and against ordinary ones).
fn pairs_give_the_scalar_bits(
    name: &str,
    scalar: fn(f64, f64) -> f64,
    slice: fn(&[f64], &[f64], &mut [f64]),
    lanes: fn([f64; 4], [f64; 4]) -> [f64; 4],
    seed: u64,
) {
    let first = arguments(4_003, seed);
    let second: Vec<f64> = arguments(4_003, seed + 1).into_iter().rev().collect();
    let special = &first[..20];
    let (mut a, mut b) = (first.clone(), second);
    for &u in special {
        for &v in special {
            a.push(u);
            b.push(v);
        }
    }
    let mut out = vec![0.0; a.len()];
    slice(&a, &b, &mut out);
    for i in 0..a.len() {
        assert!(
            same_bits(scalar(a[i], b[i]), out[i]),
            "{name}({:e}, {:e}): slice differs",
            a[i],
            b[i]
        );
    }
    for (ba, bb) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        let got = lanes(ba.try_into().unwrap(), bb.try_into().unwrap());
        for i in 0..4 {
            assert!(
                same_bits(scalar(ba[i], bb[i]), got[i]),
                "{name}({:e}, {:e}): lanes differ",
                ba[i],
                bb[i]
            );
        }
    }
}

#[test]
fn atan2_lanes_and_slices_give_the_scalar_bits() {
    pairs_give_the_scalar_bits("atan2", atan2, atan2_slice, atan2_lanes::<4>, 5);
}

#[test]
fn hypot_lanes_and_slices_give_the_scalar_bits() {
    pairs_give_the_scalar_bits("hypot", hypot, hypot_slice, hypot_lanes::<4>, 7);
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
    // atan2: the signs of zeros count; infinities give the octants.
    let pi = std::f64::consts::PI;
    let pio2 = std::f64::consts::FRAC_PI_2;
    assert!(same_bits(atan2(0.0, 0.0), 0.0));
    assert!(same_bits(atan2(-0.0, 0.0), -0.0));
    assert_eq!(atan2(0.0, -0.0), pi);
    assert_eq!(atan2(-0.0, -0.0), -pi);
    assert_eq!(atan2(0.0, -1.0), pi);
    assert_eq!(atan2(-0.0, -1.0), -pi);
    assert_eq!(atan2(1.0, 0.0), pio2);
    assert_eq!(atan2(-1.0, -0.0), -pio2);
    assert_eq!(atan2(inf, inf), std::f64::consts::FRAC_PI_4);
    assert_eq!(atan2(-inf, -inf), -3.0 * std::f64::consts::FRAC_PI_4);
    assert_eq!(atan2(1.0, -inf), pi);
    assert!(same_bits(atan2(-1.0, inf), -0.0));
    assert_eq!(atan2(inf, 1.0), pio2);
    assert!(atan2(nan, 1.0).is_nan() && atan2(1.0, nan).is_nan());
    assert_eq!(atan2(1.0, 1.0), std::f64::consts::FRAC_PI_4);
    assert_eq!(atan2(5e-324, 1.0), 5e-324);
    assert_eq!(atan2(1e-300, -1.0), pi);
    assert_eq!(atan2(1e300, 1e-300), pio2);
    // hypot: an infinity wins over NaN; no overflow or underflow on the way.
    assert_eq!(hypot(inf, nan), inf);
    assert_eq!(hypot(nan, -inf), inf);
    assert!(hypot(nan, 1.0).is_nan());
    assert_eq!(hypot(0.0, -0.0), 0.0);
    assert_eq!(hypot(3.0, -4.0), 5.0);
    assert_eq!(hypot(3e300, 4e300), 5e300);
    assert_eq!(hypot(3e-320, 4e-320), 5e-320);
    assert_eq!(hypot(-5e-324, 0.0), 5e-324);
    assert_eq!(hypot(f64::MAX, 1.0), f64::MAX);
    // tan and atan: odd, exact at zero, NaN where C99 says.
    assert!(same_bits(tan(-0.0), -0.0) && tan(0.0) == 0.0);
    assert!(tan(inf).is_nan() && tan(nan).is_nan());
    assert_eq!(tan(std::f64::consts::FRAC_PI_4), 0.9999999999999999);
    assert_eq!(tan(1e-300), 1e-300);
    assert!(same_bits(atan(-0.0), -0.0));
    assert_eq!(atan(inf), pio2);
    assert_eq!(atan(-inf), -pio2);
    assert_eq!(atan(1.0), std::f64::consts::FRAC_PI_4);
    assert!(atan(nan).is_nan());
}
