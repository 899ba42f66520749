//! The trainable tanh MLP: parameters in one flat f32 vector in torch's layout
//! (`W_l [out][in]` row-major, then `b_l`, layer by layer), a batched forward pass that keeps
//! every activation, and the backward pass to per-tensor gradients in the same layout.
//!
//! The products run on [`crate::gemm`]; the activation is `cpmx-policy`'s tanh (the same
//! function and bits as the inference actor). Files use the inference actor's tensor names
//! `{prefix}.{l}.weight` / `{prefix}.{l}.bias`, so a trained actor loads with
//! `cpmx_policy::MlpActor` (and [`Mlp::to_actor`] hands it over in memory).

use cpmx_policy::{Activation, ActorError, MlpActor, MlpLayout};
use rand::RngExt;
use rand_chacha::ChaCha20Rng;
use safetensors::{Dtype, SafeTensors};

use rayon::prelude::*;

use crate::gemm::{Mat, gemm};

/// Elements per task of the element-wise passes (a multiple of the 8 SIMD lanes). Each
/// element is computed alone, so the split never changes a bit.
const ELEMENTWISE_CHUNK: usize = 8192;
/// Bias-gradient columns per task.
const BIAS_COLUMNS: usize = 64;

/// A tanh MLP (tanh after every layer but the last).
#[derive(Debug, Clone, PartialEq)]
pub struct Mlp {
    sizes: Vec<usize>,
    /// Offsets of `W_l` and `b_l` in the flat parameter vector.
    offsets: Vec<(usize, usize)>,
    /// All parameters.
    pub params: Vec<f32>,
}

/// The activations of one forward pass, kept for the backward pass.
#[derive(Debug, Clone, Default)]
pub struct Tape {
    rows: usize,
    /// `h[0]` is the input, `h[l + 1]` the output of layer `l` (after tanh for hidden layers).
    h: Vec<Vec<f32>>,
    /// Gradient buffers of the backward pass.
    dz: Vec<f32>,
    dh: Vec<f32>,
}

impl Tape {
    /// The network's output of the last forward pass, `[rows][outputs]`.
    pub fn output(&self) -> &[f32] {
        self.h.last().map_or(&[], |v| &v[..])
    }
}

impl Mlp {
    /// A network with PyTorch's default `nn.Linear` initialisation: weights and biases uniform
    /// in `±1/sqrt(fan_in)`, drawn layer by layer (weights row-major, then biases) from `rng`.
    pub fn init(sizes: &[usize], rng: &mut ChaCha20Rng) -> Self {
        let mut mlp = Self::zeros(sizes);
        for l in 0..mlp.layers() {
            let bound = 1.0 / (sizes[l] as f32).sqrt();
            let (w, b) = mlp.offsets[l];
            let end = b + sizes[l + 1];
            for p in &mut mlp.params[w..end] {
                *p = rng.random_range(-bound..bound);
            }
        }
        mlp
    }

    /// A network of the given widths (input first) with all parameters 0.
    pub fn zeros(sizes: &[usize]) -> Self {
        assert!(sizes.len() >= 2, "an MLP has at least one layer");
        let mut offsets = Vec::new();
        let mut at = 0;
        for pair in sizes.windows(2) {
            offsets.push((at, at + pair[0] * pair[1]));
            at += pair[0] * pair[1] + pair[1];
        }
        Mlp {
            sizes: sizes.to_vec(),
            offsets,
            params: vec![0.0; at],
        }
    }

    /// Layer widths, input first.
    pub fn sizes(&self) -> &[usize] {
        &self.sizes
    }

    /// Number of layers.
    pub fn layers(&self) -> usize {
        self.sizes.len() - 1
    }

    /// Input width.
    pub fn inputs(&self) -> usize {
        self.sizes[0]
    }

    /// Output width.
    pub fn outputs(&self) -> usize {
        self.sizes[self.sizes.len() - 1]
    }

    /// `(name suffix, offset, length)` of every tensor in file order: `{l}.weight`, `{l}.bias`.
    pub fn tensors(&self) -> Vec<(String, usize, usize)> {
        let mut out = Vec::new();
        for (l, &(w, b)) in self.offsets.iter().enumerate() {
            out.push((format!("{l}.weight"), w, b - w));
            out.push((format!("{l}.bias"), b, self.sizes[l + 1]));
        }
        out
    }

