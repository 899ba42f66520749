//! CommonRoad XML (2018b and 2020a) loader: lanelets (boundaries, markings, topology, types) and
//! intersections. It validates what the path builder relies on and reports every problem as a
//! [`MapError`] with its place in the file; it never panics on any input.
//!
//! What the benchmark's scenario files hold besides the road (obstacles, planning problems,
//! traffic signs and lights, stop lines, location and tags) is not used; it is counted in the
//! map's notes. Lanelets no vehicle may drive are dropped after the references are checked,
//! with every reference to them: lanelets whose `userOneWay`/`userBidirectional` name no
//! vehicle class, and, without users, lanelets typed `sidewalk`, `crosswalk`, `bicycleLane`
//! or `busStop`. `userBidirectional` lanelets are driven in their own direction only.

use std::collections::HashSet;

use roxmltree::{Document, Node};

use crate::error::{LineIndex, MapError, SourceLocation};
use crate::lanelet::{Adjacent, DrivingDirection, Incoming, Intersection, Lanelet, LaneletId};
use crate::numerics::Numerics;
use crate::polyline::{Point, Polyline};
pub(crate) use crate::xml::{loc, xml_error};

/// What a CommonRoad file holds, before reference paths are built.
#[derive(Debug, Clone, PartialEq)]
pub struct CommonRoadMap {
    /// The root's `benchmarkID` attribute, if any.
    pub benchmark_id: Option<String>,
    /// Lanelets in file order.
    pub lanelets: Vec<Lanelet>,
    /// Intersection elements in file order.
    pub intersections: Vec<Intersection>,
    /// What was read but not used (one line each), for `cpmx validate`.
    pub notes: Vec<String>,
}

/// CommonRoad road users that are vehicles.
const VEHICLE_USERS: [&str; 7] = [
    "vehicle",
    "car",
    "truck",
    "bus",
    "motorcycle",
    "priorityVehicle",
    "taxi",
];
/// Lanelet types no vehicle drives on (when the lanelet names no users).
const NON_VEHICLE_TYPES: [&str; 4] = ["sidewalk", "crosswalk", "bicycleLane", "busStop"];
/// Top-level elements that are read over, by the name the notes use.
const IGNORED: [(&str, &str); 7] = [
    ("staticObstacle", "static obstacles"),
    ("dynamicObstacle", "dynamic obstacles"),
    ("environmentObstacle", "environment obstacles"),
    ("obstacle", "obstacles"),
    ("planningProblem", "planning problems"),
    ("trafficSign", "traffic signs"),
    ("trafficLight", "traffic lights"),
];

/// Parses CommonRoad XML text. Coordinates are rounded with `numerics` (SigmaRL: `Float32`).
pub fn parse(text: &str, numerics: Numerics) -> Result<CommonRoadMap, MapError> {
    let doc = Document::parse(text).map_err(|e| xml_error(text, &e))?;
    read_document(&doc, &LineIndex::new(text), numerics)
}

