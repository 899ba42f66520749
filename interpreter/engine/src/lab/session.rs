//! The driver's endpoints on the lab's topics, and what it waits for: the start trigger, then
//! ticks, stops, a restarted middleware, an interrupt, or silence.

use std::sync::atomic::{AtomicBool, Ordering};
use std::thread;
use std::time::{Duration, Instant};

use cpmx_lab::{
    DiscoveryConfig, KeyedReader, KeyedWriter, LabParticipant, Reader, ReadyStatus, StopRequest,
    SystemTrigger, TimeStamp, VehicleCommandTrajectory, VehicleStateList, Writer, topics,
};

use crate::engine::RunError;

/// How often the driver polls its readers while it waits.
const POLL_INTERVAL: Duration = Duration::from_millis(1);

/// The lab's endpoints as the HLC uses them.
pub(super) struct Session {
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

/// What the driver waits for during a run.
pub(super) enum Event {
    /// The newest list at or after the start, and how many older ones came with it.
    Tick {
        list: VehicleStateList,
        superseded: usize,
    },
    /// The lab ended the run (stop trigger, stop request).
    Stop(String),
    /// A start trigger for a later start: the middleware was restarted (its new start).
    Restarted(u64),
    /// The operator asked to stop (Ctrl-C).
    Interrupted,
    /// Nothing for the timeout.
    Silent,
}

impl Session {
    pub(super) fn join(config: &DiscoveryConfig, vehicles: usize) -> Result<Self, RunError> {
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

    /// Announces the planner for every vehicle (`hlc_<id>`), with the run's seed as the
    /// announcement's `next_start_stamp`.
    pub(super) fn announce(&self, vehicle_ids: &[u8], run_seed: u64) -> Result<(), RunError> {
        for id in vehicle_ids {
            self.ready.write(ReadyStatus {
                source_id: format!("{}{id}", super::HLC_SOURCE_PREFIX),
                next_start_stamp: TimeStamp {
                    nanoseconds: run_seed,
                },
            })?;
        }
        Ok(())
    }

    /// Publishes each vehicle's command through its own writer.
    pub(super) fn send(&self, commands: &[VehicleCommandTrajectory]) -> Result<(), RunError> {
        for (writer, command) in self.commands.iter().zip(commands) {
            writer.write(command.clone())?;
        }
        Ok(())
    }

    /// The start trigger's time, or `Ok(None)` when none came within `timeout`. Stop triggers
    /// before the start belong to an earlier run and are skipped.
    pub(super) fn wait_start(
        &mut self,
        timeout: Duration,
        stop: Option<&AtomicBool>,
    ) -> Result<Option<u64>, RunError> {
        let started = Instant::now();
        loop {
            if let Some(start) = self.triggers.take()?.iter().find(|t| !t.is_stop()) {
                return Ok(Some(start.next_start.nanoseconds));
            }
            if interrupted(stop) {
                return Err(RunError::Interrupted);
            }
            if started.elapsed() >= timeout {
                return Ok(None);
            }
            thread::sleep(POLL_INTERVAL);
        }
    }

    /// The next tick at or after the start, a stop, a restart, an interrupt, or silence for
    /// `timeout`.
    pub(super) fn next_event(
        &mut self,
        start_ns: u64,
        vehicle_ids: &[u8],
        timeout: Duration,
        stop: Option<&AtomicBool>,
    ) -> Result<Event, RunError> {
        let started = Instant::now();
        loop {
            let triggers = self.triggers.take()?;
            if triggers.iter().any(SystemTrigger::is_stop) {
                return Ok(Event::Stop("the lab sent the stop trigger".into()));
            }
            // The start trigger again (a lab sends it again: its writer is reliable) is not a
            // restart, nor is an older one that came late; a later start is.
            if let Some(restart) = triggers
                .iter()
                .filter(|t| !t.is_stop() && t.next_start.nanoseconds > start_ns)
                .max_by_key(|t| t.next_start.nanoseconds)
            {
                return Ok(Event::Restarted(restart.next_start.nanoseconds));
            }
            if let Some(request) = self
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
            if interrupted(stop) {
                return Ok(Event::Interrupted);
            }
            let lists: Vec<VehicleStateList> = self
                .lists
                .take()?
                .into_iter()
                .filter(|l| l.t_now >= start_ns)
                .collect();
            let superseded = lists.len().saturating_sub(1);
            if let Some(list) = lists.into_iter().max_by_key(|l| l.t_now) {
                return Ok(Event::Tick { list, superseded });
            }
            if started.elapsed() >= timeout {
                return Ok(Event::Silent);
            }
            thread::sleep(POLL_INTERVAL);
        }
    }

    /// The newest list taken now, if any (the safe stop answers it).
    pub(super) fn newest_list(&mut self) -> Result<Option<VehicleStateList>, RunError> {
        Ok(self.lists.take()?.into_iter().max_by_key(|l| l.t_now))
    }
}

/// Whether the operator asked to stop.
pub(super) fn interrupted(stop: Option<&AtomicBool>) -> bool {
    stop.is_some_and(|s| s.load(Ordering::SeqCst))
}
