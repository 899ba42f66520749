//! Lanelet2 OSM loader (as JOSM and lanelet2 write it): nodes, ways, and relations with
//! `type=lanelet` whose `left` and `right` members are ways. Topology is derived from the
//! geometry's shared nodes. Errors carry their place in the file; it never panics.
//!
//! Choices, since the format leaves them open:
//! - **Ids.** Node, way and relation ids are 64-bit and may be negative (JOSM numbers elements
//!   it has not uploaded with negative ids). Each kind's ids must be unique in the file. A
//!   lanelet's id is its relation's id; the reverse direction of a two-way lanelet has the id
//!   [`crate::reversed_id`] gives, `-id - 1` (`42440` -> `-42441`).
//! - **Coordinates.** A node's `local_x`/`local_y` tags (metres, as Autoware's maps and
//!   lanelet2's local projector write them) are used when the file has them (then every node
//!   must have them). Otherwise `lat`/`lon` (WGS84 degrees) are projected equirectangularly
//!   around the south-west corner of all nodes: `x = R (lon - lon_min) cos(lat_mid)`,
//!   `y = R (lat - lat_min)` (angles in radians, `R = 6 378 137 m`, `lat_mid` the middle
//!   latitude). Over a map a kilometre across this differs from lanelet2's UTM projection by a
//!   rigid offset plus less than 0.1 % in lengths; x points east, y north.
//! - **Who drives.** Only lanelets a car may use are read, as lanelet2's traffic rules infer it
//!   for `vehicle:car`: with any `participant:*` tag, only those with `participant:vehicle=yes`
//!   or `participant:vehicle:car=yes`; otherwise by `subtype`: `road` (the default),
//!   `highway`, `play_street`, `exit`. Crosswalks, walkways, stairs and bicycle, bus and
//!   emergency lanes are skipped, with a note.
//! - **Direction.** The left way gives the driving direction; the right way is reversed when
//!   its end points match the left way's better reversed. Lanelets tagged `one_way=no`
//!   (or `one_way:vehicle=no`, `one_way:vehicle:car=no`) are also read backwards, as a second
//!   lanelet with the reversed id whose left boundary is the right one run backwards.
//! - **Point counts.** When the two boundaries have different numbers of nodes, both are
//!   resampled, evenly by arc length, to the larger count (end points kept), so that the
//!   centre line is their point-wise mean as everywhere else.
//! - **Topology.** Lanelet B succeeds A when A's left and right ways end at the nodes where B's
//!   left and right ways start. A and B are adjacent when they share a boundary way: A's left
//!   way is B's right way (same direction) or B's left way run backwards (opposite direction).
//! - **Not read.** Regulatory elements (traffic lights, signs, right of way, speed limits) and
//!   a lanelet's `regulatory_element` members, areas (`type=multipolygon` or `area`) and any
//!   other relation are skipped, each kind counted in the map's notes.
//! - **Attributes.** Line markings are the ways' `subtype` tags for `line_thin`/`line_thick`
//!   ways, else their `type`; the lanelet type is the relation's `subtype`.

use std::collections::HashMap;

use roxmltree::{Document, Node};

use crate::commonroad::{list_ids, loc};
use crate::error::{LineIndex, MapError, SourceLocation};
use crate::lanelet::{Adjacent, DrivingDirection, Lanelet, LaneletId, reversed_id};
use crate::polyline::{Point, Polyline, dist};

/// Earth radius of the equirectangular projection [m] (WGS84 equatorial radius).
pub const EARTH_RADIUS_M: f64 = 6_378_137.0;

/// Subtypes a car drives on when no `participant:*` tag says otherwise.
const CAR_SUBTYPES: [&str; 4] = ["road", "highway", "play_street", "exit"];

/// What a lanelet2 file holds, before reference paths are built.
#[derive(Debug, Clone, PartialEq)]
pub struct Lanelet2Map {
    /// The lanelets a car drives, in relation order (a two-way lanelet's reverse right after
    /// it).
    pub lanelets: Vec<Lanelet>,
    /// What was read but not used (one line each), for `cpmx validate`.
    pub notes: Vec<String>,
}

/// Parses lanelet2 OSM text.
pub fn parse(text: &str) -> Result<Lanelet2Map, MapError> {
    let doc = Document::parse(text).map_err(|e| crate::commonroad::xml_error(text, &e))?;
    read_document(&doc, &LineIndex::new(text))
}

struct Way {
    nodes: Vec<i64>,
    marking: Option<String>,
    location: SourceLocation,
}

struct Bound {
    nodes: Vec<i64>,
    way: i64,
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

    // Read the nodes.
    let nodes = read_nodes(text, elements("node"))?;

