//! The lanelet2 OSM loader on a small map written for these tests (`tests/data/`).

use cpmx_world::{Adjacent, DrivingDirection, Map, MapError, MapFormat, MapKind};

const OSM: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/two_lanes.osm");

#[test]
fn reads_lanelets_topology_and_paths() {
    let map = Map::load(OSM).expect("loads");
    assert_eq!(map.kind(), MapKind::Generic);
    let ids: Vec<i64> = map.lanelets().map(|l| l.id).collect();
    assert_eq!(ids, vec![100, 101, 102]);

    let a = map.lanelet(100).expect("100");
    assert_eq!(a.left_boundary.points, vec![[0.0, 0.15], [1.0, 0.15]]);
    // Lanelet2's centre line advances one bound at a time (the left first on ties).
    assert_eq!(
        a.center_line.points,
        vec![[0.0, 0.075], [0.5, 0.075], [1.0, 0.075]]
    );
    assert_eq!(a.successors, vec![101]);
    assert_eq!(a.left_line_marking.as_deref(), Some("solid"));
    assert_eq!(a.right_line_marking.as_deref(), Some("dashed"));
    assert_eq!(a.lanelet_types, vec!["road".to_owned()]);
    let same = |id| {
        Some(Adjacent {
            id,
            direction: DrivingDirection::Same,
            lane_change: Some(true),
        })
    };
    assert_eq!(a.adjacent_right, same(102));
    assert_eq!(map.lanelet(102).expect("102").adjacent_left, same(100));

    // Way 13 runs backwards and has 3 nodes: driven inverted (it lies right of the left
    // way); the left boundary keeps its 2 nodes.
    let b = map.lanelet(101).expect("101");
    assert_eq!(b.predecessors, vec![100]);
    assert_eq!(b.right_boundary.points, vec![[1.0, 0.0], [1.5, 0.0], [2.0, 0.0]]);
    assert_eq!(b.left_boundary.points, vec![[1.0, 0.15], [2.0, 0.15]]);
    assert_eq!(b.center_line.len(), 4);

    // Generic numbering: chains from lanelets without predecessors, by id.
    assert_eq!(map.valid_path_ids(), vec![0, 1]);
    let p0 = map.reference_path(0).expect("path 0");
    assert_eq!(p0.lanelet_ids, vec![100, 101]);
    assert!(!p0.is_loop);
    // The lanelets' centre lines joined (3 + 4 points, the joint once).
    assert_eq!(p0.center_line.len(), 6);
    assert!((p0.center_line.length_m() - 2.0).abs() < 1e-12);
    // The road of 100 includes 102 to its right.
    assert_eq!(p0.right_boundary_shared.points[0], [0.0, -0.15]);
    assert_eq!(map.reference_path(1).expect("path 1").lanelet_ids, vec![102]);
}

#[test]
fn projects_lat_lon_without_local_tags() {
    let text = r#"<osm>
      <node id="1" lat="50.0" lon="6.0"/><node id="2" lat="50.0" lon="6.00001"/>
      <node id="3" lat="49.999998" lon="6.0"/><node id="4" lat="49.999998" lon="6.00001"/>
      <way id="10"><nd ref="1"/><nd ref="2"/></way><way id="11"><nd ref="3"/><nd ref="4"/></way>
      <relation id="5"><member type="way" role="left" ref="10"/>
        <member type="way" role="right" ref="11"/><tag k="type" v="lanelet"/></relation>
    </osm>"#;
    let map = Map::from_str(text, MapFormat::Auto).expect("loads");
    let l = map.lanelet(5).expect("5");
    // Node 2 as lanelet2 1.2.3's `UtmProjector(Origin(49.999998, 6.0))` projects it.
    let [x, y] = l.left_boundary.points[1];
    assert!((x - 0.725_425_867).abs() < 1e-6, "{x}");
    assert!((y - 0.193_551_173).abs() < 1e-6, "{y}");
}

#[test]
fn reports_unknown_references_and_bad_coordinates() {
    let text = std::fs::read_to_string(OSM).expect("test map");
    let unknown_node = text.replace("<nd ref=\"16\"/>", "<nd ref=\"99\"/>");
    assert!(matches!(
        Map::from_str(&unknown_node, MapFormat::Auto),
        Err(MapError::UnknownReference { .. })
    ));
    let unknown_way = text.replace("role=\"right\" ref=\"14\"", "role=\"right\" ref=\"98\"");
    assert!(matches!(
        Map::from_str(&unknown_way, MapFormat::Auto),
        Err(MapError::UnknownReference { .. })
    ));
    let bad = text.replace("v=\"1.5\"", "v=\"x\"");
    let Err(MapError::InvalidCoordinate { location, .. }) = Map::from_str(&bad, MapFormat::Auto) else {
        panic!("expected an invalid coordinate")
    };
    assert_eq!(location.line, 15);
    // A CommonRoad file read as OSM is rejected by its root element.
    assert!(matches!(
        Map::from_str("<commonRoad/>", MapFormat::Lanelet2Osm),
        Err(MapError::UnknownFormat { .. })
    ));
}
