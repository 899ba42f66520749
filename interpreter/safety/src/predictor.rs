//! The MTV-based safety margin of SigmaRL's ECC 2025 paper (`sigmarl/cbf.py`,
//! `mtv_based_sm_predictor.py`): the margin between two car footprints is the length of the
//! minimum translation vector that separates them (negative when they overlap), which depends
//! on their headings, unlike the distance of two circles. A small network (3 → 64 → 64 → 1,
//! tanh) learned it from the other car's pose in the ego car's frame; SigmaRL keeps the rows
//! at `margin − error bound` (the network's largest error on its test set). Outside the box the
//! network was trained on, the margin of the footprints' circumscribed circles stands in, as
//! in SigmaRL.
//!
//! The network's gradient and Hessian are computed in closed form in `f64` (SigmaRL uses
//! torch's autograd in `float32`, and divides the Hessian's row `i` by the `i`-th input scale
//! squared, which for the mixed position–heading entries is not the chain rule; cpmx uses the
//! chain rule).

use crate::cbf::{CbfParameters, CbfState, Motion};

/// The learned margin: the network's layers and its error bound.
#[derive(Debug, Clone, PartialEq)]
pub struct MarginPredictor {
    /// `[64][3]` row-major, then its bias.
    first: (Vec<f64>, Vec<f64>),
    /// `[64][64]`, then its bias.
    second: (Vec<f64>, Vec<f64>),
    /// `[64]` (one output), then its bias.
    output: (Vec<f64>, f64),
    /// The largest error of the network on its test set [m] (SigmaRL's `error_upper_bound`).
    pub error_bound_m: f64,
}

/// Why a state dict is not SigmaRL's margin network.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "not SigmaRL's margin network (`DistancePredictor`: Linear(3, 64), Tanh, Linear(64, 64), Tanh, Linear(64, 1)): {0}"
)]
pub struct PredictorError(pub String);

/// A row between two cars of the predicted margin: `coefficients · [u_i, u_j] + constant ≥ 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct PredictedRow {
    /// h: the margin less the error bound [m].
    pub(crate) barrier_m: f64,
    pub(crate) coefficients: [[f64; 2]; 2],
    pub(crate) constant: f64,
}

impl MarginPredictor {
    /// The network of `layers` (`model.{0,2,4}.{weight,bias}` as `(name, shape, values)`) with
    /// its error bound.
    pub fn new(
        layers: &[(String, Vec<usize>, Vec<f32>)],
        error_bound_m: f64,
    ) -> Result<Self, PredictorError> {
        let take = |name: &str, shape: &[usize]| -> Result<Vec<f64>, PredictorError> {
            let (_, found, values) = layers
                .iter()
                .find(|(n, _, _)| n == name)
                .ok_or_else(|| PredictorError(format!("no tensor `{name}`")))?;
            if found != shape {
                return Err(PredictorError(format!(
                    "`{name}` has shape {found:?}, expected {shape:?}"
                )));
            }
            Ok(values.iter().map(|&v| f64::from(v)).collect())
        };
        if !error_bound_m.is_finite() || error_bound_m < 0.0 {
            return Err(PredictorError(format!("an error bound of {error_bound_m} m")));
        }
        Ok(MarginPredictor {
            first: (take("model.0.weight", &[64, 3])?, take("model.0.bias", &[64])?),
            second: (take("model.2.weight", &[64, 64])?, take("model.2.bias", &[64])?),
            output: (take("model.4.weight", &[1, 64])?, take("model.4.bias", &[1])?[0]),
            error_bound_m,
        })
    }

