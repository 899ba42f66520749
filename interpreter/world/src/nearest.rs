//! A fast nearest-segment query for the simulator's hot path. [`SegmentGrid`] buckets the
//! segments of one polyline in a uniform grid and searches rings of cells outward from the
//! query; it returns exactly what [`Polyline::nearest_segment`] returns (same distance, same
//! first minimising segment, same projection parameter), because it evaluates the same
//! function on a candidate set that provably holds every segment that could tie or win.

use crate::polyline::{Point, Polyline, SegmentDistance, point_segment_distance};

/// Largest number of cells along one axis.
const MAX_CELLS_PER_AXIS: usize = 64;
/// Safety margin [m] on the ring lower bound, far above floating-point rounding of distances
/// on map-sized coordinates, so that a segment outside the searched cells can never tie.
const MARGIN_M: f64 = 1e-7;

/// A polyline with its segments bucketed in a uniform grid.
#[derive(Debug, Clone)]
pub struct SegmentGrid {
    polyline: Polyline,
    origin: Point,
    cell_m: f64,
    nx: usize,
    ny: usize,
    /// Segment indices per cell, row-major (`iy * nx + ix`), ascending.
    cells: Vec<Vec<u32>>,
}

impl SegmentGrid {
    /// Builds the grid of `polyline`.
    pub fn new(polyline: Polyline) -> Self {
        // Size the grid: cells about a mean segment long, at most 64 per axis.
        let pts = &polyline.points;
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in pts {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let segments = polyline.segment_count();
        if segments == 0 || !lo.iter().chain(&hi).all(|v| v.is_finite()) {
            return Self {
                polyline,
                origin: [0.0; 2],
                cell_m: 1.0,
                nx: 0,
                ny: 0,
                cells: Vec::new(),
            };
        }
        let extent = (hi[0] - lo[0]).max(hi[1] - lo[1]);
        let mean_segment_m = polyline.length_m() / segments as f64;
        let cell_m = mean_segment_m
            .max(extent / MAX_CELLS_PER_AXIS as f64)
            .max(1e-9 * (1.0 + extent));
        let cells_along = |span: f64| ((span / cell_m).floor() as usize + 1).min(MAX_CELLS_PER_AXIS);
        let (nx, ny) = (cells_along(hi[0] - lo[0]), cells_along(hi[1] - lo[1]));
        let mut grid = Self {
            polyline: Polyline::default(),
            origin: lo,
            cell_m,
            nx,
            ny,
            cells: vec![Vec::new(); nx * ny],
        };

        // Bucket every segment into the cells its bounding box touches.
        for (i, w) in pts.windows(2).enumerate() {
            let (ax, ay) = grid.cell_of(w[0]);
            let (bx, by) = grid.cell_of(w[1]);
            for iy in ay.min(by)..=ay.max(by) {
                for ix in ax.min(bx)..=ax.max(bx) {
                    grid.cells[iy * nx + ix].push(i as u32);
                }
            }
        }
        grid.polyline = polyline;
        grid
    }

    /// The polyline.
    pub fn polyline(&self) -> &Polyline {
        &self.polyline
    }

    /// The cell holding `p`, clamped to the grid.
    fn cell_of(&self, p: Point) -> (usize, usize) {
        let c = |v: f64, o: f64, n: usize| {
            let i = ((v - o) / self.cell_m).floor();
            if i.is_nan() || i < 0.0 {
                0
            } else {
                (i as usize).min(n - 1)
            }
        };
        (c(p[0], self.origin[0], self.nx), c(p[1], self.origin[1], self.ny))
    }

    /// Nearest segment to `p`, identical to [`Polyline::nearest_segment`].
    pub fn nearest_segment(&self, p: Point) -> Option<SegmentDistance> {
        let max_x = self.origin[0] + self.nx as f64 * self.cell_m;
        let max_y = self.origin[1] + self.ny as f64 * self.cell_m;
        let inside = p[0] >= self.origin[0] && p[0] <= max_x && p[1] >= self.origin[1] && p[1] <= max_y;
        if self.nx == 0 || !inside {
            // Outside the grid (or degenerate): the plain search.
            return self.polyline.nearest_segment(p);
        }
        let pts = &self.polyline.points;
        let (cx, cy) = self.cell_of(p);
        let mut best: Option<SegmentDistance> = None;
        for r in 0.. {
            // Visit the cells of ring r.
            let (x0, x1) = (cx.saturating_sub(r), (cx + r).min(self.nx - 1));
            let (y0, y1) = (cy.saturating_sub(r), (cy + r).min(self.ny - 1));
            for iy in y0..=y1 {
                let on_edge_row = iy + r == cy || iy == cy + r;
                let step = if on_edge_row { 1 } else { (x1 - x0).max(1) };
                let mut ix = x0;
                while ix <= x1 {
                    if on_edge_row || ix + r == cx || ix == cx + r {
                        for &s in &self.cells[iy * self.nx + ix] {
                            let s = s as usize;
                            let (distance_m, t) = point_segment_distance(p, pts[s], pts[s + 1]);
                            let better = best.is_none_or(|b| {
                                distance_m < b.distance_m || (distance_m == b.distance_m && s < b.segment)
                            });
                            if better {
                                best = Some(SegmentDistance {
                                    distance_m,
                                    segment: s,
                                    t,
                                });
                            }
                        }
                    }
                    ix += step;
                }
            }

            // Stop when no unvisited cell can hold a segment as close as the best one.
            let covers_all = x0 == 0 && y0 == 0 && x1 == self.nx - 1 && y1 == self.ny - 1;
            if covers_all {
                break;
            }
            let mut bound = f64::INFINITY;
            if x0 > 0 {
                bound = bound.min(p[0] - (self.origin[0] + x0 as f64 * self.cell_m));
            }
            if x1 < self.nx - 1 {
                bound = bound.min(self.origin[0] + (x1 + 1) as f64 * self.cell_m - p[0]);
            }
            if y0 > 0 {
                bound = bound.min(p[1] - (self.origin[1] + y0 as f64 * self.cell_m));
            }
            if y1 < self.ny - 1 {
                bound = bound.min(self.origin[1] + (y1 + 1) as f64 * self.cell_m - p[1]);
            }
            if best.is_some_and(|b| b.distance_m + MARGIN_M < bound) {
                break;
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
        #[test]
        fn grid_equals_brute_force(line in polyline_strategy(),
                                   qs in prop::collection::vec((-1.0f64..3.0, -1.0f64..3.0), 1..20)) {
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
