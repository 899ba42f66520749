//! `cpmx lab emulate`: the CPM Lab's middleware and vehicles, played from a simulated
//! fidelity of a spec over the lab's topics, so that the lab driver can be tested and
//! rehearsed without a lab.
//!
//! For each run: wait until a planner announced `ReadyStatus hlc_<id>` for every vehicle id
//! of the spec's lab fidelity, place one [`VehicleStack`] per vehicle at the run's initial
//! configuration, send the start `SystemTrigger`, then tick: publish a `VehicleStateList`
//! with the vehicles' reported states (`mapping::lab_state`), wait for one
//! `VehicleCommandTrajectory` per vehicle made for that tick, hand them to the vehicles and
//! run their 50 Hz loops for one period. After `timing.steps` ticks (or a collision under
//! `on_collision: end-run`) send the stop trigger and wait for the next planner.
//!
//! Time is simulated and lock-step, as the lab's `--simulated_time` mode: the clock advances
//! by `timing.dt` only when every vehicle's trajectory for the tick arrived, so a run is as
//! fast as the driver and does not depend on the machine's load. Stamps are nanoseconds from
//! the wall-clock time at the run's start; the vehicles keep the twin's clock (nanoseconds from
//! `cpmx_stack::RUN_START_NS`), and every stamp crosses between the two by the same whole
//! number of nanoseconds, so the vehicles see the times a twin run gives them. Each list holds,
//! per vehicle, the newest state valid at the tick, stamped as the twin's vehicles stamp it
//! (`create` = the time its pose holds, the end of the 20 ms step that produced it,
//! `valid_after = create + 60 ms`; `VehicleStack::listed_state`), as the twin engine's planner
//! sees it, so a run matches the twin engine's run of the same fidelity step for step.
//!
//! Which run: the driver puts its run seed into the announcements' `next_start_stamp`; the
//! emulator looks the seed up in the spec's matrix (runs that differ only in fidelity share
//! it) and uses that run's initial configuration and random streams. An announcement with
//! an unknown stamp (e.g. cpm_lib's 11111) gets the first initial configuration and the
//! spec's `seed`.
//!
//! Lists that stay unanswered are re-sent every [`RESEND_INTERVAL`] (best-effort topics); a
//! planner silent for the lab fidelity's `timeout_s` loses its run and the emulator waits
//! for the next one. Progress is reported through [`EmulatorEvent`]s; nothing is printed.

use std::collections::{BTreeSet, HashMap};
use std::thread;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use cpmx_follower::TrajectoryPoint;
use cpmx_lab::{
    DiscoveryConfig, KeyedReader, LabError, LabParticipant, Reader, ReadyStatus, SystemTrigger, TimeStamp,
    VehicleCommandTrajectory, VehicleState, VehicleStateList, Writer, topics,
};
use cpmx_spec::model::{Control, Fidelity, LabFidelity, OnCollision, SimulatedFidelity};
use cpmx_spec::{CheckedSpec, RunPlan};

use super::mapping::lab_state;
use super::{discovery_config, hlc_vehicle_id, ns_from_s, timeout};
use crate::experiment::Experiment;
use crate::starts::InitialState;
use cpmx_stack::control_periods;
use cpmx_stack::{CONTROL_PERIOD_NS, CONTROL_PERIOD_S, RUN_START_NS, StampedState, VehicleStack};

/// How often the emulator polls its readers.
const POLL_INTERVAL: Duration = Duration::from_millis(1);

/// How long the stop trigger waits for its readers' acknowledgments.
const STOP_DELIVERY: Duration = Duration::from_secs(1);

/// How long an unanswered state list (and the start trigger) waits before it is re-sent.
pub const RESEND_INTERVAL: Duration = Duration::from_millis(100);

/// Why the emulator cannot serve a spec.
#[derive(Debug, thiserror::Error)]
pub enum EmulateError {
    #[error("the spec has no lab fidelity (`driver: cpm-dds`) whose planner to serve")]
    NoLabFidelity,
    #[error("the spec has no fidelity `{0}`")]
    UnknownFidelity(String),
    #[error(
        "fidelity `{0}` is not a simulated `control: trajectory` fidelity: the lab's vehicles follow trajectories"
    )]
    NotTrajectory(String),
    #[error("the spec has no simulated `control: trajectory` fidelity to play the lab with")]
    NoTrajectoryFidelity,
    #[error("lab fidelity `{name}`: {reason}")]
    Discovery { name: String, reason: String },
    #[error("`timing.dt` must be a multiple of the vehicles' {CONTROL_PERIOD_S} s period")]
    Timing,
    #[error("the spec has no initial configuration to place the vehicles at")]
    NoConfiguration,
    #[error("lab fidelity `{name}` has {ids} vehicle ids for {agents} agents")]
    VehicleCount { name: String, ids: usize, agents: usize },
    #[error("cannot build the vehicles of fidelity `{fidelity}`: {reason}")]
    Vehicle { fidelity: String, reason: String },
    #[error(transparent)]
    Lab(#[from] LabError),
}