    /// Layer `l`'s weight `[out][in]`.
    pub fn weight(&self, l: usize) -> &[f32] {
        let (w, b) = self.offsets[l];
        &self.params[w..b]
    }

    /// Layer `l`'s bias.
    pub fn bias(&self, l: usize) -> &[f32] {
        let b = self.offsets[l].1;
        &self.params[b..b + self.sizes[l + 1]]
    }

    /// Multiply-accumulates of one forward pass over `rows` rows.
    pub fn forward_macs(&self, rows: usize) -> u64 {
        self.sizes.windows(2).map(|p| (rows * p[0] * p[1]) as u64).sum()
    }

    /// Multiply-accumulates of one backward pass (no input gradient).
    pub fn backward_macs(&self, rows: usize) -> u64 {
        2 * self.forward_macs(rows) - (rows * self.sizes[0] * self.sizes[1]) as u64
    }

    /// Forward pass over `rows` rows of `x` (`[rows][inputs]`), keeping the activations in
    /// `tape`; the output is `tape.output()`.
    pub fn forward(&self, x: &[f32], rows: usize, tape: &mut Tape) {
        assert_eq!(x.len(), rows * self.inputs(), "input size");
        tape.rows = rows;
        tape.h.resize_with(self.sizes.len(), Vec::new);
        tape.h[0].clear();
        tape.h[0].extend_from_slice(x);
        for l in 0..self.layers() {
            let (inputs, outputs) = (self.sizes[l], self.sizes[l + 1]);
            let (before, after) = tape.h.split_at_mut(l + 1);
            let (x, y) = (&before[l], &mut after[0]);
            y.resize(rows * outputs, 0.0);
            for row in y.chunks_exact_mut(outputs) {
                row.copy_from_slice(self.bias(l));
            }
            // y = x W^T + b
            gemm(
                rows,
                outputs,
                inputs,
                Mat::rows(x, inputs),
                Mat::transposed(self.weight(l), inputs),
                y,
                outputs,
                true,
            );
            if l + 1 < self.layers() {
                if serial() {
                    tanh(y);
                } else {
                    y.par_chunks_mut(ELEMENTWISE_CHUNK).for_each(tanh);
                }
            }
        }
    }

    /// Backward pass of the last [`Mlp::forward`] in `tape`: `d_out` is the loss gradient with
    /// respect to the output (`[rows][outputs]`); `grad` (the parameters' layout) receives the
    /// parameter gradients (overwritten).
    pub fn backward(&self, tape: &mut Tape, d_out: &[f32], grad: &mut [f32]) {
        let rows = tape.rows;
        assert_eq!(d_out.len(), rows * self.outputs(), "output gradient size");
        assert_eq!(grad.len(), self.params.len(), "gradient size");
        let mut dz = std::mem::take(&mut tape.dz);
        let mut dh = std::mem::take(&mut tape.dh);
        dz.clear();
        dz.extend_from_slice(d_out);
        for l in (0..self.layers()).rev() {
            let (inputs, outputs) = (self.sizes[l], self.sizes[l + 1]);
            let (w_at, b_at) = self.offsets[l];
            // dW = dZ^T H_l
            gemm(
                outputs,
                inputs,
                rows,
                Mat::transposed(&dz, outputs),
                Mat::rows(&tape.h[l], inputs),
                &mut grad[w_at..b_at],
                inputs,
                false,
            );
            // db = column sums of dZ, rows in order (columns split between threads).
            let db = &mut grad[b_at..b_at + outputs];
            let column_sums = |(c, db): (usize, &mut [f32])| {
                let j0 = c * BIAS_COLUMNS;
                db.fill(0.0);
                for row in dz.chunks_exact(outputs) {
                    for (d, &v) in db.iter_mut().zip(&row[j0..]) {
                        *d += v;
                    }
                }
            };
            if serial() {
                db.chunks_mut(BIAS_COLUMNS).enumerate().for_each(column_sums);
            } else {
                db.par_chunks_mut(BIAS_COLUMNS).enumerate().for_each(column_sums);
            }
            if l == 0 {
                break;
            }
            // dH = dZ W, then through tanh: dZ_prev = dH (1 - h^2).
            dh.resize(rows * inputs, 0.0);
            gemm(
                rows,
                inputs,
                outputs,
                Mat::rows(&dz, outputs),
                Mat::rows(self.weight(l), inputs),
                &mut dh,
                inputs,
                false,
            );
            let through_tanh = |(dh, h): (&mut [f32], &[f32])| {
                for (d, &h) in dh.iter_mut().zip(h) {
                    *d *= 1.0 - h * h;
                }
            };
            if serial() {
                through_tanh((&mut dh[..], &tape.h[l][..]));
            } else {
                dh.par_chunks_mut(ELEMENTWISE_CHUNK)
                    .zip(tape.h[l].par_chunks(ELEMENTWISE_CHUNK))
                    .for_each(through_tanh);
            }
            std::mem::swap(&mut dz, &mut dh);
        }
        tape.dz = dz;
        tape.dh = dh;
    }

