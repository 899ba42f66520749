//! The built-in baseline `builtin: lane-follow`: pure pursuit along the own centre line, a
//! time-gap rule behind the nearest agent ahead, and first-come first-served yielding where
//! the centre lines of two agents cross. No weights, no randomness.
//!
//! It keeps per agent the last centre-line segment (so that a path that crosses itself is
//! tracked locally) and per pair of paths their crossing points (computed once).

use cpmx_vehicle::Command;

use crate::geometry::PreparedPath;
use crate::observation::{AgentState, ObservationInput};
use crate::policy::{Policy, PolicyError, check_commands};

/// Parameters of the lane-follow baseline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaneFollowParams {
    /// Pure-pursuit look-ahead along the centre line from the rear axle [m].
    pub look_ahead_m: f64,
    /// Cruise speed [m/s].
    pub target_speed_mps: f64,
    /// Time gap kept to the agent ahead [s].
    pub time_gap_s: f64,
    /// Gap kept at standstill (bumper to bumper) [m].
    pub standstill_gap_m: f64,
    /// An agent counts as ahead when its centre is within this distance of the own centre
    /// line ahead [m] (one lane width).
    pub lane_width_m: f64,
    /// How far ahead other agents and crossings are considered [m].
    pub horizon_m: f64,
    /// Radius of the area around a crossing of two centre lines [m].
    pub crossing_radius_m: f64,
}

impl Default for LaneFollowParams {
    fn default() -> Self {
        LaneFollowParams {
            look_ahead_m: 0.25,
            target_speed_mps: 0.5,
            time_gap_s: 1.0,
            standstill_gap_m: 0.25,
            lane_width_m: 0.15,
            horizon_m: 1.5,
            crossing_radius_m: 0.2,
        }
    }
}

/// A crossing of two agents' centre lines.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Crossing {
    point: [f64; 2],
}

/// The lane-follow policy.
#[derive(Debug, Clone, Default)]
pub struct LaneFollow {
    /// Its parameters.
    pub params: LaneFollowParams,
    /// Last centre-line segment per agent (`None` before the first call).
    segments: Vec<Option<usize>>,
    /// Crossing points per ordered pair of path ids, computed on first use.
    crossings: Vec<((usize, usize), Vec<Crossing>)>,
}

/// Segments searched behind and ahead of the previous one.
const WINDOW_BACK: usize = 5;
const WINDOW_AHEAD: usize = 25;

impl LaneFollow {
    /// A lane-follow policy with the given parameters.
    pub fn new(params: LaneFollowParams) -> Self {
        LaneFollow {
            params,
            ..Default::default()
        }
    }

    /// Nearest segment to `p` near the previous one (whole path on the first call) and the
    /// projection point on it.
    fn track(&mut self, agent: usize, path: &PreparedPath, p: [f64; 2]) -> (usize, [f64; 2]) {
        let pts = &path.center_points;
        let n_seg = pts.len().saturating_sub(1);
        let candidates: Vec<usize> = match self.segments[agent] {
            Some(last) if n_seg > WINDOW_BACK + WINDOW_AHEAD => (0..=WINDOW_BACK + WINDOW_AHEAD)
                .map(|k| (last + n_seg + k - WINDOW_BACK) % n_seg)
                .filter(|&s| path.is_loop || (s + WINDOW_BACK >= last && s <= last + WINDOW_AHEAD))
                .collect(),
            _ => (0..n_seg).collect(),
        };
        let mut best = (f64::INFINITY, 0, p);
        for s in candidates {
            let q = project(pts[s], pts[s + 1], p);
            let d = dist(q, p);
            if d < best.0 {
                best = (d, s, q);
            }
        }
        self.segments[agent] = Some(best.1);
        (best.1, best.2)
    }

    /// Crossing points of the centre lines of two paths (cached).
    fn crossings_of(&mut self, a: &PreparedPath, b: &PreparedPath) -> &[Crossing] {
        let key = (a.id, b.id);
        let at = match self.crossings.iter().position(|(k, _)| *k == key) {
            Some(at) => at,
            None => {
                let mut found = Vec::new();
                if a.id != b.id {
                    for s in a.center_points.windows(2) {
                        for t in b.center_points.windows(2) {
                            if let Some(point) = segment_intersection(s[0], s[1], t[0], t[1]) {
                                // Keep one point per crossing (neighbouring segments repeat it).
                                if found.iter().all(|c: &Crossing| dist(c.point, point) > 0.05) {
                                    found.push(Crossing { point });
                                }
                            }
                        }
                    }
                }
                self.crossings.push((key, found));
                self.crossings.len() - 1
            }
        };
        &self.crossings[at].1
    }

