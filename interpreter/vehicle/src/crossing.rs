//! SigmaRL's collision test (`interX`, `helper_scenario.py`): two curves collide when a
//! segment of one properly crosses a segment of the other, i.e. the end points of each lie
//! strictly on opposite sides of the other's line. Touching and containment are not
//! collisions. Rectangles are closed curves of their 4 edges.
//!
//! The training environment's collisions and resets, the sim engine's `replace-agent` and the
//! metrics' per-sample collision rates all use these tests.

use crate::Footprint;

/// A point of the map frame [m].
type Point = [f64; 2];

/// `(b - a) x (c - a)`.
#[inline(always)]
fn orient(a: Point, b: Point, c: Point) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

/// Whether segments `s` and `t` cross properly (SigmaRL's strict test).
#[inline(always)]
pub fn cross_properly(s: [Point; 2], t: [Point; 2]) -> bool {
    orient(s[0], s[1], t[0]) * orient(s[0], s[1], t[1]) < 0.0
        && orient(t[0], t[1], s[0]) * orient(t[0], t[1], s[1]) < 0.0
}

/// The 4 closed edges of a rectangle.
#[inline(always)]
fn edges(r: &Footprint) -> [[Point; 2]; 4] {
    [[r[0], r[1]], [r[1], r[2]], [r[2], r[3]], [r[3], r[0]]]
}

/// Axis-aligned box `[min_x, min_y, max_x, max_y]` of some points.
#[inline(always)]
fn bounding_box(points: &[Point]) -> [f64; 4] {
    points.iter().fold(
        [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY],
        |b, p| [b[0].min(p[0]), b[1].min(p[1]), b[2].max(p[0]), b[3].max(p[1])],
    )
}

#[inline(always)]
fn boxes_overlap(a: &[f64; 4], b: &[f64; 4]) -> bool {
    a[0] <= b[2] && b[0] <= a[2] && a[1] <= b[3] && b[1] <= a[3]
}

/// Whether two rectangles' edges cross (SigmaRL's agent-agent collision).
pub fn rectangles_cross(a: &Footprint, b: &Footprint) -> bool {
    if !boxes_overlap(&bounding_box(a), &bounding_box(b)) {
        return false;
    }
    let (ea, eb) = (edges(a), edges(b));
    ea.iter().any(|s| eb.iter().any(|t| cross_properly(*s, *t)))
}

/// Whether a rectangle's edges cross a segment (SigmaRL's entry and exit lines).
pub fn rectangle_crosses_segment(r: &Footprint, segment: [Point; 2]) -> bool {
    if !boxes_overlap(&bounding_box(r), &bounding_box(&segment)) {
        return false;
    }
    edges(r).iter().any(|e| cross_properly(*e, segment))
}

/// Polylines stored as segments with bounding boxes, for crossing tests against rectangles.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Walls {
    segments: Vec<[Point; 2]>,
    boxes: Vec<[f64; 4]>,
}

impl Walls {
    /// The segments of some polylines.
    pub fn new(polylines: &[&Vec<Point>]) -> Self {
        let mut w = Walls::default();
        for line in polylines {
            for pair in line.windows(2) {
                let s = [pair[0], pair[1]];
                w.boxes.push(bounding_box(&s));
                w.segments.push(s);
            }
        }
        w
    }

    /// Whether a rectangle's edges cross any of the polylines.
    pub fn crossed_by(&self, r: &Footprint) -> bool {
        let rb = bounding_box(r);
        let e = edges(r);
        self.segments
            .iter()
            .zip(&self.boxes)
            .filter(|(_, b)| boxes_overlap(&rb, b))
            .any(|(s, _)| e.iter().any(|edge| cross_properly(*edge, *s)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn square(cx: f64, cy: f64, h: f64) -> Footprint {
        [
            [cx + h, cy + h],
            [cx + h, cy - h],
            [cx - h, cy - h],
            [cx - h, cy + h],
        ]
    }

    #[test]
    fn overlapping_squares_cross_but_containment_and_touching_do_not() {
        assert!(rectangles_cross(&square(0.0, 0.0, 1.0), &square(1.5, 0.3, 1.0)));
        assert!(!rectangles_cross(&square(0.0, 0.0, 1.0), &square(0.0, 0.0, 0.5)));
        assert!(!rectangles_cross(&square(0.0, 0.0, 1.0), &square(2.0, 0.0, 1.0)));
        assert!(!rectangles_cross(&square(0.0, 0.0, 1.0), &square(5.0, 0.0, 1.0)));
    }

    #[test]
    fn walls_and_lines() {
        let w = Walls::new(&[&vec![[-5.0, 0.9], [5.0, 0.9]], &vec![[-5.0, -3.0], [5.0, -3.0]]]);
        assert!(w.crossed_by(&square(0.0, 0.0, 1.0)));
        assert!(!w.crossed_by(&square(0.0, -0.2, 1.0)));
        assert!(rectangle_crosses_segment(
            &square(0.0, 0.0, 1.0),
            [[0.0, 0.0], [0.0, 3.0]]
        ));
        assert!(!rectangle_crosses_segment(
            &square(0.0, 0.0, 1.0),
            [[0.0, 0.0], [0.0, 0.5]]
        ));
    }

    proptest! {
        #![proptest_config(ProptestConfig { failure_persistence: None, ..ProptestConfig::default() })]
        /// The bounding-box pruning never changes the answer of the plain all-pairs test.
        #[test]
        fn pruning_agrees_with_all_pairs(ax in -2.0..2.0f64, ay in -2.0..2.0f64, yaw in -4.0..4.0f64,
                                          bx in -2.0..2.0f64, by in -2.0..2.0f64, yaw2 in -4.0..4.0f64) {
            let p = crate::VehicleParams { length_m: 1.5, width_m: 0.7, ..crate::VehicleParams::MU_CAR };
            let a = crate::footprint_corners(&p, ax, ay, yaw);
            let b = crate::footprint_corners(&p, bx, by, yaw2);
            let plain = edges(&a).iter().any(|s| edges(&b).iter().any(|t| cross_properly(*s, *t)));
            prop_assert_eq!(rectangles_cross(&a, &b), plain);
            let line = vec![b[0], b[1], b[2]];
            let walls = Walls::new(&[&line]);
            let plain_walls = edges(&a).iter().any(|s| line.windows(2).any(|t| cross_properly(*s, [t[0], t[1]])));
            prop_assert_eq!(walls.crossed_by(&a), plain_walls);
        }
    }
}
