//! The lab driver (`driver: cpm-dds`): one run as the CPM Lab's high-level controller (HLC).
//!
//! Start-up as the lab's `HLCCommunicator` (cpm-lab-interface.md §1.5): join the spec's
//! domain, announce `ReadyStatus{source_id: "hlc_<id>"}` for every vehicle id, wait for the
//! start `SystemTrigger`. Then every `VehicleStateList` is a tick: the listed states become
//! the planner's bicycle states (`mapping`: position and yaw unchanged, σ = σ_max · servo),
//! the twin's planner rolls the run's policy out, and every vehicle gets one
//! `VehicleCommandTrajectory`, created and valid at the tick, whose points start at the
//! state's `create_stamp` (the lab's states are at least 60 ms old; `cpmx_stack::anchor_ns`)
//! and run Hp·dt from there in whole nanoseconds on the lab's clock (checked to cover the
//! vehicles' lead time). Every tick's states are the
//! run's recording, with times relative to the first tick, each moved by its velocity over its
//! age to the tick. The run ends after
//! `timing.steps` ticks, or earlier on a stop trigger or a `StopRequest`; a lab that falls
//! silent for `timeout_s` ends it with an error that keeps what was recorded. A middleware
//! whose period is not `timing.dt` is refused (`RunError::LabPeriod`).
//!
//! The announcement's `next_start_stamp` (arbitrary for the lab; cpm_lib sends 11111) carries
//! the run's seed, so that `cpmx lab emulate` can place its vehicles as the run's initial
//! configuration. The lab is one: runs of this engine take turns (a process-wide lock).
//! Irregularities that do not end a run (late ticks, vehicles missing from a list) are
//! summarised on stderr when the run ends.

use std::sync::{Mutex, PoisonError};
use std::thread;
use std::time::{Duration, Instant};

use cpmx_lab::{
    DiscoveryConfig, Header, KeyedReader, KeyedWriter, LabParticipant, Reader, ReadyStatus, StopRequest,
    SystemTrigger, TimeStamp, TrajectoryPoint, VehicleCommandTrajectory, VehicleStateList, Writer, topics,
};
use cpmx_planner::PlannedTrajectory;
use cpmx_policy::AgentPaths;
use cpmx_recording::Recording;
use cpmx_spec::model::{Fidelity, LabFidelity};
use cpmx_vehicle::{BicycleState, VehicleParams};

use super::mapping::{policy_state, recorded_sample};
use super::{MIN_TRAJECTORY_POINTS, VEHICLE_LEAD_S, discovery_config, ns_from_s, s_since, timeout};
use crate::engine::{Engine, RunError, RunInputs};
use crate::twin::planner;
use cpmx_stack::STATE_VALID_AFTER_S;
use cpmx_stack::{anchor_ns, anchored_time_ns, max_state_age_ns};

/// How often the driver polls its readers while it waits.
const POLL_INTERVAL: Duration = Duration::from_millis(1);

/// A tick counts as late when it follows the previous one by more than this many periods.
const LATE_TICK_PERIODS: f64 = 1.5;

/// One lab at a time: runs of the lab engine in one process take turns.
static LAB_IN_USE: Mutex<()> = Mutex::new(());

/// The engine of lab fidelities: runs the planner against the CPM Lab's middleware (or
/// `cpmx lab emulate`) over DDS.
#[derive(Debug, Clone, Copy, Default)]
pub struct LabEngine;

