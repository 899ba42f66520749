//! The multiprecision reference (astro-float at 128 bits) and the arguments the accuracy is
//! measured on: the ranges the stack uses and wider ones. Shared by `tests/accuracy.rs` and
//! `examples/accuracy.rs`.

use astro_float_num::{BigFloat, Consts, RoundingMode};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

const PRECISION: usize = 128;
const RM: RoundingMode = RoundingMode::ToEven;

/// A function of the crate and where its arguments are drawn.
#[derive(Debug, Clone, Copy)]
pub enum Case {
    /// sin and cos of x uniform in [−limit, limit].
    SinCos { limit: f64 },
    /// sin and cos of ±2^e, e uniform in [lo, hi].
    SinCosLog { lo: f64, hi: f64 },
    /// exp of x uniform in [lo, hi].
    Exp { lo: f64, hi: f64 },
    /// tan of x uniform in [−limit, limit].
    Tan { limit: f64 },
    /// atan of x = ±2^e, e uniform in [lo, hi].
    AtanLog { lo: f64, hi: f64 },
    /// pow(x, y), x = 2^e with e uniform in [lo, hi], y uniform in [y_lo, y_hi].
    Pow { lo: f64, hi: f64, y_lo: f64, y_hi: f64 },
    /// pow(x, y) for x uniform in (0, 1] and a fixed y (the grey-box motor term and its inverse).
    PowFixed { y: f64 },
    /// atan2(y, x) of (x, y) uniform in the square [−limit, limit]² (velocities, headings).
    Atan2 { limit: f64 },
    /// atan2(y, x) of x = ±2^a, y = ±2^b, a and b uniform in [lo, hi] (every ratio, every octant).
    Atan2Log { lo: f64, hi: f64 },
    /// hypot(x, y) of (x, y) uniform in the square [−limit, limit]².
    Hypot { limit: f64 },
    /// hypot(x, y) of x = ±2^a, y = ±2^b, a and b uniform in [lo, hi].
    HypotLog { lo: f64, hi: f64 },
}

impl Case {
    pub fn name(&self) -> String {
        match *self {
            Case::SinCos { limit } => format!("sin_cos, x in [-{limit}, {limit}]"),
            Case::SinCosLog { lo, hi } => format!("sin_cos, x = ±2^e, e in [{lo}, {hi}]"),
            Case::Exp { lo, hi } => format!("exp, x in [{lo}, {hi}]"),
            Case::Tan { limit } => format!("tan, x in [-{limit}, {limit}]"),
            Case::AtanLog { lo, hi } => format!("atan, x = ±2^e, e in [{lo}, {hi}]"),
            Case::Pow { lo, hi, y_lo, y_hi } => {
                format!("pow, x = 2^e, e in [{lo}, {hi}], y in [{y_lo}, {y_hi}]")
            }
            Case::PowFixed { y } => format!("pow, x in (0, 1], y = {y}"),
            Case::Atan2 { limit } => format!("atan2, (x, y) in [-{limit}, {limit}]²"),
            Case::Atan2Log { lo, hi } => format!("atan2, x, y = ±2^e, e in [{lo}, {hi}]"),
            Case::Hypot { limit } => format!("hypot, (x, y) in [-{limit}, {limit}]²"),
            Case::HypotLog { lo, hi } => format!("hypot, x, y = ±2^e, e in [{lo}, {hi}]"),
        }
    }

    /// The next arguments (x, y) from a stream.
    pub fn arguments(&self, rng: &mut ChaCha8Rng) -> (f64, f64) {
        match *self {
            Case::SinCos { limit } => (rng.random_range(-limit..=limit), 0.0),
            Case::SinCosLog { lo, hi } => {
                let sign = if rng.random::<bool>() { 1.0 } else { -1.0 };
                (sign * 2f64.powf(rng.random_range(lo..=hi)), 0.0)
            }
            Case::Exp { lo, hi } => (rng.random_range(lo..=hi), 0.0),
            Case::Tan { limit } => (rng.random_range(-limit..=limit), 0.0),
            Case::AtanLog { lo, hi } => {
                let sign = if rng.random::<bool>() { 1.0 } else { -1.0 };
                (sign * 2f64.powf(rng.random_range(lo..=hi)), 0.0)
            }
            Case::Pow { lo, hi, y_lo, y_hi } => (
                2f64.powf(rng.random_range(lo..=hi)),
                rng.random_range(y_lo..=y_hi),
            ),
            Case::PowFixed { y } => (1.0 - rng.random::<f64>(), y),
            Case::Atan2 { limit } | Case::Hypot { limit } => {
                (rng.random_range(-limit..=limit), rng.random_range(-limit..=limit))
            }
            Case::Atan2Log { lo, hi } | Case::HypotLog { lo, hi } => {
                let mut signed = || {
                    let magnitude = 2f64.powf(rng.random_range(lo..=hi));
                    if rng.random::<bool>() {
                        magnitude
                    } else {
                        -magnitude
                    }
                };
                (signed(), signed())
            }
        }
    }
}

