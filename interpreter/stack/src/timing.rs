//! When a plan reaches a vehicle and what times its points carry, as in the lab: plans start
//! from states at least 60 ms old and are anchored at the state's time, so that the reference
//! passes where the car was when the state was measured; the vehicle's MPC reads its
//! reference up to [`VEHICLE_LEAD_S`] after its clock. The twin engine, the lab driver, the
//! lab emulator and training environments that run the vehicles all time plans this way.

use cpmx_follower::TrajectoryPoint;
use cpmx_planner::PlannedTrajectory;

use crate::CONTROL_PERIOD_S;

/// The end of the reference window the vehicles' MPC samples, after the vehicle's clock
/// (cpm-lab-interface.md §3.3/§3.4: points must cover up to `t_now + 360 ms`).
pub const VEHICLE_LEAD_S: f64 = 0.36;

/// The time a plan from a state created at `create_s` starts at, planned at the tick
/// `t_now_s`: the state's own time, so that the reference passes where the car was when the
/// state was measured; a state older than `max_age_s` (a vehicle missing from the lists, whose
/// last state is used) is taken as the tick's, so the trajectory keeps the lead time the
/// vehicles need.
pub fn anchor_s(create_s: f64, t_now_s: f64, max_age_s: f64) -> f64 {
    if create_s.is_finite() && create_s <= t_now_s && t_now_s - create_s <= max_age_s + 1e-9 {
        create_s
    } else {
        t_now_s
    }
}

/// The oldest state a plan of Hp steps of `dt_s` may start from and still cover the
/// vehicles' reference window until the next tick's command takes over [s].
pub fn max_state_age_s(prediction_horizon: u32, dt_s: f64) -> f64 {
    (f64::from(prediction_horizon) * dt_s - dt_s - VEHICLE_LEAD_S).max(0.0)
}

/// Time of point `k` of a trajectory anchored at `anchor_s` (one expression for the twin, the
/// lab driver and the emulator, so that their times agree to the bit).
pub fn anchored_time_s(anchor_s: f64, k: usize, step_s: f64) -> f64 {
    anchor_s + k as f64 * step_s
}

/// Control periods per policy period, if `dt_s` is a whole multiple of the control period.
pub fn control_periods(dt_s: f64) -> Option<usize> {
    let n = (dt_s / CONTROL_PERIOD_S).round() as usize;
    (n > 0 && (n as f64 * CONTROL_PERIOD_S - dt_s).abs() < 1e-9).then_some(n)
}

/// A planned trajectory in the lab's form.
pub fn trajectory_points(trajectory: &PlannedTrajectory) -> Vec<TrajectoryPoint> {
    trajectory
        .iter()
        .map(|p| TrajectoryPoint {
            t_s: p.t_s,
            x_m: p.x_m,
            y_m: p.y_m,
            vx_mps: p.velocity_mps[0],
            vy_mps: p.velocity_mps[1],
        })
        .collect()
}