/// Reads a parsed CommonRoad document.
pub(crate) fn read_document(
    doc: &Document,
    text: &LineIndex,
    numerics: Numerics,
) -> Result<CommonRoadMap, MapError> {
    let root = doc.root_element();
    if root.tag_name().name() != "commonRoad" {
        return Err(MapError::UnknownFormat {
            location: loc(text, root),
            message: format!(
                "expected a <commonRoad> root element, found <{}>",
                root.tag_name().name()
            ),
        });
    }

    // Read lanelets and intersections.
    let mut lanelets = Vec::new();
    let mut intersections = Vec::new();
    let mut refs: Vec<(SourceLocation, LaneletId, &'static str)> = Vec::new();
    let mut ignored = [0usize; IGNORED.len()];
    let mut not_for_vehicles = Vec::new();
    for child in root.children().filter(Node::is_element) {
        match child.tag_name().name() {
            "lanelet" => {
                let (lanelet, vehicles) = parse_lanelet(text, child, numerics, &mut refs)?;
                if !vehicles {
                    not_for_vehicles.push(lanelet.id);
                }
                lanelets.push(lanelet);
            }
            "intersection" => intersections.push(parse_intersection(text, child, &mut refs)?),
            name => {
                // 2018b keeps every obstacle in `<obstacle>` with its `<role>`.
                let name = match name {
                    "obstacle" => match child_text(child, "role") {
                        Some("static") => "staticObstacle",
                        Some("dynamic") => "dynamicObstacle",
                        _ => "obstacle",
                    },
                    name => name,
                };
                if let Some(i) = IGNORED.iter().position(|(n, _)| *n == name) {
                    ignored[i] += 1;
                }
            }
        }
    }

    // Check ids and references.
    let mut ids = HashSet::new();
    for l in &lanelets {
        if !ids.insert(l.id) {
            return Err(MapError::Malformed {
                location: l.location,
                message: format!("duplicate lanelet id {}", l.id),
            });
        }
    }
    if let Some((location, id, what)) = refs.into_iter().find(|(_, id, _)| !ids.contains(id)) {
        return Err(MapError::UnknownReference {
            location,
            message: format!("{what} refers to unknown lanelet {id}"),
        });
    }

    // Drop what vehicles do not drive, with every reference to it.
    let mut notes: Vec<String> = IGNORED
        .iter()
        .zip(ignored)
        .filter(|(_, n)| *n > 0)
        .map(|((_, what), n)| format!("{n} {what} ignored"))
        .collect();
    if !not_for_vehicles.is_empty() {
        notes.push(format!(
            "{} lanelets not for vehicles skipped (sidewalks, crosswalks, bicycle lanes): {}",
            not_for_vehicles.len(),
            list_ids(&not_for_vehicles)
        ));
        let dropped: HashSet<LaneletId> = not_for_vehicles.into_iter().collect();
        lanelets.retain(|l| !dropped.contains(&l.id));
        for l in &mut lanelets {
            l.predecessors.retain(|id| !dropped.contains(id));
            l.successors.retain(|id| !dropped.contains(id));
            l.adjacent_left = l.adjacent_left.filter(|a| !dropped.contains(&a.id));
            l.adjacent_right = l.adjacent_right.filter(|a| !dropped.contains(&a.id));
        }
        for inc in intersections.iter_mut().flat_map(|i| &mut i.incomings) {
            for list in [
                &mut inc.incoming_lanelets,
                &mut inc.successors_right,
                &mut inc.successors_straight,
                &mut inc.successors_left,
            ] {
                list.retain(|id| !dropped.contains(id));
            }
        }
    }
    Ok(CommonRoadMap {
        benchmark_id: root.attribute("benchmarkID").map(str::to_owned),
        lanelets,
        intersections,
        notes,
    })
}

/// Up to ten ids, then how many more.
pub(crate) fn list_ids(ids: &[LaneletId]) -> String {
    let mut s: Vec<String> = ids.iter().take(10).map(ToString::to_string).collect();
    if ids.len() > 10 {
        s.push(format!("and {} more", ids.len() - 10));
    }
    s.join(", ")
}

/// A boundary as read: points, line marking, and where it is.
type ParsedBound = (Vec<Point>, Option<String>, SourceLocation);

fn parse_lanelet(
    text: &LineIndex,
    node: Node,
    numerics: Numerics,
    refs: &mut Vec<(SourceLocation, LaneletId, &'static str)>,
) -> Result<(Lanelet, bool), MapError> {
    let location = loc(text, node);
    let mut users: Vec<String> = Vec::new();
    let id = id_attribute(text, node, "id")?;
    let mut bounds: [Option<ParsedBound>; 2] = [None, None];
    let mut lanelet = Lanelet {
        id,
        left_boundary: Polyline::default(),
        right_boundary: Polyline::default(),
        center_line: Polyline::default(),
        left_line_marking: None,
        right_line_marking: None,
        predecessors: Vec::new(),
        successors: Vec::new(),
        adjacent_left: None,
        adjacent_right: None,
        lanelet_types: Vec::new(),
        location,
    };
    for child in node.children().filter(Node::is_element) {
        match child.tag_name().name() {
            name @ ("leftBound" | "rightBound") => {
                let slot = usize::from(name == "rightBound");
                if bounds[slot].is_some() {
                    return Err(MapError::Malformed {
                        location: loc(text, child),
                        message: format!("lanelet {id}: more than one <{name}>"),
                    });
                }
                let (points, marking) = parse_bound(text, child, numerics)?;
                bounds[slot] = Some((points, marking, loc(text, child)));
            }
            tag @ ("predecessor" | "successor") => {
                let r = id_attribute(text, child, "ref")?;
                refs.push((loc(text, child), r, "a predecessor/successor"));
                if tag == "predecessor" {
                    lanelet.predecessors.push(r);
                } else {
                    lanelet.successors.push(r);
                }
            }
            tag @ ("adjacentLeft" | "adjacentRight") => {
                let r = id_attribute(text, child, "ref")?;
                refs.push((loc(text, child), r, "an adjacent lanelet"));
                let direction = match child.attribute("drivingDir") {
                    Some("same") => DrivingDirection::Same,
                    Some("opposite") => DrivingDirection::Opposite,
                    other => {
                        return Err(MapError::Malformed {
                            location: loc(text, child),
                            message: format!(
                                "lanelet {id}: drivingDir must be `same` or `opposite`, found {other:?}"
                            ),
                        });
                    }
                };
                let adjacent = Some(Adjacent {
                    id: r,
                    direction,
                    lane_change: None,
                });
                if tag == "adjacentLeft" {
                    lanelet.adjacent_left = adjacent;
                } else {
                    lanelet.adjacent_right = adjacent;
                }
            }
            "laneletType" => {
                if let Some(t) = child.text().map(str::trim).filter(|t| !t.is_empty()) {
                    lanelet.lanelet_types.push(t.to_owned());
                }
            }
            "userOneWay" | "userBidirectional" => {
                if let Some(t) = child.text().map(str::trim).filter(|t| !t.is_empty()) {
                    users.push(t.to_owned());
                }
            }
            _ => {}
        }
    }

    // Check the boundaries.
    let [left, right] = bounds;
    let missing = |name: &str| MapError::Malformed {
        location,
        message: format!("lanelet {id}: missing <{name}>"),
    };
    let (left, left_marking, left_loc) = left.ok_or_else(|| missing("leftBound"))?;
    let (right, right_marking, right_loc) = right.ok_or_else(|| missing("rightBound"))?;
    for (points, at) in [(&left, left_loc), (&right, right_loc)] {
        if points.len() < 2 {
            return Err(MapError::TooFewPoints {
                location: at,
                lanelet: id,
                count: points.len(),
            });
        }
    }
    if left.len() != right.len() {
        return Err(MapError::BoundaryLengthMismatch {
            location,
            lanelet: id,
            left: left.len(),
            right: right.len(),
        });
    }
    lanelet.center_line = Polyline::new(
        left.iter()
            .zip(&right)
            .map(|(&l, &r)| numerics.mean(l, r))
            .collect(),
    );
    lanelet.left_boundary = Polyline::new(left);
    lanelet.right_boundary = Polyline::new(right);
    lanelet.left_line_marking = left_marking;
    lanelet.right_line_marking = right_marking;
    let vehicles = if users.is_empty() {
        !lanelet
            .lanelet_types
            .iter()
            .any(|t| NON_VEHICLE_TYPES.contains(&t.as_str()))
    } else {
        users.iter().any(|u| VEHICLE_USERS.contains(&u.as_str()))
    };
    Ok((lanelet, vehicles))
}

fn parse_bound(
    text: &LineIndex,
    node: Node,
    numerics: Numerics,
) -> Result<(Vec<Point>, Option<String>), MapError> {
    let mut points = Vec::new();
    let mut marking = None;
    for child in node.children().filter(Node::is_element) {
        match child.tag_name().name() {
            "point" => {
                let x = coordinate(text, child, "x", numerics)?;
                let y = coordinate(text, child, "y", numerics)?;
                points.push([x, y]);
            }
            "lineMarking" if marking.is_none() => {
                marking = child.text().map(|t| t.trim().to_owned());
            }
            _ => {}
        }
    }
    Ok((points, marking))
}

fn coordinate(text: &LineIndex, point: Node, axis: &str, numerics: Numerics) -> Result<f64, MapError> {
    let Some(node) = point.children().find(|c| c.has_tag_name(axis)) else {
        return Err(MapError::InvalidCoordinate {
            location: loc(text, point),
            message: format!("<point> has no <{axis}>"),
        });
    };
    let raw = node.text().unwrap_or("").trim();
    raw.parse::<f64>()
        .ok()
        .and_then(|v| numerics.coordinate(v))
        .ok_or_else(|| MapError::InvalidCoordinate {
            location: loc(text, node),
            message: format!("<{axis}> must be a finite number, found {raw:?}"),
        })
}

fn parse_intersection(
    text: &LineIndex,
    node: Node,
    refs: &mut Vec<(SourceLocation, LaneletId, &'static str)>,
) -> Result<Intersection, MapError> {
    let mut intersection = Intersection {
        id: id_attribute(text, node, "id")?,
        incomings: Vec::new(),
    };
    for inc in node.children().filter(|c| c.has_tag_name("incoming")) {
        let mut incoming = Incoming {
            id: id_attribute(text, inc, "id")?,
            incoming_lanelets: Vec::new(),
            successors_right: Vec::new(),
            successors_straight: Vec::new(),
            successors_left: Vec::new(),
        };
        for child in inc.children().filter(Node::is_element) {
            let list = match child.tag_name().name() {
                "incomingLanelet" => &mut incoming.incoming_lanelets,
                "successorsRight" => &mut incoming.successors_right,
                "successorsStraight" => &mut incoming.successors_straight,
                "successorsLeft" => &mut incoming.successors_left,
                _ => continue,
            };
            let r = id_attribute(text, child, "ref")?;
            refs.push((loc(text, child), r, "an intersection"));
            list.push(r);
        }
        intersection.incomings.push(incoming);
    }
    Ok(intersection)
}

/// Reads a 64-bit integer id attribute.
/// The trimmed text of `node`'s first child element named `name`.
fn child_text<'a>(node: Node<'a, '_>, name: &str) -> Option<&'a str> {
    node.children()
        .find(|c| c.is_element() && c.tag_name().name() == name)
        .and_then(|c| c.text())
        .map(str::trim)
}

fn id_attribute(text: &LineIndex, node: Node, name: &str) -> Result<i64, MapError> {
    let raw = node.attribute(name);
    raw.and_then(|v| v.trim().parse::<i64>().ok())
        .ok_or_else(|| MapError::Malformed {
            location: loc(text, node),
            message: format!(
                "<{}> needs a 64-bit integer `{name}` attribute, found {raw:?}",
                node.tag_name().name()
            ),
        })
}
