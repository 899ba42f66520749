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

use crate::agents::AgentRows;
use crate::float16;
use crate::pseudo_distance::Boundary;
use crate::qp::{self, QpRow};

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
    /// Rows that keep the vehicles' circles apart (not in SigmaRL 1.4.0, which filters one
    /// vehicle; its later centralised QP has them).
    pub agents: Option<AgentRows>,
    /// Where the QP has no solution: the weight of each row's squared slack in a relaxed QP
    /// (SigmaRL's later QP: 1e9); `None`: the clamped nominal command goes through (1.4.0).
    pub slack_weight: Option<f64>,
    /// How the `float16` distances combine with SigmaRL's `float64` constants.
    pub arithmetic: Arithmetic,
}

/// How NumPy combines the pseudo-distance's `float16` values with Python's numbers, which
/// moves a row by up to 7e-4: SigmaRL's code is the same, NumPy's rules are not.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Arithmetic {
    /// NumPy 2 (NEP 50): Python numbers become `float16` first and every operation rounds to
    /// `float16`; the rows between cars take their circles' centres in `f64`. The filter as
    /// checked against SigmaRL 1.4.0's own under NumPy 2.
    #[default]
    Numpy2,
    /// NumPy 1.26, which SigmaRL 1.6.0 pins: a difference of two `float16` values is rounded,
    /// anything with a Python number is `float64` (the margin, the divisions, the curvature's
    /// `x₊ − 2x + x₋`); the circles' centres are `float32`. SigmaRL 1.6.0's CBF-informed reward
    /// as it computed it.
    Numpy1,
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
            agents: None,
            slack_weight: None,
            arithmetic: Arithmetic::Numpy2,
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
    /// h: the pseudo-distance less the circle's radius [m].
    pub margin_m: f64,
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
    /// Indices into `rows` of the rows the solution lies on (slack below 1e-7) or, relaxed,
    /// violates.
    pub active: Vec<usize>,
    /// Whether the QP had no solution and its rows were relaxed (`slack_weight`).
    pub relaxed: bool,
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
    let command = Command::of(p, state, nominal);
    let rows = rows(p, state, left, right);
    if !state.is_finite() || !rows.iter().all(CbfRow::is_finite) {
        return command.fallback(Fallback::NotFinite, rows);
    }
    let qp_rows: Vec<QpRow> = rows.iter().map(|r| QpRow::own(0, r)).collect();
    let (input, relaxed) = match qp::solve_relaxing(p, &[command.input64()], &qp_rows) {
        Ok((inputs, relaxed)) => (inputs[0], relaxed),
        Err(why) => return command.fallback(why, rows),
    };
    let active = active_rows(&rows, input);
    command.filtered(p, state, input, rows, active, relaxed)
}

/// Indices of the `rows` that `input` lies on (slack below 1e-7), or violates.
pub(crate) fn active_rows(rows: &[CbfRow], input: [f64; 2]) -> Vec<usize> {
    rows.iter()
        .enumerate()
        .filter(|(_, r)| r.coefficients[0] * input[0] + r.coefficients[1] * input[1] + r.constant < 1e-7)
        .map(|(i, _)| i)
        .collect()
}

impl CbfState {
    /// Whether every component is a number.
    pub fn is_finite(&self) -> bool {
        [
            self.x_m,
            self.y_m,
            self.yaw_rad,
            self.speed_mps,
            self.steering_rad,
        ]
        .iter()
        .all(|v| v.is_finite())
    }
}

impl CbfRow {
    /// Whether the row's coefficients and constant are numbers.
    pub fn is_finite(&self) -> bool {
        self.constant.is_finite() && self.coefficients.iter().all(|c| c.is_finite())
    }
}

/// A nominal command as the QP sees it: clamped to the command ranges, and as the
/// acceleration and steering rate that reach it over one step (`rl_action_to_u`, `f32`).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Command {
    clamped: [f32; 2],
    input: [f32; 2],
}

impl Command {
    pub(crate) fn of(p: &CbfParameters, state: CbfState, nominal: [f32; 2]) -> Command {
        Command::over(p, state, nominal, p.step_s)
    }

    /// [`Command::of`] reached over `step_s` instead of the rows' step.
    pub(crate) fn over(p: &CbfParameters, state: CbfState, nominal: [f32; 2], step_s: f64) -> Command {
        let speed = nominal[0].clamp(p.speed_range_mps[0], p.speed_range_mps[1]);
        let steering = nominal[1].clamp(-p.max_steering_rad, p.max_steering_rad);
        let dt32 = step_s as f32;
        let input = [
            ((speed - state.speed_mps) / dt32).clamp(
                -p.acceleration_limit_mps2 as f32,
                p.acceleration_limit_mps2 as f32,
            ),
            ((steering - state.steering_rad) / dt32).clamp(
                -p.steering_rate_limit_radps as f32,
                p.steering_rate_limit_radps as f32,
            ),
        ];
        Command {
            clamped: [speed, steering],
            input,
        }
    }

