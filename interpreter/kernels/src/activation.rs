//! The element-wise functions after a dense layer: [`Activation`], and the float32 tanh of
//! SigmaRL's networks ([`tanh`]) with its SIMD paths, which give the portable function's bits.

/// The element-wise function after a dense layer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Activation {
    /// None (the output layer).
    #[default]
    Identity,
    /// `tanh` (SigmaRL's hidden layers), within 2.5e-7 of the exact value.
    Tanh,
    /// `max(x, 0)`.
    Relu,
    /// `x` for `x > 0`, else `exp(x) - 1` (alpha 1, torch's default).
    Elu,
}

impl Activation {
    /// Apply in place.
    pub fn apply(self, v: &mut [f32]) {
        match self {
            Activation::Identity => {}
            Activation::Tanh => tanh(v),
            Activation::Relu => v.iter_mut().for_each(|x| *x = if *x > 0.0 { *x } else { 0.0 }),
            Activation::Elu => v.iter_mut().for_each(|x| {
                if *x <= 0.0 {
                    *x = x.exp_m1();
                }
            }),
        }
    }
}

/// Element-wise float32 tanh ([`tanh_portable`]), 16 lanes at a time with AVX-512 or 8 with
/// AVX2 when the CPU has them: the same operations in the same order, each rounded
/// separately, so the same bits on every CPU (a test sweeps the range).
pub fn tanh(v: &mut [f32]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx512f") && std::arch::is_x86_feature_detected!("avx512dq") {
        let (head, tail) = v.as_chunks_mut::<16>();
        // SAFETY: the CPU supports AVX-512F and DQ (checked just above).
        unsafe { tanh_chunks_avx512(head) };
        tanh_avx2_or_portable(tail);
        return;
    }
    tanh_avx2_or_portable(v);
}

fn tanh_avx2_or_portable(v: &mut [f32]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        let (head, tail) = v.as_chunks_mut::<8>();
        // SAFETY: the CPU supports AVX2 (checked just above).
        unsafe { tanh_chunks_avx2(head) };
        tanh_portable(tail);
        return;
    }
    tanh_portable(v);
}

/// [`tanh8_avx2`] over chunks, inlined into one loop so that out-of-order execution
/// overlaps the (long) dependency chains of consecutive chunks.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn tanh_chunks_avx2(chunks: &mut [[f32; 8]]) {
    for chunk in chunks {
        // SAFETY: AVX2 is enabled in this function.
        unsafe { tanh8_avx2(chunk) };
    }
}

/// [`tanh16_avx512`] over chunks, in one loop.
///
/// # Safety
/// The CPU must support AVX-512F and DQ.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512dq")]
unsafe fn tanh_chunks_avx512(chunks: &mut [[f32; 16]]) {
    for chunk in chunks {
        // SAFETY: AVX-512F and DQ are enabled in this function.
        unsafe { tanh16_avx512(chunk) };
    }
}

/// Sixteen lanes of the tanh of [`tanh8_avx2`]: the same operations in the same order.
///
/// # Safety
/// The CPU must support AVX-512F and DQ.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512dq")]
#[inline]
unsafe fn tanh16_avx512(v: &mut [f32; 16]) {
    use std::arch::x86_64::*;
    // SAFETY: `v` holds 16 values.
    let x = unsafe { _mm512_loadu_ps(v.as_ptr()) };
    let splat = _mm512_set1_ps;
    let sign = splat(-0.0);
    let ax = _mm512_andnot_ps(sign, x);
    // Small arguments: x + x^3 P(x^2).
    let z = _mm512_mul_ps(x, x);
    let mut p = _mm512_add_ps(_mm512_mul_ps(splat(-5.704_988_7e-3), z), splat(2.063_909e-2));
    p = _mm512_sub_ps(_mm512_mul_ps(p, z), splat(5.373_971_6e-2));
    p = _mm512_add_ps(_mm512_mul_ps(p, z), splat(1.333_144_2e-1));
    p = _mm512_sub_ps(_mm512_mul_ps(p, z), splat(3.333_328e-1));
    let small = _mm512_add_ps(_mm512_mul_ps(_mm512_mul_ps(p, z), x), x);
    // Large arguments: 1 - 2 / (exp(2 min(|x|, 10)) + 1) with the sign of x.
    let y = _mm512_mul_ps(splat(2.0), _mm512_min_ps(ax, splat(10.0)));
    let shifter = splat(12_582_912.0);
    let shifted = _mm512_add_ps(_mm512_mul_ps(y, splat(std::f32::consts::LOG2_E)), shifter);
    let nf = _mm512_sub_ps(shifted, shifter);
    let r = _mm512_sub_ps(
        _mm512_sub_ps(y, _mm512_mul_ps(nf, splat(0.693_359_4))),
        _mm512_mul_ps(nf, splat(-2.121_944_4e-4)),
    );
    let mut q = _mm512_add_ps(_mm512_mul_ps(splat(1.987_569_1e-4), r), splat(1.398_199_9e-3));
    q = _mm512_add_ps(_mm512_mul_ps(q, r), splat(8.333_452e-3));
    q = _mm512_add_ps(_mm512_mul_ps(q, r), splat(4.166_579_6e-2));
    q = _mm512_add_ps(_mm512_mul_ps(q, r), splat(1.666_666_5e-1));
    q = _mm512_add_ps(_mm512_mul_ps(q, r), splat(0.5));
    let q = _mm512_add_ps(
        _mm512_add_ps(_mm512_mul_ps(_mm512_mul_ps(q, r), r), r),
        splat(1.0),
    );
    let pow2 = _mm512_castsi512_ps(_mm512_slli_epi32::<23>(_mm512_add_epi32(
        _mm512_castps_si512(shifted),
        _mm512_set1_epi32(127),
    )));
    let e = _mm512_mul_ps(q, pow2);
    let large_abs = _mm512_sub_ps(
        splat(1.0),
        _mm512_div_ps(splat(2.0), _mm512_add_ps(e, splat(1.0))),
    );
    let large = _mm512_or_ps(_mm512_andnot_ps(sign, large_abs), _mm512_and_ps(sign, x));
    let use_large = _mm512_cmp_ps_mask::<_CMP_GE_OQ>(ax, splat(0.625));
    // SAFETY: `v` holds 16 values.
    unsafe { _mm512_storeu_ps(v.as_mut_ptr(), _mm512_mask_blend_ps(use_large, small, large)) };
}

