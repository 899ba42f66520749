//! Lanelet2 OSM loader (as JOSM and lanelet2 write it): nodes, ways, and relations with
//! `type=lanelet` whose `left` and `right` members are ways. Topology is derived from the
//! geometry's shared nodes. Errors carry their place in the file; it never panics.
//!
//! Choices, since the format leaves them open:
//! - **Coordinates.** A node's `local_x`/`local_y` tags (metres) are used when the file has
//!   them (then every node must have them). Otherwise `lat`/`lon` are projected
//!   equirectangularly around the south-west corner of all nodes:
//!   `x = R (lon - lon_min) cos(lat_mid)`, `y = R (lat - lat_min)` (angles in radians,
//!   `R = 6 378 137 m`, `lat_mid` the middle latitude), which is exact to well below a
//!   millimetre over a lab-sized map.
//! - **Direction.** The left way gives the driving direction; the right way is reversed when
//!   its end points match the left way's better reversed.
//! - **Point counts.** When the two boundaries have different numbers of nodes, both are
//!   resampled, evenly by arc length, to the larger count (end points kept), so that the
//!   centre line is their point-wise mean as everywhere else.
//! - **Topology.** Lanelet B succeeds A when A's left and right ways end at the nodes where B's
//!   left and right ways start. A and B are adjacent when they share a boundary way: A's left
//!   way is B's right way (same direction) or B's left way run backwards (opposite direction).
//! - **Ids and attributes.** The lanelet id is the relation id (a non-negative integer below
//!   2^32); line markings are the ways' `subtype` tags for `line_thin`/`line_thick` ways, else
//!   their `type`; the lanelet type is the relation's `subtype`.

use std::collections::HashMap;

use roxmltree::{Document, Node};

use crate::commonroad::loc;
use crate::error::{LineIndex, MapError, SourceLocation};
use crate::lanelet::{Adjacent, DrivingDirection, Lanelet, LaneletId};
use crate::polyline::{Point, Polyline, dist};

/// Earth radius of the equirectangular projection [m] (WGS84 equatorial radius).
pub const EARTH_RADIUS_M: f64 = 6_378_137.0;

/// Parses lanelet2 OSM text into lanelets (in relation order).
pub fn parse(text: &str) -> Result<Vec<Lanelet>, MapError> {
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
pub(crate) fn read_document(doc: &Document, text: &LineIndex) -> Result<Vec<Lanelet>, MapError> {
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
    let mut ways = HashMap::new();
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
        ways.insert(
            id,
            Way {
                nodes: refs,
                marking: marking.map(str::to_owned),
                location: loc(text, w),
            },
        );
    }

    // Read the lanelet relations.
    let mut lanelets = Vec::new();
    let mut bounds: Vec<[Bound; 2]> = Vec::new();
    for rel in elements("relation").filter(|r| tag(*r, "type") == Some("lanelet")) {
        let location = loc(text, rel);
        let raw = int_attribute(text, rel, "id")?;
        let id = LaneletId::try_from(raw).map_err(|_| MapError::Malformed {
            location,
            message: format!("lanelet id {raw} must be a non-negative integer below 2^32"),
        })?;
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
        let mut right_nodes = right.nodes.clone();
        let point = |n: &i64| nodes.get(n).copied().unwrap_or_default();
        let ends = |a: &[i64], b: &[i64]| match (a.first(), a.last(), b.first(), b.last()) {
            (Some(a0), Some(a1), Some(b0), Some(b1)) => {
                dist(point(a0), point(b0)) + dist(point(a1), point(b1))
            }
            _ => 0.0,
        };
        let reversed: Vec<i64> = right_nodes.iter().rev().copied().collect();
        if ends(&left.nodes, &reversed) < ends(&left.nodes, &right_nodes) {
            right_nodes = reversed;
        }
        let (l, r) = equal_counts(
            left.nodes.iter().map(point).collect(),
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
            left_line_marking: left.marking.clone(),
            right_line_marking: right.marking.clone(),
            predecessors: Vec::new(),
            successors: Vec::new(),
            adjacent_left: None,
            adjacent_right: None,
            lanelet_types: tag(rel, "subtype").map(str::to_owned).into_iter().collect(),
            location,
        });
        bounds.push([
            Bound {
                nodes: left.nodes.clone(),
                way: left_id,
            },
            Bound {
                nodes: right_nodes,
                way: right_id,
            },
        ]);
    }
    if let Some(dup) = first_duplicate(&lanelets) {
        return Err(MapError::Malformed {
            location: dup.location,
            message: format!("duplicate lanelet id {}", dup.id),
        });
    }
    derive_topology(&mut lanelets, &bounds);
    Ok(lanelets)
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
        raw.push((id, p));
    }
    if !local && let Some(b) = crate::map::Bounds::of(raw.iter().map(|(_, p)| *p)) {
        let lat_mid = ((b.min_y_m + b.max_y_m) / 2.0).to_radians();
        for (_, p) in &mut raw {
            *p = [
                EARTH_RADIUS_M * (p[0] - b.min_x_m).to_radians() * lat_mid.cos(),
                EARTH_RADIUS_M * (p[1] - b.min_y_m).to_radians(),
            ];
        }
    }
    Ok(raw.into_iter().collect())
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
