//! Maps as the tools write them: a JOSM-style lanelet2 map with negative ids, two-way
//! lanelets, a crosswalk, regulatory elements and areas; CommonRoad 2020a and 2018b scenarios as
//! the benchmark ships them (obstacles, planning problem, traffic signs and lights); and broken
//! variants of both and of the Lanelet2 example map, each with a located diagnostic. No
//! mutation or truncation makes a loader panic.

use cpmx_world::{Map, MapError, MapFormat, SourceLocation, reversed_id};
use proptest::prelude::*;

/// A JOSM-style lanelet2 map (lat/lon, negative ids of new elements): lanelet -10 continues
/// into -11 (two-way, `one_way=no`); -12 is a crosswalk over -11; a traffic light regulatory
/// element and a parking area.
const JOSM: &str = include_str!("data/formats/josm-negative-ids.osm");

/// A CommonRoad 2020a scenario as the benchmark writes them: large ids, a road of two
/// lanelets with a sidewalk beside it and a crosswalk over it, an intersection with a
/// crossing, a traffic sign and light, obstacles and a planning problem.
const COMMONROAD: &str = include_str!("data/formats/commonroad-2020a.xml");

fn load(text: &str) -> Result<Map, MapError> {
    Map::from_str(text, MapFormat::Auto)
}

/// The 1-based line where `needle` first occurs (the `nth`, 0-based, occurrence).
fn line_of(text: &str, needle: &str, nth: usize) -> u32 {
    let at = text.match_indices(needle).nth(nth).expect("needle").0;
    text[..at].matches('\n').count() as u32 + 1
}

/// The location of an error, for the error kinds that have one.
fn location(e: &MapError) -> SourceLocation {
    match e {
        MapError::NotXml { location, .. }
        | MapError::UnknownFormat { location, .. }
        | MapError::InvalidCoordinate { location, .. }
        | MapError::BoundaryLengthMismatch { location, .. }
        | MapError::TooFewPoints { location, .. }
        | MapError::UnknownReference { location, .. }
        | MapError::Malformed { location, .. } => *location,
        other => panic!("no location: {other}"),
    }
}

#[test]
fn josm_map_with_negative_ids_and_lanelet2_semantics() {
    let map = load(JOSM).expect("loads");
    let ids: Vec<i64> = map.lanelets().map(|l| l.id).collect();
    let back = reversed_id(-11);
    assert_eq!(back, 10);
    // The crosswalk is not driven; the two-way lanelet is read both ways.
    assert_eq!(ids, vec![-10, -11, back]);
    assert_eq!(map.lanelet(-10).expect("-10").successors, vec![-11]);
    assert_eq!(map.lanelet(back).expect("back").successors, Vec::<i64>::new());
    assert_eq!(map.lanelet(back).expect("back").predecessors, Vec::<i64>::new());
    // Lat/lon projected as lanelet2's `UtmProjector` at the south-west corner (lat 48.99999,
    // lon 8.4) projects them: nodes -4 and -5 (lanelet -10's left bound), as lanelet2 1.2.3
    // gives them.
    let l = map.lanelet(-10).expect("-10");
    for (got, want) in l
        .left_boundary
        .points
        .iter()
        .zip([[0.035_143_924, 4.446_576_536], [7.349_336_677, 4.388_772_945]])
    {
        assert!(
            (got[0] - want[0]).abs() < 1e-6 && (got[1] - want[1]).abs() < 1e-6,
            "{:?}",
            l.left_boundary
        );
    }
    // Paths: the chain -10 -> -11, then the reverse on its own.
    let paths: Vec<Vec<i64>> = map.reference_paths().map(|p| p.lanelet_ids.clone()).collect();
    assert_eq!(paths, vec![vec![-10, -11], vec![back]]);
    let notes = map.notes().join("\n");
    for what in [
        "1 lanelets a vehicle may not pass skipped (Lanelet2's German rules: crosswalks, walkways, bicycle or bus lanes): -12",
        "1 two-way lanelets",
        "1 regulatory elements",
        "1 regulatory_element members",
        "1 areas (multipolygon) skipped",
    ] {
        assert!(notes.contains(what), "{what}: {notes}");
    }
}

