//! The [`Map`] the rest of cpmx uses: lanelets, numbered reference paths (SigmaRL's numbering
//! on the CPM Lab map, a generic one elsewhere, user-defined paths on top), bounds,
//! intersections, named regions, and the queries the simulator and `cpmx validate` need.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::OnceLock;

use roxmltree::Document;

use crate::ReferencePath;
use crate::cpm_lab;
use crate::error::{LineIndex, MapError, PathError};
use crate::lanelet::{Intersection, Lanelet, LaneletId};
use crate::nearest::PathIndex;
use crate::numerics::Numerics;
use crate::paths::{CentreRule, PathBuilder, SharedJoin, SharedRule};
use crate::polyline::{Point, dist};
use crate::{commonroad, generic, osm};

/// The format of a map file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MapFormat {
    /// Detect from the root element: `<commonRoad>` or `<osm>`.
    Auto,
    /// CommonRoad XML.
    CommonRoad,
    /// Lanelet2 OSM XML.
    Lanelet2Osm,
}

/// Which of SigmaRL's path sets of the CPM Lab map is numbered.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PathSet {
    /// The 40 loops of `cpm_entire` (ids 0..39); for other maps, the generic numbering.
    #[default]
    Entire,
    /// The 24 open intersection paths of `cpm_mixed` (ids 0..23).
    Intersection,
    /// The 4 merge-in paths (ids 0..3).
    MergeIn,
    /// The 4 merge-out paths (ids 0..3).
    MergeOut,
}

/// What kind of map this is, which decides the path numbering.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MapKind {
    /// SigmaRL's CPM Lab map (recognised by its lanelets and topology).
    CpmLab,
    /// Any other map file (generic numbering, see the `generic` module).
    Generic,
    /// A map written by this project (`stdlib:NAME`).
    Builtin(&'static str),
    /// One of SigmaRL's scenario maps (`map: {sigmarl: NAME}`): its paths are the scenario
    /// table's.
    SigmarlScenario,
}

/// Axis-aligned bounds of a map [m].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    /// Smallest x [m].
    pub min_x_m: f64,
    /// Smallest y [m].
    pub min_y_m: f64,
    /// Largest x [m].
    pub max_x_m: f64,
    /// Largest y [m].
    pub max_y_m: f64,
}

impl Bounds {
    /// The bounding box of `points` (`None` when there are none).
    pub fn of(points: impl IntoIterator<Item = Point>) -> Option<Self> {
        let mut b: Option<Bounds> = None;
        for p in points {
            let c = b.get_or_insert(Bounds {
                min_x_m: p[0],
                min_y_m: p[1],
                max_x_m: p[0],
                max_y_m: p[1],
            });
            c.min_x_m = c.min_x_m.min(p[0]);
            c.min_y_m = c.min_y_m.min(p[1]);
            c.max_x_m = c.max_x_m.max(p[0]);
            c.max_y_m = c.max_y_m.max(p[1]);
        }
        b
    }
}

/// A loaded map with its numbered reference paths.
#[derive(Debug, Clone)]
pub struct Map {
    kind: MapKind,
    numerics: Numerics,
    benchmark_id: Option<String>,
    /// Every lanelet of the file (paths are built from these even when a region is active).
    all_lanelets: Vec<Lanelet>,
    intersections: Vec<Intersection>,
    regions: BTreeMap<String, Vec<LaneletId>>,
    region: Option<String>,
    bounds: Bounds,
    path_set: PathSet,
    /// Paths a built-in map brings (its [`PathSet::Entire`]).
    fixed_paths: Option<Vec<ReferencePath>>,
    paths: BTreeMap<usize, ReferencePath>,
    /// Nearest-segment grids, built on first use.
    indexes: BTreeMap<usize, OnceLock<PathIndex>>,
    /// What the loader read but did not use.
    notes: Vec<String>,
    /// How paths' centre lines are made (Lanelet2 maps join the lanelets' own).
    centre: CentreRule,
    /// How paths' shared boundaries are joined (the SigmaRL release they follow).
    join: SharedJoin,
}

/// The parts a loader or built-in map hands over.
pub(crate) struct MapParts {
    pub kind: MapKind,
    pub numerics: Numerics,
    pub benchmark_id: Option<String>,
    pub lanelets: Vec<Lanelet>,
    pub intersections: Vec<Intersection>,
    pub regions: BTreeMap<String, Vec<LaneletId>>,
    /// Paths given directly (built-in maps); `None` numbers them from the lanelets.
    pub paths: Option<Vec<ReferencePath>>,
    /// What the loader read but did not use.
    pub notes: Vec<String>,
    /// How paths' centre lines are made.
    pub centre: CentreRule,
}

