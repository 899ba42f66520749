//! Reference-path geometry prepared for the per-step queries of observations and baselines:
//! polylines stored as blocks of segments, each block with a bounding box, so that SigmaRL's
//! nearest-segment search over a whole path only measures the few blocks near the query
//! point, with the same result as measuring every segment. Built once per run, never per step.

use std::sync::Arc;

use cpmx_world::{Point, Polyline, ReferencePath};

/// Segments per block (two 256-bit vectors of float32).
const BLOCK: usize = 16;

/// How far (in metres) a block's bounding box is grown. A segment's float32 distance differs from the
/// exact distance by a few float32 ulps of the coordinates (under 1e-6 m on maps of a few
/// metres), far below this margin: a segment in a block whose grown box is farther from the
/// query point than some measured distance cannot attain (or tie) the minimum.
const BOX_MARGIN_M: f32 = 1e-3;

/// Relative slack on the same comparison, for query points far from the map, where the
/// round-off of the squared distances grows with their size.
const BOX_SLACK: f32 = 1.0 + 1e-4;

/// A polyline as float32 blocks of segment starts and directions, with a bounding box per block.
///
/// Queries repeat SigmaRL's `get_perpendicular_distances` in float32 with torch's operation
/// order (projection `dot / |v|^2`, clamp, closest point `start + v t`, norm), because which
/// segment wins a near-tie (a point on a vertex) decides the short-term reference points.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Segments {
    /// Blocks of [`BLOCK`] segments; the last one is padded with NaN segments, which never
    /// attain a minimum.
    blocks: Vec<Block>,
    /// Bounding box `[min_x, min_y, max_x, max_y]` of each block, grown by [`BOX_MARGIN_M`].
    boxes: Vec<[f32; 4]>,
    /// Number of segments.
    len: usize,
}

/// [`BLOCK`] segments, component-major.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Block {
    start_x: [f32; BLOCK],
    start_y: [f32; BLOCK],
    dir_x: [f32; BLOCK],
    dir_y: [f32; BLOCK],
    /// `|dir|^2` (0 for a degenerate segment, which then measures the distance to its start).
    len2: [f32; BLOCK],
}

impl Block {
    /// A block of NaN segments.
    const EMPTY: Block = Block {
        start_x: [f32::NAN; BLOCK],
        start_y: [f32::NAN; BLOCK],
        dir_x: [f32::NAN; BLOCK],
        dir_y: [f32::NAN; BLOCK],
        len2: [f32::NAN; BLOCK],
    };

