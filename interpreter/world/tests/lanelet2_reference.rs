//! cpmx's reading of maps against the reference libraries, run in Python by
//! `tests/python/map_reference.py`: Lanelet2 maps against the `lanelet2` package (every vehicle
//! lanelet's bounds and their orientation, successors, neighbours and lane changes, centre-line
//! length; reference paths as routes of Lanelet2's routing graph), CommonRoad maps against
//! `commonroad-io` (successors, neighbours, centre-line length).
//!
//! The interpreter is `CPMX_PYTHON` (`scripts/test` makes `target/python-venv` from
//! `python/requirements-test.txt` and sets it). Without it the tests say so in one line and
//! pass, unless `CPMX_REQUIRE_PYTHON=1`. Maps: the Lanelet2 example and the CPM Lab map
//! (`../shared/reference`), the test maps in `tests/data/`, and every `.osm` file in the folder
//! `CPMX_LANELET2_MAPS` names and every `.xml` file in `CPMX_COMMONROAD_SCENARIOS`, if set.

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::process::Command;

use cpmx_world::{Adjacent, DrivingDirection, LaneletId, Map, osm};
use serde_json::Value;

const MANIFEST: &str = env!("CARGO_MANIFEST_DIR");

/// Lanelet centre lines agree with Lanelet2's to this [m]: the same algorithm on the same
/// coordinates (lat/lon by the same UTM projection, differing in rounding only).
const LANELET2_CENTRE_TOLERANCE_M: f64 = 1e-6;
/// Reference paths agree with the sum of their lanelets' Lanelet2 centre-line lengths to this
/// fraction.
const LANELET2_PATH_TOLERANCE: f64 = 1e-9;
/// CommonRoad centre lines agree with commonroad-io's within what `f32` allows: cpmx reads
/// CommonRoad coordinates as SigmaRL does, rounded to `f32` (each point moves by up to an ulp of
/// its coordinates), and computes in `f32`; commonroad-io in `f64`. The bound for a centre line
/// of `n` points of length `L` whose coordinates reach `c` in magnitude, in units of `f32`'s
/// epsilon: `4 n c + 2 n L`.
fn commonroad_centre_tolerance_m(points: usize, length_m: f64, coordinate_m: f64) -> f64 {
    let n = points as f64;
    (4.0 * n * coordinate_m + 2.0 * n * length_m) * f64::from(f32::EPSILON)
}
/// CommonRoad lanelet types no vehicle drives (as cpmx's reader has them).
const NON_VEHICLE_TYPES: [&str; 4] = ["sidewalk", "crosswalk", "bicycleLane", "busStop"];
/// CommonRoad road users that are vehicles.
const VEHICLE_USERS: [&str; 6] = ["vehicle", "car", "truck", "bus", "motorcycle", "priorityVehicle"];

/// The interpreter, or `None` (said in one line) when the test is skipped.
fn python() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("CPMX_PYTHON") {
        return Some(p.into());
    }
    assert!(
        std::env::var("CPMX_REQUIRE_PYTHON").as_deref() != Ok("1"),
        "CPMX_REQUIRE_PYTHON=1 but CPMX_PYTHON is not set"
    );
    eprintln!("skipped: CPMX_PYTHON is not set (scripts/test sets it to target/python-venv/bin/python)");
    None
}

/// The reference libraries' reading of `maps`, keyed by path.
fn reference(python: &Path, maps: &[PathBuf]) -> HashMap<String, Value> {
    let script = Path::new(MANIFEST).join("../../tests/python/map_reference.py");
    let out = Command::new(python)
        .arg(&script)
        .args(maps)
        .output()
        .expect("the Python interpreter runs");
    assert!(
        out.status.success(),
        "{} failed: {}",
        script.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    let json: Value = serde_json::from_slice(&out.stdout).expect("the script prints JSON");
    json.as_object()
        .expect("an object")
        .iter()
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect()
}

fn lanelet2_maps() -> Vec<PathBuf> {
    let data = Path::new(MANIFEST).join("tests/data");
    let mut maps = vec![
        cpmx_testdata::reference_file("maps/lanelet2/mapping_example.osm"),
        data.join("two_lanes.osm"),
    ];
    maps.extend(files_in(&data.join("lanelet2/autoware"), "osm"));
    if let Some(dir) = std::env::var_os("CPMX_LANELET2_MAPS") {
        maps.extend(files_in(Path::new(&dir), "osm"));
    }
    maps
}

/// The files in `dir` with `extension`, sorted.
fn files_in(dir: &Path, extension: &str) -> Vec<PathBuf> {
    let mut found: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == extension))
        .collect();
    found.sort();
    found
}

fn id(v: &Value) -> LaneletId {
    v.as_i64().expect("an integer id")
}

fn ids(v: &Value) -> Vec<LaneletId> {
    let mut ids: Vec<LaneletId> = v.as_array().expect("a list").iter().map(id).collect();
    ids.sort_unstable();
    ids
}

fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied().unwrap_or(f64::NAN)
}

/// A same-direction neighbour as the routing graph gives it: `(id, lane change allowed)`.
fn same_direction(adjacent: Option<Adjacent>) -> Option<(LaneletId, bool)> {
    adjacent
        .filter(|a| a.direction == DrivingDirection::Same)
        .map(|a| {
            (
                a.id,
                a.lane_change
                    .expect("Lanelet2 neighbours say whether lane changes are allowed"),
            )
        })
}

fn reference_neighbour(v: &Value) -> Option<(LaneletId, bool)> {
    (!v.is_null()).then(|| (id(&v["id"]), v["lane_change"].as_bool().expect("a boolean")))
}

#[test]
fn lanelet2_maps_read_as_lanelet2_reads_them() {
    let Some(python) = python() else { return };
    let maps = lanelet2_maps();
    let reference = reference(&python, &maps);
    for path in &maps {
        let name = path.display().to_string();
        let expected = &reference[&name];
        let by_id: HashMap<LaneletId, &Value> = expected["lanelets"]
            .as_array()
            .expect("lanelets")
            .iter()
            .map(|l| (id(&l["id"]), l))
            .collect();

        // A map without lanelets for vehicles is refused at its root element.
        let text = std::fs::read_to_string(path).expect("the map is readable");
        if by_id.is_empty() {
            let refused = Map::from_str(&text, cpmx_world::MapFormat::Auto);
            assert!(
                matches!(refused, Err(cpmx_world::MapError::Malformed { ref message, .. }) if message.contains("no lanelets")),
                "{name}: Lanelet2 has no vehicle lanelets, cpmx {refused:?}"
            );
            eprintln!("{name}: no lanelets for vehicles, refused as in Lanelet2");
            continue;
        }

        // The same lanelets, each oriented, connected and centred as Lanelet2 has it.
        let read = osm::parse(&text).unwrap_or_else(|e| panic!("{name}: {e}"));
        let ours: HashSet<LaneletId> = read.lanelets.iter().map(|l| l.id).collect();
        let theirs: HashSet<LaneletId> = by_id.keys().copied().collect();
        assert_eq!(ours, theirs, "{name}: the lanelets a vehicle drives");
        let mut problems = Vec::new();
        let mut centre_diffs_m = Vec::new();
        for (lanelet, bounds) in read.lanelets.iter().zip(&read.bounds) {
            let l = by_id[&lanelet.id];
            let theirs_bounds = (
                id(&l["left_way"]),
                l["left_inverted"].as_bool(),
                id(&l["right_way"]),
                l["right_inverted"].as_bool(),
            );
            let ours_bounds = (
                bounds.left_way,
                Some(bounds.left_inverted),
                bounds.right_way,
                Some(bounds.right_inverted),
            );
            if ours_bounds != theirs_bounds {
                problems.push(format!(
                    "{}: bounds {ours_bounds:?}, Lanelet2 {theirs_bounds:?}",
                    lanelet.id
                ));
            }
            let mut following = lanelet.successors.clone();
            following.sort_unstable();
            if following != ids(&l["following"]) {
                problems.push(format!(
                    "{}: following {following:?}, Lanelet2 {:?}",
                    lanelet.id,
                    ids(&l["following"])
                ));
            }
            for (side, ours) in [("left", lanelet.adjacent_left), ("right", lanelet.adjacent_right)] {
                let theirs = reference_neighbour(&l[side]);
                if same_direction(ours) != theirs {
                    problems.push(format!("{}: {side} {ours:?}, Lanelet2 {theirs:?}", lanelet.id));
                }
            }
            let diff_m =
                (lanelet.center_line.length_m() - l["centre_length_m"].as_f64().expect("a length")).abs();
            centre_diffs_m.push(diff_m);
            if diff_m > LANELET2_CENTRE_TOLERANCE_M {
                problems.push(format!(
                    "{}: centre line {diff_m} m longer or shorter",
                    lanelet.id
                ));
            }
        }
        assert!(
            problems.is_empty(),
            "{name}: {} of {} lanelets differ from Lanelet2:\n{}",
            problems.len(),
            read.lanelets.len(),
            problems[..problems.len().min(20)].join("\n")
        );

        // Reference paths: routes of the routing graph covering every lanelet, with Lanelet2's
        // lengths.
        let map = Map::load(path).expect("loads");
        let mut on_paths = HashSet::new();
        let mut path_diffs = Vec::new();
        for p in map.reference_paths() {
            on_paths.extend(p.lanelet_ids.iter().copied());
            for pair in p.lanelet_ids.windows(2) {
                assert!(
                    ids(&by_id[&pair[0]]["following"]).contains(&pair[1]),
                    "{name}: path {} runs {} -> {}, not following in Lanelet2's routing graph",
                    p.id,
                    pair[0],
                    pair[1]
                );
            }
            let lanelet2_m: f64 = p
                .lanelet_ids
                .iter()
                .map(|l| by_id[l]["centre_length_m"].as_f64().expect("a length"))
                .sum();
            let diff = (p.center_line.length_m() - lanelet2_m).abs() / lanelet2_m.max(1e-9);
            assert!(
                diff <= LANELET2_PATH_TOLERANCE,
                "{name}: path {} length off by {diff}",
                p.id
            );
            path_diffs.push(diff);
        }
        assert_eq!(on_paths, theirs, "{name}: every lanelet is on a reference path");
        eprintln!(
            "{name}: {} lanelets as Lanelet2 reads them; centre lines within {:.1e} m (median \
             {:.1e}); {} paths within {:.1e} of Lanelet2's lengths",
            read.lanelets.len(),
            centre_diffs_m.iter().copied().fold(0.0, f64::max),
            median(centre_diffs_m),
            path_diffs.len(),
            path_diffs.iter().copied().fold(0.0, f64::max),
        );
    }
}

