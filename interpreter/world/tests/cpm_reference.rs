//! Reference agreement: the CPM Lab map read from SigmaRL's `cpm.xml` must give SigmaRL's
//! lanelets and all 72 reference paths (40 + 24 + 4 + 4) of `cpm_reference_paths.json`.
//! The reference files are read in place (never copied); a missing file fails the test.

use cpmx_world::{DrivingDirection, Map, PathSet, Polyline};
use serde_json::Value;

/// The tolerance for every coordinate [m].
const TOLERANCE_M: f64 = 1e-9;
/// The README's tolerance for `center_line_yaw` [rad].
const YAW_TOLERANCE_RAD: f64 = 1.2e-7;

fn reference() -> Value {
    let text = cpmx_testdata::read_reference("maps/cpm_reference_paths.json");
    serde_json::from_str(&text).expect("reference JSON")
}

fn map() -> Map {
    let map = cpmx_testdata::reference_file("maps/cpm.xml");
    Map::load(&map).unwrap_or_else(|e| panic!("{}: {e}", map.display()))
}

/// A JSON coordinate: the shortest decimal of a float32, so round it back to that float32.
fn f32_value(v: &Value) -> f64 {
    f64::from(v.as_f64().expect("number") as f32)
}

/// Largest coordinate difference between a polyline and a JSON list of points; panics on a
/// different point count.
fn max_diff(what: &str, ours: &Polyline, json: &Value) -> f64 {
    let json = json.as_array().expect("points");
    assert_eq!(ours.len(), json.len(), "{what}: point count");
    ours.points
        .iter()
        .zip(json)
        .map(|(p, q)| {
            let q = q.as_array().expect("point");
            (p[0] - f32_value(&q[0]))
                .abs()
                .max((p[1] - f32_value(&q[1])).abs())
        })
        .fold(0.0, f64::max)
}

fn ids(v: &Value) -> Vec<i64> {
    v.as_array()
        .expect("ids")
        .iter()
        .map(|x| x.as_i64().expect("id"))
        .collect()
}

#[test]
fn all_72_reference_paths_match_sigmarl() {
    let reference = reference();
    let map = map();
    assert!(map.is_cpm_lab(), "cpm.xml must be recognised as the CPM Lab map");
    assert_eq!(map.benchmark_id(), Some("C-ZAM_AC-1_1_T-1"));
    let sets = [
        (PathSet::Entire, "reference_paths", 40),
        (PathSet::Intersection, "reference_paths_intersection", 24),
        (PathSet::MergeIn, "reference_paths_merge_in", 4),
        (PathSet::MergeOut, "reference_paths_merge_out", 4),
    ];
    let (mut worst_m, mut worst_yaw_rad, mut checked) = (0.0f64, 0.0f64, 0);
    for (set, key, count) in sets {
        let map = map.with_path_set(set).expect("path set");
        let json = reference[key].as_array().expect(key);
        assert_eq!(json.len(), count, "{key}");
        assert_eq!(map.valid_path_ids(), (0..count).collect::<Vec<_>>(), "{key}");
        for p in json {
            let index = p["index"].as_u64().expect("index") as usize;
            let ours = map.reference_path(index).expect("path exists");
            let what = format!("{key}[{index}]");
            assert_eq!(ours.id, index);
            assert_eq!(ours.lanelet_ids, ids(&p["lanelet_ids"]), "{what} lanelets");
            assert_eq!(
                ours.is_loop,
                p["is_loop"].as_bool().expect("is_loop"),
                "{what} is_loop"
            );
            for (name, line) in [
                ("center_line", &ours.center_line),
                ("left_boundary", &ours.left_boundary),
                ("right_boundary", &ours.right_boundary),
                ("left_boundary_shared", &ours.left_boundary_shared),
                ("right_boundary_shared", &ours.right_boundary_shared),
            ] {
                let d = max_diff(&format!("{what}.{name}"), line, &p[name]);
                assert!(d <= TOLERANCE_M, "{what}.{name}: max difference {d} m");
                worst_m = worst_m.max(d);
            }
            let yaw = p["center_line_yaw"].as_array().expect("yaw");
            assert_eq!(ours.center_line_yaw_rad.len(), yaw.len(), "{what} yaw count");
            for (a, b) in ours.center_line_yaw_rad.iter().zip(yaw) {
                let d = (a - f32_value(b)).rem_euclid(std::f64::consts::TAU);
                let d = d.min(std::f64::consts::TAU - d);
                assert!(d <= YAW_TOLERANCE_RAD, "{what} yaw off by {d} rad");
                worst_yaw_rad = worst_yaw_rad.max(d);
            }
            checked += 1;
        }
    }
    assert_eq!(checked, 72);
    eprintln!("72 paths: worst coordinate difference {worst_m:e} m, worst yaw {worst_yaw_rad:e} rad");
}