    // Read the ways.
    let mut ways: HashMap<i64, Way> = HashMap::new();
    for w in elements("way") {
        let id = int_attribute(text, w, "id")?;
        let mut refs = Vec::new();
        for nd in w.children().filter(|c| c.has_tag_name("nd")) {
            let r = int_attribute(text, nd, "ref")?;
            if !nodes.contains_key(&r) {
                return Err(MapError::UnknownReference {
                    location: loc(text, nd),
                    message: format!("way {id} refers to unknown node {r}"),
                });
            }
            refs.push(r);
        }
        let kind = tag(w, "type");
        let marking = match kind {
            Some("line_thin" | "line_thick") => tag(w, "subtype").or(kind),
            _ => kind,
        };
        let location = loc(text, w);
        if let Some(first) = ways.get(&id) {
            return Err(duplicate("way", id, location, first.location));
        }
        ways.insert(
            id,
            Way {
                nodes: refs,
                marking: marking.map(str::to_owned),
                location,
            },
        );
    }

    // Read the lanelet relations; count what is skipped.
    let mut lanelets = Vec::new();
    let mut bounds: Vec<[Bound; 2]> = Vec::new();
    let mut relations: HashMap<i64, SourceLocation> = HashMap::new();
    let mut skipped: Vec<LaneletId> = Vec::new();
    let mut two_way_count = 0usize;
    let (mut regulatory, mut regulatory_members, mut areas, mut other) = (0usize, 0usize, 0usize, 0usize);
    for rel in elements("relation") {
        let location = loc(text, rel);
        let id = int_attribute(text, rel, "id")?;
        if let Some(first) = relations.insert(id, location) {
            return Err(duplicate("relation", id, location, first));
        }
        match tag(rel, "type") {
            Some("lanelet") => {}
            Some("regulatory_element") => {
                regulatory += 1;
                continue;
            }
            Some("multipolygon" | "area") => {
                areas += 1;
                continue;
            }
            _ => {
                other += 1;
                continue;
            }
        }
        if !for_cars(rel) {
            skipped.push(id);
            continue;
        }
        regulatory_members += rel
            .children()
            .filter(|m| m.has_tag_name("member") && m.attribute("role") == Some("regulatory_element"))
            .count();
        let member = |role: &str| -> Result<(i64, &Way), MapError> {
            let m = rel
                .children()
                .find(|m| m.has_tag_name("member") && m.attribute("role") == Some(role))
                .ok_or_else(|| MapError::Malformed {
                    location,
                    message: format!("lanelet {id} has no `{role}` member"),
                })?;
            let r = int_attribute(text, m, "ref")?;
            let way = ways.get(&r).ok_or_else(|| MapError::UnknownReference {
                location: loc(text, m),
                message: format!("lanelet {id} refers to unknown way {r}"),
            })?;
            if way.nodes.len() < 2 {
                return Err(MapError::TooFewPoints {
                    location: way.location,
                    lanelet: id,
                    count: way.nodes.len(),
                });
            }
            Ok((r, way))
        };
        let (left_id, left) = member("left")?;
        let (right_id, right) = member("right")?;
        let point = |n: &i64| nodes.get(n).copied().unwrap_or_default();
        let ends = |a: &[i64], b: &[i64]| match (a.first(), a.last(), b.first(), b.last()) {
            (Some(a0), Some(a1), Some(b0), Some(b1)) => {
                dist(point(a0), point(b0)) + dist(point(a1), point(b1))
            }
            _ => 0.0,
        };
        let mut right_nodes = right.nodes.clone();
        let reversed: Vec<i64> = right_nodes.iter().rev().copied().collect();
        if ends(&left.nodes, &reversed) < ends(&left.nodes, &right_nodes) {
            right_nodes = reversed;
        }
        let kind: Vec<String> = tag(rel, "subtype").map(str::to_owned).into_iter().collect();
        let mut push =
            |id: LaneletId,
             (left_id, left_nodes, left_marking): (i64, Vec<i64>, &Option<String>),
             (right_id, right_nodes, right_marking): (i64, Vec<i64>, &Option<String>)| {
                let (l, r) = equal_counts(
                    left_nodes.iter().map(point).collect(),
                    right_nodes.iter().map(point).collect(),
                );
                let center = l
                    .iter()
                    .zip(&r)
                    .map(|(a, b)| [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0]);
                lanelets.push(Lanelet {
                    id,
                    center_line: Polyline::new(center.collect()),
                    left_boundary: Polyline::new(l),
                    right_boundary: Polyline::new(r),
                    left_line_marking: left_marking.clone(),
                    right_line_marking: right_marking.clone(),
                    predecessors: Vec::new(),
                    successors: Vec::new(),
                    adjacent_left: None,
                    adjacent_right: None,
                    lanelet_types: kind.clone(),
                    location,
                });
                bounds.push([
                    Bound {
                        nodes: left_nodes,
                        way: left_id,
                    },
                    Bound {
                        nodes: right_nodes,
                        way: right_id,
                    },
                ]);
            };
        let backwards = |n: &[i64]| n.iter().rev().copied().collect::<Vec<_>>();
        let (back_left, back_right) = (backwards(&right_nodes), backwards(&left.nodes));
        push(
            id,
            (left_id, left.nodes.clone(), &left.marking),
            (right_id, right_nodes, &right.marking),
        );
        if two_way(rel) {
            two_way_count += 1;
            push(
                reversed_id(id),
                (right_id, back_left, &right.marking),
                (left_id, back_right, &left.marking),
            );
        }
    }
    if let Some(dup) = first_duplicate(&lanelets) {
        return Err(MapError::Malformed {
            location: dup.location,
            message: format!(
                "lanelet id {} is used twice (the reverse of a two-way lanelet N is numbered -N-1)",
                dup.id
            ),
        });
    }
    derive_topology(&mut lanelets, &bounds);

