//! SigmaRL's scenario maps: JOSM files whose ways are lane centre lines, not Lanelet2 maps, and
//! the scenario table (`maps/scenarios.json`, SigmaRL's `constants.SCENARIOS`) that gives each
//! its scale, lane width and reference paths. Read as SigmaRL's `ParseOSM` reads them
//! (`sigmarl/parse_osm.py`), so that a scenario's lanelets and paths equal SigmaRL's bit for
//! bit:
//!
//! - every `<node>` counts; x comes from the latitude, y from the longitude:
//!   `x = (lat - min lat) * scale + 1.2 * lane width` in `f64`, then rounded to `f32`;
//! - a way is lanelet N by its `lanes=N` tag (ids 1..N without gaps), its nodes in stored order
//!   its centre line; its boundaries lie ±width/2 along the left normal of the segment leaving
//!   each point (the last point takes the last segment's), in `f32` arithmetic with torch's
//!   rounding (`norm` = one fused multiply-add);
//! - a reference path joins its lanelets' centre lines, dropping each later lanelet's first
//!   point, and computes its boundaries and yaws anew from the joined line; its road
//!   boundaries are its own lane's (SigmaRL's agents see no other lane).
//!
//! A damaged file gets a located diagnostic: missing or non-numeric coordinates and `lanes`
//! tags, a way naming an unknown node, duplicate or missing lanelet ids, paths through unknown
//! lanelets or lanelets that do not join.

use std::collections::{BTreeMap, BTreeSet, HashMap};

use roxmltree::Document;
use serde::Deserialize;

use crate::ReferencePath;
use crate::error::{LineIndex, MapError, SourceLocation};
use crate::lanelet::{Lanelet, LaneletId};
use crate::map::{Map, MapKind, MapParts};
use crate::numerics::Numerics;
use crate::paths::CentreRule;
use crate::polyline::{Point, Polyline};
use crate::xml::{loc, xml_error};

/// One scenario of SigmaRL's table, with the fields the geometry needs.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct SigmarlScenario {
    /// The map file, relative to the table's folder.
    pub map_path: String,
    /// Lane width [m]: the boundaries lie half of it either side of the centre line.
    pub lane_width: f64,
    /// Metres per degree of latitude and longitude.
    pub scale: f64,
    /// Agents SigmaRL places in the scenario by default.
    pub n_agents: usize,
    /// Each reference path as its lanelets' ids (the `lanes` tags), numbered by position.
    #[serde(default)]
    pub reference_paths_ids: Vec<Vec<String>>,
    /// The lanelets whose agents an agent on a lanelet observes (SigmaRL's mask).
    #[serde(default)]
    pub neighboring_lanelet_ids: BTreeMap<String, Vec<String>>,
}

/// SigmaRL's scenario table (`maps/scenarios.json`: `{"scenarios": {NAME: {...}}}`).
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct ScenarioTable {
    /// The scenarios by name.
    pub scenarios: BTreeMap<String, SigmarlScenario>,
}

impl ScenarioTable {
    /// Parses the table; a malformed one is located by line and column.
    pub fn parse(text: &str) -> Result<ScenarioTable, MapError> {
        serde_json::from_str(text).map_err(|e| MapError::Malformed {
            location: SourceLocation::from_line_column(
                text,
                u32::try_from(e.line()).unwrap_or(u32::MAX),
                u32::try_from(e.column()).unwrap_or(u32::MAX),
            ),
            message: format!("not SigmaRL's scenario table: {e}"),
        })
    }

    /// The scenarios whose map is one of SigmaRL's JOSM centre-line files (not the CPM Lab's
    /// CommonRoad map), by name.
    pub fn osm_scenarios(&self) -> impl Iterator<Item = (&str, &SigmarlScenario)> {
        self.scenarios
            .iter()
            .filter(|(_, s)| s.map_path.ends_with(".osm"))
            .map(|(n, s)| (n.as_str(), s))
    }
}

