//! `exp` and `pow`: `pow(x, y) = exp(y·ln x)` with `ln x` and the product carried in two
//! doubles (about 2^-65 relative), `exp` of a two-double argument by `k·ln 2 + r`, |r| ≤ ln 2/2,
//! and a Taylor polynomial.
//!
//! The kernels are branch-free for the common case (positive normal `x`, finite `y`, a
//! result in the normal range); everything else (zeros, negative bases, infinities, NaN,
//! subnormals, overflow and underflow) goes through the `slow` functions, which the scalar
//! functions and the lanes both call.

use crate::dd::{add, fast_two_sum, mul, select, two_prod, two_sum};

/// ln 2 with 41 significant bits (k·LN2_HI is exact for |k| < 2^12) and the rest.
const LN2_HI: f64 = f64::from_bits(0x3fe6_2e42_fefa_3800);
const LN2_LO: f64 = f64::from_bits(0x3d2e_f357_93c7_6730);
/// ln 2 in two doubles (for k·ln 2 with a 64-bit product).
const LN2: (f64, f64) = (
    f64::from_bits(0x3fe6_2e42_fefa_39ef),
    f64::from_bits(0x3c7a_bc9e_3b39_803f),
);
const INV_LN2: f64 = f64::from_bits(0x3ff7_1547_652b_82fe);
const ROUNDER: f64 = 6_755_399_441_055_744.0;
/// exp's kernel bound: |k| ≤ 1021 keeps 2^k and the result normal.
const EXP_FAST_LIMIT: f64 = 707.0;

/// 1/n!, n = 3..16: on |r| ≤ ln 2/2 the first term left out is below 2^-74 of exp r.
const EXP: [f64; 14] = [
    1.0 / 6.0,
    1.0 / 24.0,
    1.0 / 120.0,
    1.0 / 720.0,
    1.0 / 5_040.0,
    1.0 / 40_320.0,
    1.0 / 362_880.0,
    1.0 / 3_628_800.0,
    1.0 / 39_916_800.0,
    1.0 / 479_001_600.0,
    1.0 / 6_227_020_800.0,
    1.0 / 87_178_291_200.0,
    1.0 / 1_307_674_368_000.0,
    1.0 / 20_922_789_888_000.0,
];

/// 2/(2j+1), j = 2..14 (the atanh series of ln past its cubic term; |s| ≤ 0.1716 leaves
/// below 2^-70).
const LN: [f64; 13] = [
    2.0 / 5.0,
    2.0 / 7.0,
    2.0 / 9.0,
    2.0 / 11.0,
    2.0 / 13.0,
    2.0 / 15.0,
    2.0 / 17.0,
    2.0 / 19.0,
    2.0 / 21.0,
    2.0 / 23.0,
    2.0 / 25.0,
    2.0 / 27.0,
    2.0 / 29.0,
];
/// 2/3 in two doubles.
const TWO_THIRDS: (f64, f64) = (
    f64::from_bits(0x3fe5_5555_5555_5555),
    f64::from_bits(0x3c85_5555_5555_5555),
);

/// exp(hi + lo) = value · 2^k with value in [√½, √2] within one rounding of the value (the
/// polynomial's sum is compensated up to the final addition), for |hi| < 2^51·ln 2 and
/// |lo| ≤ 2^-40·|hi|.
#[inline(always)]
fn exp_parts(hi: f64, lo: f64) -> (f64, f64, u64) {
    let t = hi * INV_LN2 + ROUNDER;
    let k = t - ROUNDER;
    // r = hi − k·ln 2 + lo: the first difference is exact.
    let (r, e) = two_sum(hi - k * LN2_HI, -(k * LN2_LO));
    // lo may be as large as r's last place times hi: folded into r's head and tail first, so
    // that the tail's product with exp r needs only its first-order term.
    let (r, r_lo) = two_sum(r, e + lo);
    // exp(r + r_lo) = 1 + r + r²/2 + r³·P(r) + r_lo·exp(r), with r² exact.
    let mut p = EXP[13];
    for c in EXP[..13].iter().rev() {
        p = *c + r * p;
    }
    let (sq, sq_lo) = two_prod(r, r);
    let tail = r * sq * p;
    let (s, s_lo) = two_sum(1.0, r);
    let small = 0.5 * sq + (s_lo + (tail + 0.5 * sq_lo + r_lo * (1.0 + r)));
    (s + small, k, t.to_bits())
}

/// exp(hi + lo) for |hi| ≤ [`EXP_FAST_LIMIT`], where 2^k and the result are normal.
#[inline(always)]
fn exp_kernel(hi: f64, lo: f64) -> f64 {
    let (value, _, t_bits) = exp_parts(hi, lo);
    // 2^k as a double: k's low 12 bits from the rounder, moved into the exponent field.
    let scale = f64::from_bits((t_bits & 0xfff).wrapping_add(1023) << 52);
    value * scale
}

