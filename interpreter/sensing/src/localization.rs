//! The on-car localization of the CPM Lab (`Localization.cxx`, cpm-lab-interface.md §5): a
//! ring buffer of states at the control rate, dead reckoning from odometer distance and gyro
//! yaw increments, and a fixed-gain blend toward each positioning fix at the buffered state
//! of the fix's time slot, after which every later state is re-processed (a
//! delay-compensated complementary filter).
//!
//! Owns the buffer, the filter step and the simulated gyro drift (the lab's simulated IMU adds
//! `1e-4·U(0, 1)` rad per step). It does not produce fixes (that is
//! [`IpsModel`](crate::IpsModel)) or odometry (the vehicle model does).
//!
//! Two choices differ from the lab and are documented here: the buffer starts at the known
//! initial pose (the lab starts at zero, resets at step 25 and converges on IPS fixes before
//! a run starts), and odometry arrives as increments rather than running totals.

use std::collections::VecDeque;

use rand::RngExt;
use rand_chacha::ChaCha20Rng;

use crate::{Pose2, PoseFix, SensingError, check_range, wrap_angle_rad};

/// Parameters of the localization.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalizationParams {
    /// Control period, one buffered state per period [s], in (0, 10].
    pub period_s: f64,
    /// Number of buffered states, ≥ 2.
    pub buffer_len: usize,
    /// Gain of the blend toward a fix, in [0, 1].
    pub fusion_gain: f64,
    /// The gyro drift added each step is `imu_drift_per_step_rad·U(0, 1)` [rad], ≥ 0.
    pub imu_drift_per_step_rad: f64,
    /// Fixes measured longer ago than this are ignored [s], ≥ 0.
    pub max_fix_age_s: f64,
}

impl LocalizationParams {
    /// The lab: 20 ms, 512 states (≈ 10 s), gain 0.3, drift 1e-4 rad per step, 10 s.
    pub const LAB: LocalizationParams = LocalizationParams {
        period_s: 0.02,
        buffer_len: 512,
        fusion_gain: 0.3,
        imu_drift_per_step_rad: 1e-4,
        max_fix_age_s: 10.0,
    };
}

/// What the car's own sensors measured over one period (true values; the gyro drift is added
/// by [`Localization::step`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct OdometryReading {
    /// Distance the odometer counted [m].
    pub distance_increment_m: f64,
    /// Yaw change the gyro integrated [rad].
    pub yaw_increment_rad: f64,
    /// Odometer speed at the end of the period [m/s].
    pub speed_mps: f64,
}

/// The car's current belief.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    /// Time of the newest buffered state [s].
    pub time_s: f64,
    /// Estimated pose; yaw wrapped to [-π, π].
    pub pose: Pose2,
    /// Odometer speed [m/s].
    pub speed_mps: f64,
}

/// What became of a fix.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FixOutcome {
    /// Blended in; later states were re-processed.
    Applied,
    /// Older than the buffer (or than `max_fix_age_s`): ignored.
    TooOld,
    /// Measured after the newest buffered state's slot: ignored.
    FromTheFuture,
    /// Its slot already holds a fix (the first one wins, as in the lab): ignored.
    SlotTaken,
}

/// One buffered state.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Slot {
    /// Dead-reckoning increments that led into this slot (drift included).
    distance_increment_m: f64,
    yaw_increment_rad: f64,
    /// The fix blended in at this slot, if any.
    fix: Option<Pose2>,
    /// Estimated pose after dead reckoning and blending.
    pose: Pose2,
}

/// The on-car localization of one vehicle.
///
/// Each period: [`Localization::step`] with the period's odometry, then
/// [`Localization::apply_fix`] for each fix that arrived (the lab's order). Slot `k` holds the
/// state at `start_time_s + k·period_s` and takes fixes measured in
/// `[its time, its time + period_s)`.
///
/// Draw order: one `U[0, 1)` per [`Localization::step`] (the gyro drift), always.
#[derive(Debug, Clone, PartialEq)]
pub struct Localization {
    params: LocalizationParams,
    start_time_s: f64,
    /// Index of the newest slot since the start.
    newest_step: u64,
    slots: VecDeque<Slot>,
    speed_mps: f64,
}

