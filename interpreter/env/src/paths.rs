//! The reference paths agents are placed on, prepared once per environment set: the
//! observation's prepared path (shared with `cpmx-policy`, whose float32 segment search in
//! SigmaRL's order also gives the reward its closest points and boundary distances), the
//! start headings, the entry and exit lines, and the shared boundaries as segments with
//! bounding boxes for the crossing tests.

use std::sync::Arc;

use cpmx_policy::PreparedPath;
use cpmx_world::{Point, ReferencePath};

use crate::config::ConfigError;
use cpmx_vehicle::Walls;

/// One reference path as the environment uses it.
#[derive(Debug, Clone)]
pub struct TrainingPath {
    /// The observation's prepared path (centre line and shared boundaries).
    pub prepared: Arc<PreparedPath>,
    /// Yaw of each centre-line segment [rad] (the start heading at a point).
    pub center_yaw_rad: Vec<f64>,
    /// Left and right shared boundaries, for the crossing test.
    pub boundaries: Walls,
    /// First left-shared point to first right-shared point (open paths only).
    pub entry: Option<[Point; 2]>,
    /// Last left-shared point to last right-shared point (open paths only).
    pub exit: Option<[Point; 2]>,
    /// Admissible start indices `[first, end)`.
    pub start_indices: (usize, usize),
    /// The left and right shared boundaries' points, for drawing.
    pub outline: [Vec<Point>; 2],
}

impl TrainingPath {
    /// Prepares `path`, with start indices in `[first_index, floor(n / 2))` (SigmaRL's
    /// training scenario).
    pub fn new(path: &ReferencePath, first_index: usize) -> Result<Self, ConfigError> {
        Self::with_start_window(path, first_index, path.center_line.points.len() / 2)
    }

    /// Prepares `path`, with start indices in `[3, n - 3)`: SigmaRL's testing mode on every
    /// scenario but its training mix (its starts and re-placements).
    pub fn for_testing(path: &ReferencePath) -> Result<Self, ConfigError> {
        const MARGIN: usize = 3;
        Self::with_start_window(path, MARGIN, path.center_line.points.len().saturating_sub(MARGIN))
    }

    fn with_start_window(path: &ReferencePath, first_index: usize, end: usize) -> Result<Self, ConfigError> {
        let n = path.center_line.points.len();
        let left = &path.left_boundary_shared.points;
        let right = &path.right_boundary_shared.points;
        if n < 2 || left.len() < 2 || right.len() < 2 || path.center_line_yaw_rad.len() + 1 < n {
            return Err(ConfigError::DegeneratePath { id: path.id });
        }
        if first_index >= end {
            return Err(ConfigError::NoStartPoint {
                id: path.id,
                points: n,
                first: first_index,
                end,
            });
        }
        let (entry, exit) = if path.is_loop {
            (None, None)
        } else {
            (
                Some([left[0], right[0]]),
                Some([left[left.len() - 1], right[right.len() - 1]]),
            )
        };
        Ok(TrainingPath {
            prepared: Arc::new(PreparedPath::new(path)),
            center_yaw_rad: path.center_line_yaw_rad.clone(),
            boundaries: Walls::new(&[left, right]),
            entry,
            exit,
            start_indices: (first_index, end),
            outline: [left.clone(), right.clone()],
        })
    }

    /// Centre-line point `index` of SigmaRL's long-term path: the centre line, then
    /// `extension` points continuing its last segment, then the last of those repeated
    /// (loops wrap around, skipping the closing point).
    pub fn long_term_point(&self, index: usize, extension: usize) -> Point {
        let p = &self.prepared;
        let n = p.center_points.len();
        if p.is_loop || index < n {
            return p.center_point(index);
        }
        p.center_point(index.min(n - 1 + extension))
    }
}

/// Prepares every path of a path set.
pub fn prepare_paths(paths: &[ReferencePath], first_index: usize) -> Result<Vec<TrainingPath>, ConfigError> {
    if paths.is_empty() {
        return Err(ConfigError::NoPaths);
    }
    paths.iter().map(|p| TrainingPath::new(p, first_index)).collect()
}