    /// The tensors as `({prefix}.{l}.weight|bias, shape, values)`, in file order.
    pub fn named_tensors(&self, prefix: &str) -> Vec<(String, Vec<usize>, &[f32])> {
        let mut out = Vec::new();
        for l in 0..self.layers() {
            out.push((
                format!("{prefix}.{l}.weight"),
                vec![self.sizes[l + 1], self.sizes[l]],
                self.weight(l),
            ));
            out.push((
                format!("{prefix}.{l}.bias"),
                vec![self.sizes[l + 1]],
                self.bias(l),
            ));
        }
        out
    }

    /// Read a network stored under `prefix` (its layout from the shapes, as the inference
    /// actor reads it).
    pub fn from_safetensors(bytes: &[u8], prefix: &str) -> Result<Self, ActorError> {
        let layout = MlpLayout::from_safetensors(bytes, prefix)?;
        let tensors = SafeTensors::deserialize(bytes).map_err(|e| ActorError::Format(e.to_string()))?;
        let mut mlp = Self::zeros(&layout.sizes());
        for (suffix, at, len) in mlp.tensors() {
            let name = format!("{prefix}.{suffix}");
            let view = tensors.tensor(&name).map_err(|_| ActorError::MissingTensor {
                name: name.clone(),
                expected: vec![len],
            })?;
            if view.dtype() != Dtype::F32 || view.data().len() != 4 * len {
                return Err(ActorError::Dtype {
                    name,
                    found: format!("{} with {} bytes", view.dtype(), view.data().len()),
                });
            }
            for (p, b) in mlp.params[at..at + len]
                .iter_mut()
                .zip(view.data().chunks_exact(4))
            {
                *p = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
            }
        }
        Ok(mlp)
    }

    /// The inference actor with these weights (`cpmx-policy`'s kernels).
    pub fn to_actor(&self) -> Result<MlpActor, ActorError> {
        let layers: Vec<(&[f32], &[f32])> = (0..self.layers())
            .map(|l| (self.weight(l), self.bias(l)))
            .collect();
        MlpActor::from_layers(&self.sizes, &layers, Activation::Tanh)
    }
}

/// Whether rayon's current pool has one thread: element-wise loops then run as plain loops
/// (a parallel iterator costs its task splitting even alone; the results are the same).
pub(crate) fn serial() -> bool {
    rayon::current_num_threads() == 1
}

/// `cpmx-policy`'s tanh ([`cpmx_policy::tanh_in_place`]), 16 lanes at a time with AVX-512 or
/// 8 with AVX2 when the CPU has them: the same operations in the same order, each rounded
/// separately, so the same bits (a test sweeps the range).
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
        cpmx_policy::tanh_in_place(tail);
        return;
    }
    cpmx_policy::tanh_in_place(v);
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

/// Eight lanes of `cpmx-policy`'s Cephes tanh (see `kernel.rs` there for the algorithm).
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_simd_tanh_gives_the_policy_crates_bits() {
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
        cpmx_policy::tanh_in_place(&mut want);
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
