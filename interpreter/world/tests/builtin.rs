//! The built-in map `stdlib:intersection`: geometry a 1:18 car can drive, documented numbering.

use cpmx_world::builtin::{LANE_WIDTH_M, MAX_SPACING_M, builtin_names};
use cpmx_world::polyline::dist;
use cpmx_world::{Map, MapError, MapKind, Point};

/// Smallest turning radius of the car: wheelbase 0.15 m, steering 31 deg [m].
fn min_radius_m() -> f64 {
    0.15 / 31f64.to_radians().tan()
}

/// Curvature of the circle through three points [1/m].
fn curvature(a: Point, b: Point, c: Point) -> f64 {
    let cross = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    2.0 * cross.abs() / (dist(a, b) * dist(b, c) * dist(a, c))
}

#[test]
fn twelve_drivable_paths_with_distinct_ends() {
    assert!(builtin_names().contains(&"intersection"));
    let map = Map::builtin("intersection").expect("builds");
    assert_eq!(map.kind(), MapKind::Builtin("intersection"));
    assert_eq!(map.valid_path_ids(), (0..12).collect::<Vec<_>>());
    let mut ends = Vec::new();
    for p in map.reference_paths() {
        let n = p.center_line.len();
        for line in [
            &p.left_boundary,
            &p.right_boundary,
            &p.left_boundary_shared,
            &p.right_boundary_shared,
        ] {
            assert_eq!(line.len(), n, "path {}: equal point counts", p.id);
        }
        // Continuous, points at most 5 cm apart on every polyline.
        for line in [&p.center_line, &p.left_boundary, &p.left_boundary_shared] {
            for w in line.points.windows(2) {
                let d = dist(w[0], w[1]);
                assert!(d > 0.0 && d <= MAX_SPACING_M + 1e-12, "path {}: gap {d}", p.id);
            }
        }
        // Curvature within the car's limit; right turns no tighter than 0.3 m.
        for w in p.center_line.points.windows(3) {
            let k = curvature(w[0], w[1], w[2]);
            assert!(k <= 1.0 / 0.3 + 1e-6, "path {}: curvature {k}", p.id);
            assert!(k < 1.0 / min_radius_m());
        }
        // Own lane 0.15 m wide everywhere; the road adds the oncoming lane on the left.
        for i in 0..n {
            let (l, r, c) = (
                p.left_boundary.points[i],
                p.right_boundary.points[i],
                p.center_line.points[i],
            );
            assert!(
                (dist(l, r) - LANE_WIDTH_M).abs() < 1e-9,
                "path {} point {i}",
                p.id
            );
            assert!((dist(c, p.left_boundary_shared.points[i]) - 1.5 * LANE_WIDTH_M).abs() < 1e-9);
            assert_eq!(p.right_boundary_shared.points[i], r);
        }
        assert!(!p.is_loop);
        assert_eq!(p.lanelet_ids.len(), 3);
        let key = |q: Point| ((q[0] * 1e6).round() as i64, (q[1] * 1e6).round() as i64);
        ends.push((key(p.center_line.points[0]), key(p.center_line.points[n - 1])));
    }
    let mut unique = ends.clone();
    unique.sort();
    unique.dedup();
    assert_eq!(unique.len(), 12, "distinct start/end pairs");
}

#[test]
fn numbering_and_region() {
    let map = Map::builtin("intersection").expect("builds");
    // Path 1 = from the north, straight on: starts at the top heading south.
    let (x, y, yaw) = map.pose_at(1, 0.0).expect("pose");
    assert!((x - (1.65 - 0.075)).abs() < 1e-12 && (y - 3.3).abs() < 1e-12);
    assert!((yaw + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    // Path 0 = from the north, turning right: leaves heading west.
    let p0 = map.reference_path(0).expect("path 0");
    let end = p0.center_line.points[p0.center_line.len() - 1];
    assert!((end[0] - 0.0).abs() < 1e-9 && (end[1] - (1.65 + 0.075)).abs() < 1e-9);
    let region = map.with_region("intersection").expect("region");
    assert_eq!(region.valid_path_ids().len(), 12);
    assert_eq!(region.lanelets().count(), 16);
    assert!(matches!(
        Map::builtin("roundabout"),
        Err(MapError::UnknownBuiltin(_))
    ));
}
