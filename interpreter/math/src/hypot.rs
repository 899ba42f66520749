//! `hypot(x, y) = √(x² + y²)`: the sum of the squares in two doubles (Dekker's exact squares),
//! its square root corrected once by a Newton step carried in two doubles, then rounded once:
//! within half an ulp and a hair of the exact value.
//!
//! [`kernel`] is branch-free when the larger magnitude lies in [2^-500, 2^500] (no square
//! overflows or leaves the normal range); infinities, NaN, zeros and the rest go through
//! [`slow`], which scales by 2^±600 (exactly) around the kernel.

use crate::dd::{add, select, two_prod};

/// The kernel's range of the larger magnitude.
const LOW: f64 = f64::from_bits(0x20b0_0000_0000_0000); // 2^-500
const HIGH: f64 = f64::from_bits(0x5f30_0000_0000_0000); // 2^500
/// The slow path's scales.
const UP: f64 = f64::from_bits(0x6570_0000_0000_0000); // 2^600
const DOWN: f64 = f64::from_bits(0x1a70_0000_0000_0000); // 2^-600

/// Whether [`kernel`] gives the answer: both finite and the larger magnitude in its range.
#[inline(always)]
pub(crate) fn in_kernel(x: f64, y: f64) -> bool {
    let (ax, ay) = (x.abs(), y.abs());
    let larger = select(ax >= ay, ax, ay);
    (ax <= HIGH) & (ay <= HIGH) & (larger >= LOW)
}

/// √(x² + y²) for arguments [`in_kernel`] accepts.
#[inline(always)]
pub(crate) fn kernel(x: f64, y: f64) -> f64 {
    let (ax, ay) = (x.abs(), y.abs());
    let larger = select(ax >= ay, ax, ay);
    let smaller = select(ax >= ay, ay, ax);
    let (s, s_tail) = add(two_prod(larger, larger), two_prod(smaller, smaller));
    let root = s.sqrt();
    // s − root² exactly (root² is within an ulp of s), then the tail: the Newton step's residual.
    let (square, square_tail) = two_prod(root, root);
    let residual = ((s - square) - square_tail) + s_tail;
    root + residual / (root + root)
}

/// hypot for any arguments: C99 Annex F's special values (an infinity wins over NaN), else the
/// kernel on arguments scaled by an exact power of two.
#[cold]
#[inline(never)]
pub(crate) fn slow(x: f64, y: f64) -> f64 {
    if x.is_infinite() || y.is_infinite() {
        return f64::INFINITY;
    }
    if x.is_nan() || y.is_nan() {
        return f64::NAN;
    }
    let larger = x.abs().max(y.abs());
    if larger == 0.0 {
        0.0
    } else if larger > HIGH {
        // The smaller may lose bits below 2^-1022 here: it is then below 2^-900 of the larger.
        kernel(x * DOWN, y * DOWN) * UP
    } else {
        // A subnormal result is rounded a second time by the scaling back (within one ulp).
        kernel(x * UP, y * UP) * DOWN
    }
}