impl Map {
    /// Loads a map file, detecting its format from the root element.
    pub fn load(path: impl AsRef<Path>) -> Result<Map, MapError> {
        Self::load_with_format(path, MapFormat::Auto)
    }

    /// Loads a map file of the given format.
    pub fn load_with_format(path: impl AsRef<Path>, format: MapFormat) -> Result<Map, MapError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| MapError::Io {
            path: path.to_owned(),
            source,
        })?;
        Self::from_str(&text, format)
    }

    /// Reads a map from its text.
    ///
    /// CommonRoad coordinates are read as SigmaRL reads them (rounded to `f32`, path
    /// arithmetic in `f32`), so the CPM Lab map's paths equal SigmaRL's bit for bit; lanelet2
    /// maps are read in `f64`.
    pub fn from_str(text: &str, format: MapFormat) -> Result<Map, MapError> {
        // Check for well-formedness and find the format.
        let doc = Document::parse(text).map_err(|e| commonroad::xml_error(text, &e))?;
        let index = LineIndex::new(text);
        let root = doc.root_element();
        let format = match (format, root.tag_name().name()) {
            (MapFormat::Auto, "commonRoad") => MapFormat::CommonRoad,
            (MapFormat::Auto, "osm") => MapFormat::Lanelet2Osm,
            (MapFormat::Auto, other) => {
                return Err(MapError::UnknownFormat {
                    location: commonroad::loc(&index, root),
                    message: format!(
                        "cannot detect the map format from root element <{other}> \
                         (expected <commonRoad> or <osm>)"
                    ),
                });
            }
            (f, _) => f,
        };

        // Read the lanelets.
        let parts = match format {
            MapFormat::Lanelet2Osm => {
                let osm = osm::read_document(&doc, &index)?;
                MapParts {
                    kind: MapKind::Generic,
                    numerics: Numerics::Float64,
                    benchmark_id: None,
                    lanelets: osm.lanelets,
                    intersections: Vec::new(),
                    regions: BTreeMap::new(),
                    paths: None,
                    notes: osm.notes,
                    centre: CentreRule::LaneletCentreLines,
                }
            }
            _ => {
                let numerics = Numerics::Float32;
                let cr = commonroad::read_document(&doc, &index, numerics)?;
                let kind = if cpm_lab::is_cpm_lab(&cr.lanelets) {
                    MapKind::CpmLab
                } else {
                    MapKind::Generic
                };
                MapParts {
                    kind,
                    numerics,
                    benchmark_id: cr.benchmark_id,
                    regions: intersection_regions(&cr.intersections),
                    lanelets: cr.lanelets,
                    intersections: cr.intersections,
                    paths: None,
                    notes: cr.notes,
                    centre: CentreRule::PointwiseMean,
                }
            }
        };
        if parts.lanelets.is_empty() {
            let what = match format {
                MapFormat::Lanelet2Osm => {
                    "no relation tagged `type=lanelet` that vehicles may drive on; crosswalks and \
                     sidewalks do not count"
                }
                _ => "no <lanelet> element",
            };
            return Err(MapError::Malformed {
                location: commonroad::loc(&index, root),
                message: format!("the map has no lanelets ({what})"),
            });
        }
        Self::assemble(parts)
    }

    /// Assembles a map and numbers its paths.
    pub(crate) fn assemble(parts: MapParts) -> Result<Map, MapError> {
        if parts.lanelets.is_empty() {
            return Err(MapError::NoLanelets);
        }
        let bounds = if parts.kind == MapKind::CpmLab {
            let ([min_x_m, max_x_m], [min_y_m, max_y_m]) = cpm_lab::BOUNDS_M;
            Bounds {
                min_x_m,
                min_y_m,
                max_x_m,
                max_y_m,
            }
        } else {
            lanelet_bounds(parts.lanelets.iter()).ok_or(MapError::NoLanelets)?
        };
        let mut map = Map {
            kind: parts.kind,
            numerics: parts.numerics,
            benchmark_id: parts.benchmark_id,
            all_lanelets: parts.lanelets,
            intersections: parts.intersections,
            regions: parts.regions,
            region: None,
            bounds,
            path_set: PathSet::Entire,
            fixed_paths: parts.paths,
            paths: BTreeMap::new(),
            indexes: BTreeMap::new(),
            notes: parts.notes,
            centre: parts.centre,
            join: SharedJoin::Blend,
        };
        if map.kind == MapKind::Generic {
            let numbering = generic::generic_path_lanelets(&map.all_lanelets);
            map.set_paths(map.build_paths(&numbering.sequences)?);
            map.note_numbering(&numbering);
        } else {
            map.set_paths(map.number_paths(PathSet::Entire)?);
        }
        Ok(map)
    }

    /// Notes how a generic numbering went: where the enumeration stopped at its limits (and
    /// coverage walks took over), and the lanelets on no path because their chains'
    /// boundaries do not line up.
    fn note_numbering(&mut self, numbering: &generic::GenericNumbering) {
        if numbering.stopped_early {
            self.notes.push(format!(
                "the enumeration of chains and loops stopped at its limit ({} paths or {} search \
                 steps) after {} paths; paths {}.. are coverage walks that put every other \
                 lanelet on a path",
                generic::MAX_GENERIC_PATHS,
                generic::MAX_SEARCH_STEPS,
                numbering.enumerated,
                numbering.enumerated
            ));
        }
        let on_paths: std::collections::HashSet<LaneletId> = self
            .paths
            .values()
            .flat_map(|p| p.lanelet_ids.iter().copied())
            .collect();
        let mut missing: Vec<LaneletId> = self
            .all_lanelets
            .iter()
            .map(|l| l.id)
            .filter(|id| !on_paths.contains(id))
            .collect();
        if missing.is_empty() {
            return;
        }
        missing.sort_unstable();
        let shown: Vec<String> = missing.iter().take(10).map(ToString::to_string).collect();
        let more = if missing.len() > shown.len() { ", ..." } else { "" };
        self.notes.push(format!(
            "{} lanelets are on no reference path ({}{more}): the chains through them have \
             boundaries that do not line up; name paths through them with \
             `ref_paths: [{{id, lanelets}}]`",
            missing.len(),
            shown.join(", ")
        ));
    }

    /// The same map with another of SigmaRL's path sets numbered (CPM Lab map only; every map
    /// has [`PathSet::Entire`]). Drops user-defined paths and any region.
    pub fn with_path_set(&self, set: PathSet) -> Result<Map, MapError> {
        let mut map = self.clone();
        map.region = None;
        map.path_set = set;
        map.set_paths(map.number_paths(set)?);
        Ok(map)
    }

    /// The lanelet sequences of a path set, numbered by position.
    fn number_paths(&self, set: PathSet) -> Result<Vec<ReferencePath>, PathError> {
        let sequences: Vec<Vec<LaneletId>> = match (self.kind, set) {
            (MapKind::CpmLab, PathSet::Entire) => (0..cpm_lab::PATH_TO_LOOP.len())
                .filter_map(cpm_lab::entire_path_lanelets)
                .collect(),
            (MapKind::CpmLab, PathSet::Intersection) => to_vecs(&cpm_lab::INTERSECTION_PATHS),
            (MapKind::CpmLab, PathSet::MergeIn) => to_vecs(&cpm_lab::MERGE_IN_PATHS),
            (MapKind::CpmLab, PathSet::MergeOut) => to_vecs(&cpm_lab::MERGE_OUT_PATHS),
            (MapKind::Builtin(_) | MapKind::SigmarlScenario, PathSet::Entire) => {
                return Ok(self.fixed_paths.clone().unwrap_or_default());
            }
            (_, PathSet::Entire) => generic::generic_path_lanelets(&self.all_lanelets).sequences,
            (_, set) => {
                return Err(PathError::SetUnavailable {
                    set: format!("{set:?}"),
                });
            }
        };
        self.build_paths(&sequences)
    }

    /// Builds numbered paths from lanelet sequences; on generic maps a chain whose boundaries
    /// do not line up is skipped and its id stays unused.
    fn build_paths(&self, sequences: &[Vec<LaneletId>]) -> Result<Vec<ReferencePath>, PathError> {
        let builder = self.builder();
        let mut paths = Vec::with_capacity(sequences.len());
        for (id, lanelets) in sequences.iter().enumerate() {
            match builder.build(id, lanelets) {
                Ok(p) => paths.push(p),
                // Generic chains whose own boundaries do not line up have no centre line;
                // they are skipped (their id stays unused).
                Err(PathError::BoundaryMismatch { .. }) if self.kind == MapKind::Generic => {}
                Err(e) => return Err(e),
            }
        }
        Ok(paths)
    }

    fn builder(&self) -> PathBuilder<'_> {
        let rule = if self.kind == MapKind::CpmLab {
            SharedRule::Groups(&cpm_lab::BOUNDARY_SHARING_GROUPS)
        } else {
            SharedRule::Adjacency
        };
        PathBuilder::new(&self.all_lanelets, self.numerics, rule)
            .with_centre_rule(self.centre)
            .with_shared_join(self.join)
    }

    /// The same map with every path built from lanelets rebuilt with its shared boundaries
    /// joined by `join` (SigmaRL 1.2.0's paths: [`SharedJoin::LikeOwn`]). A built-in map's fixed
    /// paths stay as they are.
    pub fn with_shared_join(mut self, join: SharedJoin) -> Result<Map, PathError> {
        if self.join == join || self.fixed_paths.is_some() {
            return Ok(self);
        }
        self.join = join;
        let builder = self.builder();
        let rebuilt = self
            .paths
            .values()
            .map(|p| builder.build(p.id, &p.lanelet_ids))
            .collect::<Result<Vec<_>, _>>()?;
        self.set_paths(rebuilt);
        Ok(self)
    }

    fn set_paths(&mut self, paths: Vec<ReferencePath>) {
        self.indexes = paths.iter().map(|p| (p.id, OnceLock::new())).collect();
        self.paths = paths.into_iter().map(|p| (p.id, p)).collect();
    }

    /// Adds (or replaces) a user-defined path `id` through `lanelets`, as a spec's
    /// `ref_paths: [{id, lanelets}]` does. Consecutive lanelets must be successors. It is built
    /// with the same recipe as SigmaRL's paths (on the CPM Lab map with SigmaRL's
    /// boundary-sharing groups).
    pub fn add_reference_path(&mut self, id: usize, lanelets: &[LaneletId]) -> Result<(), PathError> {
        let path = self.builder().build(id, lanelets)?;
        self.indexes.insert(id, OnceLock::new());
        self.paths.insert(id, path);
        Ok(())
    }

    /// The same map restricted to the named region: only the region's lanelets, only the
    /// paths (of the current set, with their ids and whole geometry unchanged) that run
    /// through at least one of them, and bounds shrunk to those lanelets. On maps with
    /// intersection elements (the CPM Lab map), region `intersection` is the union of every
    /// `<intersection>`'s incoming lanelets and their right/straight/left successors, and
    /// `intersection-<id>` each single one.
    pub fn with_region(&self, name: &str) -> Result<Map, MapError> {
        let Some(ids) = self.regions.get(name) else {
            return Err(MapError::UnknownRegion {
                name: name.to_owned(),
                available: self.region_names().collect::<Vec<_>>().join(", "),
            });
        };
        let mut map = self.clone();
        map.region = Some(name.to_owned());
        map.paths
            .retain(|_, p| p.lanelet_ids.iter().any(|l| ids.contains(l)));
        map.indexes.retain(|id, _| map.paths.contains_key(id));
        if let Some(b) = lanelet_bounds(self.all_lanelets.iter().filter(|l| ids.contains(&l.id))) {
            map.bounds = b;
        }
        Ok(map)
    }

    /// What the loader read but did not use (regulatory elements, areas, lanelets not for
    /// cars, obstacles, ...), one line each.
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// What kind of map this is.
    pub fn kind(&self) -> MapKind {
        self.kind
    }

    /// Whether this is SigmaRL's CPM Lab map.
    pub fn is_cpm_lab(&self) -> bool {
        self.kind == MapKind::CpmLab
    }

    /// The precision its coordinates and paths are computed in.
    pub fn numerics(&self) -> Numerics {
        self.numerics
    }

    /// The CommonRoad `benchmarkID`, if any.
    pub fn benchmark_id(&self) -> Option<&str> {
        self.benchmark_id.as_deref()
    }

    /// The numbered path set.
    pub fn path_set(&self) -> PathSet {
        self.path_set
    }

    /// The active region, if the map was restricted.
    pub fn region(&self) -> Option<&str> {
        self.region.as_deref()
    }

    /// Lanelets in file order (only the region's when a region is active).
    pub fn lanelets(&self) -> impl Iterator<Item = &Lanelet> {
        let region = self.region.as_ref().and_then(|r| self.regions.get(r));
        self.all_lanelets
            .iter()
            .filter(move |l| region.is_none_or(|ids| ids.contains(&l.id)))
    }

    /// The lanelet with this id (any lanelet of the file).
    pub fn lanelet(&self, id: LaneletId) -> Option<&Lanelet> {
        self.all_lanelets.iter().find(|l| l.id == id)
    }

    /// The intersection elements.
    pub fn intersections(&self) -> &[Intersection] {
        &self.intersections
    }

    /// Names of the regions `with_region` accepts.
    pub fn region_names(&self) -> impl Iterator<Item = &str> {
        self.regions.keys().map(String::as_str)
    }

    /// The lanelets of a named region.
    pub fn region_lanelets(&self, name: &str) -> Option<&[LaneletId]> {
        self.regions.get(name).map(Vec::as_slice)
    }

    /// The map's bounds (for the CPM Lab map SigmaRL's hard-coded 4.5 m x 4.0 m).
    pub fn bounds(&self) -> Bounds {
        self.bounds
    }

    /// The reference path with this id.
    pub fn reference_path(&self, id: usize) -> Option<&ReferencePath> {
        self.paths.get(&id)
    }

    /// All reference paths, by ascending id.
    pub fn reference_paths(&self) -> impl Iterator<Item = &ReferencePath> {
        self.paths.values()
    }

    /// The ids a spec may use, ascending.
    pub fn valid_path_ids(&self) -> Vec<usize> {
        self.paths.keys().copied().collect()
    }

    /// The nearest-segment grids of a path, for fast per-step queries (built on first use,
    /// a few milliseconds per path; thread-safe).
    pub fn path_index(&self, id: usize) -> Option<&PathIndex> {
        let path = self.paths.get(&id)?;
        Some(self.indexes.get(&id)?.get_or_init(|| PathIndex::new(path)))
    }

    /// The pose at arc length `arc_length_m` along path `path_id`'s centre line: the point by
    /// linear interpolation and the yaw of its segment (zero-length segments are skipped; at a
    /// joint the earlier segment is used). Loops wrap around; open paths give `None` outside
    /// `[0, length]`.
    pub fn pose_at(&self, path_id: usize, arc_length_m: f64) -> Option<(f64, f64, f64)> {
        let path = self.paths.get(&path_id)?;
        let pts = &path.center_line.points;
        let length_m = path.center_line.length_m();
        if !arc_length_m.is_finite() || length_m <= 0.0 {
            return None;
        }
        let s = if path.is_loop {
            arc_length_m.rem_euclid(length_m)
        } else if (0.0..=length_m).contains(&arc_length_m) {
            arc_length_m
        } else {
            return None;
        };
        let mut start_m = 0.0;
        let mut last = None;
        for w in pts.windows(2) {
            let seg_m = dist(w[0], w[1]);
            if seg_m <= 0.0 {
                continue;
            }
            last = Some((w[0], w[1], seg_m, start_m));
            if s <= start_m + seg_m {
                break;
            }
            start_m += seg_m;
        }
        let (a, b, seg_m, start_m) = last?;
        let t = ((s - start_m) / seg_m).clamp(0.0, 1.0);
        let yaw_rad = (b[1] - a[1]).atan2(b[0] - a[0]);
        Some((a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), yaw_rad))
    }

    /// Whether a rectangle footprint lies on path `path_id`'s road (between its shared
    /// boundaries); `None` for an unknown path. See [`ReferencePath::footprint_on_road`].
    pub fn footprint_on_road(&self, path_id: usize, corners: &[Point; 4]) -> Option<bool> {
        Some(self.paths.get(&path_id)?.footprint_on_road(corners))
    }

    /// How far [m] a footprint reaches beyond the road of reference path `path_id` (0 on the
    /// road); `None` for an unknown path. See [`ReferencePath::footprint_off_road_m`].
    pub fn footprint_off_road_m(&self, path_id: usize, corners: &[Point; 4]) -> Option<f64> {
        Some(self.paths.get(&path_id)?.footprint_off_road_m(corners))
    }
}

fn to_vecs(paths: &[&[LaneletId]]) -> Vec<Vec<LaneletId>> {
    paths.iter().map(|p| p.to_vec()).collect()
}

fn lanelet_bounds<'a>(lanelets: impl Iterator<Item = &'a Lanelet>) -> Option<Bounds> {
    Bounds::of(lanelets.flat_map(|l| {
        l.left_boundary
            .points
            .iter()
            .chain(&l.right_boundary.points)
            .copied()
    }))
}

/// Regions from intersection elements: `intersection` (all of them) and `intersection-<id>`.
pub(crate) fn intersection_regions(intersections: &[Intersection]) -> BTreeMap<String, Vec<LaneletId>> {
    let mut regions = BTreeMap::new();
    let mut all = Vec::new();
    for i in intersections {
        let mut ids: Vec<LaneletId> = i.incomings.iter().flat_map(|c| c.lanelet_ids()).collect();
        ids.sort_unstable();
        ids.dedup();
        all.extend_from_slice(&ids);
        regions.insert(format!("intersection-{}", i.id), ids);
    }
    if !intersections.is_empty() {
        all.sort_unstable();
        all.dedup();
        regions.insert("intersection".to_owned(), all);
    }
    regions
}
