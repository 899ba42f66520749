//! `atan2(y, x)`: the ratio `t` of the smaller magnitude to the larger in two doubles, `t`
//! reduced around the nearest `c = k/8` (`r = (t − c)/(1 + t·c)`, |r| ≤ 1/16, in two doubles),
//! `atan r` by its Taylor series, `atan(k/8)` from a table in two doubles, then the octant
//! (`π/2 − θ` when |y| > |x|, `π − θ` when x is negative) in two doubles, rounded once, and the
//! sign of `y` last.
//!
//! [`kernel`] is branch-free when both magnitudes lie in [2^-500, 2^500] (or the smaller is
//! zero); NaN, infinities, zeros and the rest go through [`slow`], which scales both arguments
//! by one exact power of two around the kernel or answers a vanishing ratio directly.

use crate::dd::{add, fast_two_sum, select, two_prod};

/// The kernel's range of the magnitudes.
const LOW: f64 = f64::from_bits(0x20b0_0000_0000_0000); // 2^-500
const HIGH: f64 = f64::from_bits(0x5f30_0000_0000_0000); // 2^500
/// 1.5·2^52: adding it rounds a double of magnitude < 2^51 to an integer.
const ROUNDER: f64 = 6_755_399_441_055_744.0;
/// π and π/2 in two doubles.
const PI: (f64, f64) = (
    f64::from_bits(0x4009_21fb_5444_2d18),
    f64::from_bits(0x3ca1_a626_3314_5c07),
);
const PIO2: (f64, f64) = (
    f64::from_bits(0x3ff9_21fb_5444_2d18),
    f64::from_bits(0x3c91_a626_3314_5c07),
);
/// 3π/4 rounded.
const THREE_PIO4: f64 = f64::from_bits(0x4002_d97c_7f33_21d2);
/// atan(k/8), k = 0..8, in two doubles (the head rounded, the tail the rest; mpmath at 300 bits).
const ATAN_EIGHTHS: [(f64, f64); 9] = [
    (0.0, 0.0),
    (
        f64::from_bits(0x3fbf_d5ba_9aac_2f6e),
        f64::from_bits(0xbc4c_d376_8676_0c17),
    ),
    (
        f64::from_bits(0x3fcf_5b75_f92c_80dd),
        f64::from_bits(0x3c68_ab6e_3cf7_afbd),
    ),
    (
        f64::from_bits(0x3fd6_f619_41e4_def1),
        f64::from_bits(0xbc7c_63aa_e6f6_e918),
    ),
    (
        f64::from_bits(0x3fdd_ac67_0561_bb4f),
        f64::from_bits(0x3c7a_2b7f_222f_65e2),
    ),
    (
        f64::from_bits(0x3fe1_e00b_abde_feb4),
        f64::from_bits(0xbc59_28df_287a_668f),
    ),
    (
        f64::from_bits(0x3fe4_978f_a326_9ee1),
        f64::from_bits(0x3c72_419a_87f2_a458),
    ),
    (
        f64::from_bits(0x3fe7_00a7_c578_4634),
        f64::from_bits(0xbc78_c34d_25aa_def6),
    ),
    (
        f64::from_bits(0x3fe9_21fb_5444_2d18),
        f64::from_bits(0x3c81_a626_3314_5c07),
    ),
];
/// (−1)^j/(2j+1), j = 1..7: on |r| ≤ 1/16 the first term left out is below 2^-68 of atan r.
const ATAN: [f64; 7] = [
    -1.0 / 3.0,
    1.0 / 5.0,
    -1.0 / 7.0,
    1.0 / 9.0,
    -1.0 / 11.0,
    1.0 / 13.0,
    -1.0 / 15.0,
];

/// Whether [`kernel`] gives the answer: both finite, the larger magnitude in its range and the
/// smaller in it too or zero.
#[inline(always)]
pub(crate) fn in_kernel(y: f64, x: f64) -> bool {
    let (ay, ax) = (y.abs(), x.abs());
    let swap = ay > ax;
    let larger = select(swap, ay, ax);
    let smaller = select(swap, ax, ay);
    (ax <= HIGH) & (ay <= HIGH) & (larger >= LOW) & ((smaller >= LOW) | (smaller == 0.0))
}

