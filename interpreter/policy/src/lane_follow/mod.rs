//! The built-in baseline `builtin: lane-follow`: pure pursuit along the own centre line, a
//! time-gap rule behind the nearest agent ahead on the own lane, first-come first-served
//! yielding where the paths of two agents conflict, and a comfortable stop at the end of an
//! open path. No weights, no randomness.
//!
//! State kept between calls: per agent the last centre-line segment (so that a path that
//! crosses itself is tracked locally) and its arrival ticket; per path the cumulative arc
//! lengths and per pair of paths their conflict intervals (both computed once).
//!
//! # Conflicts and right of way
//!
//! Two paths conflict where their centre lines come closer than
//! [`LaneFollowParams::conflict_distance_m`]. A crossing gives an interval of arc length on
//! each path (the close stretch widened by [`LaneFollowParams::crossing_radius_m`]); a merge
//! (the paths run on together, same direction) gives the stretch from just before the merge
//! point until a car length past it, after which the time-gap rule takes over. Paths that
//! share their start (diverging paths) do not conflict; the time-gap rule covers them.
//!
//! An agent draws a ticket when it comes within [`LaneFollowParams::horizon_m`] of its first
//! conflict interval and keeps it until it has left them all. Tickets are ordered by the step
//! they were drawn, then by the distance to the first interval at that step, then by agent
//! index: a total order that never changes while agents wait, so the holder of the earliest
//! ticket is never held up by a later one (no deadlock). An agent that leads a queue inherits
//! the ticket of its follower if that is earlier. An agent yields to another at a conflict
//! when the other is inside its interval, or when the other holds an earlier ticket and the
//! agent itself has not entered any interval yet (then it waits before its first one, so that
//! it blocks nobody while waiting). An agent inside an interval is committed and goes on.

use std::f64::consts::FRAC_1_SQRT_2;

use cpmx_vehicle::Command;

use crate::geometry::PreparedPath;
use crate::observation::ObservationInput;
use crate::policy::{Policy, PolicyError, check_commands};

mod centre_line;

use centre_line::*;

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
    /// Lane width [m]: an agent counts as ahead when its centre is within half of it of the
    /// own centre line ahead and it heads along it.
    pub lane_width_m: f64,
    /// How far ahead other agents and conflicts are considered [m].
    pub horizon_m: f64,
    /// Margin added before and after the stretch where two crossing centre lines are closer
    /// than [`LaneFollowParams::conflict_distance_m`] [m].
    pub crossing_radius_m: f64,
    /// Two centre lines conflict where they are closer than this [m] (less than the distance
    /// of two adjacent lanes, more than a vehicle width).
    pub conflict_distance_m: f64,
    /// Comfortable deceleration for stops before conflicts and at the end of a path [m/s^2].
    pub comfort_decel_mps2: f64,
    /// Distance of the centre from the last point of an open path when stopped there [m].
    pub end_margin_m: f64,
    /// Time until a command takes effect (one policy step) [s]: stops are planned from the
    /// position reached by then.
    pub reaction_time_s: f64,
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
            crossing_radius_m: 0.12,
            conflict_distance_m: 0.12,
            comfort_decel_mps2: 1.0,
            end_margin_m: 0.15,
            reaction_time_s: 0.1,
        }
    }
}

/// Identifies a path's geometry across calls: id, number of points and last point.
type PathKey = (usize, usize, u64, u64);

fn path_key(path: &PreparedPath) -> PathKey {
    let last = path.center_points.last().copied().unwrap_or([0.0, 0.0]);
    (
        path.id,
        path.center_points.len(),
        last[0].to_bits(),
        last[1].to_bits(),
    )
}

/// An interval of arc length [m]; on a loop it may reach past the length (it wraps).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Interval {
    start: f64,
    end: f64,
}

/// A conflict of two paths: the intervals where each must not be while the other is in its.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Conflict {
    mine: Interval,
    theirs: Interval,
}

/// Where an agent is relative to an interval of its path.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Place {
    /// This far before its start [m].
    Before(f64),
    Inside,
    Past,
}

/// Arc lengths of a path's centre-line points.
#[derive(Debug, Clone, PartialEq)]
struct Arcs {
    cum: Vec<f64>,
    length: f64,
    is_loop: bool,
}

