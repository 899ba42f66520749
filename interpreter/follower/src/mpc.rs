//! The CPM Lab's trajectory MPC (§3.3 of the interface notes) as a linear time-varying QP
//! solved with clarabel, over any [`Model`].
//!
//! This module owns one control decision: delay compensation, sampling and checking the
//! reference window, linearisation, the QP and the lab's objective check. It does not pick
//! commands or keep time; `follower.rs` does.
//!
//! # Numbers
//! Fixed by the lab (`MpcController`): control period 20 ms; delay compensation 3 steps
//! with the last applied inputs; Hp = 6 prediction steps of 50 ms, Hu = 3 moves with
//! move blocking `[1, 1, 2, 2, 3, 3]`; reference at `t_now + 60 ms + 50 ms + k·50 ms`,
//! positions only; cost `Σ wₖ²·|p − p_ref|²` with `w = [1, 1, 2, 1, 1, 3]` plus move
//! penalties (0.5 throttle, 0.01 servo, first move against the previous input); rejection
//! when the first point is not before the window, the last point ends before it, |aₓ| or
//! |a_y| > 20 m/s², |κ| > 50 /m at speed > 0.1 m/s, or the objective ≥ 1.5.
//!
//! Chosen here because the lab does not say (its solver is 20 projected-gradient steps on
//! the nonlinear model): the solver (an exact QP solve with clarabel instead of 20 gradient
//! steps); linearisation along the model's own prediction from the delay-compensated state
//! `x̄₀` under the feed-forward inputs `ūₖ` of the reference samples (`x̄ₖ₊₁ = step(x̄ₖ, ūₖ)`,
//! the model's Jacobians); rate limits as constraints (the lab
//! has none: first move against the previous input over one control period, later moves
//! over two MPC steps); move weights for the bicycle ([`BICYCLE_MOVE_WEIGHTS`]); the
//! objective check evaluates the cost on a nonlinear rollout of the solution; the history
//! records every applied input, stop inputs included (the lab skips it on rejections).
//!
//! Why the prediction and not the reference: linearised about the reference's own
//! feed-forward states (as cpmx did before), the QP's model starts each step from where the
//! reference is, not from where the car will be; the residuals `x̄ₖ₊₁ − step(x̄ₖ, ūₖ)` of the
//! grey-box model's approximate inverse (no p2 speed loss, no speed transient, the servo's
//! heading offset) then steer the optimum. Through the CPM Lab intersection's left turns the
//! grey-box twin turned right round (heading error π, CD 0.17–0.22 m against sim-mpc's
//! 0.008 m; `tests/twin_turns.rs`). The lab's MPC predicts with the nonlinear model from the
//! measured state; linearising along that prediction follows sim-mpc within 2 mm of CD.
//!
//! The QP is condensed: the six decision variables are the three moves (`NU` inputs each);
//! predicted positions are affine in them, and the KKT system has 30 rows for the bicycle
//! (6 variables, 24 bound and rate rows). A sparse formulation (moves and six states as
//! variables, dynamics as equalities) would have about 90; it was not measured. One solve
//! (bicycle, circle) takes ≈ 90 µs in the dev profile and ≈ 72 µs in release on a shared
//! 2-core machine, most of it in clarabel's 8 interior-point iterations.

use std::collections::VecDeque;

use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus};
use nalgebra::{SMatrix, SVector};
use thiserror::Error;

use crate::gradient::{self, WarmStart};
use crate::model::{Model, jacobians, position_jacobian};
use crate::trajectory::{Trajectory, TrajectorySample};

/// Prediction steps Hp (lab).
pub const PREDICTION_STEPS: usize = 6;
/// Control moves Hu (lab).
pub const CONTROL_MOVES: usize = 3;

/// Weight of the pull of each move towards the feed-forward input, as a fraction of that
/// input's move weight (chosen here; the lab's MPC has no such term).
pub const FEEDFORWARD_PULL: f64 = 0.01;
/// Move held at each prediction step (lab's blocking `[1, 1, 2, 2, 3, 3]`, 0-based).
pub(crate) const MOVE_OF_STEP: [usize; PREDICTION_STEPS] = [0, 0, 1, 1, 2, 2];

/// Move weights of the lab's grey-box MPC: throttle 0.5, steering servo 0.01.
pub const LAB_MOVE_WEIGHTS: [f64; 2] = [0.5, 0.01];

