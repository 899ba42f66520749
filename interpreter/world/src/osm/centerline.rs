//! A lanelet's centre line as Lanelet2 computes it (`calculateCenterline` in
//! `lanelet2_core/src/Lanelet.cpp`), so that reference paths on Lanelet2 maps have the lengths
//! Lanelet2 gives (cpmx's tests compare them with the `lanelet2` package to 1e-6 m).
//!
//! The centre line starts at the midpoint of the bounds' first points. Then, repeatedly, each
//! bound proposes its point (after its current one) closest to the other bound's current point
//! whose connection is clean: the segment from the last centre point to the new midpoint
//! crosses neither bound nor the entry or exit line outward, and the connection between the two
//! bound points crosses neither bound elsewhere. The closer proposal (half the distance between
//! the bound points; the left one on ties) advances its bound and adds the midpoint. When
//! neither bound can propose, the midpoint of the last points ends the line.

use crate::polyline::{Point, dist};

/// Lanelet2's centre line between two bounds (both at least one point, in driving direction).
/// `same_start` says whether both bounds start at the same node.
pub fn centerline(left: &[Point], right: &[Point], same_start: bool) -> Vec<Point> {
    let (Some(&l0), Some(&r0)) = (left.first(), right.first()) else {
        return Vec::new();
    };
    let bounds = BoundChecker::new(left, right);
    let mut center = vec![mid(l0, r0)];
    let (mut lc, mut rc) = (0usize, 0usize);
    if same_start && left.len() > 1 {
        lc = 1;
    }
    loop {
        let last = center[center.len() - 1];
        let left_candidate = closest_clean_point(&bounds, Side::Left, lc + 1, right[rc], last);
        let right_candidate = closest_clean_point(&bounds, Side::Right, rc + 1, left[lc], last);
        match (left_candidate, right_candidate) {
            (Some((l, ld)), r) if r.is_none_or(|(_, rd)| ld <= rd) => {
                center.push(mid(left[l], right[rc]));
                lc = l;
            }
            (_, Some((r, _))) => {
                center.push(mid(left[lc], right[r]));
                rc = r;
            }
            _ => break,
        }
    }
    if !(lc + 1 == left.len() && rc + 1 == right.len()) {
        center.push(mid(left[left.len() - 1], right[right.len() - 1]));
    }
    center
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Side {
    Left,
    Right,
}

/// Lanelet2's `findClosestNonintersectingPoint`: the point of `side`'s bound at index `from`
/// or later that is closest to `other` and connects cleanly, with half its distance to `other`.
fn closest_clean_point(
    bounds: &BoundChecker,
    side: Side,
    from: usize,
    other: Point,
    last: Point,
) -> Option<(usize, f64)> {
    let points = bounds.points(side);
    // Every point by its distance to `other`, as Lanelet2's nearest-neighbour query visits them.
    let mut order: Vec<(f64, usize)> = points
        .iter()
        .enumerate()
        .map(|(i, &p)| (squared(p, other), i))
        .collect();
    order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let d_last_other = dist(other, last);
    let mut best: Option<(usize, f64)> = None;
    for (_, i) in order {
        if i < from {
            continue;
        }
        let candidate = points[i];
        let half_m = dist(candidate, other) / 2.0;
        if let Some((_, best_m)) = best {
            // No later point can be closer (triangle inequality).
            if dist(other, candidate) / 2.0 - d_last_other > best_m {
                break;
            }
            if best_m <= half_m {
                continue;
            }
        }
        let connection = [other, candidate];
        let centre_step = [last, mid(other, candidate)];
        if !bounds.intersects(centre_step)
            && !bounds.second_crosses(connection, side)
            && !bounds.second_crosses([candidate, other], side.other())
        {
            best = Some((i, half_m));
        }
    }
    best
}

impl Side {
    fn other(self) -> Side {
        match self {
            Side::Left => Side::Right,
            Side::Right => Side::Left,
        }
    }
}

/// Lanelet2's `BoundChecker`: the segments of both bounds, the entry line (first right point
/// to first left point) and the exit line (last left point to last right point).
struct BoundChecker<'a> {
    left: &'a [Point],
    right: &'a [Point],
    entry: [Point; 2],
    exit: [Point; 2],
}

impl<'a> BoundChecker<'a> {
    fn new(left: &'a [Point], right: &'a [Point]) -> Self {
        let entry = [right[0], left[0]];
        let exit = [left[left.len() - 1], right[right.len() - 1]];
        Self {
            left,
            right,
            entry,
            exit,
        }
    }

    fn points(&self, side: Side) -> &'a [Point] {
        match side {
            Side::Left => self.left,
            Side::Right => self.right,
        }
    }

    /// Whether `seg` meets a bound segment that does not start at `seg`'s start, or crosses the
    /// entry or exit line ending outside.
    fn intersects(&self, seg: [Point; 2]) -> bool {
        let meets_bound = |points: &[Point]| {
            points
                .windows(2)
                .any(|s| segments_intersect([s[0], s[1]], seg) && s[0] != seg[0])
        };
        meets_bound(self.left)
            || meets_bound(self.right)
            || (segments_intersect(seg, self.entry) && left_of(self.entry[0], self.entry[1], seg[1]))
            || (segments_intersect(seg, self.exit) && left_of(self.exit[0], self.exit[1], seg[1]))
    }

    /// Whether `seg` meets a segment of `side`'s bound that does not touch `seg`'s end.
    fn second_crosses(&self, seg: [Point; 2], side: Side) -> bool {
        self.points(side)
            .windows(2)
            .any(|s| segments_intersect([s[0], s[1]], seg) && s[0] != seg[1] && s[1] != seg[1])
    }
}