    /// The command of agent `i`.
    fn command(&mut self, input: &ObservationInput<'_>, i: usize) -> Command {
        let p = self.params;
        let (look_ahead, horizon, radius) = (p.look_ahead_m, p.horizon_m, p.crossing_radius_m);
        let me = input.agents[i];
        let path = &input.paths.paths[i];
        let vehicle = input.vehicle;
        let (sin, cos) = me.yaw_rad.sin_cos();
        let to_ego = |q: [f64; 2]| {
            let (dx, dy) = (q[0] - me.x_m, q[1] - me.y_m);
            [dx * cos + dy * sin, -dx * sin + dy * cos]
        };

        // Pure pursuit from the rear axle (whose path curvature is tan(δ) / wheelbase).
        let rear = [
            me.x_m - vehicle.rear_axle_m * cos,
            me.y_m - vehicle.rear_axle_m * sin,
        ];
        let (segment, foot) = self.track(i, path, rear);
        let target = walk(path, segment, foot, look_ahead);
        let t = to_ego(target);
        let t = [t[0] + vehicle.rear_axle_m, t[1]];
        let ld = t[0].hypot(t[1]).max(1e-3);
        let curvature = 2.0 * t[1] / (ld * ld);
        let steering = (vehicle.wheelbase_m * curvature)
            .atan()
            .clamp(-vehicle.max_steering_rad, vehicle.max_steering_rad);

        // Time gap to the nearest agent ahead in the own lane.
        let mut speed = p.target_speed_mps;
        let ahead_line: Vec<[f64; 2]> = (0..=10)
            .map(|k| walk(path, segment, foot, horizon * f64::from(k) / 10.0))
            .collect();
        for (j, other) in input.agents.iter().enumerate() {
            if j == i {
                continue;
            }
            let q = to_ego([other.x_m, other.y_m]);
            let in_cone = q[0] > 0.0 && q[1].abs() < q[0] + vehicle.width_m;
            let lateral = ahead_line
                .windows(2)
                .map(|w| {
                    dist(
                        project(w[0], w[1], [other.x_m, other.y_m]),
                        [other.x_m, other.y_m],
                    )
                })
                .fold(f64::INFINITY, f64::min);
            if in_cone && lateral <= p.lane_width_m {
                let gap = q[0].hypot(q[1]) - vehicle.length_m;
                speed = speed.min(((gap - p.standstill_gap_m) / p.time_gap_s).max(0.0));
            }
        }

        // Yield before a crossing that another agent occupies or reaches first.
        let my_distance = |c: [f64; 2]| {
            let q = to_ego(c);
            (q[0] > -radius).then(|| dist(c, [me.x_m, me.y_m]))
        };
        for (j, other) in input.agents.iter().enumerate() {
            if j == i {
                continue;
            }
            let other_path = &input.paths.paths[j];
            let crossings = self.crossings_of(path, other_path).to_vec();
            for c in crossings {
                let Some(mine) = my_distance(c.point) else {
                    continue;
                };
                let inside_me = mine < radius;
                let approaching = mine < radius + horizon / 2.0;
                if inside_me || !approaching {
                    continue;
                }
                let theirs = dist(c.point, [other.x_m, other.y_m]);
                let their_heading_to_c = heading_towards(other, c.point);
                let other_inside = theirs < radius;
                let other_first = their_heading_to_c
                    && theirs < radius + horizon / 2.0
                    && (theirs < mine || (theirs == mine && j < i));
                if other_inside || other_first {
                    // Stop before the crossing area.
                    let room = mine - radius - vehicle.length_m / 2.0;
                    speed = speed.min((room / p.time_gap_s).max(0.0));
                }
            }
        }

        Command {
            speed_mps: speed,
            steering_rad: steering,
        }
    }
}

impl Policy for LaneFollow {
    fn act(&mut self, input: &ObservationInput<'_>, out: &mut [Command]) -> Result<(), PolicyError> {
        check_commands(input, out)?;
        if input.paths.len() != input.agents.len() {
            return Err(crate::ObservationError::PathCount {
                paths: input.paths.len(),
                agents: input.agents.len(),
            }
            .into());
        }
        self.segments.resize(input.agents.len(), None);
        for (i, slot) in out.iter_mut().enumerate() {
            *slot = if input.paths.paths[i].center_points.len() < 2 {
                Command::default()
            } else {
                self.command(input, i)
            };
        }
        Ok(())
    }

    fn reset(&mut self) {
        self.segments.clear();
    }
}

/// Whether `agent` is not driving away from `c`.
fn heading_towards(agent: &AgentState, c: [f64; 2]) -> bool {
    let (sin, cos) = agent.yaw_rad.sin_cos();
    (c[0] - agent.x_m) * cos + (c[1] - agent.y_m) * sin > 0.0
}

/// The point `distance_m` along the centre line from `foot` on `segment` (clamped at the end
/// of an open path, wrapping on a loop).
fn walk(path: &PreparedPath, segment: usize, foot: [f64; 2], distance_m: f64) -> [f64; 2] {
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
fn project(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> [f64; 2] {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    [a[0] + t * dx, a[1] + t * dy]
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Proper intersection point of segments `p1p2` and `q1q2` (parallel segments: none).
fn segment_intersection(p1: [f64; 2], p2: [f64; 2], q1: [f64; 2], q2: [f64; 2]) -> Option<[f64; 2]> {
    let r = [p2[0] - p1[0], p2[1] - p1[1]];
    let s = [q2[0] - q1[0], q2[1] - q1[1]];
    let denom = r[0] * s[1] - r[1] * s[0];
    if denom.abs() < 1e-12 {
        return None;
    }
    let qp = [q1[0] - p1[0], q1[1] - p1[1]];
    let t = (qp[0] * s[1] - qp[1] * s[0]) / denom;
    let u = (qp[0] * r[1] - qp[1] * r[0]) / denom;
    ((0.0..1.0).contains(&t) && (0.0..1.0).contains(&u)).then(|| [p1[0] + t * r[0], p1[1] + t * r[1]])
}
