//! SigmaRL's scenario maps (`sigmarl-published/maps/`: JOSM centre-line files and the scenario
//! table) read as SigmaRL's `ParseOSM` reads them. The geometry summary of every scenario is a
//! snapshot; it was checked against SigmaRL's own parser (bassamlab/SigmaRL 4c8032d) when it
//! was taken: every centre-line, boundary and yaw value below is SigmaRL's bit for bit.

use cpmx_world::{Map, MapError, MapKind, Polyline, ScenarioTable};

fn table() -> ScenarioTable {
    ScenarioTable::parse(&cpmx_testdata::read_reference(
        "sigmarl-published/maps/scenarios.json",
    ))
    .unwrap()
}

fn load(name: &str) -> Map {
    let table = table();
    let scenario = &table.scenarios[name];
    let text = cpmx_testdata::read_reference(&format!("sigmarl-published/maps/{}", scenario.map_path));
    Map::from_sigmarl_osm(&text, scenario, scenario.lane_width).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn point(p: [f64; 2]) -> String {
    format!("({:?}, {:?})", p[0], p[1])
}

fn ends(line: &Polyline) -> String {
    format!(
        "first={} last={}",
        point(line.points[0]),
        point(*line.points.last().unwrap())
    )
}

/// A scenario's geometry in the layout of the reference script that was run beside
/// SigmaRL's parser (lanelets by index, then paths; f32 values widened, printed exactly).
fn summary(name: &str) -> String {
    let map = load(name);
    let mut out = Vec::new();
    for (i, l) in map.lanelets().enumerate() {
        out.push(format!(
            "lanelet idx {i} (lanes={}) n={} {} length_f64={:?}",
            l.id,
            l.center_line.len(),
            ends(&l.center_line),
            l.center_line.length_m()
        ));
        out.push(format!(
            "    left {} | right {}",
            ends(&l.left_boundary),
            ends(&l.right_boundary)
        ));
    }
    for p in map.reference_paths() {
        let ids: Vec<String> = p.lanelet_ids.iter().map(ToString::to_string).collect();
        out.push(format!(
            "path {} lanelets={} is_loop={} n={} {} length_f64={:?} yaw0={:?} yawN={:?}",
            p.id,
            ids.join(","),
            if p.is_loop { "True" } else { "False" },
            p.center_line.len(),
            ends(&p.center_line),
            p.center_line.length_m(),
            p.center_line_yaw_rad[0],
            p.center_line_yaw_rad.last().unwrap()
        ));
        out.push(format!(
            "    left {} | right {}",
            ends(&p.left_boundary),
            ends(&p.right_boundary)
        ));
    }
    out.join("\n")
}

#[test]
fn every_scenario_loads_with_the_tables_paths() {
    let table = table();
    let names: Vec<&str> = table.osm_scenarios().map(|(n, _)| n).collect();
    assert_eq!(names.len(), 16, "{names:?}");
    for (name, scenario) in table.osm_scenarios() {
        let map = load(name);
        assert_eq!(map.kind(), MapKind::SigmarlScenario);
        assert_eq!(
            map.reference_paths().count(),
            scenario.reference_paths_ids.len(),
            "{name}"
        );
        for path in map.reference_paths() {
            // The joined centre line is the lanelets' without the repeated joints.
            let points: usize = path
                .lanelet_ids
                .iter()
                .map(|id| map.lanelet(*id).unwrap().center_line.len())
                .sum();
            assert_eq!(
                path.center_line.len(),
                points - (path.lanelet_ids.len() - 1),
                "{name}"
            );
            assert_eq!(path.left_boundary, path.left_boundary_shared);
        }
    }
}

#[test]
fn the_geometry_is_sigmarls() {
    for name in [
        "intersection_2",
        "interchange_1",
        "roundabout_1",
        "on_ramp_2_multilane",
    ] {
        insta::assert_snapshot!(name, summary(name));
    }
}

#[test]
fn boundaries_lie_half_a_lane_width_beside_the_centre_line() {
    let map = load("roundabout_2");
    for l in map.lanelets() {
        for ((c, left), right) in l
            .center_line
            .points
            .iter()
            .zip(&l.left_boundary.points)
            .zip(&l.right_boundary.points)
        {
            let half = |p: &[f64; 2]| (p[0] - c[0]).hypot(p[1] - c[1]);
            assert!((half(left) - 0.1).abs() < 1e-6 && (half(right) - 0.1).abs() < 1e-6);
        }
    }
}

#[test]
fn a_damaged_map_is_located() {
    let table = table();
    let scenario = &table.scenarios["intersection_1"];
    let text = cpmx_testdata::read_reference("sigmarl-published/maps/intersection_1.osm");
    let error = |text: &str| -> String {
        let e: MapError = Map::from_sigmarl_osm(text, scenario, 0.2).unwrap_err();
        e.to_string()
    };
    // A latitude that is not a number.
    let at = text.find(" lat='").or_else(|| text.find(" lat=\"")).unwrap();
    let bad = format!(
        "{}{}",
        &text[..at + 6],
        &text[at + 6..].replacen(|c: char| c.is_ascii_digit(), "x", 1)
    );
    let line = text[..at].lines().count();
    let message = error(&bad);
    assert!(
        message.starts_with(&format!("{line}:")) && message.contains("needs a finite `lat`"),
        "{message}"
    );
    // A lanelet tag that is not an id.
    let message = error(&text.replacen("k='lanes' v='1'", "k='lanes' v='one'", 1));
    assert!(message.contains("`lanes` tag is its lanelet id"), "{message}");
    // A missing lanelet.
    let message = error(&text.replacen("k='lanes' v='2'", "k='name' v='2'", 1));
    assert!(message.contains("no way has `lanes=2`"), "{message}");
    // Cut short.
    let message = error(&text[..text.len() / 2]);
    assert!(message.contains("not XML"), "{message}");
}