/// Eight lanes of [`tanh_portable`] (Cephes `tanhf`).
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn tanh8_avx2(v: &mut [f32; 8]) {
    use std::arch::x86_64::*;
    // (Plain calls: a closure or function pointer would not inherit the target feature.)
    // SAFETY: `v` holds 8 values.
    let x = unsafe { _mm256_loadu_ps(v.as_ptr()) };
    let sign = _mm256_set1_ps(-0.0);
    let ax = _mm256_andnot_ps(sign, x);
    // Small arguments: x + x^3 P(x^2).
    let z = _mm256_mul_ps(x, x);
    let mut p = _mm256_add_ps(
        _mm256_mul_ps(_mm256_set1_ps(-5.704_988_7e-3), z),
        _mm256_set1_ps(2.063_909e-2),
    );
    p = _mm256_sub_ps(_mm256_mul_ps(p, z), _mm256_set1_ps(5.373_971_6e-2));
    p = _mm256_add_ps(_mm256_mul_ps(p, z), _mm256_set1_ps(1.333_144_2e-1));
    p = _mm256_sub_ps(_mm256_mul_ps(p, z), _mm256_set1_ps(3.333_328e-1));
    let small = _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(p, z), x), x);
    // Large arguments: 1 - 2 / (exp(2 min(|x|, 10)) + 1) with the sign of x.
    let y = _mm256_mul_ps(_mm256_set1_ps(2.0), _mm256_min_ps(ax, _mm256_set1_ps(10.0)));
    let shifter = _mm256_set1_ps(12_582_912.0);
    let shifted = _mm256_add_ps(
        _mm256_mul_ps(y, _mm256_set1_ps(std::f32::consts::LOG2_E)),
        shifter,
    );
    let nf = _mm256_sub_ps(shifted, shifter);
    let r = _mm256_sub_ps(
        _mm256_sub_ps(y, _mm256_mul_ps(nf, _mm256_set1_ps(0.693_359_4))),
        _mm256_mul_ps(nf, _mm256_set1_ps(-2.121_944_4e-4)),
    );
    let mut q = _mm256_add_ps(
        _mm256_mul_ps(_mm256_set1_ps(1.987_569_1e-4), r),
        _mm256_set1_ps(1.398_199_9e-3),
    );
    q = _mm256_add_ps(_mm256_mul_ps(q, r), _mm256_set1_ps(8.333_452e-3));
    q = _mm256_add_ps(_mm256_mul_ps(q, r), _mm256_set1_ps(4.166_579_6e-2));
    q = _mm256_add_ps(_mm256_mul_ps(q, r), _mm256_set1_ps(1.666_666_5e-1));
    q = _mm256_add_ps(_mm256_mul_ps(q, r), _mm256_set1_ps(0.5));
    let q = _mm256_add_ps(
        _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(q, r), r), r),
        _mm256_set1_ps(1.0),
    );
    let pow2 = _mm256_castsi256_ps(_mm256_slli_epi32::<23>(_mm256_add_epi32(
        _mm256_castps_si256(shifted),
        _mm256_set1_epi32(127),
    )));
    let e = _mm256_mul_ps(q, pow2);
    let large_abs = _mm256_sub_ps(
        _mm256_set1_ps(1.0),
        _mm256_div_ps(_mm256_set1_ps(2.0), _mm256_add_ps(e, _mm256_set1_ps(1.0))),
    );
    let large = _mm256_or_ps(_mm256_andnot_ps(sign, large_abs), _mm256_and_ps(sign, x));
    let use_large = _mm256_cmp_ps::<_CMP_GE_OQ>(ax, _mm256_set1_ps(0.625));
    // SAFETY: `v` holds 8 values.
    unsafe { _mm256_storeu_ps(v.as_mut_ptr(), _mm256_blendv_ps(small, large, use_large)) };
}

