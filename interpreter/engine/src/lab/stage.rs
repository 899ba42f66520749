//! One emulated run's vehicles on the lab's clock, with the run's faults: the state lists the
//! middleware publishes (vehicles that left them missing, empty or stale; low batteries), the
//! trajectories handed to the vehicles, and their 50 Hz steps (positioning fixes lost while a
//! fault lasts).
//!
//! Stamps are nanoseconds from the wall-clock time at the run's start (plus the faults' clock
//! offset); the vehicles keep the twin's clock (nanoseconds from `cpmx_stack::RUN_START_NS`),
//! and every stamp crosses between the two by the same whole number of nanoseconds, so the
//! vehicles see the times a twin run gives them. Each list holds, per vehicle, the newest state
//! valid at the tick, stamped as the twin's vehicles stamp it (`create` = the time its pose
//! holds, `valid_after = create + 60 ms`; `VehicleStack::listed_state`).

use std::collections::BTreeSet;
use std::time::{SystemTime, UNIX_EPOCH};

use cpmx_follower::TrajectoryPoint;
use cpmx_lab::{SystemTrigger, TimeStamp, VehicleCommandTrajectory, VehicleState, VehicleStateList};
use cpmx_spec::model::ListedAs;
use cpmx_vehicle::VehicleParams;

use super::faults::FaultPlan;
use super::mapping::lab_state;
use super::safe_stop::is_stop_command;
use cpmx_stack::{CONTROL_PERIOD_NS, RUN_START_NS, StampedState, VehicleStack, step_together};

/// A vehicle slower than this stands [m/s].
const STANDING_MPS: f64 = 0.01;

/// A run's vehicles and faults.
pub(super) struct Stage {
    pub vehicles: Vec<VehicleStack>,
    pub ids: Vec<u8>,
    pub faults: FaultPlan,
    pub vehicle: VehicleParams,
    /// The lab's stamp of the vehicles' [`RUN_START_NS`].
    pub origin_ns: u64,
    /// The period in the lists [ms], and in ns.
    pub period_ms: u64,
    pub dt_ns: u64,
    /// Per agent: the state it last listed (a vehicle listed stale repeats it).
    listed: Vec<Option<VehicleState>>,
    /// Per agent: whether its positioning fixes are lost now.
    ips_lost: Vec<bool>,
    /// The vehicles that were sent a stop command.
    pub stop_commanded: BTreeSet<u8>,
    /// The vehicles' clock after their last step [ns].
    clock_ns: u64,
}

impl Stage {
    /// The stage of a run starting now (on the wall clock, moved by the clock offset).
    pub fn new(
        vehicles: Vec<VehicleStack>,
        ids: &[u8],
        faults: FaultPlan,
        vehicle: VehicleParams,
        dt_ns: u64,
    ) -> Self {
        let origin_ns = wall_clock_ns().saturating_add_signed(faults.clock_offset_ns);
        let agents = vehicles.len();
        Self {
            vehicles,
            ids: ids.to_vec(),
            faults,
            vehicle,
            origin_ns,
            period_ms: dt_ns / 1_000_000,
            dt_ns,
            listed: vec![None; agents],
            ips_lost: vec![false; agents],
            stop_commanded: BTreeSet::new(),
            clock_ns: RUN_START_NS,
        }
    }

    /// The vehicles' time of tick `tick` [ns].
    pub fn tick_ns(&self, tick: u64) -> u64 {
        RUN_START_NS + tick * self.dt_ns
    }

    /// The start trigger of a run (or of a restarted middleware) at the vehicles' `t_ns`.
    pub fn start_trigger(&self, t_ns: u64) -> SystemTrigger {
        SystemTrigger {
            next_start: TimeStamp {
                nanoseconds: lab_ns(self.origin_ns, t_ns),
            },
        }
    }

    /// The middleware's list at the vehicles' `tick_ns`.
    pub fn list(&mut self, tick_ns: u64) -> VehicleStateList {
        let mut state_list = Vec::with_capacity(self.ids.len());
        for (agent, (v, id)) in self.vehicles.iter().zip(&self.ids).enumerate() {
            let left = self
                .faults
                .leave_lists
                .iter()
                .find(|(a, span, _)| *a == agent && span.contains(tick_ns))
                .map(|(_, _, listed)| *listed);
            match left {
                Some(ListedAs::Missing) => {}
                Some(ListedAs::Empty) => state_list.push(VehicleState {
                    vehicle_id: *id,
                    ..VehicleState::default()
                }),
                Some(ListedAs::Stale) => state_list.extend(self.listed[agent]),
                None => {
                    let s: StampedState = v.listed_state(tick_ns);
                    let battery_v = self
                        .faults
                        .low_battery
                        .iter()
                        .find(|(a, _)| *a == agent)
                        .map_or(s.battery_voltage_v, |(_, volts)| *volts);
                    let state = VehicleState {
                        ips_update_age_nanoseconds: s.ips_update_age_ns,
                        battery_voltage: battery_v,
                        ..lab_state(
                            *id,
                            &s.state,
                            lab_ns(self.origin_ns, s.create_ns),
                            lab_ns(self.origin_ns, s.valid_after_ns()),
                            &self.vehicle,
                        )
                    };
                    self.listed[agent] = Some(state);
                    state_list.push(state);
                }
            }
        }
        VehicleStateList {
            t_now: lab_ns(self.origin_ns, tick_ns),
            period_ms: self.period_ms,
            state_list,
            vehicle_observation_list: Vec::new(),
            active_vehicle_ids: self.ids.iter().map(|id| i32::from(*id)).collect(),
        }
    }

