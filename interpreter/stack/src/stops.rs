//! How a vehicle's 50 Hz periods went: in how many the lab's follower stopped the car, and why.
//!
//! On the µCar the controller sends the stop input whenever it cannot follow: no valid command
//! yet, a command too old, the positioning lost for 3 s, or a trajectory its MPC refuses (too
//! large an acceleration or curvature, too little lead time). A run through the lab's stack that
//! stops its cars this way drives differently from one that does not, without any metric
//! saying why; these counts say it (`follower.*` in a run's statistics).

use std::collections::BTreeMap;

use cpmx_follower::{Status, StopReason};

/// The 50 Hz periods of one or more vehicles, and those in which the follower stopped the car,
/// by reason.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FollowerStops {
    /// Periods stepped.
    pub periods: u64,
    /// Stopped before any command was valid (a run's first periods).
    pub no_command: u64,
    /// Stopped because the newest command was too old.
    pub stale_command: u64,
    /// Stopped because the positioning had not corrected the estimate for too long.
    pub lost_ips: u64,
    /// Stopped because the MPC refused the trajectory.
    pub refused: u64,
}

impl FollowerStops {
    /// Counts one period that ended with `status`.
    pub fn count(&mut self, status: &Status) {
        self.periods += 1;
        if let Status::Stopped(reason) = status {
            match reason {
                StopReason::NoCommand => self.no_command += 1,
                StopReason::StaleCommand { .. } => self.stale_command += 1,
                StopReason::LostIps { .. } => self.lost_ips += 1,
                StopReason::Rejected(_) => self.refused += 1,
            }
        }
    }

    /// The counts as a run's statistics, by name (`follower.refused`, ...).
    pub fn statistics(&self) -> BTreeMap<String, f64> {
        [
            ("follower.periods", self.periods),
            ("follower.stopped_no_command", self.no_command),
            ("follower.stopped_stale_command", self.stale_command),
            ("follower.stopped_lost_ips", self.lost_ips),
            ("follower.stopped_refused", self.refused),
        ]
        .into_iter()
        .map(|(name, count)| (name.to_owned(), count as f64))
        .collect()
    }

    /// Periods stopped once a command had come: refused, too old or without positioning (a
    /// run's first periods before any command are not counted).
    pub fn stopped_once_commanded(&self) -> u64 {
        self.stale_command + self.lost_ips + self.refused
    }

    /// A note for a run whose cars were stopped once they had a command, if any was.
    pub fn note(&self) -> Option<String> {
        let stopped = self.stopped_once_commanded();
        (stopped > 0).then(|| {
            format!(
                "the lab's follower stopped the cars in {stopped} of {} 50 Hz periods: {} trajectories \
                 refused by the MPC, {} with a command too old, {} with the positioning lost",
                self.periods, self.refused, self.stale_command, self.lost_ips
            )
        })
    }
}

/// The counts of several vehicles together.
impl std::iter::Sum for FollowerStops {
    fn sum<I: Iterator<Item = FollowerStops>>(all: I) -> FollowerStops {
        all.fold(FollowerStops::default(), |total, s| FollowerStops {
            periods: total.periods + s.periods,
            no_command: total.no_command + s.no_command,
            stale_command: total.stale_command + s.stale_command,
            lost_ips: total.lost_ips + s.lost_ips,
            refused: total.refused + s.refused,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cpmx_follower::Rejection;

    #[test]
    fn periods_are_counted_by_the_reason_the_car_stopped() {
        let mut one = FollowerStops::default();
        for status in [
            Status::Stopped(StopReason::NoCommand),
            Status::Following,
            Status::Stopped(StopReason::Rejected(Rejection::TooFewPoints)),
            Status::Stopped(StopReason::StaleCommand { age_ns: 1 }),
            Status::Following,
        ] {
            one.count(&status);
        }
        let mut other = FollowerStops::default();
        other.count(&Status::Stopped(StopReason::LostIps { age_ns: 1 }));
        let both: FollowerStops = [one, other].into_iter().sum();
        assert_eq!(
            both,
            FollowerStops {
                periods: 6,
                no_command: 1,
                stale_command: 1,
                lost_ips: 1,
                refused: 1,
            }
        );
        assert_eq!(both.statistics()["follower.stopped_refused"], 1.0);
        assert_eq!(both.statistics().len(), 5);
        assert_eq!(
            both.note().as_deref(),
            Some(
                "the lab's follower stopped the cars in 3 of 6 50 Hz periods: 1 trajectories refused \
                 by the MPC, 1 with a command too old, 1 with the positioning lost"
            )
        );
        // The start's periods without a command are no stop worth a note.
        assert_eq!(
            FollowerStops {
                periods: 3,
                no_command: 3,
                ..Default::default()
            }
            .note(),
            None
        );
    }
}
