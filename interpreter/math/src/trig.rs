//! `sin`, `cos`, `sin_cos` and `tan`: the argument reduced to `r = x − k·π/2` in two doubles, then a
//! polynomial on |r| ≤ π/4 and the quadrant `k mod 4`.
//!
//! [`kernel`] is branch-free for |x| < 2^20·π/2 (Cody–Waite reduction with π/2 in four parts);
//! larger, infinite and NaN arguments go through [`slow`] (Payne–Hanek reduction with 1,216 bits
//! of 2/π), which the scalar function and the lanes both call, so every path gives the same bits.

use crate::dd::{fast_two_sum, select, two_prod, two_sum};

/// 2/π rounded.
const TWO_OVER_PI: f64 = f64::from_bits(0x3fe4_5f30_6dc9_c883);
/// π/2 in four parts: the first three of 33 bits (k·part is exact for |k| < 2^20), the last of
/// 53; their sum is π/2 to about 2^-160.
const PIO2_1: f64 = f64::from_bits(0x3ff9_21fb_5440_0000);
const PIO2_2: f64 = f64::from_bits(0x3dd0_b461_1a60_0000);
const PIO2_3: f64 = f64::from_bits(0x3ba3_198a_2e00_0000);
const PIO2_4: f64 = f64::from_bits(0x397b_839a_2520_49c1);
/// π/2 in two doubles (for the Payne–Hanek fraction).
const PIO2_HI: f64 = f64::from_bits(0x3ff9_21fb_5444_2d18);
const PIO2_LO: f64 = f64::from_bits(0x3c91_a626_3314_5c07);
/// 1.5·2^52: adding it rounds a double of magnitude < 2^51 to an integer held in the low bits.
const ROUNDER: f64 = 6_755_399_441_055_744.0;
/// The fast reduction's bound: |k| < 2^20 keeps k·PIO2_{1,2,3} exact.
pub(crate) const FAST_LIMIT: f64 = 1_647_099.0; // < 2^20·π/2 ≈ 1,647,099.3
/// Below it sin x rounds to x and cos x to 1.
const TINY: f64 = 1.0 / 134_217_728.0; // 2^-27

/// Taylor coefficients (−1)^j/(2j+1)! of sin, j = 1..9, and (−1)^j/(2j)! of cos, j = 2..10:
/// on |r| ≤ π/4 the first term left out is below 2^-72 of the value.
const SIN: [f64; 9] = [
    -1.0 / 6.0,
    1.0 / 120.0,
    -1.0 / 5_040.0,
    1.0 / 362_880.0,
    -1.0 / 39_916_800.0,
    1.0 / 6_227_020_800.0,
    -1.0 / 1_307_674_368_000.0,
    1.0 / 355_687_428_096_000.0,
    -1.0 / 121_645_100_408_832_000.0,
];
const COS: [f64; 9] = [
    1.0 / 24.0,
    -1.0 / 720.0,
    1.0 / 40_320.0,
    -1.0 / 3_628_800.0,
    1.0 / 479_001_600.0,
    -1.0 / 87_178_291_200.0,
    1.0 / 20_922_789_888_000.0,
    -1.0 / 6_402_373_705_728_000.0,
    1.0 / 2_432_902_008_176_640_000.0,
];

/// sin and cos of `x + y` (|x| ≤ π/4 + ε, |y| ≤ 2^-52·|x|), each as a head and a tail whose
/// sum is within one rounding of the value: sin = x + (the polynomial's part), cos =
/// (1 − x²/2) + (the rest).
#[inline(always)]
fn sin_cos_parts(x: f64, y: f64) -> ((f64, f64), (f64, f64)) {
    let z = x * x;
    let v = z * x;
    // sin(x + y) ≈ x + S1·x³ + x⁵·P(x²) + y·(1 − x²/2).
    let mut p = SIN[8];
    for c in SIN[1..8].iter().rev() {
        p = *c + z * p;
    }
    let sin_tail = -((z * (0.5 * y - v * p) - y) - v * SIN[0]);
    // cos(x + y) ≈ (1 − x²/2) + x⁴·Q(x²) − x·y, with x² exact and 1 − x²/2 compensated.
    let mut q = COS[8];
    for c in COS[..8].iter().rev() {
        q = *c + z * q;
    }
    let (zh, zl) = two_prod(x, x);
    let half = 0.5 * zh;
    let w = 1.0 - half;
    let cos_tail = (((1.0 - w) - half) - 0.5 * zl) + (z * (z * q) - x * y);
    ((x, sin_tail), (w, cos_tail))
}

