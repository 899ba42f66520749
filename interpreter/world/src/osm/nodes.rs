//! The elements of an OSM file as Lanelet2's reader takes them: nodes with their coordinates
//! in metres, ways with their nodes and tags, ids and tags read with located errors. Elements
//! marked `action="delete"` (JOSM's deleted, not yet uploaded elements) are left out, as
//! Lanelet2 leaves them out.
//!
//! Coordinates: a node's `local_x`/`local_y` tags (metres, as Autoware's maps and
//! lanelet2's local projector write them) when the file has them (then every node must have
//! them); otherwise `lat`/`lon` by Lanelet2's UTM projection with the origin at the south-west
//! corner of all nodes (`projection.rs`). The elevation is the `ele` tag (0 without one; an
//! empty value is 0 as Lanelet2 reads it); it only enters the bounds' orientation.

use std::collections::HashMap;

use roxmltree::Node;

use super::orientation::Point3;
use super::projection::UtmProjector;
use super::rules::Tags;
use crate::commonroad::loc;
use crate::error::{LineIndex, MapError, SourceLocation};

/// A way: its nodes in stored order, its tags and where it is.
pub struct Way {
    pub nodes: Vec<i64>,
    pub tags: Tags,
    pub location: SourceLocation,
}

/// Whether JOSM marked the element deleted.
pub fn deleted(element: Node) -> bool {
    element.attribute("action") == Some("delete")
}

/// The element's `<tag>` children, the last value of a repeated key kept (as Lanelet2 keeps it).
pub fn tags(element: Node) -> Tags {
    element
        .children()
        .filter(|c| c.has_tag_name("tag"))
        .filter_map(|c| Some((c.attribute("k")?.to_owned(), c.attribute("v")?.to_owned())))
        .collect()
}

/// The value of the first `<tag k=key>` child.
pub fn tag<'a>(node: Node<'a, '_>, key: &str) -> Option<&'a str> {
    node.children()
        .find(|c| c.has_tag_name("tag") && c.attribute("k") == Some(key))
        .and_then(|c| c.attribute("v"))
}

/// An integer attribute, or a located error naming it.
pub fn int_attribute(text: &LineIndex, node: Node, name: &str) -> Result<i64, MapError> {
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

pub fn duplicate(what: &str, id: i64, at: SourceLocation, first: SourceLocation) -> MapError {
    MapError::Malformed {
        location: at,
        message: format!("duplicate {what} id {id} (first defined at {first})"),
    }
}

/// Node coordinates [m] with elevation, by id.
pub fn read_nodes<'a, 'i: 'a>(
    text: &LineIndex,
    nodes: impl Iterator<Item = Node<'a, 'i>>,
) -> Result<HashMap<i64, Point3>, MapError> {
    let nodes: Vec<Node> = nodes.filter(|n| !deleted(*n)).collect();
    let local = nodes.iter().any(|n| tag(*n, "local_x").is_some());
    let number = |n: Node, v: Option<&str>, what: &str| -> Result<f64, MapError> {
        v.and_then(|v| v.trim().parse::<f64>().ok())
            .filter(|v| v.is_finite())
            .ok_or_else(|| MapError::InvalidCoordinate {
                location: loc(text, n),
                message: format!("node needs a finite `{what}`, found {v:?}"),
            })
    };

    // Read every node's numbers: local x/y or lat/lon, and the elevation.
    let mut raw = Vec::with_capacity(nodes.len());
    let mut seen: HashMap<i64, SourceLocation> = HashMap::new();
    for &n in &nodes {
        let id = int_attribute(text, n, "id")?;
        if let Some(first) = seen.insert(id, loc(text, n)) {
            return Err(duplicate("node", id, loc(text, n), first));
        }
        let ele = match tag(n, "ele").map(str::trim) {
            None | Some("") => 0.0,
            value => number(n, value, "ele")?,
        };
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
            [lat, lon]
        };
        raw.push((id, p, ele, n));
    }

    // Project lat/lon at the south-west corner.
    if !local && let Some(&(_, first, _, n)) = raw.first() {
        let (lat0, lon0) = raw.iter().fold((first[0], first[1]), |(la, lo), (_, p, _, _)| {
            (la.min(p[0]), lo.min(p[1]))
        });
        let outside = |n: Node, lat: f64| MapError::InvalidCoordinate {
            location: loc(text, n),
            message: format!(
                "lat {lat} is outside the UTM projection's latitudes (80° S to 84° N); give the \
                 nodes `local_x`/`local_y` tags in metres"
            ),
        };
        let projector = UtmProjector::new(lat0, lon0).map_err(|e| outside(n, e.lat_deg))?;
        for (_, p, _, n) in &mut raw {
            *p = projector
                .forward(p[0], p[1])
                .map_err(|e| outside(*n, e.lat_deg))?;
        }
    }
    Ok(raw
        .into_iter()
        .map(|(id, p, ele, _)| (id, [p[0], p[1], ele]))
        .collect())
}

/// Reads the ways (each node known, ids unique).
pub fn read_ways<'a, 'i: 'a>(
    text: &LineIndex,
    ways: impl Iterator<Item = Node<'a, 'i>>,
    nodes: &HashMap<i64, Point3>,
) -> Result<HashMap<i64, Way>, MapError> {
    let mut out: HashMap<i64, Way> = HashMap::new();
    for w in ways.filter(|w| !deleted(*w)) {
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
        let location = loc(text, w);
        if let Some(first) = out.get(&id) {
            return Err(duplicate("way", id, location, first.location));
        }
        out.insert(
            id,
            Way {
                nodes: refs,
                tags: tags(w),
                location,
            },
        );
    }
    Ok(out)
}
