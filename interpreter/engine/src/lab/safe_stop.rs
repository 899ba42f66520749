//! The safe stop: how a lab run ends for the vehicles, whatever ended it (its last tick, the
//! lab's stop, a fault, a failure, Ctrl-C). The driver hands every vehicle of the run a stop
//! command: a `VehicleCommandTrajectory` whose points all lie before its `valid_after` (where
//! the vehicle's last state put it, at rest). The vehicle's MPC refuses it ("insufficient lead
//! time"), so its controller brakes with the lab's stop signal (throttle = clip(−0.5·v),
//! servo 0) every 20 ms from the moment the command is valid, and, once the command is a
//! second old, goes on stopping because no new command came — as the lab's controller stops
//! a car itself. (A `VehicleCommandDirect` would hold one throttle for a second: computed from
//! a speed the planner saw 60 ms before, it brakes too late or drives the car backwards.)
//!
//! The command is stamped by the lab's clock, never the driver's: with the newest tick's
//! `t_now` when a list comes (the lab's simulated time answers that tick with it), else with
//! the last `t_now` plus the time since it came. It is sent again while the stop lasts,
//! because the topic is best effort. A failed run sends it at once; a run that ran its course
//! first lets its last commands go out (at the next tick, or 50 ms later).

use std::thread;
use std::time::{Duration, Instant};

use cpmx_lab::{Header, TimeStamp, TrajectoryPoint, VehicleCommandTrajectory};

use super::MIN_TRAJECTORY_POINTS;
use super::session::Session;

/// How long the driver keeps commanding the stop after a run [wall clock].
pub const STOP_WINDOW: Duration = Duration::from_millis(300);

/// How often the stop is sent again when no tick comes.
const RESEND: Duration = Duration::from_millis(50);

/// The stop command of vehicle `vehicle_id`, last seen at (`x_m`, `y_m`), created and valid at
/// `t_ns` on the lab's clock: [`MIN_TRAJECTORY_POINTS`] points `step_ns` apart up to `t_ns`,
/// all at that position at rest.
pub fn stop_command(vehicle_id: u8, x_m: f64, y_m: f64, t_ns: u64, step_ns: u64) -> VehicleCommandTrajectory {
    let stamp = TimeStamp { nanoseconds: t_ns };
    let points = (0..MIN_TRAJECTORY_POINTS as u64)
        .rev()
        .map(|k| TrajectoryPoint {
            t: TimeStamp {
                nanoseconds: t_ns.saturating_sub(k * step_ns),
            },
            px: x_m,
            py: y_m,
            vx: 0.0,
            vy: 0.0,
        })
        .collect();
    VehicleCommandTrajectory {
        vehicle_id,
        header: Header {
            create_stamp: stamp,
            valid_after_stamp: stamp,
        },
        trajectory_points: points,
    }
}

/// Whether a command stops its vehicle: it has no point after its `valid_after`, so no
/// vehicle can follow it (the lab's middleware warns of exactly this).
pub fn is_stop_command(command: &VehicleCommandTrajectory) -> bool {
    let valid_after_ns = command.header.valid_after_stamp.nanoseconds;
    command
        .trajectory_points
        .iter()
        .all(|p| p.t.nanoseconds <= valid_after_ns)
}

/// The lab's clock as the driver last heard it: a tick's `t_now` and when it came.
#[derive(Debug, Clone, Copy)]
pub(super) struct LabClock {
    pub t_now_ns: u64,
    pub received: Instant,
}

impl LabClock {
    /// The lab's time now, by the time since the tick came.
    fn now_ns(&self) -> u64 {
        let elapsed_ns = u64::try_from(self.received.elapsed().as_nanos()).unwrap_or(u64::MAX);
        self.t_now_ns.saturating_add(elapsed_ns)
    }
}

/// Commands every vehicle (`vehicle_ids`, last seen at `positions`) to stop for
/// [`STOP_WINDOW`], answering every tick that comes meanwhile; at once when `at_once`, else
/// from the next tick or after [`RESEND`], whichever comes first. Without a tick ever heard
/// (`clock` is `None`) the vehicles never had a command from this run, and nothing is sent.
/// Errors of the middleware are ignored: the stop is the last thing a run does, and a
/// vehicle without commands stops after a second anyway.
pub(super) fn stop_vehicles(
    session: &mut Session,
    vehicle_ids: &[u8],
    positions: &[(f64, f64)],
    clock: Option<LabClock>,
    step_ns: u64,
    at_once: bool,
) {
    let Some(mut clock) = clock else {
        return;
    };
    let commands = |t_ns: u64| -> Vec<VehicleCommandTrajectory> {
        vehicle_ids
            .iter()
            .zip(positions)
            .map(|(id, (x_m, y_m))| stop_command(*id, *x_m, *y_m, t_ns, step_ns))
            .collect()
    };
    let started = Instant::now();
    let mut sent: Option<Instant> = (!at_once).then_some(started);
    while started.elapsed() < STOP_WINDOW {
        if let Ok(Some(list)) = session.newest_list()
            && list.t_now >= clock.t_now_ns
        {
            clock = LabClock {
                t_now_ns: list.t_now,
                received: Instant::now(),
            };
            let _ = session.send(&commands(list.t_now));
            sent = Some(Instant::now());
        } else if sent.is_none_or(|s| s.elapsed() >= RESEND) {
            let _ = session.send(&commands(clock.now_ns()));
            sent = Some(Instant::now());
        }
        thread::sleep(Duration::from_millis(1));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stop_command_has_no_point_after_its_valid_after() {
        let command = stop_command(3, 1.5, 2.5, 10_000_000_000, 100_000_000);
        assert!(is_stop_command(&command));
        let times: Vec<u64> = command
            .trajectory_points
            .iter()
            .map(|p| p.t.nanoseconds)
            .collect();
        assert_eq!(times, [9_800_000_000, 9_900_000_000, 10_000_000_000]);
        assert!(
            command
                .trajectory_points
                .iter()
                .all(|p| (p.px, p.py, p.vx, p.vy) == (1.5, 2.5, 0.0, 0.0))
        );
        let mut moving = command.clone();
        moving.trajectory_points[2].t.nanoseconds += 1;
        assert!(!is_stop_command(&moving));
    }
}