impl Arcs {
    fn new(path: &PreparedPath) -> Self {
        let mut cum = vec![0.0];
        for w in path.center_points.windows(2) {
            cum.push(cum[cum.len() - 1] + dist(w[0], w[1]));
        }
        Arcs {
            length: cum[cum.len() - 1],
            cum,
            is_loop: path.is_loop,
        }
    }

    fn place(&self, s: f64, iv: Interval) -> Place {
        if self.is_loop && self.length > 0.0 {
            let x = (s - iv.start).rem_euclid(self.length);
            if x <= iv.end - iv.start {
                Place::Inside
            } else {
                Place::Before(self.length - x)
            }
        } else if s < iv.start {
            Place::Before(iv.start - s)
        } else if s <= iv.end {
            Place::Inside
        } else {
            Place::Past
        }
    }
}

/// An agent's position on its path at this step.
#[derive(Debug, Clone, Copy)]
struct Tracked {
    /// Segment and foot point of the rear axle.
    segment: usize,
    foot: [f64; 2],
    /// Arc length of the centre [m].
    s: f64,
    /// Index into `LaneFollow::arcs`.
    arcs: usize,
}

/// A conflict as seen by one agent at this step.
#[derive(Debug, Clone, Copy)]
struct Pending {
    other: usize,
    mine: Place,
    theirs: Place,
}

/// Arrival ticket: step drawn, distance to the first conflict then, agent index.
type Ticket = (u64, f64, usize);

/// The lane-follow policy.
#[derive(Debug, Clone, Default)]
pub struct LaneFollow {
    /// Its parameters.
    pub params: LaneFollowParams,
    /// Last centre-line segment per agent (`None` before the first call).
    segments: Vec<Option<usize>>,
    /// Arrival ticket per agent.
    tickets: Vec<Option<Ticket>>,
    /// Calls since the last reset.
    step: u64,
    /// Arc lengths per path, computed on first use.
    arcs: Vec<(PathKey, Arcs)>,
    /// Conflicts per ordered pair of paths, computed on first use.
    conflicts: Vec<((PathKey, PathKey), Vec<Conflict>)>,
}

/// Segments searched behind and ahead of the previous one.
const WINDOW_BACK: usize = 5;
const WINDOW_AHEAD: usize = 25;
/// How far past a merge point the merge conflict lasts (then the time-gap rule takes over) [m].
const MERGE_LENGTH_M: f64 = 0.5;
/// Stops end this far before the conflict interval [m].
const STOP_MARGIN_M: f64 = 0.02;
/// An agent counts as committed to a conflict once this far inside its interval (a little
/// overshoot while stopping does not commit it) [m].
const COMMIT_TOLERANCE_M: f64 = 0.06;

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

    /// Index of the arc lengths of `path` in `self.arcs` (computed on first use).
    fn arcs_of(&mut self, path: &PreparedPath) -> usize {
        let key = path_key(path);
        match self.arcs.iter().position(|(k, _)| *k == key) {
            Some(at) => at,
            None => {
                self.arcs.push((key, Arcs::new(path)));
                self.arcs.len() - 1
            }
        }
    }

    /// Index of the conflicts of `a` with `b` in `self.conflicts` (both orders computed on
    /// first use).
    fn conflicts_of(&mut self, a: &PreparedPath, b: &PreparedPath) -> usize {
        let key = (path_key(a), path_key(b));
        if let Some(at) = self.conflicts.iter().position(|(k, _)| *k == key) {
            return at;
        }
        let (arcs_a, arcs_b) = (Arcs::new(a), Arcs::new(b));
        let (d, pad) = (self.params.conflict_distance_m, self.params.crossing_radius_m);
        let runs_a = close_runs(a, b, &arcs_a, d);
        let runs_b = close_runs(b, a, &arcs_b, d);
        let mut ab = Vec::new();
        let mut ba = Vec::new();
        for ra in &runs_a {
            let pa = a.center_points[ra.core];
            let Some(rb) = runs_b.iter().min_by(|x, y| {
                dist(b.center_points[x.core], pa).total_cmp(&dist(b.center_points[y.core], pa))
            }) else {
                continue;
            };
            let (ta, tb) = (tangent(a, ra.core), tangent(b, rb.core));
            let aligned = ta[0] * tb[0] + ta[1] * tb[1] > 0.866 && ra.end - ra.start > 2.0 * d;
            let (ia, ib) = if aligned {
                if ra.at_path_start && rb.at_path_start {
                    continue;
                }
                let merge = |r: &Run| Interval {
                    start: r.start - pad,
                    end: r.start + pad + MERGE_LENGTH_M,
                };
                (merge(ra), merge(rb))
            } else {
                let cross = |r: &Run| Interval {
                    start: r.start - pad,
                    end: r.end + pad,
                };
                (cross(ra), cross(rb))
            };
            ab.push(Conflict { mine: ia, theirs: ib });
            ba.push(Conflict { mine: ib, theirs: ia });
        }
        self.conflicts.push(((path_key(b), path_key(a)), ba));
        self.conflicts.push((key, ab));
        self.conflicts.len() - 1
    }
}

