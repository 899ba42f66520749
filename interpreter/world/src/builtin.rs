//! Maps written by this project, generated in code (`stdlib:NAME`).
//!
//! `intersection`: a four-way intersection at the CPM Lab's scale. Roads run north-south and
//! east-west through the centre (1.65 m, 1.65 m); each has two lanes of 0.15 m, one per
//! direction (right-hand traffic). The intersection box is 0.9 m x 0.9 m; each arm is 1.2 m
//! long, so the map spans 3.3 m x 3.3 m from the origin. Turns are circular arcs centred on
//! the box corners: right turns have a centre-line radius of 0.375 m, left turns 0.525 m (a
//! 1:18 car with wheelbase 0.15 m and 31 deg steering manages about 0.25 m).
//!
//! Lanelets: incoming arms N, E, S, W = 1..4 (N = the arm north of the box, driven towards
//! the box), outgoing arms N, E, S, W = 5..8, and the 12 movements inside the box = 9..20
//! (`9 + path id`). Reference paths (12, open): id = `3 * entry + movement` with entries
//! N, E, S, W = 0..3 and movements right, straight, left = 0..2; each runs incoming arm ->
//! movement -> outgoing arm. Shared boundaries are the road: the own right boundary and,
//! on the left, the far edge of the oncoming lane (0.225 m left of the centre line).
//! Region `intersection` = the `<intersection>`-style element: incoming arms and the 12
//! movements. Every polyline has a point at least every 5 cm; all five polylines of a path
//! have the same number of points.

use std::f64::consts::{FRAC_PI_2, PI};

use crate::ReferencePath;
use crate::error::MapError;
use crate::lanelet::{Adjacent, DrivingDirection, Incoming, Intersection, Lanelet, LaneletId};
use crate::map::{Map, MapKind, MapParts, intersection_regions};
use crate::numerics::Numerics;
use crate::polyline::{Point, Polyline};

/// Lane width [m].
pub const LANE_WIDTH_M: f64 = 0.15;
/// Half the side of the intersection box [m].
pub const HALF_BOX_M: f64 = 0.45;
/// Length of each arm [m].
pub const ARM_LENGTH_M: f64 = 1.2;
/// Largest distance between consecutive points of any polyline [m].
pub const MAX_SPACING_M: f64 = 0.05;

/// Names of the built-in maps.
pub fn builtin_names() -> &'static [&'static str] {
    &["intersection"]
}

impl Map {
    /// A built-in map by name (see [`builtin_names`]).
    pub fn builtin(name: &str) -> Result<Map, MapError> {
        match name {
            "intersection" => intersection(),
            _ => Err(MapError::UnknownBuiltin(name.to_owned())),
        }
    }
}

/// A piece of centre line: a straight or a circular arc.
#[derive(Debug, Clone, Copy)]
enum Piece {
    Line {
        start: Point,
        heading_rad: f64,
        length_m: f64,
    },
    Arc {
        center: Point,
        radius_m: f64,
        /// Heading at the start [rad].
        heading_rad: f64,
        /// Signed turn (positive = left) [rad].
        sweep_rad: f64,
    },
}

impl Piece {
    /// Point and heading at fraction `f` of the piece.
    fn at(self, f: f64) -> (Point, f64) {
        match self {
            Piece::Line {
                start,
                heading_rad,
                length_m,
            } => {
                let (s, c) = heading_rad.sin_cos();
                (
                    [start[0] + f * length_m * c, start[1] + f * length_m * s],
                    heading_rad,
                )
            }
            Piece::Arc {
                center,
                radius_m,
                heading_rad,
                sweep_rad,
            } => {
                let h = heading_rad + f * sweep_rad;
                // The centre lies to the left for a left turn, to the right for a right turn.
                let side = sweep_rad.signum();
                let (s, c) = h.sin_cos();
                (
                    [center[0] + side * radius_m * s, center[1] - side * radius_m * c],
                    h,
                )
            }
        }
    }

