//! `f64` written as Rust's `Display` writes it (the shortest digits that read back to the same
//! number, positional, no exponent: `0.1`, `1`, `-0`, `0.0000001`), but from Schubfach's
//! digits (`zmij`), several times faster than `core::fmt`'s Grisu with its Dragon fallback.
//! `trajectory.csv` is written this way: the same bytes as `to_string()` (tested on random
//! bit patterns), in a fraction of the time a run's recording took to format.
//!
//! Both give the shortest digits closest to the value; they differ only where two candidates
//! are equally close (Schubfach rounds the tie to even, `core::fmt` up). A tie needs the exact
//! value to have at most 18 significant digits, which a finite `x = m·2^e` (m odd) has only
//! when −25 ≤ e < 0 (for e < −25 the expansion m·5^−e has at least 19 digits) or when x is an
//! integer of at least 2^53 (below, every integer is a double and its own shortest form). Those
//! values, rare in a recording (0.5, 0.25, huge integers), are written by `core::fmt` itself.

/// Appends `x` to `out` exactly as `format!("{x}")` would write it.
pub fn push_display(out: &mut Vec<u8>, x: f64) {
    if x.is_nan() {
        out.extend_from_slice(b"NaN");
        return;
    }
    if x.is_sign_negative() {
        out.push(b'-');
    }
    if x.is_infinite() {
        out.extend_from_slice(b"inf");
        return;
    }
    if may_tie(x) {
        use std::io::Write as _;
        // Writing to a Vec cannot fail.
        let _ = write!(out, "{}", x.abs());
        return;
    }
    let mut buffer = zmij::Buffer::new();
    let shortest = buffer.format_finite(x.abs()).as_bytes();
    // `shortest` is `I[.F][e±E]`: the digits I and F, the point after I, then 10^E. Written
    // positionally (most values), it is `Display`'s but for an integer's `.0`.
    let (mantissa, exponent) = match shortest.iter().position(|&b| b == b'e') {
        Some(e) => (&shortest[..e], parse_exponent(&shortest[e + 1..])),
        None => {
            out.extend_from_slice(shortest.strip_suffix(b".0").unwrap_or(shortest));
            return;
        }
    };
    let mut digits = [0u8; 32];
    let mut count = 0;
    let mut point = None;
    for &b in mantissa {
        if b == b'.' {
            point = Some(count);
        } else {
            digits[count] = b;
            count += 1;
        }
    }
    // The value is 0.d₁d₂… × 10^point once leading zeros are gone.
    let mut point = point.unwrap_or(count) as i64 + exponent;
    let mut first = 0;
    while first < count && digits[first] == b'0' {
        first += 1;
        point -= 1;
    }
    while count > first && digits[count - 1] == b'0' {
        count -= 1;
    }
    let digits = &digits[first..count];
    if digits.is_empty() {
        out.push(b'0');
    } else if point <= 0 {
        out.extend_from_slice(b"0.");
        out.extend(std::iter::repeat_n(b'0', point.unsigned_abs() as usize));
        out.extend_from_slice(digits);
    } else if point as usize >= digits.len() {
        out.extend_from_slice(digits);
        out.extend(std::iter::repeat_n(b'0', point as usize - digits.len()));
    } else {
        let (whole, fraction) = digits.split_at(point as usize);
        out.extend_from_slice(whole);
        out.push(b'.');
        out.extend_from_slice(fraction);
    }
}

/// Whether two shortest candidates can be equally close to `x` (finite): see the module's
/// comment.
fn may_tie(x: f64) -> bool {
    const MANTISSA_BITS: u32 = 52;
    let bits = x.to_bits();
    let fraction = bits & ((1 << MANTISSA_BITS) - 1);
    let biased = ((bits >> MANTISSA_BITS) & 0x7ff) as i64;
    let (mantissa, exponent) = match biased {
        0 => (fraction, -1074),
        _ => (fraction | (1 << MANTISSA_BITS), biased - 1075),
    };
    if mantissa == 0 {
        return false;
    }
    let exponent = exponent + i64::from(mantissa.trailing_zeros());
    (-25..0).contains(&exponent) || (exponent >= 0 && x.abs() >= 9_007_199_254_740_992.0)
}

/// The exponent after `e`: an optional sign and decimal digits.
fn parse_exponent(text: &[u8]) -> i64 {
    let (negative, digits) = match text.first() {
        Some(b'-') => (true, &text[1..]),
        Some(b'+') => (false, &text[1..]),
        _ => (false, text),
    };
    let magnitude = digits
        .iter()
        .fold(0i64, |value, &d| value * 10 + i64::from(d - b'0'));
    if negative { -magnitude } else { magnitude }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn displayed(x: f64) -> String {
        let mut out = Vec::new();
        push_display(&mut out, x);
        String::from_utf8(out).unwrap()
    }

    #[test]
    fn special_values_and_boundaries_read_as_display_writes_them() {
        for x in [
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.1,
            0.3,
            1e-7,
            1.5e-300,
            1e16,
            1.234e21,
            f64::MIN_POSITIVE,
            5e-324,
            f64::MAX,
            f64::MIN,
            f64::EPSILON,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            123456.789,
            0.000123,
            2.0f64.powi(60),
            // A tie: 29545024329553.5625 lies midway between …562 and …563.
            f64::from_bits(4808400729005314448),
            0.5,
            1e6 + 2.0f64.powi(-11),
        ] {
            assert_eq!(displayed(x), x.to_string(), "{x:e}");
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig { failure_persistence: None, cases: 20_000, ..ProptestConfig::default() })]

        #[test]
        fn any_bit_pattern_reads_as_display_writes_it(bits in any::<u64>()) {
            let x = f64::from_bits(bits);
            prop_assert_eq!(displayed(x), x.to_string());
        }

        #[test]
        fn a_recording_s_range_reads_as_display_writes_it(x in -100.0f64..100.0) {
            prop_assert_eq!(displayed(x), x.to_string());
        }
    }
}
