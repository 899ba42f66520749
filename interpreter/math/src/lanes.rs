//! The functions over arrays and slices: each kernel run on every lane (the compiler keeps the
//! straight-line kernel in SIMD registers, AVX-512 or AVX2 where the CPU has them, chosen at run
//! time), then the lanes outside the kernel's domain recomputed by the scalar slow path. The
//! bits are the scalar functions' bits whatever the path (see the crate's invariants).

use crate::{atan, exp_log, hypot, trig};

/// Lanes per block of the slice functions: one AVX-512 register, two AVX2 ones.
const BLOCK: usize = 8;

#[inline(always)]
fn sin_cos_block<const N: usize>(x: &[f64; N]) -> ([f64; N], [f64; N]) {
    let mut sin = [0.0; N];
    let mut cos = [0.0; N];
    // In two passes (the reduction, then the polynomials), which the vectoriser takes apart.
    let mut quadrant = [0u64; N];
    let mut rh = [0.0; N];
    let mut rl = [0.0; N];
    for i in 0..N {
        (quadrant[i], rh[i], rl[i]) = trig::reduce(x[i]);
    }
    for i in 0..N {
        (sin[i], cos[i]) = trig::finish(x[i], quadrant[i], rh[i], rl[i]);
    }
    (sin, cos)
}

/// The lanes outside sin_cos's kernel recomputed by its slow path. Apart from the blocks: in the
/// same function as the kernel's loop, the compiler no longer vectorises that loop.
#[inline(never)]
fn sin_cos_fix(x: &[f64], sin: &mut [f64], cos: &mut [f64]) {
    for (i, &value) in x.iter().enumerate() {
        if !trig::in_kernel(value) {
            (sin[i], cos[i]) = trig::slow(value);
        }
    }
}

#[inline(always)]
fn tan_block<const N: usize>(x: &[f64; N]) -> [f64; N] {
    let mut out = [0.0; N];
    for i in 0..N {
        out[i] = trig::tan_kernel(x[i]);
    }
    for i in 0..N {
        if !trig::in_kernel(x[i]) {
            out[i] = trig::tan_slow(x[i]);
        }
    }
    out
}

#[inline(always)]
fn exp_block<const N: usize>(x: &[f64; N]) -> [f64; N] {
    let mut out = [0.0; N];
    for i in 0..N {
        out[i] = exp_log::exp(x[i]);
    }
    for i in 0..N {
        if !exp_log::exp_in_kernel(x[i]) {
            out[i] = exp_log::exp_slow(x[i]);
        }
    }
    out
}

#[inline(always)]
fn pow_block<const N: usize>(x: &[f64; N], y: &[f64; N]) -> [f64; N] {
    let mut out = [0.0; N];
    let mut inside = [false; N];
    for i in 0..N {
        let ln = exp_log::ln_kernel(x[i]);
        inside[i] = exp_log::pow_in_kernel(x[i], y[i], ln);
        out[i] = exp_log::pow_kernel(y[i], ln);
    }
    for i in 0..N {
        if !inside[i] {
            out[i] = exp_log::pow_slow(x[i], y[i]);
        }
    }
    out
}

/// A two-argument function's kernel on every lane, then its slow path on the lanes outside the
/// kernel's domain.
#[inline(always)]
fn pair_block<const N: usize>(
    a: &[f64; N],
    b: &[f64; N],
    in_kernel: impl Fn(f64, f64) -> bool,
    kernel: impl Fn(f64, f64) -> f64,
    slow: impl Fn(f64, f64) -> f64,
) -> [f64; N] {
    let mut out = [0.0; N];
    let mut inside = [false; N];
    for i in 0..N {
        inside[i] = in_kernel(a[i], b[i]);
        out[i] = kernel(a[i], b[i]);
    }
    for i in 0..N {
        if !inside[i] {
            out[i] = slow(a[i], b[i]);
        }
    }
    out
}

#[inline(always)]
fn atan2_block<const N: usize>(y: &[f64; N], x: &[f64; N]) -> [f64; N] {
    pair_block(y, x, atan::in_kernel, atan::kernel, atan::slow)
}

#[inline(always)]
fn hypot_block<const N: usize>(x: &[f64; N], y: &[f64; N]) -> [f64; N] {
    pair_block(x, y, hypot::in_kernel, hypot::kernel, hypot::slow)
}

/// Runs `$body` compiled for the best vector extension this CPU has (the same bits on each).
macro_rules! dispatch {
    (fn($($arg:ident: $ty:ty),*) -> $out:ty, $body:expr) => {{
        #[cfg(target_arch = "x86_64")]
        {
            #[target_feature(enable = "avx512f")]
            fn avx512($($arg: $ty),*) -> $out {
                $body
            }
            #[target_feature(enable = "avx2")]
            fn avx2($($arg: $ty),*) -> $out {
                $body
            }
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: the CPU has AVX-512F (checked above).
                return unsafe { avx512($($arg),*) };
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2 (checked above).
                return unsafe { avx2($($arg),*) };
            }
        }
        $body
    }};
}

/// A one-argument function over a slice in blocks of 8 lanes, the rest one by one.
macro_rules! singles {
    ($name:literal, $x:ident, $out:ident, $block:ident, $scalar:path) => {{
        assert_eq!(
            $x.len(),
            $out.len(),
            concat!($name, ": slices of different lengths")
        );
        dispatch!(fn($x: &[f64], $out: &mut [f64]) -> (), {
            let mut blocks = $x.chunks_exact(BLOCK);
            let mut offset = 0;
            for block in &mut blocks {
                $out[offset..offset + BLOCK]
                    .copy_from_slice(&$block::<BLOCK>(block.try_into().expect("a block of 8")));
                offset += BLOCK;
            }
            for (i, value) in blocks.remainder().iter().enumerate() {
                $out[offset + i] = $scalar(*value);
            }
        })
    }};
}

