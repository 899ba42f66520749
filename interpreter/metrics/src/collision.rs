//! Signed distances between two vehicle footprints (negative = overlapping): SigmaRL's
//! corner-projection rule and the true minimum-translation-vector distance (parry).
//!
//! This module owns the pairwise geometry only; when a distance becomes an event is the
//! hysteresis module's business.

use cpmx_vehicle::{Footprint, VehicleParams, footprint_corners};
use parry2d_f64::math::{Pose, Vector};
use parry2d_f64::query;
use parry2d_f64::shape::Cuboid;

use crate::config::CollisionGeometry;

/// A footprint with the pose it was built from (parry needs the pose, SigmaRL the corners).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlacedBox {
    /// Centre [m].
    pub centre_m: [f64; 2],
    /// Heading [rad].
    pub yaw_rad: f64,
    /// Half length and half width [m].
    pub half_extents_m: [f64; 2],
    /// Corners in SigmaRL's order (front-left, front-right, rear-right, rear-left).
    pub corners_m: Footprint,
}

impl PlacedBox {
    /// The footprint of `vehicle` at a pose.
    pub fn from_pose(vehicle: &VehicleParams, x_m: f64, y_m: f64, yaw_rad: f64) -> Self {
        Self {
            centre_m: [x_m, y_m],
            yaw_rad,
            half_extents_m: [vehicle.length_m / 2.0, vehicle.width_m / 2.0],
            corners_m: footprint_corners(vehicle, x_m, y_m, yaw_rad),
        }
    }
}

/// Signed distance between two boxes with the chosen geometry [m].
pub fn signed_distance_m(geometry: CollisionGeometry, a: &PlacedBox, b: &PlacedBox) -> f64 {
    match geometry {
        CollisionGeometry::Mtv => mtv_distance_m(a, b),
        CollisionGeometry::SigmarlMtv => sigmarl_mtv_distance_m(&a.corners_m, &b.corners_m),
    }
}

/// The true signed distance: minus the penetration depth (parry's `contact`, the length of
/// the minimum translation vector) when the boxes overlap, else their Euclidean distance
/// (parry's `distance`; 0 when touching).
///
/// The two boxes are put in a canonical order first, so the result is bit-for-bit symmetric.
pub fn mtv_distance_m(a: &PlacedBox, b: &PlacedBox) -> f64 {
    let key = |p: &PlacedBox| {
        [
            p.centre_m[0],
            p.centre_m[1],
            p.yaw_rad,
            p.half_extents_m[0],
            p.half_extents_m[1],
        ]
    };
    let (first, second) = if key(a).partial_cmp(&key(b)) == Some(std::cmp::Ordering::Greater) {
        (b, a)
    } else {
        (a, b)
    };
    let (pose1, shape1) = parry_box(first);
    let (pose2, shape2) = parry_box(second);
    // Cuboid–cuboid queries are always supported; `Err` cannot occur, NaN marks it anyway.
    match query::contact(&pose1, &shape1, &pose2, &shape2, 0.0) {
        Ok(Some(contact)) if contact.dist < 0.0 => contact.dist,
        Ok(_) => query::distance(&pose1, &shape1, &pose2, &shape2).map_or(f64::NAN, |d| d.distance),
        Err(_) => f64::NAN,
    }
}

fn parry_box(b: &PlacedBox) -> (Pose, Cuboid) {
    let pose = Pose::new(Vector::new(b.centre_m[0], b.centre_m[1]), b.yaw_rad);
    let shape = Cuboid::new(Vector::new(b.half_extents_m[0], b.half_extents_m[1]));
    (pose, shape)
}

/// SigmaRL's `get_distances_between_agents(..., "mtv")` for one pair of rectangles.
///
/// Axes of a rectangle: the unit vectors of its edges corner 0→1 and 1→2. Every corner of
/// one rectangle is projected on the other's axes; its per-axis gap is `proj − min` if
/// `proj ≤ min`, `max − proj` if `proj ≥ max`, else 0, and its distance the norm of the two
/// gaps. The pair distance is the smallest of the 8 corner distances, unless some corner
/// lies strictly inside the other rectangle's projection interval on both of its axes (with
/// a non-zero overlap): then it is minus the smallest projection overlap on the 4 axes.
/// Symmetric in its arguments by construction.
pub fn sigmarl_mtv_distance_m(a: &Footprint, b: &Footprint) -> f64 {
    let ab = one_way(a, b);
    let ba = one_way(b, a);
    if ab.inside || ba.inside {
        -ab.min_overlap_m.min(ba.min_overlap_m)
    } else {
        ab.min_corner_distance_m.min(ba.min_corner_distance_m)
    }
}

/// The corners of `a` against the axes of `b`.
struct OneWay {
    /// Smallest corner distance (0 if a corner projects inside on both axes).
    min_corner_distance_m: f64,
    /// Smallest overlap of the two projection intervals on `b`'s axes.
    min_overlap_m: f64,
    /// Whether a corner of `a` is strictly inside `b` on both axes, with a non-zero overlap
    /// (the script's `MTVs_*_Euclidean_negative.abs() > 0`).
    inside: bool,
}