/// sin and cos of `x + y` (|x| ≤ π/4 + ε, |y| ≤ 2^-52·|x|), each within one rounding of the
/// value: the polynomial's tail is added to the head last.
#[inline(always)]
fn sin_cos_reduced(x: f64, y: f64) -> (f64, f64) {
    let ((sin, sin_tail), (cos, cos_tail)) = sin_cos_parts(x, y);
    (sin + sin_tail, cos + cos_tail)
}

/// sin and cos of `k·π/2 + (x + y)` from the quadrant's low two bits.
#[inline(always)]
fn place(quadrant: u64, x: f64, y: f64) -> (f64, f64) {
    let (s, c) = sin_cos_reduced(x, y);
    // Odd quadrants swap sin and cos; the signs come from bit 1 of k and of k + 1. In integer
    // masks rather than branches, which keeps the lanes together.
    let swap = 0u64.wrapping_sub(quadrant & 1);
    let (s, c) = (s.to_bits(), c.to_bits());
    let sin = (c & swap) | (s & !swap);
    let cos = (s & swap) | (c & !swap);
    let sin_sign = (quadrant & 2) << 62;
    let cos_sign = (quadrant.wrapping_add(1) & 2) << 62;
    (f64::from_bits(sin ^ sin_sign), f64::from_bits(cos ^ cos_sign))
}

/// The quadrant's bits and r = x − k·π/2 in two doubles, for |x| < [`FAST_LIMIT`].
#[inline(always)]
pub(crate) fn reduce(x: f64) -> (u64, f64, f64) {
    let t = x * TWO_OVER_PI + ROUNDER;
    let k = t - ROUNDER;
    // r = x − k·π/2: the first product and difference are exact, the next two kept in tails.
    let a = x - k * PIO2_1;
    let (r1, e1) = two_sum(a, -(k * PIO2_2));
    let (r2, e2) = two_sum(r1, -(k * PIO2_3));
    let (rh, rl) = fast_two_sum(r2, (e1 + e2) - k * PIO2_4);
    (t.to_bits(), rh, rl)
}

/// sin and cos of x from its reduction ([`reduce`]); tiny x exactly (x, 1).
#[inline(always)]
pub(crate) fn finish(x: f64, quadrant: u64, rh: f64, rl: f64) -> (f64, f64) {
    let (sin, cos) = place(quadrant, rh, rl);
    let tiny = x.abs() < TINY;
    (select(tiny, x, sin), select(tiny, 1.0, cos))
}

/// sin and cos for |x| < [`FAST_LIMIT`]; straight-line code the vectoriser keeps in lanes.
#[inline(always)]
pub(crate) fn kernel(x: f64) -> (f64, f64) {
    let (quadrant, rh, rl) = reduce(x);
    finish(x, quadrant, rh, rl)
}

/// tan of `k·π/2 + (x + y)` (|x| ≤ π/4 + ε): sin and cos of the reduced argument in two doubles
/// each ([`sin_cos_parts`]), divided in two doubles (−cos/sin in odd quadrants), rounded once.
#[inline(always)]
fn tan_reduced(odd: bool, x: f64, y: f64) -> f64 {
    let (sin, cos) = sin_cos_parts(x, y);
    let (sin, cos) = (fast_two_sum(sin.0, sin.1), fast_two_sum(cos.0, cos.1));
    let numerator = (select(odd, -cos.0, sin.0), select(odd, -cos.1, sin.1));
    let denominator = (select(odd, sin.0, cos.0), select(odd, sin.1, cos.1));
    let t = numerator.0 / denominator.0;
    let (product, product_tail) = two_prod(t, denominator.0);
    t + (((numerator.0 - product) - product_tail) + numerator.1 - t * denominator.1) / denominator.0
}

/// tan for |x| < [`FAST_LIMIT`]; tiny x exactly x.
#[inline(always)]
pub(crate) fn tan_kernel(x: f64) -> f64 {
    let (quadrant, rh, rl) = reduce(x);
    select(x.abs() < TINY, x, tan_reduced(quadrant & 1 == 1, rh, rl))
}

/// Whether [`kernel`] gives the answer for `x` (finite and |x| < [`FAST_LIMIT`]).
#[inline(always)]
pub(crate) fn in_kernel(x: f64) -> bool {
    x.abs() < FAST_LIMIT
}

/// 2/π's first 1,216 bits after the binary point, most significant word first.
const TWO_OVER_PI_BITS: [u64; 19] = [
    0xa2f9_836e_4e44_1529,
    0xfc27_57d1_f534_ddc0,
    0xdb62_9599_3c43_9041,
    0xfe51_63ab_debb_c561,
    0xb724_6e3a_424d_d2e0,
    0x0649_2eea_09d1_921c,
    0xfe1d_eb1c_b129_a73e,
    0xe882_35f5_2ebb_4484,
    0xe99c_7026_b45f_7e41,
    0x3991_d639_8353_39f4,
    0x9c84_5f8b_bdf9_283b,
    0x1ff8_97ff_de05_980f,
    0xef2f_118b_5a0a_6d1f,
    0x6d36_7ecf_27cb_09b7,
    0x4f46_3f66_9e5f_ea2d,
    0x7527_bac7_ebe5_f17b,
    0x3d07_39f7_8a52_92ea,
    0x6bfb_5fb1_1f8d_5d08,
    0x5603_3046_fc7b_6bab,
];

