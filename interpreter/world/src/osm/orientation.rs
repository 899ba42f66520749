//! A lanelet's driving direction as Lanelet2 sets it when it loads a map (`geometry::align`
//! in `lanelet2_core`): ways are shared between neighbouring lanelets, so their stored order
//! says nothing; Lanelet2 turns the bounds so that the `right` way lies on the right of the
//! `left` one and the `left` way on the left of the `right` one.
//!
//! The rule, step by step as Lanelet2 runs it on the 3D points (x, y, elevation):
//! 1. The left way is inverted unless the middle point of the right way (its point
//!    `len / 2`, or the mean of its ends for two points) lies strictly right of it.
//! 2. The right way is then inverted unless the middle point of the (possibly inverted) left
//!    way lies strictly left of it.
//!
//! "Right of a way" is the sign of the signed distance to the way's closest segment (3D
//! distance, the first of equally close segments), with Lanelet2's correction where the
//! closest point is a segment's end and the next segment turns away. A point on the way counts
//! as neither side, and the way is inverted. A way of one point is never inverted.

/// A point with elevation [m].
pub type Point3 = [f64; 3];

/// Whether each bound has to be inverted: `(left, right)`.
pub fn align(left: &[Point3], right: &[Point3]) -> (bool, bool) {
    if (left.len() <= 1 && right.len() <= 1) || left.is_empty() || right.is_empty() {
        return (false, false);
    }
    let right_of_left = signed_distance(left, middle(right.iter().copied())) < 0.0;
    let invert_left = !right_of_left && left.len() > 1;
    let left_mid = if invert_left {
        middle(left.iter().rev().copied())
    } else {
        middle(left.iter().copied())
    };
    let left_of_right = signed_distance(right, left_mid) > 0.0;
    let invert_right = !left_of_right && right.len() > 1;
    (invert_left, invert_right)
}

/// Lanelet2's middle point of a way.
fn middle(points: impl ExactSizeIterator<Item = Point3> + Clone) -> Point3 {
    let n = points.len();
    if n > 2 {
        points.clone().nth(n / 2).unwrap_or_default()
    } else {
        let mut it = points;
        let first = it.next().unwrap_or_default();
        let last = it.last().unwrap_or(first);
        [
            (first[0] + last[0]) * 0.5,
            (first[1] + last[1]) * 0.5,
            (first[2] + last[2]) * 0.5,
        ]
    }
}

/// Lanelet2's `signedDistance` of `p` to a way: positive on its left.
fn signed_distance(way: &[Point3], p: Point3) -> f64 {
    // The closest segment: the first with the smallest 3D distance (a search that stops at a
    // zero distance); a one-point way is its own segment.
    let mut best: Option<(usize, Point3, f64)> = None;
    let segments = way.len().saturating_sub(1).max(1);
    for i in 0..segments {
        let (a, b) = (way[i], way[(i + 1).min(way.len() - 1)]);
        let q = project(a, b, p);
        let d = norm(sub(q, p));
        if best.is_none_or(|(_, _, bd)| bd > d) {
            best = Some((i, q, d));
        }
        if d == 0.0 {
            break;
        }
    }
    let Some((i, projected, d)) = best else {
        return 0.0;
    };
    let (s1, s2) = (way[i], way[(i + 1).min(way.len() - 1)]);
    let mut is_left = left_of(s1, s2, p);
    // Where the closest point is the segment's end, the next segment may decide.
    if s2 == projected
        && let Some(at) = way.iter().position(|q| *q == s2)
        && let Some(&next) = way.get(at + 1)
        && is_left != left_of(s2, next, p)
        && is_left == left_of(s1, s2, next)
    {
        is_left = !is_left;
    }
    if is_left { d } else { -d }
}

/// Lanelet2's `pointIsLeftOf`: the z of the cross product of the 3D vectors.
fn left_of(a: Point3, b: Point3, p: Point3) -> bool {
    let (u, v) = (sub(b, a), sub(p, a));
    u[0] * v[1] - u[1] * v[0] > 0.0
}

/// The point of segment `a`-`b` closest to `p` (Lanelet2's `projectedPoint`).
fn project(a: Point3, b: Point3, p: Point3) -> Point3 {
    let (v, w) = (sub(b, a), sub(p, a));
    let c1 = dot(w, v);
    if c1 <= 0.0 {
        return a;
    }
    let c2 = dot(v, v);
    if c2 <= c1 {
        return b;
    }
    let t = c1 / c2;
    [v[0] * t + a[0], v[1] * t + a[1], v[2] * t + a[2]]
}

fn sub(a: Point3, b: Point3) -> Point3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: Point3, b: Point3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn norm(a: Point3) -> f64 {
    dot(a, a).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn line(points: &[[f64; 2]]) -> Vec<Point3> {
        points.iter().map(|p| [p[0], p[1], 0.0]).collect()
    }

    #[test]
    fn bounds_are_turned_so_that_left_is_left() {
        let l = line(&[[0.0, 1.0], [5.0, 1.0], [10.0, 1.0]]);
        let r = line(&[[0.0, 0.0], [10.0, 0.0]]);
        let lr: Vec<Point3> = l.iter().rev().copied().collect();
        let rr: Vec<Point3> = r.iter().rev().copied().collect();
        assert_eq!(align(&l, &r), (false, false));
        assert_eq!(align(&lr, &r), (true, false));
        assert_eq!(align(&l, &rr), (false, true));
        // Both stored against the direction the roles give: both inverted.
        assert_eq!(align(&lr, &rr), (true, true));
        // Roles swapped (left way lies right): driven the other way.
        assert_eq!(align(&r, &l), (true, true));
    }

    #[test]
    fn a_point_on_the_way_counts_as_neither_side() {
        let l = line(&[[0.0, 0.0], [10.0, 0.0]]);
        let r = line(&[[2.0, 0.0], [4.0, 0.0]]);
        assert_eq!(align(&l, &r), (true, true));
    }

    proptest! {
        #![proptest_config(ProptestConfig { failure_persistence: None, ..ProptestConfig::default() })]
        /// A lane bent either way, rotated and stored in any order, is driven the way its roles
        /// say: the left way on the left. (The rule is Lanelet2's heuristic: a bend so sharp
        /// that a two-point bound's chord leaves the lane can fool it, in Lanelet2 as here; the
        /// bend is kept below that: a sagitta of at most 2.5 |bend| m against half a lane width
        /// of at least 1 m.)
        #[test]
        fn any_rotated_lane_is_driven_left_on_the_left(
            angle in -3.2f64..3.2, bend in -0.3f64..0.3, width in 2.0f64..5.0,
            flip_left: bool, flip_right: bool, n in 2usize..8,
        ) {
            let (c, s) = (angle.cos(), angle.sin());
            let centre = |t: f64| [10.0 * t, bend * 10.0 * t * t];
            let side = |offset: f64, m: usize| -> Vec<Point3> {
                (0..m).map(|i| {
                    let t = i as f64 / (m - 1) as f64;
                    let [x, y] = centre(t);
                    let (dx, dy) = (10.0f64, 2.0 * bend * 10.0 * t);
                    let len = dx.hypot(dy);
                    let (px, py) = (x - dy / len * offset, y + dx / len * offset);
                    [c * px - s * py, s * px + c * py, 0.0]
                }).collect()
            };
            let (mut l, mut r) = (side(width / 2.0, n), side(-width / 2.0, n + 1));
            if flip_left { l.reverse(); }
            if flip_right { r.reverse(); }
            prop_assert_eq!(align(&l, &r), (flip_left, flip_right));
        }
    }
}