#[test]
fn lanelets_match_sigmarl_parse() {
    let reference = reference();
    let map = map();
    let json = reference["lanelets"].as_array().expect("lanelets");
    let ours: Vec<_> = map.lanelets().collect();
    assert_eq!(ours.len(), json.len());
    for (l, j) in ours.iter().zip(json) {
        let what = format!("lanelet {}", l.id);
        assert_eq!(l.id, j["id"].as_i64().expect("id"), "{what}");
        for (name, line) in [
            ("left_boundary", &l.left_boundary),
            ("right_boundary", &l.right_boundary),
            ("center_line", &l.center_line),
        ] {
            assert_eq!(max_diff(&what, line, &j[name]), 0.0, "{what}.{name}");
        }
        assert_eq!(
            l.left_line_marking.as_deref(),
            j["left_line_marking"].as_str(),
            "{what}"
        );
        assert_eq!(
            l.right_line_marking.as_deref(),
            j["right_line_marking"].as_str(),
            "{what}"
        );
        assert_eq!(l.predecessors, ids(&j["predecessor"]), "{what} predecessors");
        assert_eq!(l.successors, ids(&j["successor"]), "{what} successors");
        for (ours, name) in [
            (l.adjacent_left, "adjacent_left"),
            (l.adjacent_right, "adjacent_right"),
        ] {
            let theirs = &j[name];
            match ours {
                None => assert!(theirs.is_null(), "{what}.{name}"),
                Some(a) => {
                    assert_eq!(a.id, theirs["id"].as_i64().expect("id"), "{what}");
                    let dir = match a.direction {
                        DrivingDirection::Same => "same",
                        DrivingDirection::Opposite => "opposite",
                    };
                    assert_eq!(Some(dir), theirs["drivingDirection"].as_str(), "{what}");
                }
            }
        }
        // SigmaRL looks for a `lanelet_type` child while the file writes `<laneletType>`, so
        // its dump has null everywhere; we read the file's value.
        assert!(j["lanelet_type"].is_null());
        assert_eq!(l.lanelet_types.len(), 1, "{what} type");
    }
}

#[test]
fn intersection_matches_sigmarl_parse() {
    let reference = reference();
    let map = map();
    let json = reference["intersection_info"]
        .as_array()
        .expect("intersection_info");
    let [intersection] = map.intersections() else {
        panic!("one intersection expected");
    };
    assert_eq!(intersection.id, 105);
    assert_eq!(intersection.incomings.len(), json.len());
    for (i, j) in intersection.incomings.iter().zip(json) {
        assert_eq!(
            i.incoming_lanelets,
            vec![j["incomingLanelet"].as_i64().expect("id")]
        );
        assert_eq!(
            i.successors_right,
            vec![j["successorsRight"].as_i64().expect("id")]
        );
        assert_eq!(i.successors_straight, ids(&j["successorsStraight"]));
        assert_eq!(i.successors_left, vec![j["successorsLeft"].as_i64().expect("id")]);
    }
    let b = map.bounds();
    assert_eq!((b.min_x_m, b.max_x_m, b.min_y_m, b.max_y_m), (0.0, 4.5, 0.0, 4.0));
}

/// SigmaRL 1.2.0 joined each path's shared boundaries as it joined the own ones (a piece loses
/// its first point, no blend where the lanes beside the path change, loops not re-closed): its
/// paths have SigmaRL 1.5.0's centre lines and own boundaries, and shared boundaries shorter by
/// the blends' extra points. Point counts as SigmaRL 1.2.0's own parser gives them.
#[test]
fn sigmarl_1_2_0_joins_shared_boundaries_like_the_own_ones() {
    let blended = map();
    let joined = map().with_shared_join(cpmx_world::SharedJoin::LikeOwn).unwrap();
    for (id, left, right) in [(0, 177, 169), (1, 127, 123), (3, 127, 123), (5, 145, 141)] {
        let (a, b) = (
            blended.reference_path(id).unwrap(),
            joined.reference_path(id).unwrap(),
        );
        assert_eq!(a.center_line, b.center_line);
        assert_eq!(
            (a.left_boundary.clone(), a.right_boundary.clone()),
            (b.left_boundary.clone(), b.right_boundary.clone())
        );
        assert_eq!(
            (b.left_boundary_shared.len(), b.right_boundary_shared.len()),
            (left, right),
            "path {id}"
        );
        // Where SigmaRL 1.5.0 re-closes a loop, 1.2.0's ends stay the 0.15 m lane apart.
        if a.right_boundary_shared.len() == b.right_boundary_shared.len() + 8 {
            let p = &b.right_boundary_shared.points;
            let gap = (p[0][0] - p[p.len() - 1][0]).hypot(p[0][1] - p[p.len() - 1][1]);
            assert!((gap - 0.15).abs() < 1e-3, "path {id}: ends {gap} m apart");
        }
    }
    // Every other path keeps its number.
    assert_eq!(
        joined.reference_paths().count(),
        blended.reference_paths().count()
    );
}
