//! Closed-loop harness shared by the tracking tests: a planner that sends a trajectory
//! window every 100 ms, a plant with an optional input delay, and error statistics.

#![allow(dead_code)] // each test binary uses a subset

pub mod greybox;

use std::collections::VecDeque;

use cpmx_follower::{
    Follower, Model, Output, StateEstimate, Status, Trajectory, TrajectoryCommand, TrajectoryPoint,
};

/// Control period of the loop [s].
pub const PERIOD_S: f64 = 0.02;
/// Control period of the loop [ns].
pub const PERIOD_NS: u64 = 20_000_000;
/// Spacing of the planner's points [ns].
pub const POINT_SPACING_NS: u64 = 100_000_000;

/// A reference motion: position and velocity at a time.
pub type Reference = fn(f64) -> ([f64; 2], [f64; 2]);

/// Circle of radius 0.6 m at 0.5 m/s around (2.25, 2.0), starting at its bottom heading +x.
pub fn circle(t_s: f64) -> ([f64; 2], [f64; 2]) {
    let (r, v) = (0.6, 0.5);
    let w = v / r;
    let a = w * t_s;
    (
        [2.25 + r * a.sin(), 2.0 - r * a.cos()],
        [v * a.cos(), v * a.sin()],
    )
}

/// Straight at 0.6 m/s along +x, a 0.15 m lane change to the left (cosine profile over
/// 1.5 s starting at 2 s).
pub fn lane_change(t_s: f64) -> ([f64; 2], [f64; 2]) {
    let (v, offset, start, duration) = (0.6, 0.15, 2.0, 1.5);
    let tau = ((t_s - start) / duration).clamp(0.0, 1.0);
    let w = std::f64::consts::PI / duration;
    let y = 0.5 * offset * (1.0 - (std::f64::consts::PI * tau).cos());
    let vy = if tau > 0.0 && tau < 1.0 {
        0.5 * offset * w * (std::f64::consts::PI * tau).sin()
    } else {
        0.0
    };
    ([0.5 + v * t_s, 1.0 + y], [v, vy])
}

/// The command a planner sends at `t_ns`: points every 0.1 s on the absolute grid from
/// 0.2 s before (not before 0) to `lead_ns` after, valid at once.
pub fn command_at(reference: Reference, t_ns: u64, lead_ns: u64) -> TrajectoryCommand {
    let first = (t_ns / POINT_SPACING_NS).saturating_sub(2);
    let last = (t_ns + lead_ns).div_ceil(POINT_SPACING_NS);
    let points = (first..=last)
        .map(|i| {
            let (p, v) = reference(i as f64 * 0.1);
            TrajectoryPoint {
                t_ns: i * POINT_SPACING_NS,
                x_m: p[0],
                y_m: p[1],
                vx_mps: v[0],
                vy_mps: v[1],
            }
        })
        .collect();
    TrajectoryCommand {
        create_stamp_ns: t_ns,
        valid_after_ns: t_ns,
        trajectory: Trajectory::new(points).expect("grid points are valid"),
    }
}

/// What a closed-loop run produced.
pub struct Run<const NX: usize, const NU: usize> {
    /// Position error |p − p_ref(t)| at each control time [m].
    pub errors_m: Vec<f64>,
    /// Plant states at each control time.
    pub states: Vec<[f64; NX]>,
    /// Follower outputs.
    pub outputs: Vec<Output<NU>>,
}

impl<const NX: usize, const NU: usize> Run<NX, NU> {
    /// Mean and max error over control times in `[from_s, to_s)`.
    pub fn error_stats(&self, from_s: f64, to_s: f64) -> (f64, f64) {
        let window: Vec<f64> = self
            .errors_m
            .iter()
            .enumerate()
            .filter(|(n, _)| (*n as f64 * PERIOD_S) >= from_s && (*n as f64 * PERIOD_S) < to_s)
            .map(|(_, e)| *e)
            .collect();
        let mean = window.iter().sum::<f64>() / window.len() as f64;
        (mean, window.iter().cloned().fold(0.0, f64::max))
    }

    /// Whether every step was following.
    pub fn always_following(&self) -> bool {
        self.outputs.iter().all(|o| o.status == Status::Following)
    }
}

/// Runs `steps` control periods: the planner sends a command every 100 ms (if `send`), the
/// follower sees the exact state, the plant applies inputs `plant_delay_steps` periods late.
pub fn run<M: Model<NX, NU>, const NX: usize, const NU: usize>(
    follower: &mut Follower<M, NX, NU>,
    plant: impl Fn(&[f64; NX], &[f64; NU]) -> [f64; NX],
    reference: Reference,
    initial: [f64; NX],
    plant_delay_steps: usize,
    steps: usize,
) -> Run<NX, NU> {
    let mut state = initial;
    let mut queue: VecDeque<[f64; NU]> = std::iter::repeat_n([0.0; NU], plant_delay_steps).collect();
    let mut out = Run {
        errors_m: Vec::new(),
        states: Vec::new(),
        outputs: Vec::new(),
    };
    for n in 0..steps as u64 {
        let t_ns = n * PERIOD_NS;
        if n % 5 == 0 {
            follower.receive(command_at(reference, t_ns, 1_000_000_000));
        }
        let output = follower.control(
            t_ns,
            &StateEstimate {
                state,
                ips_update_age_ns: 0,
            },
        );
        let (p_ref, _) = reference(n as f64 * PERIOD_S);
        out.errors_m
            .push((state[0] - p_ref[0]).hypot(state[1] - p_ref[1]));
        out.states.push(state);
        queue.push_back(output.input);
        out.outputs.push(output);
        let applied = queue.pop_front().expect("queue holds delay + 1 inputs");
        state = plant(&state, &applied);
    }
    out
}
