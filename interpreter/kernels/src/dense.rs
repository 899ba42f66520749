//! The dense layer of every MLP in cpmx: the inference actor (`cpmx-policy`) and the trainer's
//! networks (`cpmx-learn`) run their layers through [`dense_layer`], so an actor computes the
//! same bits when `cpmx run` evaluates it as when `cpmx train` collected with it.

use rayon::prelude::*;

use crate::Activation;
use crate::gemm::{Mat, PackedB, gemm, gemm_packed};

/// Elements per task of a parallel activation pass (a multiple of the 16 SIMD lanes). Each
/// element is computed alone, so the split never changes a bit.
pub const ELEMENTWISE_CHUNK: usize = 8192;

/// `y = activation(x W^T + b)` over `rows` rows: `x` is `[rows][inputs]`, `y` receives
/// `[rows][outputs]`, and `weight_t` is W^T as an `inputs x outputs` view: torch's
/// `[outputs][inputs]` weight through [`Mat::transposed`], or a stored transpose through
/// [`Mat::rows`] (read in place by the AVX-512 kernel, the better layout for a few rows).
///
/// Every output is one running sum that starts from the bias and adds `x_k w_k` in increasing
/// `k`, one fused multiply-add per term ([`gemm`]): the bits do not depend on the layout of W,
/// the batch an agent is in, the CPU's vector extensions or the thread count. The activation
/// runs on rayon's current pool when it has several threads and `y` is long.
#[allow(clippy::too_many_arguments)]
pub fn dense_layer(
    x: &[f32],
    rows: usize,
    inputs: usize,
    outputs: usize,
    weight_t: Mat<'_>,
    bias: &[f32],
    activation: Activation,
    y: &mut [f32],
) {
    start_from_bias(x, rows, inputs, outputs, bias, y);
    gemm(
        rows,
        outputs,
        inputs,
        Mat::rows(x, inputs),
        weight_t,
        y,
        outputs,
        true,
    );
    activate(activation, y);
}

/// [`dense_layer`] with W^T packed once ([`PackedB`], `inputs x outputs`): an actor's layers,
/// which every decision reads with a few rows. The same bits.
pub fn dense_layer_packed(
    x: &[f32],
    rows: usize,
    weight_t: &PackedB,
    bias: &[f32],
    activation: Activation,
    y: &mut [f32],
) {
    let (inputs, outputs) = (weight_t.rows(), weight_t.cols());
    start_from_bias(x, rows, inputs, outputs, bias, y);
    gemm_packed(rows, Mat::rows(x, inputs), weight_t, y, outputs, true);
    activate(activation, y);
}

/// Checks the sizes and writes the bias into every row of `y`.
fn start_from_bias(x: &[f32], rows: usize, inputs: usize, outputs: usize, bias: &[f32], y: &mut [f32]) {
    assert_eq!(x.len(), rows * inputs, "input size");
    assert_eq!(y.len(), rows * outputs, "output size");
    assert_eq!(bias.len(), outputs, "bias size");
    for row in y.chunks_exact_mut(outputs) {
        row.copy_from_slice(bias);
    }
}

/// The activation over `y`, on rayon's current pool when it has several threads and `y` is long.
fn activate(activation: Activation, y: &mut [f32]) {
    if activation == Activation::Identity {
        return;
    }
    if rayon::current_num_threads() > 1 && y.len() > ELEMENTWISE_CHUNK {
        y.par_chunks_mut(ELEMENTWISE_CHUNK)
            .for_each(|chunk| activation.apply(chunk));
    } else {
        activation.apply(y);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_layer_matches_a_naive_product_and_its_bits_do_not_depend_on_the_layout_or_batch() {
        let (inputs, outputs, rows) = (37, 21, 5);
        let w: Vec<f32> = (0..inputs * outputs).map(|i| (i as f32 * 0.37).sin()).collect(); // [out][in]
        let w_t: Vec<f32> = (0..inputs * outputs)
            .map(|i| w[(i % outputs) * inputs + i / outputs])
            .collect(); // [in][out]
        let b: Vec<f32> = (0..outputs).map(|j| j as f32 * 0.1).collect();
        let x: Vec<f32> = (0..rows * inputs).map(|i| (i as f32).cos()).collect();
        let want = |r: usize, j: usize| {
            let z = (0..inputs)
                .map(|k| f64::from(x[r * inputs + k]) * f64::from(w[j * inputs + k]))
                .sum::<f64>()
                + f64::from(b[j]);
            z.tanh()
        };
        let run = |rows: usize, weight_t: Mat<'_>| {
            let mut y = vec![f32::NAN; rows * outputs];
            dense_layer(
                &x[..rows * inputs],
                rows,
                inputs,
                outputs,
                weight_t,
                &b,
                Activation::Tanh,
                &mut y,
            );
            y
        };
        let torch = run(rows, Mat::transposed(&w, inputs));
        let stored = run(rows, Mat::rows(&w_t, outputs));
        for r in 0..rows {
            for j in 0..outputs {
                let got = torch[r * outputs + j];
                assert!((f64::from(got) - want(r, j)).abs() < 1e-5, "r={r} j={j}");
                assert_eq!(got.to_bits(), stored[r * outputs + j].to_bits());
            }
        }
        // A row's outputs are the same bits alone as in the batch.
        for batch in 1..rows {
            let first = run(batch, Mat::rows(&w_t, outputs));
            assert_eq!(first[..], torch[..batch * outputs]);
        }
    }

    #[test]
    fn thread_count_does_not_change_a_wide_layer() {
        let (inputs, outputs, rows) = (64, 256, 100);
        let w: Vec<f32> = (0..inputs * outputs)
            .map(|i| (i as f32 * 0.11).cos() * 0.2)
            .collect();
        let b = vec![0.1f32; outputs];
        let x: Vec<f32> = (0..rows * inputs).map(|i| (i as f32 * 0.7).sin()).collect();
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut y = vec![0.0f32; rows * outputs];
            pool.install(|| {
                dense_layer(
                    &x,
                    rows,
                    inputs,
                    outputs,
                    Mat::transposed(&w, inputs),
                    &b,
                    Activation::Tanh,
                    &mut y,
                )
            });
            y.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        };
        assert_eq!(run(1), run(2));
    }
}