/// Move weights chosen for the bicycle (speed command [m/s], steering [rad]): the lab's
/// weights carried through the input scales near 0.5 m/s (≈ 6.9 m/s per unit throttle,
/// ≈ 0.54 rad per unit servo), rounded: 0.5/6.9² ≈ 0.01, 0.01/0.54² ≈ 0.03.
pub const BICYCLE_MOVE_WEIGHTS: [f64; 2] = [0.01, 0.03];

/// Tuning and timing of the MPC.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MpcConfig<const NU: usize> {
    /// Period of the vehicle loop [s] (lab: 0.02).
    pub control_period_s: f64,
    /// Control periods of actuation delay compensated by prediction (lab: 3).
    pub delay_steps: usize,
    /// Prediction step [s] (lab: 0.05).
    pub mpc_step_s: f64,
    /// Position weights wₖ, squared in the cost (lab: `[1, 1, 2, 1, 1, 3]`).
    pub position_weights: [f64; PREDICTION_STEPS],
    /// Weight of squared input moves, per input.
    pub move_weights: [f64; NU],
    /// Solutions with an objective at or above this stop the car (lab: 1.5).
    pub max_objective: f64,
    /// Largest |aₓ|, |a_y| of the reference [m/s²] (lab: 20).
    pub max_reference_accel_mps2: f64,
    /// Largest |κ| of the reference [1/m] while faster than the next field (lab: 50).
    pub max_curvature_per_m: f64,
    /// Speed above which curvature is checked [m/s] (lab: 0.1).
    pub curvature_check_speed_mps: f64,
    /// How the moves are found (lab: [`Solver::Gradient`]).
    pub solver: Solver,
    /// Gradient steps per period with [`Solver::Gradient`] (lab: 20).
    pub gradient_iterations: usize,
    /// The battery voltage the filter starts from [V] (lab: 8).
    pub initial_battery_voltage_v: f64,
    /// Gain of the battery voltage's low-pass filter per period (lab: 0.1).
    pub battery_filter_gain: f64,
}

/// The optimiser of the MPC.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Solver {
    /// The lab's: 20 warm-started gradient steps with momentum on the nonlinear model
    /// (`gradient.rs`).
    #[default]
    Gradient,
    /// The exact optimum of the linearised problem (clarabel), with rate limits as constraints.
    Qp,
}

impl<const NU: usize> MpcConfig<NU> {
    /// The lab's numbers with the given move weights.
    pub fn lab(move_weights: [f64; NU]) -> Self {
        Self {
            control_period_s: 0.02,
            delay_steps: 3,
            mpc_step_s: 0.05,
            position_weights: [1.0, 1.0, 2.0, 1.0, 1.0, 3.0],
            move_weights,
            max_objective: 1.5,
            max_reference_accel_mps2: 20.0,
            max_curvature_per_m: 50.0,
            curvature_check_speed_mps: 0.1,
            solver: Solver::Gradient,
            gradient_iterations: gradient::GRADIENT_ITERATIONS,
            initial_battery_voltage_v: 8.0,
            battery_filter_gain: 0.1,
        }
    }
}

/// Why the MPC refuses to drive (the lab then sends its stop signals).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum Rejection {
    /// Fewer than two points.
    #[error("trajectory has fewer than two points")]
    TooFewPoints,
    /// The first point is not before the prediction window.
    #[error("the first trajectory point ({first_s} s) is in the future (window starts {window_start_s} s)")]
    FirstPointInFuture {
        /// Time of the first point [s].
        first_s: f64,
        /// Start of the prediction window [s].
        window_start_s: f64,
    },
    /// The last point ends before the prediction window does.
    #[error("insufficient lead time: increase it by {missing_s} s")]
    InsufficientLeadTime {
        /// How much later the last point must be [s].
        missing_s: f64,
    },
    /// The reference accelerates harder than the limit.
    #[error("large acceleration in reference trajectory: {accel_mps2} m/s²")]
    LargeAcceleration {
        /// The offending component [m/s²].
        accel_mps2: f64,
    },
    /// The reference curves more sharply than the limit.
    #[error("large curvature in reference trajectory: {curvature_per_m} /m")]
    LargeCurvature {
        /// The offending curvature [1/m].
        curvature_per_m: f64,
    },
    /// The optimal cost is too large (reference too far from the vehicle).
    #[error("large MPC objective {objective}")]
    LargeObjective {
        /// The objective of the solution.
        objective: f64,
    },
    /// The state estimate holds NaN or infinity.
    #[error("state estimate is not finite")]
    NonFiniteState,
    /// clarabel did not solve the QP.
    #[error("QP solver failed: {status}")]
    SolverFailed {
        /// clarabel's status or setup error.
        status: String,
    },
}

