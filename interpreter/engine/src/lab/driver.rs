//! The lab driver (`driver: cpm-dds`): one run as the CPM Lab's high-level controller (HLC).
//!
//! Start-up as the lab's `HLCCommunicator` (cpm-lab-interface.md §1.5): join the spec's
//! domain, announce `ReadyStatus{source_id: "hlc_<id>"}` for every vehicle id, wait for the
//! start `SystemTrigger`. Then every `VehicleStateList` is a tick. Until the preflight passes
//! (`preflight`: every vehicle reports, fresh fixes, charged, at its start) the vehicles are
//! kept standing and the operator is shown what is wrong. From the first tick that passes, the
//! listed states become the planner's bicycle states (`mapping`: position and yaw unchanged,
//! σ = σ_max · servo), the twin's planner rolls the run's policy out, and every vehicle gets
//! one `VehicleCommandTrajectory`, created and valid at the tick, whose points start at the
//! state's `create_stamp` (the lab's states are at least 60 ms old; `cpmx_stack::anchor_ns`)
//! and run Hp·dt from there in whole nanoseconds on the lab's clock. Every tick's states are
//! the run's recording, with times relative to the first planned tick, each moved by its
//! velocity over its age to the tick.
//!
//! The run ends after `timing.steps` ticks, or earlier on a stop trigger or a `StopRequest`; a
//! fault ends it with an error that keeps what was recorded: a lab silent for `timeout_s`, a
//! middleware whose period is not `timing.dt`, a vehicle whose positioning fixes are older than
//! `ips_age_limit_s`, a vehicle missing from the lists for longer than a plan may start from,
//! Ctrl-C (the runner's stop flag). However a run ends, every vehicle is commanded to stop
//! (`safe_stop`). Irregularities that do not end a run, and the planner's latency per tick,
//! are kept as the run's notes (`irregular`). docs/lab.md has the table of faults.
//!
//! The announcement's `next_start_stamp` (arbitrary for the lab; cpm_lib sends 11111) carries
//! the run's seed, so that `cpmx lab emulate` can place its vehicles as the run's initial
//! configuration. The lab is one: runs of this engine take turns (a process-wide lock).

use std::sync::atomic::AtomicBool;
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use cpmx_lab::{
    DiscoveryConfig, Header, TimeStamp, TrajectoryPoint, VehicleCommandTrajectory, VehicleStateList,
};
use cpmx_planner::PlannedTrajectory;
use cpmx_policy::AgentPaths;
use cpmx_recording::Recording;
use cpmx_spec::model::{Fidelity, LabFidelity, Preflight};
use cpmx_vehicle::{BicycleState, VehicleParams};

use super::irregular::{Irregularities, LATE_TICK_PERIODS};
use super::mapping::{policy_state, recorded_sample};
use super::safe_stop::{LabClock, stop_command, stop_vehicles};
use super::session::{Event, Session};
use super::{
    MIN_TRAJECTORY_POINTS, VEHICLE_LEAD_S, discovery_config, ns_from_s, preflight, s_since, timeout,
};
use crate::engine::{Engine, Operator, RunError, RunInputs};
use crate::starts::InitialState;
use crate::twin::planner;
use cpmx_stack::{STATE_VALID_AFTER_S, VEHICLE_LEAD_NS, anchor_ns, anchored_time_ns, max_state_age_ns};

/// How often the operator is shown the preflight's table again while the run waits.
const SHOW_TABLE_EVERY: Duration = Duration::from_secs(5);

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
        let agents = inputs.starts.len();
        let drive = Drive {
            lab,
            preflight: lab.preflight(),
            vehicle: experiment.vehicle,
            paths: inputs.agent_paths()?,
            planner: planner(planner_spec, dt_s, experiment.vehicle),
            policy: inputs.policy()?,
            starts: inputs.starts,
            stop: inputs.stop,
            operator: inputs.operator,
            steps: spec.timing.steps as usize,
            dt_s,
            step_ns: ns_from_s(dt_s),
            max_age_ns: max_state_age_ns(planner_spec.prediction_horizon, ns_from_s(dt_s)),
            ips_limit_ns: ns_from_s(lab.ips_age_limit_s()),
            created_ns: vec![None; agents],
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
            reach_ns: vec![None; agents],
            clock: None,
            recording: Recording {
                notes: Vec::new(),
                latency_s: Vec::new(),
                statistics: Default::default(),
                times_s: Vec::with_capacity(spec.timing.steps as usize),
                ref_paths: inputs.starts.iter().map(|s| s.ref_path).collect(),
                samples: Vec::with_capacity(spec.timing.steps as usize),
            },
            notes: Irregularities::new(agents),
            knowledge: lab_knowledge(lab, inputs),
        };
        drive.run(&config, inputs.plan.seed)
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