/// Element-wise float32 tanh, within 2.5e-7 of the exact value (Cephes `tanhf`: an odd
/// polynomial below 0.625, `1 - 2 / (exp(2|x|) + 1)` above; NaN stays NaN). Branch-free, so it
/// runs on 8 lanes at once; only basic IEEE operations, so every path gives the same bits.
///
/// The reference for the SIMD paths of [`tanh`] (the same bits); inlined into the caller, it
/// vectorises for the caller's target features.
#[inline(always)]
pub fn tanh_portable(v: &mut [f32]) {
    for x in v.iter_mut() {
        *x = tanh_f32(*x);
    }
}

#[inline(always)]
fn tanh_f32(x: f32) -> f32 {
    let ax = x.abs();
    // Small arguments: x + x^3 P(x^2).
    let z = x * x;
    let small = ((((-5.704_988_7e-3 * z + 2.063_909e-2) * z - 5.373_971_6e-2) * z + 1.333_144_2e-1) * z
        - 3.333_328e-1)
        * z
        * x
        + x;
    // Large arguments: 1 - 2 / (exp(2|x|) + 1), saturating (tanh(10) rounds to 1 in f32).
    let e = exp_pos(2.0 * if ax < 10.0 { ax } else { 10.0 });
    let large = (1.0 - 2.0 / (e + 1.0)).copysign(x);
    // NaN takes the polynomial branch, which keeps it.
    if ax >= 0.625 { large } else { small }
}

/// `exp(y)` for `0 <= y <= 20` (Cephes `expf`: range reduction by ln 2, degree-6 polynomial).
#[inline(always)]
fn exp_pos(y: f32) -> f32 {
    const SHIFTER: f32 = 12_582_912.0; // 1.5 * 2^23: adding it rounds to an integer
    let shifted = y * std::f32::consts::LOG2_E + SHIFTER;
    let nf = shifted - SHIFTER;
    let r = y - nf * 0.693_359_4 - nf * -2.121_944_4e-4;
    let p = (((((1.987_569_1e-4 * r + 1.398_199_9e-3) * r + 8.333_452e-3) * r + 4.166_579_6e-2) * r
        + 1.666_666_5e-1)
        * r
        + 0.5)
        * r
        * r
        + r
        + 1.0;
    p * f32::from_bits(shifted.to_bits().wrapping_add(127) << 23)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tanh_is_within_a_few_ulp_everywhere() {
        let mut worst = 0.0f64;
        let mut x = -12.0f32;
        while x < 12.0 {
            let mut v = [x, x * 1e-3];
            tanh(&mut v);
            for (got, arg) in v.into_iter().zip([x, x * 1e-3]) {
                worst = worst.max((f64::from(got) - f64::from(arg).tanh()).abs());
            }
            x += 1.0e-4;
        }
        assert!(worst < 2.5e-7, "worst {worst:e}");
        let mut v = [0.0f32, 1e-30, -1e-30, f32::MAX, f32::MIN, f32::NAN];
        tanh(&mut v);
        assert_eq!(v[..5], [0.0, 1e-30, -1e-30, 1.0, -1.0]);
        assert!(v[5].is_nan());
    }

    #[test]
    fn the_simd_tanh_gives_the_portable_bits() {
        let mut x: Vec<f32> = (-130_000..130_000).map(|i| i as f32 * 1e-4).collect();
        x.extend([
            f32::MAX,
            f32::MIN,
            1e-30,
            -1e-30,
            0.0,
            -0.0,
            0.625,
            -0.625,
            10.0,
            9.999_999,
        ]);
        x.extend([f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 0.624_999_9]);
        let mut want = x.clone();
        tanh_portable(&mut want);
        // The widest vectors this CPU has, and AVX2 (or the portable loop) alone.
        for path in [tanh as fn(&mut [f32]), tanh_avx2_or_portable] {
            let mut got = x.clone();
            path(&mut got);
            for ((g, w), a) in got.iter().zip(&want).zip(&x) {
                assert!(
                    g.to_bits() == w.to_bits() || (g.is_nan() && w.is_nan()),
                    "tanh({a}): {g} vs {w}"
                );
            }
        }
    }
}
