//! cpmx's own transcendental functions: `sin`, `cos`, `sin_cos`, `tan`, `exp`, `pow`, `atan`,
//! `atan2` and `hypot`, each within
//! one unit in the last place of the exact value, with the same bits on every CPU, for any
//! thread count, and in scalar code and SIMD lanes alike.
//!
//! Why a library of our own: the twin's numbers used to depend on the host's libm (glibc's
//! `sin_cos` and `pow` in the MPC followers and the grey-box plant), which neither gives the
//! same bits on every machine nor has vector versions with its bits. Here each function is one
//! algorithm written as straight-line IEEE arithmetic.
//!
//! Invariants:
//! - **No fused multiply-add.** Every operation is a separately rounded `+`, `−`, `×`, `÷` or `√`
//!   (Rust never contracts them), so an x86 lane, an ARM lane and a scalar register compute
//!   the same bits. Exact products use Dekker's splitting, not FMA.
//! - **One kernel per function**, `#[inline(always)]`, branch-free over its common domain; the
//!   lanes ([`sin_cos_lanes`], [`pow_lanes`], [`atan2_lanes`], …) run it on every lane and send the lanes
//!   outside that domain (NaN, infinities, huge arguments, zeros, overflow) through the same
//!   scalar `slow` path the scalar functions use.
//! - **Written once**: code generic over [`Real`] runs on `f64` or on [`Lanes`] (several
//!   independent problems side by side) with the same operations in the same order, so the
//!   lanes give the scalar bits (`real.rs`).
//! - **Accuracy**: within 1 ulp of the correctly rounded result (measured against a
//!   multiprecision reference: `cargo run --release -p cpmx-math --example accuracy`, and
//!   tested on a sample in `tests/accuracy.rs`); docs/performance.md has the figures.

mod atan;
mod dd;
mod exp_log;
mod hypot;
mod lanes;
mod real;
mod trig;

pub use real::{Lanes, Real};

pub use lanes::{
    atan2_lanes, atan2_slice, exp_lanes, exp_slice, hypot_lanes, hypot_slice, pow_lanes, pow_slice,
    sin_cos_lanes, sin_cos_slice, tan_lanes, tan_slice,
};

/// sin x and cos x together (one argument reduction).
#[inline]
pub fn sin_cos(x: f64) -> (f64, f64) {
    if trig::in_kernel(x) {
        trig::kernel(x)
    } else {
        trig::slow(x)
    }
}

/// sin x.
#[inline]
pub fn sin(x: f64) -> f64 {
    sin_cos(x).0
}

/// cos x.
#[inline]
pub fn cos(x: f64) -> f64 {
    sin_cos(x).1
}

/// tan x.
#[inline]
pub fn tan(x: f64) -> f64 {
    if trig::in_kernel(x) {
        trig::tan_kernel(x)
    } else {
        trig::tan_slow(x)
    }
}

/// e^x.
#[inline]
pub fn exp(x: f64) -> f64 {
    if exp_log::exp_in_kernel(x) {
        exp_log::exp(x)
    } else {
        exp_log::exp_slow(x)
    }
}

/// x^y, with C99 Annex F's special cases.
#[inline]
pub fn pow(x: f64, y: f64) -> f64 {
    let ln = exp_log::ln_kernel(x);
    if exp_log::pow_in_kernel(x, y, ln) {
        exp_log::pow_kernel(y, ln)
    } else {
        exp_log::pow_slow(x, y)
    }
}

/// The angle of the point (x, y) from the positive x axis, in [−π, π], with C99 Annex F's
/// special cases (the signs of zeros count).
#[inline]
pub fn atan2(y: f64, x: f64) -> f64 {
    if atan::in_kernel(y, x) {
        atan::kernel(y, x)
    } else {
        atan::slow(y, x)
    }
}

/// atan x, in [−π/2, π/2]: `atan2(x, 1)`, which is exactly that (the ratio x/1 is exact).
#[inline]
pub fn atan(x: f64) -> f64 {
    atan2(x, 1.0)
}

/// √(x² + y²) without overflow or underflow on the way (an infinity wins over NaN, as C99 says).
#[inline]
pub fn hypot(x: f64, y: f64) -> f64 {
    if hypot::in_kernel(x, y) {
        hypot::kernel(x, y)
    } else {
        hypot::slow(x, y)
    }
}
