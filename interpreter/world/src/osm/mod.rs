//! Lanelet2 OSM loader: lanelets as Lanelet2 reads them and as its routing graph connects them
//! for a vehicle under German rules, so that cpmx's reference paths on a Lanelet2 map are
//! routes Lanelet2 would drive. Errors carry their place in the file; it never panics. The
//! `lanelet2` package checks it in the tests (`tests/python/map_reference.py`).
//!
//! Each concern follows Lanelet2's own code, named in its module:
//! - `nodes`: elements, ids and coordinates (`local_x`/`local_y`, else lat/lon by Lanelet2's
//!   UTM projection at the south-west corner, `projection`); deleted elements left out.
//! - `rules`: which lanelets a vehicle passes, which it also drives backwards (`one_way=no`),
//!   which line types allow lane changes (Lanelet2's `GermanVehicle` rules).
//! - `orientation`: the driving direction from the bounds' roles (`geometry::align`): the
//!   `left` way on the left; the stored node order of the ways says nothing.
//! - `centerline`: Lanelet2's centre line between the bounds (or the lanelet's own
//!   `centerline` member when it has one, as Lanelet2 uses it).
//! - `routing`: following lanelets and neighbours as in Lanelet2's routing graph.
//!
//! cpmx's choices on top:
//! - **Ids.** Node, way and relation ids are 64-bit and may be negative (JOSM numbers elements
//!   it has not uploaded with negative ids). Each kind's ids must be unique in the file. A
//!   lanelet's id is its relation's id; the inverse of a two-way lanelet (Lanelet2's
//!   `lanelet.invert()`) has the id [`crate::reversed_id`] gives, `-id - 1`.
//! - **Boundaries.** A lanelet's boundaries are its bounds' nodes in driving order (their point
//!   counts may differ); its centre line is Lanelet2's, and reference paths join the lanelets'
//!   centre lines.
//! - **Not read.** Regulatory elements (traffic lights, signs, right of way, speed limits; the
//!   German rules for a vehicle take no right of way from them either), areas (a vehicle may
//!   not use them under German rules) and other relations are counted in the map's notes.
//! - **Attributes.** Line markings are the ways' `subtype` tags for `line_thin`/`line_thick`
//!   ways, else their `type`; the lanelet type is the relation's `subtype`.

mod centerline;
pub(crate) mod nodes;
mod orientation;
mod projection;
mod routing;
mod rules;

use std::collections::HashMap;

use roxmltree::{Document, Node};

pub use projection::{OutsideUtm, UtmProjector};
pub use rules::PARTICIPANT;

use crate::commonroad::{list_ids, loc};
use crate::error::{LineIndex, MapError, SourceLocation};
use crate::lanelet::{Lanelet, LaneletId, reversed_id};
use crate::polyline::{Point, Polyline};
use nodes::{Way, deleted, int_attribute, read_nodes, read_ways, tags};
use orientation::Point3;
use routing::{Bound, Directed};

/// What a lanelet2 file holds, before reference paths are built.
#[derive(Debug, Clone, PartialEq)]
pub struct Lanelet2Map {
    /// The lanelets a vehicle drives, in relation order (a two-way lanelet's inverse right
    /// after it).
    pub lanelets: Vec<Lanelet>,
    /// How each lanelet drives its bounds, in the order of `lanelets`.
    pub bounds: Vec<DrivenBounds>,
    /// What was read but not used (one line each), for `cpmx validate`.
    pub notes: Vec<String>,
}

/// Which ways a lanelet's bounds are and whether it drives each against the way's stored node
/// order (Lanelet2's `leftBound().inverted()`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DrivenBounds {
    /// The lanelet's id.
    pub id: LaneletId,
    /// The left bound's way.
    pub left_way: i64,
    /// Whether the left bound runs against its way.
    pub left_inverted: bool,
    /// The right bound's way.
    pub right_way: i64,
    /// Whether the right bound runs against its way.
    pub right_inverted: bool,
}

/// Parses lanelet2 OSM text.
pub fn parse(text: &str) -> Result<Lanelet2Map, MapError> {
    let doc = Document::parse(text).map_err(|e| crate::commonroad::xml_error(text, &e))?;
    read_document(&doc, &LineIndex::new(text))
}

/// Counts of what is not read, for the notes.
#[derive(Default)]
struct Skipped {
    not_for_vehicles: Vec<LaneletId>,
    regulatory: usize,
    regulatory_members: usize,
    areas: usize,
    other: usize,
    two_way: usize,
    own_centerlines: usize,
}