fn one_way(a: &Footprint, b: &Footprint) -> OneWay {
    let axes = [unit(b[0], b[1]), unit(b[1], b[2])];
    let project = |p: [f64; 2], axis: [f64; 2]| p[0] * axis[0] + p[1] * axis[1];

    // Projection intervals of both rectangles on b's axes.
    let mut interval_b = [[f64::INFINITY, f64::NEG_INFINITY]; 2];
    let mut interval_a = [[f64::INFINITY, f64::NEG_INFINITY]; 2];
    for (k, axis) in axes.iter().enumerate() {
        for (corner_b, corner_a) in b.iter().zip(a) {
            let pb = project(*corner_b, *axis);
            interval_b[k] = [interval_b[k][0].min(pb), interval_b[k][1].max(pb)];
            let pa = project(*corner_a, *axis);
            interval_a[k] = [interval_a[k][0].min(pa), interval_a[k][1].max(pa)];
        }
    }
    let overlap = |k: usize| interval_b[k][1].min(interval_a[k][1]) - interval_b[k][0].max(interval_a[k][0]);
    let min_overlap_m = overlap(0).min(overlap(1));

    let mut min_corner_distance_m = f64::INFINITY;
    let mut any_inside = false;
    for corner in a {
        let mut gap = [0.0; 2];
        let mut inside = true;
        for (k, axis) in axes.iter().enumerate() {
            let p = project(*corner, *axis);
            let [lo, hi] = interval_b[k];
            if p <= lo {
                gap[k] += p - lo;
            }
            if p >= hi {
                gap[k] += hi - p;
            }
            inside &= p > lo && p < hi;
        }
        min_corner_distance_m = min_corner_distance_m.min(gap[0].hypot(gap[1]));
        any_inside |= inside;
    }
    OneWay {
        min_corner_distance_m,
        min_overlap_m,
        inside: any_inside && min_overlap_m != 0.0,
    }
}

fn unit(from: [f64; 2], to: [f64; 2]) -> [f64; 2] {
    let d = [to[0] - from[0], to[1] - from[1]];
    let n = d[0].hypot(d[1]);
    [d[0] / n, d[1] / n]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn placed(x_m: f64, y_m: f64, yaw_rad: f64) -> PlacedBox {
        PlacedBox::from_pose(&VehicleParams::MU_CAR, x_m, y_m, yaw_rad)
    }

    #[test]
    fn disjoint_aligned_boxes_are_their_gap_apart() {
        let (a, b) = (placed(0.0, 0.0, 0.0), placed(0.32, 0.0, 0.0));
        for g in [CollisionGeometry::Mtv, CollisionGeometry::SigmarlMtv] {
            assert!((signed_distance_m(g, &a, &b) - 0.10).abs() < 1e-12, "{g:?}");
        }
    }

    #[test]
    fn overlapping_aligned_boxes_are_minus_their_overlap() {
        let (a, b) = (placed(0.0, 0.0, 0.0), placed(0.2, 0.01, 0.0));
        for g in [CollisionGeometry::Mtv, CollisionGeometry::SigmarlMtv] {
            assert!((signed_distance_m(g, &a, &b) + 0.02).abs() < 1e-12, "{g:?}");
        }
    }

    #[test]
    fn a_plus_shaped_crossing_is_positive_only_for_sigmarl() {
        // Same centre, one turned by 90°: no corner lies inside the other box.
        let (a, b) = (
            placed(1.0, 1.0, 0.0),
            placed(1.0, 1.0, std::f64::consts::FRAC_PI_2),
        );
        assert!(sigmarl_mtv_distance_m(&a.corners_m, &b.corners_m) >= 0.0);
        // True MTV: push one box out along its short axis by (0.22 + 0.107) / 2.
        assert!((mtv_distance_m(&a, &b) + 0.1635).abs() < 1e-9);
    }

    mod properties {
        use super::*;
        use proptest::prelude::*;

        fn any_box() -> impl Strategy<Value = PlacedBox> {
            (-0.5..0.5f64, -0.5..0.5f64, -4.0..4.0f64).prop_map(|(x, y, yaw)| placed(x, y, yaw))
        }

        proptest! {
            #![proptest_config(ProptestConfig { failure_persistence: None, ..ProptestConfig::default() })]
            #[test]
            fn both_geometries_are_symmetric(a in any_box(), b in any_box()) {
                for g in [CollisionGeometry::Mtv, CollisionGeometry::SigmarlMtv] {
                    prop_assert_eq!(signed_distance_m(g, &a, &b), signed_distance_m(g, &b, &a));
                }
            }

            #[test]
            fn disjoint_boxes_are_parrys_distance_apart(a in any_box(), b in any_box()) {
                let (pose_a, shape_a) = parry_box(&a);
                let (pose_b, shape_b) = parry_box(&b);
                prop_assume!(!query::intersection_test(&pose_a, &shape_a, &pose_b, &shape_b).unwrap().intersecting);
                let parry = query::distance(&pose_a, &shape_a, &pose_b, &shape_b).unwrap().distance;
                for g in [CollisionGeometry::Mtv, CollisionGeometry::SigmarlMtv] {
                    let d = signed_distance_m(g, &a, &b);
                    prop_assert!((d - parry).abs() < 1e-9, "{:?}: {} vs parry {}", g, d, parry);
                }
            }

            #[test]
            fn a_corner_inside_means_overlap_for_both(a in any_box(), b in any_box()) {
                // SigmaRL only reports overlaps it can see at a corner; those are real ones.
                if sigmarl_mtv_distance_m(&a.corners_m, &b.corners_m) < 0.0 {
                    prop_assert!(mtv_distance_m(&a, &b) < 0.0);
                }
            }
        }
    }
}
