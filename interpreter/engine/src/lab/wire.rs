//! The emulator's side of the lab's topics (the middleware's endpoints), with each faulty topic's
//! samples passing through a [`FaultyChannel`], and the middleware's restart: a new participant
//! that waits for the planner's announcements again.

use std::time::{Duration, Instant};

use cpmx_lab::{
    DiscoveryConfig, KeyedReader, LabError, LabParticipant, Reader, ReadyStatus, SystemTrigger,
    VehicleCommandTrajectory, VehicleStateList, Writer, topics,
};
use cpmx_spec::model::LabFaults;

use super::faults::FaultyChannel;
use super::hlc_vehicle_id;

/// How long the stop trigger waits for its readers' acknowledgments.
const STOP_DELIVERY: Duration = Duration::from_secs(1);

/// The middleware's endpoints.
struct Endpoints {
    _participant: LabParticipant,
    ready: Reader<ReadyStatus>,
    triggers: Writer<SystemTrigger>,
    lists: Writer<VehicleStateList>,
    commands: KeyedReader<VehicleCommandTrajectory>,
}

impl Endpoints {
    fn new(config: &DiscoveryConfig) -> Result<Self, LabError> {
        let participant = LabParticipant::new(config)?;
        Ok(Self {
            ready: participant.reader(&topics::READY_STATUS)?,
            triggers: participant.writer(&topics::SYSTEM_TRIGGER)?,
            lists: participant.writer(&topics::VEHICLE_STATE_LIST)?,
            commands: participant.keyed_reader(&topics::VEHICLE_COMMAND_TRAJECTORY)?,
            _participant: participant,
        })
    }
}

/// The emulator's topics for one run, faults included.
pub(super) struct Wire {
    config: DiscoveryConfig,
    endpoints: Endpoints,
    lists: FaultyChannel<VehicleStateList>,
    triggers: FaultyChannel<SystemTrigger>,
    commands: FaultyChannel<VehicleCommandTrajectory>,
    /// Announcements read while a run played, for the next [`Wire::announcements`].
    pending: Vec<ReadyStatus>,
}

impl Wire {
    /// Joins the domain as the middleware.
    pub fn new(config: &DiscoveryConfig) -> Result<Self, LabError> {
        Ok(Self {
            config: config.clone(),
            endpoints: Endpoints::new(config)?,
            lists: FaultyChannel::new(None, "vehicleStateList", 0),
            triggers: FaultyChannel::new(None, "systemTrigger", 0),
            commands: FaultyChannel::new(None, "vehicleCommandTrajectory", 0),
            pending: Vec::new(),
        })
    }

    /// Plays `faults` in the run with `run_seed` (none without): fresh channels, and the
    /// commands of an earlier run discarded.
    pub fn start_run(&mut self, faults: Option<&LabFaults>, run_seed: u64) -> Result<(), LabError> {
        self.lists = FaultyChannel::new(faults, "vehicleStateList", run_seed);
        self.triggers = FaultyChannel::new(faults, "systemTrigger", run_seed);
        self.commands = FaultyChannel::new(faults, "vehicleCommandTrajectory", run_seed);
        self.endpoints.commands.take()?;
        Ok(())
    }

    /// The planners' announcements since the last call (those read while a run played
    /// first).
    pub fn announcements(&mut self) -> Result<Vec<ReadyStatus>, LabError> {
        let mut out = std::mem::take(&mut self.pending);
        out.extend(self.endpoints.ready.take()?);
        Ok(out)
    }

    /// Whether a planner announced a run other than `stamp`'s (the driver moved on); those
    /// announcements are kept for the next run, the run's own are dropped.
    pub fn other_run_announced(&mut self, stamp: u64) -> Result<bool, LabError> {
        let other: Vec<ReadyStatus> = self
            .endpoints
            .ready
            .take()?
            .into_iter()
            .filter(|s| hlc_vehicle_id(&s.source_id).is_some() && s.next_start_stamp.nanoseconds != stamp)
            .collect();
        let announced = !other.is_empty();
        self.pending.extend(other);
        Ok(announced)
    }

    /// Sends a state list (through the topic's faults).
    pub fn send_list(&mut self, list: VehicleStateList) {
        self.lists.send(list, Instant::now());
    }

    /// Sends a trigger (through the topic's faults).
    pub fn send_trigger(&mut self, trigger: SystemTrigger) {
        self.triggers.send(trigger, Instant::now());
    }

    /// Writes what has arrived at the other end of the faulty channels by now.
    pub fn flush(&mut self) -> Result<(), LabError> {
        let now = Instant::now();
        for trigger in self.triggers.arrived(now) {
            self.endpoints.triggers.write(trigger)?;
        }
        for list in self.lists.arrived(now) {
            self.endpoints.lists.write(list)?;
        }
        Ok(())
    }

    /// The commands that have arrived by now (through the topic's faults).
    pub fn commands(&mut self) -> Result<Vec<VehicleCommandTrajectory>, LabError> {
        let now = Instant::now();
        for command in self.endpoints.commands.take()? {
            self.commands.send(command, now);
        }
        Ok(self.commands.arrived(now))
    }

    /// The stop trigger, past every fault (the lab's reliable trigger), delivered before the
    /// next run or the process's end can drop it.
    pub fn send_stop(&mut self) -> Result<(), LabError> {
        self.flush()?;
        self.endpoints.triggers.write(SystemTrigger {
            next_start: cpmx_lab::TimeStamp::STOP,
        })?;
        self.endpoints.triggers.wait_for_acknowledgments(STOP_DELIVERY)?;
        Ok(())
    }

    /// Restarts the middleware: a new participant replaces this one (which leaves the
    /// domain), and waits up to `timeout` for the planner's announcements of the run `stamp`
    /// (transient local: the planner's writer sends them to the new participant again).
    /// `Ok(false)` when they do not come.
    pub fn restart(&mut self, stamp: u64, ids: &[u8], timeout: Duration) -> Result<bool, LabError> {
        self.other_run_announced(stamp)?;
        self.endpoints = Endpoints::new(&self.config)?;
        let started = Instant::now();
        let mut seen = Vec::new();
        while started.elapsed() < timeout {
            for status in self.endpoints.ready.take()? {
                match hlc_vehicle_id(&status.source_id) {
                    Some(id) if status.next_start_stamp.nanoseconds == stamp => seen.push(id),
                    Some(_) => self.pending.push(status),
                    None => {}
                }
            }
            if ids.iter().all(|id| seen.contains(id)) {
                return Ok(true);
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        Ok(false)
    }
}
