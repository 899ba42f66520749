//! SigmaRL's CBF safety filter of the ITSC 2025 paper (`sigmarl/cbf_qp.py`,
//! `CBFQP.solve_decentralized_cbf_qp` at tag 1.4.0): one vehicle against its lane's two
//! boundaries. The vehicle is a row of circles along its axis; for each circle and boundary a
//! truncated-Taylor CBF row `λ·h + ḣ·Δt + ½·ḧ·Δt² ≥ 0` (h the pseudo-distance less the circle's
//! radius, its gradient and Hessian by finite differences) keeps the predicted margin
//! positive; the QP changes the nominal acceleration and steering rate as little as its
//! weights allow. Arithmetic as SigmaRL's: the state and the bicycle's derivatives in `f32`,
//! the distances and their finite differences in `float16` (NumPy's rules), the rows in `f64`.
//! Where the QP has no solution, or a row is not finite, the nominal action goes through
//! (clamped), as in SigmaRL, and the outcome says why.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus};

use crate::float16;
use crate::pseudo_distance::Boundary;

/// The filter's parameters; [`CbfParameters::sigmarl`] gives SigmaRL's (tag 1.4.0).
#[derive(Debug, Clone, PartialEq)]
pub struct CbfParameters {
    /// Circles along the vehicle's axis (SigmaRL: 3).
    pub circles: usize,
    /// The vehicle's length [m]: the circles' centres split it evenly.
    pub length_m: f64,
    /// Distance from the centre to the rear axle [m] (SigmaRL's `l_r`).
    pub rear_axle_m: f64,
    /// Wheelbase [m].
    pub wheelbase_m: f64,
    /// The radius a boundary must keep from each circle's centre [m] (SigmaRL: 0.05).
    pub circle_radius_m: f64,
    /// The finite-difference step of the distance's derivatives [m] (SigmaRL: 0.02).
    pub difference_step_m: f64,
    /// The class-K gain λ of the truncated-Taylor CBF (SigmaRL: 0.1).
    pub gain: f64,
    /// The step Δt the CBF looks ahead and the action converts over [s] (SigmaRL: its `dt`).
    pub step_s: f64,
    /// Weights of the squared change of acceleration and steering rate (SigmaRL: 30, 1).
    pub weights: [f64; 2],
    /// Bounds of the acceleration [m/s²] and steering rate [rad/s] the QP may choose
    /// (SigmaRL: ±40 both).
    pub acceleration_limit_mps2: f64,
    /// See `acceleration_limit_mps2`.
    pub steering_rate_limit_radps: f64,
    /// The speed command's range [m/s] (SigmaRL: −0.5 to 1).
    pub speed_range_mps: [f32; 2],
    /// The steering command's bound [rad] (SigmaRL: π/4).
    pub max_steering_rad: f32,
}

impl CbfParameters {
    /// SigmaRL's filter at tag 1.4.0 (`constants.AGENTS` of that tag: 0.16 m, axles at ±0.08 m)
    /// for a step of `step_s`.
    pub fn sigmarl(step_s: f64) -> CbfParameters {
        CbfParameters {
            circles: 3,
            length_m: 0.16,
            rear_axle_m: 0.08,
            wheelbase_m: 0.16,
            circle_radius_m: 0.05,
            difference_step_m: 0.02,
            gain: 0.1,
            step_s,
            weights: [30.0, 1.0],
            acceleration_limit_mps2: 40.0,
            steering_rate_limit_radps: 40.0,
            speed_range_mps: [-0.5, 1.0],
            max_steering_rad: std::f64::consts::FRAC_PI_4 as f32,
        }
    }

    /// The circles' centres along the vehicle's axis, from the rear [m].
    pub fn circle_offsets_m(&self) -> Vec<f64> {
        let step = self.length_m / self.circles as f64;
        let start = -self.length_m / 2.0 + step / 2.0;
        (0..self.circles).map(|i| start + i as f64 * step).collect()
    }
}

