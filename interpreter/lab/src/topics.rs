//! The lab's topics (name, registered type name, keyed or not), its two DDS domains and
//! the QoS of each flow, as the C++ lab sets them (reference §1.2–§1.4).
//!
//! QoS is chosen so that cpmx endpoints match the lab's RTI endpoints in both roles: where
//! the lab's two sides differ, cpmx writers offer at least what any lab reader requests
//! and cpmx readers request no more than any lab writer offers. Deviations from a single
//! lab process are noted on the profile.
//!
//! This module only describes; [`crate::LabParticipant`] creates the endpoints.

use std::marker::PhantomData;

use rustdds::{
    Duration, QosPolicies, QosPolicyBuilder,
    policy::{Durability, History, Reliability},
};

use crate::messages::{
    LabMessage, ReadyStatus, StopRequest, SystemTrigger, VehicleCommandDirect, VehicleCommandPathTracking,
    VehicleCommandSpeedCurvature, VehicleCommandTrajectory, VehicleObservation, VehicleState,
    VehicleStateList,
};

/// The lab domain as the lab's installer usually sets it (`DDS_DOMAIN`, "usually 21").
pub const LAB_DOMAIN_ID: u16 = 21;

/// The middleware's local domain to its planners (`HLCCommunicator::DEFAULT_MIDDLEWARE_DOMAIN`).
pub const MIDDLEWARE_DOMAIN_ID: u16 = 1;

/// Largest domain id whose RTPS ports (7400 + 250·domain + offsets) fit into 16 bits.
pub const MAX_DOMAIN_ID: u16 = 232;

/// RTI's default `max_blocking_time` for reliable writers, in milliseconds.
const RELIABLE_MAX_BLOCKING_MS: i64 = 100;

/// The QoS of one side of one flow (reference §1.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum QosProfile {
    /// `cpm::Writer` default: best effort, keep-last 1, volatile (vehicle states and IPS
    /// observations, vehicle commands, the state list).
    BestEffortLatest,
    /// `MultiVehicleReader`: best effort, keep-last 2000 (the middleware's state and
    /// observation readers).
    BestEffortHistory2000,
    /// `AsyncReader` / vehicle `Reader`: best effort, keep-all (command readers).
    BestEffortKeepAll,
    /// Ready handshake on both sides: reliable, keep-all, transient-local.
    ReliableKeepAllTransientLocal,
    /// Reliable, keep-last 1, volatile (the middleware's and the LCC's `systemTrigger`
    /// writers).
    ReliableLatest,
    /// Reliable, keep-all, volatile: trigger and stop-request readers and the
    /// stop-request writer. The lab's `HLCCommunicator` reads triggers best effort; a
    /// reliable reader still matches the lab's reliable trigger writers and does not lose
    /// a stop trigger.
    ReliableKeepAll,
}

impl QosProfile {
    /// The profile as rustdds QoS policies.
    pub fn policies(self) -> QosPolicies {
        let reliable = Reliability::Reliable {
            max_blocking_time: Duration::from_millis(RELIABLE_MAX_BLOCKING_MS),
        };
        let (reliability, history, durability) = match self {
            QosProfile::BestEffortLatest => (
                Reliability::BestEffort,
                History::KeepLast { depth: 1 },
                Durability::Volatile,
            ),
            QosProfile::BestEffortHistory2000 => (
                Reliability::BestEffort,
                History::KeepLast { depth: 2000 },
                Durability::Volatile,
            ),
            QosProfile::BestEffortKeepAll => {
                (Reliability::BestEffort, History::KeepAll, Durability::Volatile)
            }
            QosProfile::ReliableKeepAllTransientLocal => {
                (reliable, History::KeepAll, Durability::TransientLocal)
            }
            QosProfile::ReliableLatest => (reliable, History::KeepLast { depth: 1 }, Durability::Volatile),
            QosProfile::ReliableKeepAll => (reliable, History::KeepAll, Durability::Volatile),
        };
        QosPolicyBuilder::new()
            .reliability(reliability)
            .history(history)
            .durability(durability)
            .build()
    }
}

