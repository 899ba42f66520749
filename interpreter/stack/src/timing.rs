//! When a plan reaches a vehicle and what times its points carry, as in the lab: plans start
//! from states at least 60 ms old and are anchored at the state's time, so that the reference
//! passes where the car was when the state was measured; the vehicle's MPC reads its
//! reference up to [`VEHICLE_LEAD_NS`] after its clock. The twin engine, the lab driver, the
//! lab emulator and training environments that run the vehicles all time plans this way.
//!
//! Time is the vehicles' clock in integer nanoseconds, as the lab's messages carry it
//! (`TimeStamp{nanoseconds: u64}`): ticks, control periods (20 ms = 20,000,000 ns), state
//! stamps and point times are sums of whole nanoseconds, so the follower decides its window's
//! boundaries as the lab's controller does at any time, and the twin, the lab driver and the
//! emulator give the same stamps to the nanosecond. A simulated vehicle's clock reads
//! [`RUN_START_NS`] when its run starts.

use cpmx_follower::TrajectoryPoint;
use cpmx_planner::PlannedTrajectory;

use crate::{CONTROL_PERIOD_NS, CONTROL_PERIOD_S};

/// The end of the reference window the vehicles' MPC samples, after the vehicle's clock
/// (cpm-lab-interface.md §3.3/§3.4: points must cover up to `t_now + 360 ms`) [s].
pub const VEHICLE_LEAD_S: f64 = 0.36;
/// [`VEHICLE_LEAD_S`] in nanoseconds.
pub const VEHICLE_LEAD_NS: u64 = 360_000_000;

/// A simulated vehicle's clock when its run starts (tick 0), or when a training environment
/// places it: 1 s, so that the state it stood in before (stamped 60 ms earlier) and a plan
/// anchored at that state have times on the lab's unsigned clock, and the clock is past the
/// first second, in which the lab's command reader behaves differently (`cpmx-follower`).
pub const RUN_START_NS: u64 = 1_000_000_000;

/// A duration in whole nanoseconds, rounded (0 for NaN or a negative one; saturating).
pub fn duration_ns(span_s: f64) -> u64 {
    // `as` saturates and maps NaN to 0.
    (span_s * 1e9).round() as u64
}

/// The time a plan from a state created at `create_ns` starts at, planned at the tick
/// `t_now_ns`: the state's own time, so that the reference passes where the car was when the
/// state was measured; a state older than `max_age_ns` (a vehicle missing from the lists, whose
/// last state is used) or from the future is taken as the tick's, so the trajectory keeps the
/// lead time the vehicles need.
pub fn anchor_ns(create_ns: u64, t_now_ns: u64, max_age_ns: u64) -> u64 {
    match t_now_ns.checked_sub(create_ns) {
        Some(age_ns) if age_ns <= max_age_ns => create_ns,
        _ => t_now_ns,
    }
}

/// The oldest state a plan of Hp steps of `dt_ns` may start from and still cover the
/// vehicles' reference window until the next tick's command takes over:
/// `Hp·dt − dt − 360 ms`, at least 0 [ns].
pub fn max_state_age_ns(prediction_horizon: u32, dt_ns: u64) -> u64 {
    (u64::from(prediction_horizon) * dt_ns).saturating_sub(dt_ns + VEHICLE_LEAD_NS)
}

/// Time of point `k` of a trajectory anchored at `anchor_ns`, `anchor + k·step` (one
/// expression for the twin, the lab driver and the emulator, so that their times agree) [ns].
pub fn anchored_time_ns(anchor_ns: u64, k: usize, step_ns: u64) -> u64 {
    anchor_ns.saturating_add((k as u64).saturating_mul(step_ns))
}

/// When the policy decides in a run whose vehicles step every control period: decision `k` at
/// the first period at or after `k·dt`. A step of whole periods decides exactly every `dt`;
/// another at least one period long (SigmaRL's published 0.05 s against the lab's 0.02 s)
/// decides after 2 or 3 periods in turn (0.04 s, 0.06 s), as a lab that acts only on its
/// vehicles' periods would, and its plans keep their points `dt` apart.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DecisionSchedule {
    dt_ns: u64,
}

impl DecisionSchedule {
    /// The schedule of a policy step of `dt_s`, if it is at least one control period.
    pub fn new(dt_s: f64) -> Option<DecisionSchedule> {
        let dt_ns = duration_ns(dt_s);
        (dt_ns >= CONTROL_PERIOD_NS).then_some(DecisionSchedule { dt_ns })
    }

    /// The policy's step [ns]: the spacing of a plan's points.
    pub fn step_ns(self) -> u64 {
        self.dt_ns
    }

    /// Whether every decision is exactly `dt` after the one before (a whole number of periods).
    pub fn is_exact(self) -> bool {
        self.dt_ns.is_multiple_of(CONTROL_PERIOD_NS)
    }