    /// The network's output at the normalised input `u`, with its gradient and Hessian in `u`.
    fn evaluate(&self, u: [f64; 3]) -> (f64, [f64; 3], [[f64; 3]; 3]) {
        let (w0, b0) = &self.first;
        let (w1, b1) = &self.second;
        let (w2, b2) = (&self.output.0, self.output.1);
        // First layer: a1 = tanh(W0 u + b0), its derivatives in u.
        let mut a1 = [0.0; 64];
        let mut da1 = [[0.0; 3]; 64];
        let mut dda1 = [[[0.0; 3]; 3]; 64];
        for m in 0..64 {
            let w = [w0[3 * m], w0[3 * m + 1], w0[3 * m + 2]];
            let a = (w[0] * u[0] + w[1] * u[1] + w[2] * u[2] + b0[m]).tanh();
            let slope = 1.0 - a * a;
            a1[m] = a;
            for p in 0..3 {
                da1[m][p] = slope * w[p];
                for q in 0..3 {
                    dda1[m][p][q] = -2.0 * a * slope * w[p] * w[q];
                }
            }
        }
        // Second layer and the output.
        let (mut out, mut gradient, mut hessian) = (b2, [0.0; 3], [[0.0; 3]; 3]);
        for k in 0..64 {
            let row = &w1[64 * k..64 * (k + 1)];
            let mut z = b1[k];
            let mut dz = [0.0; 3];
            let mut ddz = [[0.0; 3]; 3];
            for m in 0..64 {
                z += row[m] * a1[m];
                for p in 0..3 {
                    dz[p] += row[m] * da1[m][p];
                    for q in 0..3 {
                        ddz[p][q] += row[m] * dda1[m][p][q];
                    }
                }
            }
            let a = z.tanh();
            let slope = 1.0 - a * a;
            out += w2[k] * a;
            for p in 0..3 {
                gradient[p] += w2[k] * slope * dz[p];
                for q in 0..3 {
                    hessian[p][q] += w2[k] * (slope * ddz[p][q] - 2.0 * a * slope * dz[p] * dz[q]);
                }
            }
        }
        (out, gradient, hessian)
    }

    /// The margin between two footprints of `length_m` × `width_m` when the other's pose in
    /// the ego's frame is `pose` (x, y [m], heading [rad]), with its gradient and Hessian in the
    /// pose: the network's inside the box it learned (|x|, |y| < 2R + L/2, R the half diagonal;
    /// positions scaled by the length, the heading by π), the circumscribed circles' outside.
    pub fn margin(&self, pose: [f64; 3], length_m: f64, width_m: f64) -> (f64, [f64; 3], [[f64; 3]; 3]) {
        let radius = length_m.hypot(width_m) / 2.0;
        let reach = 2.0 * radius + length_m / 2.0;
        let [x, y, _] = pose;
        if x.abs() < reach && y.abs() < reach {
            let heading = (pose[2] + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI)
                - std::f64::consts::PI;
            let scale = [length_m, length_m, std::f64::consts::PI];
            let (out, g, h) = self.evaluate([x / scale[0], y / scale[1], heading / scale[2]]);
            let gradient = std::array::from_fn(|p| g[p] * length_m / scale[p]);
            let hessian =
                std::array::from_fn(|p| std::array::from_fn(|q| h[p][q] * length_m / (scale[p] * scale[q])));
            (out * length_m, gradient, hessian)
        } else {
            let d = x.hypot(y);
            let d3 = d * d * d;
            (
                d - 2.0 * radius,
                [x / d, y / d, 0.0],
                [
                    [y * y / d3, -x * y / d3, 0.0],
                    [-x * y / d3, x * x / d3, 0.0],
                    [0.0; 3],
                ],
            )
        }
    }
}