/// `(a_hi + a_lo) − (b_hi + b_lo)` in two doubles.
#[inline(always)]
fn sub(a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
    add(a, (-b.0, -b.1))
}

/// atan2(y, x) for arguments [`in_kernel`] accepts.
#[inline(always)]
pub(crate) fn kernel(y: f64, x: f64) -> f64 {
    let (ay, ax) = (y.abs(), x.abs());
    let swap = ay > ax;
    let larger = select(swap, ay, ax);
    let smaller = select(swap, ax, ay);
    // t = smaller/larger ∈ [0, 1] in two doubles.
    let t = smaller / larger;
    let (product, product_tail) = two_prod(t, larger);
    let t_tail = ((smaller - product) - product_tail) / larger;
    // c = k/8 nearest t: t − c is exact (Sterbenz, or c = 0) and a multiple of t's last place.
    let eighths = (t * 8.0 + ROUNDER) - ROUNDER;
    let c = eighths * 0.125;
    let numerator = fast_two_sum(t - c, t_tail);
    let (tc, tc_tail) = two_prod(t, c);
    let denominator = add((1.0, 0.0), (tc, tc_tail + t_tail * c));
    // r = numerator/denominator in two doubles, |r| ≤ 1/16.
    let r = numerator.0 / denominator.0;
    let (q, q_tail) = two_prod(r, denominator.0);
    let r_tail = (((numerator.0 - q) - q_tail) + numerator.1 - r * denominator.1) / denominator.0;
    let z = r * r;
    let mut p = ATAN[6];
    for coefficient in ATAN[..6].iter().rev() {
        p = *coefficient + z * p;
    }
    let atan_r = fast_two_sum(r, r_tail + r * (z * p));
    // atan(k/8) by blends, not an index: a lane-wise load the vectoriser keeps in registers.
    let mut atan_c = (0.0, 0.0);
    for (k, &value) in ATAN_EIGHTHS.iter().enumerate().skip(1) {
        atan_c = select_pair(eighths == k as f64, value, atan_c);
    }
    let theta = add(atan_c, atan_r);
    let theta = select_pair(swap, sub(PIO2, theta), theta);
    let theta = select_pair(x.is_sign_negative(), sub(PI, theta), theta);
    theta.0.copysign(y)
}

#[inline(always)]
fn select_pair(choose: bool, v: (f64, f64), w: (f64, f64)) -> (f64, f64) {
    (select(choose, v.0, w.0), select(choose, v.1, w.1))
}

/// atan2 for any arguments: C99 Annex F's special values, else the kernel on arguments scaled by
/// one power of two (the ratio does not change), or, for a ratio below 2^-500 (where atan t
/// rounds to t), the ratio's octant directly.
#[cold]
#[inline(never)]
pub(crate) fn slow(y: f64, x: f64) -> f64 {
    if x.is_nan() || y.is_nan() {
        return x + y;
    }
    let negative_x = x.is_sign_negative();
    let theta = if x.is_infinite() && y.is_infinite() {
        select(negative_x, THREE_PIO4, PI.0 / 4.0)
    } else if x.is_infinite() {
        select(negative_x, PI.0, 0.0)
    } else if y.is_infinite() {
        PIO2.0
    } else if x == 0.0 && y == 0.0 {
        select(negative_x, PI.0, 0.0)
    } else {
        let (ay, ax) = (y.abs(), x.abs());
        let swap = ay > ax;
        let (larger, smaller) = if swap { (ay, ax) } else { (ax, ay) };
        if smaller == 0.0 || smaller / larger < LOW {
            // atan t = t to far below the last place; π/2 ± t and π ± t round to π/2 and π.
            match (swap, negative_x) {
                (false, false) => smaller / larger,
                (false, true) => PI.0,
                (true, _) => PIO2.0,
            }
        } else {
            // Both scaled by the larger's power of two (exact unless the smaller falls below
            // the normals, which then holds fewer bits than the ratio's last place needs only
            // below 2^-500, answered above).
            let exponent = ((larger.to_bits() >> 52) & 0x7ff) as i64 - 1023;
            let half = f64::from_bits(((1023 - exponent / 2) as u64) << 52);
            let rest = f64::from_bits(((1023 - (exponent - exponent / 2)) as u64) << 52);
            return kernel(y * half * rest, x * half * rest);
        }
    };
    theta.copysign(y)
}
