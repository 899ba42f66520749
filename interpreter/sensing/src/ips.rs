//! The indoor positioning system as the lab's simulated vehicles model it
//! (`SimulationIPS.cxx`, cpm-lab-interface.md §5–§6): frames of the true pose at a fixed rate,
//! some dropped, uniform noise, delivered late but stamped with the measurement time.
//!
//! Owns the frame clock, the noise and drop draws and the queue of fixes in flight. It does
//! not fuse fixes (that is [`Localization`](crate::Localization)).
//!
//! One difference from the lab's code, by design: the lab delays by a FIFO of 3 *published*
//! frames, so a dropped frame lengthens the delay of the next ones by a frame; here every fix
//! arrives exactly `latency_ms` after its measurement.

use std::collections::VecDeque;

use rand::RngExt;
use rand_chacha::ChaCha20Rng;

use crate::{Pose2, SensingError, check_range, wrap_angle_rad};

/// Tolerance when comparing times, in periods (frame clock) or seconds (delivery).
const TIME_EPS: f64 = 1e-9;

/// Parameters of the positioning system (the spec's `SensingModel` without the fusion gain).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IpsParams {
    /// Frame rate [Hz], in (0, 1000].
    pub rate_hz: f64,
    /// Delay between a frame and its arrival on the car [ms], in [0, 10000].
    pub latency_ms: f64,
    /// Half-width of the uniform noise on x and on y [m], ≥ 0.
    pub noise_position_m: f64,
    /// Half-width of the uniform noise on yaw [rad], ≥ 0.
    pub noise_yaw_rad: f64,
    /// Probability that a frame is dropped, in [0, 1].
    pub drop_probability: f64,
}

impl IpsParams {
    /// The lab's simulated IPS: 50 Hz, 60 ms, ±2 mm, ±0.01 rad, 1 frame in 20 dropped.
    pub const LAB: IpsParams = IpsParams {
        rate_hz: 50.0,
        latency_ms: 60.0,
        noise_position_m: 0.002,
        noise_yaw_rad: 0.01,
        drop_probability: 0.05,
    };
}

/// A positioning fix: a measured pose stamped with the time it was measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseFix {
    /// When the frame was taken [s] (not when it arrived).
    pub measured_at_s: f64,
    /// The measured pose; yaw wrapped to [-π, π].
    pub pose: Pose2,
}

/// The simulated positioning system of one vehicle.
///
/// Frames are due at `k / rate_hz`, k = 0, 1, …; a call to [`IpsModel::step`] at or after a
/// due time takes one frame of the pose it is given, stamped with the call's time (call it at
/// the frame rate or faster; a slower caller gets one frame per call).
///
/// Draw order, per frame taken, always four draws whatever the parameters (so that changing
/// the drop rate or the noise does not shift later frames' draws): `u ~ U[0, 1)` (dropped iff
/// `u < drop_probability`), then `U[-1, 1]` for x, y and yaw, scaled by the noise half-widths.
#[derive(Debug, Clone, PartialEq)]
pub struct IpsModel {
    params: IpsParams,
    period_s: f64,
    latency_s: f64,
    next_frame: u64,
    in_flight: VecDeque<(f64, PoseFix)>,
}

impl IpsModel {
    /// A positioning system; parameters outside their documented ranges are errors.
    pub fn new(params: &IpsParams) -> Result<Self, SensingError> {
        check_range(
            "rate_hz",
            params.rate_hz,
            f64::MIN_POSITIVE,
            1000.0,
            "in (0, 1000]",
        )?;
        check_range("latency_ms", params.latency_ms, 0.0, 10_000.0, "in [0, 10000]")?;
        check_range(
            "noise_position_m",
            params.noise_position_m,
            0.0,
            f64::MAX,
            "finite and ≥ 0",
        )?;
        check_range(
            "noise_yaw_rad",
            params.noise_yaw_rad,
            0.0,
            f64::MAX,
            "finite and ≥ 0",
        )?;
        check_range("drop_probability", params.drop_probability, 0.0, 1.0, "in [0, 1]")?;
        Ok(Self {
            params: *params,
            period_s: 1.0 / params.rate_hz,
            latency_s: params.latency_ms / 1000.0,
            next_frame: 0,
            in_flight: VecDeque::new(),
        })
    }

    /// The parameters.
    pub fn params(&self) -> &IpsParams {
        &self.params
    }

    /// Advance to `time_s` with the vehicle at `true_pose`: take a frame if one is due, then
    /// return the fixes that have arrived by `time_s`, oldest first.
    pub fn step(&mut self, time_s: f64, true_pose: Pose2, rng: &mut ChaCha20Rng) -> Vec<PoseFix> {
        // Take a frame if one is due.
        let frames_elapsed = time_s / self.period_s + TIME_EPS;
        if self.next_frame as f64 <= frames_elapsed {
            self.next_frame = frames_elapsed.floor() as u64 + 1;
            if let Some(fix) = self.frame(time_s, true_pose, rng) {
                self.in_flight.push_back((time_s + self.latency_s, fix));
            }
        }

        // Deliver what has arrived.
        let mut arrived = Vec::new();
        while let Some(&(arrives_at_s, fix)) = self.in_flight.front() {
            if arrives_at_s > time_s + TIME_EPS {
                break;
            }
            arrived.push(fix);
            self.in_flight.pop_front();
        }
        arrived
    }

    /// One frame: the drop and noise draws, in the documented order.
    fn frame(&self, time_s: f64, pose: Pose2, rng: &mut ChaCha20Rng) -> Option<PoseFix> {
        let p = &self.params;
        let u_drop: f64 = rng.random();
        let noise_x = rng.random_range(-1.0..=1.0) * p.noise_position_m;
        let noise_y = rng.random_range(-1.0..=1.0) * p.noise_position_m;
        let noise_yaw = rng.random_range(-1.0..=1.0) * p.noise_yaw_rad;
        (u_drop >= p.drop_probability).then_some(PoseFix {
            measured_at_s: time_s,
            pose: Pose2 {
                x_m: pose.x_m + noise_x,
                y_m: pose.y_m + noise_y,
                yaw_rad: wrap_angle_rad(pose.yaw_rad + noise_yaw),
            },
        })
    }
}

#[cfg(test)]
#[path = "ips_tests.rs"]
mod tests;
