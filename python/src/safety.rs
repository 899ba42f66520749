//! `_cbf_filter(...)`: SigmaRL's CBF safety filter (`cpmx-safety`) for one vehicle and step, so
//! that Python can set it beside SigmaRL's own `cbf_qp.py` on the same states.

use cpmx_safety::{Boundary, CbfParameters, CbfState, Fallback, Side, filter};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// A CBF row as Python receives it: circle, side, margin [m], coefficients of acceleration and
/// steering rate, constant.
type Row = (usize, &'static str, f64, f64, f64, f64);

/// The filtered action, why the nominal one went through (`None`, `"infeasible"`,
/// `"not-finite"`, `"unsolved"`), the active rows' indices and every row.
type Filtered = ([f32; 2], Option<&'static str>, Vec<usize>, Vec<Row>);

/// Filters `action` (`[speed, steering]`) for a vehicle in `state` (`[x, y, yaw, speed,
/// steering]`) between the boundaries `left` and `right` (lists of `[x, y]`), with SigmaRL's
/// parameters (tag 1.4.0) but `circles` and the step `dt_s`.
#[pyfunction]
#[pyo3(signature = (state, action, left, right, circles=3, dt_s=0.05))]
pub fn _cbf_filter(
    state: [f32; 5],
    action: [f32; 2],
    left: Vec<[f32; 2]>,
    right: Vec<[f32; 2]>,
    circles: usize,
    dt_s: f64,
) -> PyResult<Filtered> {
    let boundary = |points: Vec<[f32; 2]>, side: &str| {
        Boundary::new(points)
            .ok_or_else(|| PyValueError::new_err(format!("the {side} boundary needs two points or more")))
    };
    let (left, right) = (boundary(left, "left")?, boundary(right, "right")?);
    if circles == 0 || !(dt_s.is_finite() && dt_s > 0.0) {
        return Err(PyValueError::new_err(format!(
            "circles must be positive and dt_s a positive number (got {circles} and {dt_s})"
        )));
    }
    let parameters = CbfParameters {
        circles,
        ..CbfParameters::sigmarl(dt_s)
    };
    let [x_m, y_m, yaw_rad, speed_mps, steering_rad] = state;
    let out = filter(
        &parameters,
        CbfState {
            x_m,
            y_m,
            yaw_rad,
            speed_mps,
            steering_rad,
        },
        action,
        &left,
        &right,
    );
    let fallback = out.fallback.map(|f| match f {
        Fallback::Infeasible => "infeasible",
        Fallback::NotFinite => "not-finite",
        Fallback::Unsolved => "unsolved",
    });
    let rows = out
        .rows
        .iter()
        .map(|r| {
            let side = match r.side {
                Side::Left => "left",
                Side::Right => "right",
            };
            (
                r.circle,
                side,
                r.margin_m,
                r.coefficients[0],
                r.coefficients[1],
                r.constant,
            )
        })
        .collect();
    Ok((out.action, fallback, out.active, rows))
}
