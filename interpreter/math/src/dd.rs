//! Error-free transformations without FMA: the sums and products this crate carries in two
//! doubles (a head and a tail whose sum is the value to about 106 bits).
//!
//! Every function is a fixed sequence of IEEE additions and multiplications, each rounded
//! once: Rust never contracts `a * b + c` into a fused multiply-add, so the same sequence gives
//! the same bits in a scalar register and in any SIMD lane.

/// Veltkamp's constant 2^27 + 1: splits a double into two 26-bit halves.
const SPLITTER: f64 = 134_217_729.0;

/// `a + b = s + e` exactly (Knuth's TwoSum, any order of magnitudes).
#[inline(always)]
pub(crate) fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    let e = (a - (s - bb)) + (b - bb);
    (s, e)
}

/// `a + b = s + e` exactly when `|a| ≥ |b|` (or `a` is zero) (Dekker's Fast2Sum).
#[inline(always)]
pub(crate) fn fast_two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let e = b - (s - a);
    (s, e)
}

/// `a = hi + lo` with both halves of at most 26 significant bits (|a| < 2^995).
#[inline(always)]
fn split(a: f64) -> (f64, f64) {
    let t = SPLITTER * a;
    let hi = t - (t - a);
    (hi, a - hi)
}

/// `a · b = p + e` exactly (Dekker's TwoProduct; |a|, |b| < 2^995, no underflow).
#[inline(always)]
pub(crate) fn two_prod(a: f64, b: f64) -> (f64, f64) {
    let p = a * b;
    let (ah, al) = split(a);
    let (bh, bl) = split(b);
    let e = ((ah * bh - p) + ah * bl + al * bh) + al * bl;
    (p, e)
}

/// `(a_hi + a_lo) + (b_hi + b_lo)` to about 106 bits, normalised.
#[inline(always)]
pub(crate) fn add(a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
    let (s, e) = two_sum(a.0, b.0);
    let e = e + (a.1 + b.1);
    fast_two_sum(s, e)
}

/// `(a_hi + a_lo) · (b_hi + b_lo)` to about 104 bits, normalised.
#[inline(always)]
pub(crate) fn mul(a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
    let (p, e) = two_prod(a.0, b.0);
    let e = e + (a.0 * b.1 + a.1 * b.0);
    fast_two_sum(p, e)
}

/// `v` if `choose`, else `w`: a select the vectoriser turns into a blend.
#[inline(always)]
pub(crate) fn select(choose: bool, v: f64, w: f64) -> f64 {
    if choose { v } else { w }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_transformations_are_exact_where_the_sums_can_be_checked() {
        // 1 + 2^-60 cannot be a double; its tail keeps the part that was lost.
        let tiny = 2f64.powi(-60);
        assert_eq!(two_sum(1.0, tiny), (1.0, tiny));
        assert_eq!(two_sum(tiny, 1.0), (1.0, tiny));
        assert_eq!(fast_two_sum(1.0, tiny), (1.0, tiny));
        // (1 + 2^-30)² = 1 + 2^-29 + 2^-60.
        let a = 1.0 + 2f64.powi(-30);
        assert_eq!(two_prod(a, a), (1.0 + 2f64.powi(-29), tiny));
        // (1 + 2^-40)(1 - 2^-40) = 1 - 2^-80.
        let (p, e) = two_prod(1.0 + 2f64.powi(-40), 1.0 - 2f64.powi(-40));
        assert_eq!((p, e), (1.0, -(2f64.powi(-80))));
        assert_eq!(add((1.0, tiny), (1.0, tiny)), (2.0, 2.0 * tiny));
        assert_eq!(mul((2.0, tiny), (3.0, 0.0)), (6.0, 3.0 * tiny));
    }
}