/// What the emulator is doing, for the command line to show.
#[derive(Debug, Clone, PartialEq)]
pub enum EmulatorEvent {
    /// Waiting for a planner's `hlc_<id>` announcements.
    Waiting,
    /// A run started: the run's key in the spec's matrix (or the configuration used).
    Started { run: String, seed: u64 },
    /// The run ended after `ticks` answered ticks; the stop trigger was sent.
    Finished { ticks: usize },
    /// The planner fell silent after `ticks` answered ticks; the stop trigger was sent.
    Abandoned { ticks: usize },
}

/// The lab, played from one simulated fidelity of a spec.
#[derive(Debug)]
pub struct Emulator<'a> {
    experiment: &'a Experiment,
    plans: Vec<RunPlan>,
    lab_name: String,
    lab: &'a LabFidelity,
    fidelity_name: String,
    fidelity: &'a SimulatedFidelity,
    config: DiscoveryConfig,
    substeps: usize,
}

/// One run as the emulator plays it.
#[derive(Debug)]
struct EmulatedRun {
    name: String,
    seed: u64,
    starts: Vec<InitialState>,
}

/// The emulator's endpoints (the middleware's side of each topic).
struct Endpoints {
    _participant: LabParticipant,
    ready: Reader<ReadyStatus>,
    triggers: Writer<SystemTrigger>,
    lists: Writer<VehicleStateList>,
    commands: KeyedReader<VehicleCommandTrajectory>,
}

