//! The nearest segment of a line queried a few hundred times: [`SegmentBoxes`] keeps the
//! bounding box of every run of [`BOX_SEGMENTS`] segments (built in one pass, unlike the
//! [`SegmentGrid`](crate::SegmentGrid) a map keeps for the simulator's hot path), and a query
//! measures only the segments of the boxes that can hold the answer. It returns exactly what
//! [`Polyline::nearest_segment`] returns (distance, segment, projection parameter), as the
//! metrics need for a run's centre lines.
//!
//! Why nothing is lost: a box whose (exact) distance from the point exceeds the best squared
//! distance found so far by a relative [`PRUNE_MARGIN`] and an absolute margin of
//! [`PRUNE_MARGIN_M`] × the coordinates' scale cannot hold a segment whose computed squared
//! distance ties or beats it: the computed distances err by a few ulp of the coordinates, many
//! orders below both margins. Where squares approach underflow (or overflow, or meet NaN) no
//! box is skipped.

use crate::polyline::{Point, Polyline, SegmentDistance, point_segment_distance, squared_distance};

/// Segments per box.
const BOX_SEGMENTS: usize = 16;
/// Relative margin on squared distances before a box is skipped.
const PRUNE_MARGIN: f64 = 1e-6;
/// Absolute margin on distances before a box is skipped, per metre of the coordinates' scale.
const PRUNE_MARGIN_M: f64 = 1e-9;
/// Squared distances below this are too close to underflow to skip a box by.
const SMALLEST_PRUNED: f64 = 1e-250;

/// A polyline with the bounding boxes of its runs of segments.
#[derive(Debug, Clone)]
pub struct SegmentBoxes {
    polyline: Polyline,
    /// Per box: min x, min y, max x, max y of its segments' end points (NaN points left out).
    boxes: Vec<[f64; 4]>,
    /// The largest absolute coordinate of the line.
    scale_m: f64,
}

impl SegmentBoxes {
    /// Boxes `polyline`'s segments.
    pub fn new(polyline: Polyline) -> Self {
        let segments = polyline.segment_count();
        let boxes = (0..segments.div_ceil(BOX_SEGMENTS))
            .map(|b| {
                let last_point = ((b + 1) * BOX_SEGMENTS).min(segments);
                polyline.points[b * BOX_SEGMENTS..=last_point].iter().fold(
                    [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY],
                    |[x0, y0, x1, y1], p| [x0.min(p[0]), y0.min(p[1]), x1.max(p[0]), y1.max(p[1])],
                )
            })
            .collect();
        let scale_m = polyline
            .points
            .iter()
            .flat_map(|p| [p[0].abs(), p[1].abs()])
            .fold(0.0, f64::max);
        Self {
            polyline,
            boxes,
            scale_m,
        }
    }

    /// The polyline.
    pub fn polyline(&self) -> &Polyline {
        &self.polyline
    }

    /// Nearest segment to `p`, identical to [`Polyline::nearest_segment`].
    pub fn nearest_segment(&self, p: Point) -> Option<SegmentDistance> {
        let points = &self.polyline.points;
        if points.len() < 2 {
            return None;
        }
        let scale_m = self.scale_m.max(p[0].abs()).max(p[1].abs());
        let absolute = (PRUNE_MARGIN_M * scale_m).powi(2);
        // Whether box `b` is provably farther than `squared` (and the numbers are safe).
        let beyond = |b: usize, squared: f64| {
            let lower = box_squared_distance(&self.boxes[b], p);
            lower >= SMALLEST_PRUNED && lower > squared * (1.0 + PRUNE_MARGIN) + absolute
        };
        let segments_of = |b: usize| b * BOX_SEGMENTS..((b + 1) * BOX_SEGMENTS).min(points.len() - 1);
        let squared = |s: usize| squared_distance(p, points[s], points[s + 1]);

        // The smallest squared distance, from the box nearest the point outward.
        let nearest_box = self
            .boxes
            .iter()
            .map(|b| box_squared_distance(b, p))
            .enumerate()
            .min_by(|(_, a), (_, b)| a.total_cmp(b))
            .map_or(0, |(b, _)| b);
        let mut smallest = segments_of(nearest_box)
            .map(squared)
            .fold(f64::INFINITY, f64::min);
        for b in (0..self.boxes.len()).filter(|&b| b != nearest_box) {
            if !beyond(b, smallest) {
                smallest = segments_of(b).map(squared).fold(smallest, f64::min);
            }
        }

        // The candidates within 1e-9 of it, measured with `hypot` in order; the first segment
        // always starts the search (Polyline::nearest_segment's rules).
        let bound = smallest * (1.0 + 1e-9) + f64::MIN_POSITIVE;
        let (distance_m, t) = point_segment_distance(p, points[0], points[1]);
        let mut best = SegmentDistance {
            distance_m,
            segment: 0,
            t,
        };
        for b in (0..self.boxes.len()).filter(|&b| !beyond(b, bound)) {
            for segment in segments_of(b).filter(|&s| s > 0 && squared(s) <= bound) {
                let (distance_m, t) = point_segment_distance(p, points[segment], points[segment + 1]);
                if distance_m < best.distance_m {
                    best = SegmentDistance {
                        distance_m,
                        segment,
                        t,
                    };
                }
            }
        }
        Some(best)
    }

