//! `cpmx lab emulate`: the CPM Lab's middleware and vehicles, played from a simulated
//! fidelity of a spec over the lab's topics, so that the lab driver can be tested and
//! rehearsed without a lab — a well-behaved lab, or one with faults.
//!
//! For each run: wait until a planner announced `ReadyStatus hlc_<id>` for every vehicle id
//! of the spec's lab fidelity, place one [`VehicleStack`] per vehicle at the run's initial
//! configuration, draw the run's faults, send the start `SystemTrigger`, then tick: publish a
//! `VehicleStateList` with the vehicles' reported states (`stage`), hand the trajectories
//! that come to the vehicles and run their 50 Hz loops. After `timing.steps` ticks driven by
//! the planner (or a collision under `on_collision: end-run`) send the stop trigger and wait
//! for the next planner. Two clocks (`EmulatorClock`): simulated time in lock-step, as the
//! lab's `--simulated_time` mode (`lockstep`), or the wall clock, as the lab runs
//! (`realtime`).
//!
//! Which run: the driver puts its run seed into the announcements' `next_start_stamp`; the
//! emulator looks the seed up in the spec's matrix (runs that differ only in fidelity share
//! it) and uses that run's initial configuration and random streams. An announcement with
//! an unknown stamp (e.g. cpm_lib's 11111) gets the first initial configuration and the
//! spec's `seed`. A planner silent for the lab fidelity's `timeout_s`, or one that announces
//! another run, loses its run and the emulator serves the next one.
//!
//! Faults (`faults`: the lab fidelity's, or `--faults FILE`) are drawn per run from their
//! seed and the run's (`faults`). Progress is reported through [`EmulatorEvent`]s; nothing
//! is printed.

use std::collections::{BTreeSet, HashMap};
use std::thread;
use std::time::{Duration, Instant};

use cpmx_lab::{DiscoveryConfig, LabError};
use cpmx_spec::model::{Control, Fidelity, LabFaults, LabFidelity, OnCollision, SimulatedFidelity};
use cpmx_spec::{CheckedSpec, RunPlan};

use super::faults::FaultPlan;
use super::stage::Stage;
use super::wire::Wire;
use super::{discovery_config, hlc_vehicle_id, ns_from_s, timeout};
use crate::experiment::Experiment;
use crate::starts::InitialState;
use cpmx_stack::control_periods;
use cpmx_stack::{CONTROL_PERIOD_NS, CONTROL_PERIOD_S, FollowerStops, VehicleStack};

pub use super::lockstep::RESEND_INTERVAL;

/// How long the vehicles drive on after a run, before the emulator says which stand [ns] (as
/// long as the lab's controller keeps a command).
const AFTER_THE_RUN_NS: u64 = 1_000_000_000;

/// How long the emulator takes the commands of a planner that finished its run (its safe stop
/// lasts `STOP_WINDOW`) [wall clock].
const STOPS_AFTER_THE_RUN: Duration = Duration::from_millis(500);

/// How often the emulator polls for announcements.
const POLL_INTERVAL: Duration = Duration::from_millis(1);

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

/// Which clock the emulated lab runs on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum EmulatorClock {
    /// Simulated time in lock-step with the planner (deterministic, as fast as the planner).
    #[default]
    Simulated,
    /// The wall clock: the middleware ticks every period whether the planner answered or not.
    RealTime,
}