/// One run in progress.
struct Drive<'a> {
    lab: &'a LabFidelity,
    preflight: Preflight,
    vehicle: VehicleParams,
    paths: AgentPaths,
    planner: cpmx_planner::Planner,
    policy: Box<dyn cpmx_policy::Policy>,
    /// The run's planned starts, which the preflight checks.
    starts: &'a [InitialState],
    /// Set when the operator asks to stop (Ctrl-C).
    stop: Option<&'a AtomicBool>,
    /// Where the preflight shows the operator what it waits for.
    operator: Option<&'a Operator>,
    steps: usize,
    dt_s: f64,
    step_ns: u64,
    /// The oldest state a plan may start from (`cpmx_stack::max_state_age_ns`) [ns].
    max_age_ns: u64,
    /// A positioning fix older than this ends the run [ns].
    ips_limit_ns: u64,
    /// Per agent: the `create_stamp` of its last state (none before the first).
    created_ns: Vec<Option<u64>>,
    /// Per agent: the state of the last list that had it (the start before the first).
    last_states: Vec<BicycleState>,
    /// Per agent: the time of the last point of its last trajectory [ns].
    reach_ns: Vec<Option<u64>>,
    /// The lab's clock as last heard.
    clock: Option<LabClock>,
    recording: Recording,
    notes: Irregularities,
    /// What each agent knows of the others through the lab fidelity's communication layer.
    knowledge: cpmx_sensing::NeighbourKnowledge,
}

/// The preflight's wait for the operator.
struct Waiting {
    since: Instant,
    shown: Option<Instant>,
}

