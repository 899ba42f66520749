//! Lane violation of one footprint against its reference path's own lane, with the rules of
//! SigmaRL's `get_boundary_violation_timesteps`: a proper crossing of a lane boundary
//! (`interX`, strict signs) or a corner outside the lane polygon `left + reversed(right)`
//! (matplotlib's even-odd `Path.contains_points`).
//!
//! This module owns these two geometric tests. The slack of the paper is applied by the
//! caller, which shrinks the footprint before testing it.

use cpmx_vehicle::Footprint;
use cpmx_world::Point;

/// The own lane of an agent, prepared for the violation test.
#[derive(Debug, Clone, PartialEq)]
pub struct Lane {
    left_m: Vec<Point>,
    right_m: Vec<Point>,
    /// `left` followed by `right` reversed (for loops: a ring with a seam).
    polygon_m: Vec<Point>,
}

impl Lane {
    /// The lane between two boundary polylines (as SigmaRL stores them: both in driving
    /// direction).
    pub fn new(left_m: Vec<Point>, right_m: Vec<Point>) -> Self {
        let polygon_m = left_m.iter().chain(right_m.iter().rev()).copied().collect();
        Self {
            left_m,
            right_m,
            polygon_m,
        }
    }

    /// Whether the footprint violates the lane: its closed outline properly crosses a
    /// boundary, or one of its corners is not inside the lane polygon.
    pub fn is_violated_by(&self, footprint_m: &Footprint) -> bool {
        let outline = [
            footprint_m[0],
            footprint_m[1],
            footprint_m[2],
            footprint_m[3],
            footprint_m[0],
        ];
        interx_intersects(&outline, &self.left_m)
            || interx_intersects(&outline, &self.right_m)
            || !footprint_m.iter().all(|&p| contains_point(&self.polygon_m, p))
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
    for [[x0, y0], [x1, y1]] in edges {
        let (above0, above1) = (y0 >= ty, y1 >= ty);
        if above0 != above1 && (((y1 - ty) * (x0 - x1) >= (x1 - tx) * (y0 - y1)) == above1) {
            inside = !inside;
        }
    }
    inside
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
}
