//! The vehicle-side 50 Hz loop in trajectory mode (§3.1 of the interface notes): keep the
//! newest valid trajectory command, apply the lab's stop rules, run the MPC.
//!
//! This module owns command selection and the stop decision. It does not integrate the
//! plant or estimate the state; the caller hands in an estimate each period and applies the
//! returned input.
//!
//! Lab rules (`Controller.cxx`): each step the command with the largest `create_stamp` among
//! those whose `valid_after` has passed is used, and only that message's points; it is fresh
//! while `t_now − valid_after < 1 s`, otherwise the car stops ("No new commands received");
//! an IPS update older than 3 s stops the car ("Lost IPS position reference"); the MPC's
//! rejections ([`Rejection`]) stop it for that step. Stopping applies the model's stop input.

use thiserror::Error;

use crate::model::Model;
use crate::mpc::{Mpc, Rejection};
use crate::trajectory::Trajectory;

/// Commands received but not yet valid are kept up to this many (the oldest by creation
/// stamp is dropped beyond it; chosen here, the lab's reader keeps all).
pub const MAX_PENDING_COMMANDS: usize = 32;

/// A trajectory command (the lab's `VehicleCommandTrajectory`, stamps in seconds).
#[derive(Debug, Clone, PartialEq)]
pub struct TrajectoryCommand {
    /// When the planner created it [s].
    pub create_stamp_s: f64,
    /// From when on the vehicle may use it [s].
    pub valid_after_s: f64,
    /// Its points.
    pub trajectory: Trajectory,
}

/// Why a command was not accepted at all.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum CommandError {
    /// A stamp is NaN or infinite.
    #[error("command stamps must be finite")]
    NonFiniteStamp,
}

/// Timeouts of the loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FollowerConfig {
    /// A command older than this (since `valid_after`) stops the car [s] (lab: 1).
    pub command_timeout_s: f64,
    /// An IPS update older than this stops the car [s] (lab: 3).
    pub ips_timeout_s: f64,
}

impl Default for FollowerConfig {
    /// The lab's timeouts.
    fn default() -> Self {
        Self {
            command_timeout_s: 1.0,
            ips_timeout_s: 3.0,
        }
    }
}

/// What the vehicle knows about itself at a control step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StateEstimate<const NX: usize> {
    /// The model state (pose, speed, …) at the control time.
    pub state: [f64; NX],
    /// Time since the last IPS correction [s].
    pub ips_update_age_s: f64,
}

/// Why the car is being stopped.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum StopReason {
    /// No command has become valid yet.
    #[error("no trajectory command received")]
    NoCommand,
    /// The newest valid command is too old.
    #[error("no new commands received for {age_s} s")]
    StaleCommand {
        /// Time since its `valid_after` [s].
        age_s: f64,
    },
    /// The IPS has not corrected the estimate for too long.
    #[error("lost IPS position reference ({age_s} s)")]
    LostIps {
        /// Time since the last IPS update [s].
        age_s: f64,
    },
    /// The MPC refused the trajectory or failed.
    #[error(transparent)]
    Rejected(#[from] Rejection),
}

/// The follower's state after a step.
#[derive(Debug, Clone, PartialEq)]
pub enum Status {
    /// Tracking the trajectory with the MPC.
    Following,
    /// Sending the stop input.
    Stopped(StopReason),
}

/// One step's result: the input to apply now and why.
#[derive(Debug, Clone, PartialEq)]
pub struct Output<const NU: usize> {
    /// Plant input for the next control period.
    pub input: [f64; NU],
    /// Following or stopped (with the reason).
    pub status: Status,
}

/// The 50 Hz trajectory follower of one vehicle.
#[derive(Debug, Clone)]
pub struct Follower<M, const NX: usize, const NU: usize> {
    mpc: Mpc<M, NX, NU>,
    config: FollowerConfig,
    current: Option<TrajectoryCommand>,
    pending: Vec<TrajectoryCommand>,
}

impl<M: Model<NX, NU>, const NX: usize, const NU: usize> Follower<M, NX, NU> {
    /// A follower with no command yet.
    pub fn new(mpc: Mpc<M, NX, NU>, config: FollowerConfig) -> Self {
        Self {
            mpc,
            config,
            current: None,
            pending: Vec::new(),
        }
    }

    /// The MPC (its model and configuration).
    pub fn mpc(&self) -> &Mpc<M, NX, NU> {
        &self.mpc
    }

    /// The vehicle's battery voltage measurement [V], filtered by the MPC as on the car.
    pub fn measure_battery_voltage(&mut self, voltage_v: f64) {
        self.mpc.measure_battery_voltage(voltage_v);
    }

    /// The command in use, if any.
    pub fn current_command(&self) -> Option<&TrajectoryCommand> {
        self.current.as_ref()
    }

    /// Accepts a command; it is considered from its `valid_after` on.
    pub fn receive(&mut self, command: TrajectoryCommand) -> Result<(), CommandError> {
        if !(command.create_stamp_s.is_finite() && command.valid_after_s.is_finite()) {
            return Err(CommandError::NonFiniteStamp);
        }
        self.pending.push(command);
        if self.pending.len() > MAX_PENDING_COMMANDS {
            let oldest = (0..self.pending.len()).min_by(|&a, &b| {
                self.pending[a]
                    .create_stamp_s
                    .total_cmp(&self.pending[b].create_stamp_s)
            });
            if let Some(i) = oldest {
                self.pending.remove(i);
            }
        }
        Ok(())
    }

    /// One control period at `t_now_s`: the input to apply and the status.
    pub fn control(&mut self, t_now_s: f64, estimate: &StateEstimate<NX>) -> Output<NU> {
        self.activate_commands(t_now_s);
        let decision = self.decide(t_now_s, estimate);
        let output = match decision {
            Ok(input) => Output {
                input,
                status: Status::Following,
            },
            Err(reason) => Output {
                input: self.mpc.model().stop_input(&estimate.state),
                status: Status::Stopped(reason),
            },
        };
        self.mpc.record_applied(output.input);
        output
    }

    /// Makes the newest command whose `valid_after` has passed the current one.
    fn activate_commands(&mut self, t_now_s: f64) {
        let mut i = 0;
        while i < self.pending.len() {
            if self.pending[i].valid_after_s <= t_now_s {
                let candidate = self.pending.swap_remove(i);
                let newer = self
                    .current
                    .as_ref()
                    .is_none_or(|c| candidate.create_stamp_s >= c.create_stamp_s);
                if newer {
                    self.current = Some(candidate);
                }
            } else {
                i += 1;
            }
        }
    }

    /// The MPC input, or why the car must stop.
    fn decide(&mut self, t_now_s: f64, estimate: &StateEstimate<NX>) -> Result<[f64; NU], StopReason> {
        let command = self.current.as_ref().ok_or(StopReason::NoCommand)?;
        let age_s = t_now_s - command.valid_after_s;
        let fresh = age_s < self.config.command_timeout_s;
        if !fresh {
            return Err(StopReason::StaleCommand { age_s });
        }
        let ips_recent = estimate.ips_update_age_s <= self.config.ips_timeout_s;
        if !ips_recent {
            return Err(StopReason::LostIps {
                age_s: estimate.ips_update_age_s,
            });
        }
        let solution = self.mpc.solve(t_now_s, &estimate.state, &command.trajectory)?;
        Ok(solution.input)
    }
}