    // Say what was not read.
    let mut notes = Vec::new();
    if !skipped.is_empty() {
        notes.push(format!(
            "{} lanelets not for cars skipped (crosswalks, walkways, bicycle or bus lanes): {}",
            skipped.len(),
            list_ids(&skipped)
        ));
    }
    if two_way_count > 0 {
        notes.push(format!(
            "{two_way_count} two-way lanelets (one_way=no) are also read backwards, the reverse of N numbered -N-1"
        ));
    }
    for (n, what) in [
        (
            regulatory,
            "regulatory elements (traffic lights, signs, right of way) ignored",
        ),
        (
            regulatory_members,
            "regulatory_element members of lanelets ignored",
        ),
        (areas, "areas (multipolygon) skipped"),
        (other, "other relations skipped"),
    ] {
        if n > 0 {
            notes.push(format!("{n} {what}"));
        }
    }
    Ok(Lanelet2Map { lanelets, notes })
}

/// Whether a car may drive a lanelet relation (lanelet2's inference for `vehicle:car`).
fn for_cars(rel: Node) -> bool {
    let participants: Vec<(&str, &str)> = rel
        .children()
        .filter(|c| c.has_tag_name("tag"))
        .filter_map(|c| Some((c.attribute("k")?, c.attribute("v")?)))
        .filter_map(|(k, v)| Some((k.strip_prefix("participant:")?, v)))
        .collect();
    if participants.is_empty() {
        return tag(rel, "subtype").is_none_or(|s| CAR_SUBTYPES.contains(&s));
    }
    participants
        .iter()
        .any(|(who, v)| matches!(*who, "vehicle" | "vehicle:car") && is_yes(v))
}

/// Whether a car may drive a lanelet both ways.
fn two_way(rel: Node) -> bool {
    ["one_way", "one_way:vehicle", "one_way:vehicle:car"]
        .iter()
        .any(|k| tag(rel, k).is_some_and(is_no))
}

fn is_yes(v: &str) -> bool {
    matches!(v.trim(), "yes" | "true" | "1")
}

fn is_no(v: &str) -> bool {
    matches!(v.trim(), "no" | "false" | "0")
}

fn duplicate(what: &str, id: i64, at: SourceLocation, first: SourceLocation) -> MapError {
    MapError::Malformed {
        location: at,
        message: format!("duplicate {what} id {id} (first defined at {first})"),
    }
}

/// Node coordinates: local tags when the file has them, else the projection.
fn read_nodes<'a, 'i: 'a>(
    text: &LineIndex,
    nodes: impl Iterator<Item = Node<'a, 'i>>,
) -> Result<HashMap<i64, Point>, MapError> {
    let nodes: Vec<Node> = nodes.collect();
    let local = nodes.iter().any(|n| tag(*n, "local_x").is_some());
    let number = |n: Node, v: Option<&str>, what: &str| -> Result<f64, MapError> {
        v.and_then(|v| v.trim().parse::<f64>().ok())
            .filter(|v| v.is_finite())
            .ok_or_else(|| MapError::InvalidCoordinate {
                location: loc(text, n),
                message: format!("node needs a finite `{what}`, found {v:?}"),
            })
    };
    let mut raw = Vec::with_capacity(nodes.len());
    for &n in &nodes {
        let id = int_attribute(text, n, "id")?;
        let p = if local {
            [
                number(n, tag(n, "local_x"), "local_x")?,
                number(n, tag(n, "local_y"), "local_y")?,
            ]
        } else {
            let lat = number(n, n.attribute("lat"), "lat")?;
            let lon = number(n, n.attribute("lon"), "lon")?;
            if !(-90.0..=90.0).contains(&lat) || !(-180.0..=180.0).contains(&lon) {
                return Err(MapError::InvalidCoordinate {
                    location: loc(text, n),
                    message: format!("lat {lat} / lon {lon} out of range"),
                });
            }
            [lon, lat]
        };
        raw.push((id, p, n));
    }
    let mut seen: HashMap<i64, SourceLocation> = HashMap::new();
    for (id, _, n) in &raw {
        if let Some(first) = seen.insert(*id, loc(text, *n)) {
            return Err(duplicate("node", *id, loc(text, *n), first));
        }
    }
    if !local && let Some(b) = crate::map::Bounds::of(raw.iter().map(|(_, p, _)| *p)) {
        let lat_mid = ((b.min_y_m + b.max_y_m) / 2.0).to_radians();
        for (_, p, _) in &mut raw {
            *p = [
                EARTH_RADIUS_M * (p[0] - b.min_x_m).to_radians() * lat_mid.cos(),
                EARTH_RADIUS_M * (p[1] - b.min_y_m).to_radians(),
            ];
        }
    }
    Ok(raw.into_iter().map(|(id, p, _)| (id, p)).collect())
}

