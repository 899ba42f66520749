//! The numeric kernels of the MLP: a dense layer over a group of up to [`GROUP`] agents that
//! streams weight panels packed once at load, and its activations (a vectorisable tanh, relu,
//! elu). Shapes are checked by
//! the caller (`actor`); this module only computes.
//!
//! Activations of a group of `R` agents are stored feature-major (`x[k * R + r]`), so every
//! inner loop runs over contiguous arrays of known length (no bounds checks). The product is
//! written once over a small [`Vector`] trait (AVX2 chosen at run time, SSE2, portable arrays),
//! so the `R x 16` accumulators stay in registers whatever LLVM's vectoriser decides.

/// Agents evaluated together: every weight is loaded once per group.
pub(crate) const GROUP: usize = 4;
/// Outputs per weight panel (two 256-bit or four 128-bit vectors); layer widths are padded
/// to a multiple of it.
pub(crate) const PANEL: usize = 16;
/// Inputs summed in register before a block sum is added to the total.
const K_BLOCK: usize = 16;

/// Round `n` up to a multiple of `m`.
pub(crate) fn pad(n: usize, m: usize) -> usize {
    n.div_ceil(m) * m
}

/// A dense layer `y = x W^T + b`, optionally followed by tanh, with W packed in panels of
/// [`PANEL`] outputs: panel `p` holds `inputs` rows of `PANEL` weights
/// (`packed[p * inputs + k].0[c] = W[p * PANEL + c][k]`), streamed front to back, one cache
/// line per row.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Dense {
    /// Input width.
    inputs: usize,
    /// Output width padded to [`PANEL`].
    out_padded: usize,
    /// The packed weights, zero in the padding outputs.
    packed: Vec<WeightRow>,
    /// `out_padded` biases, zero in the padding.
    bias: Vec<f32>,
    /// The activation that follows.
    activation: Activation,
}

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

impl Dense {
    /// Pack a layer from torch's `weight` (`[outputs][inputs]`, row-major) and `bias`.
    pub(crate) fn new(
        weight: &[f32],
        bias: &[f32],
        inputs: usize,
        outputs: usize,
        activation: Activation,
    ) -> Self {
        let out_padded = pad(outputs, PANEL);
        let mut packed = vec![WeightRow([0.0; PANEL]); inputs * out_padded / PANEL];
        for (j, row) in weight.chunks_exact(inputs).take(outputs).enumerate() {
            let (p, c) = (j / PANEL, j % PANEL);
            for (k, &w) in row.iter().enumerate() {
                packed[p * inputs + k].0[c] = w;
            }
        }
        let mut padded_bias = bias[..outputs].to_vec();
        padded_bias.resize(out_padded, 0.0);
        Dense {
            inputs,
            out_padded,
            packed,
            bias: padded_bias,
            activation,
        }
    }

    /// Input width.
    pub(crate) fn inputs(&self) -> usize {
        self.inputs
    }

    /// Output width padded to [`PANEL`] (the padding outputs are 0).
    pub(crate) fn out_padded(&self) -> usize {
        self.out_padded
    }