/// One accepted control decision.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution<const NU: usize> {
    /// The input to apply now.
    pub input: [f64; NU],
    /// The cost of the solution on the nonlinear model.
    pub objective: f64,
    /// Predicted positions at the six reference times [m].
    pub predicted_m: [[f64; 2]; PREDICTION_STEPS],
    /// Reference positions at those times [m].
    pub reference_m: [[f64; 2]; PREDICTION_STEPS],
}

/// The MPC with its input history (for delay compensation and the first move's penalty).
#[derive(Debug, Clone)]
pub struct Mpc<M, const NX: usize, const NU: usize> {
    model: M,
    config: MpcConfig<NU>,
    /// The last `delay_steps` applied inputs, oldest first.
    history: VecDeque<[f64; NU]>,
    previous_input: [f64; NU],
    qp: QpCache,
    /// The gradient solver's iterate and momentum.
    warm: WarmStart<NU>,
    /// The newest battery voltage measurement, if the vehicle measures one [V].
    battery_measured_v: Option<f64>,
    /// The low-pass filtered battery voltage the model predicts with [V].
    battery_filtered_v: f64,
}

/// The clarabel solver of the previous step. Every step's QP has the same sparsity, so
/// updating P, q and b skips the solver's setup (allocation, ordering, symbolic
/// factorisation). Equilibration and presolve are off, so a kept solver computes exactly
/// what a new one would (clarabel has no warm start). A clone starts without one.
#[derive(Default)]
struct QpCache(Option<DefaultSolver<f64>>);

impl Clone for QpCache {
    fn clone(&self) -> Self {
        Self(None)
    }
}

impl std::fmt::Debug for QpCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.0.is_some() {
            "QpCache(solver)"
        } else {
            "QpCache(empty)"
        })
    }
}

impl<M: Model<NX, NU>, const NX: usize, const NU: usize> Mpc<M, NX, NU> {
    /// An MPC whose input history is all zeros (as the lab starts).
    pub fn new(model: M, config: MpcConfig<NU>) -> Self {
        Self {
            model,
            history: std::iter::repeat_n([0.0; NU], config.delay_steps).collect(),
            config,
            previous_input: [0.0; NU],
            qp: QpCache::default(),
            warm: WarmStart::reset(),
            battery_measured_v: None,
            battery_filtered_v: config.initial_battery_voltage_v,
        }
    }

    /// The vehicle's battery voltage measurement for the next solve [V] (the lab filters it,
    /// `V ← V + 0.1·(V_meas − V)` from 8 V, and predicts with the filtered value).
    pub fn measure_battery_voltage(&mut self, voltage_v: f64) {
        if voltage_v.is_finite() {
            self.battery_measured_v = Some(voltage_v);
        }
    }

    /// The filtered battery voltage the model predicts with [V].
    pub fn battery_voltage_v(&self) -> f64 {
        self.battery_filtered_v
    }

    /// The model.
    pub fn model(&self) -> &M {
        &self.model
    }

    /// The configuration.
    pub fn config(&self) -> &MpcConfig<NU> {
        &self.config
    }

    /// Records the input the vehicle was just given (call once per control period).
    pub fn record_applied(&mut self, input: [f64; NU]) {
        if self.config.delay_steps > 0 {
            self.history.pop_front();
            self.history.push_back(input);
        }
        self.previous_input = input;
    }

    /// The state after the actuation delay, predicted with the inputs already sent.
    pub fn compensate_delay(&self, state: &[f64; NX]) -> [f64; NX] {
        self.history.iter().fold(*state, |x, u| {
            self.model.step(&x, u, self.config.control_period_s)
        })
    }

    /// The input for `state` (measured at `t_now_s`) following `trajectory`.
    pub fn solve(
        &mut self,
        t_now_s: f64,
        state: &[f64; NX],
        trajectory: &Trajectory,
    ) -> Result<Solution<NU>, Rejection> {
        let result = self.try_solve(t_now_s, state, trajectory);
        if result.is_err() {
            // The lab resets its optimizer on every rejection.
            self.warm = WarmStart::reset();
        }
        result
    }