/// A lab topic carrying messages of type `T`, with the QoS cpmx uses on each side.
#[derive(Debug)]
pub struct TopicDef<T> {
    name: &'static str,
    writer_qos: QosProfile,
    reader_qos: QosProfile,
    marker: PhantomData<fn() -> T>,
}

impl<T: LabMessage> TopicDef<T> {
    /// Defines a topic; the constants below are the lab's.
    pub const fn new(name: &'static str, writer_qos: QosProfile, reader_qos: QosProfile) -> Self {
        TopicDef {
            name,
            writer_qos,
            reader_qos,
            marker: PhantomData,
        }
    }

    /// The DDS topic name.
    pub const fn name(&self) -> &'static str {
        self.name
    }

    /// The registered DDS type name.
    pub const fn type_name(&self) -> &'static str {
        T::TYPE_NAME
    }

    /// QoS of cpmx writers on this topic.
    pub const fn writer_qos(&self) -> QosProfile {
        self.writer_qos
    }

    /// QoS of cpmx readers on this topic.
    pub const fn reader_qos(&self) -> QosProfile {
        self.reader_qos
    }
}

/// `vehicleState` (lab domain): vehicles at 50 Hz → middleware, LCC, IPS.
pub const VEHICLE_STATE: TopicDef<VehicleState> = TopicDef::new(
    "vehicleState",
    QosProfile::BestEffortLatest,
    QosProfile::BestEffortHistory2000,
);

/// `vehicleObservation` (lab domain): IPS at 50 Hz → vehicles, middleware, LCC.
pub const VEHICLE_OBSERVATION: TopicDef<VehicleObservation> = TopicDef::new(
    "vehicleObservation",
    QosProfile::BestEffortLatest,
    QosProfile::BestEffortHistory2000,
);

/// `vehiclePoseSimulated` (lab domain): simulated vehicles' ground-truth poses.
pub const VEHICLE_POSE_SIMULATED: TopicDef<VehicleObservation> = TopicDef::new(
    "vehiclePoseSimulated",
    QosProfile::BestEffortLatest,
    QosProfile::BestEffortHistory2000,
);

/// `vehicleCommandTrajectory` (both domains): planner → middleware → vehicle.
pub const VEHICLE_COMMAND_TRAJECTORY: TopicDef<VehicleCommandTrajectory> = TopicDef::new(
    "vehicleCommandTrajectory",
    QosProfile::BestEffortLatest,
    QosProfile::BestEffortKeepAll,
);

/// `vehicleCommandPathTracking` (both domains).
pub const VEHICLE_COMMAND_PATH_TRACKING: TopicDef<VehicleCommandPathTracking> = TopicDef::new(
    "vehicleCommandPathTracking",
    QosProfile::BestEffortLatest,
    QosProfile::BestEffortKeepAll,
);

/// `vehicleCommandSpeedCurvature` (both domains).
pub const VEHICLE_COMMAND_SPEED_CURVATURE: TopicDef<VehicleCommandSpeedCurvature> = TopicDef::new(
    "vehicleCommandSpeedCurvature",
    QosProfile::BestEffortLatest,
    QosProfile::BestEffortKeepAll,
);

/// `vehicleCommandDirect` (both domains).
pub const VEHICLE_COMMAND_DIRECT: TopicDef<VehicleCommandDirect> = TopicDef::new(
    "vehicleCommandDirect",
    QosProfile::BestEffortLatest,
    QosProfile::BestEffortKeepAll,
);

/// `vehicleStateList` (local domain): the middleware's tick to the planner.
pub const VEHICLE_STATE_LIST: TopicDef<VehicleStateList> = TopicDef::new(
    "vehicleStateList",
    QosProfile::BestEffortLatest,
    QosProfile::BestEffortLatest,
);

