//! Lane violation of one footprint against its reference path's own lane, with the rules of
//! SigmaRL's `get_boundary_violation_timesteps`: a proper crossing of a lane boundary
//! (`interX`, strict signs) or a corner outside the lane polygon `left + reversed(right)`
//! (matplotlib's even-odd `Path.contains_points`).
//!
//! This module owns these two geometric tests. The slack of the paper is applied by the
//! caller, which shrinks the footprint before testing it.
//!
//! A lane is a whole reference path (hundreds of points) and a footprint is tested every step,
//! so the boundaries and the polygon are cut into blocks of [`BLOCK_SEGMENTS`] segments with
//! their bounding boxes: a block whose box misses the footprint's cannot hold a crossing, and a
//! block entirely above or below a corner cannot flip its even-odd count. Skipping them gives
//! the answer of the full tests exactly.

use cpmx_vehicle::Footprint;
use cpmx_world::Point;

/// Segments per block of a boundary or of the lane polygon.
pub const BLOCK_SEGMENTS: usize = 16;

/// The own lane of an agent, prepared for the violation test.
#[derive(Debug, Clone, PartialEq)]
pub struct Lane {
    left_m: Blocked,
    right_m: Blocked,
    /// `left` followed by `right` reversed, closed (its first point repeated at the end; for
    /// loops: a ring with a seam).
    ring_m: Blocked,
}

/// A polyline cut into blocks of [`BLOCK_SEGMENTS`] segments, each with its bounding box.
#[derive(Debug, Clone, PartialEq)]
struct Blocked {
    points: Vec<Point>,
    /// `[x_min, x_max, y_min, y_max]` of each block's points.
    boxes: Vec<[f64; 4]>,
}

impl Blocked {
    fn new(points: Vec<Point>) -> Self {
        let boxes = (0..points.len().saturating_sub(1))
            .step_by(BLOCK_SEGMENTS)
            .map(|start| bounding_box(&points[start..points.len().min(start + BLOCK_SEGMENTS + 1)]))
            .collect();
        Self { points, boxes }
    }

    /// The points of each block (consecutive blocks share an end point) with its box.
    fn blocks(&self) -> impl Iterator<Item = (&[Point], &[f64; 4])> {
        self.boxes.iter().enumerate().map(|(b, bounds)| {
            let start = b * BLOCK_SEGMENTS;
            (
                &self.points[start..self.points.len().min(start + BLOCK_SEGMENTS + 1)],
                bounds,
            )
        })
    }
}

/// The footprint's closed outline (its first corner repeated at the end).
fn outline(footprint_m: &Footprint) -> [Point; 5] {
    [
        footprint_m[0],
        footprint_m[1],
        footprint_m[2],
        footprint_m[3],
        footprint_m[0],
    ]
}

fn bounding_box(points: &[Point]) -> [f64; 4] {
    points.iter().fold(
        [f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY],
        |[x0, x1, y0, y1], &[x, y]| [x0.min(x), x1.max(x), y0.min(y), y1.max(y)],
    )
}

impl Lane {
    /// The lane between two boundary polylines (as SigmaRL stores them: both in driving
    /// direction).
    pub fn new(left_m: Vec<Point>, right_m: Vec<Point>) -> Self {
        let mut ring_m: Vec<Point> = left_m.iter().chain(right_m.iter().rev()).copied().collect();
        if let Some(&first) = ring_m.first() {
            ring_m.push(first);
        }
        Self {
            left_m: Blocked::new(left_m),
            right_m: Blocked::new(right_m),
            ring_m: Blocked::new(ring_m),
        }
    }

    /// Whether the footprint violates the lane: its closed outline properly crosses a
    /// boundary, or one of its corners is not inside the lane polygon.
    pub fn is_violated_by(&self, footprint_m: &Footprint) -> bool {
        let outline = outline(footprint_m);
        let [x_min, x_max, y_min, y_max] = bounding_box(&outline);
        // A box that misses the outline's (false for NaN, which then takes the full test).
        let misses = |b: &[f64; 4]| b[1] < x_min || b[0] > x_max || b[3] < y_min || b[2] > y_max;
        let crosses = |boundary: &Blocked| {
            boundary
                .blocks()
                .any(|(points, bounds)| !misses(bounds) && interx_intersects(&outline, points))
        };
        crosses(&self.left_m) || crosses(&self.right_m) || !footprint_m.iter().all(|&p| self.contains(p))
    }

    /// [`contains_point`] on the lane polygon, skipping the blocks that lie entirely at or above
    /// the point's height or entirely below it (none of their edges flips the count).
    fn contains(&self, p: Point) -> bool {
        let [tx, ty] = p;
        if !(tx.is_finite() && ty.is_finite()) || self.ring_m.points.is_empty() {
            return false;
        }
        let mut inside = false;
        for (points, bounds) in self.ring_m.blocks() {
            if bounds[2] >= ty || bounds[3] < ty {
                continue;
            }
            for w in points.windows(2) {
                inside ^= flips(w[0], w[1], tx, ty);
            }
        }
        inside
    }
}

