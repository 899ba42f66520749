//! Polylines and the distance queries SigmaRL uses on them (`get_perpendicular_distances`).

/// A point in the map frame [m].
pub type Point = [f64; 2];

/// An ordered list of points; segment `i` joins point `i` and point `i + 1`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Polyline {
    /// The points, in order.
    pub points: Vec<Point>,
}

/// The result of a nearest-segment query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentDistance {
    /// Unsigned distance to the polyline [m].
    pub distance_m: f64,
    /// Index of the first segment that attains the minimum.
    pub segment: usize,
    /// Projection parameter on that segment, clamped to [0, 1].
    pub t: f64,
}

impl SegmentDistance {
    /// SigmaRL's "closest point index": the end point of the nearest segment.
    pub fn closest_point_index(&self) -> usize {
        self.segment + 1
    }
}

impl Polyline {
    /// A polyline through `points`.
    pub fn new(points: Vec<Point>) -> Self {
        Self { points }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether it has no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Number of segments.
    pub fn segment_count(&self) -> usize {
        self.points.len().saturating_sub(1)
    }

    /// Nearest segment to `p` (the first one on ties), or `None` for fewer than two points.
    ///
    /// The distances are `hypot`s (SigmaRL's norm). Only the segments whose squared distance
    /// comes within a relative 1e-9 of the smallest can attain the smallest `hypot` (the two
    /// differ by a few ulp), so only those are measured with it: the answer of measuring every
    /// segment, at a fraction of the cost.
    pub fn nearest_segment(&self, p: Point) -> Option<SegmentDistance> {
        let squared = |pair: &[Point]| squared_distance(p, pair[0], pair[1]);
        let smallest = self.points.windows(2).map(squared).fold(f64::INFINITY, f64::min);
        let bound = smallest * (1.0 + 1e-9) + f64::MIN_POSITIVE;
        let mut best: Option<SegmentDistance> = None;
        for (segment, pair) in self.points.windows(2).enumerate() {
            // The first segment always starts the search, as when every segment is measured
            // (it stays the answer when every distance is NaN).
            let candidate = squared(pair) <= bound; // false for NaN
            if segment > 0 && !candidate {
                continue;
            }
            let (distance_m, t) = point_segment_distance(p, pair[0], pair[1]);
            if best.is_none_or(|b| distance_m < b.distance_m) {
                best = Some(SegmentDistance {
                    distance_m,
                    segment,
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

    /// Total length [m].
    pub fn length_m(&self) -> f64 {
        self.points.windows(2).map(|w| dist(w[0], w[1])).sum()
    }

    /// Length along the polyline from the projection of `p` (on its nearest segment) to the
    /// last point [m]; infinite for fewer than two points.
    pub fn remaining_m(&self, p: Point) -> f64 {
        let Some(nearest) = self.nearest_segment(p) else {
            return f64::INFINITY;
        };
        let (a, b) = (self.points[nearest.segment], self.points[nearest.segment + 1]);
        let rest: f64 = self.points[nearest.segment + 1..]
            .windows(2)
            .map(|w| dist(w[0], w[1]))
            .sum();
        dist(a, b) * (1.0 - nearest.t) + rest
    }
}

/// The squared distance from `p` to the segment `a`–`b`, as [`Polyline::nearest_segment`]
/// ranks segments before it measures the closest with `hypot`.
#[inline]
pub(crate) fn squared_distance(p: Point, a: Point, b: Point) -> f64 {
    let q = projection(p, a, b).0;
    let (dx, dy) = (p[0] - q[0], p[1] - q[1]);
    dx * dx + dy * dy
}

/// Distance from `p` to the segment `a`–`b` and the projection parameter clamped to [0, 1].
/// A degenerate segment (a == b) measures the distance to `a`.
pub fn point_segment_distance(p: Point, a: Point, b: Point) -> (f64, f64) {
    let (q, t) = projection(p, a, b);
    (dist(p, q), t)
}

/// The point of the segment `a`–`b` nearest to `p` and its parameter clamped to [0, 1].
#[inline]
fn projection(p: Point, a: Point, b: Point) -> (Point, f64) {
    let ab = [b[0] - a[0], b[1] - a[1]];
    let ap = [p[0] - a[0], p[1] - a[1]];
    let len2 = ab[0] * ab[0] + ab[1] * ab[1];
    let t = if len2 > 0.0 {
        ((ap[0] * ab[0] + ap[1] * ab[1]) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    ([a[0] + t * ab[0], a[1] + t * ab[1]], t)
}

/// Euclidean distance between two points.
pub fn dist(a: Point, b: Point) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_segment_reports_the_end_point_as_closest_index() {
        let line = Polyline::new(vec![[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]);
        let d = line.nearest_segment([1.5, 0.3]).unwrap();
        assert_eq!(d.segment, 1);
        assert_eq!(d.closest_point_index(), 2);
        assert!((d.distance_m - 0.3).abs() < 1e-12);
    }

    #[test]
    fn what_remains_is_measured_along_the_line() {
        let line = Polyline::new(vec![[0.0, 0.0], [1.0, 0.0], [1.0, 2.0]]);
        assert!((line.remaining_m([0.25, 0.1]) - 2.75).abs() < 1e-12);
        assert!((line.remaining_m([1.2, 1.5]) - 0.5).abs() < 1e-12);
        assert_eq!(line.remaining_m([1.0, 3.0]), 0.0);
        assert_eq!(
            Polyline::new(vec![[0.0, 0.0]]).remaining_m([0.0, 0.0]),
            f64::INFINITY
        );
    }

    /// Every segment measured with `hypot`, the first minimum kept.
    fn nearest_by_measuring_every_segment(line: &Polyline, p: Point) -> Option<SegmentDistance> {
        let mut best: Option<SegmentDistance> = None;
        for (segment, pair) in line.points.windows(2).enumerate() {
            let (distance_m, t) = point_segment_distance(p, pair[0], pair[1]);
            if best.is_none_or(|b| distance_m < b.distance_m) {
                best = Some(SegmentDistance {
                    distance_m,
                    segment,
                    t,
                });
            }
        }
        best
    }

    proptest::proptest! {
        /// Random polylines (with repeated points, so ties happen) and points, NaN included:
        /// the candidates' search answers as measuring every segment, bit for bit.
        #[test]
        fn the_nearest_segment_is_the_one_measuring_every_segment_finds(
            points in proptest::collection::vec((-3i32..3, -3i32..3), 0..40),
            scale in proptest::sample::select(vec![1.0, 0.1, 1e-160, 1e155]),
            p in (-4.0..4.0f64, -4.0..4.0f64),
            nan in proptest::bool::weighted(0.05),
        ) {
            let line = Polyline::new(
                points.iter().map(|&(x, y)| [f64::from(x) * scale, f64::from(y) * scale]).collect(),
            );
            let p = if nan { [f64::NAN, p.1] } else { [p.0 * scale, p.1 * scale] };
            let got = line.nearest_segment(p);
            let want = nearest_by_measuring_every_segment(&line, p);
            proptest::prop_assert_eq!(got.map(|d| d.segment), want.map(|d| d.segment));
            proptest::prop_assert_eq!(
                got.map(|d| (d.distance_m.to_bits(), d.t.to_bits())),
                want.map(|d| (d.distance_m.to_bits(), d.t.to_bits()))
            );
        }
    }

    #[test]
    fn ties_go_to_the_first_segment() {
        let line = Polyline::new(vec![[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]);
        assert_eq!(line.nearest_segment([1.0, 1.0]).unwrap().segment, 0);
    }
}