/// `readyStatus` (both domains): `hlc_<id>` announcements and timer readiness.
pub const READY_STATUS: TopicDef<ReadyStatus> = TopicDef::new(
    "readyStatus",
    QosProfile::ReliableKeepAllTransientLocal,
    QosProfile::ReliableKeepAllTransientLocal,
);

/// `systemTrigger` (both domains): start at `next_start`, stop at `u64::MAX`.
pub const SYSTEM_TRIGGER: TopicDef<SystemTrigger> = TopicDef::new(
    "systemTrigger",
    QosProfile::ReliableLatest,
    QosProfile::ReliableKeepAll,
);

/// `stopRequest` (lab domain): planner → LCC. The reference does not state this flow's
/// QoS; a reliable writer matches either kind of reader.
pub const STOP_REQUEST: TopicDef<StopRequest> = TopicDef::new(
    "stopRequest",
    QosProfile::ReliableKeepAll,
    QosProfile::BestEffortKeepAll,
);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn topic_name_is_the_type_name_with_a_lowercase_first_letter() {
        let names = [
            (VEHICLE_STATE.name(), VEHICLE_STATE.type_name()),
            (VEHICLE_OBSERVATION.name(), VEHICLE_OBSERVATION.type_name()),
            (
                VEHICLE_COMMAND_TRAJECTORY.name(),
                VEHICLE_COMMAND_TRAJECTORY.type_name(),
            ),
            (
                VEHICLE_COMMAND_PATH_TRACKING.name(),
                VEHICLE_COMMAND_PATH_TRACKING.type_name(),
            ),
            (
                VEHICLE_COMMAND_SPEED_CURVATURE.name(),
                VEHICLE_COMMAND_SPEED_CURVATURE.type_name(),
            ),
            (VEHICLE_COMMAND_DIRECT.name(), VEHICLE_COMMAND_DIRECT.type_name()),
            (VEHICLE_STATE_LIST.name(), VEHICLE_STATE_LIST.type_name()),
            (READY_STATUS.name(), READY_STATUS.type_name()),
            (SYSTEM_TRIGGER.name(), SYSTEM_TRIGGER.type_name()),
            (STOP_REQUEST.name(), STOP_REQUEST.type_name()),
        ];
        for (name, type_name) in names {
            let mut chars = type_name.chars();
            let first = chars.next().map(|c| c.to_ascii_lowercase());
            let expected: String = first.into_iter().chain(chars).collect();
            assert_eq!(name, expected);
        }
        assert_eq!(VEHICLE_POSE_SIMULATED.type_name(), "VehicleObservation");
    }

    #[test]
    fn ready_status_is_reliable_keep_all_transient_local() {
        let qos = READY_STATUS.writer_qos().policies();
        assert!(qos.is_reliable());
        assert!(!qos.is_volatile());
        assert!(format!("{qos:?}").contains("KeepAll"));
    }

    #[test]
    fn cpmx_writers_satisfy_cpmx_readers_on_every_topic() {
        let pairs = [
            VEHICLE_STATE.writer_qos(),
            VEHICLE_STATE.reader_qos(),
            VEHICLE_COMMAND_TRAJECTORY.writer_qos(),
            VEHICLE_COMMAND_TRAJECTORY.reader_qos(),
            VEHICLE_STATE_LIST.writer_qos(),
            VEHICLE_STATE_LIST.reader_qos(),
            READY_STATUS.writer_qos(),
            READY_STATUS.reader_qos(),
            SYSTEM_TRIGGER.writer_qos(),
            SYSTEM_TRIGGER.reader_qos(),
            STOP_REQUEST.writer_qos(),
            STOP_REQUEST.reader_qos(),
        ];
        for pair in pairs.chunks(2) {
            let offered = pair[0].policies();
            let requested = pair[1].policies();
            assert_eq!(offered.compliance_failure_wrt(&requested), None, "{pair:?}");
        }
    }
}
