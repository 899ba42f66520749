//! Loading the shared reference data (SigmaRL's map dump, metric cases, rollout) for the
//! agreement tests. A missing file fails the test with a message naming the folder.

#![allow(dead_code)]

use cpmx_metrics::PathGeometry;
use cpmx_recording::{AgentSample, Recording};
use cpmx_world::Point;
use serde_json::Value;

pub const MAP: &str = "maps/cpm_reference_paths.json";
pub const CASES: &str = "metrics/cases.json";
pub const ROLLOUT: &str = "rollouts/rollout_1.json";
pub const ROLLOUT_METRICS: &str = "rollouts/metrics_1.json";

/// A JSON file of the reference data, by its path in the folder (fails the test, naming the
/// folder, when it is missing).
#[track_caller]
pub fn read_json(path: &str) -> Value {
    let text = cpmx_testdata::read_reference(path);
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// A float32 value as written in the reference (shortest f32 decimal), widened exactly.
pub fn f32_value(v: &Value) -> f64 {
    let x = v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"));
    x as f32 as f64
}

fn points(v: &Value) -> Vec<Point> {
    v.as_array()
        .expect("a point list")
        .iter()
        .map(|p| [f32_value(&p[0]), f32_value(&p[1])])
        .collect()
}

/// One reference path's lines as read from the map dump.
pub struct PathLines {
    pub id: usize,
    pub center_line: Vec<Point>,
    pub left_boundary: Vec<Point>,
    pub right_boundary: Vec<Point>,
    pub is_loop: bool,
}

impl PathLines {
    pub fn geometry(&self) -> PathGeometry<'_> {
        PathGeometry {
            id: self.id,
            center_line: &self.center_line,
            left_boundary: &self.left_boundary,
            right_boundary: &self.right_boundary,
            road_left_boundary: &self.left_boundary,
            road_right_boundary: &self.right_boundary,
            is_loop: self.is_loop,
        }
    }
}

/// The 40 `cpm_entire` reference paths, with `id` = SigmaRL's 0-based index.
pub fn reference_paths(map: &Value) -> Vec<PathLines> {
    map["reference_paths"]
        .as_array()
        .expect("reference_paths")
        .iter()
        .map(|p| PathLines {
            id: p["index"].as_u64().expect("index") as usize,
            center_line: points(&p["center_line"]),
            left_boundary: points(&p["left_boundary"]),
            right_boundary: points(&p["right_boundary"]),
            is_loop: p["is_loop"].as_bool().unwrap_or(false),
        })
        .collect()
}

/// Centre of the bounding box of all lanelet boundaries (SigmaRL's `map_center_from_lanelets`).
pub fn map_centre(map: &Value) -> Point {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for lanelet in map["lanelets"].as_array().expect("lanelets") {
        for key in ["left_boundary", "right_boundary"] {
            for p in points(&lanelet[key]) {
                for k in 0..2 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
        }
    }
    [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])]
}

/// A recording on a 0.1 s grid from `pos [T][N][2]`, `rot [T][N]`, `vel [T][N][2]`.
pub fn recording(pos: &Value, rot: &Value, vel: &Value, ref_paths: Vec<usize>) -> Recording {
    let pos = pos.as_array().expect("pos");
    let mut r = Recording {
        notes: Vec::new(),
        latency_s: Vec::new(),
        statistics: Default::default(),
        times_s: (0..pos.len()).map(|k| k as f64 * 0.1).collect(),
        ref_paths,
        samples: Vec::new(),
    };
    for (k, row) in pos.iter().enumerate() {
        let row = row.as_array().expect("row");
        r.samples.push(
            (0..row.len())
                .map(|i| AgentSample {
                    x_m: f32_value(&row[i][0]),
                    y_m: f32_value(&row[i][1]),
                    yaw_rad: f32_value(&rot[k][i]),
                    velocity_mps: [f32_value(&vel[k][i][0]), f32_value(&vel[k][i][1])],
                    steering_rad: f64::NAN,
                })
                .collect(),
        );
    }
    r
}

/// Largest errors seen for one output.
#[derive(Debug, Default, Clone, Copy)]
pub struct Worst {
    pub relative: f64,
    pub absolute: f64,
}

impl Worst {
    /// Records `ours` against `reference` (both NaN: agreement).
    pub fn record(&mut self, ours: f64, reference: f64) {
        if ours.is_nan() && reference.is_nan() {
            return;
        }
        let absolute = (ours - reference).abs();
        let relative = if reference == 0.0 {
            absolute
        } else {
            absolute / reference.abs()
        };
        self.absolute = self.absolute.max(if absolute.is_nan() {
            f64::INFINITY
        } else {
            absolute
        });
        self.relative = self.relative.max(if relative.is_nan() {
            f64::INFINITY
        } else {
            relative
        });
    }
}

/// A reference number, `null` = NaN.
pub fn number(v: &Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}
