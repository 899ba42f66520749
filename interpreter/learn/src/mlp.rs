//! The trainable tanh MLP: parameters in one flat f32 vector in torch's layout
//! (`W_l [out][in]` row-major, then `b_l`, layer by layer), a batched forward pass that keeps
//! every activation, and the backward pass to per-tensor gradients in the same layout.
//!
//! The forward pass runs `cpmx-kernels`' [`dense_layer`], the inference actor's layer, so the
//! actor `cpmx run` evaluates computes the bits it computed while training; the backward
//! products run on the same [`gemm`]. Files use the inference actor's tensor names
//! `{prefix}.{l}.weight` / `{prefix}.{l}.bias`, so a trained actor loads with
//! `cpmx_policy::MlpActor` (and [`Mlp::to_actor`] hands it over in memory).

use cpmx_policy::{Activation, ActorError, MlpActor, MlpLayout};
use rand::RngExt;
use rand_chacha::ChaCha20Rng;
use safetensors::{Dtype, SafeTensors};

use rayon::prelude::*;

use cpmx_kernels::dense::ELEMENTWISE_CHUNK;
use cpmx_kernels::{Mat, dense_layer, gemm};
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
            let activation = if l + 1 < self.layers() {
                Activation::Tanh
            } else {
                Activation::Identity
            };
            dense_layer(
                x,
                rows,
                inputs,
                outputs,
                Mat::transposed(self.weight(l), inputs),
                self.bias(l),
                activation,
                y,
            );
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

#[cfg(test)]
mod tests {
    use rand::SeedableRng;

    use super::*;

    #[test]
    fn the_inference_actor_computes_the_training_forward_bits() {
        let mut rng = ChaCha20Rng::seed_from_u64(3);
        let mlp = Mlp::init(&[35, 64, 48, 4], &mut rng);
        let rows = 7;
        let x: Vec<f32> = (0..rows * 35).map(|i| (i as f32 * 0.37).sin() * 3.0).collect();
        let mut tape = Tape::default();
        mlp.forward(&x, rows, &mut tape);
        let actor = mlp.to_actor().expect("an actor");
        let mut ws = actor.workspace(rows);
        let mut raw = vec![0.0f32; rows * 4];
        actor.forward(&x, &mut ws, &mut raw).expect("a forward pass");
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&raw), bits(tape.output()));
    }
}
