//! The CBF filter's quadratic programme, for one vehicle or several solved together: minimise
//! Σ (u − u₀)ᵀ R (u − u₀) over every vehicle's input u = [a, ω], subject to the CBF rows
//! (each over one vehicle's input, or two for a pair's rows) and each input's bounds; with
//! clarabel at tolerances far below SigmaRL's solver's. Where the rows admit no input, a
//! relaxed QP (a squared slack per row, at `slack_weight`) finds the least violation.
//!
//! One vehicle's QP has two unknowns: its answer is the nominal input projected (in the
//! weights' metric) onto the polygon of its rows, which lies on at most two of them. So it is
//! solved exactly by enumeration ([`solve_one`]: the nominal, its projection on each row's line,
//! each two rows' corner; the nearest feasible one), in about a microsecond where clarabel
//! takes a few hundred to set up and solve; no corner is feasible only if the polygon is empty.

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
}

/// The inputs nearest `nominals` that satisfy `rows`, and whether the rows had to be relaxed
/// (only when `p.slack_weight` allows it).
pub(crate) fn solve_relaxing(
    p: &CbfParameters,
    nominals: &[[f64; 2]],
    rows: &[QpRow],
) -> Result<(Vec<[f64; 2]>, bool), Fallback> {
    let exact = match nominals {
        [nominal] if rows.iter().all(|r| r.second.is_none()) => solve_one(p, *nominal, rows).map(|u| vec![u]),
        _ => solve(p, nominals, rows, None),
    };
    match (exact, p.slack_weight) {
        (Err(Fallback::Infeasible), Some(weight)) => {
            solve(p, nominals, rows, Some(weight)).map(|u| (u, true))
        }
        (result, _) => result.map(|u| (u, false)),
    }
}

/// One vehicle's QP (every row over its input alone), solved exactly: minimise
/// ‖v − v₀‖² with v = [√w_a·a, √w_ω·ω] over the rows and the bounds, as the nearest feasible
/// point among v₀, its projections on each row's line and the corners of each two rows.
pub(crate) fn solve_one(p: &CbfParameters, nominal: [f64; 2], rows: &[QpRow]) -> Result<[f64; 2], Fallback> {
    let scale = [p.weights[0].sqrt(), p.weights[1].sqrt()];
    // Each row as n·v + c ≥ 0 in the weighted coordinates, then the four bounds.
    let mut lines: Vec<([f64; 2], f64)> = rows
        .iter()
        .map(|r| ([r.first.1[0] / scale[0], r.first.1[1] / scale[1]], r.constant))
        .collect();
    let (a_max, w_max) = (
        p.acceleration_limit_mps2 * scale[0],
        p.steering_rate_limit_radps * scale[1],
    );
    lines.extend([
        ([-1.0, 0.0], a_max),
        ([1.0, 0.0], a_max),
        ([0.0, -1.0], w_max),
        ([0.0, 1.0], w_max),
    ]);
    let v0 = [nominal[0] * scale[0], nominal[1] * scale[1]];
    let value = |(n, c): &([f64; 2], f64), v: [f64; 2]| n[0] * v[0] + n[1] * v[1] + c;
    // A row holds within round-off of its own terms (clarabel's 1e-10 feasibility, relative).
    let feasible = |v: [f64; 2]| {
        lines.iter().all(|line @ (n, c)| {
            let size = (n[0] * v[0]).abs() + (n[1] * v[1]).abs() + c.abs();
            value(line, v) >= -1e-10 * size.max(1e-300)
        })
    };
    let mut best: Option<([f64; 2], f64)> = None;
    let mut consider = |v: [f64; 2]| {
        let cost = (v[0] - v0[0]).powi(2) + (v[1] - v0[1]).powi(2);
        if v.iter().all(|x| x.is_finite()) && best.is_none_or(|(_, b)| cost < b) && feasible(v) {
            best = Some((v, cost));
        }
    };
    consider(v0);
    for line @ (n, _) in &lines {
        let norm_sq = n[0] * n[0] + n[1] * n[1];
        if norm_sq > 0.0 {
            let t = value(line, v0) / norm_sq;
            consider([v0[0] - t * n[0], v0[1] - t * n[1]]);
        }
    }
    for (i, (n1, c1)) in lines.iter().enumerate() {
        for (n2, c2) in &lines[i + 1..] {
            let det = n1[0] * n2[1] - n1[1] * n2[0];
            if det != 0.0 {
                consider([(-c1 * n2[1] + c2 * n1[1]) / det, (-n1[0] * c2 + n2[0] * c1) / det]);
            }
        }
    }
    best.map(|(v, _)| [v[0] / scale[0], v[1] / scale[1]])
        .ok_or(Fallback::Infeasible)
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

#[cfg(test)]
mod tests {
    use super::*;

    /// 3,000 QPs of one vehicle from a fixed stream: the enumeration finds clarabel's answer,
    /// and no answer exactly where clarabel finds the rows infeasible.
    #[test]
    fn one_vehicles_qp_solved_by_enumeration_is_clarabels() {
        let mut seed = 0x2545_f491_4f6c_dd1d_u64;
        let mut uniform = move |low: f64, high: f64| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            low + (high - low) * (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let p = CbfParameters::sigmarl(0.05);
        let (mut solved, mut infeasible) = (0, 0);
        for _ in 0..3000 {
            let rows: Vec<QpRow> = (0..(2 + (uniform(0.0, 5.0) as usize)))
                .map(|_| QpRow {
                    first: (0, [uniform(-1e-3, 1e-3), uniform(-1e-3, 1e-3)]),
                    second: None,
                    constant: uniform(-0.03, 0.03),
                })
                .collect();
            let nominal = [uniform(-40.0, 40.0), uniform(-40.0, 40.0)];
            match (solve(&p, &[nominal], &rows, None), solve_one(&p, nominal, &rows)) {
                (Ok(reference), Ok(exact)) => {
                    solved += 1;
                    for (r, e) in reference[0].iter().zip(exact) {
                        assert!(
                            (r - e).abs() <= 1e-6 * (1.0 + r.abs()),
                            "{reference:?} {exact:?} {rows:?}"
                        );
                    }
                }
                (Err(Fallback::Infeasible), Err(Fallback::Infeasible)) => infeasible += 1,
                (reference, exact) => {
                    panic!("clarabel {reference:?}, enumeration {exact:?}: {rows:?} {nominal:?}")
                }
            }
        }
        assert!(
            solved > 500 && infeasible > 500,
            "{solved} solved, {infeasible} infeasible"
        );
    }
}