/// What the emulator is doing, for the command line to show.
#[derive(Debug, Clone, PartialEq)]
pub enum EmulatorEvent {
    /// Waiting for a planner's `hlc_<id>` announcements.
    Waiting,
    /// A run started: the run's key in the spec's matrix (or the configuration used), and
    /// the faults drawn for it.
    Started {
        run: String,
        seed: u64,
        faults: Vec<String>,
    },
    /// A fault of the middleware happened (a pause, a restart).
    Fault(String),
    /// The planner commanded these vehicles to stop during the run (a failed run's safe stop);
    /// these stood still at its end.
    Stopped { commanded: Vec<u8>, standing: Vec<u8> },
    /// The run ended after `ticks` ticks the planner drove; the stop trigger was sent.
    Finished { ticks: usize },
    /// The planner, having driven `ticks` ticks, stopped every vehicle (its safe stop after a
    /// failure or an interrupt); the stop trigger was sent.
    Ended { ticks: usize },
    /// The planner fell silent after `ticks` driven ticks; the stop trigger was sent.
    Abandoned { ticks: usize },
    /// The planner announced another run after `ticks` driven ticks; the stop trigger was
    /// sent.
    Superseded { ticks: usize },
    /// The vehicles' followers stopped their cars during the run once they had a command
    /// (refused trajectories, commands too old, positioning lost): the periods of every
    /// vehicle together, sent after the run's end when there were any.
    FollowerStopped(FollowerStops),
}

/// How one run ends: its length, the planner's timeout, collisions, the run's announcement.
#[derive(Debug, Clone, Copy)]
pub(super) struct RunRules {
    /// Ticks driven by the planner.
    pub steps: usize,
    pub timeout: Duration,
    /// End at the first collision (`on_collision: end-run`).
    pub on_collision: bool,
    /// The run's announcement stamp (another one means the planner moved on).
    pub stamp: u64,
}

impl RunRules {
    /// The timeout [ns].
    pub fn timeout_ns(&self) -> u64 {
        u64::try_from(self.timeout.as_nanos()).unwrap_or(u64::MAX)
    }
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
    faults: Option<LabFaults>,
    clock: EmulatorClock,
}

/// One run as the emulator plays it.
#[derive(Debug)]
struct EmulatedRun {
    name: String,
    seed: u64,
    starts: Vec<InitialState>,
}