    pub(crate) fn input64(&self) -> [f64; 2] {
        self.input.map(f64::from)
    }

    /// The clamped nominal command goes through, for the reason `why`.
    pub(crate) fn fallback(&self, why: Fallback, rows: Vec<CbfRow>) -> CbfOutcome {
        CbfOutcome {
            action: self.clamped,
            nominal: self.clamped,
            nominal_input: self.input,
            input: None,
            rows,
            active: Vec::new(),
            relaxed: false,
            fallback: Some(why),
        }
    }

    /// The QP's `input` as a command (`u_to_rl_action`, `f64`): one step of the rates, the
    /// steering wrapped to [−π, π), both clamped; written back into SigmaRL's `f32` action.
    pub(crate) fn filtered(
        &self,
        p: &CbfParameters,
        state: CbfState,
        input: [f64; 2],
        rows: Vec<CbfRow>,
        active: Vec<usize>,
        relaxed: bool,
    ) -> CbfOutcome {
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
            nominal: self.clamped,
            nominal_input: self.input,
            input: Some(input),
            rows,
            active,
            relaxed,
            fallback: None,
        }
    }
}

/// The CBF rows for every circle and boundary (SigmaRL's order: by circle, left then right).
pub fn rows(p: &CbfParameters, s: CbfState, left: &Boundary, right: &Boundary) -> Vec<CbfRow> {
    let motion = Motion::of(p, s);
    // The circles' centres (`get_circle_centers`, f32).
    let (sin32, cos32) = (s.yaw_rad.sin(), s.yaw_rad.cos());
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
        let (velocity, acceleration) = motion.point(offset);
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
            let (margin, g, hessian, lambda_h) = match p.arithmetic {
                Arithmetic::Numpy2 => {
                    // The finite differences, each operation rounded to float16.
                    let gradient = [
                        float16(float16(d[1] - d[0]) / step16),
                        float16(float16(d[2] - d[0]) / step16),
                    ];
                    let second = |plus: f32, minus: f32| {
                        let numerator = float16(float16(plus - float16(2.0 * d[0])) + minus);
                        f64::from(float16(numerator / step_sq16))
                    };
                    let mixed = f64::from(float16(
                        float16(float16(float16(d[5] - d[6]) - d[7]) + d[8]) / step_4sq16,
                    ));
                    let margin = float16(d[0] - radius16);
                    (
                        f64::from(margin),
                        [f64::from(gradient[0]), f64::from(gradient[1])],
                        [[second(d[1], d[3]), mixed], [mixed, second(d[2], d[4])]],
                        f64::from(float16(gain16 * margin)),
                    )
                }
                Arithmetic::Numpy1 => {
                    let step = p.difference_step_m;
                    let d64 = d.map(f64::from);
                    let second = |plus: f64, minus: f64| (plus - 2.0 * d64[0] + minus) / (step * step);
                    let mixed =
                        f64::from(float16(float16(float16(d[5] - d[6]) - d[7]) + d[8])) / (4.0 * step * step);
                    let margin = d64[0] - p.circle_radius_m;
                    (
                        margin,
                        [
                            f64::from(float16(d[1] - d[0])) / step,
                            f64::from(float16(d[2] - d[0])) / step,
                        ],
                        [[second(d64[1], d64[3]), mixed], [mixed, second(d64[2], d64[4])]],
                        p.gain * margin,
                    )
                }
            };
            let margin_rate = g[0] * velocity[0] + g[1] * velocity[1];
            // ṗᵀ H ṗ as NumPy's (ṗᵀ H) ṗ in f64.
            let hv = [
                velocity[0] * hessian[0][0] + velocity[1] * hessian[1][0],
                velocity[0] * hessian[0][1] + velocity[1] * hessian[1][1],
            ];
            let curvature = hv[0] * velocity[0] + hv[1] * velocity[1];
            // ḧ = g·p̈ + ṗᵀHṗ, affine in u; the row λh + ḣΔt + ½ḧΔt².
            let ddh: [f64; 3] = std::array::from_fn(|j| {
                g[0] * acceleration[0][j] + g[1] * acceleration[1][j] + if j == 0 { curvature } else { 0.0 }
            });
            let half_dt_sq = 0.5 * p.step_s * p.step_s;
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

/// The bicycle's motion in a state as the filter predicts it: the first derivatives (SigmaRL's
/// `KinematicBicycleModel.ode`, `f32`) and the second, affine in u = [a, ω]
/// (`compute_dstate_2nd_time`, `f64`), each second derivative as `[constant, ∂/∂a, ∂/∂ω]`.
#[derive(Clone, Copy)]
pub(crate) struct Motion {
    pub(crate) dx: f64,
    pub(crate) dy: f64,
    pub(crate) dyaw: f64,
    pub(crate) sin_yaw: f64,
    pub(crate) cos_yaw: f64,
    pub(crate) ddx: [f64; 3],
    pub(crate) ddy: [f64; 3],
    pub(crate) ddyaw: [f64; 3],
}

impl Motion {
    pub(crate) fn of(p: &CbfParameters, s: CbfState) -> Motion {
        let ratio = (p.rear_axle_m / p.wheelbase_m) as f32;
        let beta = (ratio * s.steering_rad.tan()).atan();
        let dx = s.speed_mps * (s.yaw_rad + beta).cos();
        let dy = s.speed_mps * (s.yaw_rad + beta).sin();
        let dyaw = (s.speed_mps / p.wheelbase_m as f32) * s.steering_rad.tan() * beta.cos();
        let (dx, dy, dyaw) = (f64::from(dx), f64::from(dy), f64::from(dyaw));
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
        let per_wheelbase = v / p.wheelbase_m;
        let (sin_yaw, cos_yaw) = yaw.sin_cos();
        Motion {
            dx,
            dy,
            dyaw,
            sin_yaw,
            cos_yaw,
            ddx: [
                -(v * sin_course) * dyaw,
                cos_course,
                -(v * sin_course) * dbeta_domega,
            ],
            ddy: [
                (v * cos_course) * dyaw,
                sin_course,
                (v * cos_course) * dbeta_domega,
            ],
            ddyaw: [
                0.0,
                (1.0 / p.wheelbase_m) * cos_beta * tan_delta,
                per_wheelbase * cos_beta * sec_sq - per_wheelbase * sin_beta * tan_delta * dbeta_domega,
            ],
        }
    }

    /// The velocity of the point `offset` metres ahead of the centre on the vehicle's axis, and
    /// its acceleration (`compute_center_state_time_derivatives`), each coordinate as
    /// `[constant, ∂/∂a, ∂/∂ω]`.
    pub(crate) fn point(&self, offset: f64) -> ([f64; 2], [[f64; 3]; 2]) {
        let Motion {
            dx,
            dy,
            dyaw,
            sin_yaw,
            cos_yaw,
            ddx,
            ddy,
            ddyaw,
        } = *self;
        let velocity = [dx - offset * sin_yaw * dyaw, dy + offset * cos_yaw * dyaw];
        let acceleration: [[f64; 3]; 2] = [
            std::array::from_fn(|j| {
                ddx[j] - offset * (sin_yaw * ddyaw[j] + if j == 0 { cos_yaw * dyaw * dyaw } else { 0.0 })
            }),
            std::array::from_fn(|j| {
                ddy[j] + offset * (cos_yaw * ddyaw[j] - if j == 0 { sin_yaw * dyaw * dyaw } else { 0.0 })
            }),
        ];
        (velocity, acceleration)
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

    #[test]
    fn a_qp_without_solution_lets_the_nominal_action_through_unless_its_rows_may_be_relaxed() {
        let (left, right) = lane();
        // Heading straight at the left boundary at full speed, 10 cm from it: no braking is enough.
        let hopeless = CbfState {
            x_m: 0.013,
            y_m: 0.05,
            yaw_rad: std::f32::consts::FRAC_PI_2,
            speed_mps: 1.0,
            steering_rad: 0.0,
        };
        let p = CbfParameters::sigmarl(0.05);
        let out = filter(&p, hopeless, [1.0, 0.0], &left, &right);
        assert_eq!(
            (out.fallback, out.action, out.relaxed),
            (Some(Fallback::Infeasible), [1.0, 0.0], false),
            "{out:?}"
        );
        let relaxing = CbfParameters {
            slack_weight: Some(1e9),
            ..p
        };
        let out = filter(&relaxing, hopeless, [1.0, 0.0], &left, &right);
        assert_eq!((out.fallback, out.relaxed), (None, true), "{out:?}");
        assert_eq!(out.action[0], -0.5, "it brakes as hard as it may: {out:?}");
    }
}