    /// The time of decision `k` after the run's start: the first period at or after `k·dt` [ns].
    pub fn offset_ns(self, k: u64) -> u64 {
        k.saturating_mul(self.dt_ns).div_ceil(CONTROL_PERIOD_NS) * CONTROL_PERIOD_NS
    }

    /// The control periods from decision `k` to the next.
    pub fn periods_after(self, k: u64) -> u64 {
        (self.offset_ns(k + 1) - self.offset_ns(k)) / CONTROL_PERIOD_NS
    }

    /// The longest time from a decision to the next [ns].
    pub fn longest_gap_ns(self) -> u64 {
        self.dt_ns.div_ceil(CONTROL_PERIOD_NS) * CONTROL_PERIOD_NS
    }
}

/// Control periods per policy period, if `dt_s` is a whole multiple of the control period.
pub fn control_periods(dt_s: f64) -> Option<usize> {
    let n = (dt_s / CONTROL_PERIOD_S).round() as usize;
    (n > 0 && (n as f64 * CONTROL_PERIOD_S - dt_s).abs() < 1e-9).then_some(n)
}

/// A planned trajectory in the lab's form, anchored: point `k` at
/// [`anchored_time_ns`]`(anchor_ns, k, step_ns)` (the planner's own times, `k·dt` from its
/// start, are replaced).
pub fn trajectory_points(
    trajectory: &PlannedTrajectory,
    anchor_ns: u64,
    step_ns: u64,
) -> Vec<TrajectoryPoint> {
    trajectory
        .iter()
        .enumerate()
        .map(|(k, p)| TrajectoryPoint {
            t_ns: anchored_time_ns(anchor_ns, k, step_ns),
            x_m: p.x_m,
            y_m: p.y_m,
            vx_mps: p.velocity_mps[0],
            vy_mps: p.velocity_mps[1],
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1_000_000;

    #[test]
    fn plans_are_anchored_at_states_young_enough() {
        // Hp = 12 steps of 100 ms: a plan may start from a state up to 740 ms old.
        let max_age_ns = max_state_age_ns(12, 100 * MS);
        assert_eq!(max_age_ns, 740 * MS);
        let tick_ns = RUN_START_NS + 5_000 * MS;
        assert_eq!(
            anchor_ns(tick_ns - 60 * MS, tick_ns, max_age_ns),
            tick_ns - 60 * MS
        );
        assert_eq!(
            anchor_ns(tick_ns - 740 * MS, tick_ns, max_age_ns),
            tick_ns - 740 * MS
        );
        assert_eq!(anchor_ns(tick_ns - 740 * MS - 1, tick_ns, max_age_ns), tick_ns);
        assert_eq!(anchor_ns(tick_ns + 1, tick_ns, max_age_ns), tick_ns);
        // A horizon too short for the lead time allows no age at all.
        assert_eq!(max_state_age_ns(4, 100 * MS), 0);
    }

    #[test]
    fn anchored_times_are_whole_nanosecond_sums() {
        assert_eq!(
            anchored_time_ns(RUN_START_NS - 60 * MS, 3, 100 * MS),
            RUN_START_NS + 240 * MS
        );
        assert_eq!(anchored_time_ns(u64::MAX - 1, 2, 100 * MS), u64::MAX);
        assert_eq!(duration_ns(0.1), 100 * MS);
        assert_eq!(duration_ns(0.3), 300 * MS);
        assert_eq!(duration_ns(f64::NAN), 0);
        assert_eq!(duration_ns(-1.0), 0);
    }

    #[test]
    fn a_step_of_whole_periods_decides_every_step_another_on_the_next_period() {
        let exact = DecisionSchedule::new(0.1).unwrap();
        assert!(exact.is_exact());
        assert_eq!(
            (0..4).map(|k| exact.offset_ns(k)).collect::<Vec<_>>(),
            [0, 100 * MS, 200 * MS, 300 * MS]
        );
        assert_eq!(exact.periods_after(7), 5);
        // SigmaRL's 0.05 s on the lab's 0.02 s periods: 0, 0.06, 0.10, 0.16, 0.20 s.
        let sigmarl = DecisionSchedule::new(0.05).unwrap();
        assert!(!sigmarl.is_exact());
        let offsets: Vec<u64> = (0..5).map(|k| sigmarl.offset_ns(k)).collect();
        assert_eq!(offsets, [0, 60 * MS, 100 * MS, 160 * MS, 200 * MS]);
        assert_eq!(
            (0..4).map(|k| sigmarl.periods_after(k)).collect::<Vec<_>>(),
            [3, 2, 3, 2]
        );
        assert_eq!(sigmarl.longest_gap_ns(), 60 * MS);
        // Over a long run the decisions keep to the step's grid: never more than a period late.
        let k = 1_000_003;
        assert!(sigmarl.offset_ns(k) - k * 50 * MS < 20 * MS);
        assert!(DecisionSchedule::new(0.01).is_none(), "shorter than a period");
    }
}