/// Reads a parsed OSM document.
pub(crate) fn read_document(doc: &Document, text: &LineIndex) -> Result<Lanelet2Map, MapError> {
    let root = doc.root_element();
    if root.tag_name().name() != "osm" {
        return Err(MapError::UnknownFormat {
            location: loc(text, root),
            message: format!(
                "expected an <osm> root element, found <{}>",
                root.tag_name().name()
            ),
        });
    }
    let elements = |name: &'static str| root.children().filter(move |c| c.has_tag_name(name));

    // Read the nodes and ways.
    let points = read_nodes(text, elements("node"))?;
    let ways = read_ways(text, elements("way"), &points)?;

    // Read the lanelet relations a vehicle may pass, oriented; count what is skipped.
    let mut lanelets = Vec::new();
    let mut directed = Vec::new();
    let mut relations: HashMap<i64, SourceLocation> = HashMap::new();
    let mut skipped = Skipped::default();
    for rel in elements("relation").filter(|r| !deleted(*r)) {
        let location = loc(text, rel);
        let id = int_attribute(text, rel, "id")?;
        if let Some(first) = relations.insert(id, location) {
            return Err(nodes::duplicate("relation", id, location, first));
        }
        let rel_tags = tags(rel);
        match rel_tags.get("type").map(String::as_str) {
            Some("lanelet") => {}
            Some("regulatory_element") => {
                skipped.regulatory += 1;
                continue;
            }
            Some("multipolygon" | "area") => {
                skipped.areas += 1;
                continue;
            }
            _ => {
                skipped.other += 1;
                continue;
            }
        }
        if !rules::passable(&rel_tags) {
            skipped.not_for_vehicles.push(id);
            continue;
        }
        skipped.regulatory_members += members(rel, "regulatory_element").count();
        let lanelet = read_lanelet(text, rel, id, &ways, &points)?;
        if lanelet.own_centerline {
            skipped.own_centerlines += 1;
        }
        let kind: Vec<String> = rel_tags.get("subtype").cloned().into_iter().collect();
        let marking = |b: &Bound| ways.get(&b.way).and_then(|w| marking(&w.tags));
        let two_way = rules::two_way(&rel_tags);
        let mut push = |id: LaneletId, left: Bound, right: Bound, center: Vec<Point>| {
            let polyline =
                |b: &Bound| Polyline::new(b.nodes.iter().map(|n| xy(points.get(n).copied())).collect());
            lanelets.push(Lanelet {
                id,
                left_boundary: polyline(&left),
                right_boundary: polyline(&right),
                center_line: Polyline::new(center),
                left_line_marking: marking(&left),
                right_line_marking: marking(&right),
                predecessors: Vec::new(),
                successors: Vec::new(),
                adjacent_left: None,
                adjacent_right: None,
                lanelet_types: kind.clone(),
                location,
            });
            directed.push(Directed { id, left, right });
        };
        let (left, right, center) = (lanelet.left, lanelet.right, lanelet.center);
        if two_way {
            skipped.two_way += 1;
            let back: Vec<Point> = center.iter().rev().copied().collect();
            let (back_left, back_right) = (right.invert(), left.invert());
            push(id, left, right, center);
            push(reversed_id(id), back_left, back_right, back);
        } else {
            push(id, left, right, center);
        }
    }
    if let Some(dup) = first_duplicate(&lanelets) {
        return Err(MapError::Malformed {
            location: dup.location,
            message: format!(
                "lanelet id {} is used twice (the inverse of a two-way lanelet N is numbered -N-1)",
                dup.id
            ),
        });
    }

    // Connect them as Lanelet2's routing graph does.
    let lane_changes: HashMap<i64, rules::LaneChange> = ways
        .iter()
        .map(|(id, w)| (*id, rules::lane_change(&w.tags)))
        .collect();
    let relations = routing::relations(&directed, &lane_changes);
    let index: HashMap<LaneletId, usize> = lanelets.iter().enumerate().map(|(i, l)| (l.id, i)).collect();
    for (i, r) in relations.into_iter().enumerate() {
        for &next in &r.following {
            if let Some(&j) = index.get(&next) {
                let id = lanelets[i].id;
                lanelets[j].predecessors.push(id);
            }
        }
        lanelets[i].successors = r.following;
        lanelets[i].adjacent_left = r.left;
        lanelets[i].adjacent_right = r.right;
    }
    let bounds = directed
        .iter()
        .map(|d| DrivenBounds {
            id: d.id,
            left_way: d.left.way,
            left_inverted: d.left.inverted,
            right_way: d.right.way,
            right_inverted: d.right.inverted,
        })
        .collect();
    Ok(Lanelet2Map {
        lanelets,
        bounds,
        notes: notes(&skipped),
    })
}

/// A lanelet relation's oriented bounds and centre line.
struct ReadLanelet {
    left: Bound,
    right: Bound,
    center: Vec<Point>,
    own_centerline: bool,
}

fn members<'a, 'i>(rel: Node<'a, 'i>, role: &'static str) -> impl Iterator<Item = Node<'a, 'i>> {
    rel.children()
        .filter(move |m| m.has_tag_name("member") && m.attribute("role") == Some(role))
}