    /// Unsigned distance from `p` to the polyline (infinite for fewer than two points).
    pub fn distance_m(&self, p: Point) -> f64 {
        self.nearest_segment(p).map_or(f64::INFINITY, |d| d.distance_m)
    }
}

/// The squared distance from `p` to a box (zero inside; NaN for a NaN point).
fn box_squared_distance(&[x0, y0, x1, y1]: &[f64; 4], p: Point) -> f64 {
    let dx = (x0 - p[0]).max(p[0] - x1).max(0.0);
    let dy = (y0 - p[1]).max(p[1] - y1).max(0.0);
    if p[0].is_nan() || p[1].is_nan() {
        return f64::NAN;
    }
    dx * dx + dy * dy
}

#[cfg(test)]
mod tests {
    use super::*;

    proptest::proptest! {
        /// Random polylines (repeated points make ties; long ones make many boxes) and points,
        /// NaN included, at scales from near underflow to near overflow: the boxes answer as
        /// the plain search, bit for bit.
        #[test]
        fn the_boxes_answer_as_the_plain_search(
            points in proptest::collection::vec((-40i32..40, -40i32..40), 0..120),
            scale in proptest::sample::select(vec![1.0, 0.01, 1e-160, 1e-140, 1e100, 1e155]),
            p in (-50.0..50.0f64, -50.0..50.0f64),
            nan in proptest::bool::weighted(0.05),
            nan_point in proptest::option::weighted(0.05, 0usize..120),
        ) {
            let mut points: Vec<Point> =
                points.iter().map(|&(x, y)| [f64::from(x) * scale, f64::from(y) * scale]).collect();
            if let Some(i) = nan_point.filter(|&i| i < points.len()) {
                points[i][0] = f64::NAN;
            }
            let line = Polyline::new(points);
            let p = if nan { [f64::NAN, p.1] } else { [p.0 * scale, p.1 * scale] };
            let boxes = SegmentBoxes::new(line.clone());
            let got = boxes.nearest_segment(p);
            let want = line.nearest_segment(p);
            proptest::prop_assert_eq!(got.map(|d| d.segment), want.map(|d| d.segment));
            proptest::prop_assert_eq!(
                got.map(|d| (d.distance_m.to_bits(), d.t.to_bits())),
                want.map(|d| (d.distance_m.to_bits(), d.t.to_bits()))
            );
        }

        /// Points along a smooth line (a circle sampled finely, as centre lines are), near
        /// and on it: the same answers.
        #[test]
        fn the_boxes_answer_as_the_plain_search_along_a_smooth_line(
            n in 20usize..400,
            radius_m in 0.5..5.0f64,
            angle in 0.0..std::f64::consts::TAU,
            offset_m in -0.3..0.3f64,
        ) {
            let line = Polyline::new(
                (0..n)
                    .map(|i| {
                        let a = i as f64 / n as f64 * std::f64::consts::TAU;
                        [2.0 + radius_m * a.cos(), 1.5 + radius_m * a.sin()]
                    })
                    .collect(),
            );
            let p = [2.0 + (radius_m + offset_m) * angle.cos(), 1.5 + (radius_m + offset_m) * angle.sin()];
            let boxes = SegmentBoxes::new(line.clone());
            proptest::prop_assert_eq!(boxes.nearest_segment(p), line.nearest_segment(p));
        }
    }

    #[test]
    fn short_lines_have_no_segment_or_one() {
        assert_eq!(
            SegmentBoxes::new(Polyline::new(vec![])).nearest_segment([0.0, 0.0]),
            None
        );
        assert_eq!(
            SegmentBoxes::new(Polyline::new(vec![[1.0, 1.0]])).distance_m([0.0, 0.0]),
            f64::INFINITY
        );
        let one = SegmentBoxes::new(Polyline::new(vec![[0.0, 0.0], [2.0, 0.0]]));
        assert_eq!(one.distance_m([1.0, 0.5]), 0.5);
    }
}
