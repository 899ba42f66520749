//! The Lanelet2 project's own example map (`mapping_example.osm`, JOSM-drawn Karlsruhe: 64-bit
//! ids, lat/lon, crosswalks, two-way lanelets, regulatory elements, areas), read from
//! `../shared/reference/maps/lanelet2/` like the other reference data.

use std::collections::HashSet;

use cpmx_world::{Map, MapKind, reversed_id};

/// Lanelet relations of the file by a plain reading: (id, subtype, one_way, participant tags).
fn relations(text: &str) -> Vec<(i64, Option<String>, Option<String>, bool)> {
    let doc = roxmltree::Document::parse(text).expect("the example is XML");
    let tag = |n: roxmltree::Node, k: &str| {
        n.children()
            .find(|c| c.has_tag_name("tag") && c.attribute("k") == Some(k))
            .and_then(|c| c.attribute("v"))
            .map(str::to_owned)
    };
    doc.root_element()
        .children()
        .filter(|r| r.has_tag_name("relation") && tag(*r, "type").as_deref() == Some("lanelet"))
        .map(|r| {
            let participants = r.children().any(|c| {
                c.has_tag_name("tag") && c.attribute("k").is_some_and(|k| k.starts_with("participant:"))
            });
            (
                r.attribute("id").and_then(|v| v.parse().ok()).expect("id"),
                tag(r, "subtype"),
                tag(r, "one_way"),
                participants,
            )
        })
        .collect()
}

#[test]
fn the_example_map_loads_with_lanelet2_semantics() {
    let path = cpmx_testdata::reference_file("maps/lanelet2/mapping_example.osm");
    let text = std::fs::read_to_string(&path).expect("the Lanelet2 example map is readable");
    let map = Map::load(&path).expect("the example map loads");
    assert_eq!(map.kind(), MapKind::Generic);
    let ids: HashSet<i64> = map.lanelets().map(|l| l.id).collect();

    // 64-bit ids, as JOSM and the lanelet2 tools write them.
    assert!(ids.contains(&32_215_298_016_831_761));

    let rels = relations(&text);
    let (mut roads, mut two_way, mut skipped) = (0, 0, 0);
    for (id, subtype, one_way, participants) in &rels {
        let for_cars = !participants && matches!(subtype.as_deref(), None | Some("road" | "highway"));
        match subtype.as_deref() {
            Some("crosswalk" | "walkway" | "bicycle_lane") if !participants => {
                assert!(!ids.contains(id), "{subtype:?} {id} is not for cars");
                skipped += 1;
            }
            _ if for_cars => {
                roads += 1;
                assert!(ids.contains(id), "road lanelet {id} is read");
                let reverse = reversed_id(*id);
                if matches!(one_way.as_deref(), Some("no" | "false")) {
                    two_way += 1;
                    let (a, b) = (
                        map.lanelet(*id).expect("forward"),
                        map.lanelet(reverse)
                            .expect("two-way lanelets are read backwards too"),
                    );
                    let back: Vec<_> = a.right_boundary.points.iter().rev().copied().collect();
                    assert_eq!(b.left_boundary.points, back, "{id}");
                } else {
                    assert!(map.lanelet(reverse).is_none(), "one-way {id} is not reversed");
                }
            }
            _ => {}
        }
    }
    assert!(
        roads > 200 && two_way > 10 && skipped > 5,
        "{roads} {two_way} {skipped}"
    );

    // What is not read is said.
    let notes = map.notes().join("\n");
    for what in [
        "regulatory elements",
        "areas (multipolygon)",
        "a vehicle may not pass",
    ] {
        assert!(notes.contains(what), "{notes}");
    }

    // Real-world scale in metres, from the documented projection.
    let b = map.bounds();
    let (w, h) = (b.max_x_m - b.min_x_m, b.max_y_m - b.min_y_m);
    assert!(
        (100.0..5000.0).contains(&w) && (100.0..5000.0).contains(&h),
        "{w} x {h}"
    );
    let widths: Vec<f64> = map
        .lanelets()
        .filter(|l| l.lanelet_types.iter().any(|t| t == "road"))
        .map(|l| {
            let (p, q) = (l.left_boundary.points[0], l.right_boundary.points[0]);
            (p[0] - q[0]).hypot(p[1] - q[1])
        })
        .collect();
    let mean = widths.iter().sum::<f64>() / widths.len() as f64;
    assert!((2.0..6.0).contains(&mean), "mean lane width {mean} m");

    // Reference paths are numbered, and every one has a centre line.
    let paths: Vec<_> = map.reference_paths().collect();
    assert!(paths.len() > 20, "{}", paths.len());
    for p in paths {
        assert!(p.center_line.length_m() > 1.0, "path {}", p.id);
        assert!(p.lanelet_ids.iter().all(|id| ids.contains(id)));
    }
}

#[test]
fn a_user_path_through_a_two_way_lanelet_backwards() {
    let path = cpmx_testdata::reference_file("maps/lanelet2/mapping_example.osm");
    let text = std::fs::read_to_string(&path).expect("the Lanelet2 example map is readable");
    let mut map = Map::load(&path).expect("loads");
    let two_way = relations(&text)
        .into_iter()
        .find(|(id, s, w, p)| {
            !p && s.as_deref() == Some("road") && w.as_deref() == Some("no") && map.lanelet(*id).is_some()
        })
        .expect("a two-way road lanelet")
        .0;
    let back = reversed_id(two_way);
    map.add_reference_path(5000, &[back])
        .expect("a path over the reverse");
    let forward = map.lanelet(two_way).expect("forward").center_line.points.clone();
    let path = map.reference_path(5000).expect("added");
    assert_eq!(path.center_line.points.first(), forward.last());
    assert_eq!(path.center_line.points.last(), forward.first());
}