/// The pairs of a two-argument function in blocks of 8 lanes, the rest one by one.
macro_rules! pairs {
    ($name:literal, $a:ident, $b:ident, $out:ident, $block:ident, $scalar:path) => {{
        assert!(
            $a.len() == $b.len() && $a.len() == $out.len(),
            concat!($name, ": slices of different lengths")
        );
        dispatch!(fn($a: &[f64], $b: &[f64], $out: &mut [f64]) -> (), {
            let mut blocks = $a.chunks_exact(BLOCK).zip($b.chunks_exact(BLOCK));
            let mut offset = 0;
            for (ba, bb) in &mut blocks {
                let value = $block::<BLOCK>(
                    ba.try_into().expect("a block of 8"),
                    bb.try_into().expect("a block of 8"),
                );
                $out[offset..offset + BLOCK].copy_from_slice(&value);
                offset += BLOCK;
            }
            for i in offset..$a.len() {
                $out[i] = $scalar($a[i], $b[i]);
            }
        })
    }};
}

/// sin and cos of each lane.
#[inline(always)]
pub fn sin_cos_lanes<const N: usize>(x: [f64; N]) -> ([f64; N], [f64; N]) {
    let (mut sin, mut cos) = sin_cos_block(&x);
    sin_cos_fix(&x, &mut sin, &mut cos);
    (sin, cos)
}

/// tan x of each lane.
#[inline(always)]
pub fn tan_lanes<const N: usize>(x: [f64; N]) -> [f64; N] {
    tan_block(&x)
}

/// e^x of each lane.
#[inline(always)]
pub fn exp_lanes<const N: usize>(x: [f64; N]) -> [f64; N] {
    exp_block(&x)
}

/// x^y of each pair of lanes.
#[inline(always)]
pub fn pow_lanes<const N: usize>(x: [f64; N], y: [f64; N]) -> [f64; N] {
    pow_block(&x, &y)
}

/// atan2(y, x) of each pair of lanes.
#[inline(always)]
pub fn atan2_lanes<const N: usize>(y: [f64; N], x: [f64; N]) -> [f64; N] {
    atan2_block(&y, &x)
}

/// hypot(x, y) of each pair of lanes.
#[inline(always)]
pub fn hypot_lanes<const N: usize>(x: [f64; N], y: [f64; N]) -> [f64; N] {
    hypot_block(&x, &y)
}

/// `sin[i], cos[i] = sin_cos(x[i])` for every i, in blocks of 8 lanes with the CPU's widest
/// vectors.
///
/// # Panics
/// If the three slices differ in length.
pub fn sin_cos_slice(x: &[f64], sin: &mut [f64], cos: &mut [f64]) {
    assert!(
        x.len() == sin.len() && x.len() == cos.len(),
        "sin_cos_slice: slices of different lengths"
    );
    dispatch!(fn(x: &[f64], sin: &mut [f64], cos: &mut [f64]) -> (), {
        let mut blocks = x.chunks_exact(BLOCK);
        let mut offset = 0;
        for block in &mut blocks {
            let (s, c) = sin_cos_block::<BLOCK>(block.try_into().expect("a block of 8"));
            sin[offset..offset + BLOCK].copy_from_slice(&s);
            cos[offset..offset + BLOCK].copy_from_slice(&c);
            offset += BLOCK;
        }
        for (i, value) in blocks.remainder().iter().enumerate() {
            (sin[offset + i], cos[offset + i]) = crate::sin_cos(*value);
        }
        sin_cos_fix(x, sin, cos);
    })
}

/// `out[i] = tan(x[i])` for every i, in blocks of 8 lanes.
///
/// # Panics
/// If the slices differ in length.
pub fn tan_slice(x: &[f64], out: &mut [f64]) {
    singles!("tan_slice", x, out, tan_block, crate::tan)
}

/// `out[i] = exp(x[i])` for every i, in blocks of 8 lanes.
///
/// # Panics
/// If the slices differ in length.
pub fn exp_slice(x: &[f64], out: &mut [f64]) {
    singles!("exp_slice", x, out, exp_block, crate::exp)
}

/// `out[i] = pow(x[i], y[i])` for every i, in blocks of 8 lanes.
///
/// # Panics
/// If the slices differ in length.
pub fn pow_slice(x: &[f64], y: &[f64], out: &mut [f64]) {
    pairs!("pow_slice", x, y, out, pow_block, crate::pow)
}

/// `out[i] = atan2(y[i], x[i])` for every i, in blocks of 8 lanes.
///
/// # Panics
/// If the slices differ in length.
pub fn atan2_slice(y: &[f64], x: &[f64], out: &mut [f64]) {
    pairs!("atan2_slice", y, x, out, atan2_block, crate::atan2)
}

/// `out[i] = hypot(x[i], y[i])` for every i, in blocks of 8 lanes.
///
/// # Panics
/// If the slices differ in length.
pub fn hypot_slice(x: &[f64], y: &[f64], out: &mut [f64]) {
    pairs!("hypot_slice", x, y, out, hypot_block, crate::hypot)
}