#[test]
fn commonroad_maps_read_as_commonroad_io_reads_them() {
    let Some(python) = python() else { return };
    let mut maps = vec![cpmx_testdata::reference_file("maps/cpm.xml")];
    maps.extend(files_in(
        &Path::new(MANIFEST).join("tests/data/commonroad"),
        "xml",
    ));
    if let Some(dir) = std::env::var_os("CPMX_COMMONROAD_SCENARIOS") {
        maps.extend(files_in(Path::new(&dir), "xml"));
    }
    let reference = reference(&python, &maps);
    for path in &maps {
        let name = path.display().to_string();
        let by_id: HashMap<LaneletId, &Value> = reference[&name]["lanelets"]
            .as_array()
            .expect("lanelets")
            .iter()
            .map(|l| (id(&l["id"]), l))
            .collect();
        let map = Map::load(path).unwrap_or_else(|e| panic!("{name}: {e}"));

        // cpmx reads the lanelets a vehicle may use: those it leaves out are typed or used as
        // no vehicle lane.
        let kept: HashSet<LaneletId> = map.lanelets().map(|l| l.id).collect();
        for (lanelet, l) in &by_id {
            if kept.contains(lanelet) {
                continue;
            }
            let names = |key: &str| -> Vec<String> {
                l[key]
                    .as_array()
                    .expect("a list")
                    .iter()
                    .filter_map(|v| v.as_str().map(str::to_owned))
                    .collect()
            };
            let (types, users) = (names("types"), names("users"));
            let not_for_vehicles = types.iter().any(|t| NON_VEHICLE_TYPES.contains(&t.as_str()))
                || (!users.is_empty() && !users.iter().any(|u| VEHICLE_USERS.contains(&u.as_str())));
            assert!(
                not_for_vehicles,
                "{name}: lanelet {lanelet} ({types:?}, {users:?}) is not read"
            );
        }
        let keep = |ids: Vec<LaneletId>| -> Vec<LaneletId> {
            ids.into_iter().filter(|i| kept.contains(i)).collect()
        };
        let (mut pairs, mut worst) = (0, 0.0f64);
        for lanelet in map.lanelets() {
            let l = by_id[&lanelet.id];
            let mut successors = lanelet.successors.clone();
            successors.sort_unstable();
            assert_eq!(successors, keep(ids(&l["following"])), "{name}: {}", lanelet.id);
            pairs += successors.len();
            for (side, ours) in [("left", lanelet.adjacent_left), ("right", lanelet.adjacent_right)] {
                let theirs = &l[side];
                let theirs = (!theirs.is_null() && kept.contains(&id(&theirs["id"]))).then(|| {
                    (
                        id(&theirs["id"]),
                        theirs["same_direction"].as_bool() == Some(true),
                    )
                });
                let ours = ours.map(|a| (a.id, a.direction == DrivingDirection::Same));
                assert_eq!(ours, theirs, "{name}: {} {side}", lanelet.id);
            }
            let theirs_m = l["centre_length_m"].as_f64().expect("a length");
            let diff_m = (lanelet.center_line.length_m() - theirs_m).abs();
            let c = &lanelet.center_line.points;
            let coordinate_m = c.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
            let tolerance_m = commonroad_centre_tolerance_m(c.len(), theirs_m, coordinate_m);
            assert!(
                diff_m <= tolerance_m,
                "{name}: {} centre line {diff_m} m off (f32 allows {tolerance_m} m)",
                lanelet.id
            );
            worst = worst.max(diff_m / theirs_m);
        }
        eprintln!(
            "{name}: {} lanelets ({} not for vehicles left out) and {pairs} successor pairs as \
             commonroad-io reads them; centre lines within {worst:.1e} of its lengths",
            kept.len(),
            by_id.len() - kept.len()
        );
    }
}
