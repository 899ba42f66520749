//! The vehicle-side 50 Hz loop in trajectory mode (§3.1 of the interface notes): keep the
//! newest valid trajectory command, apply the lab's stop rules, run the MPC.
//!
//! This module owns command selection and the stop decision. It does not integrate the
//! plant or estimate the state; the caller hands in an estimate each period and applies the
//! returned input.
//!
//! Lab rules (`Controller.cxx`, `cpm/Reader.hpp`): each step the command with the largest
//! `create_stamp` among those whose `valid_after` has passed is used (of equal stamps, the one
//! that arrived last), and only that message's points; it is fresh while
//! `t_now − valid_after < 1 s`, otherwise the car stops ("No new commands received"); an IPS
//! update older than 3 s stops the car ("Lost IPS position reference"); the MPC's rejections
//! ([`Rejection`]) stop it for that step. Stopping applies the model's stop input.
//!
//! Times are the lab's integer nanoseconds and compared as integers, as the lab does. The stops
//! the lab's controller makes itself — no command, a stale one, lost IPS — are decided before
//! the MPC is called (`Controller.cxx:376-395` switch to its `Stop` state, which sends
//! `get_stop_signals` without `MpcController::update`): the MPC's input history, warm start
//! and battery filter stay as they were; only the MPC's own rejections change them
//! (`mpc.rs`).
//!
//! Not followed: the lab's reader reports the age of "no sample at all" as `t_now` itself
//! (`Reader.hpp:105`), so on a clock that reads less than 1 s the lab's controller would run
//! its MPC on an empty command (and refuse it, filtering the battery voltage). The lab's
//! clock is the wall clock; cpmx's vehicle stacks start theirs at 1 s (`cpmx-stack`), so a
//! follower without a command simply stops.

use thiserror::Error;

use crate::gradient::GradientResult;
use crate::model::Model;
use crate::mpc::{Begun, Mpc, Pending, Rejection, Solution};
use crate::trajectory::Trajectory;

/// Commands received but not yet valid are kept up to this many (the oldest by creation
/// stamp is dropped beyond it; chosen here, the lab's reader keeps all).
pub const MAX_PENDING_COMMANDS: usize = 32;

/// A trajectory command (the lab's `VehicleCommandTrajectory`, stamps in nanoseconds).
#[derive(Debug, Clone, PartialEq)]
pub struct TrajectoryCommand {
    /// When the planner created it [ns].
    pub create_stamp_ns: u64,
    /// From when on the vehicle may use it [ns].
    pub valid_after_ns: u64,
    /// Its points.
    pub trajectory: Trajectory,
}

/// Timeouts of the loop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FollowerConfig {
    /// A command this old or older (since `valid_after`) stops the car [ns] (lab: 1 s,
    /// `Controller.hpp:94`).
    pub command_timeout_ns: u64,
    /// An IPS update older than this stops the car [ns] (lab: 3 s, `Controller.cxx:376`).
    pub ips_timeout_ns: u64,
}

impl Default for FollowerConfig {
    /// The lab's timeouts.
    fn default() -> Self {
        Self {
            command_timeout_ns: 1_000_000_000,
            ips_timeout_ns: 3_000_000_000,
        }
    }
}

/// What the vehicle knows about itself at a control step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StateEstimate<const NX: usize> {
    /// The model state (pose, speed, …) at the control time.
    pub state: [f64; NX],
    /// Time since the last IPS correction [ns] (the lab's `IPS_update_age_nanoseconds`).
    pub ips_update_age_ns: u64,
}

