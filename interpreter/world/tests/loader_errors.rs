//! Loader errors: each kind of broken map gives its typed error with the right place, and no
//! input (truncated or mutated versions of the CPM Lab map) makes a loader panic.

use cpmx_world::{Map, MapError, MapFormat};

fn lanelet(id: u32, left: &[(f64, f64)], right: &[(f64, f64)], extra: &str) -> String {
    let pts = |ps: &[(f64, f64)]| {
        ps.iter()
            .map(|(x, y)| format!("<point><x>{x}</x><y>{y}</y></point>"))
            .collect::<String>()
    };
    format!(
        "<lanelet id=\"{id}\">\n<leftBound>{}</leftBound>\n<rightBound>{}</rightBound>\n{extra}</lanelet>\n",
        pts(left),
        pts(right)
    )
}

fn doc(body: &str) -> String {
    format!("<?xml version=\"1.0\"?>\n<commonRoad benchmarkID=\"X\">\n{body}</commonRoad>\n")
}

const L: &[(f64, f64)] = &[(0.0, 0.15), (1.0, 0.15)];
const R: &[(f64, f64)] = &[(0.0, 0.0), (1.0, 0.0)];

fn load(text: &str) -> Result<Map, MapError> {
    Map::from_str(text, MapFormat::Auto)
}

#[test]
fn not_xml_reports_line_and_column() {
    let err = load("<commonRoad>\n  <lanelet id=\"1\">\n</commonRoad>").unwrap_err();
    let MapError::NotXml { location, .. } = err else {
        panic!("{err:?}")
    };
    assert_eq!(location.line, 3);
    assert!(location.offset > 0);
}

#[test]
fn unknown_root_is_reported() {
    assert!(matches!(load("<gpx/>"), Err(MapError::UnknownFormat { .. })));
}

#[test]
fn invalid_coordinate_points_at_the_element() {
    let body = lanelet(1, L, R, "").replace("<x>1</x>", "<x>abc</x>");
    let err = load(&doc(&body)).unwrap_err();
    let MapError::InvalidCoordinate { location, .. } = err else {
        panic!("{err:?}")
    };
    assert_eq!(location.line, 4);
    let missing = lanelet(1, L, R, "").replacen("<y>0.15</y>", "", 1);
    assert!(matches!(
        load(&doc(&missing)),
        Err(MapError::InvalidCoordinate { .. })
    ));
    let huge = lanelet(1, L, R, "").replacen("<x>0</x>", "<x>1e39</x>", 1);
    assert!(matches!(
        load(&doc(&huge)),
        Err(MapError::InvalidCoordinate { .. })
    ));
}

#[test]
fn boundaries_of_different_lengths() {
    let body = lanelet(7, &[(0.0, 0.15), (0.5, 0.15), (1.0, 0.15)], R, "");
    let err = load(&doc(&body)).unwrap_err();
    assert!(
        matches!(
            err,
            MapError::BoundaryLengthMismatch {
                lanelet: 7,
                left: 3,
                right: 2,
                ..
            }
        ),
        "{err:?}"
    );
}

#[test]
fn fewer_than_two_points() {
    let body = lanelet(3, &[(0.0, 0.15)], &[(0.0, 0.0)], "");
    let err = load(&doc(&body)).unwrap_err();
    assert!(
        matches!(
            err,
            MapError::TooFewPoints {
                lanelet: 3,
                count: 1,
                ..
            }
        ),
        "{err:?}"
    );
}

#[test]
fn unknown_lanelet_reference() {
    let body = lanelet(1, L, R, "<successor ref=\"9\"/>\n");
    let err = load(&doc(&body)).unwrap_err();
    let MapError::UnknownReference { location, message } = &err else {
        panic!("{err:?}")
    };
    assert_eq!(location.line, 6);
    assert!(message.contains('9'), "{message}");
}

#[test]
fn a_tiny_valid_map_loads_with_generic_paths() {
    let body = lanelet(1, L, R, "<successor ref=\"2\"/>\n")
        + &lanelet(
            2,
            &[(1.0, 0.15), (2.0, 0.15)],
            &[(1.0, 0.0), (2.0, 0.0)],
            "<predecessor ref=\"1\"/>\n",
        );
    let map = load(&doc(&body)).expect("valid");
    assert!(!map.is_cpm_lab());
    assert_eq!(map.valid_path_ids(), vec![0]);
    let p = map.reference_path(0).expect("path 0");
    assert_eq!(p.lanelet_ids, vec![1, 2]);
    assert_eq!(p.center_line.len(), 3);
}

/// A deterministic stream of pseudo-random numbers (no RNG dependency needed).
fn lcg(state: &mut u64) -> usize {
    *state = state
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (*state >> 33) as usize
}

#[test]
fn truncated_and_mutated_maps_never_panic() {
    let full = cpmx_testdata::read_reference("maps/cpm.xml");
    // Truncations of the whole file at spread-out byte offsets.
    let mut state = 7;
    for k in 0..12 {
        let cut = (full.len() * k / 12 + lcg(&mut state) % 997).min(full.len());
        let cut = (0..=cut).rev().find(|&c| full.is_char_boundary(c)).unwrap_or(0);
        let _ = load(&full[..cut]);
    }
    // Mutations of a small map made of the file's first lanelets and its intersection.
    let head_end = full
        .match_indices("</lanelet>")
        .nth(3)
        .map_or(full.len(), |(i, _)| i + "</lanelet>".len());
    let small = format!("{}\n</commonRoad>\n", &full[..head_end]);
    let replacements = [
        "",
        "<",
        ">",
        "-1",
        "nan",
        "inf",
        "1e40",
        "abc",
        "</x>",
        "<x>",
        "\"",
        "ref=\"999\"",
        "<successor ref=\"1\"/>",
        "<point><x>1</x></point>",
        "&amp;",
        "&bogus;",
        "0",
    ];
    let tiny = doc(&(lanelet(
        1,
        L,
        R,
        "<successor ref=\"2\"/><adjacentLeft ref=\"2\" drivingDir=\"same\"/>\n",
    ) + &lanelet(
        2,
        &[(1.0, 0.15), (2.0, 0.15)],
        &[(1.0, 0.0), (2.0, 0.0)],
        "<successor ref=\"1\"/>\n",
    )));
    assert!(load(&tiny).is_ok());
    for i in 0..400 {
        let mut text = if i % 2 == 0 { small.clone() } else { tiny.clone() };
        for _ in 0..(1 + lcg(&mut state) % 3) {
            let at = lcg(&mut state) % text.len();
            let len = lcg(&mut state) % 12;
            let (a, b) = (at, (at + len).min(text.len()));
            if text.is_char_boundary(a) && text.is_char_boundary(b) {
                let r = replacements[lcg(&mut state) % replacements.len()];
                text.replace_range(a..b, r);
            }
        }
        let _ = load(&text);
        let _ = Map::from_str(&text, MapFormat::Lanelet2Osm);
    }
}