impl Engine for LabEngine {
    fn run(&self, inputs: &RunInputs<'_>) -> Result<Recording, RunError> {
        let _lab = LAB_IN_USE.lock().unwrap_or_else(PoisonError::into_inner);
        let experiment = inputs.experiment;
        let spec = &experiment.spec;
        let unsupported = |reason: String| RunError::Unsupported(inputs.plan.fidelity.clone(), reason);
        let Some(Fidelity::Lab(lab)) = spec.fidelities.get(&inputs.plan.fidelity) else {
            return Err(unsupported("not a lab fidelity".into()));
        };
        let config = discovery_config(lab).map_err(&unsupported)?;
        let planner_spec = spec
            .planner
            .as_ref()
            .ok_or_else(|| unsupported("the spec has no `planner`".into()))?;
        let dt_s = spec.timing.dt;
        let horizon_s = f64::from(planner_spec.prediction_horizon) * dt_s;
        let needed_s = dt_s + VEHICLE_LEAD_S + STATE_VALID_AFTER_S;
        if horizon_s < needed_s - 1e-9
            || (planner_spec.prediction_horizon as usize) < MIN_TRAJECTORY_POINTS - 1
        {
            return Err(unsupported(format!(
                "the lab's vehicles follow a trajectory until {VEHICLE_LEAD_S} s after the next tick, and \
                 it starts at its state's time, at least {STATE_VALID_AFTER_S} s before the tick: \
                 `planner.prediction_horizon` · dt must be at least {needed_s:.2} s (and Hp at least 2), it is {horizon_s:.2} s"
            )));
        }
        if lab.vehicle_ids.len() != inputs.starts.len() {
            return Err(unsupported(format!(
                "{} vehicle ids for {} agents",
                lab.vehicle_ids.len(),
                inputs.starts.len()
            )));
        }

        // Prepare the planner, the policy and the agents' last known states (their starts).
        let paths = inputs.agent_paths()?;
        let drive = Drive {
            lab,
            vehicle: experiment.vehicle,
            paths,
            planner: planner(planner_spec, dt_s, experiment.vehicle),
            policy: inputs.policy()?,
            steps: spec.timing.steps as usize,
            dt_s,
            max_age_ns: max_state_age_ns(planner_spec.prediction_horizon, ns_from_s(dt_s)),
            created_ns: vec![None; inputs.starts.len()],
            last_states: inputs
                .starts
                .iter()
                .map(|s| BicycleState {
                    x_m: s.x_m,
                    y_m: s.y_m,
                    yaw_rad: s.yaw_rad,
                    speed_mps: s.speed_mps,
                    steering_rad: 0.0,
                })
                .collect(),
            recording: Recording {
                notes: Vec::new(),
                times_s: Vec::with_capacity(spec.timing.steps as usize),
                ref_paths: inputs.starts.iter().map(|s| s.ref_path).collect(),
                samples: Vec::with_capacity(spec.timing.steps as usize),
            },
            notes: Notes::new(lab.vehicle_ids.len()),
            knowledge: lab_knowledge(lab, inputs),
        };
        let (mut recording, notes) = drive.run(&config, inputs.plan.seed)?;
        recording.notes.extend(notes.summary(&lab.vehicle_ids));
        Ok(recording)
    }
}

/// The lab fidelity's communication layer for a run: distributions drawn from the run's
/// `randomisation` stream, lost messages from its `communication` stream.
fn lab_knowledge(lab: &LabFidelity, inputs: &RunInputs<'_>) -> cpmx_sensing::NeighbourKnowledge {
    use rand::SeedableRng;
    let seed = inputs.plan.seed;
    let mut rng = rand_chacha::ChaCha20Rng::from_seed(cpmx_spec::matrix::stream_key(seed, "randomisation"));
    let communication = lab
        .communication
        .as_ref()
        .map(|c| c.draw(|_, d, range| cpmx_stack::draw_value(d, range, &mut rng)));
    cpmx_stack::neighbour_knowledge(inputs.starts.len(), communication.as_ref(), None, |name| {
        cpmx_spec::matrix::stream_key(seed, name)
    })
}

/// What a run noticed without failing.
#[derive(Debug, Clone, PartialEq)]
struct Notes {
    /// Ticks that followed the previous one by more than [`LATE_TICK_PERIODS`] periods.
    late_ticks: usize,
    /// Per agent: ticks whose list had no usable state of its vehicle.
    missing: Vec<usize>,
    /// How the run ended before `timing.steps` ticks, if it did.
    stopped: Option<String>,
}

impl Notes {
    fn new(agents: usize) -> Self {
        Self {
            late_ticks: 0,
            missing: vec![0; agents],
            stopped: None,
        }
    }

    /// One line for the user, if anything happened.
    fn summary(&self, vehicle_ids: &[u8]) -> Option<String> {
        let mut parts = Vec::new();
        if let Some(reason) = &self.stopped {
            parts.push(reason.clone());
        }
        if self.late_ticks > 0 {
            parts.push(format!("{} late ticks (planned anyway)", self.late_ticks));
        }
        for (id, count) in vehicle_ids.iter().zip(&self.missing).filter(|(_, c)| **c > 0) {
            parts.push(format!(
                "vehicle {id} missing from {count} ticks (its last state was used)"
            ));
        }
        (!parts.is_empty()).then(|| parts.join("; "))
    }
}