    /// Number of segments so that even the outermost offset polyline keeps `MAX_SPACING_M`.
    fn segments(self) -> usize {
        let outer_m = match self {
            Piece::Line { length_m, .. } => length_m,
            Piece::Arc {
                radius_m, sweep_rad, ..
            } => sweep_rad.abs() * (radius_m + 1.5 * LANE_WIDTH_M),
        };
        (outer_m / MAX_SPACING_M).ceil().max(1.0) as usize
    }

    /// The piece sampled at lateral `offset_m` (positive = left of the driving direction).
    fn sample(self, offset_m: f64) -> Vec<Point> {
        let n = self.segments();
        (0..=n)
            .map(|i| {
                let (p, h) = self.at(i as f64 / n as f64);
                let (s, c) = h.sin_cos();
                [p[0] - offset_m * s, p[1] + offset_m * c]
            })
            .collect()
    }

    fn end(self) -> (Point, f64) {
        self.at(1.0)
    }
}

/// Joins sampled pieces, dropping each joint's repeated point.
fn join(pieces: &[Piece], offset_m: f64) -> Vec<Point> {
    let mut out: Vec<Point> = Vec::new();
    for p in pieces {
        let pts = p.sample(offset_m);
        let skip = usize::from(!out.is_empty());
        out.extend(pts.into_iter().skip(skip));
    }
    out
}

fn lanelet(id: LaneletId, piece: Piece) -> Lanelet {
    let half = LANE_WIDTH_M / 2.0;
    let left = piece.sample(half);
    let right = piece.sample(-half);
    let center = left
        .iter()
        .zip(&right)
        .map(|(&l, &r)| Numerics::Float64.mean(l, r))
        .collect();
    Lanelet {
        id,
        left_boundary: Polyline::new(left),
        right_boundary: Polyline::new(right),
        center_line: Polyline::new(center),
        left_line_marking: Some("dashed".to_owned()),
        right_line_marking: Some("solid".to_owned()),
        predecessors: Vec::new(),
        successors: Vec::new(),
        adjacent_left: None,
        adjacent_right: None,
        lanelet_types: vec!["urban".to_owned()],
        location: Default::default(),
    }
}

