//! The optimiser side of SigmaRL's update: joint gradient-norm clipping over all parameter
//! tensors (torch's `clip_grad_norm_`), Adam (torch's defaults, no weight decay) and the
//! learning-rate schedule of `mappo_cavs.py`.

use rayon::prelude::*;

/// Elements per task of the element-wise updates.
const CHUNK: usize = 16384;

/// Torch's `clip_grad_norm_(params, max_norm)` over several gradient tensors: the total norm is
/// the L2 norm of the per-tensor L2 norms; every gradient is scaled by
/// `min(1, max_norm / (total + 1e-6))`. Returns the total norm before clipping. Sums run in
/// float64 in a fixed order.
pub fn clip_grad_norm(grads: &mut [&mut [f32]], max_norm: f64) -> f64 {
    let total = grads.iter().map(|g| squared_norm(g)).sum::<f64>().sqrt();
    let coef = (max_norm / (total + 1e-6)).min(1.0) as f32;
    if coef < 1.0 {
        for g in grads.iter_mut() {
            if crate::mlp::serial() {
                g.iter_mut().for_each(|v| *v *= coef);
            } else {
                g.par_chunks_mut(CHUNK)
                    .for_each(|g| g.iter_mut().for_each(|v| *v *= coef));
            }
        }
    }
    total
}

/// Sum of squares in float64.
pub fn squared_norm(g: &[f32]) -> f64 {
    g.iter().map(|&v| f64::from(v) * f64::from(v)).sum()
}

/// Matching chunks of the parameters, the gradient and the two moments.
type AdamChunk<'a> = ((&'a mut [f32], &'a [f32]), (&'a mut [f32], &'a mut [f32]));

/// Adam's hyperparameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdamConfig {
    /// β1.
    pub beta1: f32,
    /// β2.
    pub beta2: f32,
    /// ε.
    pub eps: f32,
}

impl Default for AdamConfig {
    /// Torch's defaults: 0.9, 0.999, 1e-8.
    fn default() -> Self {
        AdamConfig {
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
        }
    }
}

/// Adam's moments for one flat parameter vector.
#[derive(Debug, Clone, PartialEq)]
pub struct AdamState {
    /// First moments.
    pub m: Vec<f32>,
    /// Second moments.
    pub v: Vec<f32>,
}

impl AdamState {
    /// Zero moments for `len` parameters.
    pub fn new(len: usize) -> Self {
        AdamState {
            m: vec![0.0; len],
            v: vec![0.0; len],
        }
    }

    /// One Adam step number `step` (1-based) with learning rate `lr`, as torch's single-tensor
    /// Adam computes it: `m = β1 m + (1-β1) g`, `v = β2 v + (1-β2) g²`,
    /// `p -= (lr / (1-β1^t)) m / (sqrt(v) / sqrt(1-β2^t) + ε)`.
    pub fn step(&mut self, config: &AdamConfig, step: u64, lr: f64, params: &mut [f32], grad: &[f32]) {
        let t = step as i32;
        let bias1 = 1.0 - f64::from(config.beta1).powi(t);
        let bias2_sqrt = (1.0 - f64::from(config.beta2).powi(t)).sqrt() as f32;
        let step_size = (lr / bias1) as f32;
        let (b1, b2) = (config.beta1, config.beta2);
        let eps = config.eps;
        // Element-wise, so splitting the vectors between threads changes no bit.
        let update = |((params, grad), (m, v)): AdamChunk<'_>| {
            for (((p, &g), m), v) in params.iter_mut().zip(grad).zip(m).zip(v) {
                *m = b1 * *m + (1.0 - b1) * g;
                *v = b2 * *v + (1.0 - b2) * g * g;
                let denom = v.sqrt() / bias2_sqrt + eps;
                *p -= step_size * *m / denom;
            }
        };
        if crate::mlp::serial() {
            update(((params, grad), (&mut self.m, &mut self.v)));
        } else {
            params
                .par_chunks_mut(CHUNK)
                .zip(grad.par_chunks(CHUNK))
                .zip(self.m.par_chunks_mut(CHUNK).zip(self.v.par_chunks_mut(CHUNK)))
                .for_each(update);
        }
    }
}

/// The learning rate of iteration `k` (1-based) of `n_iters` (`mappo_cavs.py:517-525`): set
/// after each iteration for the next one, so iterations 1 and 2 both use `lr`, and iteration
/// `k >= 2` uses `lr_min + (lr - lr_min) (1 - (k - 2) / n_iters)`.
pub fn learning_rate(k: u64, n_iters: u64, lr: f64, lr_min: f64) -> f64 {
    if k <= 1 {
        lr
    } else {
        lr_min + (lr - lr_min) * (1.0 - (k - 2) as f64 / n_iters as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schedule_lags_one_iteration() {
        assert_eq!(learning_rate(1, 1000, 1e-4, 1e-5), 1e-4);
        assert_eq!(learning_rate(2, 1000, 1e-4, 1e-5), 1e-4);
        assert!((learning_rate(1000, 1000, 1e-4, 1e-5) - 1.018e-5).abs() < 1e-12);
    }

    #[test]
    fn clipping_scales_to_the_maximum_norm() {
        let (mut a, mut b) = (vec![3.0f32], vec![4.0f32, 0.0]);
        let total = clip_grad_norm(&mut [&mut a, &mut b], 1.0);
        assert_eq!(total, 5.0);
        assert!((f64::from(a[0]).hypot(f64::from(b[0])) - 1.0).abs() < 1e-6);
        let mut c = vec![0.1f32];
        clip_grad_norm(&mut [&mut c], 1.0);
        assert_eq!(c, [0.1]);
    }

    #[test]
    fn adam_first_step_moves_by_lr_against_the_gradient_sign() {
        let mut state = AdamState::new(2);
        let mut p = vec![1.0f32, 1.0];
        state.step(&AdamConfig::default(), 1, 0.01, &mut p, &[0.5, -2.0]);
        assert!((p[0] - 0.99).abs() < 1e-6 && (p[1] - 1.01).abs() < 1e-6, "{p:?}");
    }
}