/// The 64 bits of 2/π after the binary point starting at bit `start` (bit 0 is the first).
fn two_over_pi_word(start: usize) -> u64 {
    let (word, shift) = (start / 64, start % 64);
    let high = TWO_OVER_PI_BITS[word] << shift;
    if shift == 0 {
        high
    } else {
        high | (TWO_OVER_PI_BITS[word + 1] >> (64 - shift))
    }
}

/// sin and cos of any double: NaN for infinities and NaN, Payne–Hanek reduction for
/// |x| ≥ [`FAST_LIMIT`].
#[cold]
#[inline(never)]
pub(crate) fn slow(x: f64) -> (f64, f64) {
    if !x.is_finite() {
        return (f64::NAN, f64::NAN);
    }
    if in_kernel(x) {
        return kernel(x);
    }
    let (quadrant, rh, rl) = reduce_large(x.abs());
    let (sin, cos) = place(quadrant, rh, rl);
    if x < 0.0 { (-sin, cos) } else { (sin, cos) }
}

/// tan of any double: NaN for infinities and NaN, Payne–Hanek reduction for
/// |x| ≥ [`FAST_LIMIT`].
#[cold]
#[inline(never)]
pub(crate) fn tan_slow(x: f64) -> f64 {
    if !x.is_finite() {
        return f64::NAN;
    }
    if in_kernel(x) {
        return tan_kernel(x);
    }
    let (quadrant, rh, rl) = reduce_large(x.abs());
    let tan = tan_reduced(quadrant & 1 == 1, rh, rl);
    if x < 0.0 { -tan } else { tan }
}

/// The quadrant's bits and r = |x| − k·π/2 in two doubles for a finite |x| ≥ [`FAST_LIMIT`]
/// (Payne–Hanek: the bits of 2/π that matter for |x|'s exponent).
fn reduce_large(x: f64) -> (u64, f64, f64) {
    // |x| = m·2^s with m a 53-bit integer, s ≥ −32. The bits of 2/π before position s − 2
    // add multiples of 4 to x·2/π: they change nothing.
    let bits = x.to_bits();
    let m = (bits & ((1 << 52) - 1)) | (1 << 52);
    let s = ((bits >> 52) as i64) - 1075;
    let first = (s - 2).max(0) as usize;
    // x·2/π ≈ m · W · 2^(s − first − 192), W the 192 bits of 2/π from `first` on.
    let window = [
        two_over_pi_word(first),
        two_over_pi_word(first + 64),
        two_over_pi_word(first + 128),
    ];
    // m·W in four 64-bit limbs, least significant first.
    let mut limbs = [0u64; 4];
    let mut carry = 0u128;
    for (i, word) in window.iter().rev().enumerate() {
        let product = u128::from(m) * u128::from(*word) + carry;
        limbs[i] = product as u64;
        carry = product >> 64;
    }
    limbs[3] = carry as u64;
    let product = (
        u128::from(limbs[3]) << 64 | u128::from(limbs[2]),
        u128::from(limbs[1]) << 64 | u128::from(limbs[0]),
    );
    // The binary point sits `point` bits above the product's least significant bit.
    let point = (first as i64 + 192 - s) as u32; // 190 ..= 224
    let bit = |n: u32| -> u128 {
        // The 128 bits of the product from bit n upwards (n < 256).
        if n >= 128 {
            product.0 >> (n - 128)
        } else if n == 0 {
            product.1
        } else {
            (product.0 << (128 - n)) | (product.1 >> n)
        }
    };
    let mut quadrant = (bit(point) & 3) as u64;
    let fraction = bit(point - 128); // the 128 bits after the point
    // Round to the nearest quadrant: the fraction in [−1/2, 1/2) of a quadrant.
    let signed = fraction as i128; // wraps fractions ≥ 1/2 to negative, as the rounding wants
    if fraction >> 127 == 1 {
        quadrant += 1;
    }
    let head = signed as f64;
    let tail = (signed - head as i128) as f64;
    let scale = 2f64.powi(-128);
    let (f_hi, f_lo) = fast_two_sum(head * scale, tail * scale);
    let (p, e) = two_prod(f_hi, PIO2_HI);
    let (rh, rl) = fast_two_sum(p, e + (f_hi * PIO2_LO + f_lo * PIO2_HI));
    (quadrant, rh, rl)
}