impl<'a> Emulator<'a> {
    /// The emulator of the spec's (first) lab fidelity, played by `fidelity` or else by the
    /// spec's first simulated `control: trajectory` fidelity, with the lab fidelity's faults.
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
            faults: lab.faults.clone().filter(|f| !f.is_empty()),
            clock: EmulatorClock::default(),
        })
    }

    /// Plays `faults` instead of the lab fidelity's (`cpmx lab emulate --faults`).
    pub fn with_faults(mut self, faults: Option<LabFaults>) -> Self {
        self.faults = faults.filter(|f| !f.is_empty());
        self
    }

    /// Runs on `clock`.
    pub fn with_clock(mut self, clock: EmulatorClock) -> Self {
        self.clock = clock;
        self
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

    /// The faults played, if any.
    pub fn faults(&self) -> Option<&LabFaults> {
        self.faults.as_ref()
    }

    /// Serves planners one after the other: `runs` of them, or until the process is stopped.
    pub fn serve(
        &self,
        runs: Option<usize>,
        on_event: &mut dyn FnMut(EmulatorEvent),
    ) -> Result<(), EmulateError> {
        let mut wire = Wire::new(&self.config)?;
        let mut served = 0;
        while runs.is_none_or(|n| served < n) {
            on_event(EmulatorEvent::Waiting);
            let stamp = self.wait_ready(&mut wire)?;
            let run = self.run_for(stamp);
            self.play(&mut wire, &run, stamp, on_event)?;
            served += 1;
        }
        Ok(())
    }

    /// Blocks until one announcement stamp was seen with every vehicle id; returns it.
    fn wait_ready(&self, wire: &mut Wire) -> Result<u64, EmulateError> {
        let mut seen: HashMap<u64, BTreeSet<u8>> = HashMap::new();
        loop {
            for status in wire.announcements()? {
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
            .find(|p| {
                // The lab fidelity, or a point of it when its communication layer is swept.
                p.fidelity == self.lab_name
                    || p.fidelity
                        .strip_prefix(self.lab_name.as_str())
                        .is_some_and(|point| point.starts_with('@'))
            })
            .and_then(|p| Some((p, self.experiment.start(p)?)));
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
                    starts: starts.any().unwrap_or_default().to_vec(),
                }
            }
        }
    }

    /// Plays one run: says how it ended, then which vehicles the planner stopped.
    fn play(
        &self,
        wire: &mut Wire,
        run: &EmulatedRun,
        stamp: u64,
        on_event: &mut dyn FnMut(EmulatorEvent),
    ) -> Result<(), EmulateError> {
        let spec = &self.experiment.spec;
        let ids = &self.lab.vehicle_ids;
        let faults = self
            .faults
            .as_ref()
            .map(|f| FaultPlan::draw(f, ids, run.seed))
            .unwrap_or_default();
        on_event(EmulatorEvent::Started {
            run: run.name.clone(),
            seed: run.seed,
            faults: faults.description.clone(),
        });

        // The vehicles where the run (or a misplacement) puts them.
        let (fidelity, _) = crate::randomise::draw_for_run(self.fidelity, run.seed);
        let mut starts = run.starts.clone();
        for (agent, [dx, dy, dyaw]) in &faults.misplaced {
            if let Some(s) = starts.get_mut(*agent) {
                s.x_m += dx;
                s.y_m += dy;
                s.yaw_rad += dyaw;
            }
        }
        let vehicles = starts
            .iter()
            .enumerate()
            .map(|(i, start)| VehicleStack::new(&fidelity, self.experiment.vehicle, start, run.seed, i))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|reason| EmulateError::Vehicle {
                fidelity: self.fidelity_name.clone(),
                reason,
            })?;
        let dt_ns = self.substeps as u64 * CONTROL_PERIOD_NS;
        debug_assert_eq!(dt_ns, ns_from_s(spec.timing.dt));
        let mut stage = Stage::new(vehicles, ids, faults, self.experiment.vehicle, dt_ns);
        let rules = RunRules {
            steps: spec.timing.steps as usize,
            timeout: timeout(self.lab),
            on_collision: spec.on_collision == OnCollision::EndRun,
            stamp,
        };

        wire.start_run(self.faults.as_ref(), run.seed)?;
        let ended = match self.clock {
            EmulatorClock::Simulated => super::lockstep::play(&mut stage, wire, &rules, on_event)?,
            EmulatorClock::RealTime => super::realtime::play(&mut stage, wire, &rules, on_event)?,
        };
        on_event(ended.clone());
        // Counted before the planner's stops are handed over and the lab's time goes on,
        // where a car whose command grows old is meant to stop.
        let stops: FollowerStops = stage.vehicles.iter().map(VehicleStack::stops).sum();
        if stops.note().is_some() {
            on_event(EmulatorEvent::FollowerStopped(stops));
        }
        // A planner that finished its run stops its vehicles now: their commands are handed
        // over. Then the lab's time goes on: the vehicles do what they were told last (a car
        // whose command is a second old stops), and the emulator says which stand.
        if matches!(
            ended,
            EmulatorEvent::Finished { .. } | EmulatorEvent::Ended { .. }
        ) {
            take_stops(&mut stage, wire, STOPS_AFTER_THE_RUN)?;
        }
        stage.coast(AFTER_THE_RUN_NS);
        if !stage.stop_commanded.is_empty() {
            on_event(EmulatorEvent::Stopped {
                commanded: stage.stop_commanded.iter().copied().collect(),
                standing: stage.standing(),
            });
        }
        wire.send_stop()?;
        Ok(())
    }
}

/// Hands the commands that come within `span` to the vehicles (the planner's stop after its
/// last tick).
fn take_stops(stage: &mut Stage, wire: &mut Wire, span: Duration) -> Result<(), EmulateError> {
    let until = Instant::now() + span;
    while Instant::now() < until {
        for command in wire.commands()? {
            stage.receive(&command);
        }
        thread::sleep(POLL_INTERVAL);
    }
    Ok(())
}