/// Reads a lanelet's bounds, orients them and computes its centre line.
fn read_lanelet(
    text: &LineIndex,
    rel: Node,
    id: LaneletId,
    ways: &HashMap<i64, Way>,
    points: &HashMap<i64, Point3>,
) -> Result<ReadLanelet, MapError> {
    let location = loc(text, rel);
    let member = |role: &'static str, min_points: usize| -> Result<Option<(i64, &Way)>, MapError> {
        let mut found = members(rel, role);
        let Some(m) = found.next() else {
            return Ok(None);
        };
        if let Some(second) = found.next() {
            return Err(MapError::Malformed {
                location: loc(text, second),
                message: format!("lanelet {id} has more than one `{role}` member"),
            });
        }
        let r = int_attribute(text, m, "ref")?;
        let way = ways.get(&r).ok_or_else(|| MapError::UnknownReference {
            location: loc(text, m),
            message: format!("lanelet {id} refers to unknown way {r} as its `{role}`"),
        })?;
        if way.nodes.len() < min_points {
            return Err(MapError::TooFewPoints {
                location: way.location,
                lanelet: id,
                count: way.nodes.len(),
            });
        }
        Ok(Some((r, way)))
    };
    let bound = |role: &'static str| {
        member(role, 2)?.ok_or_else(|| MapError::Malformed {
            location,
            message: format!("lanelet {id} has no `{role}` member"),
        })
    };
    let ((left_id, left), (right_id, right)) = (bound("left")?, bound("right")?);
    let point = |n: &i64| points.get(n).copied().unwrap_or_default();
    let (p_left, p_right): (Vec<Point3>, Vec<Point3>) = (
        left.nodes.iter().map(point).collect(),
        right.nodes.iter().map(point).collect(),
    );

    // Orient the bounds as Lanelet2 does.
    let (invert_left, invert_right) = orientation::align(&p_left, &p_right);
    let stored = |way: i64, w: &Way| Bound {
        way,
        inverted: false,
        nodes: w.nodes.clone(),
    };
    let orient = |b: Bound, invert: bool| if invert { b.invert() } else { b };
    let left = orient(stored(left_id, left), invert_left);
    let right = orient(stored(right_id, right), invert_right);

    // Its own centre line, else Lanelet2's.
    let xy_of = |b: &Bound| -> Vec<Point> { b.nodes.iter().map(|n| xy(points.get(n).copied())).collect() };
    let (center, own_centerline) = match member("centerline", 1)? {
        Some((_, way)) => (
            way.nodes.iter().map(|n| xy(points.get(n).copied())).collect(),
            true,
        ),
        None => {
            let same_start = left.nodes.first() == right.nodes.first();
            (
                centerline::centerline(&xy_of(&left), &xy_of(&right), same_start),
                false,
            )
        }
    };
    Ok(ReadLanelet {
        left,
        right,
        center,
        own_centerline,
    })
}

fn xy(p: Option<Point3>) -> Point {
    p.map_or([0.0, 0.0], |p| [p[0], p[1]])
}

/// A way's line marking: its subtype for painted lines, else its type.
fn marking(tags: &rules::Tags) -> Option<String> {
    let kind = tags.get("type").map(String::as_str);
    match kind {
        Some("line_thin" | "line_thick") => tags.get("subtype").map(String::as_str).or(kind),
        _ => kind,
    }
    .map(str::to_owned)
}

/// Says what was not read, one line each.
fn notes(skipped: &Skipped) -> Vec<String> {
    let mut notes = Vec::new();
    if !skipped.not_for_vehicles.is_empty() {
        notes.push(format!(
            "{} lanelets a vehicle may not pass skipped (Lanelet2's German rules: crosswalks, \
             walkways, bicycle or bus lanes): {}",
            skipped.not_for_vehicles.len(),
            list_ids(&skipped.not_for_vehicles)
        ));
    }
    if skipped.two_way > 0 {
        notes.push(format!(
            "{} two-way lanelets (one_way=no) are also read inverted, the inverse of N numbered -N-1",
            skipped.two_way
        ));
    }
    if skipped.own_centerlines > 0 {
        notes.push(format!(
            "{} lanelets have their own `centerline` member, used as their centre line",
            skipped.own_centerlines
        ));
    }
    for (n, what) in [
        (
            skipped.regulatory,
            "regulatory elements (traffic lights, signs, right of way) ignored",
        ),
        (
            skipped.regulatory_members,
            "regulatory_element members of lanelets ignored",
        ),
        (skipped.areas, "areas (multipolygon) skipped"),
        (skipped.other, "other relations skipped"),
    ] {
        if n > 0 {
            notes.push(format!("{n} {what}"));
        }
    }
    notes
}

fn first_duplicate(lanelets: &[Lanelet]) -> Option<&Lanelet> {
    let mut seen = std::collections::HashSet::new();
    lanelets.iter().find(|l| !seen.insert(l.id))
}