/// The truncated-Taylor row `λh + ḣΔt + ½ḧΔt² ≥ 0` on the predicted margin between cars `i`
/// and `j` (footprints `length_m` × `width_m`), with h = margin − error bound and the pose of
/// `j` in `i`'s frame and its derivatives as SigmaRL's `compute_state_time_derivatives`
/// (its eqs. (1)–(6)), affine in both cars' inputs.
pub(crate) fn predicted_row(
    p: &CbfParameters,
    predictor: &MarginPredictor,
    footprint_m: [f64; 2],
    states: [CbfState; 2],
) -> PredictedRow {
    let [si, sj] = states;
    let [mi, mj] = states.map(|s| Motion::of(p, s));
    let (cos_i, sin_i) = (mi.cos_yaw, mi.sin_yaw);
    let global = [
        f64::from(sj.x_m) - f64::from(si.x_m),
        f64::from(sj.y_m) - f64::from(si.y_m),
    ];
    let pose = [
        cos_i * global[0] + sin_i * global[1],
        -sin_i * global[0] + cos_i * global[1],
        f64::from(sj.yaw_rad) - f64::from(si.yaw_rad),
    ];
    let (margin, gradient, hessian) = predictor.margin(pose, footprint_m[0], footprint_m[1]);
    let d_global = [mj.dx - mi.dx, mj.dy - mi.dy];
    let yaw_rate_i = mi.dyaw;
    // First derivatives in i's frame (eqs. (3), (4)).
    let velocity = [
        cos_i * d_global[0] - global[0] * sin_i * yaw_rate_i
            + sin_i * d_global[1]
            + global[1] * cos_i * yaw_rate_i,
        cos_i * d_global[1]
            - global[1] * sin_i * yaw_rate_i
            - sin_i * d_global[0]
            - global[0] * cos_i * yaw_rate_i,
        mj.dyaw - mi.dyaw,
    ];
    // Second derivatives (eqs. (5), (6)), each as [constant, ∂/∂a_i, ∂/∂ω_i, ∂/∂a_j, ∂/∂ω_j].
    let joint = |of_i: [f64; 3], of_j: [f64; 3]| -> [f64; 5] {
        [of_j[0] - of_i[0], -of_i[1], -of_i[2], of_j[1], of_j[2]]
    };
    let dd_global = [joint(mi.ddx, mj.ddx), joint(mi.ddy, mj.ddy)];
    let dd_yaw_i: [f64; 5] = [mi.ddyaw[0], mi.ddyaw[1], mi.ddyaw[2], 0.0, 0.0];
    let acceleration: [[f64; 5]; 3] = [
        std::array::from_fn(|c| {
            let constant = c == 0;
            cos_i * dd_global[0][c] - global[0] * sin_i * dd_yaw_i[c]
                + sin_i * dd_global[1][c]
                + global[1] * cos_i * dd_yaw_i[c]
                + if constant {
                    -2.0 * d_global[0] * sin_i * yaw_rate_i - global[0] * cos_i * yaw_rate_i.powi(2)
                        + 2.0 * d_global[1] * cos_i * yaw_rate_i
                        - global[1] * sin_i * yaw_rate_i.powi(2)
                } else {
                    0.0
                }
        }),
        std::array::from_fn(|c| {
            let constant = c == 0;
            cos_i * dd_global[1][c]
                - global[1] * sin_i * dd_yaw_i[c]
                - sin_i * dd_global[0][c]
                - global[0] * cos_i * dd_yaw_i[c]
                + if constant {
                    -2.0 * d_global[1] * sin_i * yaw_rate_i
                        - global[1] * cos_i * yaw_rate_i.powi(2)
                        - 2.0 * d_global[0] * cos_i * yaw_rate_i
                        + global[0] * sin_i * yaw_rate_i.powi(2)
                } else {
                    0.0
                }
        }),
        joint(mi.ddyaw, mj.ddyaw),
    ];
    let barrier = margin - predictor.error_bound_m;
    let rate: f64 = (0..3).map(|k| gradient[k] * velocity[k]).sum();
    let curvature: f64 = (0..3)
        .flat_map(|k| (0..3).map(move |l| (k, l)))
        .map(|(k, l)| velocity[k] * hessian[k][l] * velocity[l])
        .sum();
    let second: [f64; 5] = std::array::from_fn(|c| {
        (0..3).map(|k| gradient[k] * acceleration[k][c]).sum::<f64>() + if c == 0 { curvature } else { 0.0 }
    });
    let half_dt_sq = 0.5 * p.step_s * p.step_s;
    PredictedRow {
        barrier_m: barrier,
        coefficients: [
            [half_dt_sq * second[1], half_dt_sq * second[2]],
            [half_dt_sq * second[3], half_dt_sq * second[4]],
        ],
        constant: p.gain * barrier + rate * p.step_s + half_dt_sq * second[0],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A network of random weights (the derivatives' check needs no trained one).
    fn random_predictor() -> MarginPredictor {
        let mut state = 12345u64;
        let mut next = |n: usize| -> Vec<f32> {
            (0..n)
                .map(|_| {
                    state = state
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    ((state >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 0.6
                })
                .collect()
        };
        let layers = vec![
            ("model.0.weight".to_owned(), vec![64, 3], next(192)),
            ("model.0.bias".to_owned(), vec![64], next(64)),
            ("model.2.weight".to_owned(), vec![64, 64], next(4096)),
            ("model.2.bias".to_owned(), vec![64], next(64)),
            ("model.4.weight".to_owned(), vec![1, 64], next(64)),
            ("model.4.bias".to_owned(), vec![1], next(1)),
        ];
        MarginPredictor::new(&layers, 0.0128).unwrap()
    }

    #[test]
    fn the_closed_form_derivatives_are_the_finite_differences() {
        let net = random_predictor();
        let pose = [0.11, -0.07, 0.4];
        let (_, gradient, hessian) = net.margin(pose, 0.16, 0.08);
        let step = 1e-5;
        for p in 0..3 {
            let at = |d: f64| {
                let mut q = pose;
                q[p] += d;
                net.margin(q, 0.16, 0.08)
            };
            let (plus, minus) = (at(step), at(-step));
            let numeric = (plus.0 - minus.0) / (2.0 * step);
            assert!(
                (numeric - gradient[p]).abs() < 1e-6,
                "{p}: {numeric} vs {}",
                gradient[p]
            );
            for (q, exact) in hessian[p].iter().enumerate() {
                let numeric = (plus.1[q] - minus.1[q]) / (2.0 * step);
                assert!((numeric - exact).abs() < 1e-4, "{p},{q}: {numeric} vs {exact}");
            }
        }
    }

    #[test]
    fn far_cars_get_the_circles_margin_and_a_wrong_network_is_refused() {
        let net = random_predictor();
        let (margin, gradient, _) = net.margin([1.0, 0.0, 2.0], 0.16, 0.08);
        let radius = 0.16f64.hypot(0.08) / 2.0;
        assert!((margin - (1.0 - 2.0 * radius)).abs() < 1e-12);
        assert_eq!(gradient, [1.0, 0.0, 0.0]);
        let wrong = vec![("model.0.weight".to_owned(), vec![64, 4], vec![0.0; 256])];
        let error = MarginPredictor::new(&wrong, 0.01).unwrap_err();
        assert!(error.to_string().contains("shape [64, 4]"), "{error}");
    }

    /// The row's value is the Taylor prediction of h: moving the cars by the row's own inputs
    /// over Δt changes h as the row says (to second order).
    #[test]
    fn the_row_predicts_the_margin_of_the_moved_cars() {
        let net = random_predictor();
        let p = CbfParameters {
            gain: 1.0,
            step_s: 0.01,
            ..CbfParameters::sigmarl(0.01)
        };
        let cars = [
            CbfState {
                x_m: 0.0,
                y_m: 0.0,
                yaw_rad: 0.1,
                speed_mps: 0.6,
                steering_rad: 0.1,
            },
            CbfState {
                x_m: 0.15,
                y_m: 0.05,
                yaw_rad: 2.0,
                speed_mps: 0.4,
                steering_rad: -0.2,
            },
        ];
        let row = predicted_row(&p, &net, [0.16, 0.08], cars);
        // With zero inputs the row is h + ḣΔt + ½ḧ₀Δt², the prediction of h after Δt.
        let moved = cars.map(|s| {
            let m = Motion::of(&p, s);
            let dt = p.step_s;
            let (ddx, ddy, ddyaw) = (m.ddx[0], m.ddy[0], m.ddyaw[0]);
            CbfState {
                x_m: (f64::from(s.x_m) + m.dx * dt + 0.5 * ddx * dt * dt) as f32,
                y_m: (f64::from(s.y_m) + m.dy * dt + 0.5 * ddy * dt * dt) as f32,
                yaw_rad: (f64::from(s.yaw_rad) + m.dyaw * dt + 0.5 * ddyaw * dt * dt) as f32,
                ..s
            }
        });
        let after = predicted_row(&p, &net, [0.16, 0.08], moved).barrier_m;
        assert!((row.constant - after).abs() < 1e-5, "{} vs {after}", row.constant);
    }
}