/// The lab's endpoints as the HLC uses them.
struct Session {
    _participant: LabParticipant,
    ready: Writer<ReadyStatus>,
    triggers: Reader<SystemTrigger>,
    stop_requests: KeyedReader<StopRequest>,
    lists: Reader<VehicleStateList>,
    /// One writer per vehicle: rustdds keeps the last sample of a keep-last-1 writer over
    /// all instances, so a burst of commands for several vehicles through one writer would
    /// reach the lab as the last one only.
    commands: Vec<KeyedWriter<VehicleCommandTrajectory>>,
}

impl Session {
    fn join(config: &DiscoveryConfig, vehicles: usize) -> Result<Self, RunError> {
        let participant = LabParticipant::new(config)?;
        let commands = (0..vehicles)
            .map(|_| participant.keyed_writer(&topics::VEHICLE_COMMAND_TRAJECTORY))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            ready: participant.writer(&topics::READY_STATUS)?,
            triggers: participant.reader(&topics::SYSTEM_TRIGGER)?,
            stop_requests: participant.keyed_reader(&topics::STOP_REQUEST)?,
            lists: participant.reader(&topics::VEHICLE_STATE_LIST)?,
            commands,
            _participant: participant,
        })
    }
}

impl Session {
    /// Publishes each vehicle's command through its own writer.
    fn send(&self, commands: &[VehicleCommandTrajectory]) -> Result<(), RunError> {
        for (writer, command) in self.commands.iter().zip(commands) {
            writer.write(command.clone())?;
        }
        Ok(())
    }
}

/// What the driver waits for during a run.
enum Event {
    Tick(VehicleStateList),
    Stop(String),
    Silent,
}

/// One run in progress.
struct Drive<'a> {
    lab: &'a LabFidelity,
    vehicle: VehicleParams,
    paths: AgentPaths,
    planner: cpmx_planner::Planner,
    policy: Box<dyn cpmx_policy::Policy>,
    steps: usize,
    dt_s: f64,
    /// The oldest state a plan may start from (`cpmx_stack::max_state_age_ns`) [ns].
    max_age_ns: u64,
    /// Per agent: the `create_stamp` of its last state (none before the first).
    created_ns: Vec<Option<u64>>,
    /// Per agent: the state of the last list that had it (the start before the first).
    last_states: Vec<BicycleState>,
    recording: Recording,
    notes: Notes,
    /// What each agent knows of the others through the lab fidelity's communication layer.
    knowledge: cpmx_sensing::NeighbourKnowledge,
}