impl Map {
    /// Reads one of SigmaRL's JOSM centre-line maps with its scenario's table entry, its
    /// boundaries at `lane_width_m` (SigmaRL's `ParseOSM(lane_width=...)`; the table's
    /// `lane_width` when SigmaRL passes none).
    pub fn from_sigmarl_osm(
        text: &str,
        scenario: &SigmarlScenario,
        lane_width_m: f64,
    ) -> Result<Map, MapError> {
        let doc = Document::parse(text).map_err(|e| xml_error(text, &e))?;
        let index = LineIndex::new(text);
        let root = doc.root_element();
        if root.tag_name().name() != "osm" {
            return Err(MapError::UnknownFormat {
                location: loc(&index, root),
                message: format!(
                    "SigmaRL's scenario maps are JOSM files with an <osm> root, found <{}>",
                    root.tag_name().name()
                ),
            });
        }
        let scale = scenario.scale;
        if !(scale.is_finite() && scale > 0.0 && lane_width_m.is_finite() && lane_width_m > 0.0) {
            return Err(MapError::Malformed {
                location: loc(&index, root),
                message: format!(
                    "the scenario's scale ({scale}) and lane width ({lane_width_m} m) must be positive"
                ),
            });
        }
        let nodes = read_nodes(&index, &doc)?;
        let centre_lines = read_ways(&index, &doc, &nodes, scale, lane_width_m)?;
        let half_width = (lane_width_m / 2.0) as f32;
        let root_location = loc(&index, root);
        let paths = reference_paths(scenario, &centre_lines, half_width, root_location)?;
        let mut lanelets: Vec<Lanelet> = centre_lines
            .iter()
            .map(|(id, (line, location))| {
                let (left, right) = boundaries(line, half_width);
                Lanelet {
                    id: *id,
                    left_boundary: widen(&left),
                    right_boundary: widen(&right),
                    center_line: widen(line),
                    left_line_marking: None,
                    right_line_marking: None,
                    predecessors: Vec::new(),
                    successors: Vec::new(),
                    adjacent_left: None,
                    adjacent_right: None,
                    lanelet_types: Vec::new(),
                    location: *location,
                }
            })
            .collect();
        // Neighbours as SigmaRL derives them: consecutive lanelets of any path (sorted; its are
        // sets).
        let mut links: BTreeSet<(LaneletId, LaneletId)> = BTreeSet::new();
        for path in &paths {
            for pair in path.lanelet_ids.windows(2) {
                links.insert((pair[0], pair[1]));
            }
        }
        for lanelet in &mut lanelets {
            lanelet.successors = links.iter().filter(|l| l.0 == lanelet.id).map(|l| l.1).collect();
            lanelet.predecessors = links.iter().filter(|l| l.1 == lanelet.id).map(|l| l.0).collect();
        }
        let mut notes = Vec::new();
        let on_paths: BTreeSet<LaneletId> =
            paths.iter().flat_map(|p| p.lanelet_ids.iter().copied()).collect();
        let off: Vec<String> = lanelets
            .iter()
            .filter(|l| !on_paths.contains(&l.id))
            .map(|l| l.id.to_string())
            .collect();
        if !off.is_empty() {
            notes.push(format!(
                "lanelets {} are on no reference path of the scenario",
                off.join(", ")
            ));
        }
        Map::assemble(MapParts {
            kind: MapKind::SigmarlScenario,
            numerics: Numerics::Float32,
            benchmark_id: None,
            lanelets,
            intersections: Vec::new(),
            regions: BTreeMap::new(),
            paths: Some(paths),
            notes,
            centre: CentreRule::LaneletCentreLines,
        })
    }
}

/// Each node's `(lat, lon)` [°] and where it is, by id.
type Nodes = HashMap<i64, ((f64, f64), SourceLocation)>;

