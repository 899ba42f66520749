//! Geometry along a centre line for the lane-follow baseline: the stretches where two paths
//! come close (their conflicts), the line's direction, pure-pursuit steering, the gap to an agent
//! ahead on the own line, and walking a distance along it.

use super::*;

/// A stretch of a path where it is close to another path.
#[derive(Debug, Clone, Copy)]
pub(super) struct Run {
    pub(super) start: f64,
    pub(super) end: f64,
    /// Index of the point closest to the other path.
    pub(super) core: usize,
    /// Whether it begins at the start of an open path.
    pub(super) at_path_start: bool,
}

/// Stretches of `a` closer than `d` to `b` (widened to the neighbouring points; on a loop a
/// stretch through the closing point is one run).
pub(super) fn close_runs(a: &PreparedPath, b: &PreparedPath, arcs: &Arcs, d: f64) -> Vec<Run> {
    let pts = &a.center_points;
    let dists: Vec<f64> = pts.iter().map(|&p| b.center.distance_m(p)).collect();
    let last = pts.len() - 1;
    let mut runs: Vec<Run> = Vec::new();
    let mut k = 0;
    while k <= last {
        if dists[k] >= d {
            k += 1;
            continue;
        }
        let k0 = k;
        while k < last && dists[k + 1] < d {
            k += 1;
        }
        let k1 = k;
        let core = (k0..=k1)
            .min_by(|&x, &y| dists[x].total_cmp(&dists[y]))
            .unwrap_or(k0);
        runs.push(Run {
            start: arcs.cum[k0.saturating_sub(1)],
            end: arcs.cum[(k1 + 1).min(last)],
            core,
            at_path_start: k0 == 0 && !a.is_loop,
        });
        k += 1;
    }
    if a.is_loop && runs.len() > 1 && dists[0] < d && dists[last] < d {
        let first = runs.remove(0);
        let tail = runs.last_mut().expect("two runs");
        tail.end = first.end + arcs.length;
        if dists[first.core] < dists[tail.core] {
            tail.core = first.core;
        }
    }
    runs
}

/// Unit direction of the centre line at point `k`.
pub(super) fn tangent(path: &PreparedPath, k: usize) -> [f64; 2] {
    let pts = &path.center_points;
    let (a, b) = if k + 1 < pts.len() {
        (pts[k], pts[k + 1])
    } else {
        (pts[k - 1], pts[k])
    };
    let l = dist(a, b).max(1e-12);
    [(b[0] - a[0]) / l, (b[1] - a[1]) / l]
}

/// Pure-pursuit steering from the rear axle (whose path curvature is tan(δ) / wheelbase),
/// aiming at the point `look_ahead_m` along the centre line (never past the end of an open
/// path).
pub(super) fn pure_pursuit(
    path: &PreparedPath,
    tracked: Tracked,
    me: &crate::observation::AgentState,
    vehicle: &cpmx_vehicle::VehicleParams,
    look_ahead_m: f64,
) -> f64 {
    let (sin, cos) = me.yaw_rad.sin_cos();
    let target = walk(path, tracked.segment, tracked.foot, look_ahead_m);
    let (dx, dy) = (target[0] - me.x_m, target[1] - me.y_m);
    let t = [dx * cos + dy * sin + vehicle.rear_axle_m, -dx * sin + dy * cos];
    let ld = t[0].hypot(t[1]).max(1e-3);
    let curvature = 2.0 * t[1] / (ld * ld);
    (vehicle.wheelbase_m * curvature)
        .atan()
        .clamp(-vehicle.max_steering_rad, vehicle.max_steering_rad)
}

/// Arc distance between the centres of the agent tracked by `me` and `other` along the own
/// centre line, if `other` is on it ahead within the horizon (centre within half a lane width
/// of it, heading along it within 45 degrees).
pub(super) fn gap_along(
    path: &PreparedPath,
    me: Tracked,
    other: &crate::observation::AgentState,
    rear_axle_m: f64,
    p: &LaneFollowParams,
) -> Option<f64> {
    let pts = &path.center_points;
    let n_seg = pts.len() - 1;
    let q = [other.x_m, other.y_m];
    let (mut at, mut s, mut travelled) = (me.foot, me.segment, 0.0);
    let mut best: Option<(f64, f64, [f64; 2])> = None;
    for _ in 0..=n_seg {
        let end = pts[s + 1];
        let proj = project(at, end, q);
        let lateral = dist(proj, q);
        if best.is_none_or(|b| lateral < b.0) {
            best = Some((
                lateral,
                travelled + dist(at, proj),
                [end[0] - at[0], end[1] - at[1]],
            ));
        }
        travelled += dist(at, end);
        if travelled > p.horizon_m + rear_axle_m {
            break;
        }
        at = end;
        s += 1;
        if s == n_seg {
            if !path.is_loop {
                break;
            }
            s = 0;
            at = pts[0];
        }
    }
    let (lateral, along, dir) = best?;
    let (sin, cos) = other.yaw_rad.sin_cos();
    let norm = dir[0].hypot(dir[1]);
    let aligned = norm > 0.0 && (dir[0] * cos + dir[1] * sin) / norm >= FRAC_1_SQRT_2;
    let gap = along - rear_axle_m;
    (lateral <= p.lane_width_m / 2.0 && aligned && gap > 0.0 && gap <= p.horizon_m).then_some(gap)
}

/// The point `distance_m` along the centre line from `foot` on `segment` (clamped at the end
/// of an open path, wrapping on a loop).
pub(super) fn walk(path: &PreparedPath, segment: usize, foot: [f64; 2], distance_m: f64) -> [f64; 2] {
    let pts = &path.center_points;
    let n_seg = pts.len() - 1;
    let (mut at, mut s, mut left) = (foot, segment, distance_m);
    for _ in 0..=n_seg {
        let end = pts[s + 1];
        let d = dist(at, end);
        if d >= left {
            let f = if d > 0.0 { left / d } else { 0.0 };
            return [at[0] + f * (end[0] - at[0]), at[1] + f * (end[1] - at[1])];
        }
        left -= d;
        at = end;
        s += 1;
        if s == n_seg {
            if !path.is_loop {
                return at;
            }
            s = 0;
            at = pts[0];
        }
    }
    at
}

/// Closest point to `p` on the segment `a`–`b`.
pub(super) fn project(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> [f64; 2] {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    [a[0] + t * dx, a[1] + t * dy]
}

pub(super) fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}