#[test]
fn commonroad_2020a_scenario_reads_the_road_and_ignores_the_rest() {
    let map = load(COMMONROAD).expect("loads");
    assert_eq!(map.benchmark_id(), Some("DEU_Test-1_1_T-1"));
    let ids: Vec<i64> = map.lanelets().map(|l| l.id).collect();
    assert_eq!(
        ids,
        vec![50195, 50196],
        "the crosswalk and the sidewalk are not driven"
    );
    assert_eq!(map.lanelet(50195).expect("50195").adjacent_right, None);
    let paths: Vec<Vec<i64>> = map.reference_paths().map(|p| p.lanelet_ids.clone()).collect();
    assert_eq!(paths, vec![vec![50195, 50196]]);
    assert_eq!(
        map.region_lanelets("intersection-50400"),
        Some(&[50195, 50196][..])
    );
    assert_eq!(
        map.notes(),
        [
            "1 static obstacles ignored",
            "1 dynamic obstacles ignored",
            "1 planning problems ignored",
            "1 traffic signs ignored",
            "1 traffic lights ignored",
            "2 lanelets not for vehicles skipped (sidewalks, crosswalks, bicycle lanes): 50197, 50198",
        ]
    );
}

/// A CommonRoad 2018b scenario as the benchmark shipped them: obstacles in `<obstacle>` with
/// a `<role>`, no intersections, traffic signs or lights.
const COMMONROAD_2018B: &str = include_str!("data/formats/commonroad-2018b.xml");

#[test]
fn commonroad_2018b_scenario_reads_the_road_and_counts_its_obstacles() {
    let map = load(COMMONROAD_2018B).expect("loads");
    assert_eq!(map.benchmark_id(), Some("USA_Test-1_1_T-1"));
    let paths: Vec<Vec<i64>> = map.reference_paths().map(|p| p.lanelet_ids.clone()).collect();
    assert_eq!(paths, vec![vec![100, 101]]);
    assert_eq!(
        map.notes(),
        [
            "1 static obstacles ignored",
            "1 dynamic obstacles ignored",
            "1 planning problems ignored",
        ]
    );
}

/// Each damage gives its typed error on the line that is damaged.
#[test]
fn broken_maps_give_located_diagnostics() {
    // A way with one node.
    let one_node = JOSM.replacen(
        "    <nd ref='-5' />\n    <tag k='type' v='line_thin' />\n    <tag k='subtype' v='solid' />",
        "    <tag k='type' v='line_thin' />",
        1,
    );
    let e = load(&one_node).expect_err("one-node way");
    assert!(
        matches!(
            e,
            MapError::TooFewPoints {
                lanelet: -10,
                count: 1,
                ..
            }
        ),
        "{e}"
    );
    assert_eq!(location(&e).line, line_of(&one_node, "<way id='-20'", 0));

    // Dangling references: a way to a node, a lanelet to a way, a CommonRoad successor.
    let text = JOSM.replacen("<nd ref='-6' />", "<nd ref='-99' />", 1);
    let e = load(&text).expect_err("unknown node");
    assert!(
        matches!(e, MapError::UnknownReference { .. }) && e.to_string().contains("unknown node -99"),
        "{e}"
    );
    assert_eq!(location(&e).line, line_of(&text, "<nd ref='-99'", 0));
    let text = JOSM.replacen("ref='-23' role='right'", "ref='-98' role='right'", 1);
    let e = load(&text).expect_err("unknown way");
    assert!(
        e.to_string().contains("lanelet -11 refers to unknown way -98"),
        "{e}"
    );
    assert_eq!(location(&e).line, line_of(&text, "ref='-98'", 0));
    let text = COMMONROAD.replacen("<successor ref=\"50196\"/>", "<successor ref=\"70000\"/>", 1);
    let e = load(&text).expect_err("unknown successor");
    assert!(e.to_string().contains("unknown lanelet 70000"), "{e}");
    assert_eq!(location(&e).line, line_of(&text, "<successor ref=\"70000\"", 0));

    // Duplicate ids: node, way, relation, CommonRoad lanelet; located at the second one.
    for (from, to, what, nth) in [
        ("<node id='-9'", "<node id='-8'", "duplicate node id -8", 1),
        ("<way id='-25'", "<way id='-24'", "duplicate way id -24", 1),
        (
            "<relation id='-31'",
            "<relation id='-30'",
            "duplicate relation id -30",
            1,
        ),
    ] {
        let text = JOSM.replacen(from, to, 1);
        let e = load(&text).expect_err(what);
        assert!(e.to_string().contains(what), "{e}");
        assert_eq!(location(&e).line, line_of(&text, to, nth), "{what}");
    }
    let text = COMMONROAD.replacen("<lanelet id=\"50197\">", "<lanelet id=\"50195\">", 1);
    let e = load(&text).expect_err("duplicate lanelet");
    assert!(e.to_string().contains("duplicate lanelet id 50195"), "{e}");
    assert_eq!(location(&e).line, line_of(&text, "<lanelet id=\"50195\"", 1));
}