/// The vehicle as the filter sees it (`f32`, as SigmaRL's observation holds it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CbfState {
    /// Centre x [m].
    pub x_m: f32,
    /// Centre y [m].
    pub y_m: f32,
    /// Heading [rad].
    pub yaw_rad: f32,
    /// Speed [m/s] (SigmaRL hands the filter the velocity's norm, never negative).
    pub speed_mps: f32,
    /// Steering angle [rad].
    pub steering_rad: f32,
}

/// Which boundary a row keeps a circle from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// The left boundary.
    Left,
    /// The right boundary.
    Right,
}

/// One CBF row: `coefficients · [a, ω] + constant ≥ 0`, with the margin it came from.
#[derive(Debug, Clone, PartialEq)]
pub struct CbfRow {
    /// The circle (0 at the rear).
    pub circle: usize,
    /// The boundary.
    pub side: Side,
    /// h: the pseudo-distance less the circle's radius (`float16`) [m].
    pub margin_m: f32,
    /// ḣ [m/s].
    pub margin_rate_mps: f64,
    /// Coefficients of acceleration and steering rate.
    pub coefficients: [f64; 2],
    /// The constant.
    pub constant: f64,
}

/// Why the nominal action went through unfiltered.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fallback {
    /// No action satisfies every row within the bounds.
    Infeasible,
    /// The state, or a row, is not finite (e.g. a circle's neighbourhood past a boundary's
    /// end).
    NotFinite,
    /// The solver stopped without a solution it vouches for.
    Unsolved,
}

/// What the filter did.
#[derive(Debug, Clone, PartialEq)]
pub struct CbfOutcome {
    /// The action to apply: `[speed m/s, steering rad]`.
    pub action: [f32; 2],
    /// The nominal action after the clamp to the command ranges.
    pub nominal: [f32; 2],
    /// The nominal acceleration and steering rate.
    pub nominal_input: [f32; 2],
    /// The QP's acceleration and steering rate, when it was solved.
    pub input: Option<[f64; 2]>,
    /// The rows (by circle, left before right).
    pub rows: Vec<CbfRow>,
    /// Indices into `rows` of the rows the solution lies on (slack below 1e-7).
    pub active: Vec<usize>,
    /// Why the nominal action went through, if it did.
    pub fallback: Option<Fallback>,
}

impl CbfOutcome {
    /// Whether the filter changed the action.
    pub fn intervened(&self) -> bool {
        self.action != self.nominal
    }
}

/// Filters `nominal` (`[speed m/s, steering rad]`) for a vehicle in `state` between `left`
/// and `right`.
pub fn filter(
    parameters: &CbfParameters,
    state: CbfState,
    nominal: [f32; 2],
    left: &Boundary,
    right: &Boundary,
) -> CbfOutcome {
    let p = parameters;
    // `rl_action_to_u` (f32): clamp, then the rates over one step, clamped.
    let speed = nominal[0].clamp(p.speed_range_mps[0], p.speed_range_mps[1]);
    let steering = nominal[1].clamp(-p.max_steering_rad, p.max_steering_rad);
    let dt32 = p.step_s as f32;
    let nominal_input = [
        ((speed - state.speed_mps) / dt32).clamp(
            -p.acceleration_limit_mps2 as f32,
            p.acceleration_limit_mps2 as f32,
        ),
        ((steering - state.steering_rad) / dt32).clamp(
            -p.steering_rate_limit_radps as f32,
            p.steering_rate_limit_radps as f32,
        ),
    ];
    let rows = rows(p, state, left, right);
    let clamped = [speed, steering];
    let fallback = |why: Fallback, rows: Vec<CbfRow>| CbfOutcome {
        action: clamped,
        nominal: clamped,
        nominal_input,
        input: None,
        rows,
        active: Vec::new(),
        fallback: Some(why),
    };
    let state_finite = [
        state.x_m,
        state.y_m,
        state.yaw_rad,
        state.speed_mps,
        state.steering_rad,
    ]
    .iter()
    .all(|v| v.is_finite());
    if !state_finite
        || rows
            .iter()
            .any(|r| !(r.constant.is_finite() && r.coefficients.iter().all(|c| c.is_finite())))
    {
        return fallback(Fallback::NotFinite, rows);
    }
    let input = match solve(
        p,
        [f64::from(nominal_input[0]), f64::from(nominal_input[1])],
        &rows,
    ) {
        Ok(u) => u,
        Err(why) => return fallback(why, rows),
    };
    let active = rows
        .iter()
        .enumerate()
        .filter(|(_, r)| r.coefficients[0] * input[0] + r.coefficients[1] * input[1] + r.constant < 1e-7)
        .map(|(i, _)| i)
        .collect();
    // `u_to_rl_action` (f64): one step of the rates, the steering wrapped to [−π, π), both
    // clamped; written back into SigmaRL's f32 action.
    let pi = std::f64::consts::PI;
    let v = f64::from(state.speed_mps) + input[0] * p.step_s;
    let delta = f64::from(state.steering_rad) + input[1] * p.step_s;
    let delta = (delta + pi).rem_euclid(2.0 * pi) - pi;
    let action = [
        v.clamp(f64::from(p.speed_range_mps[0]), f64::from(p.speed_range_mps[1])) as f32,
        delta.clamp(-f64::from(p.max_steering_rad), f64::from(p.max_steering_rad)) as f32,
    ];
    CbfOutcome {
        action,
        nominal: clamped,
        nominal_input,
        input: Some(input),
        rows,
        active,
        fallback: None,
    }
}