impl<'a> Emulator<'a> {
    /// The emulator of the spec's (first) lab fidelity, played by `fidelity` or else by the
    /// spec's first simulated `control: trajectory` fidelity.
    pub fn new(
        checked: &CheckedSpec,
        experiment: &'a Experiment,
        fidelity: Option<&str>,
    ) -> Result<Self, EmulateError> {
        let spec = &experiment.spec;
        let (lab_name, lab) = spec
            .fidelities
            .iter()
            .find_map(|(name, f)| match f {
                Fidelity::Lab(lab) => Some((name.clone(), lab)),
                Fidelity::Simulated(_) => None,
            })
            .ok_or(EmulateError::NoLabFidelity)?;
        let trajectory = |f: &'a Fidelity| match f {
            Fidelity::Simulated(s) if s.control == Control::Trajectory => Some(s),
            _ => None,
        };
        let (fidelity_name, fidelity) = match fidelity {
            Some(name) => {
                let f = spec
                    .fidelities
                    .get(name)
                    .ok_or_else(|| EmulateError::UnknownFidelity(name.to_owned()))?;
                (
                    name.to_owned(),
                    trajectory(f).ok_or_else(|| EmulateError::NotTrajectory(name.to_owned()))?,
                )
            }
            None => spec
                .fidelities
                .iter()
                .find_map(|(name, f)| trajectory(f).map(|s| (name.clone(), s)))
                .ok_or(EmulateError::NoTrajectoryFidelity)?,
        };
        let config = discovery_config(lab).map_err(|reason| EmulateError::Discovery {
            name: lab_name.clone(),
            reason,
        })?;
        let substeps = control_periods(spec.timing.dt).ok_or(EmulateError::Timing)?;
        if lab.vehicle_ids.len() != spec.agents as usize {
            return Err(EmulateError::VehicleCount {
                name: lab_name,
                ids: lab.vehicle_ids.len(),
                agents: spec.agents as usize,
            });
        }
        if experiment.starts.is_empty() {
            return Err(EmulateError::NoConfiguration);
        }
        Ok(Self {
            experiment,
            plans: checked.plan(),
            lab_name,
            lab,
            fidelity_name,
            fidelity,
            config,
            substeps,
        })
    }

    /// The name of the lab fidelity whose planner is served.
    pub fn lab_name(&self) -> &str {
        &self.lab_name
    }

    /// The lab fidelity whose planner is served (domain, vehicle ids, timeout).
    pub fn lab(&self) -> &LabFidelity {
        self.lab
    }

    /// The name of the simulated fidelity that plays the lab.
    pub fn fidelity_name(&self) -> &str {
        &self.fidelity_name
    }

    /// Serves planners one after the other: `runs` of them, or until the process is stopped.
    pub fn serve(
        &self,
        runs: Option<usize>,
        on_event: &mut dyn FnMut(EmulatorEvent),
    ) -> Result<(), EmulateError> {
        let participant = LabParticipant::new(&self.config)?;
        let mut endpoints = Endpoints {
            ready: participant.reader(&topics::READY_STATUS)?,
            triggers: participant.writer(&topics::SYSTEM_TRIGGER)?,
            lists: participant.writer(&topics::VEHICLE_STATE_LIST)?,
            commands: participant.keyed_reader(&topics::VEHICLE_COMMAND_TRAJECTORY)?,
            _participant: participant,
        };
        let mut served = 0;
        while runs.is_none_or(|n| served < n) {
            on_event(EmulatorEvent::Waiting);
            let stamp = self.wait_ready(&mut endpoints.ready)?;
            let run = self.run_for(stamp);
            on_event(EmulatorEvent::Started {
                run: run.name.clone(),
                seed: run.seed,
            });
            on_event(self.play(&mut endpoints, &run)?);
            served += 1;
        }
        Ok(())
    }

    /// Blocks until one announcement stamp was seen with every vehicle id; returns it.
    fn wait_ready(&self, ready: &mut Reader<ReadyStatus>) -> Result<u64, EmulateError> {
        let mut seen: HashMap<u64, BTreeSet<u8>> = HashMap::new();
        loop {
            for status in ready.take()? {
                if let Some(id) = hlc_vehicle_id(&status.source_id) {
                    seen.entry(status.next_start_stamp.nanoseconds)
                        .or_default()
                        .insert(id);
                }
            }
            let complete = seen
                .iter()
                .find(|(_, ids)| self.lab.vehicle_ids.iter().all(|id| ids.contains(id)));
            if let Some((stamp, _)) = complete {
                return Ok(*stamp);
            }
            thread::sleep(POLL_INTERVAL);
        }
    }

    /// The run whose seed the planner announced, or the first configuration.
    fn run_for(&self, stamp: u64) -> EmulatedRun {
        let found = self
            .plans
            .iter()
            .filter(|p| p.seed == stamp)
            .find(|p| p.fidelity == self.lab_name)
            .and_then(|p| Some((p, self.experiment.start(&p.initial_configuration)?)));
        match found {
            Some((plan, starts)) => EmulatedRun {
                name: plan.key.clone(),
                seed: plan.seed,
                starts: starts.to_vec(),
            },
            None => {
                let (name, starts) = &self.experiment.starts[0];
                EmulatedRun {
                    name: name.clone(),
                    seed: self.experiment.spec.seed,
                    starts: starts.clone(),
                }
            }
        }
    }

    /// Plays one run; returns how it ended.
    fn play(&self, endpoints: &mut Endpoints, run: &EmulatedRun) -> Result<EmulatorEvent, EmulateError> {
        let spec = &self.experiment.spec;
        let vehicle = self.experiment.vehicle;
        let ids = &self.lab.vehicle_ids;
        let (fidelity, _) = crate::randomise::draw_for_run(self.fidelity, run.seed);
        let mut vehicles = run
            .starts
            .iter()
            .enumerate()
            .map(|(i, start)| VehicleStack::new(&fidelity, vehicle, start, run.seed, i))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|reason| EmulateError::Vehicle {
                fidelity: self.fidelity_name.clone(),
                reason,
            })?;
        let origin_ns = wall_clock_ns();
        let dt_s = spec.timing.dt;
        let dt_ns = self.substeps as u64 * CONTROL_PERIOD_NS;
        let period_ms = ns_from_s(dt_s) / 1_000_000;
        let active_vehicle_ids: Vec<i32> = ids.iter().map(|id| i32::from(*id)).collect();
        endpoints.commands.take()?;

        let mut ticks = 0;
        let mut ended = None;
        for tick in 0..spec.timing.steps {
            // Report the vehicles' states and wait for their trajectories.
            let tick_ns = RUN_START_NS + u64::from(tick) * dt_ns;
            let t_now = lab_ns(origin_ns, tick_ns);
            let listed: Vec<StampedState> = vehicles.iter().map(|v| v.listed_state(tick_ns)).collect();
            let list = VehicleStateList {
                t_now,
                period_ms,
                state_list: listed
                    .iter()
                    .zip(ids)
                    .map(|(s, id)| VehicleState {
                        ips_update_age_nanoseconds: s.ips_update_age_ns,
                        ..lab_state(
                            *id,
                            &s.state,
                            lab_ns(origin_ns, s.create_ns),
                            lab_ns(origin_ns, s.valid_after_ns()),
                            &vehicle,
                        )
                    })
                    .collect(),
                vehicle_observation_list: Vec::new(),
                active_vehicle_ids: active_vehicle_ids.clone(),
            };
            let start = (tick == 0).then_some(SystemTrigger {
                next_start: TimeStamp {
                    nanoseconds: origin_ns,
                },
            });
            let Some(commands) = exchange(endpoints, &list, start, ids, timeout(self.lab))? else {
                ended = Some(EmulatorEvent::Abandoned { ticks });
                break;
            };
            ticks += 1;

            // The trajectories take effect and the vehicles run until the next tick.
            for (v, command) in vehicles.iter_mut().zip(commands) {
                let points = command
                    .trajectory_points
                    .iter()
                    .map(|p| TrajectoryPoint {
                        t_ns: vehicle_ns(origin_ns, p.t.nanoseconds),
                        x_m: p.px,
                        y_m: p.py,
                        vx_mps: p.vx,
                        vy_mps: p.vy,
                    })
                    .collect();
                v.receive(
                    points,
                    vehicle_ns(origin_ns, command.header.create_stamp.nanoseconds),
                    vehicle_ns(origin_ns, command.header.valid_after_stamp.nanoseconds),
                );
            }
            for sub in 0..self.substeps as u64 {
                let now_ns = tick_ns + sub * CONTROL_PERIOD_NS;
                for v in &mut vehicles {
                    v.step(now_ns);
                }
            }
            if spec.on_collision == OnCollision::EndRun
                && crate::sim::any_overlap(vehicles.iter().map(VehicleStack::pose), &vehicle)
            {
                break;
            }
        }
        endpoints.triggers.write(SystemTrigger {
            next_start: TimeStamp::STOP,
        })?;
        // Deliver the stop before the next run or the process's end drops it unsent.
        endpoints.triggers.wait_for_acknowledgments(STOP_DELIVERY)?;
        Ok(ended.unwrap_or(EmulatorEvent::Finished { ticks }))
    }
}

