//! Lanelets and intersections as read from a map file: geometry, topology and markings.
//! Pure data; loaders fill it, the path builder reads it.

use crate::error::SourceLocation;
use crate::polyline::Polyline;

/// A lanelet id as written in the map file: 64-bit and possibly negative, as OSM ids are
/// (JOSM writes negative ids for elements not yet uploaded). The reverse direction of a
/// lanelet2 lanelet tagged `one_way=no` has the id [`reversed_id`] gives (`-id - 1`).
pub type LaneletId = i64;

/// The id of the reverse direction of two-way lanelet `id`: `-id - 1` (bitwise not), so that
/// the reverse of `42440` is `-42441` and of `-7` is `6`; every 64-bit id has one, and taking
/// it twice gives `id` back. A file whose ids collide with a reverse is refused with the place.
pub fn reversed_id(id: LaneletId) -> LaneletId {
    !id
}

/// Driving direction of an adjacent lanelet relative to this one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DrivingDirection {
    /// Same direction (a parallel lane).
    Same,
    /// Opposite direction (oncoming lane).
    Opposite,
}

/// A lanelet beside this one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Adjacent {
    /// The neighbour's id.
    pub id: LaneletId,
    /// Its driving direction relative to this lanelet.
    pub direction: DrivingDirection,
    /// Whether a vehicle may change to it: on Lanelet2 maps as the routing graph decides from
    /// the shared bound's line type (`Some(false)` for an oncoming lane); `None` where the
    /// format's reader does not decide (CommonRoad).
    pub lane_change: Option<bool>,
}

/// One lanelet: two boundaries in driving direction, its centre line and its neighbours.
#[derive(Debug, Clone, PartialEq)]
pub struct Lanelet {
    /// Its id.
    pub id: LaneletId,
    /// Left boundary (in driving direction).
    pub left_boundary: Polyline,
    /// Right boundary (in driving direction).
    pub right_boundary: Polyline,
    /// Centre line: the point-wise mean of the boundaries (CommonRoad, whose boundaries have
    /// the same number of points), or Lanelet2's centre line (Lanelet2 maps).
    pub center_line: Polyline,
    /// Line marking of the left boundary (`solid`, `dashed`, ... as written), if any.
    pub left_line_marking: Option<String>,
    /// Line marking of the right boundary, if any.
    pub right_line_marking: Option<String>,
    /// Lanelets this one continues (in file order).
    pub predecessors: Vec<LaneletId>,
    /// Lanelets that continue this one (in file order).
    pub successors: Vec<LaneletId>,
    /// The lanelet to the left, if any.
    pub adjacent_left: Option<Adjacent>,
    /// The lanelet to the right, if any.
    pub adjacent_right: Option<Adjacent>,
    /// Lanelet types as written (`urban`, `highway`, ...).
    pub lanelet_types: Vec<String>,
    /// Where the lanelet is defined in the map file.
    pub location: SourceLocation,
}

/// One approach of an intersection and where it leads.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Incoming {
    /// The incoming element's id.
    pub id: i64,
    /// The lanelets that enter the intersection.
    pub incoming_lanelets: Vec<LaneletId>,
    /// Lanelets that turn right.
    pub successors_right: Vec<LaneletId>,
    /// Lanelets that go straight.
    pub successors_straight: Vec<LaneletId>,
    /// Lanelets that turn left.
    pub successors_left: Vec<LaneletId>,
}

impl Incoming {
    /// Every lanelet this incoming names.
    pub fn lanelet_ids(&self) -> impl Iterator<Item = LaneletId> + '_ {
        self.incoming_lanelets
            .iter()
            .chain(&self.successors_right)
            .chain(&self.successors_straight)
            .chain(&self.successors_left)
            .copied()
    }
}

/// An intersection element of a map.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Intersection {
    /// Its id.
    pub id: i64,
    /// Its approaches.
    pub incomings: Vec<Incoming>,
}
