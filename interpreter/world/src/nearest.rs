//! A fast nearest-segment query for the simulator's hot path. [`SegmentGrid`] stores, for
//! every cell of a uniform grid around one polyline, the few segments that can be nearest to
//! any point of the cell; a query evaluates only those, in ascending order, with the same
//! function and the same first-minimum rule as [`Polyline::nearest_segment`], so it returns
//! exactly the same answer (distance, segment, projection parameter).
//!
//! Why the candidate list is complete: let `c` be a cell's centre, `h` its half diagonal and
//! `d*` the distance from `c` to the polyline. For a point `q` in the cell, its nearest
//! segment `s` has `|q s| <= d* + h` (the segment nearest `c` is that close), so
//! `|c s| <= d* + 2h`; every segment tying with `s` satisfies the same bound. The cell keeps
//! all segments with `|c s| <= d* + 2h` (plus a rounding margin). Points outside the grid fall
//! back to the plain search.

use crate::polyline::{Point, Polyline, SegmentDistance, point_segment_distance};

/// Largest number of cells of a grid.
const MAX_CELLS: usize = 4096;
/// Margin around the polyline's bounding box covered by the grid, as a fraction of its extent.
const PAD_FRACTION: f64 = 0.1;
/// Rounding margin on the candidate bound [m], far above floating-point error of distances on
/// map-sized coordinates and far below anything geometric.
const MARGIN_M: f64 = 1e-9;

/// A polyline with, per grid cell, the segments that can be nearest to a point of the cell.
#[derive(Debug, Clone)]
pub struct SegmentGrid {
    polyline: Polyline,
    origin: Point,
    cell_m: f64,
    nx: usize,
    ny: usize,
    /// Candidate segments per cell, ascending, stored flat: cell `i` owns
    /// `candidates[starts[i]..starts[i + 1]]`.
    starts: Vec<u32>,
    candidates: Vec<u32>,
}

impl SegmentGrid {
    /// Builds the grid of `polyline`.
    pub fn new(polyline: Polyline) -> Self {
        let mut grid = Self {
            polyline: Polyline::default(),
            origin: [0.0; 2],
            cell_m: 1.0,
            nx: 0,
            ny: 0,
            starts: Vec::new(),
            candidates: Vec::new(),
        };
        let Some(b) = crate::map::Bounds::of(polyline.points.iter().copied()) else {
            grid.polyline = polyline;
            return grid;
        };
        let extent = (b.max_x_m - b.min_x_m).max(b.max_y_m - b.min_y_m);
        if polyline.segment_count() == 0 || !extent.is_finite() || extent <= 0.0 {
            grid.polyline = polyline;
            return grid;
        }

        // Size the grid: the padded bounding box in at most MAX_CELLS square cells.
        let pad = PAD_FRACTION * extent;
        let (w, h) = (
            b.max_x_m - b.min_x_m + 2.0 * pad,
            b.max_y_m - b.min_y_m + 2.0 * pad,
        );
        let cell_m = (w * h / MAX_CELLS as f64).sqrt();
        let (nx, ny) = ((w / cell_m).ceil() as usize, (h / cell_m).ceil() as usize);
        let (nx, ny) = (nx.clamp(1, MAX_CELLS), ny.clamp(1, MAX_CELLS / nx.max(1)).max(1));
        grid.origin = [b.min_x_m - pad, b.min_y_m - pad];
        grid.cell_m = cell_m;
        grid.nx = nx;
        grid.ny = ny;

        // Keep, per cell, the segments within d* + 2h of its centre.
        let half_diagonal_m = cell_m * std::f64::consts::FRAC_1_SQRT_2;
        let pts = &polyline.points;
        let mut d = vec![0.0; polyline.segment_count()];
        grid.starts.reserve(nx * ny + 1);
        grid.starts.push(0);
        for iy in 0..ny {
            for ix in 0..nx {
                let c = [
                    grid.origin[0] + (ix as f64 + 0.5) * cell_m,
                    grid.origin[1] + (iy as f64 + 0.5) * cell_m,
                ];
                let mut best = f64::INFINITY;
                for (s, w) in pts.windows(2).enumerate() {
                    d[s] = point_segment_distance(c, w[0], w[1]).0;
                    best = best.min(d[s]);
                }
                let bound = best + 2.0 * half_diagonal_m + MARGIN_M * (1.0 + best);
                grid.candidates.extend(
                    d.iter()
                        .enumerate()
                        .filter(|&(_, &ds)| ds <= bound)
                        .map(|(s, _)| s as u32),
                );
                grid.starts.push(grid.candidates.len() as u32);
            }
        }
        grid.polyline = polyline;
        grid
    }

    /// The polyline.
    pub fn polyline(&self) -> &Polyline {
        &self.polyline
    }