/// ln x in two doubles for a positive normal `x`, to about 2^-65 relative (any other `x` gives
/// a meaningless but finite-or-NaN answer, which [`pow_in_kernel`] then sends elsewhere).
#[inline(always)]
pub(crate) fn ln_kernel(x: f64) -> (f64, f64) {
    let bits = x.to_bits();
    let exponent = ((bits >> 52) as i64 - 1023) as f64;
    let m = f64::from_bits((bits & 0x000f_ffff_ffff_ffff) | 0x3ff0_0000_0000_0000);
    // m in [√½, √2).
    let big = m > std::f64::consts::SQRT_2;
    let m = select(big, 0.5 * m, m);
    let exponent = select(big, exponent + 1.0, exponent);
    // s = (m − 1)/(m + 1) in two doubles: m − 1 is exact, m + 1 kept in two.
    let f = m - 1.0;
    let (d, d_lo) = two_sum(m, 1.0);
    let s = f / d;
    let (p, p_lo) = two_prod(s, d);
    let s_lo = (((f - p) - p_lo) - s * d_lo) / d;
    // ln m = 2s + s³·(2/3 + s²·R(s²)).
    let (s2, s2_lo) = two_prod(s, s);
    let s2_lo = s2_lo + 2.0 * s * s_lo;
    let mut r = LN[12];
    for c in LN[..12].iter().rev() {
        r = *c + s2 * r;
    }
    let c = add(TWO_THIRDS, (s2 * r, 0.0));
    let s3 = mul((s2, s2_lo), (s, s_lo));
    let tail = mul(s3, c);
    let (e_hi, e_lo) = two_prod(exponent, LN2.0);
    let scaled = fast_two_sum(e_hi, e_lo + exponent * LN2.1);
    add(add(scaled, (2.0 * s, 2.0 * s_lo)), tail)
}

/// exp x for |x| ≤ [`EXP_FAST_LIMIT`].
#[inline(always)]
pub(crate) fn exp_in_kernel(x: f64) -> bool {
    x.abs() <= EXP_FAST_LIMIT
}

#[inline(always)]
pub(crate) fn exp(x: f64) -> f64 {
    exp_kernel(x, 0.0)
}

/// exp of any double.
#[cold]
#[inline(never)]
pub(crate) fn exp_slow(x: f64) -> f64 {
    exp_any(x, 0.0)
}

/// exp(hi + lo) for any `hi`: overflow to +∞, underflow through the subnormals to 0.
fn exp_any(hi: f64, lo: f64) -> f64 {
    if hi.is_nan() {
        return hi;
    }
    if hi > 709.8 {
        return f64::INFINITY;
    }
    if hi < -745.2 {
        return 0.0;
    }
    if exp_in_kernel(hi) {
        return exp_kernel(hi, lo);
    }
    // 2^k out of the kernel's range: the value scaled in two factors (a subnormal result is
    // rounded twice, still within one unit of its last place).
    let (value, k, _) = exp_parts(hi, lo);
    let half = (k / 2.0).trunc();
    value * 2f64.powi(half as i32) * 2f64.powi((k - half) as i32)
}

/// Whether [`pow_kernel`] gives pow(x, y): x positive and normal, y finite, y·ln x within
/// exp's kernel.
#[inline(always)]
pub(crate) fn pow_in_kernel(x: f64, y: f64, ln: (f64, f64)) -> bool {
    (f64::MIN_POSITIVE..f64::INFINITY).contains(&x) && y.abs() < 1e290 && (y * ln.0).abs() <= EXP_FAST_LIMIT
}

/// pow(x, y) from ln x in two doubles.
#[inline(always)]
pub(crate) fn pow_kernel(y: f64, ln: (f64, f64)) -> f64 {
    let (z, z_lo) = times(y, ln);
    exp_kernel(z, z_lo)
}

/// y·(hi + lo) in two doubles (|y| < 2^995).
#[inline(always)]
fn times(y: f64, (hi, lo): (f64, f64)) -> (f64, f64) {
    let (z, z_lo) = two_prod(y, hi);
    fast_two_sum(z, z_lo + y * lo)
}

/// pow of any two doubles, with C99's special cases (pow(x, ±0) = 1, pow(1, y) = 1, a negative
/// base to an integer power, zeros and infinities as Annex F says).
#[cold]
#[inline(never)]
pub(crate) fn pow_slow(x: f64, y: f64) -> f64 {
    if y == 0.0 || x == 1.0 {
        return 1.0;
    }
    if x.is_nan() || y.is_nan() {
        return f64::NAN;
    }
    let y_integer = y.trunc() == y;
    let y_odd = y_integer && y.abs() < 9.007_199_254_740_992e15 && (y % 2.0).abs() == 1.0;
    if y.is_infinite() {
        let ax = x.abs();
        return if ax == 1.0 {
            1.0
        } else if (ax < 1.0) == (y < 0.0) {
            f64::INFINITY
        } else {
            0.0
        };
    }
    if x == 0.0 {
        let magnitude = if y < 0.0 { f64::INFINITY } else { 0.0 };
        return if y_odd { magnitude.copysign(x) } else { magnitude };
    }
    if x.is_infinite() {
        let magnitude = if y < 0.0 { 0.0 } else { f64::INFINITY };
        return if x < 0.0 && y_odd { -magnitude } else { magnitude };
    }
    if x < 0.0 {
        if !y_integer {
            return f64::NAN;
        }
        let magnitude = pow_slow(-x, y);
        return if y_odd { -magnitude } else { magnitude };
    }
    // x positive and finite; subnormal x scaled into the normal range: ln x = ln(x·2^64) − 64 ln 2.
    let ln = if x < f64::MIN_POSITIVE {
        let (h, l) = ln_kernel(x * 2f64.powi(64));
        let (c, c_lo) = two_prod(64.0, LN2.0);
        add((h, l), (-c, -(c_lo + 64.0 * LN2.1)))
    } else {
        ln_kernel(x)
    };
    if y.abs() >= 1e290 {
        return if (ln.0 > 0.0) == (y > 0.0) {
            f64::INFINITY
        } else {
            0.0
        };
    }
    let (z, z_lo) = times(y, ln);
    exp_any(z, z_lo)
}