/// The CBF rows for every circle and boundary (SigmaRL's order: by circle, left then right).
pub fn rows(p: &CbfParameters, s: CbfState, left: &Boundary, right: &Boundary) -> Vec<CbfRow> {
    // The bicycle's first derivatives (`KinematicBicycleModel.ode`, f32).
    let ratio = (p.rear_axle_m / p.wheelbase_m) as f32;
    let beta = (ratio * s.steering_rad.tan()).atan();
    let dx = s.speed_mps * (s.yaw_rad + beta).cos();
    let dy = s.speed_mps * (s.yaw_rad + beta).sin();
    let dyaw = (s.speed_mps / p.wheelbase_m as f32) * s.steering_rad.tan() * beta.cos();
    let (dx, dy, dyaw) = (f64::from(dx), f64::from(dy), f64::from(dyaw));
    // The second derivatives (`compute_dstate_2nd_time`, f64), affine in u = [a, ω]:
    // each as [constant, ∂/∂a, ∂/∂ω].
    let (yaw, v, delta) = (
        f64::from(s.yaw_rad),
        f64::from(s.speed_mps),
        f64::from(s.steering_rad),
    );
    let k = p.rear_axle_m / p.wheelbase_m;
    let tan_delta = delta.tan();
    let beta64 = (k * tan_delta).atan();
    let sec_sq = 1.0 / delta.cos().powi(2);
    let tan_beta = k * tan_delta;
    let cos_beta = 1.0 / (1.0 + tan_beta.powi(2)).sqrt();
    let sin_beta = tan_beta * cos_beta;
    let dbeta_domega = (k * sec_sq) / (1.0 + (k * tan_delta).powi(2));
    let (sin_course, cos_course) = (yaw + beta64).sin_cos();
    let ddx = [
        -(v * sin_course) * dyaw,
        cos_course,
        -(v * sin_course) * dbeta_domega,
    ];
    let ddy = [
        (v * cos_course) * dyaw,
        sin_course,
        (v * cos_course) * dbeta_domega,
    ];
    let per_wheelbase = v / p.wheelbase_m;
    let ddyaw = [
        0.0,
        (1.0 / p.wheelbase_m) * cos_beta * tan_delta,
        per_wheelbase * cos_beta * sec_sq - per_wheelbase * sin_beta * tan_delta * dbeta_domega,
    ];
    // The circles' centres (`get_circle_centers`, f32).
    let (sin32, cos32) = (s.yaw_rad.sin(), s.yaw_rad.cos());
    let (sin_yaw, cos_yaw) = yaw.sin_cos();
    // NumPy's float16 arithmetic: Python numbers become float16 first (`constant`), every
    // result is rounded to float16 (`float16`).
    let constant = |x: f64| f32::from(half::f16::from_f64(x));
    let step16 = constant(p.difference_step_m);
    let step32 = p.difference_step_m as f32;
    let radius16 = constant(p.circle_radius_m);
    let gain16 = constant(p.gain);
    let step_sq16 = constant(p.difference_step_m * p.difference_step_m);
    let step_4sq16 = constant(4.0 * p.difference_step_m * p.difference_step_m);
    let mut rows = Vec::with_capacity(2 * p.circles);
    for (circle, offset) in p.circle_offsets_m().into_iter().enumerate() {
        let offset32 = offset as f32;
        let centre = [cos32 * offset32 + s.x_m, sin32 * offset32 + s.y_m];
        // The centre's velocity and acceleration (`compute_center_state_time_derivatives`).
        let velocity = [dx - offset * sin_yaw * dyaw, dy + offset * cos_yaw * dyaw];
        let acceleration: [[f64; 3]; 2] = [
            std::array::from_fn(|j| {
                ddx[j] - offset * (sin_yaw * ddyaw[j] + if j == 0 { cos_yaw * dyaw * dyaw } else { 0.0 })
            }),
            std::array::from_fn(|j| {
                ddy[j] + offset * (cos_yaw * ddyaw[j] - if j == 0 { sin_yaw * dyaw * dyaw } else { 0.0 })
            }),
        ];
        let offsets = [
            [0.0, 0.0],
            [step32, 0.0],
            [0.0, step32],
            [-step32, 0.0],
            [0.0, -step32],
            [step32, step32],
            [step32, -step32],
            [-step32, step32],
            [-step32, -step32],
        ];
        for (side, boundary) in [(Side::Left, left), (Side::Right, right)] {
            let d = offsets.map(|o| boundary.pseudo_distance([centre[0] + o[0], centre[1] + o[1]]));
            // The finite differences, each operation rounded to float16.
            let gradient = [
                float16(float16(d[1] - d[0]) / step16),
                float16(float16(d[2] - d[0]) / step16),
            ];
            let second = |plus: f32, minus: f32| {
                let numerator = float16(float16(plus - float16(2.0 * d[0])) + minus);
                float16(numerator / step_sq16)
            };
            let mixed = float16(float16(float16(float16(d[5] - d[6]) - d[7]) + d[8]) / step_4sq16);
            let hessian = [[second(d[1], d[3]), mixed], [mixed, second(d[2], d[4])]];
            let margin = float16(d[0] - radius16);
            let g = [f64::from(gradient[0]), f64::from(gradient[1])];
            let margin_rate = g[0] * velocity[0] + g[1] * velocity[1];
            // ṗᵀ H ṗ as NumPy's (ṗᵀ H) ṗ in f64.
            let hv = [
                velocity[0] * f64::from(hessian[0][0]) + velocity[1] * f64::from(hessian[1][0]),
                velocity[0] * f64::from(hessian[0][1]) + velocity[1] * f64::from(hessian[1][1]),
            ];
            let curvature = hv[0] * velocity[0] + hv[1] * velocity[1];
            // ḧ = g·p̈ + ṗᵀHṗ, affine in u; the row λh + ḣΔt + ½ḧΔt².
            let ddh: [f64; 3] = std::array::from_fn(|j| {
                g[0] * acceleration[0][j] + g[1] * acceleration[1][j] + if j == 0 { curvature } else { 0.0 }
            });
            let half_dt_sq = 0.5 * p.step_s * p.step_s;
            let lambda_h = f64::from(float16(gain16 * margin));
            rows.push(CbfRow {
                circle,
                side,
                margin_m: margin,
                margin_rate_mps: margin_rate,
                coefficients: [half_dt_sq * ddh[1], half_dt_sq * ddh[2]],
                constant: lambda_h + margin_rate * p.step_s + half_dt_sq * ddh[0],
            });
        }
    }
    rows
}

