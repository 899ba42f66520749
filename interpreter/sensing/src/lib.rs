//! Sensing and actuation layers of the cpmx twin, as the CPM Lab's simulated vehicles run
//! them (cpm-lab-interface.md §5, §6): the input delay line, the simulated indoor positioning
//! system, the on-car localization that fuses dead reckoning with positioning fixes, and
//! [`OnCarSensing`], which chains the last two for one car; and what agents know of each other
//! through a `communication` or `perception` layer ([`NeighbourKnowledge`]).
//!
//! This crate owns those three small state machines and the order of their random draws. It
//! knows no vehicle model (callers pass true poses and true odometer/gyro increments), no
//! spec types and no recordings. Every random draw comes from a caller-provided
//! [`ChaCha20Rng`](rand_chacha::ChaCha20Rng) — the engine passes the run's stream
//! `sensing/<agent>` — so results are reproducible.

mod delay;
mod ips;
mod localization;
mod neighbours;
mod on_car;

pub use delay::ActuationDelay;
pub use ips::{IpsModel, IpsParams, PoseFix};
pub use localization::{Estimate, FixOutcome, Localization, LocalizationParams, OdometryReading};
pub use neighbours::{CommunicationParams, NeighbourKnowledge, PerceptionParams};
pub use on_car::OnCarSensing;

use thiserror::Error;

/// A planar pose in the map frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Pose2 {
    /// x [m].
    pub x_m: f64,
    /// y [m].
    pub y_m: f64,
    /// Heading [rad], counter-clockwise from +x.
    pub yaw_rad: f64,
}

/// Invalid parameters of a sensing or actuation layer.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SensingError {
    /// A parameter is outside its range (or not finite).
    #[error("{name} = {value} is invalid: must be {expected}")]
    Parameter {
        /// Name of the parameter, with its unit suffix.
        name: &'static str,
        /// The value given.
        value: f64,
        /// The allowed range, in words.
        expected: &'static str,
    },
}

/// Check that `value` is finite and within `[min, max]`.
pub(crate) fn check_range(
    name: &'static str,
    value: f64,
    min: f64,
    max: f64,
    expected: &'static str,
) -> Result<f64, SensingError> {
    if value.is_finite() && (min..=max).contains(&value) {
        Ok(value)
    } else {
        Err(SensingError::Parameter {
            name,
            value,
            expected,
        })
    }
}

/// An angle wrapped to [-π, π] (C's `remainder(a, 2π)`, as the lab wraps yaw; ties aside).
pub fn wrap_angle_rad(angle_rad: f64) -> f64 {
    use std::f64::consts::TAU;
    angle_rad - TAU * (angle_rad / TAU).round()
}
