//! Lane polygons of reference paths and the check whether a vehicle footprint lies on a
//! path's road. Plain f64 geometry; no knowledge of vehicles beyond four corner points.

use crate::ReferencePath;
use crate::polyline::{Point, point_segment_distance};

/// A closed polygon as a ring of points (the last point joins the first implicitly).
pub type Polygon = Vec<Point>;

/// The polygon `left + reversed(right)` of two boundaries.
pub fn band_polygon(left: &[Point], right: &[Point]) -> Polygon {
    left.iter().chain(right.iter().rev()).copied().collect()
}

impl ReferencePath {
    /// The own lane: `left_boundary + reversed(right_boundary)`.
    pub fn lane_polygon(&self) -> Polygon {
        band_polygon(&self.left_boundary.points, &self.right_boundary.points)
    }

    /// The road (shared boundaries): `left_boundary_shared + reversed(right_boundary_shared)`.
    pub fn road_polygon(&self) -> Polygon {
        band_polygon(
            &self.left_boundary_shared.points,
            &self.right_boundary_shared.points,
        )
    }

    /// Whether the rectangle `corners` (in order around it) lies inside the road of this path
    /// (between the shared boundaries): every corner inside the road polygon and no edge of the
    /// rectangle crossing a shared boundary (nor, for open paths, the start or end cap). For a
    /// loop, the polygon is an annulus cut at the start; the cut is not a boundary.
    pub fn footprint_on_road(&self, corners: &[Point; 4]) -> bool {
        let polygon = self.road_polygon();
        if !corners.iter().all(|&c| point_in_polygon(c, &polygon)) {
            return false;
        }
        let left = &self.left_boundary_shared.points;
        let right = &self.right_boundary_shared.points;
        let mut walls: Vec<[Point; 2]> = left
            .windows(2)
            .chain(right.windows(2))
            .map(|w| [w[0], w[1]])
            .collect();
        if !self.is_loop
            && let (Some(&l0), Some(&r0), Some(&l1), Some(&r1)) =
                (left.first(), right.first(), left.last(), right.last())
        {
            walls.push([l0, r0]);
            walls.push([l1, r1]);
        }
        (0..4).all(|i| {
            let edge = [corners[i], corners[(i + 1) % 4]];
            walls.iter().all(|w| !segments_cross(edge, *w))
        })
    }

    /// How far [m] the rectangle `corners` reaches beyond the road of this path: 0 when it lies
    /// on the road ([`ReferencePath::footprint_on_road`]); otherwise the largest distance of a
    /// corner outside the road from the road's outline, or of a boundary point inside the
    /// rectangle from the rectangle's outline (at least the smallest positive number, so that
    /// a footprint off the road is never 0 m off).
    pub fn footprint_off_road_m(&self, corners: &[Point; 4]) -> f64 {
        if self.footprint_on_road(corners) {
            return 0.0;
        }
        let polygon = self.road_polygon();
        let distance_to_ring = |p: Point, ring: &[Point]| {
            (0..ring.len())
                .map(|i| point_segment_distance(p, ring[i], ring[(i + 1) % ring.len()]).0)
                .fold(f64::INFINITY, f64::min)
        };
        let corners_out = corners
            .iter()
            .filter(|&&c| !point_in_polygon(c, &polygon))
            .map(|&c| distance_to_ring(c, &polygon[..]));
        let walls_in = self
            .left_boundary_shared
            .points
            .iter()
            .chain(&self.right_boundary_shared.points)
            .filter(|&&p| point_in_polygon(p, &corners[..]))
            .map(|&p| distance_to_ring(p, &corners[..]));
        corners_out.chain(walls_in).fold(f64::MIN_POSITIVE, f64::max)
    }
}

/// Even-odd point-in-polygon test (points on an edge may go either way).
pub fn point_in_polygon(p: Point, polygon: &[Point]) -> bool {
    let mut inside = false;
    let n = polygon.len();
    for i in 0..n {
        let a = polygon[i];
        let b = polygon[(i + n - 1) % n];
        if (a[1] > p[1]) != (b[1] > p[1]) {
            let x = a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
            if p[0] < x {
                inside = !inside;
            }
        }
    }
    inside
}

/// Whether two segments intersect (touching counts).
pub fn segments_cross(s: [Point; 2], t: [Point; 2]) -> bool {
    let orient = |a: Point, b: Point, c: Point| (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    let on = |a: Point, b: Point, c: Point| {
        c[0] >= a[0].min(b[0]) && c[0] <= a[0].max(b[0]) && c[1] >= a[1].min(b[1]) && c[1] <= a[1].max(b[1])
    };
    let (d1, d2) = (orient(t[0], t[1], s[0]), orient(t[0], t[1], s[1]));
    let (d3, d4) = (orient(s[0], s[1], t[0]), orient(s[0], s[1], t[1]));
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    (d1 == 0.0 && on(t[0], t[1], s[0]))
        || (d2 == 0.0 && on(t[0], t[1], s[1]))
        || (d3 == 0.0 && on(s[0], s[1], t[0]))
        || (d4 == 0.0 && on(s[0], s[1], t[1]))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_contains_its_centre() {
        let sq = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        assert!(point_in_polygon([0.5, 0.5], &sq));
        assert!(!point_in_polygon([1.5, 0.5], &sq));
        assert!(segments_cross([[0.0, 0.0], [1.0, 1.0]], [[0.0, 1.0], [1.0, 0.0]]));
        assert!(!segments_cross(
            [[0.0, 0.0], [1.0, 0.0]],
            [[0.0, 1.0], [1.0, 1.0]]
        ));
    }
}