impl Drive<'_> {
    /// Start-up, then ticks until the run ends.
    fn run(mut self, config: &DiscoveryConfig, run_seed: u64) -> Result<(Recording, Notes), RunError> {
        let timeout = timeout(self.lab);
        let silent = || RunError::LabSilent {
            timeout_s: self.lab.timeout_s,
            domain: self.lab.domain,
        };

        // Announce the planner for every vehicle and wait for the start.
        let mut session = Session::join(config, self.lab.vehicle_ids.len())?;
        for id in &self.lab.vehicle_ids {
            session.ready.write(ReadyStatus {
                source_id: format!("{}{id}", super::HLC_SOURCE_PREFIX),
                next_start_stamp: TimeStamp {
                    nanoseconds: run_seed,
                },
            })?;
        }
        let start_ns = wait_start(&mut session, timeout)?.ok_or_else(silent)?;

        // Every tick: states in, trajectories out.
        let mut first_ns: Option<u64> = None;
        let mut previous: Option<(u64, Vec<VehicleCommandTrajectory>)> = None;
        while self.recording.times_s.len() < self.steps {
            let list = match next_event(&mut session, start_ns, &self.lab.vehicle_ids, timeout)? {
                Event::Tick(list) => list,
                Event::Stop(reason) => {
                    self.notes.stopped = Some(format!(
                        "{reason} after {} of {} ticks",
                        self.recording.times_s.len(),
                        self.steps
                    ));
                    break;
                }
                Event::Silent if self.recording.times_s.is_empty() => return Err(silent()),
                Event::Silent => {
                    return Err(RunError::Partial {
                        reason: Box::new(silent()),
                        recording: Box::new(self.recording),
                    });
                }
            };
            // A repeated tick (the emulator re-sends unanswered lists): answer it again.
            if let Some((t_ns, commands)) = &previous {
                if list.t_now == *t_ns {
                    session.send(commands)?;
                    continue;
                }
                if list.t_now < *t_ns {
                    continue;
                }
                let period_s = if list.period_ms > 0 {
                    list.period_ms as f64 / 1e3
                } else {
                    self.dt_s
                };
                if s_since(*t_ns, list.t_now) > LATE_TICK_PERIODS * period_s {
                    self.notes.late_ticks += 1;
                }
            }
            let dt_ms = ns_from_s(self.dt_s) / 1_000_000;
            if list.period_ms != dt_ms {
                let refused = RunError::LabPeriod {
                    period_ms: list.period_ms,
                    dt_ms,
                };
                if self.recording.times_s.is_empty() {
                    return Err(refused);
                }
                return Err(RunError::Partial {
                    reason: Box::new(refused),
                    recording: Box::new(self.recording),
                });
            }
            let origin_ns = *first_ns.get_or_insert(list.t_now);
            let commands = self.tick(&list, origin_ns)?;
            session.send(&commands)?;
            previous = Some((list.t_now, commands));
        }
        if self.recording.times_s.is_empty() {
            return Err(RunError::LabStopped(self.notes.stopped.unwrap_or_default()));
        }
        Ok((self.recording, self.notes))
    }

    /// Records the tick's states and plans every vehicle's trajectory.
    fn tick(
        &mut self,
        list: &VehicleStateList,
        origin_ns: u64,
    ) -> Result<Vec<VehicleCommandTrajectory>, RunError> {
        // The newest usable state of each vehicle; missing ones keep their last state.
        for (agent, id) in self.lab.vehicle_ids.iter().enumerate() {
            let newest = list
                .state_list
                .iter()
                .filter(|s| s.vehicle_id == *id && s.header.create_stamp.nanoseconds > 0)
                .max_by_key(|s| s.header.create_stamp)
                .and_then(|s| Some((s.header.create_stamp.nanoseconds, policy_state(s, &self.vehicle)?)));
            match newest {
                Some((created_ns, state)) => {
                    self.last_states[agent] = state;
                    self.created_ns[agent] = Some(created_ns);
                }
                None => self.notes.missing[agent] += 1,
            }
        }
        let t_s = s_since(origin_ns, list.t_now);
        self.recording.times_s.push(t_s);
        // Each state is at least 60 ms old: it is recorded where its velocity takes it by the
        // tick, so that the recording's times hold (a state older than a plan may start from,
        // of a vehicle missing from the lists, is recorded as it is).
        let recorded = self
            .last_states
            .iter()
            .zip(&self.created_ns)
            .map(|(s, created)| {
                let mut sample = recorded_sample(s, &self.vehicle);
                let age_ns = created.map_or(Some(0), |ns| list.t_now.checked_sub(ns));
                if let Some(age_ns) = age_ns.filter(|age_ns| *age_ns <= self.max_age_ns) {
                    let age_s = age_ns as f64 / 1e9;
                    sample.x_m += sample.velocity_mps[0] * age_s;
                    sample.y_m += sample.velocity_mps[1] * age_s;
                }
                sample
            })
            .collect();
        self.recording.samples.push(recorded);

        // Plan from the lab's states, each trajectory anchored at its state's time on the lab's
        // clock; all are created and valid at the tick.
        if self.knowledge.is_active() {
            let model = cpmx_vehicle::KinematicBicycle::new(self.vehicle);
            let agents: Vec<cpmx_policy::AgentState> = self
                .last_states
                .iter()
                .map(|s| cpmx_policy::AgentState::from_bicycle(s, model.velocity_mps(s)))
                .collect();
            let t_s = self.recording.times_s.last().copied().unwrap_or(0.0);
            self.planner
                .set_neighbours(Some(self.knowledge.step(t_s, &agents)));
        }
        let trajectories = self
            .planner
            .plan(self.policy.as_mut(), &self.last_states, &self.paths, 0.0)?;
        let step_ns = ns_from_s(self.dt_s);
        let stamp = TimeStamp {
            nanoseconds: list.t_now,
        };
        Ok(self
            .lab
            .vehicle_ids
            .iter()
            .zip(&trajectories)
            .zip(&self.created_ns)
            .map(|((id, trajectory), created)| {
                let anchor = created.map_or(list.t_now, |ns| anchor_ns(ns, list.t_now, self.max_age_ns));
                VehicleCommandTrajectory {
                    vehicle_id: *id,
                    header: Header {
                        create_stamp: stamp,
                        valid_after_stamp: stamp,
                    },
                    trajectory_points: lab_points(trajectory, anchor, step_ns),
                }
            })
            .collect())
    }
}