    fn try_solve(
        &mut self,
        t_now_s: f64,
        state: &[f64; NX],
        trajectory: &Trajectory,
    ) -> Result<Solution<NU>, Rejection> {
        if let Some(measured) = self.battery_measured_v {
            self.battery_filtered_v += self.config.battery_filter_gain * (measured - self.battery_filtered_v);
            self.model.set_battery_voltage_v(self.battery_filtered_v);
        }
        if !state.iter().all(|v| v.is_finite()) {
            return Err(Rejection::NonFiniteState);
        }
        let x0 = self.compensate_delay(state);
        let samples = self.reference_window(t_now_s, trajectory)?;
        let solution = match self.config.solver {
            Solver::Qp => {
                let moves = self.solve_qp(&x0, &samples)?;
                self.evaluate(&x0, &samples, &moves)
            }
            Solver::Gradient => {
                let reference_m = samples.map(|s| s.position_m);
                let r = gradient::solve(
                    &self.model,
                    &self.config,
                    &x0,
                    &reference_m,
                    &self.previous_input,
                    &mut self.warm,
                );
                Solution {
                    input: r.moves[0],
                    objective: r.objective,
                    predicted_m: r.predicted_m,
                    reference_m,
                }
            }
        };
        let acceptable = solution.objective < self.config.max_objective;
        if !acceptable {
            return Err(Rejection::LargeObjective {
                objective: solution.objective,
            });
        }
        Ok(solution)
    }

    /// The six reference samples, with the lab's checks.
    fn reference_window(
        &self,
        t_now_s: f64,
        trajectory: &Trajectory,
    ) -> Result<[TrajectorySample; PREDICTION_STEPS], Rejection> {
        let c = &self.config;
        if trajectory.points().len() < 2 {
            return Err(Rejection::TooFewPoints);
        }
        let window_start_s = t_now_s + c.delay_steps as f64 * c.control_period_s + c.mpc_step_s;
        let window_end_s = window_start_s + (PREDICTION_STEPS - 1) as f64 * c.mpc_step_s;
        let starts_before = trajectory.start_s() < window_start_s;
        if !starts_before {
            return Err(Rejection::FirstPointInFuture {
                first_s: trajectory.start_s(),
                window_start_s,
            });
        }
        if trajectory.end_s() < window_end_s {
            return Err(Rejection::InsufficientLeadTime {
                missing_s: window_end_s - trajectory.end_s(),
            });
        }

        let mut samples = [TrajectorySample::default(); PREDICTION_STEPS];
        for (k, slot) in samples.iter_mut().enumerate() {
            let t_s = window_start_s + k as f64 * c.mpc_step_s;
            let s = trajectory
                .sample(t_s)
                .map_err(|_| Rejection::InsufficientLeadTime { missing_s: 0.0 })?;
            for a in s.acceleration_mps2 {
                if a.abs() > c.max_reference_accel_mps2 {
                    return Err(Rejection::LargeAcceleration { accel_mps2: a });
                }
            }
            let curvature_per_m = s.curvature_per_m();
            if s.speed_mps() > c.curvature_check_speed_mps && curvature_per_m.abs() > c.max_curvature_per_m {
                return Err(Rejection::LargeCurvature { curvature_per_m });
            }
            *slot = s;
        }
        Ok(samples)
    }

    /// Builds and solves the condensed QP; returns the moves.
    fn solve_qp(
        &mut self,
        x0: &[f64; NX],
        samples: &[TrajectorySample; PREDICTION_STEPS],
    ) -> Result<[[f64; NU]; CONTROL_MOVES], Rejection> {
        let (hessian, gradient) = self.condense(x0, samples);
        let nz = CONTROL_MOVES * NU;

        // Objective ½zᵀPz + qᵀz with P = 2H, q = 2g (upper triangle, column-major).
        let mut colptr = Vec::with_capacity(nz + 1);
        let (mut rowval, mut nzval) = (Vec::new(), Vec::new());
        colptr.push(0);
        for j in 0..nz {
            for i in 0..=j {
                rowval.push(i);
                nzval.push(2.0 * hessian[i * nz + j]);
            }
            colptr.push(rowval.len());
        }
        let p = CscMatrix::new(nz, nz, colptr, rowval, nzval);
        let q: Vec<f64> = gradient.iter().map(|g| 2.0 * g).collect();

        let (a, b) = self.constraints();
        let failed = |status: String| Rejection::SolverFailed { status };
        let solver = match &mut self.qp.0 {
            Some(solver) => {
                solver.update_P(&p.nzval).map_err(|e| failed(e.to_string()))?;
                solver.update_q(&q).map_err(|e| failed(e.to_string()))?;
                solver.update_b(&b).map_err(|e| failed(e.to_string()))?;
                solver
            }
            empty => {
                let settings = DefaultSettings {
                    verbose: false,
                    equilibrate_enable: false,
                    presolve_enable: false,
                    ..DefaultSettings::default()
                };
                let cones = [NonnegativeConeT(b.len())];
                let solver = DefaultSolver::new(&p, &q, &a, &b, &cones, settings)
                    .map_err(|e| failed(e.to_string()))?;
                empty.insert(solver)
            }
        };
        solver.solve();
        if !matches!(
            solver.solution.status,
            SolverStatus::Solved | SolverStatus::AlmostSolved
        ) {
            return Err(failed(format!("{:?}", solver.solution.status)));
        }

        // Clip the tiny bound violations an interior-point solution may have.
        let limits = self.model.input_limits();
        let mut moves = [[0.0; NU]; CONTROL_MOVES];
        for (j, m) in moves.iter_mut().enumerate() {
            for (i, u) in m.iter_mut().enumerate() {
                *u = solver.solution.x[j * NU + i].clamp(limits.lower[i], limits.upper[i]);
            }
        }
        Ok(moves)
    }