fn mid(a: Point, b: Point) -> Point {
    [(a[0] + b[0]) * 0.5, (a[1] + b[1]) * 0.5]
}

fn squared(a: Point, b: Point) -> f64 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)
}

/// The sign of the turn `a` -> `b` -> `p`: positive when `p` lies left of `a`-`b`.
fn orientation(a: Point, b: Point, p: Point) -> f64 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

fn left_of(a: Point, b: Point, p: Point) -> bool {
    orientation(a, b, p) > 0.0
}

/// Whether two closed segments share a point (touching and overlapping count), as
/// `boost::geometry::intersects` decides it.
fn segments_intersect(a: [Point; 2], b: [Point; 2]) -> bool {
    let (d1, d2) = (orientation(b[0], b[1], a[0]), orientation(b[0], b[1], a[1]));
    let (d3, d4) = (orientation(a[0], a[1], b[0]), orientation(a[0], a[1], b[1]));
    let opposite = |x: f64, y: f64| (x > 0.0 && y < 0.0) || (x < 0.0 && y > 0.0);
    if opposite(d1, d2) && opposite(d3, d4) {
        return true;
    }
    let within = |s: [Point; 2], p: Point| {
        p[0] >= s[0][0].min(s[1][0])
            && p[0] <= s[0][0].max(s[1][0])
            && p[1] >= s[0][1].min(s[1][1])
            && p[1] <= s[0][1].max(s[1][1])
    };
    (d1 == 0.0 && within(b, a[0]))
        || (d2 == 0.0 && within(b, a[1]))
        || (d3 == 0.0 && within(a, b[0]))
        || (d4 == 0.0 && within(a, b[1]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::polyline::Polyline;
    use proptest::prelude::*;

    #[test]
    fn equal_bounds_give_the_pointwise_mean() {
        let l = [[0.0, 1.0], [1.0, 1.0], [2.0, 1.0]];
        let r = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]];
        let c = centerline(&l, &r, false);
        // Each point advances one bound: the left first on ties.
        assert_eq!(
            c,
            vec![[0.0, 0.5], [0.5, 0.5], [1.0, 0.5], [1.5, 0.5], [2.0, 0.5]]
        );
    }

    #[test]
    fn a_dense_bound_is_walked_point_by_point() {
        let l: Vec<Point> = (0..=10).map(|i| [f64::from(i), 2.0]).collect();
        let r = [[0.0, 0.0], [10.0, 0.0]];
        let c = centerline(&l, &r, false);
        assert_eq!(c.first(), Some(&[0.0, 1.0]));
        assert_eq!(c.last(), Some(&[10.0, 1.0]));
        let len_m = Polyline::new(c).length_m();
        assert!((len_m - 10.0).abs() < 1e-9, "{len_m}");
    }

    #[test]
    fn segments_touching_overlapping_and_apart() {
        let s = |a: [f64; 2], b: [f64; 2]| [a, b];
        assert!(segments_intersect(
            s([0.0, 0.0], [2.0, 2.0]),
            s([0.0, 2.0], [2.0, 0.0])
        ));
        assert!(segments_intersect(
            s([0.0, 0.0], [1.0, 0.0]),
            s([1.0, 0.0], [1.0, 1.0])
        ));
        assert!(segments_intersect(
            s([0.0, 0.0], [2.0, 0.0]),
            s([1.0, 0.0], [3.0, 0.0])
        ));
        assert!(!segments_intersect(
            s([0.0, 0.0], [1.0, 0.0]),
            s([2.0, 0.0], [3.0, 0.0])
        ));
        assert!(!segments_intersect(
            s([0.0, 0.0], [1.0, 0.0]),
            s([0.0, 1.0], [1.0, 1.0])
        ));
    }

    proptest! {
        #![proptest_config(ProptestConfig { failure_persistence: None, ..ProptestConfig::default() })]
        /// On any smooth lane the centre line runs from the first midpoint to the last, each
        /// of its points the midpoint of a left and a right bound point.
        #[test]
        fn starts_and_ends_at_the_bounds_midpoints(
            bend in -0.3f64..0.3, width in 0.5f64..5.0, nl in 2usize..12, nr in 2usize..12,
        ) {
            let side = |offset: f64, m: usize| -> Vec<Point> {
                (0..m).map(|i| {
                    let t = i as f64 / (m - 1) as f64;
                    let (x, y) = (10.0 * t, bend * 10.0 * t * t);
                    let (dx, dy) = (10.0f64, 2.0 * bend * 10.0 * t);
                    let len = dx.hypot(dy);
                    [x - dy / len * offset, y + dx / len * offset]
                }).collect()
            };
            let (l, r) = (side(width / 2.0, nl), side(-width / 2.0, nr));
            let c = centerline(&l, &r, false);
            prop_assert_eq!(c.first().copied(), Some(mid(l[0], r[0])));
            prop_assert_eq!(c.last().copied(), Some(mid(l[nl - 1], r[nr - 1])));
            for p in &c {
                prop_assert!(l.iter().any(|a| r.iter().any(|b| mid(*a, *b) == *p)));
            }
            prop_assert!(c.len() < nl + nr);
        }
    }
}