    /// Apply to a group of `R` agents: `x` holds `inputs * R` values feature-major, `y`
    /// receives `out_padded * R` values feature-major.
    ///
    /// Each output sums its products in blocks of [`K_BLOCK`] inputs (in register), adds the
    /// block sums in order, then the bias: a blocked summation like BLAS's (several times less
    /// round-off than one running sum over 256 inputs; the actor agrees with torch to 6.3e-7). Every path
    /// (AVX2, SSE2, portable) runs the same operations in the same order, with a multiply and
    /// an add rounded separately (no FMA), and the order does not depend on `R`: an agent's
    /// outputs are the same bits whatever the batch and whichever path runs.
    pub(crate) fn apply<const R: usize>(&self, x: &[f32], y: &mut [f32]) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            unsafe { self.apply_avx2::<R>(x, y) };
        } else {
            // SAFETY: every x86_64 CPU supports SSE2.
            unsafe { self.apply_with::<Sse2, R, { PANEL / 4 }>(x, y) };
        }
        #[cfg(not(target_arch = "x86_64"))]
        // SAFETY: the portable vectors need no CPU feature.
        unsafe {
            self.apply_with::<Portable, R, { PANEL / 4 }>(x, y)
        };
    }

    /// The layer with 256-bit vectors (and the tanh compiled for AVX2).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn apply_avx2<const R: usize>(&self, x: &[f32], y: &mut [f32]) {
        // SAFETY: AVX2 is enabled in this function.
        unsafe { self.apply_with::<Avx2, R, { PANEL / 8 }>(x, y) };
    }

    /// The layer with vectors `V`, `NV` of them per panel row.
    ///
    /// # Safety
    /// The CPU must support `V`'s instructions.
    #[inline(always)]
    unsafe fn apply_with<V: Vector, const R: usize, const NV: usize>(&self, x: &[f32], y: &mut [f32]) {
        let (x, _) = x[..self.inputs * R].as_chunks::<R>();
        let (biases, _) = self.bias.as_chunks::<PANEL>();
        let y = &mut y[..self.out_padded * R];
        let mut out = [[0.0f32; PANEL]; R];
        let panels = self.packed.chunks_exact(self.inputs).zip(biases);
        for ((panel, bias), y_panel) in panels.zip(y.chunks_exact_mut(PANEL * R)) {
            // SAFETY: the caller guarantees `V`'s CPU support.
            unsafe { panel_product::<V, R, NV>(panel, x, bias, &mut out) };
            // Store feature-major.
            for (c, y_c) in y_panel.as_chunks_mut::<R>().0.iter_mut().enumerate() {
                for (y_rc, out_r) in y_c.iter_mut().zip(&out) {
                    *y_rc = out_r[c];
                }
            }
        }
        match self.activation {
            Activation::Identity => {}
            Activation::Tanh => tanh_in_place(y),
            Activation::Relu => y.iter_mut().for_each(|v| *v = if *v > 0.0 { *v } else { 0.0 }),
            Activation::Elu => y.iter_mut().for_each(|v| {
                if *v <= 0.0 {
                    *v = v.exp_m1();
                }
            }),
        }
    }
}

/// One row of a weight panel, aligned to a 64-byte cache line.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(64))]
struct WeightRow([f32; PANEL]);

/// One panel of [`PANEL`] outputs for `R` agents: `out[r] = x[r] W_panel^T + bias`, with the
/// blocked summation described at [`Dense::apply`]. The `R * NV` accumulators stay in
/// registers; each weight row is loaded once for all agents.
///
/// # Safety
/// The CPU must support `V`'s instructions.
#[inline(always)]
unsafe fn panel_product<V: Vector, const R: usize, const NV: usize>(
    panel: &[WeightRow],
    x: &[[f32; R]],
    bias: &[f32; PANEL],
    out: &mut [[f32; PANEL]; R],
) {
    const { assert!(NV * V::LANES == PANEL) };
    // SAFETY (all vector operations): the caller guarantees `V`'s CPU support, and every
    // load and store covers `v * LANES .. (v + 1) * LANES` of a `[f32; PANEL]` with `v < NV`.
    unsafe {
        let load = |row: &[f32; PANEL]| -> [V; NV] {
            std::array::from_fn(|v| V::load(row.as_ptr().add(v * V::LANES)))
        };
        let mut total = [[V::zero(); NV]; R];
        for (w_block, x_block) in panel.chunks(K_BLOCK).zip(x.chunks(K_BLOCK)) {
            let mut acc = [[V::zero(); NV]; R];
            for (w, x_k) in w_block.iter().zip(x_block) {
                let w = load(&w.0);
                for (acc_r, &x_rk) in acc.iter_mut().zip(x_k) {
                    let x_rk = V::splat(x_rk);
                    for (a, &w_v) in acc_r.iter_mut().zip(&w) {
                        *a = a.add(x_rk.mul(w_v));
                    }
                }
            }
            for (total_r, acc_r) in total.iter_mut().zip(&acc) {
                for (t, &a) in total_r.iter_mut().zip(acc_r) {
                    *t = t.add(a);
                }
            }
        }
        let bias = load(bias);
        for (out_r, total_r) in out.iter_mut().zip(&total) {
            for (v, (&t, &b)) in total_r.iter().zip(&bias).enumerate() {
                t.add(b).store(out_r.as_mut_ptr().add(v * V::LANES));
            }
        }
    }
}

/// The float32 vector operations of [`panel_product`]: IEEE single-precision lanes, each
/// operation rounded on its own.
///
/// # Safety
/// Every method needs the CPU support of its implementation; `load` and `store` need `p` valid
/// for `LANES` values.
trait Vector: Copy {
    /// Number of float32 lanes.
    const LANES: usize;
    /// All lanes 0.
    unsafe fn zero() -> Self;
    /// All lanes `x`.
    unsafe fn splat(x: f32) -> Self;
    /// `LANES` values from `p` (unaligned).
    unsafe fn load(p: *const f32) -> Self;
    /// `LANES` values to `p` (unaligned).
    unsafe fn store(self, p: *mut f32);
    /// Lane-wise sum.
    unsafe fn add(self, b: Self) -> Self;
    /// Lane-wise product.
    unsafe fn mul(self, b: Self) -> Self;
}

