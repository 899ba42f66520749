//! Start sampling (`world_state_rt_sim.py:73-311`): a uniformly drawn path, a uniformly drawn
//! centre-line point in the path's admissible range, redrawn until the centre is far enough
//! from the agents it must avoid; then the heading of the segment starting there, steering 0
//! and a uniform speed. All draws come from the environment's own ChaCha stream.

use cpmx_vehicle::BicycleState;
use cpmx_world::Point;
use rand::RngExt;
use rand_chacha::ChaCha20Rng;

use crate::config::StartRule;
use crate::paths::TrainingPath;

/// Where and how an agent starts: the state the environment gives it at a reset.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    /// Index of the path in the environment's path set.
    pub path: usize,
    /// Centre-line point index it was placed at.
    pub point: usize,
    /// The bicycle state (float32 values).
    pub state: BicycleState,
    /// Velocity in the map frame [m/s].
    pub velocity_mps: [f64; 2],
}

/// Draws a placement whose centre is at least `rule.min_gap_m` from every point of `avoid`.
///
/// SigmaRL redraws forever; after `rule.max_attempts` draws this takes the candidate with
/// the largest gap instead and says so with `relaxed = true` (it needs a crowded scenario
/// that SigmaRL could not start at all).
pub fn draw_placement(
    rng: &mut ChaCha20Rng,
    paths: &[TrainingPath],
    rule: &StartRule,
    avoid: &[Point],
) -> (Placement, bool) {
    let min_gap2 = rule.min_gap_m * rule.min_gap_m;
    let mut best: Option<(f64, usize, usize)> = None;
    let mut relaxed = true;
    for _ in 0..rule.max_attempts.max(1) {
        let path = rng.random_range(0..paths.len());
        let (first, end) = paths[path].start_indices;
        let point = rng.random_range(first..end);
        let p = paths[path].prepared.center_points[point];
        // SigmaRL compares squared float32 distances.
        let gap2 = avoid
            .iter()
            .map(|q| {
                let (dx, dy) = ((p[0] - q[0]) as f32, (p[1] - q[1]) as f32);
                f64::from(dx * dx + dy * dy)
            })
            .fold(f64::INFINITY, f64::min);
        if best.is_none_or(|b| gap2 > b.0) {
            best = Some((gap2, path, point));
        }
        if gap2 >= min_gap2 {
            best = Some((gap2, path, point));
            relaxed = false;
            break;
        }
    }
    let (_, path, point) = best.expect("at least one draw");
    let speed = rule.speed_mps.0 + (rule.speed_mps.1 - rule.speed_mps.0) * f64::from(rng.random::<f32>());
    (placement_at(&paths[path], path, point, speed), relaxed)
}

/// The placement at centre-line point `point` of `paths[path]` with `speed_mps`, as SigmaRL
/// sets it (float32 values; velocity along the heading since the sideslip is 0).
pub fn placement_at(path: &TrainingPath, path_index: usize, point: usize, speed_mps: f64) -> Placement {
    let p = path.prepared.center_points[point];
    let yaw = path.center_yaw_rad[point.min(path.center_yaw_rad.len() - 1)] as f32;
    let speed = speed_mps as f32;
    let f = |v: f64| f64::from(v as f32);
    Placement {
        path: path_index,
        point,
        state: BicycleState {
            x_m: f(p[0]),
            y_m: f(p[1]),
            yaw_rad: f64::from(yaw),
            speed_mps: f64::from(speed),
            steering_rad: 0.0,
        },
        velocity_mps: [
            f64::from(speed * (f64::from(yaw).cos() as f32)),
            f64::from(speed * (f64::from(yaw).sin() as f32)),
        ],
    }
}
