//! Shared helpers of the reference-agreement tests: reading `shared/reference` data.
#![allow(dead_code)]

use cpmx_world::{Polyline, ReferencePath};
use serde_json::Value;

/// A file of the read-only SigmaRL reference data (fails the test, naming the folder, if it is
/// missing).
pub fn reference_file(relative: &str) -> std::path::PathBuf {
    cpmx_testdata::reference_file(relative)
}

/// A reference JSON file (fails the test if it is missing).
#[track_caller]
pub fn json(relative: &str) -> Value {
    let text = cpmx_testdata::read_reference(relative);
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{relative}: {e}"))
}

/// A number.
pub fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

fn polyline(v: &Value) -> Polyline {
    Polyline::new(
        v.as_array()
            .expect("points")
            .iter()
            .map(|p| [num(&p[0]), num(&p[1])])
            .collect(),
    )
}

/// All 40 `cpm_entire` reference paths, built directly from `cpm_reference_paths.json`.
pub fn reference_paths() -> Vec<ReferencePath> {
    let root = json("maps/cpm_reference_paths.json");
    root["reference_paths"]
        .as_array()
        .expect("reference_paths")
        .iter()
        .map(|p| ReferencePath {
            id: p["index"].as_u64().expect("index") as usize,
            lanelet_ids: p["lanelet_ids"]
                .as_array()
                .expect("lanelet ids")
                .iter()
                .map(|v| v.as_i64().expect("id"))
                .collect(),
            is_loop: p["is_loop"].as_bool().expect("is_loop"),
            center_line: polyline(&p["center_line"]),
            left_boundary: polyline(&p["left_boundary"]),
            right_boundary: polyline(&p["right_boundary"]),
            left_boundary_shared: polyline(&p["left_boundary_shared"]),
            right_boundary_shared: polyline(&p["right_boundary_shared"]),
            center_line_yaw_rad: nums(&p["center_line_yaw"]),
        })
        .collect()
}

/// Largest absolute difference of two equally long slices.
pub fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

/// A JSON array of numbers.
pub fn nums(v: &Value) -> Vec<f64> {
    v.as_array().expect("array").iter().map(num).collect()
}