    /// Hessian H (row-major, `nz × nz`) and gradient g of the cost `zᵀHz + 2gᵀz + const`.
    fn condense(
        &self,
        x0: &[f64; NX],
        samples: &[TrajectorySample; PREDICTION_STEPS],
    ) -> (Vec<f64>, Vec<f64>) {
        let c = &self.config;
        let nz = CONTROL_MOVES * NU;
        let mut hessian = vec![0.0; nz * nz];
        let mut gradient = vec![0.0; nz];

        // Linearisation points along the nonlinear model's prediction from x0: ūₖ = the
        // feed-forward input of sample k (within the bounds), x̄ₖ₊₁ = step(x̄ₖ, ūₖ). (Linearising
        // about the reference's own feed-forward states instead made the grey-box twin turn
        // the wrong way: see the module documentation.)
        let mut nominal = [(*x0, [0.0; NU]); PREDICTION_STEPS + 1];
        let limits = self.model.input_limits();
        for k in 0..PREDICTION_STEPS {
            let (_, mut ur) = self.model.feedforward(&samples[k], &nominal[k].0);
            for (i, u) in ur.iter_mut().enumerate() {
                *u = u.clamp(limits.lower[i], limits.upper[i]);
            }
            nominal[k].1 = ur;
            nominal[k + 1].0 = self.model.step(&nominal[k].0, &ur, c.mpc_step_s);
        }

        // Deviation dxₖ = eₖ + Σⱼ Eₖ[j]·zⱼ, propagated through the linearised steps.
        let mut e = SVector::<f64, NX>::zeros();
        let mut blocks = [SMatrix::<f64, NX, NU>::zeros(); CONTROL_MOVES];
        for k in 0..PREDICTION_STEPS {
            let (xk, uk) = &nominal[k];
            let (a, b) = jacobians(&self.model, xk, uk, c.mpc_step_s);
            let residual =
                SVector::from(self.model.step(xk, uk, c.mpc_step_s)) - SVector::from(nominal[k + 1].0);
            e = a * e - b * SVector::from(*uk) + residual;
            for (j, block) in blocks.iter_mut().enumerate() {
                *block = a * *block;
                if j == MOVE_OF_STEP[k] {
                    *block += b;
                }
            }

            // Position error at step k+1: offset + C·dx.
            let x_next = &nominal[k + 1].0;
            let cmat = position_jacobian(&self.model, x_next);
            let p = self.model.position_m(x_next);
            let pref = samples[k].position_m;
            let offset = SVector::<f64, 2>::new(p[0] - pref[0], p[1] - pref[1]) + cmat * e;
            let g: [SMatrix<f64, 2, NU>; CONTROL_MOVES] = blocks.map(|bl| cmat * bl);
            let w2 = c.position_weights[k] * c.position_weights[k];
            for (j, gj) in g.iter().enumerate() {
                let gt_offset = gj.transpose() * offset;
                for i in 0..NU {
                    gradient[j * NU + i] += w2 * gt_offset[i];
                }
                for (l, gl) in g.iter().enumerate() {
                    let block = gj.transpose() * gl;
                    for r in 0..NU {
                        for s in 0..NU {
                            hessian[(j * NU + r) * nz + l * NU + s] += w2 * block[(r, s)];
                        }
                    }
                }
            }
        }

        // Move penalties Σⱼ R·(zⱼ − zⱼ₋₁)² with z₀ = the previous input.
        for (i, (&r, &previous)) in c.move_weights.iter().zip(&self.previous_input).enumerate() {
            for j in 0..CONTROL_MOVES {
                let d = j * NU + i;
                hessian[d * nz + d] += r;
                if j > 0 {
                    let before = (j - 1) * NU + i;
                    hessian[before * nz + before] += r;
                    hessian[d * nz + before] -= r;
                    hessian[before * nz + d] -= r;
                }
            }
            gradient[i] -= r * previous;
        }

        // A small pull of every move towards the feed-forward input of its first step, so an
        // input that has no effect on the positions (the servo of a car at rest) rests at the
        // feed-forward value instead of wherever the solver leaves it.
        for (i, &r) in c.move_weights.iter().enumerate() {
            let rho = FEEDFORWARD_PULL * r;
            for j in 0..CONTROL_MOVES {
                let Some(k) = MOVE_OF_STEP.iter().position(|&m| m == j) else {
                    continue;
                };
                let d = j * NU + i;
                hessian[d * nz + d] += rho;
                gradient[d] -= rho * nominal[k].1[i];
            }
        }
        (hessian, gradient)
    }

