//! The CBF filter's quadratic programme, for one vehicle or several solved together: minimise
//! Σ (u − u₀)ᵀ R (u − u₀) over every vehicle's input u = [a, ω], subject to the CBF rows
//! (each over one vehicle's input, or two for a pair's rows) and each input's bounds; with
//! clarabel at tolerances far below SigmaRL's solver's. Where the rows admit no input, a
//! relaxed QP (a squared slack per row, at `slack_weight`) finds the least violation.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus};

use crate::cbf::{CbfParameters, CbfRow, Fallback};

/// A row `Σ coefficients · u_vehicle + constant ≥ 0` over one vehicle's input or two.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct QpRow {
    /// The first vehicle (its index among the QP's) and its input's coefficients.
    pub first: (usize, [f64; 2]),
    /// The second vehicle of a pair's row.
    pub second: Option<(usize, [f64; 2])>,
    pub constant: f64,
}

impl QpRow {
    /// Vehicle `vehicle`'s own row (a boundary's).
    pub(crate) fn own(vehicle: usize, row: &CbfRow) -> QpRow {
        QpRow {
            first: (vehicle, row.coefficients),
            second: None,
            constant: row.constant,
        }
    }

    /// The row's value at `inputs`.
    pub(crate) fn value(&self, inputs: &[[f64; 2]]) -> f64 {
        let term = |(vehicle, c): (usize, [f64; 2])| c[0] * inputs[vehicle][0] + c[1] * inputs[vehicle][1];
        term(self.first) + self.second.map_or(0.0, term) + self.constant
    }
}

/// The inputs nearest `nominals` that satisfy `rows`, and whether the rows had to be relaxed
/// (only when `p.slack_weight` allows it).
pub(crate) fn solve_relaxing(
    p: &CbfParameters,
    nominals: &[[f64; 2]],
    rows: &[QpRow],
) -> Result<(Vec<[f64; 2]>, bool), Fallback> {
    match (solve(p, nominals, rows, None), p.slack_weight) {
        (Err(Fallback::Infeasible), Some(weight)) => {
            solve(p, nominals, rows, Some(weight)).map(|u| (u, true))
        }
        (result, _) => result.map(|u| (u, false)),
    }
}

/// The QP for `nominals.len()` vehicles; with `slack_weight`, every row relaxed by a slack
/// `s ≥ 0` that costs `slack_weight · s²`.
fn solve(
    p: &CbfParameters,
    nominals: &[[f64; 2]],
    rows: &[QpRow],
    slack_weight: Option<f64>,
) -> Result<Vec<[f64; 2]>, Fallback> {
    let vehicles = nominals.len();
    let [wa, ww] = p.weights;
    let slacks = if slack_weight.is_some() { rows.len() } else { 0 };
    // Variables: each vehicle's [a, ω], then the slacks. ½ xᵀ P x + qᵀ x with P = 2R.
    let variables = 2 * vehicles + slacks;
    let mut diagonal = Vec::with_capacity(variables);
    let mut q = Vec::with_capacity(variables);
    for nominal in nominals {
        diagonal.extend([2.0 * wa, 2.0 * ww]);
        q.extend([-2.0 * wa * nominal[0], -2.0 * ww * nominal[1]]);
    }
    diagonal.extend(std::iter::repeat_n(2.0 * slack_weight.unwrap_or(0.0), slacks));
    q.extend(std::iter::repeat_n(0.0, slacks));
    let pm = CscMatrix::new(
        variables,
        variables,
        (0..=variables).collect(),
        (0..variables).collect(),
        diagonal,
    );
    // A x + s = b, s ≥ 0: the rows as −c·u (− slack) ≤ constant, each vehicle's four bounds,
    // then −slack ≤ 0. A vehicle's columns hold an entry for every row over it and all four of
    // its bounds, zeros included: one vehicle's QP has the same matrix whatever else is solved.
    let bounds_start = rows.len();
    let slack_rows_start = bounds_start + 4 * vehicles;
    let constraints = slack_rows_start + slacks;
    let mut column_starts = Vec::with_capacity(variables + 1);
    let mut row_indices = Vec::new();
    let mut values = Vec::new();
    column_starts.push(0);
    for vehicle in 0..vehicles {
        for component in 0..2 {
            for (k, row) in rows.iter().enumerate() {
                for (v, c) in std::iter::once(row.first).chain(row.second) {
                    if v == vehicle {
                        row_indices.push(k);
                        values.push(-c[component]);
                    }
                }
            }
            let bound_signs = if component == 0 {
                [1.0, -1.0, 0.0, 0.0]
            } else {
                [0.0, 0.0, 1.0, -1.0]
            };
            for (i, sign) in bound_signs.into_iter().enumerate() {
                row_indices.push(bounds_start + 4 * vehicle + i);
                values.push(sign);
            }
            column_starts.push(row_indices.len());
        }
    }
    for k in 0..slacks {
        row_indices.extend([k, slack_rows_start + k]);
        values.extend([-1.0, -1.0]);
        column_starts.push(row_indices.len());
    }
    let mut b: Vec<f64> = rows.iter().map(|r| r.constant).collect();
    for _ in 0..vehicles {
        b.extend([
            p.acceleration_limit_mps2,
            p.acceleration_limit_mps2,
            p.steering_rate_limit_radps,
            p.steering_rate_limit_radps,
        ]);
    }
    b.extend(std::iter::repeat_n(0.0, slacks));
    let a = CscMatrix::new(constraints, variables, column_starts, row_indices, values);
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
    let cones = [NonnegativeConeT(constraints)];
    let mut solver = DefaultSolver::new(&pm, &q, &a, &b, &cones, settings).map_err(|_| Fallback::Unsolved)?;
    solver.solve();
    match solver.solution.status {
        SolverStatus::Solved => Ok((0..vehicles)
            .map(|v| [solver.solution.x[2 * v], solver.solution.x[2 * v + 1]])
            .collect()),
        SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => Err(Fallback::Infeasible),
        _ => Err(Fallback::Unsolved),
    }
}