/// Order of two tickets (none = after every ticket).
fn ticket_cmp(a: Option<Ticket>, b: Option<Ticket>) -> std::cmp::Ordering {
    use std::cmp::Ordering;
    match (a, b) {
        (None, None) => Ordering::Equal,
        (None, Some(_)) => Ordering::Greater,
        (Some(_), None) => Ordering::Less,
        (Some(x), Some(y)) => x.0.cmp(&y.0).then(x.1.total_cmp(&y.1)).then(x.2.cmp(&y.2)),
    }
}

/// Speed from which a stop within `distance_m` at `decel_mps2` is possible.
fn stop_speed(distance_m: f64, decel_mps2: f64) -> f64 {
    (2.0 * decel_mps2 * distance_m.max(0.0)).sqrt()
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
        let n = input.agents.len();
        self.segments.resize(n, None);
        self.tickets.resize(n, None);
        self.step += 1;
        let p = self.params;
        let vehicle = input.vehicle;
        let paths = &input.paths.paths;

        // Where every agent is on its path.
        let mut tracked: Vec<Option<Tracked>> = Vec::with_capacity(n);
        for (i, me) in input.agents.iter().enumerate() {
            let path = &paths[i];
            if path.center_points.len() < 2 {
                tracked.push(None);
                continue;
            }
            let arcs = self.arcs_of(path);
            let (sin, cos) = me.yaw_rad.sin_cos();
            let rear = [
                me.x_m - vehicle.rear_axle_m * cos,
                me.y_m - vehicle.rear_axle_m * sin,
            ];
            let (segment, foot) = self.track(i, path, rear);
            let a = &self.arcs[arcs].1;
            let mut s = a.cum[segment] + dist(path.center_points[segment], foot) + vehicle.rear_axle_m;
            if a.is_loop && a.length > 0.0 {
                s = s.rem_euclid(a.length);
            }
            tracked.push(Some(Tracked {
                segment,
                foot,
                s,
                arcs,
            }));
        }

        // Conflicts of every agent with every other one.
        let mut pending: Vec<Vec<Pending>> = vec![Vec::new(); n];
        for i in 0..n {
            for j in 0..n {
                let (Some(ti), Some(tj)) = (tracked[i], tracked[j]) else {
                    continue;
                };
                if i == j || path_key(&paths[i]) == path_key(&paths[j]) {
                    continue;
                }
                let c = self.conflicts_of(&paths[i], &paths[j]);
                for conflict in &self.conflicts[c].1 {
                    let mine = Interval {
                        start: conflict.mine.start + COMMIT_TOLERANCE_M,
                        ..conflict.mine
                    };
                    pending[i].push(Pending {
                        other: j,
                        mine: self.arcs[ti.arcs].1.place(ti.s, mine),
                        theirs: self.arcs[tj.arcs].1.place(tj.s, conflict.theirs),
                    });
                }
            }
        }
        let committed: Vec<bool> = pending
            .iter()
            .map(|c| c.iter().any(|c| c.mine == Place::Inside))
            .collect();
        let first: Vec<f64> = pending
            .iter()
            .map(|c| {
                c.iter()
                    .filter_map(|c| match c.mine {
                        Place::Before(d) => Some(d),
                        _ => None,
                    })
                    .fold(f64::INFINITY, f64::min)
            })
            .collect();
        for i in 0..n {
            if committed[i] || first[i] <= p.horizon_m {
                let d = if committed[i] { 0.0 } else { first[i] };
                self.tickets[i].get_or_insert((self.step, d, i));
            } else {
                self.tickets[i] = None;
            }
        }

        // Who drives ahead of whom on the own lane (gap between centres along the path).
        let mut ahead: Vec<Vec<Option<f64>>> = (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| {
                        let ti = tracked[i].filter(|_| j != i)?;
                        gap_along(&paths[i], ti, &input.agents[j], vehicle.rear_axle_m, &p)
                    })
                    .collect()
            })
            .collect();
        // Queue leaders inherit earlier tickets of their followers.
        let mut effective = self.tickets.clone();
        for _ in 0..n {
            let mut changed = false;
            for i in 0..n {
                let leader = (0..n)
                    .filter_map(|j| ahead[i][j].map(|g| (g, j)))
                    .min_by(|x, y| x.0.total_cmp(&y.0));
                if let Some((_, j)) = leader
                    && ticket_cmp(effective[i], effective[j]).is_lt()
                {
                    effective[j] = effective[i];
                    changed = true;
                }
            }
            if !changed {
                break;
            }
        }
        let tickets = &self.tickets;
        let precedes = |j: usize, i: usize| {
            ticket_cmp(effective[j], effective[i])
                .then(ticket_cmp(tickets[j], tickets[i]))
                .then(j.cmp(&i))
                .is_lt()
        };
        // Two agents ahead of each other (side by side at a merge): the earlier one leads.
        for (i, j) in (0..n).flat_map(|i| (0..i).map(move |j| (i, j))) {
            if ahead[i][j].is_some() && ahead[j][i].is_some() {
                if precedes(j, i) {
                    ahead[j][i] = None;
                } else {
                    ahead[i][j] = None;
                }
            }
        }

        for (i, slot) in out.iter_mut().enumerate() {
            let Some(ti) = tracked[i] else {
                *slot = Command::default();
                continue;
            };
            let path = &paths[i];
            let arcs = &self.arcs[ti.arcs].1;
            let me = &input.agents[i];
            let steering = pure_pursuit(path, ti, me, vehicle, p.look_ahead_m);

            let mut speed = p.target_speed_mps;
            let reaction = me.speed_mps.max(0.0) * p.reaction_time_s;
            // Stop at the end of an open path.
            if !arcs.is_loop {
                let room = arcs.length - ti.s - p.end_margin_m - reaction;
                speed = speed.min(stop_speed(room, p.comfort_decel_mps2));
            }
            // Time gap to the agents ahead in the own lane.
            for gap in ahead[i].iter().flatten() {
                let gap = gap - vehicle.length_m;
                speed = speed.min(((gap - p.standstill_gap_m) / p.time_gap_s).max(0.0));
            }
            // Yield at conflicts.
            for c in &pending[i] {
                let j = c.other;
                let Place::Before(mine) = c.mine else { continue };
                if mine > p.horizon_m || ahead[i][j].is_some() {
                    continue;
                }
                let must = match c.theirs {
                    Place::Inside => true,
                    Place::Before(theirs) => {
                        !committed[i] && theirs <= 2.0 * p.horizon_m && tickets[j].is_some() && precedes(j, i)
                    }
                    Place::Past => false,
                };
                if must {
                    // An agent not yet committed waits before its first conflict.
                    let stop = if committed[i] { mine } else { first[i] };
                    let room = stop - COMMIT_TOLERANCE_M - STOP_MARGIN_M - reaction;
                    speed = speed.min(stop_speed(room, p.comfort_decel_mps2));
                }
            }
            *slot = Command {
                speed_mps: speed,
                steering_rad: steering,
            };
        }
        Ok(())
    }

    fn reset(&mut self) {
        self.segments.clear();
        self.tickets.clear();
        self.step = 0;
    }

    fn fork(&mut self) -> Box<dyn Policy> {
        Box::new(self.clone())
    }
}