/// A map with nothing to drive on is refused at its root element: a CommonRoad file without
/// lanelets, and a lanelet2 file whose only lanelet is a crosswalk.
#[test]
fn maps_without_lanelets_are_refused_at_their_root_element() {
    let commonroad = "<?xml version=\"1.0\"?>\n<commonRoad commonRoadVersion=\"2020a\">\n  <obstacle id=\"1\"/>\n</commonRoad>\n";
    let e = load(commonroad).expect_err("no lanelets");
    assert!(e.to_string().contains("no <lanelet> element"), "{e}");
    assert_eq!((location(&e).line, location(&e).column), (2, 1));

    let crosswalk_only = JOSM.replace("v='road'", "v='crosswalk'");
    assert_ne!(crosswalk_only, JOSM, "the JOSM map names its lanelets' subtype");
    let e = load(&crosswalk_only).expect_err("only a crosswalk");
    assert!(e.to_string().contains("vehicles may drive on"), "{e}");
    assert_eq!(location(&e).line, line_of(&crosswalk_only, "<osm", 0));
}

/// A truncated file is reported where it breaks off, naming the element left open: cut at
/// every byte between the root's start tag and its end tag (inside names, attributes, text,
/// right after `<` or `</`).
#[test]
fn truncated_maps_are_located_where_they_break_off() {
    for (text, name) in [
        (JOSM, "josm"),
        (COMMONROAD, "commonroad"),
        (COMMONROAD_2018B, "2018b"),
    ] {
        let root = text.find("<osm").or(text.find("<commonRoad")).expect("a root");
        let root_end = root + text[root..].find('>').expect("its start tag ends") + 1;
        let close = text.rfind("</").expect("a closing tag");
        for cut in (root_end..close).filter(|&c| text.is_char_boundary(c)) {
            let part = &text[..cut];
            let e = load(part).expect_err("truncated");
            let MapError::NotXml { location, message } = &e else {
                panic!("{name} at {cut}: {e}")
            };
            let last_line = part.trim_end().matches('\n').count() as u32 + 1;
            assert_eq!(location.line, last_line, "{name} at {cut}: {message}");
            assert!(message.contains("the file ends inside <"), "{message}");
        }
    }
}

/// The real example map, damaged: truncated, a dangling reference, a duplicate id.
#[test]
fn the_damaged_example_map_gives_located_diagnostics() {
    let text = cpmx_testdata::read_reference("maps/lanelet2/mapping_example.osm");
    let cut = text.len() * 2 / 3;
    let cut = (0..=cut).rev().find(|&c| text.is_char_boundary(c)).unwrap_or(0);
    let e = load(&text[..cut]).expect_err("truncated");
    assert!(matches!(e, MapError::NotXml { .. }), "{e}");
    assert_eq!(
        location(&e).line,
        text[..cut].trim_end().matches('\n').count() as u32 + 1
    );
    assert!(location(&e).line > 5000, "{e}");

    let text2 = text.replacen("<node id='38992'", "<node id='38994'", 1);
    let e = load(&text2).expect_err("duplicate node");
    assert!(e.to_string().contains("duplicate node id 38994"), "{e}");
    assert_eq!(location(&e).line, 4);

    let first_nd = text.find("<nd ref='").expect("a way");
    let line = text[..first_nd].matches('\n').count() as u32 + 1;
    let mut text3 = text.clone();
    text3.replace_range(first_nd..first_nd + "<nd ref='".len(), "<nd ref='9");
    let e = load(&text3).expect_err("dangling node");
    assert!(matches!(e, MapError::UnknownReference { .. }), "{e}");
    assert_eq!(location(&e).line, line);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, failure_persistence: None, ..ProptestConfig::default() })]

    /// Truncated or byte-mutated maps of both formats never make the loader panic.
    #[test]
    fn mutated_maps_never_panic(
        which in 0usize..2,
        cut in 0.0f64..1.0,
        edits in proptest::collection::vec((0.0f64..1.0, any::<u8>()), 0..6),
    ) {
        let base = if which == 0 { JOSM } else { COMMONROAD };
        let mut bytes = base.as_bytes().to_vec();
        for (at, b) in edits {
            let i = ((bytes.len() - 1) as f64 * at) as usize;
            bytes[i] = b;
        }
        bytes.truncate(((bytes.len() as f64) * (0.2 + 0.8 * cut)) as usize);
        let text = String::from_utf8_lossy(&bytes);
        if let Err(e) = load(&text) {
            let _ = e.to_string();
        }
    }
}