    /// Squared distances from `(px, py)` to the block's segments (float32, torch's order;
    /// NaN for padding).
    #[inline(always)]
    fn distances2(&self, px: f32, py: f32) -> [f32; BLOCK] {
        let mut d2 = [0.0f32; BLOCK];
        for (i, d) in d2.iter_mut().enumerate() {
            let (vx, vy) = (self.dir_x[i], self.dir_y[i]);
            let dot = (px - self.start_x[i]) * vx + (py - self.start_y[i]) * vy;
            let len2 = self.len2[i];
            let t = if len2 > 0.0 {
                (dot / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let (ex, ey) = (self.start_x[i] + vx * t - px, self.start_y[i] + vy * t - py);
            *d = ex * ex + ey * ey;
        }
        d2
    }

    /// Smallest squared distance from `(px, py)` to the block's segments (the minimum is
    /// exact, so the order of comparisons does not matter).
    #[inline(always)]
    fn min_distance2(&self, px: f32, py: f32) -> f32 {
        self.distances2(px, py)
            .into_iter()
            .fold(f32::INFINITY, |best, d2| if d2 < best { d2 } else { best })
    }
}

/// Squared distance from `(px, py)` to a box (0 inside, and for a NaN point, which is never
/// pruned).
#[inline(always)]
fn box_distance2(b: &[f32; 4], px: f32, py: f32) -> f32 {
    let dx = (b[0] - px).max(px - b[2]).max(0.0);
    let dy = (b[1] - py).max(py - b[3]).max(0.0);
    dx * dx + dy * dy
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
    /// Segment blocks of a polyline (empty for fewer than two points).
    pub fn new(line: &Polyline) -> Self {
        let mut s = Segments::default();
        for (i, pair) in line.points.windows(2).enumerate() {
            let (ax, ay) = (pair[0][0] as f32, pair[0][1] as f32);
            let (dx, dy) = (pair[1][0] as f32 - ax, pair[1][1] as f32 - ay);
            let (b, lane) = (i / BLOCK, i % BLOCK);
            if lane == 0 {
                s.blocks.push(Block::EMPTY);
                s.boxes
                    .push([f32::INFINITY, f32::INFINITY, f32::NEG_INFINITY, f32::NEG_INFINITY]);
            }
            let block = &mut s.blocks[b];
            block.start_x[lane] = ax;
            block.start_y[lane] = ay;
            block.dir_x[lane] = dx;
            block.dir_y[lane] = dy;
            block.len2[lane] = dx * dx + dy * dy;
            let bx = &mut s.boxes[b];
            for (x, y) in [(ax, ay), (ax + dx, ay + dy)] {
                *bx = [
                    bx[0].min(x - BOX_MARGIN_M),
                    bx[1].min(y - BOX_MARGIN_M),
                    bx[2].max(x + BOX_MARGIN_M),
                    bx[3].max(y + BOX_MARGIN_M),
                ];
            }
            s.len += 1;
        }
        s
    }

    /// Number of segments.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether there is no segment.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Nearest segment to `p` with SigmaRL's rule (the first one on ties), or `None` when empty.
    pub fn nearest(&self, p: Point) -> Option<Nearest> {
        let (px, py) = (p[0] as f32, p[1] as f32);
        let best2 = self.min_distance2(px, py);
        let best = best2.sqrt();
        // Ties are decided on the rounded distances, as torch compares them: the first segment
        // whose distance rounds to the minimum, in the blocks that can hold one.
        let segment = self
            .blocks
            .iter()
            .zip(&self.boxes)
            .enumerate()
            .filter(|(_, (_, bx))| !self.prunes(bx, px, py, best2))
            .find_map(|(b, (block, _))| {
                let d2 = block.distances2(px, py);
                d2.iter()
                    .position(|d2| d2.sqrt() <= best)
                    .map(|lane| b * BLOCK + lane)
            })?;
        Some(Nearest {
            distance_m: f64::from(best),
            segment,
        })
    }

    /// Unsigned distance from `p` to the polyline (infinite when empty).
    pub fn distance_m(&self, p: Point) -> f64 {
        f64::from(self.min_distance2(p[0] as f32, p[1] as f32).sqrt())
    }

    /// Whether the block with box `bx` holds no segment whose distance can reach `best2`.
    #[inline(always)]
    fn prunes(&self, bx: &[f32; 4], px: f32, py: f32, best2: f32) -> bool {
        box_distance2(bx, px, py) > best2 * BOX_SLACK
    }

    /// Smallest squared distance over all segments, measuring only the blocks that can hold
    /// it: first the block with the nearest box, then every block whose box is not farther
    /// than the best distance so far. The square root is monotone and correctly rounded, so
    /// taking it once at the end gives the same value as the minimum of the distances.
    fn min_distance2(&self, px: f32, py: f32) -> f32 {
        // The block whose box is nearest (the first on ties; block 0 if the point is NaN).
        let (first, _) = self
            .boxes
            .iter()
            .enumerate()
            .fold((0, f32::INFINITY), |(bi, bd), (i, bx)| {
                let d = box_distance2(bx, px, py);
                if d < bd { (i, d) } else { (bi, bd) }
            });
        let Some(block) = self.blocks.get(first) else {
            return f32::INFINITY;
        };
        let mut best2 = block.min_distance2(px, py);
        for (i, (block, bx)) in self.blocks.iter().zip(&self.boxes).enumerate() {
            if i != first && !self.prunes(bx, px, py, best2) {
                let d2 = block.min_distance2(px, py);
                best2 = if d2 < best2 { d2 } else { best2 };
            }
        }
        best2
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
///
/// Paths are shared (`Arc`), so that a caller holding many sets of agents on the same few
/// paths (the training environments, which re-assign paths at every reset) prepares each
/// path once and swaps pointers.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AgentPaths {
    /// One prepared path per agent.
    pub paths: Vec<Arc<PreparedPath>>,
}

impl AgentPaths {
    /// Prepare one reference path per agent (agent `i` follows `paths[i]`).
    pub fn new<'a>(paths: impl IntoIterator<Item = &'a ReferencePath>) -> Self {
        AgentPaths {
            paths: paths
                .into_iter()
                .map(|p| Arc::new(PreparedPath::new(p)))
                .collect(),
        }
    }

    /// Agents on already prepared paths (agent `i` follows `paths[i]`).
    pub fn from_shared(paths: Vec<Arc<PreparedPath>>) -> Self {
        AgentPaths { paths }
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