    /// The vehicles' tick of a command's `create_stamp` (rounded down), if it is one of this
    /// run's.
    pub fn tick_of(&self, command: &VehicleCommandTrajectory) -> Option<u64> {
        let t_ns = vehicle_ns(self.origin_ns, command.header.create_stamp.nanoseconds);
        t_ns.checked_sub(RUN_START_NS).map(|since| since / self.dt_ns)
    }

    /// Hands a command to its vehicle (kept until it is valid, as on the car).
    pub fn receive(&mut self, command: &VehicleCommandTrajectory) {
        let Some(agent) = self.ids.iter().position(|id| *id == command.vehicle_id) else {
            return;
        };
        if is_stop_command(command) {
            self.stop_commanded.insert(command.vehicle_id);
        }
        let points = command
            .trajectory_points
            .iter()
            .map(|p| TrajectoryPoint {
                t_ns: vehicle_ns(self.origin_ns, p.t.nanoseconds),
                x_m: p.px,
                y_m: p.py,
                vx_mps: p.vx,
                vy_mps: p.vy,
            })
            .collect();
        self.vehicles[agent].receive(
            points,
            vehicle_ns(self.origin_ns, command.header.create_stamp.nanoseconds),
            vehicle_ns(self.origin_ns, command.header.valid_after_stamp.nanoseconds),
        );
    }

    /// One 20 ms step of every vehicle from the vehicles' `now_ns`, positioning faults applied.
    pub fn step(&mut self, now_ns: u64) {
        for (agent, v) in self.vehicles.iter_mut().enumerate() {
            let lost = self
                .faults
                .ips_loss
                .iter()
                .any(|(a, span)| *a == agent && span.contains(now_ns));
            if lost != self.ips_lost[agent] {
                v.lose_ips(now_ns, lost);
                self.ips_lost[agent] = lost;
            }
        }
        step_together(self.vehicles.iter_mut().map(|v| (v, now_ns)));
        self.clock_ns = now_ns + CONTROL_PERIOD_NS;
    }

    /// The vehicles drive on for `span_ns` on their last commands (the lab's time goes on
    /// after the planner left).
    pub fn coast(&mut self, span_ns: u64) {
        let until_ns = self.clock_ns + span_ns;
        while self.clock_ns < until_ns {
            self.step(self.clock_ns);
        }
    }

    /// The steps of one period from the tick at `tick_ns`.
    pub fn run_period(&mut self, tick_ns: u64) {
        let mut now_ns = tick_ns;
        while now_ns < tick_ns + self.dt_ns {
            self.step(now_ns);
            now_ns += CONTROL_PERIOD_NS;
        }
    }

    /// The vehicles standing (true speed below 1 cm/s).
    pub fn standing(&self) -> Vec<u8> {
        self.ids
            .iter()
            .zip(&self.vehicles)
            .filter(|(_, v)| {
                let [vx, vy] = v.true_sample().velocity_mps;
                vx.hypot(vy) < STANDING_MPS
            })
            .map(|(id, _)| *id)
            .collect()
    }

    /// Whether two vehicles overlap.
    pub fn collided(&self) -> bool {
        crate::sim::any_overlap(self.vehicles.iter().map(VehicleStack::pose), &self.vehicle)
    }
}

/// The lab's stamp of the vehicles' time `vehicle_ns`: the run's start is `origin_ns`
/// (saturating at the ends of the lab's clock).
pub(super) fn lab_ns(origin_ns: u64, vehicle_ns: u64) -> u64 {
    let lab = i128::from(origin_ns) + i128::from(vehicle_ns) - i128::from(RUN_START_NS);
    lab.clamp(0, i128::from(u64::MAX)) as u64
}

/// The vehicles' time of the lab's stamp `lab_ns` ([`lab_ns`] the other way).
pub(super) fn vehicle_ns(origin_ns: u64, lab_ns: u64) -> u64 {
    let vehicle = i128::from(RUN_START_NS) + i128::from(lab_ns) - i128::from(origin_ns);
    vehicle.clamp(0, i128::from(u64::MAX)) as u64
}

/// Nanoseconds since the Unix epoch (the lab's time base), 1 s if the clock is before it.
fn wall_clock_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .ok()
        .and_then(|d| u64::try_from(d.as_nanos()).ok())
        .unwrap_or(1_000_000_000)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stamps_cross_between_the_lab_and_the_vehicles_by_whole_nanoseconds() {
        let origin_ns = 1_764_000_000_123_456_789;
        for vehicle in [
            0,
            RUN_START_NS - 60_000_000,
            RUN_START_NS,
            RUN_START_NS + 12_345_678_901,
        ] {
            assert_eq!(vehicle_ns(origin_ns, lab_ns(origin_ns, vehicle)), vehicle);
        }
        assert_eq!(lab_ns(origin_ns, RUN_START_NS), origin_ns);
        assert_eq!(
            lab_ns(origin_ns, RUN_START_NS - 60_000_000),
            origin_ns - 60_000_000
        );
        // Before the vehicles' clock starts: its first nanosecond.
        assert_eq!(vehicle_ns(origin_ns, 0), 0);
    }
}
