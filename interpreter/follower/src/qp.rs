//! The exact QP the MPC can solve instead of the lab's gradient steps ([`Solver::Qp`],
//! `follower: {solver: qp}`): the linearised problem's optimum found by clarabel.
//!
//! This module owns building and solving that QP and evaluating its moves; the reference
//! window, the rejections and the input history are `mpc.rs`'s.
//!
//! Chosen here because the lab's MPC has no such solver (its own is `gradient.rs`):
//! linearisation along the model's own prediction from the delay-compensated state `x̄₀` under
//! the feed-forward inputs `ūₖ` of the reference samples (`x̄ₖ₊₁ = step(x̄ₖ, ūₖ)`, the model's
//! Jacobians); rate limits as constraints (the lab has none: first move against the previous
//! input over one control period, later moves over two MPC steps); a small pull of every move
//! towards its feed-forward input ([`FEEDFORWARD_PULL`]); the objective the lab checks
//! evaluated on a nonlinear rollout of the solution.
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

use std::marker::PhantomData;

use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettings, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus};
use nalgebra::{SMatrix, SVector};

use crate::model::{Model, jacobians, position_jacobian};
#[cfg(doc)]
use crate::mpc::Solver;
use crate::mpc::{CONTROL_MOVES, MOVE_OF_STEP, MpcConfig, PREDICTION_STEPS, Rejection, Solution};
use crate::trajectory::TrajectorySample;

/// Weight of the pull of each move towards the feed-forward input, as a fraction of that
/// input's move weight (chosen here; the lab's MPC has no such term).
pub const FEEDFORWARD_PULL: f64 = 0.01;

/// The clarabel solver of the previous step. Every step's QP has the same sparsity, so
/// updating P, q and b skips the solver's setup (allocation, ordering, symbolic
/// factorisation). Equilibration and presolve are off, so a kept solver computes exactly
/// what a new one would (clarabel has no warm start). A clone starts without one.
#[derive(Default)]
pub(crate) struct QpCache(Option<DefaultSolver<f64>>);

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

/// The QP's optimal moves from the delay-compensated state `x0` for the reference `samples`,
/// evaluated as the lab evaluates its solution.
pub(crate) fn solve<M: Model<NX, NU>, const NX: usize, const NU: usize>(
    model: &M,
    config: &MpcConfig<NU>,
    x0: &[f64; NX],
    samples: &[TrajectorySample; PREDICTION_STEPS],
    previous_input: &[f64; NU],
    cache: &mut QpCache,
) -> Result<Solution<NU>, Rejection> {
    let qp = Qp {
        model,
        config,
        previous_input,
        state: PhantomData,
    };
    let moves = qp.solve(x0, samples, cache)?;
    Ok(qp.evaluate(x0, samples, &moves))
}

/// What one QP is built from.
struct Qp<'a, M, const NX: usize, const NU: usize> {
    model: &'a M,
    config: &'a MpcConfig<NU>,
    /// The input the first move is penalised against (the newest in the history).
    previous_input: &'a [f64; NU],
    state: PhantomData<[f64; NX]>,
}

impl<M: Model<NX, NU>, const NX: usize, const NU: usize> Qp<'_, M, NX, NU> {
    /// Builds and solves the condensed QP; returns the moves.
    fn solve(
        &self,
        x0: &[f64; NX],
        samples: &[TrajectorySample; PREDICTION_STEPS],
        cache: &mut QpCache,
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
        let solver = match &mut cache.0 {
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
        let c = self.config;
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
            let (a, b) = jacobians(self.model, xk, uk, c.mpc_step_s);
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
            let cmat = position_jacobian(self.model, x_next);
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
        for (i, (&r, &previous)) in c.move_weights.iter().zip(self.previous_input).enumerate() {
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
        let c = self.config;
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
        let c = self.config;
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
        let mut before = *self.previous_input;
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