impl Drive<'_> {
    /// Start-up, the preflight, then ticks until the run ends; then the safe stop.
    fn run(mut self, config: &DiscoveryConfig, run_seed: u64) -> Result<Recording, RunError> {
        let mut session = Session::join(config, self.lab.vehicle_ids.len())?;
        session.announce(&self.lab.vehicle_ids, run_seed)?;
        let ended = self.drive(&mut session);

        // Whatever ended the run, the vehicles are commanded to stop.
        let positions: Vec<(f64, f64)> = self.last_states.iter().map(|s| (s.x_m, s.y_m)).collect();
        // A run that failed stops them at once; one that ran its course lets its last commands
        // go out first (a writer keeps one sample: a stop right behind them would replace them).
        stop_vehicles(
            &mut session,
            &self.lab.vehicle_ids,
            &positions,
            self.clock,
            self.step_ns,
            ended.is_err(),
        );

        let mut recording = self.recording;
        recording.notes = self.notes.notes(&self.lab.vehicle_ids);
        recording.latency_s = self.notes.latency_s.clone();
        match ended {
            Ok(()) if recording.times_s.is_empty() => {
                Err(RunError::LabStopped(self.notes.stopped.unwrap_or_default()))
            }
            Ok(()) => Ok(recording),
            Err(reason) if recording.times_s.is_empty() => Err(reason),
            Err(reason) => Err(RunError::Partial {
                reason: Box::new(reason),
                recording: Box::new(recording),
            }),
        }
    }

    /// Waits for the start, then answers ticks until the run has its steps or ends.
    fn drive(&mut self, session: &mut Session) -> Result<(), RunError> {
        let lab = self.lab;
        let timeout = timeout(lab);
        let silent = || RunError::LabSilent {
            timeout_s: lab.timeout_s,
            domain: lab.domain,
        };
        let mut start_ns = session.wait_start(timeout, self.stop)?.ok_or_else(silent)?;

        let mut first_ns: Option<u64> = None;
        let mut previous: Option<(u64, Vec<VehicleCommandTrajectory>)> = None;
        let mut waiting = Waiting {
            since: Instant::now(),
            shown: None,
        };
        while self.recording.times_s.len() < self.steps {
            let event = session.next_event(start_ns, &lab.vehicle_ids, timeout, self.stop)?;
            let (list, superseded) = match event {
                Event::Tick { list, superseded } => (list, superseded),
                Event::Stop(reason) => {
                    self.notes.stopped = Some(format!(
                        "{reason} after {} of {} ticks",
                        self.recording.times_s.len(),
                        self.steps
                    ));
                    return Ok(());
                }
                Event::Restarted(new_start_ns) => {
                    self.notes.restarts.push(self.recording.times_s.len());
                    start_ns = new_start_ns;
                    continue;
                }
                Event::Interrupted => return Err(RunError::Interrupted),
                Event::Silent => return Err(silent()),
            };
            let received = Instant::now();
            self.notes.old_lists += superseded;
            if let Some(clock) = self.clock {
                let silence_s = received.duration_since(clock.received).as_secs_f64();
                self.notes.longest_silence_s = self.notes.longest_silence_s.max(silence_s);
            }

            // A repeated tick (the emulator re-sends unanswered lists): answer it again. Lists
            // that bring no new tick for the timeout end the run as silence does.
            if let Some((t_ns, commands)) = &previous {
                if list.t_now <= *t_ns
                    && self
                        .clock
                        .is_some_and(|c| received.duration_since(c.received) >= timeout)
                {
                    return Err(RunError::LabFault(format!(
                        "the lab sent no new tick for {} s: its lists repeat tick t_now = {} ns or go back \
                         in time",
                        lab.timeout_s, t_ns
                    )));
                }
                if list.t_now == *t_ns {
                    self.notes.repeated_ticks += 1;
                    session.send(commands)?;
                    continue;
                }
                if list.t_now < *t_ns {
                    self.notes.old_lists += 1;
                    continue;
                }
                let period_s = if list.period_ms > 0 {
                    list.period_ms as f64 / 1e3
                } else {
                    self.dt_s
                };
                let gap_s = s_since(*t_ns, list.t_now);
                if gap_s > LATE_TICK_PERIODS * period_s {
                    self.notes.late_ticks += 1;
                }
                self.notes.longest_gap_s = self.notes.longest_gap_s.max(gap_s);
            }
            self.clock = Some(LabClock {
                t_now_ns: list.t_now,
                received,
            });
            let dt_ms = self.step_ns / 1_000_000;
            if list.period_ms != dt_ms {
                return Err(RunError::LabPeriod {
                    period_ms: list.period_ms,
                    dt_ms,
                });
            }

            // Before the first planned tick: the preflight, the vehicles kept standing.
            if first_ns.is_none() && !self.preflight(&list, &mut waiting)? {
                let stops = self.stop_commands(list.t_now);
                session.send(&stops)?;
                previous = Some((list.t_now, stops));
                continue;
            }
            let origin_ns = *first_ns.get_or_insert_with(|| {
                self.notes.clock_offset_s = Some(s_since(wall_clock_ns(), list.t_now));
                list.t_now
            });
            let commands = self.tick(&list, origin_ns)?;
            session.send(&commands)?;
            self.account_latency(&list, received, &commands);
            previous = Some((list.t_now, commands));
        }
        Ok(())
    }

    /// The preflight on a list before the first planned tick: `Ok(true)` when the run may
    /// start; otherwise the operator is shown the table, and after `wait_s` the run fails
    /// with it.
    fn preflight(&mut self, list: &VehicleStateList, waiting: &mut Waiting) -> Result<bool, RunError> {
        let verdict = preflight::check(&self.preflight, list, &self.lab.vehicle_ids, self.starts);
        if verdict.passes(self.preflight.misplaced) {
            self.notes.recorded_starts = verdict.recorded_starts();
            return Ok(true);
        }
        let waited_s = waiting.since.elapsed().as_secs_f64();
        if waited_s >= self.preflight.wait_s {
            return Err(RunError::Preflight {
                headline: verdict.headline(),
                table: verdict.table(),
                waited_s,
            });
        }
        if let Some(operator) = self.operator
            && waiting
                .shown
                .is_none_or(|shown| shown.elapsed() >= SHOW_TABLE_EVERY)
        {
            operator.say(&format!(
                "preflight: {}; the vehicles are kept standing until every check passes (at most {} s \
                 more; Ctrl-C to stop):\n{}",
                verdict.headline(),
                (self.preflight.wait_s - waited_s).ceil(),
                verdict.table()
            ));
            waiting.shown = Some(Instant::now());
        }
        Ok(false)
    }

    /// Every vehicle's stop command at the lab's time `t_ns`.
    fn stop_commands(&self, t_ns: u64) -> Vec<VehicleCommandTrajectory> {
        self.lab
            .vehicle_ids
            .iter()
            .zip(&self.last_states)
            .map(|(id, s)| stop_command(*id, s.x_m, s.y_m, t_ns, self.step_ns))
            .collect()
    }

    /// Records the tick's states and plans every vehicle's trajectory; a vehicle lost to the
    /// positioning or missing from the lists for too long ends the run.
    fn tick(
        &mut self,
        list: &VehicleStateList,
        origin_ns: u64,
    ) -> Result<Vec<VehicleCommandTrajectory>, RunError> {
        // The newest state of each vehicle; missing ones keep their last state.
        let fresh_fix_ns = ns_from_s(self.preflight.max_ips_age_ms / 1e3);
        for (agent, id) in self.lab.vehicle_ids.iter().enumerate() {
            let newest = list
                .state_list
                .iter()
                .filter(|s| s.vehicle_id == *id && s.header.create_stamp.nanoseconds > 0)
                .max_by_key(|s| s.header.create_stamp)
                .filter(|s| Some(s.header.create_stamp.nanoseconds) > self.created_ns[agent])
                .and_then(|s| {
                    let state = policy_state(s, &self.vehicle)?;
                    Some((
                        s.header.create_stamp.nanoseconds,
                        s.ips_update_age_nanoseconds,
                        state,
                    ))
                });
            match newest {
                Some((created_ns, fix_age_ns, state)) => {
                    if fix_age_ns > self.ips_limit_ns {
                        return Err(RunError::LabFault(format!(
                            "vehicle {id}'s positioning fixes stopped: its IPS update age reached {:.2} s at \
                             t = {:.2} s (the limit is {} s; the lab's controller stops a car at 3 s)",
                            fix_age_ns as f64 / 1e9,
                            s_since(origin_ns, list.t_now),
                            self.lab.ips_age_limit_s()
                        )));
                    }
                    if fix_age_ns > fresh_fix_ns {
                        let (count, oldest_s) = &mut self.notes.old_fixes[agent];
                        *count += 1;
                        *oldest_s = oldest_s.max(fix_age_ns as f64 / 1e9);
                    }
                    self.last_states[agent] = state;
                    self.created_ns[agent] = Some(created_ns);
                }
                None => {
                    self.notes.missing[agent] += 1;
                    if let Some(created_ns) = self.created_ns[agent]
                        && list.t_now.saturating_sub(created_ns) > self.max_age_ns
                    {
                        return Err(RunError::LabFault(format!(
                            "vehicle {id} left the state lists: no new state for {:.2} s at t = {:.2} s \
                             (a plan may start from a state at most {:.2} s old)",
                            s_since(created_ns, list.t_now),
                            s_since(origin_ns, list.t_now),
                            self.max_age_ns as f64 / 1e9
                        )));
                    }
                }
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
                    trajectory_points: lab_points(trajectory, anchor, self.step_ns),
                }
            })
            .collect())
    }

    /// The planner's latency at this tick, and whether a vehicle was left less than its lead
    /// time: when the commands went out (the tick's `t_now` plus the latency, on the lab's
    /// clock), the previous trajectory or the new one reached less than the lead time ahead.
    fn account_latency(
        &mut self,
        list: &VehicleStateList,
        received: Instant,
        commands: &[VehicleCommandTrajectory],
    ) {
        let latency = received.elapsed();
        self.notes.latency_s.push(latency.as_secs_f64());
        let sent_ns = list
            .t_now
            .saturating_add(u64::try_from(latency.as_nanos()).unwrap_or(u64::MAX));
        let mut missed = false;
        for (reach, command) in self.reach_ns.iter_mut().zip(commands) {
            let new_reach = command.trajectory_points.last().map(|p| p.t.nanoseconds);
            for r in [*reach, new_reach].into_iter().flatten() {
                missed |= r.saturating_sub(sent_ns) < VEHICLE_LEAD_NS;
            }
            *reach = new_reach;
        }
        if missed {
            self.notes.lead_misses += 1;
        }
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

/// This machine's clock as the lab's stamps count (ns since the Unix epoch).
fn wall_clock_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .ok()
        .and_then(|d| u64::try_from(d.as_nanos()).ok())
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

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