/// The cases the accuracy is measured on.
pub const CASES: [Case; 16] = [
    Case::SinCos {
        limit: std::f64::consts::FRAC_PI_4,
    },
    Case::SinCos { limit: 20.0 },
    Case::SinCos { limit: 2_000.0 },
    Case::SinCosLog { lo: -30.0, hi: 60.0 },
    Case::Exp {
        lo: -745.0,
        hi: 709.7,
    },
    Case::Exp { lo: -1.0, hi: 1.0 },
    Case::Pow {
        lo: -30.0,
        hi: 30.0,
        y_lo: -20.0,
        y_hi: 20.0,
    },
    Case::PowFixed { y: 1.321199 },
    Case::PowFixed { y: 1.0 / 1.321199 },
    Case::Atan2 { limit: 2.0 },
    Case::Atan2Log { lo: -60.0, hi: 60.0 },
    Case::Hypot { limit: 2.0 },
    Case::HypotLog { lo: -60.0, hi: 60.0 },
    // The steering angles of the bicycle model's Jacobians, then wider.
    Case::Tan { limit: 0.7 },
    Case::Tan { limit: 2_000.0 },
    Case::AtanLog { lo: -30.0, hi: 30.0 },
];

/// The reference's state (its cache of constants).
pub struct Reference {
    consts: Consts,
}

impl Reference {
    pub fn new() -> Self {
        Self {
            consts: Consts::new().expect("astro-float's constants"),
        }
    }

    /// The errors, in units in the last place of the exact value, of the crate's answers for
    /// the case's arguments (two errors for sin_cos, one for the others; atan2's arguments are
    /// (x, y) here, the function's order is (y, x)).
    pub fn errors(&mut self, case: &Case, x: f64, y: f64) -> Vec<f64> {
        let cc = &mut self.consts;
        match case {
            Case::SinCos { .. } | Case::SinCosLog { .. } => {
                let (s, c) = cpmx_math::sin_cos(x);
                let bx = big(x);
                vec![
                    ulp_error(s, &bx.sin(PRECISION, RM, cc)),
                    ulp_error(c, &bx.cos(PRECISION, RM, cc)),
                ]
            }
            Case::Exp { .. } => vec![ulp_error(cpmx_math::exp(x), &big(x).exp(PRECISION, RM, cc))],
            Case::Tan { .. } => vec![ulp_error(cpmx_math::tan(x), &big(x).tan(PRECISION, RM, cc))],
            Case::AtanLog { .. } => {
                vec![ulp_error(cpmx_math::atan(x), &big(x).atan(PRECISION, RM, cc))]
            }
            Case::Pow { .. } | Case::PowFixed { .. } => {
                let exact = big(x)
                    .ln(PRECISION, RM, cc)
                    .mul(&big(y), PRECISION, RM)
                    .exp(PRECISION, RM, cc);
                vec![ulp_error(cpmx_math::pow(x, y), &exact)]
            }
            Case::Atan2 { .. } | Case::Atan2Log { .. } => {
                // atan(y/x), then ±π for x < 0 (the draws are never zero).
                let principal = big(y).div(&big(x), PRECISION, RM).atan(PRECISION, RM, cc);
                let exact = if x > 0.0 {
                    principal
                } else if y >= 0.0 {
                    principal.add(&cc.pi(PRECISION, RM), PRECISION, RM)
                } else {
                    principal.sub(&cc.pi(PRECISION, RM), PRECISION, RM)
                };
                vec![ulp_error(cpmx_math::atan2(y, x), &exact)]
            }
            Case::Hypot { .. } | Case::HypotLog { .. } => {
                let (bx, by) = (big(x), big(y));
                let exact = bx
                    .mul(&bx, PRECISION, RM)
                    .add(&by.mul(&by, PRECISION, RM), PRECISION, RM)
                    .sqrt(PRECISION, RM);
                vec![ulp_error(cpmx_math::hypot(x, y), &exact)]
            }
        }
    }
}

/// A double as a 128-bit number (astro-float's `from_f64` loses subnormals: they are scaled into
/// the normal range first and back by an exact power of two).
fn big(v: f64) -> BigFloat {
    if v != 0.0 && v.abs() < f64::MIN_POSITIVE {
        let down = BigFloat::from_f64(2f64.powi(-300), PRECISION);
        BigFloat::from_f64(v * 2f64.powi(600), PRECISION)
            .mul(&down, PRECISION, RM)
            .mul(&down, PRECISION, RM)
    } else {
        BigFloat::from_f64(v, PRECISION)
    }
}

/// |computed − exact| in units of the last place of doubles at the exact value's magnitude.
pub fn ulp_error(computed: f64, exact: &BigFloat) -> f64 {
    if exact.is_zero() {
        return if computed == 0.0 { 0.0 } else { f64::INFINITY };
    }
    let Some(exponent) = exact.exponent() else {
        return f64::NAN;
    };
    // exact in [2^(e−1), 2^e): its double's last place is 2^(e−53) (2^-1074 below the normals).
    let last_place = (exponent as i64 - 53).max(-1074);
    let diff = big(computed).sub(exact, PRECISION, RM);
    if diff.is_zero() {
        return 0.0;
    }
    let (words, _, _, diff_exponent, _) = diff.as_raw_parts().expect("a finite difference");
    // diff = 0.m · 2^diff_exponent with m's leading word last.
    let leading = *words.last().expect("a mantissa word") as f64 / 2f64.powi(64);
    leading * 2f64.powi((diff_exponent as i64 - last_place) as i32)
}

/// A stream of arguments for one case.
pub fn stream(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}
