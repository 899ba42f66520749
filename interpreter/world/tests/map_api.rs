//! The map API on the CPM Lab map: pose along a path, footprints on the road, regions,
//! user-defined paths, and the fast nearest-segment grids against the brute-force rule.

use std::time::Instant;

use cpmx_world::{Map, MapError, PathError, PathSet, Point};

const OSM: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/two_lanes.osm");

fn map() -> Map {
    let map = cpmx_testdata::reference_file("maps/cpm.xml");
    Map::load(&map).unwrap_or_else(|e| panic!("{}: {e}", map.display()))
}

/// Corners of a 0.22 m x 0.107 m car at a pose (front-left, front-right, rear-right, rear-left).
fn footprint(x: f64, y: f64, yaw: f64) -> [Point; 4] {
    let (s, c) = yaw.sin_cos();
    [(0.11, 0.0535), (0.11, -0.0535), (-0.11, -0.0535), (-0.11, 0.0535)]
        .map(|(dx, dy)| [x + dx * c - dy * s, y + dx * s + dy * c])
}

#[test]
fn pose_at_follows_the_centre_line() {
    let map = map();
    let p = map.reference_path(0).expect("path 0");
    let (x, y, yaw) = map.pose_at(0, 0.0).expect("pose");
    assert_eq!([x, y], p.center_line.points[0]);
    assert!((yaw - p.center_line_yaw_rad[0]).abs() < 1e-6);
    let length_m = p.center_line.length_m();
    let a = map.pose_at(0, 0.7).expect("pose");
    let b = map.pose_at(0, 0.7 + length_m).expect("loops wrap");
    assert!((a.0 - b.0).abs() < 1e-9 && (a.1 - b.1).abs() < 1e-9);
    assert!(map.pose_at(99, 0.0).is_none());

    let open = map.with_path_set(PathSet::Intersection).expect("set");
    let len = open.reference_path(3).expect("path").center_line.length_m();
    assert!(open.pose_at(3, len).is_some());
    assert!(open.pose_at(3, len + 0.01).is_none());
    assert!(open.pose_at(3, -0.01).is_none());
}

#[test]
fn footprints_on_and_off_the_road() {
    let map = map();
    for id in map.valid_path_ids() {
        let p = map.reference_path(id).expect("path");
        assert_eq!(p.lane_polygon().len(), 2 * p.center_line.len());
        for s in [0.5, 1.3, 2.9] {
            let (x, y, yaw) = map.pose_at(id, s).expect("pose");
            assert_eq!(
                map.footprint_on_road(id, &footprint(x, y, yaw)),
                Some(true),
                "path {id} s {s}"
            );
            let (sn, cs) = yaw.sin_cos();
            let off = footprint(x - 0.35 * sn, y + 0.35 * cs, yaw);
            assert_eq!(map.footprint_on_road(id, &off), Some(false), "path {id} s {s}");
        }
    }
}

#[test]
fn intersection_region_keeps_paths_through_it() {
    let map = map();
    let region = map.with_region("intersection").expect("region");
    let ids: Vec<i64> = region.lanelets().map(|l| l.id).collect();
    assert_eq!(
        ids.len(),
        8 + 8 * 4,
        "8 incoming lanelets, each with 4 successors"
    );
    assert!(ids.contains(&11) && ids.contains(&72) && !ids.contains(&4));
    let kept = region.valid_path_ids();
    assert!(!kept.is_empty() && kept.len() < 40);
    for id in 0..40 {
        let p = map.reference_path(id).expect("path");
        let through = p.lanelet_ids.iter().any(|l| ids.contains(l));
        assert_eq!(kept.contains(&id), through, "path {id}");
    }
    assert!(region.bounds().max_x_m - region.bounds().min_x_m < 4.5);
    assert!(matches!(
        map.with_region("roundabout"),
        Err(MapError::UnknownRegion { .. })
    ));
}

#[test]
fn user_defined_paths_are_validated() {
    let mut map = map();
    map.add_reference_path(30, &[4, 6, 8]).expect("valid path");
    let p = map.reference_path(30).expect("replaced");
    assert_eq!(p.lanelet_ids, vec![4, 6, 8]);
    assert!(!p.is_loop);
    assert_eq!(
        map.add_reference_path(41, &[4, 8]),
        Err(PathError::NotSuccessor {
            id: 41,
            from: 4,
            to: 8
        })
    );
    assert_eq!(
        map.add_reference_path(41, &[4, 999]),
        Err(PathError::UnknownLanelet { id: 41, lanelet: 999 })
    );
    assert_eq!(map.add_reference_path(41, &[]), Err(PathError::Empty { id: 41 }));
    assert!(map.reference_path(41).is_none());

    let osm = Map::load(OSM).expect("osm");
    assert!(osm.with_path_set(PathSet::Intersection).is_err());
}

#[test]
fn grids_answer_exactly_like_brute_force() {
    let map = map();
    let mut queries = Vec::new();
    for i in 0..46 {
        for j in 0..41 {
            // An irregular lattice over the map and a little beyond it.
            queries.push([
                -0.2 + i as f64 * 0.1 + 0.013 * j as f64,
                -0.2 + j as f64 * 0.1 + 0.007 * i as f64,
            ]);
        }
    }
    for id in (0..40).step_by(3) {
        let index = map.path_index(id).expect("index");
        let p = map.reference_path(id).expect("path");
        for q in &queries {
            assert_eq!(
                index.center_line.nearest_segment(*q),
                p.center_line.nearest_segment(*q)
            );
            assert_eq!(
                index.left_boundary_shared.nearest_segment(*q),
                p.left_boundary_shared.nearest_segment(*q)
            );
            assert_eq!(
                index.right_boundary_shared.nearest_segment(*q),
                p.right_boundary_shared.nearest_segment(*q)
            );
        }
    }

    // Speed on near-lane queries (informative only).
    let p = map.reference_path(1).expect("path");
    let index = map.path_index(1).expect("index");
    let near: Vec<Point> = (0..2000)
        .filter_map(|k| {
            map.pose_at(1, k as f64 * 0.0023)
                .map(|(x, y, _)| [x + 0.03, y - 0.02])
        })
        .collect();
    let t = Instant::now();
    let a: f64 = near
        .iter()
        .map(|q| index.right_boundary_shared.distance_m(*q))
        .sum();
    let grid_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let b: f64 = near.iter().map(|q| p.right_boundary_shared.distance_m(*q)).sum();
    let brute_s = t.elapsed().as_secs_f64();
    assert_eq!(a, b);
    eprintln!(
        "{} queries: grid {grid_s:.2e} s, brute force {brute_s:.2e} s",
        near.len()
    );
}