/// Why the car is being stopped.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum StopReason {
    /// No command has become valid yet.
    #[error("no trajectory command received")]
    NoCommand,
    /// The newest valid command is too old.
    #[error("no new commands received for {age_ns} ns")]
    StaleCommand {
        /// Time since its `valid_after` [ns].
        age_ns: u64,
    },
    /// The IPS has not corrected the estimate for too long.
    #[error("lost IPS position reference ({age_ns} ns)")]
    LostIps {
        /// Time since the last IPS update [ns].
        age_ns: u64,
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
    pub fn receive(&mut self, command: TrajectoryCommand) {
        self.pending.push(command);
        if self.pending.len() > MAX_PENDING_COMMANDS {
            let oldest = (0..self.pending.len()).min_by_key(|&i| self.pending[i].create_stamp_ns);
            if let Some(i) = oldest {
                self.pending.remove(i);
            }
        }
    }

    /// One control period at `t_now_ns`: the input to apply and the status.
    ///
    /// The same as [`Follower::begin`], the MPC's pending problem solved alone, then
    /// [`Follower::finish`].
    pub fn control(&mut self, t_now_ns: u64, estimate: &StateEstimate<NX>) -> Output<NU> {
        match self.begin(t_now_ns, estimate) {
            Begun::Decided(output) => output,
            Begun::Gradient(pending) => {
                let result = self.mpc.solve_pending(&pending);
                self.finish(&pending, result)
            }
        }
    }

    /// The first half of [`Follower::control`]: the command in force, the controller's own
    /// stops, and the MPC's decision up to its gradient solve ([`Mpc::begin`]), so that
    /// several vehicles' problems can be solved together before each [`Follower::finish`]es.
    pub fn begin(&mut self, t_now_ns: u64, estimate: &StateEstimate<NX>) -> Begun<Output<NU>, NX, NU> {
        self.activate_commands(t_now_ns);
        let trajectory = match command_to_follow(self.current.as_ref(), &self.config, t_now_ns, estimate) {
            Ok(trajectory) => trajectory,
            Err(reason) => return Begun::Decided(self.output(&estimate.state, Err(reason))),
        };
        match self.mpc.begin(t_now_ns, &estimate.state, trajectory) {
            Begun::Decided(decision) => {
                Begun::Decided(self.output(&estimate.state, decision.map_err(Into::into)))
            }
            Begun::Gradient(pending) => Begun::Gradient(pending),
        }
    }

    /// The MPC, for a solve of its pending problem together with other vehicles'
    /// ([`Mpc::gradient_parts`]).
    pub fn mpc_mut(&mut self) -> &mut Mpc<M, NX, NU> {
        &mut self.mpc
    }

    /// The second half of [`Follower::control`]: the gradient solver's `result` for the
    /// MPC's `pending` problem, checked by the MPC; the input to apply and the status.
    pub fn finish(&mut self, pending: &Pending<NX, NU>, result: GradientResult<NU>) -> Output<NU> {
        let decision = self.mpc.finish(pending, result).map_err(Into::into);
        self.output(&pending.state, decision)
    }

    /// The output of a decision: the MPC's input, or the model's stop input for `state`.
    fn output(&self, state: &[f64; NX], decision: Result<Solution<NU>, StopReason>) -> Output<NU> {
        match decision {
            Ok(solution) => Output {
                input: solution.input,
                status: Status::Following,
            },
            Err(reason) => Output {
                input: self.mpc.model().stop_input(state),
                status: Status::Stopped(reason),
            },
        }
    }

    /// Makes the newest command whose `valid_after` has passed the current one (the lab's
    /// reader: the largest `create_stamp`, of equal ones the later arrival).
    fn activate_commands(&mut self, t_now_ns: u64) {
        let mut i = 0;
        while i < self.pending.len() {
            if self.pending[i].valid_after_ns <= t_now_ns {
                // In arrival order, so that of equal stamps the later one wins.
                let candidate = self.pending.remove(i);
                let newer = self
                    .current
                    .as_ref()
                    .is_none_or(|c| candidate.create_stamp_ns >= c.create_stamp_ns);
                if newer {
                    self.current = Some(candidate);
                }
            } else {
                i += 1;
            }
        }
    }
}

/// The trajectory of the command in force, or why the car must stop without calling its MPC
/// (no command, a stale one, lost IPS).
fn command_to_follow<'a, const NX: usize>(
    current: Option<&'a TrajectoryCommand>,
    config: &FollowerConfig,
    t_now_ns: u64,
    estimate: &StateEstimate<NX>,
) -> Result<&'a Trajectory, StopReason> {
    let command = current.ok_or(StopReason::NoCommand)?;
    let age_ns = t_now_ns.saturating_sub(command.valid_after_ns);
    let fresh = age_ns < config.command_timeout_ns;
    if !fresh {
        return Err(StopReason::StaleCommand { age_ns });
    }
    let ips_lost = estimate.ips_update_age_ns > config.ips_timeout_ns;
    if ips_lost {
        return Err(StopReason::LostIps {
            age_ns: estimate.ips_update_age_ns,
        });
    }
    Ok(&command.trajectory)
}
