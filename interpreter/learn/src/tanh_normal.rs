//! SigmaRL's action distribution with its gradients: torchrl's `TanhNormal(loc, scale,
//! low = -high, high = high, safe_tanh = true)` over the network's raw outputs
//! `[loc_v, loc_δ, z_v, z_δ]` with `scale = max(softplus(z + 0.52546) + 0.01, 1e-4)`, at most
//! `max_scale` when a training bounds it (`algorithm.mappo.max_scale`: clamped as torch's
//! `clamp`, no gradient above the bound; SigmaRL has no bound, `f32::INFINITY`).
//!
//! Per dimension, an action `a` is scored through torch's float32 inverse
//! `u = atanh(clamp(a / high, ±(1 - 1e-6)))` and
//! `log p = log N(u; loc, scale) - 2 (ln 2 - u - softplus(-2u)) - ln high`, summed over the two
//! dimensions. Values are taken as float32 where torch rounds (the division, the clamp, the
//! sample) and evaluated in float64 otherwise. Gradients are with respect to the raw outputs.

/// `log(expm1(0.99))`: torchrl's `biased_softplus_1.0` bias (scale 1 for a raw output of 0).
pub const SCALE_BIAS: f32 = 0.525_458_7;
/// Added to the softplus (`biased_softplus_1.0`'s minimum).
const SCALE_OFFSET: f64 = 0.01;
/// Lower bound of the scale.
const SCALE_MIN: f64 = 1e-4;
/// `1 - finfo(float32).resolution`, rounded to float32 (0.99999899): safe tanh's limit.
pub const TANH_LIMIT: f32 = 1.0 - 1e-6;
/// `0.5 ln(2π)`.
const HALF_LN_2PI: f64 = 0.918_938_533_204_672_8;

/// A distribution's parameters from the raw outputs, and `d scale / d z`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Params {
    /// Gaussian location before tanh.
    pub loc: [f32; 2],
    /// Gaussian scale.
    pub scale: [f32; 2],
    /// `d scale / d z` per dimension.
    pub dscale_dz: [f32; 2],
}

/// A log-probability and its gradient with respect to the 4 raw outputs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scored {
    /// `log p`.
    pub log_prob: f64,
    /// `d log p / d raw`.
    pub grad_raw: [f64; 4],
}

/// Softplus as torch computes it (linear above 20), in float64.
fn softplus(x: f64) -> f64 {
    if x > 20.0 { x } else { x.exp().ln_1p() }
}

fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

/// `loc` and `scale` of the raw outputs (torchrl's `NormalParamExtractor`), the scale at most
/// `max_scale`.
pub fn params(raw: &[f32], max_scale: f32) -> Params {
    let mut scale = [0.0; 2];
    let mut dscale_dz = [0.0; 2];
    for c in 0..2 {
        let x = f64::from(raw[2 + c] + SCALE_BIAS);
        let s = softplus(x) + SCALE_OFFSET;
        scale[c] = (s.max(SCALE_MIN) as f32).min(max_scale);
        dscale_dz[c] = if s < SCALE_MIN || s as f32 > max_scale {
            0.0
        } else if x > 20.0 {
            1.0
        } else {
            sigmoid(x) as f32
        };
    }
    Params {
        loc: [raw[0], raw[1]],
        scale,
        dscale_dz,
    }
}

/// The action of a pre-tanh value: `high * clamp(tanh(x), ±TANH_LIMIT)` in float32.
pub fn squash(x: f32, high: f32) -> f32 {
    high * (f64::from(x).tanh() as f32).clamp(-TANH_LIMIT, TANH_LIMIT)
}

/// The deterministic action `high * clamp(tanh(loc))`.
pub fn mean_action(p: &Params, high: [f32; 2]) -> [f32; 2] {
    [squash(p.loc[0], high[0]), squash(p.loc[1], high[1])]
}

/// A sample `high * clamp(tanh(loc + scale * eps))` (the pre-tanh value rounded to float32).
pub fn sample(p: &Params, eps: [f32; 2], high: [f32; 2]) -> [f32; 2] {
    std::array::from_fn(|c| squash(p.loc[c] + p.scale[c] * eps[c], high[c]))
}

/// torch's inverse of one action coordinate: `(u, y)` with `y = clamp(a / high)` in float32.
fn inverse(a: f32, high: f32) -> (f64, f64) {
    let y = (a / high).clamp(-TANH_LIMIT, TANH_LIMIT);
    (f64::from(y).atanh(), f64::from(y))
}

/// `log N(u) - log|d tanh/du| - ln high` of one dimension and its partial derivatives
/// with respect to `u`, `loc`, `scale`.
fn dimension(u: f64, loc: f64, scale: f64, high: f64) -> (f64, f64, f64, f64) {
    let z = (u - loc) / scale;
    let log_det = 2.0 * (std::f64::consts::LN_2 - u - softplus(-2.0 * u));
    let lp = -0.5 * z * z - scale.ln() - HALF_LN_2PI - log_det - high.ln();
    let d_u = -z / scale + 2.0 * u.tanh();
    let d_loc = z / scale;
    let d_scale = z * z / scale - 1.0 / scale;
    (lp, d_u, d_loc, d_scale)
}

