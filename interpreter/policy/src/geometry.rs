//! Reference-path geometry prepared for the per-step queries of observations and baselines:
//! polylines stored as segment arrays, so that SigmaRL's nearest-segment search over a whole
//! path is a tight loop the compiler vectorises. Built once per run, never per step.

use cpmx_world::{Point, Polyline, ReferencePath};

/// A polyline as float32 arrays of segment starts and directions.
///
/// Queries repeat SigmaRL's `get_perpendicular_distances` in float32 with torch's operation
/// order (projection `dot / |v|^2`, clamp, closest point `start + v t`, norm), because which
/// segment wins a near-tie (a point on a vertex) decides the short-term reference points.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Segments {
    start_x: Vec<f32>,
    start_y: Vec<f32>,
    dir_x: Vec<f32>,
    dir_y: Vec<f32>,
    /// `|dir|^2` (0 for a degenerate segment, which then measures the distance to its start).
    len2: Vec<f32>,
}

/// Result of [`Segments::nearest`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Nearest {
    /// Unsigned distance to the polyline [m].
    pub distance_m: f64,
    /// Index of the first segment attaining the minimum.
    pub segment: usize,
}

impl Segments {
    /// Segment arrays of a polyline (empty for fewer than two points).
    pub fn new(line: &Polyline) -> Self {
        let mut s = Segments::default();
        for pair in line.points.windows(2) {
            let (ax, ay) = (pair[0][0] as f32, pair[0][1] as f32);
            let (dx, dy) = (pair[1][0] as f32 - ax, pair[1][1] as f32 - ay);
            s.start_x.push(ax);
            s.start_y.push(ay);
            s.dir_x.push(dx);
            s.dir_y.push(dy);
            s.len2.push(dx * dx + dy * dy);
        }
        s
    }

    /// Number of segments.
    pub fn len(&self) -> usize {
        self.start_x.len()
    }

    /// Whether there is no segment.
    pub fn is_empty(&self) -> bool {
        self.start_x.is_empty()
    }

    /// Distance from `(px, py)` to segment `i`, in float32 as torch computes it.
    #[inline(always)]
    fn distance(&self, i: usize, px: f32, py: f32) -> f32 {
        self.distance2(i, px, py).sqrt()
    }