fn intersection() -> Result<Map, MapError> {
    let half = LANE_WIDTH_M / 2.0;
    let c = HALF_BOX_M + ARM_LENGTH_M;
    let center = [c, c];
    // Travel headings when entering from N, E, S, W.
    let entry_heading = [-FRAC_PI_2, PI, FRAC_PI_2, 0.0];
    // The arm a vehicle leaves through, by exit heading.
    let arm_of_exit = |h: f64| {
        let (s, co) = h.sin_cos();
        if s > 0.5 {
            0 // north
        } else if co > 0.5 {
            1 // east
        } else if s < -0.5 {
            2 // south
        } else {
            3 // west
        }
    };
    let lane_point = |h: f64, back_m: f64| {
        // On the right-hand lane of travel heading h, `back_m` before the centre.
        let (s, co) = h.sin_cos();
        [
            center[0] - back_m * co + half * s,
            center[1] - back_m * s - half * co,
        ]
    };

    // Arms: incoming lanelets 1..4 and outgoing 5..8.
    let mut lanelets: Vec<Lanelet> = Vec::new();
    for (arm, &h) in entry_heading.iter().enumerate() {
        let start = lane_point(h, HALF_BOX_M + ARM_LENGTH_M);
        lanelets.push(lanelet(
            arm as LaneletId + 1,
            Piece::Line {
                start,
                heading_rad: h,
                length_m: ARM_LENGTH_M,
            },
        ));
    }
    for (arm, &entry_h) in entry_heading.iter().enumerate() {
        let h = entry_h + PI;
        lanelets.push(lanelet(
            arm as LaneletId + 5,
            Piece::Line {
                start: lane_point(h, -HALF_BOX_M),
                heading_rad: h,
                length_m: ARM_LENGTH_M,
            },
        ));
    }

    // Movements in the box: lanelets 9..20 and the 12 paths.
    let mut paths = Vec::new();
    let mut incomings = Vec::new();
    for (entry, &h) in entry_heading.iter().enumerate() {
        let start = lane_point(h, HALF_BOX_M);
        let (s, co) = h.sin_cos();
        let (right, left) = ([s, -co], [-s, co]);
        let moves = [
            (HALF_BOX_M - half, -FRAC_PI_2, right),
            (0.0, 0.0, right),
            (HALF_BOX_M + half, FRAC_PI_2, left),
        ];
        let mut ids = [0; 3];
        for (movement, &(radius_m, sweep_rad, side)) in moves.iter().enumerate() {
            let id = 3 * entry + movement;
            let piece = if sweep_rad == 0.0 {
                Piece::Line {
                    start,
                    heading_rad: h,
                    length_m: 2.0 * HALF_BOX_M,
                }
            } else {
                Piece::Arc {
                    center: [start[0] + radius_m * side[0], start[1] + radius_m * side[1]],
                    radius_m,
                    heading_rad: h,
                    sweep_rad,
                }
            };
            let (end, exit_h) = piece.end();
            let exit_arm = arm_of_exit(exit_h);
            let box_id = 9 + id as LaneletId;
            ids[movement] = box_id;
            let mut l = lanelet(box_id, piece);
            l.predecessors.push(entry as LaneletId + 1);
            l.successors.push(exit_arm as LaneletId + 5);
            lanelets.push(l);
            let arms = [
                Piece::Line {
                    start: lane_point(h, HALF_BOX_M + ARM_LENGTH_M),
                    heading_rad: h,
                    length_m: ARM_LENGTH_M,
                },
                piece,
                Piece::Line {
                    start: end,
                    heading_rad: exit_h,
                    length_m: ARM_LENGTH_M,
                },
            ];
            paths.push(path(
                id,
                vec![entry as LaneletId + 1, box_id, exit_arm as LaneletId + 5],
                &arms,
            ));
        }
        incomings.push(Incoming {
            id: entry as i64 + 1,
            incoming_lanelets: vec![entry as LaneletId + 1],
            successors_right: vec![ids[0]],
            successors_straight: vec![ids[1]],
            successors_left: vec![ids[2]],
        });
    }

    // Topology of the arms.
    for arm in 0..4usize {
        let box_ids: Vec<LaneletId> = (0..3).map(|m| 9 + (3 * arm + m) as LaneletId).collect();
        let from: Vec<LaneletId> = lanelets
            .iter()
            .filter(|l| l.successors.contains(&(arm as LaneletId + 5)))
            .map(|l| l.id)
            .collect();
        let opposite = |id| {
            Some(Adjacent {
                id,
                direction: DrivingDirection::Opposite,
                lane_change: Some(false),
            })
        };
        if let Some(l) = lanelets.get_mut(arm) {
            l.successors = box_ids;
            l.adjacent_left = opposite(arm as LaneletId + 5);
        }
        if let Some(l) = lanelets.get_mut(arm + 4) {
            l.predecessors = from;
            l.adjacent_left = opposite(arm as LaneletId + 1);
        }
    }
    let intersections = vec![Intersection { id: 100, incomings }];
    Map::assemble(MapParts {
        kind: MapKind::Builtin("intersection"),
        numerics: Numerics::Float64,
        benchmark_id: None,
        regions: intersection_regions(&intersections),
        lanelets,
        intersections,
        paths: Some(paths),
        notes: Vec::new(),
        centre: crate::paths::CentreRule::PointwiseMean,
    })
}

/// A path through `pieces` with the boundaries at their offsets.
fn path(id: usize, lanelet_ids: Vec<LaneletId>, pieces: &[Piece]) -> ReferencePath {
    let n = Numerics::Float64;
    let half = LANE_WIDTH_M / 2.0;
    let left = join(pieces, half);
    let right = join(pieces, -half);
    let center: Vec<Point> = left.iter().zip(&right).map(|(&l, &r)| n.mean(l, r)).collect();
    let center_line_yaw_rad = center.windows(2).map(|w| n.atan2(n.diff(w[0], w[1]))).collect();
    ReferencePath {
        id,
        lanelet_ids,
        is_loop: false,
        center_line: Polyline::new(center),
        left_boundary_shared: Polyline::new(join(pieces, half + LANE_WIDTH_M)),
        right_boundary_shared: Polyline::new(right.clone()),
        left_boundary: Polyline::new(left),
        right_boundary: Polyline::new(right),
        center_line_yaw_rad,
    }
}