    /// `A z + s = b, s ≥ 0`: input bounds, then rate limits (finite ones only).
    fn constraints(&self) -> (CscMatrix<f64>, Vec<f64>) {
        let c = &self.config;
        let limits = self.model.input_limits();
        let nz = CONTROL_MOVES * NU;
        // Columns as lists of (row, value); rows appended in order.
        let mut columns: Vec<Vec<(usize, f64)>> = vec![Vec::new(); nz];
        let mut b = Vec::new();
        for (v, column) in columns.iter_mut().enumerate() {
            let i = v % NU;
            column.push((b.len(), 1.0));
            b.push(limits.upper[i]);
            column.push((b.len(), -1.0));
            b.push(-limits.lower[i]);
        }
        for i in 0..NU {
            if !limits.max_rate_per_s[i].is_finite() {
                continue;
            }
            let previous = self.previous_input[i].clamp(limits.lower[i], limits.upper[i]);
            for j in 0..CONTROL_MOVES {
                let interval_s = if j == 0 {
                    c.control_period_s
                } else {
                    2.0 * c.mpc_step_s
                };
                let max_move = limits.max_rate_per_s[i] * interval_s;
                for sign in [1.0, -1.0] {
                    columns[j * NU + i].push((b.len(), sign));
                    if j == 0 {
                        b.push(max_move + sign * previous);
                    } else {
                        columns[(j - 1) * NU + i].push((b.len(), -sign));
                        b.push(max_move);
                    }
                }
            }
        }

        // Assemble CSC with sorted row indices.
        let mut colptr = vec![0];
        let (mut rowval, mut nzval) = (Vec::new(), Vec::new());
        for column in &mut columns {
            column.sort_by_key(|&(row, _)| row);
            for &(row, value) in column.iter() {
                rowval.push(row);
                nzval.push(value);
            }
            colptr.push(rowval.len());
        }
        (CscMatrix::new(b.len(), nz, colptr, rowval, nzval), b)
    }

    /// Rolls the nonlinear model out with the moves and evaluates the lab's cost.
    fn evaluate(
        &self,
        x0: &[f64; NX],
        samples: &[TrajectorySample; PREDICTION_STEPS],
        moves: &[[f64; NU]; CONTROL_MOVES],
    ) -> Solution<NU> {
        let c = &self.config;
        let mut x = *x0;
        let mut objective = 0.0;
        let mut predicted_m = [[0.0; 2]; PREDICTION_STEPS];
        for k in 0..PREDICTION_STEPS {
            x = self.model.step(&x, &moves[MOVE_OF_STEP[k]], c.mpc_step_s);
            let p = self.model.position_m(&x);
            let pref = samples[k].position_m;
            let w2 = c.position_weights[k] * c.position_weights[k];
            objective += w2 * ((p[0] - pref[0]).powi(2) + (p[1] - pref[1]).powi(2));
            predicted_m[k] = p;
        }
        let mut before = self.previous_input;
        for m in moves {
            for i in 0..NU {
                objective += c.move_weights[i] * (m[i] - before[i]).powi(2);
            }
            before = *m;
        }
        Solution {
            input: moves[0],
            objective,
            predicted_m,
            reference_m: samples.map(|s| s.position_m),
        }
    }
}