/// The log-probability of a given action (as torch scores a stored action) with its
/// gradient.
pub fn log_prob(p: &Params, action: [f32; 2], high: [f32; 2]) -> Scored {
    let mut out = Scored {
        log_prob: 0.0,
        grad_raw: [0.0; 4],
    };
    for c in 0..2 {
        let (u, _) = inverse(action[c], high[c]);
        let (lp, _, d_loc, d_scale) =
            dimension(u, f64::from(p.loc[c]), f64::from(p.scale[c]), f64::from(high[c]));
        out.log_prob += lp;
        out.grad_raw[c] = d_loc;
        out.grad_raw[2 + c] = d_scale * f64::from(p.dscale_dz[c]);
    }
    out
}

/// The log-probability of the reparameterised sample `high * clamp(tanh(loc + scale * eps))`
/// scored through the inverse (torchrl's one-sample entropy estimate is `-log p`), with the
/// gradient flowing through the sample as torch's safe tanh/atanh backward passes define it:
/// `du/dx = (1 - t^2) / (1 - y^2)` (t the clamped tanh, y the clamped inverse argument).
pub fn sample_log_prob(p: &Params, eps: [f32; 2], high: [f32; 2]) -> Scored {
    let mut out = Scored {
        log_prob: 0.0,
        grad_raw: [0.0; 4],
    };
    for c in 0..2 {
        let x = p.loc[c] + p.scale[c] * eps[c];
        let t = (f64::from(x).tanh() as f32).clamp(-TANH_LIMIT, TANH_LIMIT);
        let a = high[c] * t;
        let (u, y) = inverse(a, high[c]);
        let du_dx = (1.0 - f64::from(t) * f64::from(t)) / (1.0 - y * y);
        let (lp, d_u, d_loc, d_scale) =
            dimension(u, f64::from(p.loc[c]), f64::from(p.scale[c]), f64::from(high[c]));
        out.log_prob += lp;
        // x = loc + scale * eps
        out.grad_raw[c] = d_loc + d_u * du_dx;
        out.grad_raw[2 + c] = (d_scale + d_u * du_dx * f64::from(eps[c])) * f64::from(p.dscale_dz[c]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Central differences in float64 of a function of the raw outputs.
    fn numeric(f: &dyn Fn(&[f32; 4]) -> f64, raw: [f32; 4]) -> [f64; 4] {
        std::array::from_fn(|i| {
            let h = 1e-3f32;
            let (mut up, mut down) = (raw, raw);
            up[i] += h;
            down[i] -= h;
            (f(&up) - f(&down)) / f64::from(up[i] - down[i])
        })
    }

    #[test]
    fn gradients_match_central_differences() {
        let high = [1.0, 0.541_052_04];
        let cases = [
            ([0.3f32, -0.2, 0.1, -0.4], [0.5f32, -0.3], [0.7f32, -1.3]),
            ([1.2, 0.4, -1.5, 0.8], [0.9, 0.2], [-0.2, 0.4]),
            ([-0.7, 0.9, 2.0, -2.0], [-0.6, 0.5], [1.5, 0.1]),
        ];
        for (raw, action, eps) in cases {
            let lp = |r: &[f32; 4]| log_prob(&params(r, f32::INFINITY), action, high).log_prob;
            let got = log_prob(&params(&raw, f32::INFINITY), action, high).grad_raw;
            let want = numeric(&lp, raw);
            for i in 0..4 {
                // float32 rounding of loc/scale bounds the difference quotient's accuracy.
                assert!(
                    (got[i] - want[i]).abs() < 2e-3 * (1.0 + want[i].abs()),
                    "{i}: {got:?} {want:?}"
                );
            }
            let se = |r: &[f32; 4]| sample_log_prob(&params(r, f32::INFINITY), eps, high).log_prob;
            let got = sample_log_prob(&params(&raw, f32::INFINITY), eps, high).grad_raw;
            let want = numeric(&se, raw);
            for i in 0..4 {
                assert!(
                    (got[i] - want[i]).abs() < 2e-3 * (1.0 + want[i].abs()),
                    "{i}: {got:?} {want:?}"
                );
            }
        }
    }

    #[test]
    fn a_bounded_scale_stops_at_its_bound_without_gradient_above_it() {
        let high = [1.0, 0.541_052_04];
        // z = 3 gives a scale of about 3.5, z = -1 about 0.64.
        let raw = [0.2f32, -0.1, 3.0, -1.0];
        let free = params(&raw, f32::INFINITY);
        let bounded = params(&raw, 1.0);
        assert!(free.scale[0] > 3.0);
        assert_eq!(bounded.scale, [1.0, free.scale[1]]);
        assert_eq!(bounded.dscale_dz, [0.0, free.dscale_dz[1]]);
        // The clamped dimension's raw output gets no gradient; the other is unchanged.
        let action = [0.4f32, -0.2];
        let got = log_prob(&bounded, action, high).grad_raw;
        let want = log_prob(&free, action, high).grad_raw;
        assert_eq!(got[2], 0.0);
        assert_eq!(got[3], want[3]);
        let lp = |r: &[f32; 4]| log_prob(&params(r, 1.0), action, high).log_prob;
        let numeric_grad = numeric(&lp, raw);
        assert!((got[1] - numeric_grad[1]).abs() < 2e-3 * (1.0 + numeric_grad[1].abs()));
    }

    #[test]
    fn zero_raw_output_is_unit_scale() {
        let p = params(&[0.0; 4], f32::INFINITY);
        assert!((p.scale[0] - 1.0).abs() < 1e-6);
    }
}
