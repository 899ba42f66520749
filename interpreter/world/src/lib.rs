//! Maps: lanelets read from CommonRoad XML or lanelet2 OSM, reference paths numbered as
//! SigmaRL numbers them, lane polygons, and the polyline queries that observations and
//! metrics share.
//!
//! This crate owns geometry of the road. It knows nothing of vehicles' dynamics, policies or
//! metrics; it never reads a spec.
//!
//! Modules: `commonroad` and `osm` read map files into [`Lanelet`]s (`osm` as the
//! `lanelet2` library reads them and its routing graph connects them); `paths` builds
//! reference paths with SigmaRL's recipe; `cpm_lab` holds SigmaRL's hard-coded tables of the
//! CPM Lab map; `generic` numbers paths of other maps; `builtin` writes this project's maps;
//! `map` ties them into [`Map`]; `nearest`, `segment_boxes` and `geometry` answer the
//! simulator's, the metrics' and the validator's queries.

pub mod builtin;
pub mod commonroad;
pub mod cpm_lab;
mod error;
pub mod generic;
mod geometry;
mod lanelet;
mod map;
mod nearest;
mod numerics;
pub mod osm;
mod paths;
pub mod polyline;
mod segment_boxes;
pub mod sigmarl_osm;
mod xml;

pub use error::{LineIndex, MapError, PathError, SourceLocation};
pub use geometry::{Polygon, band_polygon, point_in_polygon, segments_cross};
pub use lanelet::{Adjacent, DrivingDirection, Incoming, Intersection, Lanelet, LaneletId, reversed_id};
pub use map::{Bounds, Map, MapFormat, MapKind, PathSet};
pub use nearest::{PathIndex, SegmentGrid};
pub use numerics::Numerics;
pub use paths::{CentreRule, PathBuilder, SharedJoin, SharedRule};
pub use polyline::{Point, Polyline, SegmentDistance};
pub use segment_boxes::SegmentBoxes;
pub use sigmarl_osm::{ScenarioTable, SigmarlScenario};

/// A reference path: the lane an agent follows, with its own-lane and shared (road) boundaries.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferencePath {
    /// The id a spec uses: SigmaRL's 0-based index (`predefined_ref_path_idx`, `ref_path_ids`).
    pub id: usize,
    /// The lanelets it runs through, in order.
    pub lanelet_ids: Vec<LaneletId>,
    /// Whether it is a closed loop (its last centre-line point repeats the first).
    pub is_loop: bool,
    /// Point-wise mean of the own-lane boundaries (SigmaRL's recipe), or on Lanelet2 maps the
    /// lanelets' centre lines (Lanelet2's) joined.
    pub center_line: Polyline,
    /// Own-lane left boundary.
    pub left_boundary: Polyline,
    /// Own-lane right boundary.
    pub right_boundary: Polyline,
    /// Outer left boundary of the multi-lane road (what SigmaRL's simulation observes).
    pub left_boundary_shared: Polyline,
    /// Outer right boundary of the multi-lane road.
    pub right_boundary_shared: Polyline,
    /// Yaw of each centre-line segment, `atan2(dy, dx)` of the segment vector computed in the
    /// map's precision (one value per segment) [rad].
    pub center_line_yaw_rad: Vec<f64>,
}