/// min (u − u₀)ᵀ R (u − u₀) over the rows and the bounds, with clarabel.
fn solve(p: &CbfParameters, nominal: [f64; 2], rows: &[CbfRow]) -> Result<[f64; 2], Fallback> {
    let [wa, ww] = p.weights;
    // ½ uᵀ P u + qᵀ u with P = 2R.
    let pm = CscMatrix::new(2, 2, vec![0, 1, 2], vec![0, 1], vec![2.0 * wa, 2.0 * ww]);
    let q = vec![-2.0 * wa * nominal[0], -2.0 * ww * nominal[1]];
    // A u + s = b, s ≥ 0: the rows as −c·u ≤ constant, then the four bounds.
    let n = rows.len() + 4;
    let mut column_a = Vec::with_capacity(n);
    let mut column_w = Vec::with_capacity(n);
    let mut b = Vec::with_capacity(n);
    for r in rows {
        column_a.push(-r.coefficients[0]);
        column_w.push(-r.coefficients[1]);
        b.push(r.constant);
    }
    for (ca, cw, limit) in [
        (1.0, 0.0, p.acceleration_limit_mps2),
        (-1.0, 0.0, p.acceleration_limit_mps2),
        (0.0, 1.0, p.steering_rate_limit_radps),
        (0.0, -1.0, p.steering_rate_limit_radps),
    ] {
        column_a.push(ca);
        column_w.push(cw);
        b.push(limit);
    }
    let a = CscMatrix::new(
        n,
        2,
        vec![0, n, 2 * n],
        (0..n).chain(0..n).collect(),
        column_a.into_iter().chain(column_w).collect(),
    );
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .tol_gap_abs(1e-10)
        .tol_gap_rel(1e-10)
        .tol_feas(1e-10)
        .tol_infeas_abs(1e-10)
        .tol_infeas_rel(1e-10)
        .tol_ktratio(1e-8)
        .max_iter(500)
        .build()
        .map_err(|_| Fallback::Unsolved)?;
    let cones = [NonnegativeConeT(n)];
    let mut solver = DefaultSolver::new(&pm, &q, &a, &b, &cones, settings).map_err(|_| Fallback::Unsolved)?;
    solver.solve();
    match solver.solution.status {
        SolverStatus::Solved => Ok([solver.solution.x[0], solver.solution.x[1]]),
        SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => Err(Fallback::Infeasible),
        _ => Err(Fallback::Unsolved),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lane() -> (Boundary, Boundary) {
        let line = |y: f32| Boundary::new((0..81).map(|i| [-2.0 + 0.05 * i as f32, y]).collect()).unwrap();
        (line(0.15), line(-0.15))
    }

    fn state(y_m: f32, yaw_rad: f32) -> CbfState {
        CbfState {
            x_m: 0.0,
            y_m,
            yaw_rad,
            speed_mps: 0.8,
            steering_rad: 0.0,
        }
    }

    #[test]
    fn a_centred_car_keeps_its_action_and_one_heading_out_is_turned_back() {
        let (left, right) = lane();
        let p = CbfParameters::sigmarl(0.05);
        let calm = filter(&p, state(0.0, 0.0), [0.8, 0.0], &left, &right);
        assert_eq!(
            (calm.action, calm.fallback, calm.intervened()),
            ([0.8, 0.0], None, false)
        );
        // Full steering towards the left boundary, 7 cm from it: the filter steers right.
        let pushed = filter(&p, state(0.08, 0.2), [1.0, 0.785], &left, &right);
        assert!(pushed.intervened() && pushed.action[1] < 0.0, "{pushed:?}");
        assert!(!pushed.active.is_empty());
    }

    #[test]
    fn a_state_that_is_not_a_number_lets_the_clamped_nominal_action_through() {
        let (left, right) = lane();
        let p = CbfParameters::sigmarl(0.05);
        let out = filter(&p, state(f32::NAN, 0.0), [2.0, -3.0], &left, &right);
        assert_eq!(out.fallback, Some(Fallback::NotFinite));
        assert_eq!(out.action, [1.0, -std::f32::consts::FRAC_PI_4]);
    }
}