    /// The cell holding `p`, if inside the grid.
    fn cell_of(&self, p: Point) -> Option<usize> {
        let fx = (p[0] - self.origin[0]) / self.cell_m;
        let fy = (p[1] - self.origin[1]) / self.cell_m;
        let inside = fx >= 0.0 && fy >= 0.0 && fx < self.nx as f64 && fy < self.ny as f64;
        inside.then(|| (fy as usize).min(self.ny - 1) * self.nx + (fx as usize).min(self.nx - 1))
    }

    /// Nearest segment to `p`, identical to [`Polyline::nearest_segment`].
    pub fn nearest_segment(&self, p: Point) -> Option<SegmentDistance> {
        let Some(cell) = self.cell_of(p) else {
            return self.polyline.nearest_segment(p);
        };
        let range = self.starts[cell] as usize..self.starts[cell + 1] as usize;
        let pts = &self.polyline.points;
        let mut best: Option<SegmentDistance> = None;
        for &s in &self.candidates[range] {
            let s = s as usize;
            let (distance_m, t) = point_segment_distance(p, pts[s], pts[s + 1]);
            if best.is_none_or(|b| distance_m < b.distance_m) {
                best = Some(SegmentDistance {
                    distance_m,
                    segment: s,
                    t,
                });
            }
        }
        best
    }

    /// Unsigned distance from `p` to the polyline (infinite for fewer than two points).
    pub fn distance_m(&self, p: Point) -> f64 {
        self.nearest_segment(p).map_or(f64::INFINITY, |d| d.distance_m)
    }
}

/// Grids of the polylines of one reference path, for per-step observation queries.
#[derive(Debug, Clone)]
pub struct PathIndex {
    /// Centre line.
    pub center_line: SegmentGrid,
    /// Own-lane left boundary.
    pub left_boundary: SegmentGrid,
    /// Own-lane right boundary.
    pub right_boundary: SegmentGrid,
    /// Shared (road) left boundary.
    pub left_boundary_shared: SegmentGrid,
    /// Shared (road) right boundary.
    pub right_boundary_shared: SegmentGrid,
}

impl PathIndex {
    /// Indexes the polylines of `path`.
    pub fn new(path: &crate::ReferencePath) -> Self {
        Self {
            center_line: SegmentGrid::new(path.center_line.clone()),
            left_boundary: SegmentGrid::new(path.left_boundary.clone()),
            right_boundary: SegmentGrid::new(path.right_boundary.clone()),
            left_boundary_shared: SegmentGrid::new(path.left_boundary_shared.clone()),
            right_boundary_shared: SegmentGrid::new(path.right_boundary_shared.clone()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn polyline_strategy() -> impl Strategy<Value = Polyline> {
        prop::collection::vec((-3.0f64..3.0, -3.0f64..3.0), 0..40).prop_map(|v| {
            // Build a wiggly walk with some repeated points and exact duplicates.
            let mut pts = Vec::new();
            let mut cur = [1.0, 1.0];
            for (i, (dx, dy)) in v.into_iter().enumerate() {
                if i % 7 != 3 {
                    cur = [cur[0] + dx * 0.1, cur[1] + dy * 0.1];
                }
                pts.push(cur);
            }
            Polyline::new(pts)
        })
    }

    proptest! {
        // Each case builds a full grid; a few dozen cases keep the suite fast.
        #![proptest_config(ProptestConfig { cases: 48, failure_persistence: None, ..ProptestConfig::default() })]

        #[test]
        fn grid_equals_brute_force(line in polyline_strategy(),
                                   qs in prop::collection::vec((-1.0f64..3.0, -1.0f64..3.0), 1..60)) {
            let grid = SegmentGrid::new(line.clone());
            for (x, y) in qs {
                prop_assert_eq!(grid.nearest_segment([x, y]), line.nearest_segment([x, y]));
            }
        }

        #[test]
        fn grid_equals_brute_force_on_a_circle(n in 3usize..200, x in 0.0f64..2.0, y in 0.0f64..2.0) {
            // A closed loop, like the CPM Lab paths: ties at the seam must go to segment 0.
            let pts: Vec<Point> = (0..=n)
                .map(|i| {
                    let a = std::f64::consts::TAU * (i % n) as f64 / n as f64;
                    [1.0 + 0.8 * a.cos(), 1.0 + 0.8 * a.sin()]
                })
                .collect();
            let line = Polyline::new(pts);
            let grid = SegmentGrid::new(line.clone());
            prop_assert_eq!(grid.nearest_segment([x, y]), line.nearest_segment([x, y]));
        }
    }

    #[test]
    fn exact_ties_go_to_the_first_segment() {
        let line = Polyline::new(vec![[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [1.0, 0.0]]);
        let grid = SegmentGrid::new(line.clone());
        for q in [[1.0, 1.0], [1.5, 0.2], [0.5, -0.3]] {
            assert_eq!(grid.nearest_segment(q), line.nearest_segment(q));
        }
    }
}