/// Publishes `list` (and the start trigger, if given) until every vehicle answered with a
/// trajectory made for the list's tick; `None` when the planner stays silent for `timeout`.
fn exchange(
    endpoints: &mut Endpoints,
    list: &VehicleStateList,
    start: Option<SystemTrigger>,
    ids: &[u8],
    timeout: Duration,
) -> Result<Option<Vec<VehicleCommandTrajectory>>, LabError> {
    let started = Instant::now();
    let mut sent: Option<Instant> = None;
    let mut answers: Vec<Option<VehicleCommandTrajectory>> = vec![None; ids.len()];
    loop {
        if sent.is_none_or(|s| s.elapsed() >= RESEND_INTERVAL) {
            if let Some(trigger) = start {
                endpoints.triggers.write(trigger)?;
            }
            endpoints.lists.write(list.clone())?;
            sent = Some(Instant::now());
        }
        for command in endpoints.commands.take()? {
            let slot = ids.iter().position(|id| *id == command.vehicle_id);
            if let Some(i) = slot
                && command.header.create_stamp.nanoseconds == list.t_now
            {
                answers[i] = Some(command);
            }
        }
        if answers.iter().all(Option::is_some) {
            return Ok(Some(answers.into_iter().flatten().collect()));
        }
        if started.elapsed() >= timeout {
            return Ok(None);
        }
        thread::sleep(POLL_INTERVAL);
    }
}

/// The lab's stamp of the vehicles' time `vehicle_ns`: the run's start is `origin_ns`
/// (saturating at the ends of the lab's clock).
fn lab_ns(origin_ns: u64, vehicle_ns: u64) -> u64 {
    let lab = i128::from(origin_ns) + i128::from(vehicle_ns) - i128::from(RUN_START_NS);
    lab.clamp(0, i128::from(u64::MAX)) as u64
}

/// The vehicles' time of the lab's stamp `lab_ns` ([`lab_ns`] the other way).
fn vehicle_ns(origin_ns: u64, lab_ns: u64) -> u64 {
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
