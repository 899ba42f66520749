//! Maps: lanelets read from CommonRoad XML or lanelet2 OSM, reference paths numbered as
//! SigmaRL numbers them, lane polygons, and the polyline queries that observations and
//! metrics share.
//!
//! This crate owns geometry of the road. It knows nothing of vehicles' dynamics, policies or
//! metrics; it never reads a spec.

pub mod polyline;

pub use polyline::{Point, Polyline, SegmentDistance};

/// A reference path: the lane an agent follows, with its own-lane and shared (road) boundaries.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferencePath {
    /// The id a spec uses: SigmaRL's 0-based index (`predefined_ref_path_idx`, `ref_path_ids`).
    pub id: usize,
    /// The lanelets it runs through, in order.
    pub lanelet_ids: Vec<u32>,
    /// Whether it is a closed loop (its last centre-line point repeats the first).
    pub is_loop: bool,
    /// Point-wise mean of the own-lane boundaries.
    pub center_line: Polyline,
    /// Own-lane left boundary.
    pub left_boundary: Polyline,
    /// Own-lane right boundary.
    pub right_boundary: Polyline,
    /// Outer left boundary of the multi-lane road (what SigmaRL's simulation observes).
    pub left_boundary_shared: Polyline,
    /// Outer right boundary of the multi-lane road.
    pub right_boundary_shared: Polyline,
}