/// Every node's `(lat, lon)` by id (all of them count, as in SigmaRL).
fn read_nodes(index: &LineIndex, doc: &Document) -> Result<Nodes, MapError> {
    let mut nodes = HashMap::new();
    for node in doc.root_element().children().filter(|c| c.has_tag_name("node")) {
        let location = loc(index, node);
        let id = crate::osm::nodes::int_attribute(index, node, "id")?;
        let number = |name: &str| -> Result<f64, MapError> {
            let raw = node.attribute(name);
            raw.and_then(|v| v.trim().parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .ok_or_else(|| MapError::InvalidCoordinate {
                    location,
                    message: format!("node {id} needs a finite `{name}`, found {raw:?}"),
                })
        };
        let at = (number("lat")?, number("lon")?);
        if let Some((_, first)) = nodes.insert(id, (at, location)) {
            return Err(crate::osm::nodes::duplicate("node", id, location, first));
        }
    }
    Ok(nodes)
}

/// Each lanelet's centre line in `f32`, by its `lanes` id.
type CentreLines = BTreeMap<LaneletId, (Vec<[f32; 2]>, SourceLocation)>;

/// The ways with a `lanes` tag as centre lines; ids must run 1..N once each.
fn read_ways(
    index: &LineIndex,
    doc: &Document,
    nodes: &Nodes,
    scale: f64,
    lane_width_m: f64,
) -> Result<CentreLines, MapError> {
    let root = doc.root_element();
    let (min_lat, min_lon) = nodes
        .values()
        .fold((f64::INFINITY, f64::INFINITY), |(a, b), ((lat, lon), _)| {
            (a.min(*lat), b.min(*lon))
        });
    let margin = lane_width_m * 1.2;
    let mut lines: CentreLines = BTreeMap::new();
    for way in root.children().filter(|c| c.has_tag_name("way")) {
        let location = loc(index, way);
        let Some(lanes) = crate::osm::nodes::tag(way, "lanes") else {
            continue;
        };
        let id: LaneletId = lanes
            .trim()
            .parse()
            .ok()
            .filter(|&id: &LaneletId| id >= 1)
            .ok_or_else(|| MapError::Malformed {
                location,
                message: format!(
                    "a way's `lanes` tag is its lanelet id, a positive integer; found {lanes:?}"
                ),
            })?;
        let mut points = Vec::new();
        for nd in way.children().filter(|c| c.has_tag_name("nd")) {
            let reference = crate::osm::nodes::int_attribute(index, nd, "ref")?;
            let ((lat, lon), _) = nodes.get(&reference).ok_or_else(|| MapError::Malformed {
                location: loc(index, nd),
                message: format!("lanelet {id} names node {reference}, which the file does not define"),
            })?;
            let x = (lat - min_lat) * scale + margin;
            let y = (lon - min_lon) * scale + margin;
            points.push([x as f32, y as f32]);
        }
        if points.len() < 2 {
            return Err(MapError::Malformed {
                location,
                message: format!(
                    "lanelet {id} has {} points; a centre line needs two",
                    points.len()
                ),
            });
        }
        if let Some((_, first)) = lines.insert(id, (points, location)) {
            return Err(crate::osm::nodes::duplicate(
                "lanelet (`lanes` tag)",
                id,
                location,
                first,
            ));
        }
    }
    if let Some(gap) = (1..=lines.len() as LaneletId).find(|id| !lines.contains_key(id)) {
        return Err(MapError::Malformed {
            location: loc(index, root),
            message: format!(
                "lanelet ids run 1..{} in SigmaRL's maps, but no way has `lanes={gap}`",
                lines.keys().last().copied().unwrap_or(0)
            ),
        });
    }
    Ok(lines)
}

/// The scenario's reference paths, numbered by their position in the table.
fn reference_paths(
    scenario: &SigmarlScenario,
    lines: &CentreLines,
    half_width: f32,
    root: SourceLocation,
) -> Result<Vec<ReferencePath>, MapError> {
    let mut paths = Vec::new();
    for (id, names) in scenario.reference_paths_ids.iter().enumerate() {
        let fail = |message: String| MapError::Malformed {
            location: root,
            message: format!("reference path {id} of the scenario: {message}"),
        };
        let ids: Vec<LaneletId> = names
            .iter()
            .map(|n| {
                n.trim()
                    .parse::<LaneletId>()
                    .ok()
                    .filter(|i| lines.contains_key(i))
                    .ok_or_else(|| fail(format!("the map has no lanelet `{n}`")))
            })
            .collect::<Result<_, _>>()?;
        if ids.is_empty() {
            return Err(fail("it names no lanelet".into()));
        }
        let mut centre: Vec<[f32; 2]> = Vec::new();
        for (k, lanelet) in ids.iter().enumerate() {
            let line = &lines[lanelet].0;
            if k > 0 && centre.last() != line.first() {
                return Err(fail(format!(
                    "lanelet {lanelet} does not begin where lanelet {} ends",
                    ids[k - 1]
                )));
            }
            centre.extend_from_slice(if k == 0 { line } else { &line[1..] });
        }
        let is_loop = ids.len() > 1 && ids.first() == ids.last();
        if is_loop {
            centre.pop();
        }
        let (left, right) = boundaries(&centre, half_width);
        let yaw = centre
            .windows(2)
            .map(|s| f64::from((s[1][1] - s[0][1]).atan2(s[1][0] - s[0][0])))
            .collect();
        let (left, right) = (widen(&left), widen(&right));
        paths.push(ReferencePath {
            id,
            lanelet_ids: ids,
            is_loop,
            center_line: widen(&centre),
            left_boundary_shared: left.clone(),
            right_boundary_shared: right.clone(),
            left_boundary: left,
            right_boundary: right,
            center_line_yaw_rad: yaw,
        });
    }
    Ok(paths)
}

/// Left and right boundaries ±`half_width` along the left normal of the segment leaving each
/// point (the last point: the last segment's), as SigmaRL's `_compute_boundaries` computes
/// them in `float32`.
fn boundaries(line: &[[f32; 2]], half_width: f32) -> (Vec<[f32; 2]>, Vec<[f32; 2]>) {
    let mut left = Vec::with_capacity(line.len());
    let mut right = Vec::with_capacity(line.len());
    let mut normal = [0.0f32; 2];
    for (i, c) in line.iter().enumerate() {
        if let Some(next) = line.get(i + 1) {
            let d = [next[0] - c[0], next[1] - c[1]];
            // torch.norm of (-dy, dx): one fused multiply-add over the rounded first square.
            let norm = d[0].mul_add(d[0], d[1] * d[1]).sqrt();
            normal = [-d[1], d[0]];
            if norm != 0.0 {
                normal = [normal[0] / norm, normal[1] / norm];
            }
        }
        let offset = [normal[0] * half_width, normal[1] * half_width];
        left.push([c[0] + offset[0], c[1] + offset[1]]);
        right.push([c[0] - offset[0], c[1] - offset[1]]);
    }
    (left, right)
}

fn widen(points: &[[f32; 2]]) -> Polyline {
    Polyline::new(
        points
            .iter()
            .map(|p| -> Point { [f64::from(p[0]), f64::from(p[1])] })
            .collect(),
    )
}