/// SigmaRL's `interX` (after MATLAB's InterX): whether a segment of `a` and a segment of `b`
/// cross, each segment's end points lying strictly on opposite sides of the other's line
/// (touching or collinear segments do not count).
pub fn interx_intersects(a: &[Point], b: &[Point]) -> bool {
    for sa in a.windows(2) {
        let (dxa, dya) = (sa[1][0] - sa[0][0], sa[1][1] - sa[0][1]);
        let s_a = dxa * sa[0][1] - dya * sa[0][0];
        // Side of each point of `b` with respect to the line of segment `sa`.
        let side_a = |p: Point| dxa * p[1] - dya * p[0] - s_a;
        for sb in b.windows(2) {
            if side_a(sb[0]) * side_a(sb[1]) >= 0.0 {
                continue;
            }
            let (dxb, dyb) = (sb[1][0] - sb[0][0], sb[1][1] - sb[0][1]);
            let s_b = dxb * sb[0][1] - dyb * sb[0][0];
            let side_b = |p: Point| p[1] * dxb - p[0] * dyb - s_b;
            if side_b(sa[0]) * side_b(sa[1]) < 0.0 {
                return true;
            }
        }
    }
    false
}

/// matplotlib's `Path.contains_points` (radius 0) for one point: the even-odd crossing test
/// of a +x ray against every edge of the implicitly closed polygon, with matplotlib's
/// tie-breaking (`y >= ty` is "above").
pub fn contains_point(polygon_m: &[Point], p: Point) -> bool {
    let [tx, ty] = p;
    if !(tx.is_finite() && ty.is_finite()) || polygon_m.is_empty() {
        return false;
    }
    let closing = [polygon_m[polygon_m.len() - 1], polygon_m[0]];
    let edges = polygon_m
        .windows(2)
        .map(|w| [w[0], w[1]])
        .chain(std::iter::once(closing));
    let mut inside = false;
    for [a, b] in edges {
        inside ^= flips(a, b, tx, ty);
    }
    inside
}

/// Whether the edge `a`–`b` crosses the +x ray from `(tx, ty)` (matplotlib's rule).
#[inline]
fn flips([x0, y0]: Point, [x1, y1]: Point, tx: f64, ty: f64) -> bool {
    let (above0, above1) = (y0 >= ty, y1 >= ty);
    above0 != above1 && (((y1 - ty) * (x0 - x1) >= (x1 - tx) * (y0 - y1)) == above1)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> Vec<Point> {
        vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
    }

    #[test]
    fn points_inside_and_outside_a_square() {
        assert!(contains_point(&square(), [0.5, 0.5]));
        assert!(!contains_point(&square(), [1.5, 0.5]));
        assert!(!contains_point(&square(), [0.5, -0.1]));
    }

    #[test]
    fn crossing_is_strict() {
        let a = [[0.0, 0.0], [1.0, 1.0]];
        assert!(interx_intersects(&a, &[[0.0, 1.0], [1.0, 0.0]]));
        // Touching at an end point is not a crossing.
        assert!(!interx_intersects(&a, &[[1.0, 1.0], [2.0, 0.0]]));
        assert!(!interx_intersects(&a, &[[0.0, 0.5], [0.2, 0.8]]));
    }

    #[test]
    fn a_footprint_in_a_straight_lane() {
        let lane = Lane::new(
            vec![[0.0, 0.075], [2.0, 0.075]],
            vec![[0.0, -0.075], [2.0, -0.075]],
        );
        let fp = |dy: f64| {
            [
                [1.11, 0.0535 + dy],
                [1.11, -0.0535 + dy],
                [0.89, -0.0535 + dy],
                [0.89, 0.0535 + dy],
            ]
        };
        assert!(!lane.is_violated_by(&fp(0.0)));
        assert!(lane.is_violated_by(&fp(0.03)));
        assert!(lane.is_violated_by(&fp(0.5)));
    }

    /// The full tests, without blocks.
    fn violated_without_blocks(left: &[Point], right: &[Point], footprint_m: &Footprint) -> bool {
        let polygon: Vec<Point> = left.iter().chain(right.iter().rev()).copied().collect();
        let outline = outline(footprint_m);
        interx_intersects(&outline, left)
            || interx_intersects(&outline, right)
            || !footprint_m.iter().all(|&p| contains_point(&polygon, p))
    }

    proptest::proptest! {
        /// Footprints anywhere around a winding lane of 150 points: the blocked test answers as
        /// the full one.
        #[test]
        fn blocks_answer_as_the_full_tests(
            x in -0.5..6.5f64,
            y in -2.0..2.0f64,
            yaw in -3.2..3.2f64,
            half_length in 0.01..0.3f64,
        ) {
            let centre = |k: usize| {
                let s = k as f64 * 0.04;
                [s, (s * 1.7).sin() * 1.2]
            };
            let normal = |k: usize| {
                let s = k as f64 * 0.04;
                let slope = 1.7 * 1.2 * (s * 1.7).cos();
                let n = 1.0 / (1.0 + slope * slope).sqrt();
                [-slope * n, n]
            };
            let side = |sign: f64| -> Vec<Point> {
                (0..150)
                    .map(|k| {
                        let ([cx, cy], [nx, ny]) = (centre(k), normal(k));
                        [cx + sign * 0.15 * nx, cy + sign * 0.15 * ny]
                    })
                    .collect()
            };
            let (left, right) = (side(1.0), side(-1.0));
            let (c, s) = (yaw.cos(), yaw.sin());
            let half_width = 0.05;
            let corner = |l: f64, w: f64| [x + l * c - w * s, y + l * s + w * c];
            let footprint: Footprint = [
                corner(half_length, half_width),
                corner(half_length, -half_width),
                corner(-half_length, -half_width),
                corner(-half_length, half_width),
            ];
            let lane = Lane::new(left.clone(), right.clone());
            proptest::prop_assert_eq!(
                lane.is_violated_by(&footprint),
                violated_without_blocks(&left, &right, &footprint)
            );
        }
    }
}