impl Localization {
    /// A localization that starts at `initial_pose` at `start_time_s`; parameters outside
    /// their documented ranges are errors.
    pub fn new(
        params: &LocalizationParams,
        initial_pose: Pose2,
        initial_speed_mps: f64,
        start_time_s: f64,
    ) -> Result<Self, SensingError> {
        check_range("period_s", params.period_s, f64::MIN_POSITIVE, 10.0, "in (0, 10]")?;
        let len = params.buffer_len as f64;
        check_range("buffer_len", len, 2.0, f64::MAX, "at least 2")?;
        check_range("fusion_gain", params.fusion_gain, 0.0, 1.0, "in [0, 1]")?;
        let drift = params.imu_drift_per_step_rad;
        check_range("imu_drift_per_step_rad", drift, 0.0, f64::MAX, "finite and ≥ 0")?;
        check_range(
            "max_fix_age_s",
            params.max_fix_age_s,
            0.0,
            f64::MAX,
            "finite and ≥ 0",
        )?;
        check_range("start_time_s", start_time_s, f64::MIN, f64::MAX, "finite")?;

        let first = Slot {
            distance_increment_m: 0.0,
            yaw_increment_rad: 0.0,
            fix: None,
            pose: Pose2 {
                yaw_rad: wrap_angle_rad(initial_pose.yaw_rad),
                ..initial_pose
            },
        };
        Ok(Self {
            params: *params,
            start_time_s,
            newest_step: 0,
            slots: VecDeque::from([first]),
            speed_mps: initial_speed_mps,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &LocalizationParams {
        &self.params
    }

    /// Advance one period: buffer a new state dead-reckoned from `reading` plus the gyro
    /// drift (one draw), dropping the oldest state when the buffer is full.
    pub fn step(&mut self, reading: &OdometryReading, rng: &mut ChaCha20Rng) -> Estimate {
        let drift_rad = self.params.imu_drift_per_step_rad * rng.random::<f64>();
        let previous = self.newest().pose;
        let mut slot = Slot {
            distance_increment_m: reading.distance_increment_m,
            yaw_increment_rad: reading.yaw_increment_rad + drift_rad,
            fix: None,
            pose: previous,
        };
        slot.pose = self.filter(previous, &slot);
        self.slots.push_back(slot);
        if self.slots.len() > self.params.buffer_len {
            self.slots.pop_front();
        }
        self.newest_step += 1;
        self.speed_mps = reading.speed_mps;
        self.estimate()
    }

    /// Blend `fix` into the buffered state of its time slot and re-process every later state.
    pub fn apply_fix(&mut self, fix: &PoseFix) -> FixOutcome {
        // Find the slot (the oldest buffered state has no predecessor and takes no fix).
        let newest_time_s = self.time_of(self.newest_step);
        let age_s = newest_time_s - fix.measured_at_s;
        if age_s.is_nan() || age_s > self.params.max_fix_age_s {
            return FixOutcome::TooOld;
        }
        let step = ((fix.measured_at_s - self.start_time_s) / self.params.period_s + 1e-9).floor();
        if step > self.newest_step as f64 {
            return FixOutcome::FromTheFuture;
        }
        let oldest_step = self.newest_step + 1 - self.slots.len() as u64;
        if step < (oldest_step + 1) as f64 {
            return FixOutcome::TooOld;
        }
        let index = (step as u64 - oldest_step) as usize;
        let Some(slot) = self.slots.get_mut(index) else {
            return FixOutcome::TooOld;
        };
        if slot.fix.is_some() {
            return FixOutcome::SlotTaken;
        }
        slot.fix = Some(fix.pose);

        // Re-process from that slot on.
        for i in index..self.slots.len() {
            let previous = self.slots[i - 1].pose;
            self.slots[i].pose = self.filter(previous, &self.slots[i]);
        }
        FixOutcome::Applied
    }

    /// The current pose (newest buffered state) and odometer speed.
    pub fn estimate(&self) -> Estimate {
        Estimate {
            time_s: self.time_of(self.newest_step),
            pose: self.newest().pose,
            speed_mps: self.speed_mps,
        }
    }

    fn newest(&self) -> &Slot {
        // The buffer always holds at least one slot (`new` puts one, `step` keeps ≥ 2).
        &self.slots[self.slots.len() - 1]
    }

    fn time_of(&self, step: u64) -> f64 {
        self.start_time_s + step as f64 * self.params.period_s
    }

    /// The lab's `filter_update_step`: dead reckoning from `previous`, then the blend toward
    /// the slot's fix, then the yaw wrap.
    fn filter(&self, previous: Pose2, slot: &Slot) -> Pose2 {
        // Dead reckoning; the lab ignores discontinuities (|Δs| ≥ 0.5 m, |Δψ| ≥ 1.5 rad).
        let ds = slot.distance_increment_m;
        let ds = if ds.abs() < 0.5 { ds } else { 0.0 };
        let dyaw = wrap_angle_rad(slot.yaw_increment_rad);
        let dyaw = if dyaw.abs() < 1.5 { dyaw } else { 0.0 };
        let yaw_rad = previous.yaw_rad + dyaw;
        let mut pose = Pose2 {
            x_m: previous.x_m + ds * yaw_rad.cos(),
            y_m: previous.y_m + ds * yaw_rad.sin(),
            yaw_rad,
        };

        // Blend toward the fix; yaw on the circle.
        if let Some(fix) = slot.fix {
            let gain = self.params.fusion_gain;
            pose.x_m += gain * (fix.x_m - pose.x_m);
            pose.y_m += gain * (fix.y_m - pose.y_m);
            pose.yaw_rad += gain * wrap_angle_rad(fix.yaw_rad - pose.yaw_rad);
        }
        pose.yaw_rad = wrap_angle_rad(pose.yaw_rad);
        pose
    }
}

#[cfg(test)]
#[path = "localization_tests.rs"]
mod tests;
