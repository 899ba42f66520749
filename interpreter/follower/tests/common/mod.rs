//! Closed-loop harness shared by the tracking tests: a planner that sends a trajectory
//! window every 100 ms, a plant with an optional input delay, and error statistics.

#![allow(dead_code)] // each test binary uses a subset

use std::collections::VecDeque;

use cpmx_follower::{
    Follower, Model, Output, StateEstimate, Status, Trajectory, TrajectoryCommand, TrajectoryPoint,
};

/// Control period of the loop [s].
pub const PERIOD_S: f64 = 0.02;

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

/// The command a planner sends at `t_s`: points every 0.1 s on the absolute grid from
/// 0.2 s before to `lead_s` after, valid at once.
pub fn command_at(reference: Reference, t_s: f64, lead_s: f64) -> TrajectoryCommand {
    let first = (t_s / 0.1).floor() as i64 - 2;
    let last = ((t_s + lead_s) / 0.1).ceil() as i64;
    let points = (first..=last)
        .map(|i| {
            let t = i as f64 * 0.1;
            let (p, v) = reference(t);
            TrajectoryPoint {
                t_s: t,
                x_m: p[0],
                y_m: p[1],
                vx_mps: v[0],
                vy_mps: v[1],
            }
        })
        .collect();
    TrajectoryCommand {
        create_stamp_s: t_s,
        valid_after_s: t_s,
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
    for n in 0..steps {
        let t_s = n as f64 * PERIOD_S;
        if n % 5 == 0 {
            follower
                .receive(command_at(reference, t_s, 1.0))
                .expect("finite stamps");
        }
        let output = follower.control(
            t_s,
            &StateEstimate {
                state,
                ips_update_age_s: 0.0,
            },
        );
        let (p_ref, _) = reference(t_s);
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