/// Resamples two boundaries to the same number of points (the larger count), evenly by arc
/// length; boundaries that already agree are returned unchanged.
fn equal_counts(l: Vec<Point>, r: Vec<Point>) -> (Vec<Point>, Vec<Point>) {
    if l.len() == r.len() {
        return (l, r);
    }
    let n = l.len().max(r.len());
    (resample(&l, n), resample(&r, n))
}

fn resample(points: &[Point], n: usize) -> Vec<Point> {
    let line = Polyline::new(points.to_vec());
    let total_m = line.length_m();
    let (Some(&first), Some(&last)) = (points.first(), points.last()) else {
        return Vec::new();
    };
    if n < 2 || total_m <= 0.0 {
        return vec![first; n];
    }
    let mut out = Vec::with_capacity(n);
    let (mut seg, mut start_m) = (0, 0.0);
    for i in 0..n {
        let s = total_m * i as f64 / (n - 1) as f64;
        while seg + 2 < points.len() && start_m + dist(points[seg], points[seg + 1]) < s {
            start_m += dist(points[seg], points[seg + 1]);
            seg += 1;
        }
        let (a, b) = (points[seg], points[(seg + 1).min(points.len() - 1)]);
        let len = dist(a, b);
        let t = if len > 0.0 {
            ((s - start_m) / len).clamp(0.0, 1.0)
        } else {
            0.0
        };
        out.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
    }
    if let Some(f) = out.first_mut() {
        *f = first;
    }
    if let Some(l) = out.last_mut() {
        *l = last;
    }
    out
}

/// Successors from shared end nodes, adjacency from shared ways.
fn derive_topology(lanelets: &mut [Lanelet], bounds: &[[Bound; 2]]) {
    let n = lanelets.len();
    for a in 0..n {
        for b in 0..n {
            if a == b {
                continue;
            }
            let [al, ar] = &bounds[a];
            let [bl, br] = &bounds[b];
            if al.nodes.last() == bl.nodes.first() && ar.nodes.last() == br.nodes.first() {
                let (ida, idb) = (lanelets[a].id, lanelets[b].id);
                lanelets[a].successors.push(idb);
                lanelets[b].predecessors.push(ida);
            }
            let id_b = lanelets[b].id;
            if al.way == br.way && al.nodes == br.nodes {
                lanelets[a].adjacent_left = Some(Adjacent {
                    id: id_b,
                    direction: DrivingDirection::Same,
                });
            } else if al.way == bl.way && al.nodes.iter().eq(bl.nodes.iter().rev()) {
                lanelets[a].adjacent_left = Some(Adjacent {
                    id: id_b,
                    direction: DrivingDirection::Opposite,
                });
            }
            if ar.way == bl.way && ar.nodes == bl.nodes {
                lanelets[a].adjacent_right = Some(Adjacent {
                    id: id_b,
                    direction: DrivingDirection::Same,
                });
            }
        }
    }
}

fn first_duplicate(lanelets: &[Lanelet]) -> Option<&Lanelet> {
    let mut seen = std::collections::HashSet::new();
    lanelets.iter().find(|l| !seen.insert(l.id))
}

/// The value of a `<tag k=... v=...>` child.
fn tag<'a>(node: Node<'a, '_>, key: &str) -> Option<&'a str> {
    node.children()
        .find(|c| c.has_tag_name("tag") && c.attribute("k") == Some(key))
        .and_then(|c| c.attribute("v"))
}

fn int_attribute(text: &LineIndex, node: Node, name: &str) -> Result<i64, MapError> {
    let raw = node.attribute(name);
    raw.and_then(|v| v.trim().parse::<i64>().ok())
        .ok_or_else(|| MapError::Malformed {
            location: loc(text, node),
            message: format!(
                "<{}> needs an integer `{name}` attribute, found {raw:?}",
                node.tag_name().name()
            ),
        })
}