/// Eight lanes in a 256-bit AVX register.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct Avx2(std::arch::x86_64::__m256);

#[cfg(target_arch = "x86_64")]
impl Vector for Avx2 {
    const LANES: usize = 8;
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn zero() -> Self {
        Avx2(std::arch::x86_64::_mm256_setzero_ps())
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn splat(x: f32) -> Self {
        Avx2(std::arch::x86_64::_mm256_set1_ps(x))
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn load(p: *const f32) -> Self {
        // SAFETY: the caller guarantees `p` is valid for 8 values.
        Avx2(unsafe { std::arch::x86_64::_mm256_loadu_ps(p) })
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn store(self, p: *mut f32) {
        // SAFETY: the caller guarantees `p` is valid for 8 values.
        unsafe { std::arch::x86_64::_mm256_storeu_ps(p, self.0) }
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn add(self, b: Self) -> Self {
        Avx2(std::arch::x86_64::_mm256_add_ps(self.0, b.0))
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn mul(self, b: Self) -> Self {
        Avx2(std::arch::x86_64::_mm256_mul_ps(self.0, b.0))
    }
}

/// Four lanes in a 128-bit SSE register (every x86_64 CPU).
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct Sse2(std::arch::x86_64::__m128);

#[cfg(target_arch = "x86_64")]
impl Vector for Sse2 {
    const LANES: usize = 4;
    #[inline]
    #[target_feature(enable = "sse2")]
    unsafe fn zero() -> Self {
        Sse2(std::arch::x86_64::_mm_setzero_ps())
    }
    #[inline]
    #[target_feature(enable = "sse2")]
    unsafe fn splat(x: f32) -> Self {
        Sse2(std::arch::x86_64::_mm_set1_ps(x))
    }
    #[inline]
    #[target_feature(enable = "sse2")]
    unsafe fn load(p: *const f32) -> Self {
        // SAFETY: the caller guarantees `p` is valid for 4 values.
        Sse2(unsafe { std::arch::x86_64::_mm_loadu_ps(p) })
    }
    #[inline]
    #[target_feature(enable = "sse2")]
    unsafe fn store(self, p: *mut f32) {
        // SAFETY: the caller guarantees `p` is valid for 4 values.
        unsafe { std::arch::x86_64::_mm_storeu_ps(p, self.0) }
    }
    #[inline]
    #[target_feature(enable = "sse2")]
    unsafe fn add(self, b: Self) -> Self {
        Sse2(std::arch::x86_64::_mm_add_ps(self.0, b.0))
    }
    #[inline]
    #[target_feature(enable = "sse2")]
    unsafe fn mul(self, b: Self) -> Self {
        Sse2(std::arch::x86_64::_mm_mul_ps(self.0, b.0))
    }
}

/// Four lanes in plain arrays (other architectures; tests compare it with the SIMD paths).
#[cfg(any(test, not(target_arch = "x86_64")))]
#[derive(Clone, Copy)]
struct Portable([f32; 4]);

#[cfg(any(test, not(target_arch = "x86_64")))]
impl Vector for Portable {
    const LANES: usize = 4;
    #[inline(always)]
    unsafe fn zero() -> Self {
        Portable([0.0; 4])
    }
    #[inline(always)]
    unsafe fn splat(x: f32) -> Self {
        Portable([x; 4])
    }
    #[inline(always)]
    unsafe fn load(p: *const f32) -> Self {
        // SAFETY: the caller guarantees `p` is valid for 4 values.
        Portable(unsafe { p.cast::<[f32; 4]>().read_unaligned() })
    }
    #[inline(always)]
    unsafe fn store(self, p: *mut f32) {
        // SAFETY: the caller guarantees `p` is valid for 4 values.
        unsafe { p.cast::<[f32; 4]>().write_unaligned(self.0) }
    }
    #[inline(always)]
    unsafe fn add(self, b: Self) -> Self {
        Portable(std::array::from_fn(|i| self.0[i] + b.0[i]))
    }
    #[inline(always)]
    unsafe fn mul(self, b: Self) -> Self {
        Portable(std::array::from_fn(|i| self.0[i] * b.0[i]))
    }
}

/// Element-wise float32 tanh, within 2.5e-7 of the exact value (Cephes `tanhf`: an odd
/// polynomial below 0.625, `1 - 2 / (exp(2|x|) + 1)` above; NaN stays NaN). Branch-free, so it
/// runs on 8 lanes at once; only basic IEEE operations, so every path gives the same bits.
///
/// Public (re-exported as `cpmx_policy::tanh_in_place`) so the trainer's MLP uses the same
/// activation; inlined into the caller, it vectorises for the caller's target features.
#[inline(always)]
pub fn tanh_in_place(v: &mut [f32]) {
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
            tanh_in_place(&mut v);
            for (got, arg) in v.into_iter().zip([x, x * 1e-3]) {
                worst = worst.max((f64::from(got) - f64::from(arg).tanh()).abs());
            }
            x += 1.0e-4;
        }
        assert!(worst < 2.5e-7, "worst {worst:e}");
        let mut v = [0.0f32, 1e-30, -1e-30, f32::MAX, f32::MIN, f32::NAN];
        tanh_in_place(&mut v);
        assert_eq!(v[..5], [0.0, 1e-30, -1e-30, 1.0, -1.0]);
        assert!(v[5].is_nan());
    }

    #[test]
    fn dense_layer_matches_a_naive_product_for_every_group_size() {
        let (inputs, outputs) = (37, 21);
        let w: Vec<f32> = (0..inputs * outputs).map(|i| (i as f32 * 0.37).sin()).collect(); // [out][in]
        let b: Vec<f32> = (0..outputs).map(|j| j as f32 * 0.1).collect();
        let layer = Dense::new(&w, &b, inputs, outputs, Activation::Identity);
        let x: Vec<f32> = (0..GROUP * inputs).map(|i| (i as f32).cos()).collect(); // agent-major
        let want = |r: usize, j: usize| {
            (0..inputs)
                .map(|k| f64::from(x[r * inputs + k]) * f64::from(w[j * inputs + k]))
                .sum::<f64>()
                + f64::from(b[j])
        };
        fn run<const R: usize>(layer: &Dense, x: &[f32], inputs: usize) -> Vec<f32> {
            let xt: Vec<f32> = (0..inputs * R).map(|i| x[(i % R) * inputs + i / R]).collect();
            let mut y = vec![f32::NAN; layer.out_padded() * R];
            layer.apply::<R>(&xt, &mut y);
            y
        }
        let all = [
            run::<1>(&layer, &x, inputs),
            run::<2>(&layer, &x, inputs),
            run::<3>(&layer, &x, inputs),
            run::<4>(&layer, &x, inputs),
        ];
        for (g, y) in all.iter().enumerate() {
            let rows = g + 1;
            for r in 0..rows {
                for j in 0..layer.out_padded() {
                    let got = y[j * rows + r];
                    if j < outputs {
                        assert!((f64::from(got) - want(r, j)).abs() < 1e-5, "R={rows} r={r} j={j}");
                        // The same bits whatever the group size.
                        assert_eq!(got.to_bits(), all[3][j * 4 + r].to_bits());
                    } else {
                        assert_eq!(got, 0.0);
                    }
                }
            }
        }
    }

    #[test]
    fn every_vector_path_gives_the_same_bits() {
        let (inputs, outputs) = (40, 35);
        let w: Vec<f32> = (0..inputs * outputs)
            .map(|i| (i as f32 * 0.61).sin() * 0.3)
            .collect();
        let b: Vec<f32> = (0..outputs).map(|j| (j as f32).cos()).collect();
        let layer = Dense::new(&w, &b, inputs, outputs, Activation::Tanh);
        let x: Vec<f32> = (0..inputs * 3).map(|i| (i as f32 * 0.23).sin() * 2.0).collect();
        let run = |f: &dyn Fn(&[f32], &mut [f32])| {
            let mut y = vec![0.0f32; layer.out_padded() * 3];
            f(&x, &mut y);
            y.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        };
        // SAFETY: the portable vectors need no CPU feature.
        let portable = run(&|x, y| unsafe { layer.apply_with::<Portable, 3, { PANEL / 4 }>(x, y) });
        assert_eq!(run(&|x, y| layer.apply::<3>(x, y)), portable);
        #[cfg(target_arch = "x86_64")]
        // SAFETY: every x86_64 CPU supports SSE2.
        let sse2 = run(&|x, y| unsafe { layer.apply_with::<Sse2, 3, { PANEL / 4 }>(x, y) });
        #[cfg(target_arch = "x86_64")]
        assert_eq!(sse2, portable);
    }
}