/// A planned trajectory as the lab's points: point `k` at `anchor_ns + k·step_ns` on the
/// lab's clock (`cpmx_stack::anchored_time_ns`, as the twin times its vehicles' points).
fn lab_points(trajectory: &PlannedTrajectory, anchor_ns: u64, step_ns: u64) -> Vec<TrajectoryPoint> {
    trajectory
        .iter()
        .enumerate()
        .map(|(k, p)| TrajectoryPoint {
            t: TimeStamp {
                nanoseconds: anchored_time_ns(anchor_ns, k, step_ns),
            },
            px: p.x_m,
            py: p.y_m,
            vx: p.velocity_mps[0],
            vy: p.velocity_mps[1],
        })
        .collect()
}

/// The start trigger's time, or `None` when none came within `timeout`. Stop triggers
/// before the start belong to an earlier run and are skipped.
fn wait_start(session: &mut Session, timeout: Duration) -> Result<Option<u64>, RunError> {
    let started = Instant::now();
    loop {
        if let Some(start) = session.triggers.take()?.iter().find(|t| !t.is_stop()) {
            return Ok(Some(start.next_start.nanoseconds));
        }
        if started.elapsed() >= timeout {
            return Ok(None);
        }
        thread::sleep(POLL_INTERVAL);
    }
}

/// The next tick at or after the start, a stop, or silence for `timeout`.
fn next_event(
    session: &mut Session,
    start_ns: u64,
    vehicle_ids: &[u8],
    timeout: Duration,
) -> Result<Event, RunError> {
    let started = Instant::now();
    loop {
        if session.triggers.take()?.iter().any(SystemTrigger::is_stop) {
            return Ok(Event::Stop("the lab sent the stop trigger".into()));
        }
        if let Some(request) = session
            .stop_requests
            .take()?
            .iter()
            .find(|r| vehicle_ids.contains(&r.vehicle_id))
        {
            return Ok(Event::Stop(format!(
                "a stop was requested for vehicle {}",
                request.vehicle_id
            )));
        }
        if let Some(list) = session
            .lists
            .take()?
            .into_iter()
            .filter(|l| l.t_now >= start_ns)
            .max_by_key(|l| l.t_now)
        {
            return Ok(Event::Tick(list));
        }
        if started.elapsed() >= timeout {
            return Ok(Event::Silent);
        }
        thread::sleep(POLL_INTERVAL);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn notes_summarise_what_happened() {
        let mut notes = Notes::new(2);
        assert_eq!(notes.summary(&[3, 5]), None);
        notes.late_ticks = 2;
        notes.missing[1] = 4;
        let line = notes.summary(&[3, 5]).expect("something happened");
        assert!(line.contains("2 late ticks"), "{line}");
        assert!(line.contains("vehicle 5 missing from 4 ticks"), "{line}");
    }

    #[test]
    fn points_are_stamped_on_the_labs_clock() {
        let point = |t_s| cpmx_planner::PlannedPoint {
            t_s,
            x_m: 1.0,
            y_m: 2.0,
            yaw_rad: 0.0,
            velocity_mps: [0.5, 0.0],
            speed_mps: 0.5,
            steering_rad: 0.0,
        };
        // Anchored at a state 60 ms before the tick; the planner's own times do not matter.
        let anchor_ns = 1_764_000_000_123_456_789 - 60_000_000;
        let points = lab_points(&vec![point(0.0), point(0.1), point(0.2)], anchor_ns, 100_000_000);
        let stamps: Vec<u64> = points.iter().map(|p| p.t.nanoseconds).collect();
        assert_eq!(
            stamps,
            [anchor_ns, anchor_ns + 100_000_000, anchor_ns + 200_000_000]
        );
        assert_eq!((points[0].px, points[0].vx), (1.0, 0.5));
    }
}