    /// Squared distance from `(px, py)` to segment `i` (float32, torch's order).
    #[inline(always)]
    fn distance2(&self, i: usize, px: f32, py: f32) -> f32 {
        let (vx, vy) = (self.dir_x[i], self.dir_y[i]);
        let dot = (px - self.start_x[i]) * vx + (py - self.start_y[i]) * vy;
        let len2 = self.len2[i];
        let t = if len2 > 0.0 {
            (dot / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (ex, ey) = (self.start_x[i] + vx * t - px, self.start_y[i] + vy * t - py);
        ex * ex + ey * ey
    }

    /// Nearest segment to `p` with SigmaRL's rule (the first one on ties), or `None` when empty.
    pub fn nearest(&self, p: Point) -> Option<Nearest> {
        let (px, py) = (p[0] as f32, p[1] as f32);
        let best = self.min_distance(px, py);
        // Ties are decided on the rounded distances, as torch compares them.
        let segment = (0..self.len()).find(|&i| self.distance(i, px, py) <= best)?;
        Some(Nearest {
            distance_m: f64::from(best),
            segment,
        })
    }

    /// Unsigned distance from `p` to the polyline (infinite when empty).
    pub fn distance_m(&self, p: Point) -> f64 {
        f64::from(self.min_distance(p[0] as f32, p[1] as f32))
    }

    /// Smallest distance over all segments (a loop the compiler vectorises). The square root
    /// is monotone and correctly rounded, so taking it once at the end gives the same value.
    fn min_distance(&self, px: f32, py: f32) -> f32 {
        let mut best = f32::INFINITY;
        for i in 0..self.len() {
            let d2 = self.distance2(i, px, py);
            best = if d2 < best { d2 } else { best };
        }
        best.sqrt()
    }
}

/// One agent's reference path, prepared for queries.
#[derive(Debug, Clone, PartialEq)]
pub struct PreparedPath {
    /// The path's id (SigmaRL's 0-based index).
    pub id: usize,
    /// Whether the path is a closed loop (last centre-line point repeats the first).
    pub is_loop: bool,
    /// Centre-line points [m].
    pub center_points: Vec<Point>,
    /// Centre-line segments.
    pub center: Segments,
    /// Shared (road) left boundary segments.
    pub left_shared: Segments,
    /// Shared (road) right boundary segments.
    pub right_shared: Segments,
}

impl PreparedPath {
    /// Prepare a reference path.
    pub fn new(path: &ReferencePath) -> Self {
        PreparedPath {
            id: path.id,
            is_loop: path.is_loop,
            center_points: path.center_line.points.clone(),
            center: Segments::new(&path.center_line),
            left_shared: Segments::new(&path.left_boundary_shared),
            right_shared: Segments::new(&path.right_boundary_shared),
        }
    }

    /// Centre-line point `index` with SigmaRL's continuation past the end: on a loop, an index
    /// `>= n - 1` becomes `(index + 1) mod n` (skipping the duplicated closing point); on an
    /// open path the last segment is continued (SigmaRL pads open paths by such points).
    pub fn center_point(&self, index: usize) -> Point {
        let pts = &self.center_points;
        let n = pts.len();
        match n {
            0 => [0.0, 0.0],
            1 => pts[0],
            _ if index < n - 1 => pts[index],
            _ if self.is_loop => pts[(index + 1) % n],
            _ => {
                let (a, b) = (pts[n - 2], pts[n - 1]);
                let k = (index - (n - 1)) as f64;
                [b[0] + k * (b[0] - a[0]), b[1] + k * (b[1] - a[1])]
            }
        }
    }
}

/// The prepared reference path of every agent, in agent order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AgentPaths {
    /// One prepared path per agent.
    pub paths: Vec<PreparedPath>,
}

impl AgentPaths {
    /// Prepare one reference path per agent (agent `i` follows `paths[i]`).
    pub fn new<'a>(paths: impl IntoIterator<Item = &'a ReferencePath>) -> Self {
        AgentPaths {
            paths: paths.into_iter().map(PreparedPath::new).collect(),
        }
    }

    /// Number of agents.
    pub fn len(&self) -> usize {
        self.paths.len()
    }

    /// Whether there is no agent.
    pub fn is_empty(&self) -> bool {
        self.paths.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_agrees_with_the_world_crate_including_ties() {
        let line = Polyline::new(vec![[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [2.0, 1.0], [3.0, 1.0]]);
        let segs = Segments::new(&line);
        for p in [
            [1.0, 1.0],
            [0.5, -0.2],
            [2.5, 1.5],
            [-1.0, 0.0],
            [1.0, 0.0],
            [9.0, 9.0],
        ] {
            let want = line.nearest_segment(p).unwrap();
            let got = segs.nearest(p).unwrap();
            assert_eq!(got.segment, want.segment, "{p:?}");
            assert!((got.distance_m - want.distance_m).abs() < 1e-6);
        }
    }

    #[test]
    fn loop_indices_skip_the_closing_point_and_open_paths_continue() {
        let mut path = PreparedPath {
            id: 0,
            is_loop: true,
            center_points: vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 0.0]],
            center: Segments::default(),
            left_shared: Segments::default(),
            right_shared: Segments::default(),
        };
        assert_eq!(path.center_point(2), [1.0, 1.0]);
        assert_eq!(path.center_point(3), [0.0, 0.0]);
        assert_eq!(path.center_point(4), [1.0, 0.0]);
        path.is_loop = false;
        assert_eq!(path.center_point(4), [-1.0, -1.0]);
    }
}
